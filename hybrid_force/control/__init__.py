"""The controller: constraint rows and projection (eq. 5), CLIK (eq. 27), the controller
interface, the force-loop bound, the supervisor and the laws (``laws/``).

The names of the paper's law are re-exported here: before version 0.2 they lived in the module
``hybrid_force.control`` that this package replaced.
"""

from hybrid_force.control.laws.arimoto import (
    Command,
    ControlTrace,
    Desired,
    Gains,
    LawWorkspace,
    check_damping_gain,
    default_damping_gain,
    make_gains,
)

__all__ = [
    "Command",
    "ControlTrace",
    "Desired",
    "Gains",
    "LawWorkspace",
    "check_damping_gain",
    "default_damping_gain",
    "make_gains",
]

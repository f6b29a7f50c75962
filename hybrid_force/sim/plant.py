"""The plant: the true arm on its surfaces, with its contact chosen once, rigid or compliant.

The controller never reads it: the loop (:mod:`hybrid_force.sim.loop`) hands the controller
its sensors' readings, and the plant only a command u = u0 + B f. One step of the plant:

1. :meth:`Plant.evaluate`: the arm's terms at (q, v) (:meth:`Robot.terms`) and, where they are
   defined, the constraint rows of its surfaces (:class:`~hybrid_force.sim.arm.Arm`);
2. ``Plant.accelerate``: q̈ and the contact force f under the applied torque
   sat(u0 + B f), from the contact: :class:`~hybrid_force.sim.rigid_contact.RigidContact`
   (the paper's: free, constrained, saturated or released) or
   :class:`~hybrid_force.sim.compliant_contact.CompliantContact` (Hunt–Crossley);
3. ``Plant.advance``: the step's dissipation accounted, then the contact's integration
   to t + dt (rigid: the arm's integrator, projection onto the surface in contact, touch and
   impact out of it; compliant: semi-implicit Euler of the free arm).
"""

from __future__ import annotations

from hybrid_force.control.constraint import Constraint
from hybrid_force.model.robot import Robot
from hybrid_force.sim.arm import Arm, SurfaceContact
from hybrid_force.sim.compliant_contact import CompliantContact
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.rigid_contact import RigidContact
from hybrid_force.sim.settings import SimSettings

__all__ = ["Plant"]


class Plant(Arm):
    """The true arm on its surfaces (:class:`~hybrid_force.sim.arm.Arm`) and its contact.

    Args:
        robot: the arm.
        constraint: its surfaces (the same geometry the controller knows, in its own object).
        sim: the settings it reads: ``baumgarte`` (section 6.2), ``integrator`` ("euler",
            semi-implicit, or "rk4" with the command held over the step), ``unilateral`` and
            ``release_tol`` (release when the surface would pull, f < −release_tol [N]) and
            ``torque_limits`` (saturate the applied torque at the arm's effort limits).
        touch_tol: [m] a tip that ends a step within this distance of the surface, still
            closing in, touches it.
        contact: the contact model (:mod:`hybrid_force.sim.contact`); default the paper's rigid,
            frictionless contact.

    Attributes:
        surface_contact: the contact strategy of the run
            (:class:`~hybrid_force.sim.arm.SurfaceContact`), chosen here once; the contact
            state, its events, the applied torque and the energies dissipated are the
            :class:`~hybrid_force.sim.arm.Arm`'s attributes.
        accelerate, advance, touch: the strategy's methods (their contract:
            :class:`~hybrid_force.sim.arm.SurfaceContact`).
    """

    #: the rigid contact's class (a test oracle swaps it for its readable form)
    rigid_contact: type[RigidContact] = RigidContact

    def __init__(
        self,
        robot: Robot,
        constraint: Constraint,
        sim: SimSettings,
        touch_tol: float,
        contact: ContactSettings | None = None,
    ) -> None:
        contact = contact if contact is not None else ContactSettings()
        super().__init__(robot, constraint, sim, contact)
        strategy: SurfaceContact = (
            CompliantContact(self)
            if contact.compliant
            else self.rigid_contact(self, sim, touch_tol)
        )
        self.surface_contact = strategy
        # the strategy's methods are the plant's own: one Python call per step, not two
        self.accelerate = strategy.accelerate
        self.advance = strategy.advance
        self.touch = strategy.touch

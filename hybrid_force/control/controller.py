"""The controller as a component: it sees only what it measures and owns its model.

A controller is anything with ``command(t, q, v, f) -> u``: at each control tick it receives
the time [s], the measured joint positions q̃ (n,) [rad or m] and velocities ṽ (n,)
[rad/s or m/s] and the measured contact force f̃ (k,) [N], and returns the joint torques
u (n,) [N·m or N], which the simulator holds until the next tick (zero-order hold). It is
never handed the plant's terms, its multiplier or its state: it computes what it needs from
its own model (:class:`ControllerModel`).

The scenario's law (``control.law``: the paper's ``"arimoto"`` by default, or another of
:data:`hybrid_force.control.laws.base.LAWS`) runs inside the phase supervisor
(:class:`hybrid_force.control.supervisor.HybridController`): with ideal sensing at the plant's rate
the simulator also uses its affine form u = u0 + B f to resolve the force loop exactly, the
paper's setting; a controller given to :func:`hybrid_force.sim.loop.simulate` runs sampled.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from hybrid_force.control.constraint import Constraint, ConstraintTerms, Normalization
from hybrid_force.errors import SurfaceError
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.model.robot import Robot, RobotTerms

__all__ = [
    "Controller",
    "ControllerModel",
]


@runtime_checkable
class Controller(Protocol):
    """A controller the simulator can run (see the module docstring)."""

    def command(self, t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Joint torques u (n,) [N·m or N] for the measurements at time t [s]."""
        ...


class ControllerModel:
    """What the controller computes for itself, from its own model, at the state it sees.

    Its own robot terms (M, C, g, p, J, J̇ at (q̃, ṽ), its own Pinocchio data) and its own
    constraint rows (its own :class:`Constraint`: it knows the surfaces' geometry). Its robot
    is the plant's model file, or ``control.model`` (the same joints); the controller's mass
    factor is applied by :class:`~hybrid_force.control.supervisor.HybridController` on top.
    """

    def __init__(
        self,
        robot: Robot,
        surfaces: Sequence[Surface],
        normalization: Normalization,
    ) -> None:
        self.robot = robot
        self.data = robot.new_data()
        self.constraint = Constraint(surfaces, normalization=normalization)
        self._terms = RobotTerms.zeros(robot.nv)
        self._cons = ConstraintTerms.zeros(self.constraint.k, robot.nv)

    def evaluate(self, q: np.ndarray, v: np.ndarray) -> tuple[RobotTerms, ConstraintTerms | None]:
        """Terms and constraint rows at (q, v); None rows where ∇Φ vanishes (free space)."""
        terms = self.robot.terms(q, v, self.data, out=self._terms)
        try:
            return terms, self.constraint.evaluate(terms, v, out=self._cons)
        except SurfaceError:
            return terms, None

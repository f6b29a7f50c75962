"""The compliant contact: the force follows from the tip's penetration, the arm moves freely.

The Hunt–Crossley force f = max(0, k δⁿ (1 + c δ̇)) of the penetration δ = −d [m] and its
rate δ̇ = −A q̇ [m/s] (:func:`~hybrid_force.sim.contact.compliant_force`, the "tip" row
scaling: f in N) is known before the step, so the command u = u0 + B f is evaluated at it and

    q̈ = M⁻¹ (sat(u) + Aᵀ f + F f − C q̇ − g)

with F f the tip's friction torque (:func:`~hybrid_force.sim.contact.friction_matrix`). The
tool is in contact while its tip is inside a surface or within :data:`GEOMETRIC_TOL` of it
(round-off of a projection), with a "touch" event on entry and "release" on exit. The step is
semi-implicit Euler whatever ``sim.integrator`` says (the force is in q̈ already; no
projection, no impact).
"""

from __future__ import annotations

import numpy as np

from hybrid_force.control.constraint import ConstraintTerms
from hybrid_force.control.laws.base import Command
from hybrid_force.events import Release, Touch
from hybrid_force.model.robot import RobotTerms
from hybrid_force.sim.arm import State, SurfaceContact, Vector
from hybrid_force.sim.contact import compliant_force, friction_power
from hybrid_force.sim.dynamics import free_acceleration

__all__ = ["GEOMETRIC_TOL", "CompliantContact"]

#: [m] a compliant contact holds while the tip is within this of a surface (round-off)
GEOMETRIC_TOL = 1e-12


class CompliantContact(SurfaceContact):
    """The compliant contact of one arm (module docstring; its argument: the base's)."""

    def accelerate(
        self, terms: RobotTerms, cons: ConstraintTerms | None, cmd: Command, t: float
    ) -> State:
        """The Hunt–Crossley force f of the penetration, with the free arm's q̈."""
        arm = self.arm
        arm.applied = None
        if cons is None:  # rows undefined off the surface (evaluate() raised if in contact)
            return arm.free(terms, cmd.u0), arm._zeros_k
        penetration, rate = -cons.distance, -cons.rate  # "tip" rows: A v = ḋ [m/s]
        touching = float(penetration.max()) > -GEOMETRIC_TOL
        if touching != arm.in_contact:
            if touching:
                arm.events.append(Touch(t, float(rate.max())))
            else:
                arm.events.append(Release(t, 0.0))
            arm.in_contact = touching
            arm.ever_in_contact |= touching
        if not touching:
            return arm.free(terms, cmd.u0), arm._zeros_k
        c = arm.contact
        f = compliant_force(c, penetration, rate)
        tau = arm.clipped(cmd.u0 if cmd.B is None else cmd.u0 + cmd.B @ f) + cons.A.T @ f
        friction = 0.0
        if c.friction > 0.0:
            F, speed = arm.friction_at(terms)
            tau = tau + F @ f
            friction = friction_power(c.friction, c.friction_velocity, f, speed)
        spring = c.stiffness * np.maximum(penetration, 0.0) ** c.exponent
        arm._power = (friction, float((f - spring) @ rate))  # damping: (f − kδⁿ) δ̇ ≥ 0
        return free_acceleration(arm._M(terms), arm._nle(terms), tau), f

    def advance(
        self, q: Vector, v: Vector, ddq: Vector, cmd: Command, t: float, dt: float, distance: Vector
    ) -> State:
        """Semi-implicit Euler of the free arm (the force is in q̈)."""
        self.arm.account(v, ddq, dt)
        return self.arm.euler(q, v, ddq, dt)

    def touch(self, q: Vector, v: Vector, t: float) -> State:
        """v unchanged: the force does the rest."""
        arm = self.arm
        q, _ = arm.project(q, np.zeros_like(v), iterations=3)
        arm.in_contact = arm.ever_in_contact = True
        return q, v

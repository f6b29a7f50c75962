"""The plant's arm: its terms, its joints' own dissipation, its free dynamics, its integration
and its tip's geometry, whatever the contact (:mod:`hybrid_force.sim.rigid_contact`,
:mod:`hybrid_force.sim.compliant_contact`) does with them.

:class:`Arm` holds what one step of the plant shares between the arm and its contact: the
Pinocchio data of the dynamics, the contact state (:attr:`Arm.in_contact`, its events), the
torque applied when the effort limits acted and the energies dissipated so far. The plant
(:class:`~hybrid_force.sim.plant.Plant`) is this arm with one contact strategy.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
import pinocchio as pin

from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.laws.base import Command
from hybrid_force.errors import RobotError, SurfaceError
from hybrid_force.events import Event
from hybrid_force.model.robot import LWA as _LWA
from hybrid_force.model.robot import Robot, RobotTerms
from hybrid_force.sim.contact import ContactSettings, friction_matrix, joint_dissipation
from hybrid_force.sim.dynamics import ConstrainedDynamics, free_acceleration
from hybrid_force.sim.settings import SimSettings

__all__ = ["Arm", "State", "SurfaceContact", "Vector"]

Vector = np.ndarray
"""A float64 (n,) or (k,) array of the step."""
State = tuple[np.ndarray, np.ndarray]
"""(q, v) of the arm, or (q̈ (n,), f (k,)) of a step."""


class Arm:
    """The true arm on its surfaces: everything of the plant's step but the contact force.

    Args:
        robot: the arm.
        constraint: its surfaces (the same geometry the controller knows, in its own object).
        sim: the settings it reads: ``baumgarte`` (section 6.2), ``integrator``,
            ``torque_limits``, ``dt`` and ``joint_friction_velocity``.
        contact: the contact settings (its friction law is the arm's: :meth:`friction_at`).

    Attributes:
        in_contact: the tip is on the surface (the rows hold).
        ever_in_contact: it has been, at some point of the run.
        events: touch ("impact", or "touch" for a compliant contact) and "release" events.
        effort: (n,) effort limits the plant enforces [N·m or N] (+inf: none), or None.
        applied: the torque applied at the last accelerate() when it saturated, else None
            (then the applied torque is the command u0 + B f itself).
        friction_energy, damping_energy: [J] dissipated by the tip's friction and by the
            compliant contact's damping so far.
        joint_damping_energy, joint_friction_energy: [J] dissipated by the joints' own
            damping and friction so far.

    Joint damping and friction: the model's ``damping`` d and ``friction`` τ_c (URDF
    ``<dynamics>``), which Pinocchio's algorithms ignore, act as τ_j = −(d + c) q̇ with
    c = τ_c/√(q̇² + ε²) (:func:`~hybrid_force.sim.contact.joint_dissipation`, the tip
    friction's regularised law). With the Euler integrator the coefficients are taken at the
    step's start and the velocity at its end, τ_j = −(d + c)(q̇ + dt q̈): the plant solves
    with M + dt·diag(d + c) and C q̇ + g + (d + c) q̇ (a linearly implicit step). Where the tip
    friction is explicit, this departs from it on purpose: near rest c ≈ τ_c/ε is a stiff
    damper (1e3 N·m·s/rad for τ_c = 1 N·m, ε = 1 mm/s), which an explicit step on a light
    wrist (M⁻¹ ~ 1e3 1/(kg·m²)) would need dt < 2e-6 s to keep stable; the implicit one is
    stable for any dt and still dissipates exactly (d + c) w² with w the step's end velocity.
    RK4 evaluates τ_j at each stage's velocity (explicit: mind the step). Only the plant's
    solves see them: the terms handed to the controller are untouched. All zero: no term at
    all, bit-identical.
    """

    def __init__(
        self, robot: Robot, constraint: Constraint, sim: SimSettings, contact: ContactSettings
    ) -> None:
        self.robot, self.constraint, self.contact = robot, constraint, contact
        self.friction_energy = self.damping_energy = 0.0
        self._init_joints(robot, sim)
        self._power = (0.0, 0.0)  # (friction, damping) [W] at the last accelerate()
        self.baumgarte, self.integrator = sim.baumgarte, sim.integrator
        effort = robot.effort_limits
        self.effort: np.ndarray | None = (
            effort if sim.torque_limits and bool(np.isfinite(effort).any()) else None
        )
        self.applied: np.ndarray | None = None
        self.in_contact = self.ever_in_contact = False
        self.events: list[Event] = []
        k, n = constraint.k, robot.nv
        # the dynamics' data: robot.terms fills M (crba) that the solver then factorises
        self.data = robot.new_data()
        self._terms = RobotTerms.zeros(n)
        self._cons = ConstraintTerms.zeros(k, n)
        # the step's terms and rows, their arguments bound once (evaluate)
        self._terms_at = robot.terms_into(self.data, self._terms)
        self._rows_at = constraint.evaluate
        self._zeros_k = np.zeros(k)
        # geometry helpers' own data (projection, distances)
        self._geo = robot.new_data()
        self._tip = self._geo.oMf[robot.tip_id].translation  # a view, updated in place
        self._diag = np.diag_indices(n)
        self._imp = robot.new_data()  # the velocity correction's own data (its crba)

    # ------------------------------------------------------------------ terms
    def evaluate(self, q: np.ndarray, v: np.ndarray) -> tuple[RobotTerms, ConstraintTerms | None]:
        """The arm's terms at (q, v) and the constraint rows, None where they are undefined
        off the surface (e.g. the tip on a cylinder's axis).

        Raises:
            SurfaceError: the rows are undefined while in contact.
        """
        terms = self._terms_at(q, v)  # Robot.terms(q, v, self.data, self._terms)
        if self._dissipates:  # pin.forwardDynamics reads data.M, which crba just filled
            self._joints_at(v, self.data.M)
        try:
            return terms, self._rows_at(terms, v, self._cons)
        except SurfaceError:
            if self.in_contact:
                raise
            return terms, None

    # ------------------------------------------------------------------ joint dissipation
    def _init_joints(self, robot: Robot, sim: SimSettings) -> None:
        """The joints' own damping d and Coulomb friction τ_c (the model's ``damping`` and
        ``friction``, URDF ``<dynamics>``), which Pinocchio reads and its algorithms ignore."""
        model = robot.model
        d = np.array(model.damping, dtype=float)
        c = np.array(model.friction, dtype=float)
        for name, values in (("damping", d), ("friction", c)):
            bad = np.flatnonzero(~(values >= 0.0) | ~np.isfinite(values))
            if bad.size:
                joint = _joint_of(model, int(bad[0]))
                raise RobotError(
                    f"robot '{robot.name}': joint {joint} has {name} {values[bad[0]]:g}; the "
                    f"joints' {name} must be a finite number >= 0"
                )
        #: (n,) joint damping [N·m·s/rad or N·s/m] and Coulomb friction [N·m or N] the plant
        #: applies (class docstring; ε: ``sim.joint_friction_velocity``)
        self.joint_damping, self.joint_friction = d, c
        self.joint_friction_velocity = sim.joint_friction_velocity
        # all zero: no term at all, so the run is bit-identical to an arm without them
        self._dissipates = bool(d.any() or c.any())
        # [s] h of the implicit treatment: the step with the Euler integrator, 0 (explicit)
        # with RK4, whose stages evaluate the torque at their own velocities
        self._implicit_dt = sim.dt if sim.integrator == "euler" else 0.0
        # (d, c(q̇)) (n,) each at the last evaluate(): the coefficients of this step
        self._joint_coef: tuple[np.ndarray, np.ndarray] | None = None
        self._joint_Dv: np.ndarray | None = None  # (n,) (d + c) q̇ at the step's start
        #: [J] dissipated by the joints' damping and by their friction so far
        self.joint_damping_energy = self.joint_friction_energy = 0.0

    def _joints_at(self, v: np.ndarray, M: np.ndarray | None) -> None:
        """The joints' coefficients at the step's start velocity v, and (d + c) h added to the
        diagonal of M (n, n), the mass matrix the plant's solves read (not the terms handed
        to the controller); M None: the solves read terms.M (:meth:`_M`)."""
        if not self._dissipates:
            return
        d, c = joint_dissipation(
            self.joint_damping, self.joint_friction, self.joint_friction_velocity, v
        )
        D = d + c
        self._joint_coef, self._joint_Dv = (d, c), D * v
        if M is not None and self._implicit_dt > 0.0:
            M[self._diag] += self._implicit_dt * D

    def _nle(self, terms: RobotTerms) -> np.ndarray:
        """C q̇ + g plus the joints' own (d + c) q̇ where the model has any."""
        if self._joint_Dv is None:
            return terms.nle
        return terms.nle + self._joint_Dv

    def _M(self, terms: RobotTerms) -> np.ndarray:
        """The matrix of the plant's dense solves: M, plus h (d + c) on its diagonal with
        joint damping (the implicit step, class docstring)."""
        if self._joint_coef is None or self._implicit_dt == 0.0:
            return terms.M
        d, c = self._joint_coef
        return terms.M + np.diag(self._implicit_dt * (d + c))

    def account(self, v: np.ndarray, ddq: np.ndarray, dt: float) -> None:
        """The step's dissipation [J] added to the energies: the contact's at the step's start
        forces (its power at accelerate()), the joints' over the step."""
        if self._power != (0.0, 0.0):
            self.friction_energy += self._power[0] * dt
            self.damping_energy += self._power[1] * dt
            self._power = (0.0, 0.0)
        if self._joint_coef is not None:
            # the torque −(d + c) w acts with w = v + h q̈ (h = dt: the step's end velocity,
            # whose displacement w dt the step makes; h = 0, RK4: the start's)
            d, c = self._joint_coef
            w = v + self._implicit_dt * ddq
            w2 = w * w
            self.joint_damping_energy += float(d @ w2) * dt
            self.joint_friction_energy += float(c @ w2) * dt
            self._joint_coef = self._joint_Dv = None

    # ------------------------------------------------------------------ forces and motion
    def free(self, terms: RobotTerms, u: np.ndarray) -> np.ndarray:
        """q̈ (n,) of the arm off the surface under the motor torque sat(u) [N·m or N]."""
        return free_acceleration(self._M(terms), self._nle(terms), self.clipped(u))

    def clipped(self, u: np.ndarray) -> np.ndarray:
        """The motor torque u (n,) clipped at the effort limits; :attr:`applied` set if it was."""
        if self.effort is not None and bool(np.any(np.abs(u) > self.effort)):
            u = self.applied = np.clip(u, -self.effort, self.effort)
        return u

    def friction_at(self, terms: RobotTerms) -> tuple[np.ndarray, np.ndarray]:
        """(n, k) friction torque per newton of normal force and (k,) sliding speeds [m/s] at
        the step's start (:func:`~hybrid_force.sim.contact.friction_matrix`)."""
        normals = np.array([s.normal(terms.p) for s in self.constraint.surfaces])
        c = self.contact
        return friction_matrix(c.friction, c.friction_velocity, normals, terms.J, terms.pdot)

    def euler(
        self, q: np.ndarray, v: np.ndarray, ddq: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Semi-implicit Euler: v⁺ = v + q̈ dt, q⁺ = q ⊕ v⁺ dt (new arrays)."""
        v = v + ddq * dt
        return pin.integrate(self.robot.model, q, v * dt), v

    def integrate(
        self, q: np.ndarray, v: np.ndarray, ddq: np.ndarray, cmd: Command, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) at t + dt from q̈ (n,) at t: ``sim.integrator``'s step, the command held."""
        if self.integrator == "euler":
            return self.euler(q, v, ddq, dt)
        return self._rk4(cmd, q, v, ddq, dt)

    def _rk4(
        self, cmd: Command, q: np.ndarray, v: np.ndarray, a1: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """One RK4 step with the command (u0, B) held; a1: (n,) q̈ already solved at (q, v);
        in contact the stages solve the constrained dynamics."""
        # the stages reuse the dynamics' data: the next step's evaluate() refills it
        robot, model, data = self.robot, self.robot.model, self.data
        in_contact = self.in_contact

        def acc(qs: np.ndarray, vs: np.ndarray) -> np.ndarray:
            terms = robot.terms(qs, vs, data)
            nle = terms.nle
            if self._dissipates:  # the joints' damping and friction at the stage's velocity
                d, c = joint_dissipation(
                    self.joint_damping, self.joint_friction, self.joint_friction_velocity, vs
                )
                nle = nle + (d + c) * vs
            if not in_contact:
                return free_acceleration(terms.M, nle, cmd.u0)
            cons = self.constraint.evaluate(terms, vs)
            gamma = self.baumgarte.gamma(cons.drift, cons.rate, cons.phi / cons.scale)
            # a new solver per stage: the stages' accelerations are kept until the sum
            dyn = ConstrainedDynamics(model, data, cons.A.shape[0])
            return dyn.solve(nle, cmd.u0, cmd.B, cons.A, gamma)[0]

        k1v, k1a = v, a1
        k2v = v + k1a * (dt / 2)
        k2a = acc(pin.integrate(model, q, k1v * (dt / 2)), k2v)
        k3v = v + k2a * (dt / 2)
        k3a = acc(pin.integrate(model, q, k2v * (dt / 2)), k3v)
        k4v = v + k3a * dt
        k4a = acc(pin.integrate(model, q, k3v * dt), k4v)
        q_new = pin.integrate(model, q, (k1v + 2 * k2v + 2 * k3v + k4v) * (dt / 6))
        v_new = v + (k1a + 2 * k2a + 2 * k3a + k4a) * (dt / 6)
        return q_new, v_new

    # ------------------------------------------------------------------ geometry
    def tip(self, q: np.ndarray) -> np.ndarray:
        """(3,) tip position at q [m] (a view of the plant's data)."""
        pin.forwardKinematics(self.robot.model, self._geo, q)
        return pin.updateFramePlacement(self.robot.model, self._geo, self.robot.tip_id).translation

    def distance(self, q: np.ndarray) -> np.ndarray:
        """(k,) metric distances of the tip to the surfaces at q [m]."""
        return self.constraint.distance(self.tip(q))

    def _rows(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows n̂ᵀJ (k, n) and first-order distances Φ / ‖∇Φ‖ (k,) at q."""
        model, data, fid = self.robot.model, self._geo, self.robot.tip_id
        pin.computeJointJacobians(model, data, q)
        p = pin.updateFramePlacement(model, data, fid).translation
        return self.constraint.normal_rows(p, pin.getFrameJacobian(model, data, fid, _LWA)[:3])

    def project(
        self, q: np.ndarray, v: np.ndarray, iterations: int = 1
    ) -> tuple[np.ndarray, np.ndarray]:
        """Gauss–Newton steps putting the tip on the surfaces, then the constraint impulse
        that puts v on the tangent space (:meth:`_impulse`).

        The impulse uses the rows of the last iteration's start point (the difference is of
        the order of the position correction, ~1e-9 m here) and M at the corrected q.
        """
        model = self.robot.model
        for _ in range(iterations):
            A, d = self._rows(q)
            gram = A @ A.T
            A_pinv = A.T / gram[0, 0] if A.shape[0] == 1 else A.T @ np.linalg.inv(gram)
            q = pin.integrate(model, q, -(A_pinv @ d))
        return q, self._impulse(q, v, A)

    def _impulse(self, q: np.ndarray, v: np.ndarray, A: np.ndarray) -> np.ndarray:
        """v (n,) after the plastic constraint impulse at q that makes A v = 0 (A: (k, n)):

            v⁺ = v − M⁻¹Aᵀ (A M⁻¹ Aᵀ)⁻¹ A v,     M = M(q),

        i.e. M (v⁺ − v) = Aᵀ P with P (k,) [N·s]: the correction is a force through the
        constraint, and does no work on a tangent velocity (issue 28 item 5; a plain
        projection v − A⁺ A v is not of this form and leaves a tangential residual in the
        equation of motion). ``pin.impulseDynamics`` with restitution 0 and no damping
        (:func:`~hybrid_force.sim.dynamics.plastic_impact` solves the same problem).

        M at the corrected q, the configuration at which v⁺ holds and whose M the next step
        uses: the impulse is the one that removes the least kinetic energy there (Gauss).
        Returns a new array.
        """
        return pin.impulseDynamics(self.robot.model, self._imp, q, v, A, 0.0, 0.0).copy()


class SurfaceContact(ABC):
    """How the surfaces act on the arm: the contact strategy a plant holds, chosen once
    (:class:`~hybrid_force.sim.rigid_contact.RigidContact`,
    :class:`~hybrid_force.sim.compliant_contact.CompliantContact`), whose three methods the
    plant binds as its own (:class:`~hybrid_force.sim.plant.Plant`). It sets the arm's contact
    state, its events, :attr:`Arm.applied` and the power dissipated.

    Args:
        arm: the plant's arm, whose contact state this contact sets.
    """

    def __init__(self, arm: Arm) -> None:
        self.arm = arm

    @abstractmethod
    def accelerate(
        self, terms: RobotTerms, cons: ConstraintTerms | None, cmd: Command, t: float
    ) -> State:
        """q̈ (n,) and the contact force f (k,) [N] of the step at t [s] under the applied
        torque sat(u0 + B f), from the arm's terms and the constraint rows (None off the
        surface, where they are undefined); a touch or a release is an event at t.
        :attr:`Arm.applied` is then the saturated torque when a limit acted, else None."""

    @abstractmethod
    def advance(
        self, q: Vector, v: Vector, ddq: Vector, cmd: Command, t: float, dt: float, distance: Vector
    ) -> State:
        """(q, v) at t + dt [s] from q̈ (n,) at t, the step's dissipation accounted first
        (:meth:`Arm.account`); ``distance`` (k,) [m]: the tip's distances at t. The arrays
        returned may be the contact's own buffers: the next call may reuse them."""

    @abstractmethod
    def touch(self, q: Vector, v: Vector, t: float) -> State:
        """(q, v) with the tip placed on the surface at t [s]."""


def _joint_of(model: pin.Model, iv: int) -> str:
    """The name of the joint that owns velocity index iv."""
    for j in range(1, model.njoints):
        start = model.joints[j].idx_v
        if start <= iv < start + model.joints[j].nv:
            return str(model.names[j])
    return f"#{iv}"

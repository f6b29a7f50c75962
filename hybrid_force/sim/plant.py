"""The plant: the true arm on its surfaces, with contact, release, impacts and integration.

The controller never reads it: the loop (:mod:`hybrid_force.sim.loop`) hands the controller
its sensors' readings, and the plant only a command u = u0 + B f. One step of the plant:

1. :meth:`Plant.evaluate`: the arm's terms at (q, v) (:meth:`Robot.terms`) and, where they are
   defined, the constraint rows of its surfaces;
2. :meth:`Plant.accelerate`: in contact, q̈ and f together from the constrained dynamics
   (:class:`~hybrid_force.sim.dynamics.ConstrainedDynamics`, section 6.2, with the algebraic
   loop u = u0 + B f resolved exactly); if the surface would have to pull (f < 0) the contact
   is released (unilateral surface) and the step is free;
3. :meth:`Plant.advance`: semi-implicit Euler (``pinocchio.integrate``, or q + v dt for arms
   whose joints are all bounded revolute or prismatic) or RK4 with the command held over the
   step; in contact, post-stabilisation: one Gauss–Newton step puts the tip back on the surface
   and a plastic constraint impulse, through M⁻¹Aᵀ, puts the velocity on the tangent space
   (removes the O(dt²) drift that the Baumgarte terms alone would leave; unlike a plain
   projection it does no tangential work: :meth:`Plant._impulse`); out of contact, a crossing
   of the surface between two steps is found, the tip is placed on the surface there and a
   plastic impact (A q̇⁺ = 0) is applied: the tool never passes through the surface.

:class:`Plant` does the small algebra between the Pinocchio calls in compiled kernels
(:mod:`hybrid_force.sim._kernels`); :class:`ReferencePlant` is the same plant in readable
numpy (one public method per robot term, the general constraint algebra, a dense KKT solve),
which the tests compare against.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hybrid_force._lazy import LazyKernels
from hybrid_force.control.constraint import _GRAD_TOL, Constraint, ConstraintTerms
from hybrid_force.control.laws.arimoto import Command
from hybrid_force.errors import RobotError, SurfaceError
from hybrid_force.events import Event, Impact, Release, Touch
from hybrid_force.model.robot import LWA as _LWA
from hybrid_force.model.robot import Robot, RobotTerms, reference_terms
from hybrid_force.sim.contact import (
    ContactSettings,
    compliant_force,
    friction_matrix,
    friction_power,
    joint_dissipation,
)
from hybrid_force.sim.dynamics import (
    ConstrainedDynamics,
    constrained_acceleration,
    free_acceleration,
    kkt_reference,
    plastic_impact,
)
from hybrid_force.sim.saturation import held_set
from hybrid_force.sim.settings import SimSettings

_K = LazyKernels("hybrid_force.sim._kernels")

__all__ = ["Plant", "ReferencePlant"]


class Plant:
    """The true arm on its surfaces, and its contact state.

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

    Compliant contact: the force is the Hunt–Crossley force of the tip's penetration
    (:func:`~hybrid_force.sim.contact.compliant_force`), known before the step, so the
    command u = u0 + B f is evaluated at it and q̈ = M⁻¹(sat(u) + Aᵀ f + τ_f − C q̇ − g); the
    tool is in contact while its tip is inside a surface or within ``GEOMETRIC_TOL`` of it
    (round-off of a projection), with a "touch" event on entry and "release" on exit.
    Friction: τ_f = F f with F from :func:`~hybrid_force.sim.contact.friction_matrix` at the
    step's start velocity; with the rigid contact F is added to the loop's B, so the normal
    force and its friction are solved together. The energies dissipated by friction and by the
    compliant damping are summed in :attr:`friction_energy` and :attr:`damping_energy` [J].

    Torque saturation: the applied torque is τ = sat(u0 + B f), each joint clipped to
    ±effort. With B (the exact loop of the paper's law) τ and f depend on each other: the
    plant finds the consistent set of held joints and their signs exactly
    (:func:`~hybrid_force.sim.saturation.held_set`: every held joint's command beyond its
    limit on the side it is held at, every free joint's within), then solves once with those
    joints held (their row of B removed). A step whose unsaturated command is within every
    limit takes none of this (the cheap path, unchanged).

    Attributes:
        in_contact: the tip is on the surface (the rows hold).
        ever_in_contact: it has been, at some point of the run.
        events: touch ("impact", or "touch" for a compliant contact) and "release" events,
            each {"t": s, "kind": ...}.
        friction_energy: [J] dissipated by friction so far.
        damping_energy: [J] dissipated by the compliant contact's damping so far.
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

    #: [m] a compliant contact holds while the tip is within this of a surface (round-off)
    GEOMETRIC_TOL = 1e-12

    _compiles = True  # the Euler step with projection in compiled calls, where it applies

    def __init__(
        self,
        robot: Robot,
        constraint: Constraint,
        sim: SimSettings,
        touch_tol: float,
        contact: ContactSettings | None = None,
    ) -> None:
        self.robot, self.constraint = robot, constraint
        self.contact = contact = contact if contact is not None else ContactSettings()
        self.compliant = contact.compliant
        self.friction_energy = self.damping_energy = 0.0
        self._init_joints(robot, sim)
        self._power = (0.0, 0.0)  # (friction, damping) [W] at the last accelerate()
        self._friction: np.ndarray | None = None  # (n, k) friction torque per N, this step
        self.baumgarte, self.integrator = sim.baumgarte, sim.integrator
        self.unilateral, self.release_tol = sim.unilateral, sim.release_tol
        self.touch_tol = touch_tol
        effort = robot.effort_limits
        #: (n,) effort limits the plant enforces [N·m or N] (+inf: none), or None
        self.effort: np.ndarray | None = (
            effort if sim.torque_limits and bool(np.isfinite(effort).any()) else None
        )
        #: the torque applied at the last accelerate() when it saturated, else None
        #: (then the applied torque is the command u0 + B f itself)
        self.applied: np.ndarray | None = None
        self.in_contact = self.ever_in_contact = False
        self.events: list[Event] = []
        k, n = constraint.k, robot.nv
        # the dynamics' data: robot.terms fills M (crba) that the solver then factorises
        self.data = robot.new_data()
        self._solver = ConstrainedDynamics(robot.model, self.data, k)
        self._terms = RobotTerms.zeros(n)
        self._cons = ConstraintTerms.zeros(k, n)
        self._gamma = np.zeros(k)
        self._zeros_k = np.zeros(k)
        # geometry helpers' own data (projection, distances)
        self._geo = robot.new_data()
        self._tip = self._geo.oMf[robot.tip_id].translation  # a view, updated in place
        # two (q, v) pairs for the compiled contact step: its output is never its input
        self._pairs = ((np.zeros(n), np.zeros(n)), (np.zeros(n), np.zeros(n)))
        self._tmp = (np.zeros(n), np.zeros(n))
        self._grad = np.zeros(3)
        self._row = np.zeros((1, n))  # the compiled step's constraint row
        self._diag = np.diag_indices(n)
        self._imp = robot.new_data()  # the velocity correction's own data (its crba)
        self._compiled_step = (
            self._compiles and k == 1 and robot.euclidean and sim.integrator == "euler"
        )

    # ------------------------------------------------------------------ one step
    def evaluate(self, q: np.ndarray, v: np.ndarray) -> tuple[RobotTerms, ConstraintTerms | None]:
        """The arm's terms at (q, v) and the constraint rows, None where they are undefined
        off the surface (e.g. the tip on a cylinder's axis).

        Raises:
            SurfaceError: the rows are undefined while in contact.
        """
        terms = self.robot.terms(q, v, self.data, out=self._terms)
        if self._dissipates:  # pin.forwardDynamics reads data.M, which crba just filled
            self._joints_at(v, self.data.M)
        return terms, self._rows_or_none(terms, v)

    def _rows_or_none(self, terms: RobotTerms, v: np.ndarray) -> ConstraintTerms | None:
        try:
            return self._constraint_terms(terms, v)
        except SurfaceError:
            if self.in_contact:
                raise
            return None

    def _constraint_terms(self, terms: RobotTerms, v: np.ndarray) -> ConstraintTerms:
        return self.constraint.evaluate(terms, v, out=self._cons)

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

    def accelerate(
        self, terms: RobotTerms, cons: ConstraintTerms | None, cmd: Command, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """q̈ (n,) and the contact force f (k,) [N] under the applied torque sat(u0 + B f);
        releases the contact (an event at t [s]) when the surface would have to pull.
        :attr:`applied` is the saturated torque when a limit acted, else None."""
        self.applied = None
        self._friction = None
        if self.compliant:
            return self._compliant(terms, cons, cmd, t)
        if not self.in_contact:
            return self._free(terms, cmd), self._zeros_k
        assert cons is not None  # in contact, evaluate() raised instead
        if self.contact.friction > 0.0:
            self._friction, speed = self._friction_matrix(terms)
        ddq, f = self._constrained(terms, cons, cmd)
        if self.effort is not None:
            ddq, f = self._saturated(terms, cons, cmd, ddq, f)
        # f[0]: one surface, without numpy's reduction overhead (a few µs per step)
        if self.unilateral and float(f[0] if f.shape[0] == 1 else f.min()) < -self.release_tol:
            self.events.append(Release(t, float(f.min())))
            self.in_contact = False
            self.applied = None  # the contact's saturated torque no longer applies
            self._friction = None
            return self._free(terms, cmd), self._zeros_k
        if self._friction is not None:
            c = self.contact
            self._power = (friction_power(c.friction, c.friction_velocity, f, speed), 0.0)
            self._friction = None
        return ddq, f

    def _friction_matrix(self, terms: RobotTerms) -> tuple[np.ndarray, np.ndarray]:
        """(n, k) friction torque per newton of normal force and (k,) sliding speeds [m/s]."""
        normals = np.array([s.normal(terms.p) for s in self.constraint.surfaces])
        c = self.contact
        return friction_matrix(c.friction, c.friction_velocity, normals, terms.J, terms.pdot)

    def _loop_B(self, B: np.ndarray | None) -> np.ndarray | None:
        """The loop's B with this step's friction torque per newton added, if any."""
        if self._friction is None:
            return B
        return self._friction if B is None else B + self._friction

    def _compliant(
        self, terms: RobotTerms, cons: ConstraintTerms | None, cmd: Command, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """q̈ and the Hunt–Crossley force (class docstring); touch and release events."""
        if cons is None:  # rows undefined off the surface (evaluate() raised if in contact)
            return self._free(terms, cmd), self._zeros_k
        penetration, rate = -cons.distance, -cons.rate  # "tip" rows: A v = ḋ [m/s]
        touching = float(penetration.max()) > -self.GEOMETRIC_TOL
        if touching != self.in_contact:
            if touching:
                self.events.append(Touch(t, float(rate.max())))
            else:
                self.events.append(Release(t, 0.0))
            self.in_contact = touching
            self.ever_in_contact |= touching
        if not touching:
            return self._free(terms, cmd), self._zeros_k
        c = self.contact
        f = compliant_force(c, penetration, rate)
        tau = self._clipped(cmd.u0 if cmd.B is None else cmd.u0 + cmd.B @ f) + cons.A.T @ f
        friction = 0.0
        if c.friction > 0.0:
            F, speed = self._friction_matrix(terms)
            tau = tau + F @ f
            friction = friction_power(c.friction, c.friction_velocity, f, speed)
        spring = c.stiffness * np.maximum(penetration, 0.0) ** c.exponent
        self._power = (friction, float((f - spring) @ rate))  # damping: (f − kδⁿ) δ̇ ≥ 0
        return free_acceleration(self._M(terms), self._nle(terms), tau), f

    def _free(self, terms: RobotTerms, cmd: Command) -> np.ndarray:
        return free_acceleration(self._M(terms), self._nle(terms), self._clipped(cmd.u0))

    def _clipped(self, u: np.ndarray) -> np.ndarray:
        """The motor torque u (n,) clipped at the effort limits; :attr:`applied` set if it was."""
        if self.effort is not None and bool(np.any(np.abs(u) > self.effort)):
            u = self.applied = np.clip(u, -self.effort, self.effort)
        return u

    def _saturated(
        self,
        terms: RobotTerms,
        cons: ConstraintTerms,
        cmd: Command,
        ddq: np.ndarray,
        f: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """q̈ and f under τ = sat(u0 + B f): the consistent held set (class docstring,
        :mod:`hybrid_force.sim.saturation`), then one solve with it held."""
        effort = self.effort
        assert effort is not None
        u = cmd.u0 if cmd.B is None else cmd.u0 + cmd.B @ f
        over = np.abs(u) > effort
        if not over.any():  # the cheap path: nothing to hold, q̈ and f as solved
            return ddq, f
        if cmd.B is None:  # u does not depend on f: the joints beyond are the held set
            signs = np.sign(u) * over
        else:
            # f(τ) = f̄ − W τ about the unsaturated solution (f at the torque τ = u)
            W = self._force_per_torque(terms, cons)
            pull = -self.release_tol if self.unilateral else -np.inf
            signs, _ = held_set(cmd.u0, cmd.B, f + W @ u, W, effort, pull)
        held = signs != 0
        u0 = cmd.u0.copy()
        u0[held] = signs[held] * effort[held]
        B = None
        if cmd.B is not None:
            B = cmd.B.copy()
            B[held] = 0.0
        ddq, f = self._constrained(terms, cons, Command(u0, B))
        self.applied = u0 if B is None else u0 + B @ f
        return ddq.copy(), f.copy()

    def _force_per_torque(self, terms: RobotTerms, cons: ConstraintTerms) -> np.ndarray:
        """W (k, n) [N per N·m]: f(τ) = f̄ − W τ, W = (A M⁻¹ (Aᵀ + F))⁻¹ A M⁻¹ (eq. 2 with
        the contact's friction torque F f; M at the step's q, with the joints' implicit
        damping if any: the matrix the solve uses)."""
        A = cons.A
        AMinv = np.linalg.solve(self._M(terms), A.T).T  # M symmetric: (M⁻¹ Aᵀ)ᵀ = A M⁻¹
        rows = A.T if self._friction is None else A.T + self._friction
        return np.linalg.solve(AMinv @ rows, AMinv)

    def _constrained(
        self, terms: RobotTerms, cons: ConstraintTerms, cmd: Command
    ) -> tuple[np.ndarray, np.ndarray]:
        b = self.baumgarte
        gamma = b.gamma_into(cons.drift, cons.rate, cons.phi, cons.scale, self._gamma)
        return self._solver.solve(self._nle(terms), cmd.u0, self._loop_B(cmd.B), cons.A, gamma)

    def advance(
        self,
        q: np.ndarray,
        v: np.ndarray,
        ddq: np.ndarray,
        cmd: Command,
        t: float,
        dt: float,
        distance: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) at t + dt from q̈ at t; ``distance`` (k,) [m]: the tip's distances at t.

        In contact the tip is put back on the surface; out of contact, a step that crosses
        the surface, or ends within ``touch_tol`` still closing in, touches it (an impact).
        The arrays returned may be the plant's own buffers: the next call may reuse them.
        A compliant contact is integrated as the free arm (its force is in q̈ already).
        """
        if self._power != (0.0, 0.0):  # the step's dissipation, at the step's start forces
            self.friction_energy += self._power[0] * dt
            self.damping_energy += self._power[1] * dt
            self._power = (0.0, 0.0)
        if self._joint_coef is not None:  # the joints' dissipation over the step
            # the torque −(d + c) w acts with w = v + h q̈ (h = dt: the step's end velocity,
            # whose displacement w dt the step makes; h = 0, RK4: the start's)
            d, c = self._joint_coef
            w = v + self._implicit_dt * ddq
            w2 = w * w
            self.joint_damping_energy += float(d @ w2) * dt
            self.joint_friction_energy += float(c @ w2) * dt
            self._joint_coef = self._joint_Dv = None
        if self.compliant:
            v = v + ddq * dt
            return pin.integrate(self.robot.model, q, v * dt), v
        if self.in_contact and self._compiled_step:
            return self._contact_step(q, v, ddq, dt)
        if self.applied is not None:  # RK4's stages hold the torque applied at t
            cmd = Command(self.applied, None)
        model = self.robot.model
        if self.integrator == "euler":
            v = v + ddq * dt
            q_new = pin.integrate(model, q, v * dt)
        else:
            q_new, v = self._rk4(cmd, q, v, ddq, dt)
        if self.in_contact:
            return self.project(q_new, v)
        d_new, d_old = float(self.distance(q_new).max()), float(distance.max())
        if d_new < 0.0 or (d_new <= self.touch_tol and d_new <= d_old):
            # crossed the surface, or within the tolerance and still closing in
            q_new = _crossing(model, q, q_new, d_old, d_new)
            q_new, v = self.touch(q_new, v, t + dt)
        return q_new, v

    def touch(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Place the tip on the surface and apply a plastic impact if it moves into it (a
        compliant contact: place it there, v unchanged; its force does the rest)."""
        q, _ = self.project(q, np.zeros_like(v), iterations=3)
        if self.compliant:
            self.in_contact = self.ever_in_contact = True
            return q, v
        A, _ = self._rows(q)
        speed = A @ v
        if float(speed.min()) < 0.0:
            v, impulse = plastic_impact(self.robot.model, self.robot.new_data(), q, v, A)
            self.events.append(Impact(t, float(np.abs(impulse).sum()), float(-speed.min())))
        self.in_contact = self.ever_in_contact = True
        return q, v

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

    def _contact_step(
        self, q: np.ndarray, v: np.ndarray, ddq: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Semi-implicit Euler then :meth:`project`, for one surface and a Euclidean arm:
        two compiled calls (:func:`~hybrid_force.sim._kernels.euler_step`, ``project_one``)
        and the impulse in ``pin.impulseDynamics``."""
        model, data, fid = self.robot.model, self._geo, self.robot.tip_id
        q_tmp, v_tmp = self._tmp
        _K.euler_step(q, v, ddq, dt, v_tmp, q_tmp)
        pin.computeJointJacobians(model, data, q_tmp)
        pin.updateFramePlacement(model, data, fid)
        surface = self.constraint.surfaces[0]
        desc, grad, phi = surface._descriptor, self._grad, 0.0
        if desc.shape[0] == 0:  # no closed form: evaluate in Python
            phi, grad, _ = surface.evaluate(self._tip)
        q_out, v_out = self._pairs[0] if q is not self._pairs[0][0] else self._pairs[1]
        J6 = pin.getFrameJacobian(model, data, fid, _LWA)
        row = self._row
        gn = _K.project_one(desc, self._tip, grad, phi, J6, q_tmp, q_out, row[0])
        if not gn >= _GRAD_TOL:
            self._rows(q_tmp)  # raises the precise SurfaceError
        v_out[:] = pin.impulseDynamics(model, self._imp, q_out, v_tmp, row, 0.0, 0.0)
        return q_out, v_out

    def _rk4(
        self, cmd: Command, q: np.ndarray, v: np.ndarray, a1: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """One RK4 step with the command (u0, B) held; a1: (n,) q̈ already solved at (q, v)."""
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
            ddq, _ = constrained_acceleration(model, data, nle, cmd.u0, cmd.B, cons.A, gamma)
            return ddq

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


class ReferencePlant(Plant):
    """:class:`Plant` in readable numpy: every robot term from its own Pinocchio call, the
    general k-row constraint algebra and a dense solve of the KKT system
    (:func:`~hybrid_force.sim.dynamics.kkt_reference`) instead of ``pin.forwardDynamics``."""

    _compiles = False

    def evaluate(self, q: np.ndarray, v: np.ndarray) -> tuple[RobotTerms, ConstraintTerms | None]:
        terms = reference_terms(self.robot, q, v)
        self._joints_at(v, None)  # the dense solves read _M(terms)
        return terms, self._rows_or_none(terms, v)

    def _constraint_terms(self, terms: RobotTerms, v: np.ndarray) -> ConstraintTerms:
        return self.constraint.evaluate_reference(terms, v)

    def _impulse(self, q: np.ndarray, v: np.ndarray, A: np.ndarray) -> np.ndarray:
        """:meth:`Plant._impulse` by its formula, with dense solves."""
        M = pin.crba(self.robot.model, self._imp, q)
        M = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle
        X = np.linalg.solve(M, A.T)
        return v - X @ np.linalg.solve(A @ X, A @ v)

    def _constrained(
        self, terms: RobotTerms, cons: ConstraintTerms, cmd: Command
    ) -> tuple[np.ndarray, np.ndarray]:
        gamma = self.baumgarte.gamma(cons.drift, cons.rate, cons.phi / cons.scale)
        return kkt_reference(
            self._M(terms), self._nle(terms), cmd.u0, self._loop_B(cmd.B), cons.A, gamma
        )


def _joint_of(model: pin.Model, iv: int) -> str:
    """The name of the joint that owns velocity index iv."""
    for j in range(1, model.njoints):
        start = model.joints[j].idx_v
        if start <= iv < start + model.joints[j].nv:
            return str(model.names[j])
    return f"#{iv}"


def _crossing(model: pin.Model, q0: np.ndarray, q1: np.ndarray, d0: float, d1: float) -> np.ndarray:
    """Configuration where the distance crosses 0 between q0 (d0 > 0) and q1 (d1 ≤ 0), linearly."""
    if d1 >= 0 or d0 <= d1:
        return q1
    tau = d0 / (d0 - d1)
    return pin.interpolate(model, q0, q1, tau)

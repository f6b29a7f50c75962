"""The rigid contact (the paper's): the force is the constraint's multiplier, the tip stays on
the surface, touching it is a plastic impact.

One step of :class:`RigidContact`, on the arm of :class:`~hybrid_force.sim.arm.Arm`:

* :meth:`RigidContact.accelerate`, one of four paths, in this order:

  1. **free**: off the surface, q̈ = M⁻¹(sat(u0) − C q̇ − g), f = 0;
  2. **constrained**: on it, q̈ and f together from the constrained dynamics (section 6.2,
     eq. 2; :class:`~hybrid_force.sim.dynamics.ConstrainedDynamics`) with the algebraic loop
     u = u0 + B f resolved exactly, the friction torque F f
     (:func:`~hybrid_force.sim.contact.friction_matrix`) added to B so that the normal force
     and its friction are solved together;
  3. **saturated**: when the command u0 + B f of path 2 is beyond an effort limit, the
     consistent set of held joints (:func:`~hybrid_force.sim.saturation.held_set`) and one
     solve with them held;
  4. **released**: when the surface would have to pull (f < −``release_tol``, unilateral
     contact), the contact ends and the step is path 1.

* :meth:`RigidContact.advance`: the arm's integrator; on the surface, post-stabilisation (one
  Gauss–Newton step puts the tip back on it, a plastic constraint impulse through M⁻¹Aᵀ puts
  the velocity on its tangent space: :meth:`Arm.project <hybrid_force.sim.arm.Arm.project>`),
  for one surface and a Euclidean arm with Euler in two compiled calls
  (:func:`~hybrid_force.sim._kernels.euler_step`, ``project_one``); off it, a crossing of the
  surface between two steps, or a tip within ``touch_tol`` still closing in, touches it.
* :meth:`RigidContact.touch`: the tip placed on the surface and a plastic impact
  (A q̇⁺ = 0, :func:`~hybrid_force.sim.dynamics.plastic_impact`) if it moves into it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.control.constraint import _GRAD_TOL, ConstraintTerms
from hybrid_force.control.laws.base import Command
from hybrid_force.events import Impact, Release
from hybrid_force.model.robot import LWA as _LWA
from hybrid_force.model.robot import RobotTerms
from hybrid_force.sim.arm import Arm, State, SurfaceContact, Vector
from hybrid_force.sim.contact import friction_power
from hybrid_force.sim.dynamics import ConstrainedDynamics, plastic_impact
from hybrid_force.sim.saturation import held_set
from hybrid_force.sim.settings import SimSettings

_K = LazyKernels("hybrid_force.sim._kernels")

__all__ = ["RigidContact"]

# entries of the contact step's buffer before its arrays (_kernels.STEP_HEADER)
_STEP_HEADER = 5


class RigidContact(SurfaceContact):
    """The rigid contact of one arm (module docstring: its paths).

    Args:
        arm: the plant's arm, whose contact state this contact sets.
        sim: the settings it reads: ``unilateral`` and ``release_tol`` (release when the
            surface would pull, f < −release_tol [N]) and ``integrator``.
        touch_tol: [m] a tip that ends a step within this distance of the surface, still
            closing in, touches it.
    """

    #: the Euler step with projection in compiled calls, where it applies
    compiles = True

    def __init__(self, arm: Arm, sim: SimSettings, touch_tol: float) -> None:
        super().__init__(arm)
        self.unilateral, self.release_tol = sim.unilateral, sim.release_tol
        self.touch_tol = touch_tol
        robot, k, n = arm.robot, arm.constraint.k, arm.robot.nv
        # the constrained solve of accelerate() in two compiled calls around forwardDynamics
        # (ConstrainedDynamics.solve_checked), γ's gains and the limits held in its buffer
        self._solver = ConstrainedDynamics(robot.model, arm.data, k, sim.baumgarte, arm.effort)
        self._friction: np.ndarray | None = None  # (n, k) friction torque per N, this step
        self._gamma = self._solver.gamma
        self._no_B = np.zeros((n, 0))  # B of a command that does not depend on f
        self._compiled_step = (
            self.compiles and k == 1 and robot.euclidean and sim.integrator == "euler"
        )
        # what the compiled contact step reads, looked up once (a surface's descriptor is
        # fixed when it is made)
        surface = arm.constraint.surfaces[0]
        self._step_args = (robot.model, arm._geo, arm._imp, robot.tip_id, arm._tip, surface)
        # the compiled contact step's buffer (_kernels.step_parts): its two calls take it as
        # one argument (Numba's call costs ~0.14 µs per array argument); the surface's
        # descriptor copied in once. Two q outputs: the step's output is never its input (its
        # velocity is impulseDynamics' new array)
        desc = surface._descriptor
        o = _STEP_HEADER
        ws = np.zeros(o + 5 * n + desc.shape[0])
        ws[0] = desc.shape[0]
        ws[o + 5 * n :] = desc
        self._ws, self._no_desc = ws, desc.shape[0] == 0
        # the contact step's two kernels, bound at its first call (hybrid_force._jit.entry)
        self._euler: Callable[..., None] | None = None
        self._project: Callable[..., float] | None = None
        self._given = (ws[1:2], ws[2:5])  # Φ and ∇Φ of a surface without a descriptor
        self._tmp = (ws[o : o + n], ws[o + n : o + 2 * n])  # q_tmp, v_tmp
        self._q_out = (ws[o + 2 * n : o + 3 * n], ws[o + 3 * n : o + 4 * n])
        self._row = ws[o + 4 * n : o + 5 * n].reshape(1, n)  # the step's constraint row
        self._one = k == 1
        self._rubs = arm.contact.friction > 0.0  # the tip's friction (arm.contact is fixed)
        # the step dissipates only through the tip's friction and the joints' own damping and
        # friction (Arm.account has nothing to add otherwise)
        self._accounts = self._rubs or arm._dissipates

    # ------------------------------------------------------------------ accelerate
    def accelerate(
        self, terms: RobotTerms, cons: ConstraintTerms | None, cmd: Command, t: float
    ) -> State:
        """Free, constrained, saturated or released (module docstring)."""
        arm = self.arm
        arm.applied = None
        self._friction = None
        if not arm.in_contact:  # 1. free
            return arm.free(terms, cmd.u0), arm._zeros_k
        assert cons is not None  # in contact, evaluate() raised instead
        if self._rubs:
            self._friction, speed = arm.friction_at(terms)
        if self.compiles and self._friction is None:
            # 2. constrained, the limits checked in the same compiled call
            Dv, B, solver = arm._joint_Dv, cmd.B, self._solver
            if solver.limits is not arm.effort:  # the arm's limits were replaced
                solver.set_limits(arm.effort)
            beyond = solver.solve_checked(
                terms.nle if Dv is None else terms.nle + Dv,  # Arm._nle
                cmd.u0, self._no_B if B is None else B, cons,
            )  # fmt: skip
            ddq, f = solver.ddq, solver.f
        else:  # with friction in the loop's B (the limits bound the command's), or readable
            ddq, f = self._constrained(terms, cons, cmd)
            beyond = arm.effort is not None and bool(
                _K.exceeds_effort(cmd.u0, self._no_B if cmd.B is None else cmd.B, f, arm.effort)
            )
        if beyond:  # 3. saturated: some limit reached
            ddq, f = self._saturated(terms, cons, cmd, ddq, f)
        # 4. released; f[0]: one surface, without numpy's reduction overhead (µs per step)
        if self.unilateral and (f[0] if self._one else f.min()) < -self.release_tol:
            arm.events.append(Release(t, float(f.min())))
            arm.in_contact = False
            arm.applied = None  # the contact's saturated torque no longer applies
            self._friction = None
            return arm.free(terms, cmd.u0), arm._zeros_k
        if self._friction is not None:
            c = arm.contact
            arm._power = (friction_power(c.friction, c.friction_velocity, f, speed), 0.0)
            self._friction = None
        return ddq, f

    def _constrained(
        self, terms: RobotTerms, cons: ConstraintTerms, cmd: Command
    ) -> tuple[np.ndarray, np.ndarray]:
        """q̈ and f of the constrained dynamics under u = u0 + B f (B with this step's
        friction torque per newton, if any)."""
        arm = self.arm
        gamma = arm.baumgarte.gamma_into(cons.drift, cons.rate, cons.phi, cons.scale, self._gamma)
        return self._solver.solve(arm._nle(terms), cmd.u0, self._loop_B(cmd.B), cons.A, gamma)

    def _loop_B(self, B: np.ndarray | None) -> np.ndarray | None:
        """The loop's B with this step's friction torque per newton added, if any."""
        if self._friction is None:
            return B
        return self._friction if B is None else B + self._friction

    def _saturated(
        self,
        terms: RobotTerms,
        cons: ConstraintTerms,
        cmd: Command,
        ddq: np.ndarray,
        f: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """q̈ and f under τ = sat(u0 + B f): the consistent held set
        (:mod:`hybrid_force.sim.saturation`), then one solve with it held. Called when the
        compiled test (``exceeds_effort``) found the command u0 + B f beyond a limit."""
        arm = self.arm
        effort = arm.effort
        assert effort is not None
        u = cmd.u0 if cmd.B is None else cmd.u0 + cmd.B @ f
        over = np.abs(u) > effort
        if not over.any():  # beyond only in the kernel's rounding of u (k > 1)
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
        arm.applied = u0 if B is None else u0 + B @ f
        return ddq.copy(), f.copy()

    def _force_per_torque(self, terms: RobotTerms, cons: ConstraintTerms) -> np.ndarray:
        """W (k, n) [N per N·m]: f(τ) = f̄ − W τ, W = (A M⁻¹ (Aᵀ + F))⁻¹ A M⁻¹ (eq. 2 with
        the contact's friction torque F f; M at the step's q, with the joints' implicit
        damping if any: the matrix the solve uses)."""
        A = cons.A
        AMinv = np.linalg.solve(self.arm._M(terms), A.T).T  # M symmetric: (M⁻¹ Aᵀ)ᵀ = A M⁻¹
        rows = A.T if self._friction is None else A.T + self._friction
        return np.linalg.solve(AMinv @ rows, AMinv)

    # ------------------------------------------------------------------ advance
    def advance(
        self, q: Vector, v: Vector, ddq: Vector, cmd: Command, t: float, dt: float, distance: Vector
    ) -> State:
        """The arm's integrator, then on the surface the projection, off it a touch
        (module docstring)."""
        arm = self.arm
        if self._accounts:
            arm.account(v, ddq, dt)
        if arm.in_contact and self._compiled_step:
            return self._contact_step(q, v, ddq, dt)
        if arm.applied is not None:  # RK4's stages hold the torque applied at t
            cmd = Command(arm.applied, None)
        q_new, v = arm.integrate(q, v, ddq, cmd, dt)
        if arm.in_contact:
            return arm.project(q_new, v)
        d_new, d_old = float(arm.distance(q_new).max()), float(distance.max())
        if d_new < 0.0 or (d_new <= self.touch_tol and d_new <= d_old):
            # crossed the surface, or within the tolerance and still closing in
            q_new = _crossing(arm.robot.model, q, q_new, d_old, d_new)
            q_new, v = self.touch(q_new, v, t + dt)
        return q_new, v

    def _contact_step(
        self, q: np.ndarray, v: np.ndarray, ddq: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Semi-implicit Euler then :meth:`Arm.project <hybrid_force.sim.arm.Arm.project>`,
        for one surface and a Euclidean arm: two compiled calls and the impulse in
        ``pin.impulseDynamics``."""
        model, data, imp, fid, tip, surface = self._step_args
        ws = self._ws
        q_tmp, v_tmp = self._tmp
        euler, project = self._euler, self._project
        if euler is None:  # (n,) states, the solver's q̈, this buffer
            euler = self._euler = entry(_K.euler_step, q, v, ddq, float(dt), ws)
        euler(q, v, ddq, dt, ws)
        pin.computeJointJacobians(model, data, q_tmp)
        pin.updateFramePlacement(model, data, fid)  # the tip, in the view ``tip``
        if self._no_desc:  # no closed form: evaluate in Python, into the buffer
            phi_given, grad_given = self._given
            phi_given[0], grad_given[:], _ = surface.evaluate(tip)
        slot = 1 if q is self._q_out[0] else 0
        J = pin.getFrameJacobian(model, data, fid, _LWA)
        if project is None:  # the view of the tip, Pinocchio's (6, n) Jacobian
            project = self._project = entry(_K.project_one, tip, J, ws, slot)
        gn = project(tip, J, ws, slot)
        if not gn >= _GRAD_TOL:
            self.arm._rows(q_tmp)  # raises the precise SurfaceError
        # v⁺: impulseDynamics' own new array (the next step reads it, never writes it)
        q_out = self._q_out[slot]
        return q_out, pin.impulseDynamics(model, imp, q_out, v_tmp, self._row, 0.0, 0.0)

    def touch(self, q: Vector, v: Vector, t: float) -> State:
        """A plastic impact if the tip moves into the surface (an "impact" event)."""
        arm = self.arm
        q, _ = arm.project(q, np.zeros_like(v), iterations=3)
        A, _ = arm._rows(q)
        speed = A @ v
        if float(speed.min()) < 0.0:
            v, impulse = plastic_impact(arm.robot.model, arm.robot.new_data(), q, v, A)
            arm.events.append(Impact(t, float(np.abs(impulse).sum()), float(-speed.min())))
        arm.in_contact = arm.ever_in_contact = True
        return q, v


def _crossing(model: pin.Model, q0: np.ndarray, q1: np.ndarray, d0: float, d1: float) -> np.ndarray:
    """Configuration where the distance crosses 0 between q0 (d0 > 0) and q1 (d1 ≤ 0), linearly."""
    if d1 >= 0 or d0 <= d1:
        return q1
    tau = d0 / (d0 - d1)
    return pin.interpolate(model, q0, q1, tau)

"""The desired joint path for a tip position and a tool direction: eq. 27 extended to a pose.

The paper's CLIK (eq. 27, :mod:`hybrid_force.control.clik`) drives the tip position k(q_d) to
p_d(t). With ``[tool] orientation = "normal"`` the tool axis a(q) = R(q) â (â the axis in the
tip frame, R the tip's rotation) must also follow a_d(t) (:mod:`hybrid_force.control.tool`).

**Task.** The tip's angular velocity is ω = J_ω q̇ (J_ω the angular rows of the world-aligned
frame Jacobian), and ȧ = ω × a: only ω across a moves the axis. With ĉ₁, ĉ₂ unit vectors of
the tip frame completing â to an orthonormal basis, S = [ĉ₁ᵀ; ĉ₂ᵀ] Rᵀ (2×3: the world
directions c_i = R ĉ_i as rows) selects those two components. The task (m rows) is

    A q̇_d = y,   A = [J_p; S J_ω],   y = [ṗ_d − γ (k(q_d) − p_d); S w],   w = ω_d + γ e

* roll free, m = 5: e = a × a_d (the axis error on SO(3): |e| = sin of the angle, along the
  axis of the shortest rotation from a to a_d; no Euler angles) and ω_d = a_d × ȧ_d (the
  angular velocity of a_d across itself). Along the solution, d(a·a_d)/dt = γ ‖a × a_d‖²:
  the angle θ obeys θ̇ = −γ sin θ, and a = a_d is kept exactly (ω_d × a_d = ȧ_d);
* roll held, m = 6: S = I and e = ½ Σ r_i × r_di (r_i, r_di the columns of R and R_d: the
  rotation vector of R_d Rᵀ to first order, exact at zero), ω_d the angular velocity of R_d.

**Solution.** q̇_d = A⁺ y + N z with the damped pseudo-inverse A⁺ = Aᵀ W, W = (AAᵀ + λ²I)⁻¹,
and for n > m the null-space posture term N z, N = I − A⁺A, z = −k_n (q_d − q_posture). The
rotation about the axis (roll free) is in that null space.

**Acceleration.** q̈_d is the exact time derivative of q̇_d along q̇ = q̇_d:

    q̈_d = Ȧ⁺ y + A⁺ ẏ + Ṅ z + N ż,   Ȧ⁺ = ȦᵀW + AᵀẆ,   Ẇ = −W(ȦAᵀ + AȦᵀ)W,
    Ṅ = −(Ȧ⁺A + A⁺Ȧ),   ż = −k_n q̇_d,

with ω = J_ω q̇_d, Ṡ = −S[ω]× (Ṙ = [ω]× R), so Ȧ = [J̇_p; S J̇_ω − S[ω]× J_ω] and
ẏ = [p̈_d − γ (J_p q̇_d − ṗ_d); S ẇ − S[ω]× w], ẇ = ω̇_d + γ ė with
ė = (ω × a) × a_d + a × ȧ_d (roll free; ω̇_d = a_d × ä_d) or
ė = ½ Σ ((ω × r_i) × r_di + r_i × (ω_d × r_di)) (roll held; S = I, Ṡ = 0).
ȧ_d and ä_d need ∇²Φ and p̈_d (:mod:`hybrid_force.control.tool`).

**Integration.** As :class:`~hybrid_force.control.clik.DesiredJointPath`: each step predicts
q_d(t + dt) by a second-order Taylor step and corrects it with one Newton step on the task
residual [p_d − k(q_d); S e] (the pseudo-inverse of the previous step), so position and axis
stay on their targets to round-off and q̇_d is the CLIK's own velocity. The algebra of a step
is compiled (:mod:`hybrid_force.control._pose_kernels`); ``tests/oracles/control.py`` holds
its numpy oracle.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin

from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.control.clik import _COND_MAX, ClikSettings, StepClock, desired_views
from hybrid_force.control.tool import ToolTarget, axis_angle, cross3
from hybrid_force.errors import ReachError
from hybrid_force.geometry.paths import Path
from hybrid_force.model.robot import LWA, Robot

__all__ = ["PoseJointPath", "follow_pose", "pose_inverse_kinematics"]

_K = LazyKernels("hybrid_force.control._kernels")
_PK = LazyKernels("hybrid_force.control._pose_kernels")

_START_TOL = 1e-9  # [m, rad] accepted start residual of position and axis


def _complement(axis: np.ndarray) -> np.ndarray:
    """(2, 3) rows ĉ₁, ĉ₂: with the unit axis, a right-handed orthonormal basis."""
    ref = np.eye(3)[int(np.argmin(np.abs(axis)))]
    c1 = cross3(axis, ref)
    c1 /= np.linalg.norm(c1)
    return np.array([c1, cross3(axis, c1)])


def _orientation_error(R: np.ndarray, R_d: np.ndarray) -> np.ndarray:
    """e = ½ Σ r_i × r_di (3,): the rotation vector of R_d Rᵀ to first order.

    Σ a_i × b_i = vee(B Aᵀ − A Bᵀ) for the columns a_i, b_i of A, B ([a × b]× = b aᵀ − a bᵀ).
    """
    M = R_d @ R.T
    return 0.5 * np.array((M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]))


class _PoseTask:
    """The rows of the pose task at one configuration: A, S and the error e (module docstring)."""

    def __init__(self, robot: Robot, target: ToolTarget, held: bool | None = None) -> None:
        self.robot = robot
        self.held = target.settings.roll == "held" if held is None else held
        self.m = 6 if self.held else 5
        self.axis = np.array(target.settings.axis)
        self.C = _complement(self.axis)

    def kinematics(
        self, data: pin.Data, q: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p (3,), R (3, 3), J (6, n) world-aligned) of the tip at q (fills ``data``)."""
        model, fid = self.robot.model, self.robot.tip_id
        pin.computeJointJacobians(model, data, q)
        M = pin.updateFramePlacement(model, data, fid)
        return M.translation.copy(), M.rotation.copy(), pin.getFrameJacobian(model, data, fid, LWA)

    def selector(self, R: np.ndarray) -> np.ndarray:
        """S: (2, 3) the world directions across the axis (roll free), or I (roll held)."""
        return np.eye(3) if self.held else self.C @ R.T

    def error(self, R: np.ndarray, a_d: np.ndarray, R_d: np.ndarray | None) -> np.ndarray:
        """e (3,): a × a_d (roll free) or ½ Σ r_i × r_di (roll held)."""
        if R_d is not None:
            return _orientation_error(R, R_d)
        return cross3(R @ self.axis, a_d)

    def rows(self, J: np.ndarray, S: np.ndarray) -> np.ndarray:
        """A (m, n) = [J_p; S J_ω]."""
        return np.vstack([J[:3], S @ J[3:]])


def pose_inverse_kinematics(
    robot: Robot,
    target: ToolTarget,
    t: float,
    seed: np.ndarray,
    *,
    position: np.ndarray | None = None,
    tol: float = 1e-12,
    max_iter: int = 200,
) -> np.ndarray:
    """q (nq,) with the tip at p_d(t) (or ``position``) and the tool axis along a_d(t).

    Damped Newton (Levenberg–Marquardt) iterations on the 5-row residual [p − k(q); S (a × a_d)]
    from ``seed``; the rotation about the axis stays near the seed's (minimal-norm steps).

    Raises:
        ReachError: the iterations do not converge (out of reach from the seed), naming the
            target, the seed and the residual.
    """
    task = _PoseTask(robot, target, held=False)  # a held roll starts where the axis task ends
    p_t = target.path.position(t) if position is None else np.asarray(position, dtype=float)
    a_t = target.axis(t)[0]
    q, err = _pose_newton(
        task, robot.new_data(), p_t, a_t, None, np.array(seed, float), tol, max_iter
    )
    if err < tol:
        return q
    raise ReachError(
        f"tip position {np.round(p_t, 6).tolist()} with the tool axis along "
        f"{np.round(a_t, 6).tolist()} is out of reach of '{robot.name}' from seed "
        f"{np.round(seed, 4).tolist()}: Newton iterations stopped {err:.3g} away after "
        f"{max_iter} iterations"
    )


def _pose_newton(
    task: _PoseTask,
    data: pin.Data,
    p_t: np.ndarray,
    a_t: np.ndarray,
    R_t: np.ndarray | None,
    q: np.ndarray,
    tol: float,
    max_iter: int,
) -> tuple[np.ndarray, float]:
    """The iterations of :func:`pose_inverse_kinematics`: (q, ‖residual‖ [m and rad mixed])."""
    model = task.robot.model
    err = math.inf
    for _ in range(max_iter):
        p, R, J = task.kinematics(data, q)
        S = task.selector(R)
        r = np.concatenate([p_t - p, S @ task.error(R, a_t, R_t)])
        err = math.sqrt(float(r @ r))
        if err < tol:
            return q, err
        A = task.rows(J, S)
        # Levenberg–Marquardt: the damping grows with the residual so far-off seeds stay stable
        lam2 = 1e-10 + 1e-3 * err * err
        q = pin.integrate(model, q, A.T @ np.linalg.solve(A @ A.T + lam2 * np.eye(task.m), r))
    return q, err


def follow_pose(
    robot: Robot, target: ToolTarget, q: np.ndarray, times: np.ndarray, damping: float
) -> list[tuple[float, np.ndarray, np.ndarray | None]]:
    """The desired pose followed by inverse kinematics from q (the loader's path check).

    Each sample is solved from the previous one (same branch). Returns, per time, (t, q,
    singular values of A when cond(AAᵀ + λ²I) ≥ the CLIK's limit, else None); stops after
    the first singular sample. Raises ReachError where a sample is out of reach.
    """
    task = _PoseTask(robot, target)
    start = _PoseTask(robot, target, held=False)  # a held roll starts where the axis task ends
    data = robot.new_data()
    out: list[tuple[float, np.ndarray, np.ndarray | None]] = []
    smallest = math.nan  # of the pose task Jacobian at the last sample solved
    R_fix = None
    for t in times:
        t = float(t)
        a_t = target.axis(t)[0]
        R_t = None
        if task.held:
            F, _, _ = target.frame(t)
            R_t = None if R_fix is None else F @ R_fix
        solver = start if R_fix is None else task
        q, err = _pose_newton(solver, data, target.path.position(t), a_t, R_t, q, 1e-9, 50)
        if not err < 1e-9:
            near = ""
            if out:  # a branch lost between two samples: a singular configuration is close
                t_prev = out[-1][0]
                near = (
                    f" (from the configuration at t = {t_prev:.4g} s, whose pose task Jacobian "
                    f"has its smallest singular value {smallest:.3g}: a singular "
                    "configuration may lie between them)"
                )
            raise ReachError(f"the desired tool pose is out of reach at t = {t:.4g} s{near}")
        _, R, J = task.kinematics(data, q)
        if task.held and R_fix is None:
            R_fix = F.T @ R  # the roll of the start, kept relative to the travel direction
        A = task.rows(J, task.selector(R))
        sv = np.linalg.svd(A, compute_uv=False)
        smallest = float(sv[-1])
        singular = not (sv[0] ** 2 + damping**2) < _COND_MAX * (sv[-1] ** 2 + damping**2)
        out.append((t, q.copy(), sv if singular else None))
        if singular:
            break
    return out


class PoseJointPath:
    """q_d(t), q̇_d(t), q̈_d(t) for a tip path and a tool direction (module docstring).

    The interface of :class:`~hybrid_force.control.clik.DesiredJointPath` (q, qd, qdd, p_d,
    pdot_d, pddot_d, t, :meth:`advance`, :meth:`task_error`) plus a_d (3,), the desired tool
    axis now, and :meth:`axis_error`.

    Args:
        robot: the arm (n ≥ 5 joints, n ≥ 6 for a held roll).
        path: the task-space path p_d(t).
        target: the desired tool direction (:class:`~hybrid_force.control.tool.ToolTarget`).
        q0: (nq,) q_d(0), with the tip at p_d(0) and the axis along a_d(0)
            (:func:`pose_inverse_kinematics`); also the null-space posture.
        settings: the CLIK gains (γ for position and axis alike, damping λ, posture gain k_n).
        t0: start time [s].

    Raises:
        ControlError: the arm has fewer joints than the task has rows.
        ReachError: q0 is not on the start pose, or the task Jacobian is singular on the path.

    The algebra of each step is compiled (:mod:`hybrid_force.control._pose_kernels`:
    ``pose_goal`` for a_d and its jet (and R_d) from the step's path sample, as
    :meth:`ToolTarget.axis <hybrid_force.control.tool.ToolTarget.axis>` and ``frame``;
    ``pose_velocity``, ``pose_acceleration``, ``pose_newton``) and q, qd, qdd, p_d, pdot_d,
    pddot_d, a_d are updated in place: keep a copy to remember a value. The path itself (and
    a surface other than the built-in ones) is sampled in Python.
    Its readable numpy version is the oracle of ``tests/oracles/control.py``.
    """

    a_d: np.ndarray  # (3,) the desired tool axis now
    R_d: np.ndarray | None  # (3, 3) the desired rotation now (roll held), else None

    def __init__(
        self,
        robot: Robot,
        path: Path,
        target: ToolTarget,
        q0: np.ndarray,
        settings: ClikSettings | None = None,
        t0: float = 0.0,
    ) -> None:
        target.settings.check_arm(robot)
        self.robot = robot
        self.path = path
        self.target = target
        self.settings = settings or ClikSettings()
        self._task = _PoseTask(robot, target)
        self._data = robot.new_data()
        n = robot.nv
        self._redundant = n > self._task.m
        self._eye = np.eye(n)
        self.posture = robot.check_q(q0, "q_d(0)").copy()
        self.q = self.posture.copy()
        self.t = float(t0)
        self._clock = StepClock(t0)
        self._R_fix: np.ndarray | None = None
        self._start()
        self._sample()
        p, R, _ = self._task.kinematics(self._data, self.q)
        angle = axis_angle(R @ self._task.axis, self.a_d)
        if np.linalg.norm(p - self.p_d) > _START_TOL or angle > _START_TOL:
            raise ReachError(
                f"q_d(0) = {np.round(self.q, 6).tolist()} puts the tip at "
                f"{np.round(p, 6).tolist()} with the tool axis {angle:.3g} rad from a_d, not on "
                f"the start pose (p_d = {np.round(self.p_d, 6).tolist()}, a_d = "
                f"{np.round(self.a_d, 6).tolist()}); use pose_inverse_kinematics to find q_d(0)"
            )
        if self._task.held:
            F0 = self.R_d  # the frame of travel at t0 (set by _sample while R_fix is None)
            assert F0 is not None
            self._R_fix = F0.T @ R
            self._sample()
        self._update_derivatives()

    def _start(self) -> None:
        """Buffers written in place by the kernels (module ``_pose_kernels``' names)."""
        n, m, task, cfg = self.robot.nv, self._task.m, self._task, self.settings
        nq = self.robot.nq
        # q_d, q̇_d, q̈_d and the path sample as views of one flat pack, which a law's
        # steady-contact kernel takes as one argument (``control._kernels.desired_parts``)
        self._kernels: dict[str, Callable[..., Any]] = {}  # the step's kernels (_bind)
        self.desired_pack = np.zeros(nq + 2 * n + 9)
        self.q, self.qd, self.qdd, self._smp = desired_views(self.desired_pack, n, nq)
        self.q[:] = self.posture
        self.p_d, self.pdot_d, self.pddot_d = self._smp
        self._goal = np.zeros((4, 3))  # rows a_d, ȧ_d, ω_d, ω̇_d
        self._a_d = self._goal[0]  # one view: a_d is updated in place
        self._Rd = np.eye(3)
        self._eye3 = np.eye(3)
        self._desc, self._tool, self._tilt_axis, self._travel_needed = self.target.kernel_inputs()
        self._travel = np.zeros((3, 3))
        self._grad = np.zeros(3)
        self._hess = np.zeros((3, 3))
        self._third = np.zeros(3)
        self._frame = np.array([task.axis, task.C[0], task.C[1]])
        posture = self._redundant and cfg.posture_gain > 0
        self._cfg = np.array(
            [cfg.gamma, cfg.damping**2, float(posture), cfg.posture_gain, float(task.held)]
        )
        self._S = np.zeros((3, 3))
        self._A = np.zeros((m, n))
        self._Ap = np.zeros((n, m))
        self._W = np.zeros((m, m))
        self._N = np.zeros((n, n))
        self._y = np.zeros(m)
        self._w = np.zeros(3)
        self._dq_post = np.zeros(n)
        self._zeros = np.zeros(n)
        self._q_pred = np.zeros(self.robot.nq)
        self._dt_pred = 0.0  # the dt of the predictor made ahead (0: none)
        # views of the tip in self._data (updated in place by updateFramePlacement)
        tip = self._data.oMf[self.robot.tip_id]
        self._tip, self._rot = tip.translation, tip.rotation

    def _sample(self) -> None:
        """The path sample and the desired direction (and frame) at self.t, in place
        (``_pose_kernels.pose_goal``, the compiled :meth:`ToolTarget.axis` and ``frame``)."""
        smp, t = self._smp, self.t
        if self._travel_needed:
            self.path.evaluate_with_direction_into(t, smp, self._travel)
        else:
            self.path.evaluate_into(t, smp[0], smp[1], smp[2])
        if self._desc.shape[0] == 0:
            self._grad[:], self._hess[:], self._third[:] = self.target.surface_terms(smp)
        R_fix = self._R_fix if self._R_fix is not None else self._eye3
        args = (
            self._desc, smp, self._grad, self._hess, self._third, self._tilt_axis,
            self._travel, self._tool, R_fix, self._goal, self._Rd,
        )  # fmt: skip
        goal = self._kernels.get("goal") or self._bind("goal", _PK.pose_goal, args)
        status = goal(*args)
        if status:  # an undefined direction (∇Φ = 0, the lean or the held roll)
            raise self.target.undefined(status, t, smp[0])
        self.a_d = self._a_d
        self.R_d = self._Rd if self._task.held else None

    def advance(self, dt: float) -> None:
        """Move q_d, q̇_d, q̈_d to t + dt (predictor + one Newton correction); t = t0 + i·dt
        (:class:`~hybrid_force.control.clik.StepClock`), not a sum of the steps."""
        self.t = self._clock.tick(dt)
        self._advance(dt)

    def _advance(self, dt: float) -> None:
        """:meth:`advance` once t is updated: sample, predictor, Newton, derivatives."""
        robot, data = self.robot, self._data
        model, q_pred = robot.model, self._q_pred
        self._sample()
        if robot.euclidean:
            if dt != self._dt_pred:  # otherwise the last step's kernel made the predictor
                _K.taylor_step(self.q, self.qd, self.qdd, dt, q_pred)
                self._dt_pred = dt
        else:
            q_pred[:] = pin.integrate(model, self.q, self.qd * dt + self.qdd * (0.5 * dt * dt))
        pin.forwardKinematics(model, data, q_pred)
        pin.updateFramePlacement(model, data, robot.tip_id)
        args = (self._tip, self._rot, self._smp, self._goal, self._Rd, self._frame, self._cfg)
        if robot.euclidean:
            a = (*args, self._S, self._Ap, q_pred, self.q)
            (self._kernels.get("newton") or self._bind("newton", _PK.pose_newton, a))(*a)
        else:
            step = np.zeros(robot.nv)
            _PK.pose_newton(*args, self._S, self._Ap, self._zeros, step)
            self.q[:] = pin.integrate(model, q_pred, step)
        self._update_derivatives()

    def _update_derivatives(self) -> None:
        """q̇_d and q̈_d at (t, q_d), written in place (the algebra of
        the module docstring's acceleration, compiled)."""
        robot, data = self.robot, self._data
        model, fid, q = robot.model, robot.tip_id, self.q
        pin.computeJointJacobians(model, data, q)
        # getFrameJacobian(model, data, frame_id, rf) also sets data.oMf[frame_id] =
        # data.oMi[parent] · placement, the product updateFramePlacement forms (Pinocchio's
        # frames.hpp), so self._tip and self._rot are the tip's at q_d without that call
        J6 = pin.getFrameJacobian(model, data, fid, LWA)
        if self._cfg[2]:
            if robot.euclidean:
                np.subtract(q, self.posture, out=self._dq_post)
            else:
                self._dq_post[:] = pin.difference(model, self.posture, q)
        head = (self._rot, self._smp, self._goal, self._Rd, self._frame, self._cfg, self._dq_post)
        bufs = (self._S, self._A, self._Ap, self._W, self._N, self._y, self._w, self.qd)
        v_args = (J6, self._tip, *head, *bufs)
        velocity = self._kernels.get("velocity") or self._bind(
            "velocity", _PK.pose_velocity, v_args
        )
        cond = velocity(*v_args)
        if not cond < _COND_MAX:  # the cheap bound; the SVD names the values
            self._check_conditioning(self._A.copy(), q)
        pin.computeJointJacobiansTimeVariation(model, data, q, self.qd)
        Jd6 = pin.getFrameJacobianTimeVariation(model, data, fid, LWA)
        a = (J6, Jd6, *head, *bufs, q, self._dt_pred, self.qdd, self._q_pred)
        acceleration = self._kernels.get("acceleration")
        if acceleration is None:  # (for a float dt, whatever the first one was)
            b = (*a[:-3], float(a[-3]), *a[-2:])
            acceleration = self._bind("acceleration", _PK.pose_acceleration, b)
        acceleration(*a)

    def _bind(self, name: str, kernel: Callable[..., Any], args: tuple) -> Callable[..., Any]:
        """``kernel`` for the types of ``args`` (:func:`hybrid_force._jit.entry`), kept as
        ``name`` for the later calls: this object's buffers and views, Pinocchio's (6, n)
        Jacobians, a Euclidean arm's q."""
        bound = self._kernels[name] = entry(kernel, *args)
        return bound

    def _check_conditioning(self, A: np.ndarray, q: np.ndarray) -> None:
        """ReachError naming t, q_d and the singular values when cond(AAᵀ + λ²I) ≥ the limit."""
        s = np.linalg.svd(A, compute_uv=False)
        lam2 = self.settings.damping**2
        if (s[0] ** 2 + lam2) < _COND_MAX * (s[-1] ** 2 + lam2):
            return
        raise ReachError(
            f"the pose task Jacobian of '{self.robot.name}' (tip position and tool axis) is "
            f"singular on the desired path at t = {self.t:.6g} s, q_d = "
            f"{np.round(q, 6).tolist()} (singular values {s.tolist()})"
        )

    def task_error(self) -> float:
        """‖k(q_d) − p_d‖ at the current time [m]."""
        p, _, _ = self._task.kinematics(self._data, self.q)
        return float(np.linalg.norm(p - self.p_d))

    def axis_error(self) -> float:
        """The angle [rad] between the tool axis at q_d and a_d at the current time."""
        _, R, _ = self._task.kinematics(self._data, self.q)
        return axis_angle(R @ self._task.axis, self.a_d)

"""Desired joint path from a task-space path: the paper's "Newton algorithm" (eq. 27).

q̇_d = J⁻¹(q_d) [ṗ_d − γ (k(q_d) − p_d)],   γ = 7 by default (section 6.1)

solved in step with the simulation to round-off (a predictor and one Newton correction per step,
see :class:`DesiredJointPath`), because its error becomes the arm's tracking error.
q_d(0) solves k(q_d(0)) = p_d(0) by Newton iterations from a seed (:func:`inverse_kinematics`).
For arms with more than three joints J⁻¹ is a damped pseudo-inverse and a null-space term
pulls q_d towards a posture (the seed):

q̇_d = J⁺ x + (I − J⁺J)(−k_n (q_d − q_posture)),   x = ṗ_d − γ (k(q_d) − p_d).

The joint acceleration q̈_d is the exact time derivative of q̇_d, null-space part included
(see :meth:`DesiredJointPath._update_derivatives`; its numpy oracle is in
``tests/oracles/control.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from hybrid_force import _checks as checks
from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.errors import BadInputError, ControlError, ReachError
from hybrid_force.geometry.paths import Path
from hybrid_force.model.robot import LWA as _LWA
from hybrid_force.model.robot import Robot

_K = LazyKernels("hybrid_force.control._kernels")

__all__ = ["ClikSettings", "DesiredJointPath", "inverse_kinematics"]

_START_TOL = 1e-9  # [m] accepted ‖k(q_d(0)) − p_d(0)‖
_COND_MAX = 1e8  # condition number of J J^T beyond which J is treated as singular
_TARGET = "3 finite real numbers [m] (a tip position)"
_NO_DESCRIPTOR = np.zeros(0)  # "the path sample is already there" for the Newton kernel
_NO_DESCRIPTOR.flags.writeable = False  # as the paths' own descriptors: one type (entry)


@dataclass(frozen=True)
class ClikSettings:
    """Settings of the closed-loop inverse kinematics (eq. 27).

    Attributes:
        gamma: convergence gain γ > 0 [1/s] (paper: 7).
        damping: pseudo-inverse damping λ [m] for redundant arms (J⁺ = Jᵀ(JJᵀ + λ²I)⁻¹).
        posture_gain: null-space gain k_n ≥ 0 [1/s] towards the posture (redundant arms).
    """

    gamma: float = 7.0
    damping: float = 1e-6
    posture_gain: float = 1.0

    def __post_init__(self) -> None:
        """Check the gains (finite real numbers, not bools) and store them as floats.

        Raises ControlError naming the gain ("clik gamma", "damping", "posture_gain").
        """
        for name, what, strict, unit in (
            ("gamma", "clik gamma (paper eq. 27)", True, "1/s"),
            ("damping", "clik damping", False, "m"),
            ("posture_gain", "clik posture_gain", False, "1/s"),
        ):
            value = checks.number(
                getattr(self, name), what, ControlError, minimum=0.0, strict=strict, unit=unit
            )
            object.__setattr__(self, name, value)


def _check_conditioning(J: np.ndarray, t: float, q: np.ndarray, robot: Robot) -> None:
    s = np.linalg.svd(J, compute_uv=False)
    if s[-1] <= 0 or s[0] / s[-1] > np.sqrt(_COND_MAX):
        raise ReachError(
            f"the tip Jacobian of '{robot.name}' is singular on the desired path at t = {t:.6g} s, "
            f"q_d = {np.round(q, 6).tolist()} (singular values {s.tolist()})"
        )


def inverse_kinematics(
    robot: Robot,
    target: np.ndarray,
    seed: np.ndarray | None = None,
    *,
    tol: float = 1e-12,
    max_iter: int = 200,
) -> np.ndarray:
    """Joint configuration q (nq,) with p(q) = target, by damped Newton iterations.

    Args:
        robot: the arm.
        target: (3,) tip position [m].
        seed: (nq,) start of the iterations (default: the neutral configuration). The solution
            found is the one "closest" to the seed (e.g. the RTR elbow branch of the seed).
        tol: residual ‖p(q) − target‖ accepted [m].

    Raises:
        ReachError: the iterations do not converge (the point is out of reach from the seed).
        BadInputError: target or seed is not real numbers of the right size.
        ControlError: tol is not a number > 0, max_iter not an integer >= 1.
    """
    target = checks.array(target, "inverse_kinematics: target", BadInputError, valid=_TARGET)
    if target.shape != (3,):
        raise BadInputError(
            f"inverse_kinematics: target must be {_TARGET}, got shape {target.shape}"
        )
    if seed is not None:
        seed = checks.array(seed, "inverse_kinematics: seed", BadInputError, valid="nq numbers")
    what = "inverse_kinematics: tol"
    tol = checks.number(tol, what, ControlError, minimum=0, strict=True, unit="m")
    max_iter = checks.integer(max_iter, "inverse_kinematics: max_iter", ControlError, minimum=1)
    q = robot.neutral() if seed is None else robot.check_q(seed, "seed").copy()
    q, err = newton_ik(robot, robot.new_data(), target, q, tol, max_iter)
    if err < tol:
        return q
    raise ReachError(
        f"tip position {np.round(target, 6).tolist()} is out of reach of '{robot.name}' "
        f"from seed {np.round(robot.neutral() if seed is None else seed, 4).tolist()}: "
        f"Newton iterations stopped {err:.3g} m away after {max_iter} iterations"
    )


def newton_ik(
    robot: Robot, data: pin.Data, target: np.ndarray, q: np.ndarray, tol: float, max_iter: int
) -> tuple[np.ndarray, float]:
    """The iterations of :func:`inverse_kinematics` on checked inputs, with the caller's data.

    Returns:
        (q, err): the last configuration (nq,) and its residual ‖p(q) − target‖ [m]; err < tol
        means converged. Leaves ``data`` with the forward kinematics of the returned q.
    """
    model = robot.model
    eye = np.eye(3)
    err = np.inf
    for _ in range(max_iter):
        pin.forwardKinematics(model, data, q)
        p = pin.updateFramePlacement(model, data, robot.tip_id).translation
        e = target - p
        err = math.sqrt(float(e @ e))
        if err < tol:
            return q, err
        pin.computeJointJacobians(model, data, q)
        J = pin.getFrameJacobian(model, data, robot.tip_id, _LWA)[:3]
        # Levenberg–Marquardt step: damping grows with the error so far-off seeds stay stable.
        lam2 = 1e-10 + 1e-3 * err * err
        dq = J.T @ np.linalg.solve(J @ J.T + lam2 * eye, e)
        q = pin.integrate(model, q, dq)
    return q, err


def desired_views(
    pack: np.ndarray, n: int, nq: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Views q_d (nq,), q̇_d, q̈_d (n,) and the path sample (3, 3) = [p_d, ṗ_d, p̈_d] of a
    desired-motion pack (nq + 2n + 9,): the layout of ``_kernels.desired_parts``, which a
    law's steady-contact kernel unpacks (a CLIK keeps its desired motion in one)."""
    o = nq + 2 * n
    return pack[:nq], pack[nq : nq + n], pack[nq + n : o], pack[o : o + 9].reshape(3, 3)


class StepClock:
    """The path time t = t0 + i·dt from an integer step count i (issue 28 item 6).

    ``t += dt`` accumulates a rounding error per step (3.4e-12 s after 20 s at dt = 1 ms,
    which moves p_d by 1e-12 m on eq. 25); t0 + i·dt has one rounding, so t is the loop's
    own i·dt sample time exactly when t0 = 0. A call with another dt starts a new count from
    the current t (a law that changes its step; not the case in the toolkit's loops).

    Args:
        t0: [s] the start time.
    """

    __slots__ = ("_dt", "_i", "_t0", "t")

    def __init__(self, t0: float = 0.0) -> None:
        self.t = self._t0 = float(t0)
        self._i = 0
        self._dt: float | None = None

    def tick(self, dt: float) -> float:
        """Advance by dt [s]; the new t [s]."""
        if dt != self._dt:
            self._t0, self._i, self._dt = self.t, 0, dt
        self._i += 1
        self.t = self._t0 + self._i * dt
        return self.t


class DesiredJointPath:
    """q_d(t), q̇_d(t), q̈_d(t) for a task-space path, advanced in step with a simulation.

    Each step predicts q_d(t + dt) by a second-order Taylor step and corrects it with one
    Newton step on k(q_d) = p_d(t + dt) (quadratic convergence: the residual after it is at
    round-off). Since k(q_d(0)) = p_d(0), the exact solution of eq. 27 keeps
    k(q_d(t)) = p_d(t) for all t (its γ-term stays zero), so this is the solution of eq. 27
    to round-off, at the price of three Pinocchio passes per step. q̇_d is then eq. 27 itself
    and q̈_d its exact time derivative (module docstring).

    Args:
        robot: the arm (its own Pinocchio data is created here).
        path: the task-space path p_d(t).
        q0: (nq,) q_d(0); must satisfy k(q_d(0)) = p_d(0) (see :func:`inverse_kinematics`).
        settings: the CLIK gains.
        t0: start time [s].

    The algebra of each step is compiled (:mod:`hybrid_force.control._kernels`:
    ``newton_step``, ``clik_velocity``, ``clik_acceleration``, called through their ``_ws``
    forms on one flat buffer that holds the arrays; a helix or circle is sampled inside the
    first), and q, qd, qdd, p_d, pdot_d, pddot_d are updated in place: keep a copy
    to remember a value. Its readable numpy version is the oracle of ``tests/oracles/control.py``.
    """

    def __init__(
        self,
        robot: Robot,
        path: Path,
        q0: np.ndarray,
        settings: ClikSettings | None = None,
        t0: float = 0.0,
    ) -> None:
        self.robot = robot
        self.path = path
        self.settings = settings or ClikSettings()
        self._data = robot.new_data()
        # a view of the tip translation in self._data (updated in place by updateFramePlacement
        # and getFrameJacobian)
        self._tip = self._data.oMf[robot.tip_id].translation
        n = robot.nv
        self._redundant = n > 3
        self._eye = np.eye(n)
        self.posture = robot.check_q(q0, "q_d(0)").copy()
        self.t = float(t0)
        self._clock = StepClock(t0)
        self.q = self.posture.copy()
        self._start()
        p0, _ = self._tip_and_jacobian(self.q)
        if np.linalg.norm(p0 - self.p_d) > _START_TOL:
            raise ReachError(
                f"q_d(0) = {np.round(self.q, 6).tolist()} puts the tip at "
                f"{np.round(p0, 6).tolist()}, "
                f"not on the path at p_d({self.t:g}) = {np.round(self.p_d, 6).tolist()}: eq. 27 "
                "needs k(q_d(0)) = p_d(0); use inverse_kinematics to find q_d(0)"
            )
        self._update_derivatives()

    def _start(self) -> None:
        """Buffers written in place by the kernels, and the path sample at t0.

        The kernels' arrays are views of one flat buffer (``_kernels.clik_parts``), so each
        kernel of a step takes the buffer instead of up to 14 arrays."""
        n, nq, robot, path = self.robot.nv, self.robot.nq, self.robot, self.path
        K = _K
        self._ws = np.zeros(K.clik_workspace_size(n, nq))
        self._ws[0], self._ws[1] = n, nq
        (
            q, posture, self._q_pred, self.qd, self.qdd, self._dq_post, self._Jp, self._N,
            self._W, self._x, self._sample, self._cfg,
        ) = K.clik_parts(self._ws)  # fmt: skip
        q[:], posture[:] = self.q, self.posture
        self.q, self.posture = q, posture
        #: q_d, q̇_d, q̈_d, p_d, ṗ_d, p̈_d as one flat view (``_kernels.desired_parts``)
        self.desired_pack = self._ws[K.CLIK_HEADER : K.CLIK_HEADER + K.desired_pack_size(n, nq)]
        self._dt_pred = 0.0  # the dt of the predictor made ahead (0: none), also in ws[2]
        # settings and path sample as small arrays (fewer kernel arguments); the last entry
        # of the settings: the kernel forms q_d − posture itself (a Euclidean arm's)
        cfg = self.settings
        gain = cfg.posture_gain if self._redundant else 0.0
        subtract = float(gain > 0.0 and robot.euclidean)
        self._cfg[:] = [cfg.gamma, cfg.damping**2, float(self._redundant), gain, subtract]
        self._sample[:] = path.evaluate(self.t)  # rows p_d, ṗ_d, p̈_d
        self.p_d, self.pdot_d, self.pddot_d = self._sample
        # q_d ⊖ posture by pin.difference in Python (a non-Euclidean arm with a posture term)
        self._difference = gain > 0.0 and not robot.euclidean
        # what each step passes to Pinocchio and the kernels, looked up once
        self._step_args = (robot.model, self._data, robot.tip_id, robot.euclidean)
        # the step's kernels for their arguments' types (hybrid_force._jit.entry): this
        # buffer's views, the view of the tip, Pinocchio's (6, n) Jacobians, a descriptor
        model, data, fid, _ = self._step_args
        pin.computeJointJacobians(model, data, self.q)
        J6 = pin.getFrameJacobian(model, data, fid, _LWA)
        self._velocity_ws = entry(K.clik_velocity_ws, J6, self._tip, self._ws)
        self._acceleration_ws = entry(K.clik_acceleration_ws, J6, J6, self._ws)
        self._newton_ws = entry(K.newton_step_ws, _NO_DESCRIPTOR, 0.0, self._tip, self._ws)

    def _tip_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        model, data, fid = self.robot.model, self._data, self.robot.tip_id
        pin.computeJointJacobians(model, data, q)
        p = pin.updateFramePlacement(model, data, fid).translation
        return p, pin.getFrameJacobian(model, data, fid, _LWA)[:3]

    def _update_derivatives(self) -> None:
        """q̇_d (eq. 27) and q̈_d, its exact time derivative, at (t, q_d), written in place
        (the algebra of the module docstring, compiled)."""
        model, data, fid, _ = self._step_args
        q, ws = self.q, self._ws
        pin.computeJointJacobians(model, data, q)
        # getFrameJacobian(model, data, frame_id, rf) also sets data.oMf[frame_id] =
        # data.oMi[parent] · placement, the product updateFramePlacement forms (Pinocchio's
        # frames.hpp), so self._tip is the tip at q_d without that call
        J6 = pin.getFrameJacobian(model, data, fid, _LWA)
        if self._difference:  # (a Euclidean arm's q_d − posture is formed in the kernel)
            self._dq_post[:] = pin.difference(model, self.posture, q)
        cond = self._velocity_ws(J6, self._tip, ws)
        if not cond < _COND_MAX:  # the cheap bound of cond(J Jᵀ); the SVD names the values
            _check_conditioning(J6[:3], self.t, q, self.robot)
        pin.computeJointJacobiansTimeVariation(model, data, q, self.qd)
        self._acceleration_ws(J6, pin.getFrameJacobianTimeVariation(model, data, fid, _LWA), ws)

    def advance(self, dt: float) -> None:
        """Move q_d, q̇_d, q̈_d to t + dt (predictor + one Newton correction); t = t0 + i·dt
        (:class:`StepClock`), not a sum of the steps."""
        self.t = self._clock.tick(dt)
        self._advance(dt)

    def _advance(self, dt: float) -> None:
        """:meth:`advance` once t is updated: path sample, predictor, Newton, derivatives."""
        model, data, fid, euclidean = self._step_args
        q_pred, K = self._q_pred, _K
        if euclidean:
            if dt != self._dt_pred:  # otherwise the last step's kernel made the predictor
                K.taylor_step(self.q, self.qd, self.qdd, dt, q_pred)
                self._dt_pred = self._ws[2] = dt
        else:
            q_pred[:] = pin.integrate(model, self.q, self.qd * dt + self.qdd * (0.5 * dt * dt))
        pin.forwardKinematics(model, data, q_pred)
        pin.updateFramePlacement(model, data, fid)
        p = self._tip
        desc = self.path._descriptor
        if desc.shape[0] == 0 or not euclidean:  # the path sample in Python
            self.path.evaluate_into(self.t, self.p_d, self.pdot_d, self.pddot_d)
            desc = _NO_DESCRIPTOR
        if euclidean:
            # (a path with a descriptor is sampled at t inside this call)
            self._newton_ws(desc, self.t, p, self._ws)
        else:
            self.q[:] = pin.integrate(model, q_pred, self._Jp @ (self.p_d - p))
        self._update_derivatives()

    def task_error(self) -> float:
        """‖k(q_d) − p_d‖ at the current time [m]."""
        p, _ = self._tip_and_jacobian(self.q)
        return float(np.linalg.norm(p - self.p_d))

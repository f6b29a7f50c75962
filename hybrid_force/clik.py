"""Desired joint path from a task-space path: the paper's "Newton algorithm" (eq. 27).

q̇_d = J⁻¹(q_d) [ṗ_d − γ (k(q_d) − p_d)],   γ = 7 by default (section 6.1)

integrated with RK4 in step with the simulation, so that its error (which becomes the arm's
tracking error) stays at round-off. q_d(0) solves k(q_d(0)) = p_d(0) by Newton iterations
from a seed (:func:`inverse_kinematics`). For arms with more than three joints J⁻¹ is a
damped pseudo-inverse and a null-space term pulls q_d towards a posture (the seed):

q̇_d = J⁺ x + (I − J⁺J)(−k_n (q_d − q_posture)),   x = ṗ_d − γ (k(q_d) − p_d).

The joint acceleration is the exact derivative of the task-space part (J q̈_d + J̇ q̇_d =
p̈_d − γ (J q̇_d − ṗ_d)); for redundant arms the null-space part of q̈_d is approximated by
(I − J⁺J)(−k_n q̇_d), which does not affect the tip.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from hybrid_force.errors import GainError, ReachError
from hybrid_force.paths import Path
from hybrid_force.robot import Robot

__all__ = ["ClikSettings", "DesiredJointPath", "inverse_kinematics"]

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_COND_MAX = 1e8  # condition number of J J^T beyond which J is treated as singular


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
        if not (np.isfinite(self.gamma) and self.gamma > 0):
            raise GainError(f"clik gamma must be > 0 (paper eq. 27), got {self.gamma!r}")
        if not (np.isfinite(self.damping) and self.damping >= 0):
            raise GainError(f"clik damping must be >= 0, got {self.damping!r}")
        if not (np.isfinite(self.posture_gain) and self.posture_gain >= 0):
            raise GainError(f"clik posture_gain must be >= 0, got {self.posture_gain!r}")


def _solve_task(J: np.ndarray, x: np.ndarray, damping: float) -> np.ndarray:
    """J⁺ x for a (3, n) J: exact inverse when n = 3, damped pseudo-inverse otherwise."""
    JJt = J @ J.T
    if J.shape[1] == 3:
        return np.linalg.solve(J, x)
    JJt[np.diag_indices(3)] += damping * damping
    return J.T @ np.linalg.solve(JJt, x)


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
    """
    model, data = robot.model, robot.new_data()
    target = np.asarray(target, dtype=float)
    q = robot.neutral() if seed is None else robot.check_q(seed, "seed").copy()
    err = np.inf
    for _ in range(max_iter):
        pin.forwardKinematics(model, data, q)
        p = pin.updateFramePlacement(model, data, robot.tip_id).translation
        e = target - p
        err = float(np.linalg.norm(e))
        if err < tol:
            return q
        pin.computeJointJacobians(model, data, q)
        J = pin.getFrameJacobian(model, data, robot.tip_id, _LWA)[:3]
        # Levenberg–Marquardt step: damping grows with the error so far-off seeds stay stable.
        lam2 = 1e-10 + 1e-3 * err * err
        dq = J.T @ np.linalg.solve(J @ J.T + lam2 * np.eye(3), e)
        q = pin.integrate(model, q, dq)
    raise ReachError(
        f"tip position {np.round(target, 6).tolist()} is out of reach of '{robot.name}' "
        f"from seed {np.round(robot.neutral() if seed is None else seed, 4).tolist()}: "
        f"Newton iterations stopped {err:.3g} m away after {max_iter} iterations"
    )


class DesiredJointPath:
    """q_d(t), q̇_d(t), q̈_d(t) for a task-space path, integrated in step with a simulation.

    Args:
        robot: the arm (its own Pinocchio data is created here).
        path: the task-space path p_d(t).
        q0: (nq,) q_d(0); must satisfy k(q_d(0)) = p_d(0) (see :func:`inverse_kinematics`).
        settings: the CLIK gains.
        t0: start time [s].
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
        self._redundant = robot.nv > 3
        self.posture = robot.check_q(q0, "q_d(0)").copy()
        self.t = float(t0)
        self.q = self.posture.copy()
        self.qd, self.qdd = self._derivatives(self.t, self.q)

    def _kinematics(self, q: np.ndarray, qd: np.ndarray | None = None):
        model, data, fid = self.robot.model, self._data, self.robot.tip_id
        if qd is None:
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacement(model, data, fid)
            return data.oMf[fid].translation, pin.getFrameJacobian(model, data, fid, _LWA)[:3]
        pin.computeJointJacobiansTimeVariation(model, data, q, qd)
        pin.updateFramePlacement(model, data, fid)
        J = pin.getFrameJacobian(model, data, fid, _LWA)[:3]
        Jdot = pin.getFrameJacobianTimeVariation(model, data, fid, _LWA)[:3]
        return data.oMf[fid].translation, J, Jdot

    def _velocity(self, t: float, q: np.ndarray) -> np.ndarray:
        """q̇_d of eq. 27 at (t, q)."""
        p_d, pdot_d, _ = self.path.evaluate(t)
        p, J = self._kinematics(q)
        x = pdot_d - self.settings.gamma * (p - p_d)
        if not self._redundant:
            _check_conditioning(J, t, q, self.robot)
            return np.linalg.solve(J, x)
        qd = _solve_task(J, x, self.settings.damping)
        if self.settings.posture_gain > 0:
            z = -self.settings.posture_gain * pin.difference(self.robot.model, self.posture, q)
            qd += z - _solve_task(J, J @ z, self.settings.damping)
        return qd

    def _derivatives(self, t: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        qd = self._velocity(t, q)
        _, pdot_d, pddot_d = self.path.evaluate(t)
        _, J, Jdot = self._kinematics(q, qd)
        x = pddot_d - self.settings.gamma * (J @ qd - pdot_d) - Jdot @ qd
        if not self._redundant:
            return qd, np.linalg.solve(J, x)
        qdd = _solve_task(J, x, self.settings.damping)
        if self.settings.posture_gain > 0:
            z = -self.settings.posture_gain * qd
            qdd += z - _solve_task(J, J @ z, self.settings.damping)
        return qd, qdd

    def advance(self, dt: float) -> None:
        """Integrate q_d over one step dt [s] with RK4 and update q̇_d, q̈_d."""
        model, t, q = self.robot.model, self.t, self.q
        k1 = self._velocity(t, q)
        k2 = self._velocity(t + dt / 2, pin.integrate(model, q, k1 * (dt / 2)))
        k3 = self._velocity(t + dt / 2, pin.integrate(model, q, k2 * (dt / 2)))
        k4 = self._velocity(t + dt, pin.integrate(model, q, k3 * dt))
        self.q = pin.integrate(model, q, (k1 + 2 * k2 + 2 * k3 + k4) * (dt / 6))
        self.t = t + dt
        self.qd, self.qdd = self._derivatives(self.t, self.q)

    def task_error(self) -> float:
        """‖k(q_d) − p_d‖ at the current time [m]."""
        p, _ = self._kinematics(self.q)
        return float(np.linalg.norm(p - self.path.position(self.t)))

"""Numpy oracles of the controller: the paper's laws as functions (eq. 4, 8, 11, 29-30),
the CLIKs (eq. 27 and its pose form) in readable numpy, the controller's own model on the
readable robot terms, and the whole controller on them (:class:`ReferenceController`), which
:func:`use_oracle_control` makes a run build. The package's compiled kernels are checked
against these (never imported by the package).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from hybrid_force.control.clik import _COND_MAX, DesiredJointPath, _check_conditioning
from hybrid_force.control.constraint import ConstraintTerms
from hybrid_force.control.controller import ControllerModel
from hybrid_force.control.laws.arimoto import LawWorkspace
from hybrid_force.control.laws.base import Command, ControlTrace, Desired, Gains, LawInput
from hybrid_force.control.pose_clik import PoseJointPath, _orientation_error
from hybrid_force.control.supervisor import HybridController
from hybrid_force.control.tool import cross3
from hybrid_force.errors import SurfaceError
from hybrid_force.model.robot import LWA, RobotTerms
from oracles.terms import constraint_terms, robot_terms

__all__ = [
    "ReferenceController",
    "ReferenceControllerModel",
    "ReferenceJointPath",
    "ReferenceLaw",
    "ReferencePoseJointPath",
    "arimoto_law",
    "free_space_law",
    "use_oracle_control",
]


def free_space_law(
    gains: Gains, robot: RobotTerms, v: np.ndarray, e_q: np.ndarray, desired: Desired
) -> tuple[Command, ControlTrace]:
    """Free-space law, eq. 29–30.

    q̇_r = q̇_d − Λ e_q,  s = q̇ − q̇_r,  u = M q̈_r + C q̇_r + g − K_d s.

    Args:
        robot: the controller's model terms (M, C, g) at (q, v).
        v: (n,) joint velocity. e_q: (n,) position error q − q_d.
    """
    lam = gains.Lambda
    qdot_r = desired.qd - lam * e_q
    qddot_r = desired.qdd - lam * (v - desired.qd)
    s = v - qdot_r
    u = robot.M @ qddot_r + robot.C @ qdot_r + robot.g - gains.Kd @ s
    trace = ControlTrace(
        e_q=e_q,
        s=s,
        s0=s,
        s1=np.zeros_like(s),
        e_F=np.zeros(0),
        qdot_r=qdot_r,
        qddot_r0=qddot_r,
        qddot_r_f=None,
        V=0.5 * float(s @ robot.M @ s),
        f_d=np.zeros(0),
    )
    return Command(u0=u, B=None), trace


def arimoto_law(
    gains: Gains,
    robot: RobotTerms,
    cons: ConstraintTerms,
    v: np.ndarray,
    e_q: np.ndarray,
    desired: Desired,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray | None = None,
) -> tuple[Command, ControlTrace]:
    """Modified Arimoto hybrid law, eq. 4, 8, 11, with the loop in f kept explicit.

    Args:
        robot: the controller's model terms (M, C, g) at (q, v).
        cons: the constraint terms (A, A⁺, Ȧ⁺, Q, Q̇) at (q, v).
        v: (n,) joint velocity. e_q: (n,) q − q_d.
        e_F: (k,) momentum error F − F_d [N·s] (eq. 3).
        f_d: (k,) desired force [N].
        approach: optional (k,) normal reference velocity [m/s] added as A⁺·approach to q̇_r
            (near phase only, see :mod:`hybrid_force.control.supervisor`); None in contact.

    Returns:
        The command u = u0 + B f and the trace (s₀ = Q(ė_q + Λe_q), s₁ = −βA⁺e_F, eq. 9).
    """
    lam, beta = gains.Lambda, gains.beta
    Q, Qdot, Ap, Apd = cons.Q, cons.Qdot, cons.A_pinv, cons.A_pinv_dot
    x = desired.qd - lam * e_q
    xdot = desired.qdd - lam * (v - desired.qd)
    qdot_r = Q @ x + beta * (Ap @ e_F)
    qddot_r0 = Qdot @ x + Q @ xdot + beta * (Apd @ e_F) - beta * (Ap @ f_d)
    if approach is not None:
        qdot_r = qdot_r + Ap @ approach
        qddot_r0 = qddot_r0 + Apd @ approach
    s = v - qdot_r
    M = robot.M
    u0 = (
        M @ qddot_r0
        + robot.C @ qdot_r
        + robot.g
        - gains.Kd @ s
        - cons.A.T @ (f_d - gains.gamma * e_F)
    )
    B = beta * (M @ Ap) if beta > 0 else None
    trace = ControlTrace(
        e_q=e_q,
        s=s,
        s0=Q @ (v - x),
        s1=-beta * (Ap @ e_F),
        e_F=e_F,
        qdot_r=qdot_r,
        qddot_r0=qddot_r0,
        qddot_r_f=beta * Ap,
        V=0.5 * float(s @ M @ s) + 0.5 * beta * float(e_F @ e_F),
        f_d=f_d,
    )
    return Command(u0=u0, B=B), trace


class ReferenceLaw(LawWorkspace):
    """:class:`~hybrid_force.control.laws.arimoto.LawWorkspace`'s interface over
    :func:`arimoto_law` and :func:`free_space_law` (new arrays every call)."""

    def __init__(self, n: int, k: int, gains: Gains) -> None:
        super().__init__(n, k, gains)
        self._trace: ControlTrace | None = None

    def hybrid(self, inp: LawInput) -> Command:
        """:func:`arimoto_law` with this law's gains."""
        command, self._trace = arimoto_law(
            self.gains, inp.robot, inp.rows, inp.v, inp.e_q, inp.desired, inp.e_F.copy(),
            inp.f_d, inp.approach,
        )  # fmt: skip
        self.V = self._trace.V
        return command

    def free_space(self, inp: LawInput) -> Command:
        """:func:`free_space_law` with this law's gains."""
        command, self._trace = free_space_law(self.gains, inp.robot, inp.v, inp.e_q, inp.desired)
        self.V = self._trace.V
        return command

    def trace(self, e_q: np.ndarray, e_F: np.ndarray, f_d: np.ndarray) -> ControlTrace:
        """The :class:`ControlTrace` of the last call."""
        assert self._trace is not None
        return self._trace


def _inv3(J: np.ndarray) -> np.ndarray:
    """Inverse of a 3×3 matrix by its adjugate (3× faster than np.linalg.inv at this size).

    Raises np.linalg.LinAlgError when the determinant is exactly zero.
    """
    (a, b, c), (d, e, f), (g, h, i) = J.tolist()
    c0, c1, c2 = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * c0 + b * c1 + c * c2
    if det == 0.0:
        raise np.linalg.LinAlgError("singular 3x3 matrix")
    r = 1.0 / det
    return np.array(
        [
            [c0 * r, (c * h - b * i) * r, (b * f - c * e) * r],
            [c1 * r, (a * i - c * g) * r, (c * d - a * f) * r],
            [c2 * r, (b * g - a * h) * r, (a * e - b * d) * r],
        ]
    )


class ReferenceJointPath(DesiredJointPath):
    """:class:`DesiredJointPath` in readable numpy: the oracle its kernels are tested against
    (``tests/test_kernels.py``). New arrays every step instead of updates in place.
    """

    def _start(self) -> None:
        self.p_d, self.pdot_d, self.pddot_d = self.path.evaluate(self.t)

    def _update_derivatives(self) -> None:
        self.qd, self.qdd = self._derivatives()

    def _advance(self, dt: float) -> None:
        model = self.robot.model
        self.p_d, self.pdot_d, self.pddot_d = self.path.evaluate(self.t)
        q = pin.integrate(model, self.q, self.qd * dt + self.qdd * (0.5 * dt * dt))
        # Newton correction with the pseudo-inverse of the previous step: J changes by O(dt)
        # between the two, so the residual after it is O(dt) × the predictor's O(dt³) error.
        pin.forwardKinematics(model, self._data, q)
        p = pin.updateFramePlacement(model, self._data, self.robot.tip_id).translation
        self.q = pin.integrate(model, q, self._Jp @ (self.p_d - p))
        self._update_derivatives()

    def _pinv(self, J: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """J⁻¹ (n = 3) or the damped pseudo-inverse Jᵀ W (n > 3), and W = (JJᵀ + λ²I)⁻¹
        (None for n = 3); ReachError when J is singular."""
        W = None
        try:
            if self._redundant:
                JJt = J @ J.T
                JJt[np.diag_indices(3)] += self.settings.damping**2
                W = np.linalg.inv(JJt)
                cond = float(np.abs(JJt).max() * np.abs(W).max())
                Jp = J.T @ W
            else:
                Jp = _inv3(J)
                cond = float(np.abs(J).max() * np.abs(Jp).max()) ** 2
        except np.linalg.LinAlgError:
            cond = np.inf
        if not cond < _COND_MAX:  # a cheap upper bound of cond(J Jᵀ); the SVD names the values
            _check_conditioning(J, self.t, q, self.robot)
        return Jp, W

    def _derivatives(self) -> tuple[np.ndarray, np.ndarray]:
        """q̇_d (eq. 27) and q̈_d, its exact time derivative, at the current (t, q_d).

        With x = ṗ_d − γ(k(q_d) − p_d): n = 3, q̇_d = J⁻¹x and q̈_d = J⁻¹(ẋ − J̇q̇_d).
        n > 3, q̇_d = J⁺x + N z with N = I − J⁺J and z = −k_n (q_d − q_posture), so
        q̈_d = J̇⁺x + J⁺ẋ + Ṅz + Nż, where J̇⁺ = J̇ᵀW + JᵀẆ, Ẇ = −W(J̇Jᵀ + JJ̇ᵀ)W,
        Ṅ = −(J̇⁺J + J⁺J̇), ż = −k_n q̇_d and ẋ = p̈_d − γ(J q̇_d − ṗ_d).
        """
        model, data, fid = self.robot.model, self._data, self.robot.tip_id
        q, gamma = self.q, self.settings.gamma
        p, J = self._tip_and_jacobian(q)
        Jp, W = self._pinv(J, q)
        self._Jp = Jp
        x = self.pdot_d - gamma * (p - self.p_d)
        qd = Jp @ x
        z = None
        if self._redundant and self.settings.posture_gain > 0:
            N = self._eye - Jp @ J
            z = -self.settings.posture_gain * pin.difference(model, self.posture, q)
            qd += N @ z
        pin.computeJointJacobiansTimeVariation(model, data, q, qd)
        Jdot = pin.getFrameJacobianTimeVariation(model, data, fid, LWA)[:3]
        xdot = self.pddot_d - gamma * (J @ qd - self.pdot_d)
        if W is None:
            return qd, Jp @ (xdot - Jdot @ qd)
        Wdot = -W @ (Jdot @ J.T + J @ Jdot.T) @ W
        Jp_dot = Jdot.T @ W + J.T @ Wdot
        qdd = Jp_dot @ x + Jp @ xdot
        if z is not None:
            N_dot = -(Jp_dot @ J + Jp @ Jdot)
            qdd += N_dot @ z + N @ (-self.settings.posture_gain * qd)
        return qd, qdd


def _skew(w: np.ndarray) -> np.ndarray:
    x, y, z = w
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _damped_inverse(A: np.ndarray, damping: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(A⁺ = AᵀW (n, m), W = (AAᵀ + λ²I)⁻¹ (m, m), a cheap upper bound of cond(AAᵀ + λ²I))."""
    G = A @ A.T
    G[np.diag_indices(G.shape[0])] += damping**2
    try:
        W = np.linalg.inv(G)
    except np.linalg.LinAlgError:
        return np.zeros(A.T.shape), np.zeros(G.shape), math.inf
    m = G.shape[0]  # ‖G‖₂ ≤ m max|G_ij|: an upper bound of the condition number
    return A.T @ W, W, float(m * m * np.abs(G).max() * np.abs(W).max())


class ReferencePoseJointPath(PoseJointPath):
    """:class:`PoseJointPath` in readable numpy: the oracle its kernels are tested against
    (``tests/test_pose_kernels.py``), what :class:`ReferenceController` runs. New arrays every
    step instead of updates in place; the desired direction from ``ToolTarget.axis``/``frame``.
    """

    _a: np.ndarray  # (3, 3) the a_d jet (roll free)
    _w_d: np.ndarray  # (3,) ω_d
    _wdot_d: np.ndarray  # (3,) ω̇_d

    def _start(self) -> None:
        self._Ap = np.zeros((self.robot.nv, self._task.m))

    def _sample(self) -> None:
        self.p_d, self.pdot_d, self.pddot_d = self.path.evaluate(self.t)
        self._sample_goal(np.array((self.p_d, self.pdot_d, self.pddot_d)))

    def _sample_goal(self, sample: np.ndarray) -> None:
        """The desired direction (and frame) at self.t from the path sample (3, 3) there."""
        if self._task.held:
            F, self._w_d, self._wdot_d = self.target.frame(self.t, sample)
            self.a_d = F[:, 2].copy()
            self.R_d = F if self._R_fix is None else F @ self._R_fix
        else:
            self._a = self.target.axis(self.t, sample)
            self.a_d = self._a[0]
            self._w_d = cross3(self._a[0], self._a[1])
            self._wdot_d = cross3(self._a[0], self._a[2])
            self.R_d = None

    def _update_derivatives(self) -> None:
        self.qd, self.qdd = self._derivatives()

    def _advance(self, dt: float) -> None:
        model, task = self.robot.model, self._task
        self._sample()
        q = pin.integrate(model, self.q, self.qd * dt + self.qdd * (0.5 * dt * dt))
        pin.forwardKinematics(model, self._data, q)
        M = pin.updateFramePlacement(model, self._data, self.robot.tip_id)
        e = task.error(M.rotation, self.a_d, self.R_d)
        r = np.concatenate([self.p_d - M.translation, self._S @ e])
        self.q = pin.integrate(model, q, self._Ap @ r)
        self._update_derivatives()

    def _derivatives(self) -> tuple[np.ndarray, np.ndarray]:
        """q̇_d and its exact time derivative q̈_d at (t, q_d) (module docstring)."""
        robot, task, cfg = self.robot, self._task, self.settings
        model, data, fid, q, gamma = robot.model, self._data, robot.tip_id, self.q, cfg.gamma
        p, R, J = task.kinematics(data, q)
        S = task.selector(R)
        A = task.rows(J, S)
        Ap, W, cond = _damped_inverse(A, cfg.damping)
        if not cond < _COND_MAX:
            self._check_conditioning(A, q)
        self._Ap, self._S = Ap, S
        e = task.error(R, self.a_d, self.R_d)
        w = self._w_d + gamma * e
        y = np.concatenate([self.pdot_d - gamma * (p - self.p_d), S @ w])
        qd = Ap @ y
        z = None
        if self._redundant and cfg.posture_gain > 0:
            N = self._eye - Ap @ A
            z = -cfg.posture_gain * pin.difference(model, self.posture, q)
            qd = qd + N @ z
        pin.computeJointJacobiansTimeVariation(model, data, q, qd)
        Jdot = pin.getFrameJacobianTimeVariation(model, data, fid, LWA)
        omega = J[3:] @ qd
        Sw = S @ _skew(omega) if not task.held else np.zeros((3, 3))
        e_dot = self._error_rate(R, omega)
        w_dot = self._wdot_d + gamma * e_dot
        A_dot = np.vstack([Jdot[:3], S @ Jdot[3:] - Sw @ J[3:]])
        y_dot = np.concatenate(
            [self.pddot_d - gamma * (J[:3] @ qd - self.pdot_d), S @ w_dot - Sw @ w]
        )
        W_dot = -W @ (A_dot @ A.T + A @ A_dot.T) @ W
        Ap_dot = A_dot.T @ W + A.T @ W_dot
        qdd = Ap_dot @ y + Ap @ y_dot
        if z is not None:
            N_dot = -(Ap_dot @ A + Ap @ A_dot)
            qdd = qdd + N_dot @ z + N @ (-cfg.posture_gain * qd)
        return qd, qdd

    def _error_rate(self, R: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """ė (3,) along q̇_d: the derivative of a × a_d, or of ½ Σ r_i × r_di."""
        if self.R_d is None:
            a = R @ self._task.axis
            return cross3(cross3(omega, a), self.a_d) + cross3(a, self._a[1])
        Rdot = _skew(omega) @ R
        Rd_dot = _skew(self._w_d) @ self.R_d
        return _orientation_error(Rdot, self.R_d) + _orientation_error(R, Rd_dot)


class ReferenceControllerModel(ControllerModel):
    """:class:`ControllerModel` on the readable robot terms and constraint rows."""

    def evaluate(self, q: np.ndarray, v: np.ndarray) -> tuple[RobotTerms, ConstraintTerms | None]:
        terms = robot_terms(self.robot, q, v)
        try:
            return terms, constraint_terms(self.constraint, terms, v)
        except SurfaceError:
            return terms, None


class ReferenceController(HybridController):
    """:class:`~hybrid_force.control.supervisor.HybridController` on the numpy oracles: the
    CLIKs above, the law's oracle (:func:`oracles.laws.oracle_of`, the same gains) and F, F_d
    integrated in numpy."""

    _joint_path = ReferenceJointPath
    _pose_path = ReferencePoseJointPath

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        from oracles.laws import oracle_of  # (oracles.laws imports this module's laws)

        super().__init__(*args, **kwargs)
        self._law = oracle_of(self._law, self.robot)

    def _accumulate(self, f: np.ndarray, dt: float) -> None:
        st = self._int
        st.F += f * dt
        st.F_d += st.f_d * dt
        np.subtract(st.F, st.F_d, out=self._e_F)


def use_oracle_control(monkeypatch: Any) -> None:
    """Make every run of the test build the controller on the oracles: the scenario's law
    (:class:`ReferenceController`) on :class:`ReferenceControllerModel` (the plant stays the
    package's: ``use_oracle_plant`` of ``oracles`` for it)."""
    import hybrid_force.sim.control_side as control_side

    monkeypatch.setattr(control_side, "HybridController", ReferenceController)
    monkeypatch.setattr(control_side, "ControllerModel", ReferenceControllerModel)

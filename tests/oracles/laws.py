"""Numpy oracles of the laws other than the paper's (tests/oracles/control.py has those):
each the readable form of its package law, a subclass of it with the same constructor (what
both share: settings, reports, the law's interface), its steps in numpy ("module docstring"
and the equation numbers below: the package law's module). :func:`oracle_of` turns a built
package law into its oracle.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pinocchio as pin

from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.laws.arimoto import LawWorkspace
from hybrid_force.control.laws.arimoto_adaptive import Adaptation, AdaptiveArimotoWorkspace
from hybrid_force.control.laws.base import Command, ControlTrace, Desired, Gains, Law, LawInput
from hybrid_force.control.laws.impedance import (
    ImpedanceGains,
    ImpedanceWorkspace,
    _singular,
    _task,
)
from hybrid_force.control.laws.osc_hybrid import (
    OscGains,
    OscHybridWorkspace,
    OscTrace,
    _check_desired,
    task_space,
)
from hybrid_force.control.laws.raibert_craig import (
    RaibertCraigGains,
    RaibertCraigWorkspace,
    pseudo_inverse,
    selection_matrix,
)
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.model.regressor import SlotineLiRegressor
from hybrid_force.model.robot import Robot, RobotTerms
from oracles.control import ReferenceLaw, arimoto_law, free_space_law

__all__ = [
    "AdaptiveArimotoLaw",
    "ImpedanceLaw",
    "OscHybridLaw",
    "RaibertCraigLaw",
    "cartesian_inertia",
    "impedance_matrices",
    "normal_directions",
    "oracle_of",
    "osc_hybrid_law",
]


def _hybrid_input(inp: LawInput) -> tuple[Any, ...]:
    """(robot, cons, v, e_q, desired, e_F, f_d, approach) of a hybrid step's input."""
    return inp.robot, inp.rows, inp.v, inp.e_q, inp.desired, inp.e_F, inp.f_d, inp.approach


def cartesian_inertia(robot: RobotTerms) -> np.ndarray:
    """Λ = (J M⁻¹ Jᵀ)⁻¹ (3, 3) [kg] of the model terms, symmetric.

    Raises:
        SurfaceError: J M⁻¹ Jᵀ is singular (the tip cannot move along some
            direction, so no Cartesian stiffness acts there).
    """
    try:
        Lam = np.linalg.inv(robot.J @ np.linalg.solve(robot.M, robot.J.T))
    except np.linalg.LinAlgError as exc:
        raise _singular(robot) from exc
    return 0.5 * (Lam + Lam.T)


def impedance_matrices(Lam: np.ndarray, omega: float, zeta: float) -> tuple[np.ndarray, np.ndarray]:
    """K = ω² Λ [N/m] and D = 2ζω Λ [N·s/m], each (3, 3), of a Cartesian inertia Λ (3, 3)."""
    return (omega * omega) * Lam, (2.0 * zeta * omega) * Lam


def normal_directions(constraint: Constraint, p: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """W (3, k): the task-space direction w_i = ∇Φ_i(p) / s_i of each row (A = Wᵀ J)."""
    W = np.empty((3, constraint.k))
    for i, surface in enumerate(constraint.surfaces):
        W[:, i] = surface.evaluate(p)[1] / scale[i]
    return W


def osc_hybrid_law(
    gains: OscGains,
    robot: RobotTerms,
    v: np.ndarray,
    e_q: np.ndarray,
    desired: Desired,
    hybrid: tuple[ConstraintTerms, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]
    | None = None,
) -> tuple[Command, OscTrace]:
    """One step of the law (module docstring, eq. 1, 3–6), in readable numpy.

    Args:
        robot: the controller's model terms at (q, v).
        v: (n,) joint velocity. e_q: (n,) q − q_d.
        desired: q_d, q̇_d, q̈_d (n,) and p_d, ṗ_d, p̈_d (3,) [m, m/s, m/s²].
        hybrid: None in free space (eq. 3); near and in contact (cons, W (3, k) of
            :func:`normal_directions`, e_F (k,) [N·s], f_d (k,) [N], approach (k,) [m/s] in
            the near phase or None in contact) (eq. 4–5).

    Returns:
        The command u = u0 + B f and the trace.
    """
    _check_desired(desired)
    task = task_space(robot.M, robot.J)
    a = desired.pdd - gains.kv * (robot.pdot - desired.pd) - gains.kp * (robot.p - desired.p)
    B = None
    phi = np.zeros(0)
    F = task.Lambda @ (a - robot.Jdot_v)
    if hybrid is not None:
        cons, W, e_F, f_d, approach = hybrid
        # (k, 3) (WᵀW)⁻¹Wᵀ, so that Ω̃ = W (WᵀW)⁻¹Wᵀ
        WtW_inv_Wt = (
            W.T / float(W[:, 0] @ W[:, 0]) if W.shape[1] == 1 else np.linalg.solve(W.T @ W, W.T)
        )
        nu = cons.rate
        c = W.T @ robot.Jdot_v - cons.drift
        if approach is None:  # contact: damp the normal speed
            x = -gains.kn * nu
        else:  # near: follow ν_a = −λ_a d, whose derivative is −λ_a ν
            x = gains.kn * (approach - nu) - gains.approach_rate * nu
        a = a - W @ (WtW_inv_Wt @ a) + WtW_inv_Wt.T @ (c + x)
        phi = -f_d + gains.force_i * e_F - gains.force_p * f_d
        F = task.Lambda @ (a - robot.Jdot_v) + W @ phi
        if gains.force_p > 0 and approach is None:
            B = gains.force_p * cons.A.T
    y = desired.qdd - gains.null_kp * e_q - gains.null_kd * (v - desired.qd)
    null_torque = robot.M @ task.null(y)  # Nᵀ M y = M N y
    u0 = robot.J.T @ F + robot.nle + null_torque
    trace = OscTrace(a=a, F0=F, phi=phi, null_torque=null_torque, task=task)
    return Command(u0=u0, B=B), trace


class OscHybridLaw(OscHybridWorkspace):
    """The :class:`~hybrid_force.control.laws.base.Law` of :func:`osc_hybrid_law`.

    Args: as :class:`~hybrid_force.control.laws.osc_hybrid.OscHybridWorkspace`.

    Attributes:
        V: NaN (no Lyapunov function in joules: see the module docstring).
        last: the :class:`OscTrace` of the last call (None before the first).
    """

    last: OscTrace | None = None  # (the workspace's property, here a plain attribute)

    def free_space(self, inp: LawInput) -> Command:
        """Full-task motion control (eq. 3) with the null-space posture (eq. 6)."""
        robot, v, e_q, desired = inp.robot, inp.v, inp.e_q, inp.desired
        command, self.last = osc_hybrid_law(self.gains, robot, v, e_q, desired)
        return command

    def hybrid(self, inp: LawInput) -> Command:
        """Motion along the surface, force (contact) or approach speed (near) across it."""
        robot, cons, v, e_q, desired, e_F, f_d, approach = _hybrid_input(inp)
        W = normal_directions(self.constraint, robot.p, cons.scale)
        command, self.last = osc_hybrid_law(
            self.gains, robot, v, e_q, desired, (cons, W, e_F, f_d, approach)
        )
        return command


class ImpedanceLaw(ImpedanceWorkspace):
    """The impedance law (hybrid_force.control.laws.impedance) in readable numpy: the oracle
    of :class:`ImpedanceWorkspace` (the same arguments and attributes)."""

    V = math.nan

    def __init__(self, gains: ImpedanceGains, constraint: Constraint, k: int) -> None:
        super().__init__(gains, constraint, k)
        self.stiffness = np.zeros((3, 3))
        self.damping = np.zeros((3, 3))

    def free_space(self, inp: LawInput) -> Command:
        """Eq. (1) with p_r = p_d, ṗ_r = ṗ_d (module docstring)."""
        robot, v, e_q, desired = inp.robot, inp.v, inp.e_q, inp.desired
        self._in_contact = False
        p_d, pd_d = _task(desired)
        return Command(self._torque(robot, v, e_q, desired, p_d - robot.p, pd_d), None)

    def hybrid(self, inp: LawInput) -> Command:
        """Eq. (1) near the surface (approach given) and in contact (eq. 2); e_F is unused."""
        robot, cons, v, e_q, desired, _, f_d, approach = _hybrid_input(inp)
        p_d, pd_d = _task(desired)
        e = p_d - robot.p
        if approach is not None:  # near: the reference at the tool's height, descending
            self._in_contact = False
            normals = np.array([s.normal(robot.p) for s in self.constraint.surfaces]).T  # (3, k)
            along = np.linalg.pinv(normals)  # (k, 3): the projector onto the normals is N·along
            e = e - normals @ (along @ e)
            pd_r = pd_d - normals @ (along @ pd_d) + along.T @ approach
            # a = −λ_a d, so ȧ = −λ_a ḋ = (a / d) ḋ: its feed-forward makes −λ_a a root
            pdd_r = along.T @ (approach / cons.distance * (normals.T @ robot.pdot))
            return Command(self._torque(robot, v, e_q, desired, e, pd_r, pdd_r), None)
        self._touch(f_d)
        u = self._torque(robot, v, e_q, desired, e, pd_d) - cons.A.T @ self.preload
        W = cons.A @ np.linalg.solve(robot.M, cons.A.T)
        self.offset = W @ self.preload / self.gains.omega**2
        return Command(u, None)

    def _torque(
        self,
        robot: RobotTerms,
        v: np.ndarray,
        e_q: np.ndarray,
        desired: Desired,
        e: np.ndarray,
        pd_r: np.ndarray,
        pdd_r: np.ndarray | None = None,
    ) -> np.ndarray:
        """Eq. (1) for the error e = p_r − p (3,) [m], the reference velocity ṗ_r (3,) [m/s]
        and a reference acceleration p̈_r (3,) [m/s²] beyond the path's, fed forward as Λ p̈_r."""
        g = self.gains
        Lam = cartesian_inertia(robot)
        K, D = impedance_matrices(Lam, g.omega, g.zeta)
        self.stiffness, self.damping = K, D
        force = K @ e + D @ (pd_r - robot.pdot)
        if pdd_r is not None:
            force += Lam @ pdd_r
        # null space: (I − Jᵀ J̄ᵀ)(−M y) = −M y + Jᵀ Λ J y, y = ω² e_q + 2ζω ė_q
        y = g.omega**2 * e_q + (2.0 * g.zeta * g.omega) * (v - desired.qd)
        u = robot.J.T @ (force + Lam @ (robot.J @ y)) - robot.M @ y + robot.g
        if g.feedforward:
            u += robot.M @ desired.qdd + robot.C @ desired.qd
        return u

    def update(self, dt: float, f: np.ndarray) -> None:
        """Force tracking in contact: φ += dt κ_f (f_d − f).

        φ may turn negative (the reference then sits off the surface, on the free side): that
        is how the law takes back a push the model does not know of (a gravity over-estimate).
        """
        if self._in_contact and self.gains.force_tracking:
            self.preload += dt * self.gains.force_rate * (self._f_d - f)


class RaibertCraigLaw(RaibertCraigWorkspace):
    """The law of hybrid_force.control.laws.raibert_craig in numpy (both forms): the oracle
    of :class:`RaibertCraigWorkspace` (the same arguments and attributes)."""

    V = math.nan

    def __init__(
        self, gains: RaibertCraigGains, surfaces: tuple[Surface, ...], approach_rate: float
    ) -> None:
        super().__init__(gains, surfaces, approach_rate)
        self.last_u_pos = np.zeros(gains.Kq.shape[0])
        self.redundant = gains.Kq.shape[0] > 3

    # ---------------------------------------------------------------- the phases
    def free_space(self, inp: LawInput) -> Command:
        """S = I: both forms servo every axis, J⁺(p_d − p) ≈ q_d − q; the joint path q_d
        itself is servoed (module docstring), u = u_ff − K_P e_q − K_D (q̇ − q̇_d)."""
        robot, v, e_q, desired = inp.robot, inp.v, inp.e_q, inp.desired
        g = self.gains
        u_pos = -(g.Kq @ e_q) - g.Dq @ (v - desired.qd)
        self.last_u_pos = u_pos
        if self.model_feedforward:
            u = u_pos + (robot.M @ desired.qdd + robot.C @ v + robot.g)
        else:
            u = u_pos + robot.g
        return Command(u0=u, B=None)

    def hybrid(self, inp: LawInput) -> Command:
        """Near (approach given): position along the surface, v_a across it. Contact: eq. 1–3."""
        robot, cons, v, e_q, desired, e_F, f_d, approach = _hybrid_input(inp)
        assert desired.p is not None and desired.pd is not None and desired.pdd is not None
        N = self.normals(robot.p)
        S = selection_matrix(N)
        u_ff, u_fb = self._motion(robot, v, e_q, desired, S)
        if approach is not None:
            u = u_ff + u_fb
            u += self._approach(robot, cons, v, u, approach)
            return Command(u0=u, B=None)
        g = self.gains
        if g.decouple:  # the feedback may not change the contact force (module docstring)
            MinvAT = np.linalg.solve(robot.M, cons.A.T)
            u_fb = u_fb - cons.A.T @ np.linalg.solve(cons.A @ MinvAT, MinvAT.T @ u_fb)
        # D_n = (ω_p + ω_d) × the tip's inertia along the normals, (Nᵀ J M⁻¹ Jᵀ N)⁻¹
        JN = robot.J.T @ N
        Dn = (g.position_rate + g.damping_rate) * np.linalg.inv(JN.T @ np.linalg.solve(robot.M, JN))
        u = u_ff + u_fb
        u -= cons.A.T @ ((1.0 + g.kp) * f_d - g.ki * e_F)
        u -= JN @ (Dn @ (N.T @ robot.pdot))
        B = g.kp * cons.A.T if g.kp > 0 else None
        return Command(u0=u, B=B)

    def _motion(
        self, robot: RobotTerms, v: np.ndarray, e_q: np.ndarray, desired: Desired, S: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(u_ff, u_pos + the redundant directions' hold) (n,) each, for the selection S (3, 3)
        (eq. 2 or 3)."""
        assert desired.p is not None and desired.pd is not None and desired.pdd is not None
        g = self.gains
        J = robot.J
        e = S @ (desired.p - robot.p)
        e_dot = S @ (desired.pd - robot.pdot)
        J_pinv = pseudo_inverse(J)
        if self.original:
            u_fb = g.Kq @ (J_pinv @ e) + g.Dq @ (J_pinv @ e_dot)
        else:
            u_fb = J.T @ (S @ (g.Kx @ e + g.Dx @ e_dot))
        self.last_u_pos = u_fb
        if self.model_feedforward:
            u_ff = robot.M @ (J_pinv @ (desired.pdd - robot.Jdot_v)) + robot.C @ v + robot.g
        else:
            u_ff = robot.g
        if self.redundant:  # the self-motion follows q_d (module docstring)
            null = np.eye(J.shape[1]) - J_pinv @ J
            u_fb = u_fb + null @ (-(g.Kq @ e_q) - g.Dq @ (v - desired.qd))
            if self.model_feedforward:
                u_ff = u_ff + robot.M @ (null @ desired.qdd)
        return u_ff, u_fb

    def _approach(
        self,
        robot: RobotTerms,
        cons: ConstraintTerms,
        v: np.ndarray,
        u: np.ndarray,
        approach: np.ndarray,
    ) -> np.ndarray:
        """The near phase's normal torque Aᵀ w (n,). The rows' rate r = A q̇ (= ḋ [m/s] for the
        "tip" scaling) accelerates, under the model, as ṙ = A M⁻¹(u − C q̇ − g) + Ȧ q̇ with the
        torque u (n,); w sets ṙ = −λ_a r + ω_d (v_a − r) instead, so that d̈ + (λ_a + ω_d) ḋ
        + λ_a ω_d d = 0: the tip lands at ḋ ≈ −λ_a d (module docstring)."""
        M, A, rate = robot.M, cons.A, cons.rate
        MinvAT = np.linalg.solve(M, A.T)
        now = A @ np.linalg.solve(M, u - robot.C @ v - robot.g) + cons.Adot @ v
        wanted = -self.approach_rate * rate + self.gains.damping_rate * (approach - rate)
        return A.T @ np.linalg.solve(A @ MinvAT, wanted - now)

    def normals(self, p: np.ndarray) -> np.ndarray:
        """(3, k) the surfaces' unit normals ∇Φ/‖∇Φ‖ at the tip p (3,) [m], as columns."""
        N = np.empty((3, len(self.surfaces)))
        for i, surface in enumerate(self.surfaces):
            gradient = surface.evaluate(p)[1]
            N[:, i] = gradient / math.sqrt(float(gradient @ gradient))
        return N


class AdaptiveArimotoLaw(AdaptiveArimotoWorkspace):
    """The adaptive law (hybrid_force.control.laws.arimoto_adaptive) in numpy: the oracle of
    :class:`AdaptiveArimotoWorkspace` (its settings and reports; its own arguments).

    Args:
        robot: the controller's model of the arm (its kinematics and parameter layout).
        gains: K_d, Λ, β, γ of the paper's law.
        adaptation: θ̂(0), Γ and which parameters adapt (:func:`make_adaptation`).

    Attributes:
        theta: (p,) the current estimates θ̂ (updated by :meth:`update`).
        sigma: σ of the gain schedule Γ = σ Γ₀ at the last call (non-decreasing, ≤ 1).
        V: ½ sᵀ M̂ s + ½ β e_Fᵀ e_F [J] at the last call.
    """

    sigma: float = 0.0  # (the workspace's property, here a plain attribute)

    def __init__(self, robot: Robot, gains: Gains, adaptation: Adaptation) -> None:
        self.gains = gains
        self.adaptation = adaptation
        self.regressor = SlotineLiRegressor(robot.model)
        self.theta = adaptation.theta0.copy()
        self.V = 0.0
        self._model = robot.model
        self._euclidean = robot.euclidean
        self._adapted = np.flatnonzero(adaptation.adapted)
        # the last call's Y₀ᵀ s (p,) and (β Y_M(q, A⁺_j))ᵀ s (k, p): update() needs only these,
        # since Y(q̈_r0 + β A⁺ f)ᵀ s = Y₀ᵀ s + Σ_j f_j (β Y_M(q, A⁺_j))ᵀ s
        self._gradient: np.ndarray | None = None
        self._gradient_f: np.ndarray | None = None
        self._ref: ControlTrace | None = None  # the paper's law's trace of the last call
        self.sigma = 0.0
        self._z_min = np.inf  # min over the past of Z = ½ wᵀ M w [J]

    # ------------------------------------------------------------------ the law
    def free_space(self, inp: LawInput) -> Command:
        """Eq. 29–30 adapted: u = Y(q, q̇, q̇_r, q̈_r) θ̂ − K_d s, q̇_r = q̇_d − Λ e_q."""
        robot, v, e_q, desired = inp.robot, inp.v, inp.e_q, inp.desired
        _, ref = free_space_law(self.gains, robot, v, e_q, desired)  # q̇_r, q̈_r, s of eq. 29
        q = self._configuration(desired.q, e_q)
        Y = self.regressor(q, v, ref.qdot_r, ref.qddot_r0)
        return self._command(robot, q, Y, ref, desired, None, None)

    def hybrid(self, inp: LawInput) -> Command:
        """Eq. 4, 8, 11 adapted (module docstring); the same arguments as the paper's law.

        q̇_r, q̈_r (at f = 0) and s are the paper's law's own (:func:`~.arimoto.arimoto_law`,
        whose torque with the model's M, C, g is not used)."""
        robot, cons, v, e_q, desired, e_F, f_d, approach = _hybrid_input(inp)
        g = self.gains
        _, ref = arimoto_law(g, robot, cons, v, e_q, desired, e_F, f_d, approach)
        q = self._configuration(desired.q, e_q)
        Y = self.regressor(q, v, ref.qdot_r, ref.qddot_r0)
        force = cons.A.T @ (f_d - g.gamma * e_F)
        command = self._command(
            robot, q, Y, ref, desired, cons.A_pinv if g.beta > 0 else None, force
        )
        self.V += 0.5 * g.beta * float(e_F @ e_F)
        return command

    def _command(
        self,
        robot: RobotTerms,
        q: np.ndarray,
        Y: np.ndarray,
        ref: ControlTrace,
        desired: Desired,
        Ap: np.ndarray | None,
        force: np.ndarray | None,
    ) -> Command:
        """u0 = Y θ̂ − K_d s − force (n,) and B = β M̂ A⁺ (None without Ap (n, k)); keeps what
        update() and trace() need, advances the schedule, sets V = ½ sᵀ M̂ s."""
        theta, s = self.theta, ref.s
        self._gradient, self._gradient_f, B = Y.T @ s, None, None
        if Ap is not None:
            # β M̂ A⁺ column by column: the f-dependent part of Y θ̂ (q̈_r ∋ β A⁺ f)
            beta, k = self.gains.beta, Ap.shape[1]
            B, self._gradient_f = np.empty((Ap.shape[0], k)), np.empty((k, theta.size))
            for j in range(k):
                Yj = self.regressor.inertial(q, Ap[:, j])
                B[:, j] = beta * (Yj @ theta)
                self._gradient_f[j] = beta * (Yj.T @ s)
        self._schedule(robot.M, ref.qdot_r - desired.qd)
        self.V = self._kinetic(q, s)
        self._ref = ref
        u0 = Y @ theta - self.gains.Kd @ s
        return Command(u0=u0 if force is None else u0 - force, B=B)

    def update(self, dt: float, f: np.ndarray) -> None:
        """θ̂ += dt · (−σ Γ₀ Yᵀ s) with the last call's Y at q̈_r(f), f (k,) [N] the force it
        met; then the masses are clipped to their floor (explicit Euler, then projection)."""
        if self._gradient is None:
            return
        gradient = (
            self._gradient if self._gradient_f is None else self._gradient + f @ self._gradient_f
        )
        theta, a = self.theta, self.adaptation
        theta -= (dt * self.sigma) * a.Gamma * gradient
        np.maximum(theta, a.floor, out=theta)

    # ------------------------------------------------------------------ reports
    def trace(self, e_q: np.ndarray, e_F: np.ndarray, f_d: np.ndarray) -> ControlTrace:
        """The :class:`ControlTrace` of the last call (V without the parameter term), with its
        e_q (n,), e_F (k,) and f_d (k,) copied (those of the free-space law are empty)."""
        assert self._ref is not None
        ref = self._ref
        if ref.qddot_r_f is None:  # free space
            return dataclasses.replace(ref, e_q=e_q.copy(), V=self.V)
        return dataclasses.replace(ref, e_q=e_q.copy(), e_F=e_F.copy(), f_d=f_d.copy(), V=self.V)

    # ------------------------------------------------------------------ helpers
    def _configuration(self, q_d: np.ndarray, e_q: np.ndarray) -> np.ndarray:
        """q from q_d and e_q = q ⊖ q_d (the law's interface passes the error, not q)."""
        return q_d + e_q if self._euclidean else pin.integrate(self._model, q_d, e_q)

    def _kinetic(self, q: np.ndarray, s: np.ndarray) -> float:
        """½ sᵀ M̂(q) s [J] with the estimated mass matrix."""
        return 0.5 * float(s @ (self.regressor.inertial(q, s) @ self.theta))

    def _schedule(self, M: np.ndarray, w: np.ndarray) -> None:
        """σ = min(1, Z_ref / min_{τ≤t} Z) with Z = ½ wᵀ M w, w = q̇_r − q̇_d (n,) and M (n, n)
        the controller's model (module docstring): it only ever grows."""
        z = 0.5 * float(w @ M @ w)
        if z < self._z_min:
            self._z_min = z
            z_ref = self.adaptation.energy
            self.sigma = 1.0 if z <= z_ref else z_ref / z


def oracle_of(law: Law, robot: Robot) -> Law:
    """The numpy oracle of a package law as built for a run (the same gains and settings);
    ``robot`` is the controller's model of the arm."""
    if isinstance(law, LawWorkspace):
        return ReferenceLaw(robot.nv, law._matrices.shape[2], law.gains)
    if isinstance(law, OscHybridWorkspace):
        return OscHybridLaw(law.gains, law.constraint, robot.nv)
    if isinstance(law, ImpedanceWorkspace):
        return ImpedanceLaw(law.gains, law.constraint, law.preload.shape[0])
    if isinstance(law, RaibertCraigWorkspace):
        return RaibertCraigLaw(law.gains, law.surfaces, law.approach_rate)
    if isinstance(law, AdaptiveArimotoWorkspace):
        return AdaptiveArimotoLaw(robot, law.gains, law.adaptation)
    raise TypeError(f"no oracle for the law {type(law).__name__}")

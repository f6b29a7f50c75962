"""Compiled algebra of the adaptive Arimoto law's step (Numba): the paper's reference
velocities with the inputs of the regressor's passes, the bookkeeping around Pinocchio's
joint-torque regressor (Y θ̂, Yᵀ s, β M̂ A⁺, the gain schedule, V) and the parameter update
θ̂̇ = −σ Γ₀ Yᵀ s with the masses' projection.

Reference, the readable numpy version: :class:`hybrid_force.control.laws.arimoto_adaptive.
AdaptiveArimotoLaw` (the regressor of :class:`hybrid_force.model.regressor.SlotineLiRegressor`,
three passes). The compiled law
(:class:`~hybrid_force.control.laws.arimoto_adaptive.AdaptiveArimotoWorkspace`) calls Pinocchio
between :func:`reference_velocities` and :func:`adaptive_command`, with the Slotine–Li
regressor in two passes instead of three: c(q, v) is quadratic in v, so ¼ [c(v + w) − c(v − w)]
= c((v + w)/2) − c((v − w)/2), and with the model's gravity in the first pass

    Y(q, q̇, q̇_r, q̈_r) = Y_rnea(q, (q̇ + q̇_r)/2, q̈_r) − Y⁰_rnea(q, (q̇ − q̇_r)/2, 0)

((q̇ − q̇_r)/2 = s/2; halving is exact in floating point). V's ½ sᵀ M̂ s is Pinocchio's kinetic
energy regressor at s times θ̂ (one forward pass, not a regressor pass).
``tests/test_arimoto_adaptive_kernel.py`` checks the compiled law against the reference.

Compiled with :data:`hybrid_force._jit.jit`, whose module says why and by which conventions.
"""

from __future__ import annotations

import numpy as np

from hybrid_force._jit import jit as _jit
from hybrid_force.control._kernels import arimoto


@_jit
def reference_velocities(
    M: np.ndarray,
    C: np.ndarray,
    g: np.ndarray,
    Kd: np.ndarray,
    Q: np.ndarray,
    Qdot: np.ndarray,
    Ap: np.ndarray,
    Apd: np.ndarray,
    A: np.ndarray,
    v: np.ndarray,
    e_q: np.ndarray,
    q_d: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray,
    lam: float,
    beta: float,
    gamma: float,
    euclidean: bool,
    vectors: np.ndarray,
    matrices: np.ndarray,
    halves: np.ndarray,
    q: np.ndarray,
) -> None:
    """The paper's law's q̇_r, q̈_r0, s, s0, s1 (its kernel ``control._kernels.arimoto``, whose
    u0 with the model's M, C, g is not used) and the regressor's inputs.

    The arguments up to gamma and vectors (6, n), matrices (2, n, k) are ``arimoto``'s (the
    free-space law: Q = I, Q̇ = 0, k = 0). q_d: (nq,). Writes halves (2, n) = (q̇ + q̇_r)/2,
    s/2 = (q̇ − q̇_r)/2 and, when ``euclidean``, q = q_d + e_q (nq = n; else q is left as is).
    """
    arimoto(
        M, C, g, Kd, Q, Qdot, Ap, Apd, A, v, e_q, qd, qdd, e_F, f_d, approach, lam, beta,
        gamma, vectors, matrices,
    )  # fmt: skip
    s, qdot_r = vectors[1], vectors[4]
    w_plus, w_minus = halves[0], halves[1]
    n = v.shape[0]
    for i in range(n):
        w_plus[i] = 0.5 * (v[i] + qdot_r[i])
        w_minus[i] = 0.5 * s[i]
    if euclidean:
        for i in range(n):
            q[i] = q_d[i] + e_q[i]


@_jit
def adaptive_command(
    Y_plus: np.ndarray,
    Y_minus: np.ndarray,
    Y_A: np.ndarray,
    kinetic: np.ndarray,
    theta: np.ndarray,
    Kd: np.ndarray,
    M: np.ndarray,
    A: np.ndarray,
    vectors: np.ndarray,
    qd: np.ndarray,
    e_F: np.ndarray,
    f_d: np.ndarray,
    beta: float,
    gamma: float,
    energy: float,
    state: np.ndarray,
    u0: np.ndarray,
    B: np.ndarray,
    gradient: np.ndarray,
    gradient_f: np.ndarray,
) -> float:
    """u0 = Y θ̂ − K_d s − Aᵀ(f_d − γ e_F), B = β M̂ A⁺, what the update needs, σ and V.

    Y_plus, Y_minus: (n, p) the two passes, Y = Y_plus − Y_minus (module docstring).
    Y_A: (k, n, p) Y_M(q, A⁺_j) = Y⁰_rnea(q, 0, A⁺_j). kinetic: (p,) the kinetic energy
    regressor at s. theta: (p,) θ̂. Kd, M: (n, n) K_d and the controller's model M(q).
    A: (k, n). vectors: (6, n) of :func:`reference_velocities` (s = row 1, q̇_r = row 4).
    qd: (n,) q̇_d. e_F, f_d: (k,) (k = 0 in free space). energy: Z_ref [J].
    state: (2,) σ and min Z of the schedule, updated here (σ = min(1, Z_ref / min_{τ≤t} Z),
    Z = ½ wᵀ M w, w = q̇_r − q̇_d). Writes u0 (n,), B (n, k) = β Y_A[j] θ̂ by columns,
    gradient (p,) = Yᵀ s and gradient_f (k, p) = β Y_A[j]ᵀ s. Returns
    V = ½ sᵀ M̂ s + ½ β e_Fᵀ e_F [J].
    """
    s, qdot_r = vectors[1], vectors[4]
    n, p = Y_plus.shape
    k = e_F.shape[0]
    for j in range(p):
        gradient[j] = 0.0
    for i in range(n):
        acc = 0.0
        si = s[i]
        for j in range(p):
            y = Y_plus[i, j] - Y_minus[i, j]
            acc += y * theta[j]
            gradient[j] += y * si
        kd = 0.0
        for j in range(n):
            kd += Kd[i, j] * s[j]
        force = 0.0
        for m in range(k):
            force += A[m, i] * (f_d[m] - gamma * e_F[m])
        u0[i] = acc - kd - force
    for m in range(k):
        Ym = Y_A[m]
        for j in range(p):
            gradient_f[m, j] = 0.0
        for i in range(n):
            acc = 0.0
            si = s[i]
            for j in range(p):
                y = Ym[i, j]
                acc += y * theta[j]
                gradient_f[m, j] += y * si
            B[i, m] = beta * acc
        for j in range(p):
            gradient_f[m, j] *= beta
    z = 0.0
    for i in range(n):
        mw = 0.0
        for j in range(n):
            mw += M[i, j] * (qdot_r[j] - qd[j])
        z += (qdot_r[i] - qd[i]) * mw
    z *= 0.5
    if z < state[1]:
        state[1] = z
        state[0] = 1.0 if z <= energy else energy / z
    V = 0.0
    for j in range(p):
        V += kinetic[j] * theta[j]
    eF2 = 0.0
    for m in range(k):
        eF2 += e_F[m] * e_F[m]
    return V + 0.5 * beta * eF2


@_jit
def adaptive_update(
    gradient: np.ndarray,
    gradient_f: np.ndarray,
    f: np.ndarray,
    step: float,
    Gamma: np.ndarray,
    floor: np.ndarray,
    theta: np.ndarray,
) -> None:
    """θ̂ ← max(θ̂ − step Γ₀ (Yᵀ s), floor) with Yᵀ s = gradient + fᵀ gradient_f (explicit Euler,
    then the masses' projection). gradient, Gamma, floor, theta: (p,). gradient_f: (k, p),
    f: (k,) [N] the force met (k = 0 after the free-space law). step = dt σ [s]."""
    p = theta.shape[0]
    k = f.shape[0]
    for j in range(p):
        y = gradient[j]
        for m in range(k):
            y += f[m] * gradient_f[m, j]
        t = theta[j] - step * Gamma[j] * y
        theta[j] = floor[j] if t < floor[j] else t  # a NaN stays NaN, as np.maximum

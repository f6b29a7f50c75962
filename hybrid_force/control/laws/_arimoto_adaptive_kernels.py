"""Compiled algebra of the adaptive Arimoto law's step (Numba): the paper's reference
velocities with the inputs of the regressor's passes, the bookkeeping around Pinocchio's
joint-torque regressor (Y θ̂, Yᵀ s, β M̂ A⁺, the gain schedule, V) and the parameter update
θ̂̇ = −σ Γ₀ Yᵀ s with the masses' projection.

Its oracle, the readable numpy version, is ``AdaptiveArimotoLaw`` of tests/oracles/laws.py (the
regressor of :class:`hybrid_force.model.regressor.SlotineLiRegressor`, three passes). The compiled
law (:class:`~hybrid_force.control.laws.arimoto_adaptive.AdaptiveArimotoWorkspace`) calls Pinocchio
between :func:`reference_velocities` and :func:`adaptive_command`, with the Slotine–Li regressor in
two passes instead of three: c(q, v) is quadratic in v, so ¼ [c(v + w) − c(v − w)] = c((v + w)/2) −
c((v − w)/2), and with the model's gravity in the first pass

    Y(q, q̇, q̇_r, q̈_r) = Y_rnea(q, (q̇ + q̇_r)/2, q̈_r) − Y⁰_rnea(q, (q̇ − q̇_r)/2, 0)

((q̇ − q̇_r)/2 = s/2; halving is exact in floating point). V's ½ sᵀ M̂ s is Pinocchio's kinetic
energy regressor at s times θ̂ (one forward pass, not a regressor pass).
``tests/test_arimoto_adaptive_kernel.py`` checks the compiled law against the oracle.

Compiled with :data:`hybrid_force._jit.jit`, whose module says why and by which conventions.
"""

from __future__ import annotations

import numpy as np

from hybrid_force._jit import jit as _jit
from hybrid_force._jit import jit_inline as _inline
from hybrid_force.control._kernels import (
    constraint_parts,
    desired_parts,
    reference,
    steady_inputs,
    steady_parts,
)
from hybrid_force.control._linalg_kernels import dot

#: Layout of the law's parameter vector ``params`` (7,): the gains, whether q = q_d + e_q, Z_ref,
#: and the gain schedule's state σ and min_{τ≤t} Z, which :func:`adaptive_command` updates.
LAMBDA, BETA, GAMMA, EUCLIDEAN, ENERGY, SIGMA, Z_MIN = range(7)


@_jit
def reference_velocities(
    Q: np.ndarray,
    Qdot: np.ndarray,
    Ap: np.ndarray,
    Apd: np.ndarray,
    v: np.ndarray,
    e_q: np.ndarray,
    q_d: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray,
    params: np.ndarray,
    vectors: np.ndarray,
    matrices: np.ndarray,
    q: np.ndarray,
) -> None:
    """The paper's law's q̇_r, q̈_r0, s, s0, s1 (its reference motion,
    ``control._kernels.reference``) and the regressor's inputs.

    Q, Qdot: (n, n). v, e_q, qd, qdd: (n,). Ap, Apd: (n, k). e_F, f_d, approach: (k,) (the
    free-space law: Q = I, Q̇ = 0, k = 0). q_d: (nq,). params: (7,) (Λ, β, γ, 1.0 when
    q = q_d + e_q, …: the module's layout). Writes rows 1..7 of vectors (8, n): s, s0, s1,
    q̇_r, q̈_r0 (the paper's law's rows), (q̇ + q̇_r)/2, s/2 = (q̇ − q̇_r)/2 (row 0, u0, is
    :func:`adaptive_command`'s); matrices[1] (n, k) = q̈_r,f = β A⁺ (matrices[0] is not
    used); and, when params[EUCLIDEAN] is 1, q = q_d + e_q (nq = n; else q is left as is).
    """
    reference(
        Q, Qdot, Ap, Apd, v, e_q, qd, qdd, e_F, f_d, approach, params[LAMBDA], params[BETA],
        vectors, matrices,
    )  # fmt: skip
    s, qdot_r = vectors[1], vectors[4]
    w_plus, w_minus = vectors[6], vectors[7]
    n = v.shape[0]
    for i in range(n):
        w_plus[i] = 0.5 * (v[i] + qdot_r[i])
        w_minus[i] = 0.5 * s[i]
    if params[EUCLIDEAN] != 0.0:
        for i in range(n):
            q[i] = q_d[i] + e_q[i]


@_inline
def _regress_into(
    Y: np.ndarray,
    Y_minus: np.ndarray,
    minus: bool,
    theta: np.ndarray,
    s: np.ndarray,
    out: np.ndarray,
    gradient: np.ndarray,
) -> None:
    """out (n,) = Y θ̂ and gradient (p,) = Yᵀ s for a regressor Y (n, p), less Y_minus (n, p)
    when ``minus`` (the two passes' difference, formed entry by entry; a constant at each
    call, so the inlined loop has no test)."""
    n, p = Y.shape
    for j in range(p):
        gradient[j] = 0.0
    for i in range(n):
        acc = 0.0
        si = s[i]
        for j in range(p):
            y = Y[i, j] - Y_minus[i, j] if minus else Y[i, j]
            acc += y * theta[j]
            gradient[j] += y * si
        out[i] = acc


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
    qd: np.ndarray,
    e_F: np.ndarray,
    f_d: np.ndarray,
    params: np.ndarray,
    vectors: np.ndarray,
    B: np.ndarray,
    gradients: np.ndarray,
) -> float:
    """u0 = Y θ̂ − K_d s − Aᵀ(f_d − γ e_F), B = β M̂ A⁺, what the update needs, σ and V.

    Y_plus, Y_minus: (n, p) the two passes, Y = Y_plus − Y_minus (module docstring).
    Y_A: (k, n, p) Y_M(q, A⁺_j) = Y⁰_rnea(q, 0, A⁺_j). kinetic: (p,) the kinetic energy
    regressor at s. theta: (p,) θ̂. Kd, M: (n, n) K_d and the controller's model M(q).
    A: (k, n). qd: (n,) q̇_d. e_F, f_d: (k,) (k = 0 in free space). params: (7,) (the module's
    layout); its σ and min Z are updated here: σ = min(1, Z_ref / min_{τ≤t} Z), Z = ½ wᵀ M w,
    w = q̇_r − q̇_d. vectors: (8, n) of :func:`reference_velocities` (s = row 1, q̇_r = row 4);
    u0 (n,) is written into its row 0. Writes B (n, k) = β Y_A[j] θ̂ by columns and gradients
    (1 + k, p): Yᵀ s, then β Y_A[j]ᵀ s. Returns V = ½ sᵀ M̂ s + ½ β e_Fᵀ e_F [J].
    """
    u0, s, qdot_r = vectors[0], vectors[1], vectors[4]
    beta, gamma, energy = params[BETA], params[GAMMA], params[ENERGY]
    n, p = Y_plus.shape
    k = e_F.shape[0]
    _regress_into(Y_plus, Y_minus, True, theta, s, u0, gradients[0])  # Y = Y_plus − Y_minus
    for i in range(n):
        kd = 0.0
        for j in range(n):
            kd += Kd[i, j] * s[j]
        force = 0.0
        for m in range(k):
            force += A[m, i] * (f_d[m] - gamma * e_F[m])
        u0[i] = u0[i] - kd - force
    for m in range(k):
        gradient_f = gradients[1 + m]
        _regress_into(Y_A[m], Y_plus, False, theta, s, B[:, m], gradient_f)
        for i in range(n):
            B[i, m] = beta * B[i, m]
        for j in range(p):
            gradient_f[j] *= beta
    z = 0.0  # ½ wᵀ M w, w = q̇_r − q̇_d formed in the loop (quad_form would need it stored)
    for i in range(n):
        mw = 0.0
        for j in range(n):
            mw += M[i, j] * (qdot_r[j] - qd[j])
        z += (qdot_r[i] - qd[i]) * mw
    z *= 0.5
    if z < params[Z_MIN]:
        params[Z_MIN] = z
        params[SIGMA] = 1.0 if z <= energy else energy / z
    return dot(kinetic, theta) + 0.5 * beta * dot(e_F, e_F)


@_jit
def adaptive_update(
    gradients: np.ndarray,
    f: np.ndarray,
    dt: float,
    params: np.ndarray,
    Gamma: np.ndarray,
    floor: np.ndarray,
    theta: np.ndarray,
) -> None:
    """θ̂ ← max(θ̂ − dt σ Γ₀ (Yᵀ s), floor) with Yᵀ s = gradients[0] + Σ_j f_j gradients[1 + j]
    (explicit Euler, then the masses' projection). gradients: (1 + k, p) of
    :func:`adaptive_command`; f: (k,) [N] the force met (k = 0 after the free-space law);
    dt [s]; params: (7,), σ = params[SIGMA]. Gamma, floor, theta: (p,)."""
    p = theta.shape[0]
    k = f.shape[0]
    step = dt * params[SIGMA]
    for j in range(p):
        y = gradients[0, j]
        for m in range(k):
            y += f[m] * gradients[1 + m, j]
        t = theta[j] - step * Gamma[j] * y
        theta[j] = floor[j] if t < floor[j] else t  # a NaN stays NaN, as np.maximum


# --- the steady contact step on packs (Law.hybrid_at; control._kernels "packs") -------------
def workspace_size(n: int, nq: int, k: int, p: int) -> int:
    """Length of the law's own flat buffer (:func:`workspace_parts`)."""
    return 3 + 7 + 8 * n + 2 * n * k + n * k + (1 + k) * p + 3 * p + n * n + k + nq


@_inline
def workspace_parts(
    ws: np.ndarray, n: int
) -> tuple[
    np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
    np.ndarray, np.ndarray, np.ndarray, np.ndarray,
]:  # fmt: skip
    """Views of the law's own buffer ws (:func:`workspace_size`): ws[0] = k, ws[1] = p,
    ws[2] = nq, then params (7,), vectors (8, n), matrices (2, n, k), B (n, k), gradients
    (1 + k, p), θ̂, Γ₀, floor (p,), K_d (n, n), zeros (k,) and the configuration buffer q
    (nq,) of the passes, returned in that order."""
    k, p, nq = int(ws[0]), int(ws[1]), int(ws[2])
    o = 3
    params = ws[o : o + 7]
    o += 7
    vectors = ws[o : o + 8 * n].reshape((8, n))
    o += 8 * n
    matrices = ws[o : o + 2 * n * k].reshape((2, n, k))
    o += 2 * n * k
    B = ws[o : o + n * k].reshape((n, k))
    o += n * k
    gradients = ws[o : o + (1 + k) * p].reshape((1 + k, p))
    o += (1 + k) * p
    theta = ws[o : o + p]
    o += p
    Gamma = ws[o : o + p]
    o += p
    floor = ws[o : o + p]
    o += p
    Kd = ws[o : o + n * n].reshape((n, n))
    o += n * n
    zeros = ws[o : o + k]
    o += k
    return params, vectors, matrices, B, gradients, theta, Gamma, floor, Kd, zeros, ws[o : o + nq]


@_jit
def reference_steady(
    q: np.ndarray,
    v: np.ndarray,
    flat: np.ndarray,
    desired: np.ndarray,
    steady: np.ndarray,
    ws: np.ndarray,
) -> None:
    """e_q = q − q_d into the supervisor's steady pack, then :func:`reference_velocities`
    (6 arguments, not 16). q, v: (n,) measured (a Euclidean arm); flat: the constraint
    terms' array (``control._kernels.constraint_parts``); desired: the desired motion's pack
    (``desired_parts``); steady: [e_q, e_F, f_d, …] (``steady_parts``); ws: the law's buffer
    (:func:`workspace_parts`; its q becomes q_d + e_q, as on the general path)."""
    n = v.shape[0]
    params, vectors, matrices, _, _, _, _, _, _, zeros, q_pass = workspace_parts(ws, n)
    k = zeros.shape[0]
    _, cols, squares, _ = constraint_parts(flat, k, n)
    e_q, e_F, f_d, q_d, qd, qdd, _ = steady_inputs(q, desired, steady, n, k)
    reference_velocities(
        squares[0], squares[1], cols[0], cols[1], v, e_q, q_d, qd, qdd, e_F, f_d, zeros,
        params, vectors, matrices, q_pass,
    )  # fmt: skip


@_jit
def command_steady(
    Y_plus: np.ndarray,
    Y_minus: np.ndarray,
    Y_A: np.ndarray,
    kinetic: np.ndarray,
    mats: np.ndarray,
    flat: np.ndarray,
    desired: np.ndarray,
    steady: np.ndarray,
    ws: np.ndarray,
) -> float:
    """:func:`adaptive_command` on packs (9 arguments, not 15): the passes as there, mats
    (2, n, n) = [M, C] the robot terms' pack, the rest as :func:`reference_steady`."""
    n = Y_plus.shape[0]
    params, vectors, _, B, gradients, theta, _, _, Kd, zeros, _ = workspace_parts(ws, n)
    k = zeros.shape[0]
    rows, _, _, _ = constraint_parts(flat, k, n)
    _, qd, _, _ = desired_parts(desired, n, n)
    _, e_F, f_d = steady_parts(steady, n, k)
    return adaptive_command(
        Y_plus, Y_minus, Y_A, kinetic, theta, Kd, mats[0], rows[2], qd, e_F, f_d, params,
        vectors, B, gradients,
    )  # fmt: skip


@_jit
def update_steady(ws: np.ndarray, n: int, f: np.ndarray, dt: float) -> None:
    """:func:`adaptive_update` after the hybrid law, on the law's buffer (3 arrays fewer)."""
    params, _, _, _, gradients, theta, Gamma, floor, _, _, _ = workspace_parts(ws, n)
    adaptive_update(gradients, f, dt, params, Gamma, floor, theta)

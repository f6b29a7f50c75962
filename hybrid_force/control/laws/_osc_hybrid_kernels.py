"""Compiled step of the operational-space hybrid law (Numba): Λ, J̄, N and the command.

Its oracle, the readable numpy version, is ``osc_hybrid_law`` of ``tests/oracles/laws.py``;
``tests/test_osc_hybrid_kernel.py`` checks the kernel against it. The small dense solves are
those of :mod:`hybrid_force.control._linalg_kernels`: a Cholesky factor of M for M⁻¹Jᵀ (an LU
factorisation when M has none), an LU factorisation with partial pivoting (as numpy's
``solve`` and ``inv``) for Λ = (J M⁻¹ Jᵀ)⁻¹ (3 × 3) and for (WᵀW)⁻¹Wᵀ (k × k).

Compiled with :data:`hybrid_force._jit.jit`, whose module says why and by which conventions.
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force._jit import jit as _jit
from hybrid_force.control._kernels import constraint_parts, steady_inputs
from hybrid_force.control._linalg_kernels import (
    cholesky,
    cholesky_solve_column,
    lu_solve_into,
    matvec_into,
    mul_into,
    rows3_dot,
)
from hybrid_force.geometry._kernels import surface_eval

# the modes of osc_hybrid (module docstring of osc_hybrid: eq. 3 and 4)
FREE_SPACE = 0
NEAR = 1
CONTACT = 2
# what osc_hybrid returns instead of a condition number when it cannot finish: M or WᵀW
# singular (numpy's "Singular matrix")
SINGULAR_MASS = -1.0
SINGULAR_NORMALS = -2.0


@_jit
def osc_hybrid(
    mats: np.ndarray,
    vecs: np.ndarray,
    jac: np.ndarray,
    tip: np.ndarray,
    v: np.ndarray,
    e_q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    p_d: np.ndarray,
    pd_d: np.ndarray,
    pdd_d: np.ndarray,
    descs: np.ndarray,
    grads: np.ndarray,
    scale: np.ndarray,
    rate: np.ndarray,
    drift: np.ndarray,
    A: np.ndarray,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray,
    mode: int,
    gains: np.ndarray,
    work: np.ndarray,
    vectors: np.ndarray,
    task: np.ndarray,
    Lambda: np.ndarray,
    Jbar: np.ndarray,
    W: np.ndarray,
    phi: np.ndarray,
    B: np.ndarray,
) -> float:
    """One step of the law (module docstring of osc_hybrid, eq. 1, 3–6).

    mats (2, n, n) = [M, C], vecs (2, n) = [g, nle], jac (2, 3, n) = [J, J̇], tip (3, 3) =
    [p, J̇ v, J v]: the packs of the controller's robot terms (``RobotTerms.zeros``).
    v, e_q, qd, qdd: (n,) q̇, q − q_d, q̇_d, q̈_d. p_d, pd_d, pdd_d: (3,) the task path.
    mode: FREE_SPACE (the k = 0 arrays below are not read), NEAR or CONTACT.
    descs (k, 10): each surface's descriptor (``Surface._descriptor``, zero-padded), or
    descs[i, 0] = −1 when grads[:, i] (3, k) holds its ∇Φ(p) (a surface without one).
    scale, rate, drift: (k,) s, A q̇, drift of the constraint terms; A (k, n) their rows.
    e_F, f_d, approach: (k,) (approach read only when NEAR).
    gains (8,) = [K_p, K_v, K_n, k_P, k_I, k_n, d_n, λ_a] (``OscGains`` in field order).
    work (n, n): scratch (the Cholesky factor of M).
    Writes vectors (2, n) = [u0, Nᵀτ₀], task (2, 3) = [a, F0], Lambda (3, 3), Jbar (n, 3),
    W (3, k) = ∇Φ_i / s_i, phi (k,) and, in CONTACT with k_P > 0, B (n, k) = k_P Aᵀ.

    Returns ‖S‖_F ‖S⁻¹‖_F of S = J M⁻¹ Jᵀ (``task_space``'s estimate of cond(S)); +inf when
    S is exactly singular, SINGULAR_MASS or SINGULAR_NORMALS (< 0) when M or WᵀW is exactly
    singular. The outputs are complete only when the value returned is >= 0 and below the
    caller's limit.
    """
    M = mats[0]
    nle = vecs[1]
    J = jac[0]
    p, Jdot_v, pdot = tip[0], tip[1], tip[2]
    u0, null_torque = vectors[0], vectors[1]
    a, F = task[0], task[1]
    n = v.shape[0]
    kp, kv, kn = gains[0], gains[1], gains[2]
    force_p, force_i = gains[3], gains[4]
    null_kp, null_kd, approach_rate = gains[5], gains[6], gains[7]
    # --- M⁻¹Jᵀ (n, 3) by the Cholesky factor L (lower, in work) of M = L Lᵀ, else by LU
    L = work
    X = np.empty((n, 3))  # M⁻¹Jᵀ
    if cholesky(M, L):
        for r in range(3):
            cholesky_solve_column(L, J[r], X, r)
    elif not lu_solve_into(M, J.T.copy(), X):  # M not positive definite: LU, as numpy's solve
        return SINGULAR_MASS
    # --- Λ = S⁻¹, S = J M⁻¹ Jᵀ, and the estimate of cond(S)
    S = np.empty((3, 3))
    mul_into(J, X, S, False, False)
    s_sq = 0.0
    for r in range(3):
        for c in range(3):
            s_sq += S[r, c] * S[r, c]
    eye = np.zeros((3, 3))
    for r in range(3):
        eye[r, r] = 1.0
    if not lu_solve_into(S, eye, Lambda):
        return math.inf
    l_sq = 0.0
    for r in range(3):
        for c in range(3):
            l_sq += Lambda[r, c] * Lambda[r, c]
    cond = math.sqrt(s_sq) * math.sqrt(l_sq)
    for i in range(n):  # J̄ = M⁻¹Jᵀ Λ
        for c in range(3):
            Jbar[i, c] = X[i, 0] * Lambda[0, c] + X[i, 1] * Lambda[1, c] + X[i, 2] * Lambda[2, c]
    # --- the task acceleration a (eq. 3–4) and force F (eq. 1, 5)
    for r in range(3):
        a[r] = pdd_d[r] - kv * (pdot[r] - pd_d[r]) - kp * (p[r] - p_d[r])
    k = phi.shape[0] if mode != FREE_SPACE else 0
    if k > 0:
        grad = np.empty(3)
        no_hess = np.empty((0, 0))
        for m in range(k):
            if descs[m, 0] >= 0.0:
                surface_eval(descs[m], p, grad, no_hess)
            else:
                for r in range(3):
                    grad[r] = grads[r, m]
            for r in range(3):
                W[r, m] = grad[r] / scale[m]
        P = np.empty((k, 3))  # (WᵀW)⁻¹Wᵀ
        if k == 1:
            ww = W[0, 0] * W[0, 0] + W[1, 0] * W[1, 0] + W[2, 0] * W[2, 0]
            for r in range(3):
                P[0, r] = W[r, 0] / ww
        else:
            WtW = np.empty((k, k))
            Wt = np.empty((k, 3))
            for m in range(k):
                for r in range(3):
                    Wt[m, r] = W[r, m]
                for c in range(k):
                    WtW[m, c] = W[0, m] * W[0, c] + W[1, m] * W[1, c] + W[2, m] * W[2, c]
            if not lu_solve_into(WtW, Wt, P):
                return SINGULAR_NORMALS
        Pa = np.empty(k)
        cx = np.empty(k)
        for m in range(k):
            Pa[m] = P[m, 0] * a[0] + P[m, 1] * a[1] + P[m, 2] * a[2]
            c = W[0, m] * Jdot_v[0] + W[1, m] * Jdot_v[1] + W[2, m] * Jdot_v[2] - drift[m]
            nu = rate[m]
            # contact: damp the normal speed; near: follow ν_a = −λ_a d (derivative −λ_a ν)
            x = -kn * nu if mode == CONTACT else kn * (approach[m] - nu) - approach_rate * nu
            cx[m] = c + x
            phi[m] = -f_d[m] + force_i * e_F[m] - force_p * f_d[m]
        for r in range(3):
            wpa = 0.0
            ptcx = 0.0
            for m in range(k):
                wpa += W[r, m] * Pa[m]
                ptcx += P[m, r] * cx[m]
            a[r] = a[r] - wpa + ptcx
    ad0 = a[0] - Jdot_v[0]
    ad1 = a[1] - Jdot_v[1]
    ad2 = a[2] - Jdot_v[2]
    for r in range(3):
        f = Lambda[r, 0] * ad0 + Lambda[r, 1] * ad1 + Lambda[r, 2] * ad2
        for m in range(k):
            f += W[r, m] * phi[m]
        F[r] = f
    if mode == CONTACT and force_p > 0.0:
        for i in range(n):
            for m in range(k):
                B[i, m] = force_p * A[m, i]
    # --- the null-space posture (eq. 6): Nᵀτ₀ = M (y − J̄ (J y))
    if n == 3:
        for i in range(n):
            null_torque[i] = 0.0
    else:
        y = np.empty(n)
        for i in range(n):
            y[i] = qdd[i] - null_kp * e_q[i] - null_kd * (v[i] - qd[i])
        Jy0, Jy1, Jy2 = rows3_dot(J, 0, y)
        z = np.empty(n)
        for i in range(n):
            z[i] = y[i] - (Jbar[i, 0] * Jy0 + Jbar[i, 1] * Jy1 + Jbar[i, 2] * Jy2)
        matvec_into(M, z, null_torque)
    # --- u0 = Jᵀ F + C q̇ + g + Nᵀτ₀
    for i in range(n):
        u0[i] = (J[0, i] * F[0] + J[1, i] * F[1] + J[2, i] * F[2]) + nle[i] + null_torque[i]
    return cond


# --- the steady contact step on packs (Law.hybrid_at; control._kernels "packs") -------------
def workspace_size(n: int, k: int, width: int) -> int:
    """Length of the law's own flat buffer (:func:`osc_steady`; width: the descriptors')."""
    return 3 + k * width + 3 * k + 8 + n * n + 2 * n + 6 + 9 + 3 * n + 3 * k + k + n * k + k


@_jit
def osc_steady(
    q: np.ndarray,
    v: np.ndarray,
    mats: np.ndarray,
    vecs: np.ndarray,
    jac: np.ndarray,
    tip: np.ndarray,
    flat: np.ndarray,
    desired: np.ndarray,
    steady: np.ndarray,
    ws: np.ndarray,
) -> float:
    """:func:`osc_hybrid` in CONTACT on packs (10 arguments, not 30): e_q = q − q_d written
    into the supervisor's steady pack, then the law. q, v: (n,) measured (a Euclidean arm);
    mats, vecs, jac, tip: the robot terms' packs; flat: the constraint terms' array (s, A q̇,
    drift, A); desired: the desired motion's pack; steady: [e_q, e_F, f_d, …]; ws: the law's
    buffer, ws[0:3] = k, n, the descriptors' width w, then descs (k, w), grads (3, k), gains
    (8,), work (n, n), vectors (2, n), task (2, 3), Λ (3, 3), J̄ (n, 3), W (3, k), φ (k,),
    B (n, k), zeros (k,)."""
    n = v.shape[0]
    k, w = int(ws[0]), int(ws[2])
    o = 3
    descs = ws[o : o + k * w].reshape((k, w))
    o += k * w
    grads = ws[o : o + 3 * k].reshape((3, k))
    o += 3 * k
    gains = ws[o : o + 8]
    o += 8
    work = ws[o : o + n * n].reshape((n, n))
    o += n * n
    vectors = ws[o : o + 2 * n].reshape((2, n))
    o += 2 * n
    task = ws[o : o + 6].reshape((2, 3))
    o += 6
    Lambda = ws[o : o + 9].reshape((3, 3))
    o += 9
    Jbar = ws[o : o + 3 * n].reshape((n, 3))
    o += 3 * n
    W = ws[o : o + 3 * k].reshape((3, k))
    o += 3 * k
    phi = ws[o : o + k]
    o += k
    B = ws[o : o + n * k].reshape((n, k))
    o += n * k
    zeros = ws[o : o + k]
    rows, _, _, scalars = constraint_parts(flat, k, n)
    e_q, e_F, f_d, _, qd, qdd, sample = steady_inputs(q, desired, steady, n, k)
    return osc_hybrid(
        mats, vecs, jac, tip, v, e_q, qd, qdd, sample[0], sample[1], sample[2], descs, grads,
        scalars[2], scalars[3], scalars[5], rows[2], e_F, f_d, zeros, CONTACT, gains, work,
        vectors, task, Lambda, Jbar, W, phi, B,
    )  # fmt: skip

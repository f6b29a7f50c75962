"""Compiled algebra of the raibert_craig law's step (Numba), beside its concept.

Their oracle, the readable numpy version, is ``RaibertCraigLaw`` of ``tests/oracles/laws.py``;
:class:`~hybrid_force.control.laws.raibert_craig.RaibertCraigWorkspace` calls these kernels,
one call per step, and ``tests/test_raibert_craig_kernel.py`` checks them against it.

The same formulas as the oracle, written as loops: the selection S = I − N (NᵀN)⁻¹ Nᵀ
from the surfaces' unit normals at the tip, J⁺ = Jᵀ (J Jᵀ)⁻¹, the position part (eq. 2 or 3),
the feed-forward, the redundant directions' hold (I − J⁺J)(…) (applied as x − J⁺(J x), the
matrix is not formed), the near phase's normal torque and in contact the projection P, the
normal damper D_n and the force terms. Every solve is an LU factorisation with partial
pivoting (:func:`~hybrid_force.control._linalg_kernels.lu_factor`); the products by inverses
of the oracle ((J Jᵀ)⁻¹, D_n = (ω_p + ω_d) H⁻¹) are solves here, equal to round-off. At a
singularity (J Jᵀ with a zero pivot) J⁺ is the SVD's pseudo-inverse; any other zero pivot makes
the kernel return SINGULAR_OTHER without finishing, and the caller raises numpy's error.

Compiled with :data:`hybrid_force._jit.jit`, whose module says why and by which conventions
(outputs preallocated and passed last, no fastmath).
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force._jit import jit as _jit
from hybrid_force._jit import jit_inline as _inline
from hybrid_force.control._kernels import constraint_parts, steady_inputs
from hybrid_force.control._linalg_kernels import (
    eye_minus,
    lu_factor,
    lu_solve,
    matvec2_into,
    mul_into,
    rows3_dot,
)
from hybrid_force.geometry._kernels import surface_eval

OK = 0
SINGULAR_OTHER = 2  # M, A M⁻¹ Aᵀ, NᵀN or Nᵀ J M⁻¹ Jᵀ N has a zero pivot (numpy's LinAlgError)


@_jit
def _null_apply(J: np.ndarray, Jp: np.ndarray, x: np.ndarray) -> None:
    """x (n,) ← (I − J⁺J) x = x − J⁺ (J x), J (3, n), J⁺ (n, 3)."""
    n = x.shape[0]
    y0, y1, y2 = rows3_dot(J, 0, x)
    for i in range(n):
        x[i] -= Jp[i, 0] * y0 + Jp[i, 1] * y1 + Jp[i, 2] * y2


@_inline
def _joint_feedback(
    Kq: np.ndarray, Dq: np.ndarray, e_q: np.ndarray, v: np.ndarray, qd: np.ndarray, out: np.ndarray
) -> None:
    """out (n,) = −K_P e_q − K_D (q̇ − q̇_d): the joint PD of the free space and of the
    redundant directions."""
    n = v.shape[0]
    for i in range(n):
        a = 0.0
        b = 0.0
        for j in range(n):
            a += Kq[i, j] * e_q[j]
            b += Dq[i, j] * (v[j] - qd[j])
        out[i] = -a - b


@_jit
def free_space(
    mats: np.ndarray,
    vecs: np.ndarray,
    gains: np.ndarray,
    v: np.ndarray,
    e_q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    model_feedforward: bool,
    vectors: np.ndarray,
) -> None:
    """The free-space law: u = u_ff − K_P e_q − K_D (q̇ − q̇_d).

    mats (2, n, n) = [M, C], vecs (2, n) = [g, nle] (``RobotTerms.zeros``' packs), gains
    (2, n, n) = [K_P, K_D], v, e_q, qd, qdd (n,). u_ff = M q̈_d + C q̇ + g (model) or g.
    Writes the rows of vectors (2, n): u0 and the position part u_pos = −K_P e_q − K_D (q̇ − q̇_d).
    """
    M, C, g = mats[0], mats[1], vecs[0]
    Kq, Dq = gains[0], gains[1]
    u0, u_pos = vectors[0], vectors[1]
    n = v.shape[0]
    _joint_feedback(Kq, Dq, e_q, v, qd, u_pos)
    if model_feedforward:
        matvec2_into(M, qdd, C, v, u0)  # M q̈_d + C q̇, then + g
        for i in range(n):
            u0[i] = u_pos[i] + (u0[i] + g[i])
    else:
        for i in range(n):
            u0[i] = u_pos[i] + g[i]


@_jit
def hybrid(
    mats: np.ndarray,
    vecs: np.ndarray,
    jac: np.ndarray,
    tip: np.ndarray,
    A: np.ndarray,
    Adot: np.ndarray,
    rate: np.ndarray,
    v: np.ndarray,
    e_q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    p_d: np.ndarray,
    pdot_d: np.ndarray,
    pddot_d: np.ndarray,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray,
    near: bool,
    descs: np.ndarray,
    grads: np.ndarray,
    joint_gains: np.ndarray,
    task_gains: np.ndarray,
    params: np.ndarray,
    flags: np.ndarray,
    vectors: np.ndarray,
    B: np.ndarray,
) -> int:
    """The hybrid law: the near phase (``near``) or contact (eq. 1–3).

    mats (2, n, n) = [M, C], vecs (2, n) = [g, nle], jac (2, 3, n) = [J, J̇], tip (3, 3) =
    [p, J̇ v, J v] (``RobotTerms.zeros``' packs). A, Adot (k, n), rate (k,): the constraint
    rows, their rate of change and A v. v, e_q, qd, qdd (n,); p_d, pdot_d, pddot_d (3,).
    e_F, f_d (k,); approach (k,): the near phase's v_a (read only when ``near``).
    descs (k, m): the surfaces' descriptors (``Surface._descriptor``, zero-padded); grads
    (k, 3): ∇Φ at p, written here from descs unless flags[3] (then given by the caller).
    joint_gains (2, n, n) = [K_P, K_D]; task_gains (2, 3, 3) = [K_x, D_x]; params =
    [ω_p, ω_d, k_p, k_i, λ_a]; flags = [original, model feed-forward, decouple, grads given].
    Writes the rows of vectors (2, n): u0 and u_pos (eq. 2 or 3, before the redundant hold and
    P), and in contact B (n, k) = k_p Aᵀ. Returns OK, or SINGULAR_OTHER (outputs then
    unfinished).
    """
    M, C, g = mats[0], mats[1], vecs[0]
    J = jac[0]
    p, Jdot_v, pdot = tip[0], tip[1], tip[2]
    Kq, Dq = joint_gains[0], joint_gains[1]
    Kx, Dx = task_gains[0], task_gains[1]
    wp, wd, kp, ki, approach_rate = params[0], params[1], params[2], params[3], params[4]
    original = flags[0] != 0
    model_feedforward = flags[1] != 0
    decouple = flags[2] != 0
    grads_given = flags[3] != 0
    u0, u_pos = vectors[0], vectors[1]
    n = v.shape[0]
    k = A.shape[0]

    # the unit normals N (3, k) and S = I − N (NᵀN)⁻¹ Nᵀ
    N = np.empty((3, k))
    no_hess = np.empty((0, 0))
    for i in range(k):
        if not grads_given:
            surface_eval(descs[i], p, grads[i], no_hess)
        gx, gy, gz = grads[i, 0], grads[i, 1], grads[i, 2]
        norm = math.sqrt(gx * gx + gy * gy + gz * gz)
        N[0, i] = gx / norm
        N[1, i] = gy / norm
        N[2, i] = gz / norm
    S = np.empty((3, 3))
    if k == 1:
        for r in range(3):
            for c in range(3):
                S[r, c] = (1.0 if r == c else 0.0) - N[r, 0] * N[c, 0]
    else:
        NtN = np.empty((k, k))
        Y = np.empty((k, 3))
        mul_into(N, N, NtN, True, False)
        for a in range(k):
            for r in range(3):
                Y[a, r] = N[r, a]
        piv_k = np.empty(k, dtype=np.int64)
        if not lu_factor(NtN, piv_k):
            return SINGULAR_OTHER
        lu_solve(NtN, piv_k, Y)
        mul_into(N, Y, S, False, False)
        eye_minus(S)
    e = np.empty(3)
    e_dot = np.empty(3)
    for r in range(3):
        xa = 0.0
        xb = 0.0
        for c in range(3):
            xa += S[r, c] * (p_d[c] - p[c])
            xb += S[r, c] * (pdot_d[c] - pdot[c])
        e[r] = xa
        e_dot[r] = xb

    # J⁺ = Jᵀ (J Jᵀ)⁻¹ (n, 3): the transpose of (J Jᵀ)⁻¹ J
    JJt = np.empty((3, 3))
    mul_into(J, J, JJt, False, True)
    X = np.empty((3, n))
    for r in range(3):
        for j in range(n):
            X[r, j] = J[r, j]
    piv3 = np.empty(3, dtype=np.int64)
    Jp = np.empty((n, 3))
    if lu_factor(JJt, piv3):
        lu_solve(JJt, piv3, X)
        for j in range(n):
            for r in range(3):
                Jp[j, r] = X[r, j]
    else:  # J Jᵀ singular (a singularity): the SVD's pseudo-inverse, as np.linalg.pinv
        Jp[:, :] = np.linalg.pinv(J)

    # the position part u_pos (eq. 2 or 3)
    u_fb = np.empty(n)
    if original:
        a3 = np.empty(n)
        b3 = np.empty(n)
        for j in range(n):
            a3[j] = Jp[j, 0] * e[0] + Jp[j, 1] * e[1] + Jp[j, 2] * e[2]
            b3[j] = Jp[j, 0] * e_dot[0] + Jp[j, 1] * e_dot[1] + Jp[j, 2] * e_dot[2]
        matvec2_into(Kq, a3, Dq, b3, u_fb)
    else:
        w = np.empty(3)
        matvec2_into(Kx, e, Dx, e_dot, w)
        sw = np.empty(3)
        for r in range(3):
            sw[r] = S[r, 0] * w[0] + S[r, 1] * w[1] + S[r, 2] * w[2]
        for j in range(n):
            u_fb[j] = J[0, j] * sw[0] + J[1, j] * sw[1] + J[2, j] * sw[2]
    for i in range(n):
        u_pos[i] = u_fb[i]

    # the feed-forward u_ff
    u_ff = np.empty(n)
    if model_feedforward:
        y = np.empty(3)
        for r in range(3):
            y[r] = pddot_d[r] - Jdot_v[r]
        qacc = np.empty(n)
        for j in range(n):
            qacc[j] = Jp[j, 0] * y[0] + Jp[j, 1] * y[1] + Jp[j, 2] * y[2]
        matvec2_into(M, qacc, C, v, u_ff)
        for i in range(n):
            u_ff[i] = u_ff[i] + g[i]
    else:
        for i in range(n):
            u_ff[i] = g[i]

    # the redundant directions follow q_d: (I − J⁺J) x = x − J⁺ (J x)
    if n > 3:
        h = np.empty(n)
        _joint_feedback(Kq, Dq, e_q, v, qd, h)
        _null_apply(J, Jp, h)
        for i in range(n):
            u_fb[i] += h[i]
        if model_feedforward:
            z = np.empty(n)
            for i in range(n):
                z[i] = qdd[i]
            _null_apply(J, Jp, z)
            for i in range(n):
                xa = 0.0
                for j in range(n):
                    xa += M[i, j] * z[j]
                u_ff[i] += xa

    # M's factors and M⁻¹ Aᵀ, G = A M⁻¹ Aᵀ (both phases use them, contact only with P)
    LU = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            LU[i, j] = M[i, j]
    piv = np.empty(n, dtype=np.int64)
    if not lu_factor(LU, piv):
        return SINGULAR_OTHER
    piv_k = np.empty(k, dtype=np.int64)
    G = np.empty((k, k))
    MinvAT = np.empty((n, k))
    if near or decouple:
        for j in range(n):
            for a in range(k):
                MinvAT[j, a] = A[a, j]
        lu_solve(LU, piv, MinvAT)
        mul_into(A, MinvAT, G, False, False)
        if not lu_factor(G, piv_k):
            return SINGULAR_OTHER

    if near:
        # u = u_ff + u_fb + Aᵀ w: the rows' rate follows ṙ = −λ_a r + ω_d (v_a − r)
        rhs = np.empty((n, 1))
        for i in range(n):
            u0[i] = u_ff[i] + u_fb[i]
            cv = 0.0
            for j in range(n):
                cv += C[i, j] * v[j]
            rhs[i, 0] = u0[i] - cv - g[i]
        lu_solve(LU, piv, rhs)
        wk = np.empty((k, 1))
        for a in range(k):
            now = 0.0
            for j in range(n):
                now += A[a, j] * rhs[j, 0]
            ad = 0.0
            for j in range(n):
                ad += Adot[a, j] * v[j]
            now += ad
            wanted = -approach_rate * rate[a] + wd * (approach[a] - rate[a])
            wk[a, 0] = wanted - now
        lu_solve(G, piv_k, wk)
        for i in range(n):
            acc = 0.0
            for a in range(k):
                acc += A[a, i] * wk[a, 0]
            u0[i] += acc
        return OK

    if decouple:  # P: the feedback may not change the contact force
        z = np.empty((k, 1))
        for a in range(k):
            acc = 0.0
            for j in range(n):
                acc += MinvAT[j, a] * u_fb[j]
            z[a, 0] = acc
        lu_solve(G, piv_k, z)
        for i in range(n):
            acc = 0.0
            for a in range(k):
                acc += A[a, i] * z[a, 0]
            u_fb[i] -= acc
    # D_n Nᵀ ṗ = (ω_p + ω_d) (Nᵀ J M⁻¹ Jᵀ N)⁻¹ Nᵀ ṗ
    JN = np.empty((n, k))
    for j in range(n):
        for a in range(k):
            JN[j, a] = J[0, j] * N[0, a] + J[1, j] * N[1, a] + J[2, j] * N[2, a]
    MinvJN = np.empty((n, k))
    for j in range(n):
        for a in range(k):
            MinvJN[j, a] = JN[j, a]
    lu_solve(LU, piv, MinvJN)
    H = np.empty((k, k))
    mul_into(JN, MinvJN, H, True, False)
    if not lu_factor(H, piv_k):
        return SINGULAR_OTHER
    d = np.empty((k, 1))
    for a in range(k):
        d[a, 0] = N[0, a] * pdot[0] + N[1, a] * pdot[1] + N[2, a] * pdot[2]
    lu_solve(H, piv_k, d)
    rate_sum = wp + wd
    force = np.empty(k)
    for a in range(k):
        d[a, 0] *= rate_sum
        force[a] = (1.0 + kp) * f_d[a] - ki * e_F[a]
    for i in range(n):
        acc = u_ff[i] + u_fb[i]
        fa = 0.0
        dn = 0.0
        for a in range(k):
            fa += A[a, i] * force[a]
            dn += JN[i, a] * d[a, 0]
        u0[i] = acc - fa - dn
        for a in range(k):
            B[i, a] = kp * A[a, i]
    return OK


# --- the steady contact step on packs (Law.hybrid_at; control._kernels "packs") -------------
def workspace_size(n: int, k: int, width: int) -> int:
    """Length of the law's own flat buffer (:func:`hybrid_steady`; width: the descriptors')."""
    return 3 + k * width + 3 * k + 2 * n * n + 18 + 5 + 4 + 2 * n + n * k + k


@_jit
def hybrid_steady(
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
) -> int:
    """:func:`hybrid` in contact on packs (10 arguments, not 26): e_q = q − q_d written into
    the supervisor's steady pack, then the law. q, v: (n,) measured (a Euclidean arm); mats,
    vecs, jac, tip: the robot terms' packs; flat: the constraint terms' array (A, Ȧ, A q̇);
    desired: the desired motion's pack; steady: [e_q, e_F, f_d, …]; ws: the law's buffer,
    ws[0:3] = k, n, the descriptors' width w, then descs (k, w), grads (k, 3), the joint
    gains (2, n, n), the task gains (2, 3, 3), params (5,), flags (4,) as 0.0 / 1.0, vectors
    (2, n), B (n, k), zeros (k,)."""
    n = v.shape[0]
    k, w = int(ws[0]), int(ws[2])
    o = 3
    descs = ws[o : o + k * w].reshape((k, w))
    o += k * w
    grads = ws[o : o + 3 * k].reshape((k, 3))
    o += 3 * k
    joint_gains = ws[o : o + 2 * n * n].reshape((2, n, n))
    o += 2 * n * n
    task_gains = ws[o : o + 18].reshape((2, 3, 3))
    o += 18
    params = ws[o : o + 5]
    o += 5
    flags = np.empty(4, np.int64)
    for i in range(4):
        flags[i] = int(ws[o + i])
    o += 4
    vectors = ws[o : o + 2 * n].reshape((2, n))
    o += 2 * n
    B = ws[o : o + n * k].reshape((n, k))
    o += n * k
    zeros = ws[o : o + k]
    rows, _, _, scalars = constraint_parts(flat, k, n)
    e_q, e_F, f_d, _, qd, qdd, sample = steady_inputs(q, desired, steady, n, k)
    return hybrid(
        mats, vecs, jac, tip, rows[2], rows[3], scalars[3], v, e_q, qd, qdd, sample[0],
        sample[1], sample[2], e_F, f_d, zeros, False, descs, grads, joint_gains, task_gains,
        params, flags, vectors, B,
    )  # fmt: skip

"""Compiled algebra of the controller's step (Numba): constraint rows (k = 1), the modified
Arimoto law (eq. 4, 11, 29–30), the CLIK of eq. 27 and the force momenta.

Their readable numpy versions: :class:`hybrid_force.control.constraint.Constraint` (k rows)
and, in tests/oracles/control.py, ``arimoto_law``, ``free_space_law`` and the CLIK's
``ReferenceJointPath``; ``tests/test_kernels.py`` checks each kernel against them. The plant
never calls these kernels.

Compiled with :data:`hybrid_force._jit.jit`, whose module says why and by which conventions.
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force._jit import jit as _jit
from hybrid_force._jit import jit_inline as _inline
from hybrid_force.control._linalg_kernels import (
    add_matvec_scaled,
    dot,
    eye_minus,
    mul_into,
    quad_form,
    rows3_dot,
)
from hybrid_force.geometry._kernels import path_sample, surface_eval


# --- constraint (hybrid_force.control.constraint.Constraint, k = 1) -------------------------------
@_inline
def constraint_one(
    desc: np.ndarray,
    grad: np.ndarray,
    hess: np.ndarray,
    jac: np.ndarray,
    tip: np.ndarray,
    v: np.ndarray,
    tip_scaling: bool,
    rows: np.ndarray,
    cols: np.ndarray,
    squares: np.ndarray,
    scalars: np.ndarray,
) -> tuple[float, float, float]:
    """One surface's joint-space terms: the k = 1 case of ``Constraint.evaluate``.

    desc: the surface's descriptor (see :func:`surface_eval`); when it is empty, grad (3,),
    hess (3, 3) and scalars[0, 0] = Φ, scalars[1, 0] = d are given, otherwise they are
    written here. jac (2, 3, n) = [J, J̇], tip (3, 3) = [p, J̇ v, J v]: the robot terms'
    packs (``RobotTerms.zeros``). v: (n,).
    tip_scaling: True → s = ‖∇Φ‖ ("tip"), False → s = ‖J_Φ‖ ("joint").
    Writes rows (4, 1, n) = J_Φ, J_Φn, A, Ȧ; cols (2, n, 1) = A⁺, Ȧ⁺; squares (2, n, n) =
    Q, Q̇; scalars (6, 1) = Φ, d, s, A v, raw drift, drift (``ConstraintTerms.zeros``).
    Returns (‖∇Φ‖, ‖J_Φ‖, max|J|); the caller checks them (singular configurations).
    """
    J, Jdot, p, Jdot_v, pdot = jac[0], jac[1], tip[0], tip[1], tip[2]
    if desc.shape[0] > 0:
        value, dist = surface_eval(desc, p, grad, hess)
        scalars[0, 0] = value
        scalars[1, 0] = dist
    J_phi, J_phi_n, A, Adot = rows[0], rows[1], rows[2], rows[3]
    A_pinv, A_pinv_dot = cols[0], cols[1]
    Q, Qdot = squares[0], squares[1]
    n = J.shape[1]
    hp0 = hess[0, 0] * pdot[0] + hess[0, 1] * pdot[1] + hess[0, 2] * pdot[2]
    hp1 = hess[1, 0] * pdot[0] + hess[1, 1] * pdot[1] + hess[1, 2] * pdot[2]
    hp2 = hess[2, 0] * pdot[0] + hess[2, 1] * pdot[1] + hess[2, 2] * pdot[2]
    g0, g1, g2 = grad[0], grad[1], grad[2]
    grad_norm = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    row_sq = 0.0
    row_rowdot = 0.0
    jmax = 0.0
    for j in range(n):
        r = g0 * J[0, j] + g1 * J[1, j] + g2 * J[2, j]
        rd = (
            hp0 * J[0, j]
            + hp1 * J[1, j]
            + hp2 * J[2, j]
            + g0 * Jdot[0, j]
            + g1 * Jdot[1, j]
            + g2 * Jdot[2, j]
        )
        J_phi[0, j] = r
        Adot[0, j] = rd  # row_dot for now
        row_sq += r * r
        row_rowdot += r * rd
        for i in range(3):
            a = abs(J[i, j])
            if a > jmax:
                jmax = a
    row_norm = math.sqrt(row_sq)
    if tip_scaling:
        scale = grad_norm
        scale_dot = (g0 * hp0 + g1 * hp1 + g2 * hp2) / grad_norm
    else:
        scale = row_norm
        scale_dot = row_rowdot / row_norm
    inv_s = 1.0 / scale
    k_dot = scale_dot / (scale * scale)
    aa = 0.0
    ada = 0.0
    rate = 0.0
    for j in range(n):
        r = J_phi[0, j]
        J_phi_n[0, j] = r / row_norm
        a = r * inv_s
        ad = Adot[0, j] * inv_s - r * k_dot
        A[0, j] = a
        Adot[0, j] = ad
        aa += a * a
        ada += ad * a
        rate += a * v[j]
    w = 1.0 / aa
    w_dot = -2.0 * w * w * ada
    for j in range(n):
        A_pinv[j, 0] = A[0, j] * w
        A_pinv_dot[j, 0] = Adot[0, j] * w + A[0, j] * w_dot
    for i in range(n):
        for j in range(n):
            Q[i, j] = (1.0 if i == j else 0.0) - A_pinv[i, 0] * A[0, j]
            Qdot[i, j] = -(A_pinv_dot[i, 0] * A[0, j] + A_pinv[i, 0] * Adot[0, j])
    raw_drift = (
        pdot[0] * hp0
        + pdot[1] * hp1
        + pdot[2] * hp2
        + g0 * Jdot_v[0]
        + g1 * Jdot_v[1]
        + g2 * Jdot_v[2]
    )
    scalars[2, 0] = scale
    scalars[3, 0] = rate
    scalars[4, 0] = raw_drift
    scalars[5, 0] = raw_drift / scale
    return grad_norm, row_norm, jmax


@_inline
def constraint_parts(
    flat: np.ndarray, k: int, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The packs rows (4, k, n), cols (2, n, k), squares (2, n, n), scalars (6, k) of a
    ``ConstraintTerms.zeros(k, n)``, as views of its one flat array (in that order)."""
    a = 4 * k * n
    b = a + 2 * n * k
    c = b + 2 * n * n
    rows = flat[:a].reshape((4, k, n))
    cols = flat[a:b].reshape((2, n, k))
    squares = flat[b:c].reshape((2, n, n))
    scalars = flat[c : c + 6 * k].reshape((6, k))
    return rows, cols, squares, scalars


@_jit
def constraint_one_flat(
    desc: np.ndarray,
    grad: np.ndarray,
    hess: np.ndarray,
    jac: np.ndarray,
    tip: np.ndarray,
    v: np.ndarray,
    tip_scaling: bool,
    flat: np.ndarray,
) -> tuple[float, float, float]:
    """:func:`constraint_one` writing the terms' flat array (:func:`constraint_parts`, k = 1,
    n = v.shape[0]): 8 arguments instead of 11 (Numba's call costs ~0.1 µs per array)."""
    rows, cols, squares, scalars = constraint_parts(flat, 1, v.shape[0])
    return constraint_one(desc, grad, hess, jac, tip, v, tip_scaling, rows, cols, squares, scalars)


@_jit
def constraint_one_ws(
    desc: np.ndarray,
    scratch: np.ndarray,
    jac: np.ndarray,
    tip: np.ndarray,
    v: np.ndarray,
    flat: np.ndarray,
) -> tuple[float, float, float]:
    """:func:`constraint_one_flat` for a surface with a closed form (desc not empty), with
    scratch (13,) = [1.0 when the rows are scaled at the tip, ∇Φ (3,), ∇²Φ (3, 3)]: 6
    arguments instead of 8."""
    grad, hess = scratch[1:4], scratch[4:13].reshape((3, 3))
    rows, cols, squares, scalars = constraint_parts(flat, 1, v.shape[0])
    return constraint_one(
        desc, grad, hess, jac, tip, v, scratch[0] != 0.0, rows, cols, squares, scalars
    )


# --- control (hybrid_force.control.laws.arimoto.arimoto_law) --------------------------------------
@_inline
def reference(
    Q: np.ndarray,
    Qdot: np.ndarray,
    Ap: np.ndarray,
    Apd: np.ndarray,
    v: np.ndarray,
    e_q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray,
    lam: float,
    beta: float,
    vectors: np.ndarray,
    matrices: np.ndarray,
) -> None:
    """The reference motion of the modified Arimoto law, eq. 4 and 8 (the first part of
    :func:`arimoto`, which the adaptive law shares): q̇_r, q̈_r at f = 0, s, s0, s1 and
    q̈_r,f = β A⁺.

    Q, Qdot: (n, n). v, e_q, qd, qdd: (n,). Ap, Apd: (n, k). e_F, f_d, approach: (k,).
    lam, beta: Λ, β. Writes rows 1..5 of vectors (≥ 6, n): s, s0, s1, q̇_r, q̈_r0, and
    matrices[1] (n, k) = q̈_r,f.
    """
    s, s0, s1, qdot_r, qddot_r0 = vectors[1], vectors[2], vectors[3], vectors[4], vectors[5]
    qddot_r_f = matrices[1]
    n = v.shape[0]
    k = e_F.shape[0]
    x = np.empty(n)
    xdot = np.empty(n)
    for i in range(n):
        x[i] = qd[i] - lam * e_q[i]
        xdot[i] = qdd[i] - lam * (v[i] - qd[i])
    for i in range(n):
        a = 0.0
        b = 0.0
        c = 0.0
        for j in range(n):
            a += Q[i, j] * x[j]
            b += Qdot[i, j] * x[j] + Q[i, j] * xdot[j]
            c += Q[i, j] * (v[j] - x[j])
        for m in range(k):
            a += beta * Ap[i, m] * e_F[m] + Ap[i, m] * approach[m]
            b += beta * Apd[i, m] * e_F[m] - beta * Ap[i, m] * f_d[m] + Apd[i, m] * approach[m]
        s1i = 0.0
        for m in range(k):
            s1i -= beta * Ap[i, m] * e_F[m]
            qddot_r_f[i, m] = beta * Ap[i, m]
        s1[i] = s1i
        qdot_r[i] = a
        qddot_r0[i] = b
        s0[i] = c
        s[i] = v[i] - a


@_inline
def arimoto(
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
    qd: np.ndarray,
    qdd: np.ndarray,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray,
    lam: float,
    beta: float,
    gamma: float,
    vectors: np.ndarray,
    matrices: np.ndarray,
) -> float:
    """The modified Arimoto law, eq. 4, 8, 11, as ``control.arimoto_law`` (k rows).

    M, C, Kd, Q, Qdot: (n, n). g, v, e_q, qd, qdd: (n,). Ap, Apd: (n, k). A: (k, n).
    e_F, f_d, approach: (k,) (approach all zeros when unused). lam, beta, gamma: Λ, β, γ.
    Writes the rows of vectors (6, n): u0, s, s0, s1, q̇_r, q̈_r0, and of matrices (2, n, k):
    B = β M A⁺, q̈_r,f = β A⁺. Returns V = ½ sᵀMs + ½ β e_Fᵀe_F [J].
    """
    reference(Q, Qdot, Ap, Apd, v, e_q, qd, qdd, e_F, f_d, approach, lam, beta, vectors, matrices)
    u0, s, qdot_r, qddot_r0 = vectors[0], vectors[1], vectors[4], vectors[5]
    B = matrices[0]
    n = v.shape[0]
    k = e_F.shape[0]
    for i in range(n):
        acc = g[i]
        for j in range(n):
            acc += M[i, j] * qddot_r0[j] + C[i, j] * qdot_r[j] - Kd[i, j] * s[j]
        for m in range(k):
            acc -= A[m, i] * (f_d[m] - gamma * e_F[m])
        u0[i] = acc
        for m in range(k):
            b = 0.0
            for j in range(n):
                b += M[i, j] * Ap[j, m]
            B[i, m] = beta * b
    return 0.5 * quad_form(M, s) + 0.5 * beta * dot(e_F, e_F)


@_jit
def arimoto_packed(
    mats: np.ndarray,
    vecs: np.ndarray,
    Kd: np.ndarray,
    flat: np.ndarray,
    v: np.ndarray,
    e_q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray,
    gains: np.ndarray,
    vectors: np.ndarray,
    matrices: np.ndarray,
) -> float:
    """:func:`arimoto` on the packs of the robot terms and the constraint terms' flat array
    (14 arguments, not 21: Numba's call costs about 0.1 µs per array argument).

    mats (2, n, n) = [M, C] and vecs (2, n) = [g, nle] (``RobotTerms.zeros``); flat: the
    ``ConstraintTerms.zeros(k, n)`` array (:func:`constraint_parts`; k = e_F.shape[0],
    n = v.shape[0]); gains (3,) = Λ, β, γ. The rest as :func:`arimoto`.
    """
    rows, cols, squares, _ = constraint_parts(flat, e_F.shape[0], v.shape[0])
    return arimoto(
        mats[0], mats[1], vecs[0], Kd, squares[0], squares[1], cols[0], cols[1], rows[2], v,
        e_q, qd, qdd, e_F, f_d, approach, gains[0], gains[1], gains[2], vectors, matrices,
    )  # fmt: skip


@_jit
def arimoto_contact(
    q: np.ndarray,
    q_d: np.ndarray,
    mats: np.ndarray,
    vecs: np.ndarray,
    Kd: np.ndarray,
    flat: np.ndarray,
    v: np.ndarray,
    e_q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray,
    gains: np.ndarray,
    vectors: np.ndarray,
    matrices: np.ndarray,
) -> float:
    """e_q = q − q_d written (q, q_d: (n,), a Euclidean arm), then :func:`arimoto_packed`:
    the supervisor's contact step in one call instead of a numpy subtraction and a call."""
    for i in range(e_q.shape[0]):
        e_q[i] = q[i] - q_d[i]
    return arimoto_packed(
        mats, vecs, Kd, flat, v, e_q, qd, qdd, e_F, f_d, approach, gains, vectors, matrices
    )


# --- the steady contact step's packs (Law.hybrid_at) ----------------------------------------------
# Numba's dispatcher costs about 0.13 µs per array argument of a call from Python (a no-op
# kernel: 0.35 µs with 2 arrays, 1.2 µs with 8, 2.6 µs with 16), more than most of these
# kernels' arithmetic. So the arrays that persist from step to step are views of a few flat
# buffers, each kept by its owner, and a law's steady-contact kernel takes the buffers:
# the desired motion's (the CLIK's), the supervisor's [e_q, e_F, f_d] and the law's own.
def desired_pack_size(n: int, nq: int) -> int:
    """Length of a desired-motion pack (:func:`desired_parts`)."""
    return nq + 2 * n + 9


@_inline
def desired_parts(
    pack: np.ndarray, n: int, nq: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Views q_d (nq,), q̇_d, q̈_d (n,) and the path sample (3, 3) = [p_d, ṗ_d, p̈_d] of a
    desired-motion pack (``Desired.pack``: at least :func:`desired_pack_size` long)."""
    q = pack[0:nq]
    qd = pack[nq : nq + n]
    qdd = pack[nq + n : nq + 2 * n]
    o = nq + 2 * n
    sample = pack[o : o + 9].reshape((3, 3))
    return q, qd, qdd, sample


@_inline
def steady_parts(pack: np.ndarray, n: int, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Views e_q (n,), e_F (k,), f_d (k,) of the supervisor's steady-contact pack
    (``LawInput.steady``: [e_q, e_F, f_d, F, F_d], n + 4k long)."""
    return pack[0:n], pack[n : n + k], pack[n + k : n + 2 * k]


@_inline
def steady_inputs(
    q: np.ndarray, desired: np.ndarray, steady: np.ndarray, n: int, k: int
) -> tuple[
    np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray
]:  # fmt: skip
    """What every law's steady contact kernel starts with: e_q = q − q_d (q: (n,) measured, a
    Euclidean arm) written into the supervisor's steady pack, and the views e_q, e_F, f_d
    (:func:`steady_parts`), q_d, q̇_d, q̈_d and the path sample (:func:`desired_parts`)."""
    q_d, qd, qdd, sample = desired_parts(desired, n, n)
    e_q, e_F, f_d = steady_parts(steady, n, k)
    for i in range(n):
        e_q[i] = q[i] - q_d[i]
    return e_q, e_F, f_d, q_d, qd, qdd, sample


def arimoto_workspace_size(n: int, k: int) -> int:
    """Length of the paper's law's own flat buffer (:func:`arimoto_parts`)."""
    return 1 + n * n + 3 + 6 * n + 2 * n * k + k


@_inline
def arimoto_parts(
    ws: np.ndarray, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Views of the paper's law's own buffer ws (:func:`arimoto_workspace_size`): ws[0] = k,
    then K_d (n, n), the gains (3,) = Λ, β, γ, the output vectors (6, n) and matrices
    (2, n, k) of :func:`arimoto`, and zeros (k,) (the approach term in contact)."""
    k = int(ws[0])
    o = 1
    Kd = ws[o : o + n * n].reshape((n, n))
    o += n * n
    gains = ws[o : o + 3]
    o += 3
    vectors = ws[o : o + 6 * n].reshape((6, n))
    o += 6 * n
    matrices = ws[o : o + 2 * n * k].reshape((2, n, k))
    o += 2 * n * k
    return Kd, gains, vectors, matrices, ws[o : o + k]


@_jit
def arimoto_steady(
    q: np.ndarray,
    v: np.ndarray,
    mats: np.ndarray,
    vecs: np.ndarray,
    flat: np.ndarray,
    desired: np.ndarray,
    steady: np.ndarray,
    ws: np.ndarray,
) -> float:
    """:func:`arimoto_contact` on packs (8 arguments, not 16): the supervisor's steady
    contact step. q, v: (n,) measured (a Euclidean arm); mats, vecs: the robot terms' packs;
    flat: the constraint terms' array; desired: the desired motion's pack
    (:func:`desired_parts`); steady: [e_q, e_F, f_d] (:func:`steady_parts`; e_q written
    here); ws: the law's own buffer (:func:`arimoto_parts`)."""
    n = v.shape[0]
    Kd, gains, vectors, matrices, zeros = arimoto_parts(ws, n)
    k = zeros.shape[0]
    e_q, e_F, f_d, _, qd, qdd, _ = steady_inputs(q, desired, steady, n, k)
    return arimoto_packed(
        mats, vecs, Kd, flat, v, e_q, qd, qdd, e_F, f_d, zeros, gains, vectors, matrices
    )


# --- clik (hybrid_force.control.clik.DesiredJointPath) --------------------------------------------
@_jit
def _inv3_into(a: np.ndarray, out: np.ndarray) -> float:
    """out = a⁻¹ for a (3, 3) by the adjugate; returns the determinant (0 → out unchanged)."""
    c0 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c1 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c2 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    det = a[0, 0] * c0 + a[0, 1] * c1 + a[0, 2] * c2
    if det == 0.0:
        return det
    r = 1.0 / det
    out[0, 0] = c0 * r
    out[0, 1] = (a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]) * r
    out[0, 2] = (a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]) * r
    out[1, 0] = c1 * r
    out[1, 1] = (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]) * r
    out[1, 2] = (a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]) * r
    out[2, 0] = c2 * r
    out[2, 1] = (a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]) * r
    out[2, 2] = (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]) * r
    return det


@_inline
def clik_velocity(
    J6: np.ndarray,
    p: np.ndarray,
    sample: np.ndarray,
    cfg: np.ndarray,
    q: np.ndarray,
    posture: np.ndarray,
    dq_post: np.ndarray,
    Jp: np.ndarray,
    W: np.ndarray,
    N: np.ndarray,
    x: np.ndarray,
    qd: np.ndarray,
) -> float:
    """q̇_d of eq. 27 at the current q_d, as ``DesiredJointPath._derivatives`` (first half).

    J6: (6, n) tip Jacobian (rows 0..2 used). p: (3,) tip position. sample: (3, 3) rows
    p_d, ṗ_d, p̈_d. cfg: (5,) γ, λ², redundant (0 or 1), k_n, and 1 when dq_post is to be
    formed here as q − posture (q, posture: (nq,) = (n,), a Euclidean arm), else 0 (dq_post
    given: (n,) q_d ⊖ posture, or unused without the posture term).
    Writes J⁻¹ or Jᵀ W into Jp (n, 3), W = (JJᵀ + λ²I)⁻¹ (redundant), N = I − JpJ,
    x = ṗ_d − γ(p − p_d) and q̇_d. Returns the cheap bound of cond(J Jᵀ) (inf if singular).
    """
    p_d, pdot_d = sample[0], sample[1]
    gamma, damping2, redundant, posture_gain = cfg[0], cfg[1], cfg[2] != 0.0, cfg[3]
    n = qd.shape[0]
    if cfg[4] != 0.0:
        for j in range(n):
            dq_post[j] = q[j] - posture[j]
    for r in range(3):
        x[r] = pdot_d[r] - gamma * (p[r] - p_d[r])
    if not redundant:
        Jn = np.empty((3, 3))
        for r in range(3):
            for j in range(3):
                Jn[r, j] = J6[r, j]
        if _inv3_into(Jn, Jp) == 0.0:
            return np.inf
        cond = np.abs(Jn).max() * np.abs(Jp).max()
        cond = cond * cond
    else:
        JJt = np.empty((3, 3))
        mul_into(J6, J6, JJt, False, True)
        for r in range(3):
            for c in range(3):
                JJt[r, c] = JJt[r, c] + (damping2 if r == c else 0.0)
        if _inv3_into(JJt, W) == 0.0:
            return np.inf
        cond = np.abs(JJt).max() * np.abs(W).max()
        for j in range(n):
            for c in range(3):
                Jp[j, c] = J6[0, j] * W[0, c] + J6[1, j] * W[1, c] + J6[2, j] * W[2, c]
    for j in range(n):
        qd[j] = Jp[j, 0] * x[0] + Jp[j, 1] * x[1] + Jp[j, 2] * x[2]
    if redundant and posture_gain > 0.0:
        add_posture(Jp, J6, dq_post, posture_gain, N, qd)
    return cond


@_inline
def add_posture(
    Jp: np.ndarray, A: np.ndarray, dq_post: np.ndarray, gain: float, N: np.ndarray, qd: np.ndarray
) -> None:
    """q̇_d += N z, z = −k_n (q_d ⊖ posture): the posture in the null space of the task rows
    A (≥ m, n) (its first m), N = I − A⁺A (n, n) written, A⁺ = Jp (n, m); dq_post, qd (n,)."""
    mul_into(Jp, A, N, False, False)
    eye_minus(N)
    add_matvec_scaled(N, dq_post, -gain, qd)


@_inline
def clik_acceleration(
    J6: np.ndarray,
    Jd6: np.ndarray,
    Jp: np.ndarray,
    W: np.ndarray,
    N: np.ndarray,
    x: np.ndarray,
    qd: np.ndarray,
    sample: np.ndarray,
    cfg: np.ndarray,
    dq_post: np.ndarray,
    qdd: np.ndarray,
    q: np.ndarray,
    dt_pred: float,
    q_pred: np.ndarray,
) -> None:
    """q̈_d, the exact time derivative of q̇_d (second half of ``_derivatives``).

    Jd6: (6, n) J̇(q_d, q̇_d). Other inputs as written by or given to :func:`clik_velocity`.
    Writes q̈_d and, when dt_pred > 0, the next step's predictor
    q_pred = q + q̇_d dt + q̈_d dt²/2 (as :func:`taylor_step`; Euclidean spaces only).
    """
    pdot_d, pddot_d = sample[1], sample[2]
    gamma, redundant, posture_gain = cfg[0], cfg[2] != 0.0, cfg[3]
    n = qd.shape[0]
    xdot = np.empty(3)
    pdot = rows3_dot(J6, 0, qd)
    for r in range(3):
        xdot[r] = pddot_d[r] - gamma * (pdot[r] - pdot_d[r])
    if not redundant:
        y = np.empty(3)
        for r in range(3):
            acc = xdot[r]
            for j in range(n):
                acc -= Jd6[r, j] * qd[j]
            y[r] = acc
        for j in range(n):
            qdd[j] = Jp[j, 0] * y[0] + Jp[j, 1] * y[1] + Jp[j, 2] * y[2]
    else:
        # Ẇ = −W (J̇Jᵀ + JJ̇ᵀ) W;  J̇⁺ = J̇ᵀW + JᵀẆ
        S = np.empty((3, 3))
        for r in range(3):
            for c in range(3):
                acc = 0.0
                for j in range(n):
                    acc += Jd6[r, j] * J6[c, j] + J6[r, j] * Jd6[c, j]
                S[r, c] = acc
        WS = np.empty((3, 3))
        mul_into(W, S, WS, False, False)
        Wdot = np.empty((3, 3))
        mul_into(WS, W, Wdot, False, False)
        for r in range(3):
            for c in range(3):
                Wdot[r, c] = -Wdot[r, c]
        Jpd = np.empty((n, 3))
        for j in range(n):
            for c in range(3):
                acc = 0.0
                for r in range(3):
                    acc += Jd6[r, j] * W[r, c] + J6[r, j] * Wdot[r, c]
                Jpd[j, c] = acc
        for j in range(n):
            qdd[j] = (
                Jpd[j, 0] * x[0]
                + Jpd[j, 1] * x[1]
                + Jpd[j, 2] * x[2]
                + Jp[j, 0] * xdot[0]
                + Jp[j, 1] * xdot[1]
                + Jp[j, 2] * xdot[2]
            )
        if posture_gain > 0.0:
            # Ṅ = −(J̇⁺J + J⁺J̇);  q̈_d += Ṅ z + N (−k_n q̇_d),  z = −k_n dq_post
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    nd = -(
                        Jpd[i, 0] * J6[0, j]
                        + Jpd[i, 1] * J6[1, j]
                        + Jpd[i, 2] * J6[2, j]
                        + Jp[i, 0] * Jd6[0, j]
                        + Jp[i, 1] * Jd6[1, j]
                        + Jp[i, 2] * Jd6[2, j]
                    )
                    acc += nd * (-posture_gain * dq_post[j]) + N[i, j] * (-posture_gain * qd[j])
                qdd[i] += acc
    if dt_pred > 0.0:
        taylor_step(q, qd, qdd, dt_pred, q_pred)


@_jit
def taylor_step(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, dt: float, out: np.ndarray) -> None:
    """out = q + q̇ dt + q̈ dt²/2 (Euclidean configuration spaces only)."""
    h = 0.5 * dt * dt
    for i in range(q.shape[0]):
        out[i] = q[i] + (qd[i] * dt + qdd[i] * h)


@_inline
def newton_step(
    desc: np.ndarray,
    t: float,
    sample: np.ndarray,
    q: np.ndarray,
    Jp: np.ndarray,
    p: np.ndarray,
    out: np.ndarray,
) -> None:
    """out = q + Jp (p_d − p), p_d = sample[0] (Euclidean configuration spaces only).

    desc: the path's descriptor (:func:`path_sample`); when it is not empty the path is
    evaluated here first, at t [s], into sample (3, 3) = [p_d, ṗ_d, p̈_d]; otherwise sample
    is given. Jp: (n, 3). p: (3,) tip at q.
    """
    if desc.shape[0] > 0:
        path_sample(desc, t, sample)
    target = sample[0]
    e0, e1, e2 = target[0] - p[0], target[1] - p[1], target[2] - p[2]
    for i in range(q.shape[0]):
        out[i] = q[i] + (Jp[i, 0] * e0 + Jp[i, 1] * e1 + Jp[i, 2] * e2)


# the CLIK's workspace: one flat buffer that holds its arrays, so that each of its three
# kernels of a step takes 3 or 4 arguments instead of 7 to 14 (Numba's call costs about 0.1 µs
# per array argument, more than these kernels' arithmetic)
CLIK_HEADER = 3  # n, nq, dt_pred


def clik_workspace_size(n: int, nq: int) -> int:
    """Length of the flat CLIK buffer of :func:`clik_parts` for n velocities, nq positions."""
    return CLIK_HEADER + desired_pack_size(n, nq) + 2 * nq + n + 3 * n + n * n + 9 + 3 + 5


@_inline
def clik_parts(
    ws: np.ndarray,
) -> tuple[
    np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
    np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
]:  # fmt: skip
    """Views of the CLIK buffer ws (:func:`clik_workspace_size`): ws[0] = n, ws[1] = nq,
    ws[2] = dt_pred [s], then q (nq,), qd, qdd (n,), sample (3, 3) (the desired motion's
    pack, :func:`desired_parts`, which a law's steady-contact kernel takes as one argument),
    posture, q_pred (nq,), dq_post (n,), Jp (n, 3), N (n, n), W (3, 3), x (3,), cfg (5,).
    Returned as q, posture, q_pred, qd, qdd, dq_post, Jp, N, W, x, sample, cfg (the
    arguments of :func:`clik_velocity` and :func:`clik_acceleration`)."""
    n, nq = int(ws[0]), int(ws[1])
    q, qd, qdd, sample = desired_parts(ws[CLIK_HEADER:], n, nq)
    o = CLIK_HEADER + nq + 2 * n + 9  # desired_pack_size(n, nq)
    posture = ws[o : o + nq]
    o += nq
    q_pred = ws[o : o + nq]
    o += nq
    dq_post = ws[o : o + n]
    o += n
    Jp = ws[o : o + 3 * n].reshape((n, 3))
    o += 3 * n
    N = ws[o : o + n * n].reshape((n, n))
    o += n * n
    W = ws[o : o + 9].reshape((3, 3))
    o += 9
    x = ws[o : o + 3]
    o += 3
    cfg = ws[o : o + 5]
    return q, posture, q_pred, qd, qdd, dq_post, Jp, N, W, x, sample, cfg


@_jit
def clik_velocity_ws(J6: np.ndarray, p: np.ndarray, ws: np.ndarray) -> float:
    """:func:`clik_velocity` on the arrays of the CLIK buffer ws (:func:`clik_parts`);
    J6 (6, n) the tip Jacobian, p (3,) the tip at q_d. Returns its condition bound."""
    q, posture, _, qd, _, dq_post, Jp, N, W, x, sample, cfg = clik_parts(ws)
    return clik_velocity(J6, p, sample, cfg, q, posture, dq_post, Jp, W, N, x, qd)


@_jit
def clik_acceleration_ws(J6: np.ndarray, Jd6: np.ndarray, ws: np.ndarray) -> None:
    """:func:`clik_acceleration` on the arrays of the CLIK buffer ws, with its predictor's
    dt = ws[2] (0: none); J6, Jd6 (6, n) the tip Jacobian and its time derivative."""
    q, _, q_pred, qd, qdd, dq_post, Jp, N, W, x, sample, cfg = clik_parts(ws)
    clik_acceleration(J6, Jd6, Jp, W, N, x, qd, sample, cfg, dq_post, qdd, q, ws[2], q_pred)


@_jit
def newton_step_ws(desc: np.ndarray, t: float, p: np.ndarray, ws: np.ndarray) -> None:
    """:func:`newton_step` from the buffer's predictor: q = q_pred + Jp (p_d − p), the path
    sampled at t [s] first when desc is not empty; p (3,) the tip at q_pred."""
    q, _, q_pred, _, _, _, Jp, _, _, _, sample, _ = clik_parts(ws)
    newton_step(desc, t, sample, q_pred, Jp, p, q)


# --- controller momenta ---------------------------------------------------------------------------
@_jit
def accumulate_steady(pack: np.ndarray, f: np.ndarray, dt: float) -> None:
    """:func:`accumulate` on the supervisor's steady pack [e_q, e_F, f_d, F, F_d] (n + 4k,;
    :func:`steady_parts`): F += f dt, F_d += f_d dt, e_F = F − F_d. f: (k,) [N]; dt [s]."""
    k = f.shape[0]
    n = pack.shape[0] - 4 * k
    o = n + 2 * k
    accumulate(pack[o : o + k], f, pack[o + k : o + 2 * k], pack[n + k : n + 2 * k], dt,
               pack[n : n + k])  # fmt: skip


@_jit
def accumulate(
    x: np.ndarray, dx: np.ndarray, y: np.ndarray, dy: np.ndarray, dt: float, diff: np.ndarray
) -> None:
    """x += dx dt, y += dy dt, diff = x − y (the momenta F, F_d and e_F = F − F_d, eq. 3)."""
    for m in range(x.shape[0]):
        x[m] += dx[m] * dt
        y[m] += dy[m] * dt
        diff[m] = x[m] - y[m]

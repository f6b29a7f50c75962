"""Compiled algebra of the impedance law's step (Numba): eq. (1) and (2) of
:mod:`hybrid_force.control.laws.impedance` in one call.

Its oracle, the readable numpy version, is ``ImpedanceLaw`` of tests/oracles/laws.py;
``tests/test_impedance_kernel.py`` checks this kernel against it. The dense solves are those of
:mod:`hybrid_force.control._linalg_kernels`: a Cholesky factorisation of M (n, n), the solves
M X = [Jᵀ, Aᵀ], and the inverse of the 3×3 J M⁻¹ Jᵀ by LU with partial pivoting (as LAPACK's
getrf/getri, which numpy's ``inv`` calls).

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
    lu_factor,
    lu_solve,
    mul_into,
    rows3_dot,
)

#: the phases the kernel computes (``mode``)
FREE, NEAR, CONTACT = 0, 1, 2
#: its status: the terms are fine / J M⁻¹ Jᵀ (or M) is singular
OK, SINGULAR = 0, 1


@_jit
def impedance(
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
    A: np.ndarray,
    normals: np.ndarray,
    along: np.ndarray,
    approach: np.ndarray,
    distance: np.ndarray,
    preload: np.ndarray,
    mode: int,
    along_given: bool,
    omega: float,
    zeta: float,
    feedforward: bool,
    u: np.ndarray,
    gains: np.ndarray,
    offset: np.ndarray,
    work: np.ndarray,
) -> int:
    """The torque of eq. (1) in the phase ``mode`` (FREE, NEAR or CONTACT).

    mats (2, n, n) = [M, C], vecs (2, n) = [g, nle], jac (2, 3, n) = [J, J̇], tip (3, 3) =
    [p, J̇ v, J v]: the controller's model terms as packed by ``RobotTerms.zeros``. v, e_q,
    qd, qdd: (n,). p_d, pd_d: (3,) the task path's sample.
    A (k, n): the constraint rows (read in CONTACT). normals (3, k): the surfaces' normals at
    the tip (NEAR); along (k, 3): their pseudo-inverse, given when ``along_given``, else
    computed here for k = 1 (nᵀ / nᵀn; k > 1 must give it). approach, distance (k,): the
    supervisor's approach velocity and the distances (NEAR). preload (k,): φ (CONTACT).
    omega, zeta: ω, ζ. feedforward: add M q̈_d + C q̇_d.

    Writes u (n,) the command; gains (3, 3, 3) = [Λ, K, D]; in CONTACT offset (k,) = W φ / ω²
    with W = A M⁻¹ Aᵀ; along (k, 3) when not given. work: (n, n + 3 + k) scratch.
    Returns OK, or SINGULAR when M is not positive definite or J M⁻¹ Jᵀ is singular (then
    the outputs are not all written).
    """
    M, C, g = mats[0], mats[1], vecs[0]
    J, p, pdot = jac[0], tip[0], tip[2]
    n = M.shape[0]
    k = A.shape[0]
    L = work[:, :n]
    X = work[:, n:]  # (n, 3 + k): M⁻¹ Jᵀ, then M⁻¹ Aᵀ
    # --- Cholesky M = L Lᵀ ---------------------------------------------------------------
    if not cholesky(M, L):
        return SINGULAR
    # --- X = M⁻¹ [Jᵀ, Aᵀ] ----------------------------------------------------------------
    ncol = 3 + k if mode == CONTACT else 3
    for c in range(ncol):
        cholesky_solve_column(L, J[c] if c < 3 else A[c - 3], X, c)
    # --- Λ = (J M⁻¹ Jᵀ)⁻¹ by LU, symmetrised ------------------------------------------
    S = np.empty((3, 3))  # J M⁻¹ Jᵀ, then its LU factors in place
    mul_into(J, X, S, False, False)
    Lam, K, D = gains[0], gains[1], gains[2]
    piv = np.empty(3, np.int64)
    if not lu_factor(S, piv):
        return SINGULAR
    for i in range(3):
        for j in range(3):
            Lam[i, j] = 1.0 if i == j else 0.0
    lu_solve(S, piv, Lam)
    for i in range(3):
        for j in range(3):
            if not math.isfinite(Lam[i, j]):  # an overflow in M⁻¹ or J: no inertia
                return SINGULAR
    for i in range(3):
        for j in range(i + 1, 3):
            sym = 0.5 * (Lam[i, j] + Lam[j, i])
            Lam[i, j] = sym
            Lam[j, i] = sym
    w2 = omega * omega
    w_d = 2.0 * zeta * omega
    for i in range(3):
        for j in range(3):
            K[i, j] = w2 * Lam[i, j]
            D[i, j] = w_d * Lam[i, j]
    # --- the reference: error e = p_r − p, velocity ṗ_r, extra acceleration p̈_r --------
    e = np.empty(3)
    pd_r = np.empty(3)
    pdd_r = np.zeros(3)
    for i in range(3):
        e[i] = p_d[i] - p[i]
        pd_r[i] = pd_d[i]
    if mode == NEAR:
        kn = normals.shape[1]
        if not along_given:  # k = 1: the pseudo-inverse of a column is nᵀ / nᵀn
            nn = normals[0, 0] ** 2 + normals[1, 0] ** 2 + normals[2, 0] ** 2
            for i in range(3):
                along[0, i] = normals[i, 0] / nn
        ae = np.zeros(kn)  # along e, with the error before any projection
        for r in range(kn):
            ap = 0.0
            nv = 0.0
            for i in range(3):
                ae[r] += along[r, i] * e[i]
                ap += along[r, i] * pd_d[i]
                nv += normals[i, r] * pdot[i]
            rate = approach[r] / distance[r] * nv
            for i in range(3):
                pd_r[i] += along[r, i] * approach[r] - normals[i, r] * ap
                pdd_r[i] += along[r, i] * rate
        for r in range(kn):
            for i in range(3):
                e[i] -= normals[i, r] * ae[r]
    force = np.empty(3)
    for i in range(3):
        s = 0.0
        for j in range(3):
            s += K[i, j] * e[j] + D[i, j] * (pd_r[j] - pdot[j]) + Lam[i, j] * pdd_r[j]
        force[i] = s
    # --- null space: (I − Jᵀ J̄ᵀ)(−M y) = −M y + Jᵀ Λ J y --------------------------------
    y = np.empty(n)
    for i in range(n):
        y[i] = w2 * e_q[i] + w_d * (v[i] - qd[i])
    Jy = np.empty(3)
    Jy[0], Jy[1], Jy[2] = rows3_dot(J, 0, y)
    for i in range(3):
        s = 0.0
        for j in range(3):
            s += Lam[i, j] * Jy[j]
        force[i] += s
    for i in range(n):
        s = J[0, i] * force[0] + J[1, i] * force[1] + J[2, i] * force[2] + g[i]
        for m in range(n):
            s -= M[i, m] * y[m]
        if feedforward:
            for m in range(n):
                s += M[i, m] * qdd[m] + C[i, m] * qd[m]
        u[i] = s
    if mode == CONTACT:  # −Aᵀ φ, and the depth δ = W φ / ω² (W = A M⁻¹ Aᵀ)
        for i in range(n):
            for r in range(k):
                u[i] -= A[r, i] * preload[r]
        for r in range(k):
            s = 0.0
            for c in range(k):
                w = 0.0
                for m in range(n):
                    w += A[r, m] * X[m, 3 + c]
                s += w * preload[c]
            offset[r] = s / w2
    return OK


@_jit
def advance_preload(preload: np.ndarray, f_d: np.ndarray, f: np.ndarray, step: float) -> None:
    """Force tracking: φ += step (f_d − f), step = dt κ_f; each (k,)."""
    for i in range(preload.shape[0]):
        preload[i] += step * (f_d[i] - f[i])


# --- the steady contact step on packs (Law.hybrid_at; control._kernels "packs") -------------
def workspace_size(n: int, k: int) -> int:
    """Length of the law's own flat buffer of the steady contact step (:func:`impedance_steady`)."""
    return 5 + 2 * k + 27 + n + n * (n + 3 + k) + 6 * k


@_jit
def impedance_steady(
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
    """:func:`impedance` in CONTACT on packs (10 arguments, not 25): e_q = q − q_d written
    into the supervisor's steady pack, then the law. q, v: (n,) measured (a Euclidean arm);
    mats, vecs, jac, tip: the robot terms' packs; flat: the constraint terms' array; desired:
    the desired motion's pack; steady: [e_q, e_F, f_d, …]; ws: the law's buffer, ws[0] = k,
    ws[1] = n, ws[2:5] = ω, ζ, 1.0 with the feed-forward, then preload, offset (k,), the
    gains (3, 3, 3), u (n,), work (n, n + 3 + k), normals (3, k), along (k, 3)."""
    n = v.shape[0]
    k = int(ws[0])
    o = 5
    preload = ws[o : o + k]
    offset = ws[o + k : o + 2 * k]
    o += 2 * k
    gains = ws[o : o + 27].reshape((3, 3, 3))
    o += 27
    u = ws[o : o + n]
    o += n
    work = ws[o : o + n * (n + 3 + k)].reshape((n, n + 3 + k))
    o += n * (n + 3 + k)
    normals = ws[o : o + 3 * k].reshape((3, k))
    along = ws[o + 3 * k : o + 6 * k].reshape((k, 3))
    rows, _, _, _ = constraint_parts(flat, k, n)
    e_q, _, _, _, qd, qdd, sample = steady_inputs(q, desired, steady, n, k)
    none = ws[0:0]
    return impedance(
        mats, vecs, jac, tip, v, e_q, qd, qdd, sample[0], sample[1], rows[2], normals, along,
        none, none, preload, CONTACT, False, ws[2], ws[3], ws[4] != 0.0, u, gains, offset,
        work,
    )  # fmt: skip

"""Compiled small dense linear algebra shared by the controllers' kernels (Numba).

The laws' and the pose CLIK's kernels factor symmetric positive definite matrices of a few
rows (M, AAᵀ + λ²I) by Cholesky, and general ones (J Jᵀ, WᵀW, A M⁻¹ Aᵀ, M when it has no
Cholesky factor) by LU with partial pivoting (as ``np.linalg.solve``: the multipliers are
a[r, c] · (1 / pivot), as LAPACK's dgetf2 scales a column); each factorisation lives here
once. Compiled with :data:`hybrid_force._jit.jit`, whose module says why and by which
conventions.
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force._jit import jit as _jit
from hybrid_force._jit import jit_inline as _inline


@_jit
def cholesky(A: np.ndarray, L: np.ndarray) -> bool:
    """A = L Lᵀ for a symmetric (m, m) A: writes the lower triangle and diagonal of L (m, ≥ m).

    Row by row (Cholesky–Banachiewicz), the upper triangle of L is neither read nor written.
    Returns False when a pivot is not > 0 (A not positive definite, or NaN): L is then partly
    written.
    """
    m = A.shape[0]
    for j in range(m):
        d = A[j, j]
        for c in range(j):
            d -= L[j, c] * L[j, c]
        if not d > 0.0:
            return False
        d = math.sqrt(d)
        L[j, j] = d
        for i in range(j + 1, m):
            s = A[i, j]
            for c in range(j):
                s -= L[i, c] * L[j, c]
            L[i, j] = s / d
    return True


@_jit
def cholesky_solve_column(L: np.ndarray, b: np.ndarray, X: np.ndarray, col: int) -> None:
    """X[:, col] = (L Lᵀ)⁻¹ b for b (m,), by a forward then a backward substitution."""
    m = L.shape[0]
    for i in range(m):  # L y = b
        s = b[i]
        for c in range(i):
            s -= L[i, c] * X[c, col]
        X[i, col] = s / L[i, i]
    for i in range(m - 1, -1, -1):  # Lᵀ x = y
        s = X[i, col]
        for c in range(i + 1, m):
            s -= L[c, i] * X[c, col]
        X[i, col] = s / L[i, i]


@_inline
def lu_factor(a: np.ndarray, piv: np.ndarray) -> bool:
    """a (m, m) ← its LU factors in place (partial pivoting, row swaps in piv (m,)).

    Returns False at a zero pivot (a singular matrix; a is then partly factored).
    """
    m = a.shape[0]
    for c in range(m):
        p = c
        big = abs(a[c, c])
        for r in range(c + 1, m):
            x = abs(a[r, c])
            if x > big:
                big = x
                p = r
        piv[c] = p
        if big == 0.0:
            return False
        if p != c:
            for j in range(m):
                t = a[c, j]
                a[c, j] = a[p, j]
                a[p, j] = t
        inv = 1.0 / a[c, c]
        for r in range(c + 1, m):
            f = a[r, c] * inv
            a[r, c] = f
            if f != 0.0:
                for j in range(c + 1, m):
                    a[r, j] -= f * a[c, j]
    return True


@_inline
def lu_solve(lu: np.ndarray, piv: np.ndarray, b: np.ndarray) -> None:
    """b (m, r) ← a⁻¹ b in place, from the factors of :func:`lu_factor`."""
    m = lu.shape[0]
    cols = b.shape[1]
    for c in range(m):
        p = piv[c]
        if p != c:
            for j in range(cols):
                t = b[c, j]
                b[c, j] = b[p, j]
                b[p, j] = t
    for j in range(cols):
        for r in range(1, m):
            acc = b[r, j]
            for c in range(r):
                acc -= lu[r, c] * b[c, j]
            b[r, j] = acc
        for r in range(m - 1, -1, -1):
            acc = b[r, j]
            for c in range(r + 1, m):
                acc -= lu[r, c] * b[c, j]
            b[r, j] = acc / lu[r, r]


@_inline
def lu_solve_into(a: np.ndarray, rhs: np.ndarray, out: np.ndarray) -> bool:
    """out = a⁻¹ rhs for a (m, m), rhs (m, r) by :func:`lu_factor` (a, rhs unchanged).

    Returns False when a pivot is exactly zero (a singular: numpy's LinAlgError).
    """
    m = a.shape[0]
    lu = a.copy()
    piv = np.empty(m, np.int64)
    if not lu_factor(lu, piv):
        return False
    for i in range(m):
        for j in range(rhs.shape[1]):
            out[i, j] = rhs[i, j]
    lu_solve(lu, piv, out)
    return True


# --- products: each entry summed from 0.0 in the order of the inner index (no BLAS, no FMA,
# so a kernel that calls these computes what its loops written out computed, bit for bit) ----
@_inline
def dot(a: np.ndarray, b: np.ndarray) -> float:
    """Σ_i a[i] b[i] over b's length (a may be longer)."""
    acc = 0.0
    for i in range(b.shape[0]):
        acc += a[i] * b[i]
    return acc


@_inline
def rows3_dot(A: np.ndarray, r0: int, x: np.ndarray) -> tuple[float, float, float]:
    """(A[r0] · x, A[r0 + 1] · x, A[r0 + 2] · x): three rows of A x, A (≥ r0 + 3, n), x (n,)
    (the position or the angular rows of a Jacobian times a joint velocity)."""
    y0 = 0.0
    y1 = 0.0
    y2 = 0.0
    for j in range(x.shape[0]):
        y0 += A[r0, j] * x[j]
        y1 += A[r0 + 1, j] * x[j]
        y2 += A[r0 + 2, j] * x[j]
    return y0, y1, y2


@_inline
def matvec_into(A: np.ndarray, x: np.ndarray, out: np.ndarray) -> None:
    """out (r,) = A x over the first r rows of A (≥ r, n), x (n,)."""
    for i in range(out.shape[0]):
        acc = 0.0
        for j in range(x.shape[0]):
            acc += A[i, j] * x[j]
        out[i] = acc


@_inline
def matvec2_into(
    A: np.ndarray, x: np.ndarray, B: np.ndarray, y: np.ndarray, out: np.ndarray
) -> None:
    """out (r,) = A x + B y, each row's two sums formed apart then added (a PD's K e + D ė,
    a feed-forward's M q̈ + C q̇); A, B (≥ r, n), x, y (n,)."""
    for i in range(out.shape[0]):
        a = 0.0
        b = 0.0
        for j in range(x.shape[0]):
            a += A[i, j] * x[j]
            b += B[i, j] * y[j]
        out[i] = a + b


@_inline
def add_matvec_scaled(A: np.ndarray, x: np.ndarray, scale: float, out: np.ndarray) -> None:
    """out (r,) += A (scale x), each product A[i, j] · (scale · x[j]) (a posture's −k_n N Δq)."""
    for i in range(out.shape[0]):
        acc = 0.0
        for j in range(x.shape[0]):
            acc += A[i, j] * (scale * x[j])
        out[i] += acc


@_inline
def quad_form(A: np.ndarray, x: np.ndarray) -> float:
    """xᵀ A x = Σ_i x[i] (Σ_j A[i, j] x[j]) for A (n, n), x (n,) (a kinetic energy's 2T)."""
    n = x.shape[0]
    acc = 0.0
    for i in range(n):
        row = 0.0
        for j in range(n):
            row += A[i, j] * x[j]
        acc += x[i] * row
    return acc


@_inline
def mul_into(A: np.ndarray, B: np.ndarray, out: np.ndarray, at: bool, bt: bool) -> None:
    """out (r, c) = op(A) op(B), op(X) = Xᵀ when its flag (``at``, ``bt``) is set, else X:
    over the first r rows of op(A), its columns, and c columns of op(B). The flags are
    constants at each call, so the inlined loops index the arrays as stored (a transposed
    view instead, ``A.T``, cost each call ~100 ns on 5 × 5 matrices)."""
    n = A.shape[0] if at else A.shape[1]
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            acc = 0.0
            for m in range(n):
                acc += (A[m, i] if at else A[i, m]) * (B[j, m] if bt else B[m, j])
            out[i, j] = acc


@_inline
def eye_minus(A: np.ndarray) -> None:
    """A (m, m) ← I − A in place (a projector's complement: N = I − J⁺J, S = I − N (NᵀN)⁻¹Nᵀ)."""
    m = A.shape[0]
    for i in range(m):
        for j in range(m):
            A[i, j] = (1.0 if i == j else 0.0) - A[i, j]

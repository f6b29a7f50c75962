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


@_jit
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


@_jit
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

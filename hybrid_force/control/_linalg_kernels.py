"""Compiled small dense linear algebra shared by the controllers' kernels (Numba).

The laws' and the pose CLIK's kernels factor symmetric positive definite matrices of a few
rows (M, AAᵀ + λ²I); the factorisation lives here once. Compiled with
:data:`hybrid_force._jit.jit`, whose module says why and by which conventions.
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

"""Compiled evaluation of a tricubic B-spline field (the smooth Φ of a mesh part).

Reference: :mod:`hybrid_force.geometry.mesh_field`, which builds the coefficients and says
why the field is a B-spline. Compiled with :data:`hybrid_force._jit.jit`.
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force._jit import jit as _jit


@_jit
def _basis(t: float, b: np.ndarray, d: np.ndarray, s: np.ndarray) -> None:
    """The uniform cubic B-spline's 4 weights at t ∈ [0, 1] and their 1st, 2nd derivatives in t.

    b = ((1−t)³, 3t³ − 6t² + 4, −3t³ + 3t² + 3t + 1, t³) / 6 (de Boor, *A Practical Guide to
    Splines*, the uniform case), for the coefficients of nodes i−1, i, i+1, i+2 of a cell [i, i+1].
    """
    u = 1.0 - t
    t2 = t * t
    b[0] = u * u * u / 6.0
    b[1] = (3.0 * t2 * t - 6.0 * t2 + 4.0) / 6.0
    b[2] = (-3.0 * t2 * t + 3.0 * t2 + 3.0 * t + 1.0) / 6.0
    b[3] = t2 * t / 6.0
    d[0] = -0.5 * u * u
    d[1] = 1.5 * t2 - 2.0 * t
    d[2] = -1.5 * t2 + t + 0.5
    d[3] = 0.5 * t2
    s[0] = u
    s[1] = 3.0 * t - 2.0
    s[2] = -3.0 * t + 1.0
    s[3] = t


@_jit
def field_eval(
    coef: np.ndarray,
    origin: np.ndarray,
    h: float,
    p: np.ndarray,
    grad: np.ndarray,
    hess: np.ndarray,
) -> float:
    """Φ(p) of the tricubic B-spline with coefficients ``coef`` and its ∇Φ, ∇²Φ in closed form.

    coef: (nx + 2, ny + 2, nz + 2), the coefficients of nodes −1 … n (node i at
    origin + i·h); origin: (3,) [m]; h: node spacing [m]; p: (3,) [m]. Writes grad (3,) [Φ/m]
    and hess (3, 3) [Φ/m²]. Outside the grid's box the field is continued linearly from the
    box's nearest point p_c: Φ(p_c) + ∇Φ(p_c)·(p − p_c), ∇Φ = ∇Φ(p_c), ∇²Φ = 0 (C⁰ and C¹
    along the box's normal; the box is sized so that the tool works well inside it).
    """
    bx = np.empty(4)
    dx = np.empty(4)
    sx = np.empty(4)
    by = np.empty(4)
    dy = np.empty(4)
    sy = np.empty(4)
    bz = np.empty(4)
    dz = np.empty(4)
    sz = np.empty(4)
    cell = np.empty(3, dtype=np.int64)
    local = np.empty(3)
    offset = np.zeros(3)
    outside = False
    for k in range(3):
        n = coef.shape[k] - 2
        u = (p[k] - origin[k]) / h
        top = float(n - 1)
        if u < 0.0:
            offset[k] = (u - 0.0) * h
            u = 0.0
            outside = True
        elif u > top:
            offset[k] = (u - top) * h
            u = top
            outside = True
        i = math.floor(u)
        if i > n - 2:
            i = n - 2
        cell[k] = i
        local[k] = u - i
    _basis(local[0], bx, dx, sx)
    _basis(local[1], by, dy, sy)
    _basis(local[2], bz, dz, sz)
    value = 0.0
    gx = gy = gz = 0.0
    hxx = hyy = hzz = hxy = hxz = hyz = 0.0
    i0, j0, k0 = cell[0], cell[1], cell[2]
    for a in range(4):
        for b in range(4):
            # the sums over z first: 4 numbers per (a, b) shared by every derivative
            c0 = coef[i0 + a, j0 + b, k0]
            c1 = coef[i0 + a, j0 + b, k0 + 1]
            c2 = coef[i0 + a, j0 + b, k0 + 2]
            c3 = coef[i0 + a, j0 + b, k0 + 3]
            zb = c0 * bz[0] + c1 * bz[1] + c2 * bz[2] + c3 * bz[3]
            zd = c0 * dz[0] + c1 * dz[1] + c2 * dz[2] + c3 * dz[3]
            zs = c0 * sz[0] + c1 * sz[1] + c2 * sz[2] + c3 * sz[3]
            wbb = bx[a] * by[b]
            value += wbb * zb
            gx += dx[a] * by[b] * zb
            gy += bx[a] * dy[b] * zb
            gz += wbb * zd
            hxx += sx[a] * by[b] * zb
            hyy += bx[a] * sy[b] * zb
            hzz += wbb * zs
            hxy += dx[a] * dy[b] * zb
            hxz += dx[a] * by[b] * zd
            hyz += bx[a] * dy[b] * zd
    inv_h = 1.0 / h
    inv_h2 = inv_h * inv_h
    grad[0] = gx * inv_h
    grad[1] = gy * inv_h
    grad[2] = gz * inv_h
    if outside:
        value += grad[0] * offset[0] + grad[1] * offset[1] + grad[2] * offset[2]
        for r in range(3):
            for c in range(3):
                hess[r, c] = 0.0
        return value
    hess[0, 0] = hxx * inv_h2
    hess[1, 1] = hyy * inv_h2
    hess[2, 2] = hzz * inv_h2
    hess[0, 1] = hess[1, 0] = hxy * inv_h2
    hess[0, 2] = hess[2, 0] = hxz * inv_h2
    hess[1, 2] = hess[2, 1] = hyz * inv_h2
    return value


@_jit
def field_eval_many(
    coef: np.ndarray, origin: np.ndarray, h: float, points: np.ndarray, out: np.ndarray
) -> None:
    """Φ at each row of points (m, 3) [m] into out (m,) (for checks and figures)."""
    grad = np.empty(3)
    hess = np.empty((3, 3))
    for r in range(points.shape[0]):
        out[r] = field_eval(coef, origin, h, points[r], grad, hess)

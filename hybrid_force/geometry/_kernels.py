"""Compiled evaluation of the built-in surfaces and paths (Numba).

Built-in surfaces (cylinder, sphere, plane) and paths (helix, circle) describe their closed
form by a small array (``_descriptor``) that these kernels evaluate where the Python code would
call ``surface.evaluate`` or ``path.evaluate``; user-defined surfaces and paths stay in Python.
References: :mod:`hybrid_force.geometry.surfaces` and :mod:`hybrid_force.geometry.paths`.

Compiled with :data:`hybrid_force._jit.jit`, whose module says why and by which conventions.
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force._jit import jit as _jit


# --- surfaces (hybrid_force.geometry.surfaces: Cylinder, Sphere, Plane) ---------------------------
@_jit
def surface_eval(
    desc: np.ndarray, p: np.ndarray, grad: np.ndarray, hess: np.ndarray
) -> tuple[float, float]:
    """Φ, ∇Φ, ∇²Φ and d of a surface from its descriptor (``Surface._descriptor``) at p.

    desc[0] = 0: cylinder or sphere, desc = [0, c (3), a (3), sign, r², r] (a = 0 for a
    sphere): w = p − c minus (w·a) a, Φ = ±(‖w‖² − r²), ∇Φ = ±2w, ∇²Φ = ±2(I − aaᵀ),
    d = Φ / (‖w‖ + r). desc[0] = 1: plane, desc = [1, o (3), n (3)]: Φ = d = n·(p − o),
    ∇Φ = n, ∇²Φ = 0. The same operations as the Python methods. Writes grad (3,) and, unless
    hess is (0, 0), hess (3, 3). Returns (Φ, d).
    """
    if desc[0] == 1.0:
        value = desc[4] * (p[0] - desc[1]) + desc[5] * (p[1] - desc[2]) + desc[6] * (p[2] - desc[3])
        for r in range(3):
            grad[r] = desc[4 + r]
        if hess.shape[0] == 3:
            for r in range(3):
                for c in range(3):
                    hess[r, c] = 0.0
        return value, value
    ax, ay, az = desc[4], desc[5], desc[6]
    sign = desc[7]
    wx = p[0] - desc[1]
    wy = p[1] - desc[2]
    wz = p[2] - desc[3]
    t = wx * ax + wy * ay + wz * az
    wx, wy, wz = wx - t * ax, wy - t * ay, wz - t * az
    g = 2.0 * sign
    grad[0] = g * wx
    grad[1] = g * wy
    grad[2] = g * wz
    if hess.shape[0] == 3:
        a = (ax, ay, az)
        for r in range(3):
            for c in range(3):
                hess[r, c] = g * ((1.0 if r == c else 0.0) - a[r] * a[c])
    rho2 = wx * wx + wy * wy + wz * wz
    value = sign * (rho2 - desc[8])
    return value, value / (math.sqrt(rho2) + desc[9])


# --- paths (hybrid_force.geometry.paths._CircularPath.evaluate) -----------------------------------
@_jit
def circular_path(
    basis: np.ndarray,
    phase: float,
    omega: float,
    t: float,
    p: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
) -> None:
    """p = [cos θ, sin θ, t, 1] B, ṗ = [−ω sin θ, ω cos θ, 1, 0] B, p̈ = −ω² [cos θ, sin θ] B.

    basis: (4, 3) rows r·e1, r·e2, rise·a, c. θ = phase + ω t. Writes p, v, a (3,).
    """
    th = phase + omega * t
    co = math.cos(th)
    si = math.sin(th)
    wc = omega * co
    ws = omega * si
    for j in range(3):
        b0, b1 = basis[0, j], basis[1, j]
        p[j] = co * b0 + si * b1 + t * basis[2, j] + basis[3, j]
        v[j] = -ws * b0 + wc * b1 + basis[2, j]
        a[j] = -omega * wc * b0 - omega * ws * b1


@_jit
def path_sample(desc: np.ndarray, t: float, sample: np.ndarray) -> None:
    """p_d, ṗ_d, p̈_d at t [s] into the rows of sample (3, 3), from ``Path._descriptor``.

    desc = [0, phase, ω, B (4 × 3, row-major)]: a helix or a circle (:func:`circular_path`).
    """
    basis = desc[3:15].reshape((4, 3))
    circular_path(basis, desc[1], desc[2], t, sample[0], sample[1], sample[2])

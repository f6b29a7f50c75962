"""Compiled algebra of the robot terms (Numba): the rigid-body terms of one step after
Pinocchio's passes.

Reference: :class:`hybrid_force.model.robot.Robot` (one public method per term);
``tests/test_kernels.py`` compares the two at random states.

Compiled with :data:`hybrid_force._jit.jit`, whose module says why and by which conventions.
"""

from __future__ import annotations

import numpy as np

from hybrid_force._jit import jit as _jit


# --- robot (hybrid_force.model.robot.Robot.terms) -------------------------------------------------
@_jit
def robot_terms(
    Mu: np.ndarray,
    C_in: np.ndarray,
    g_in: np.ndarray,
    p_in: np.ndarray,
    J6: np.ndarray,
    Jd6: np.ndarray,
    v: np.ndarray,
    flat: np.ndarray,
) -> None:
    """Copy one step's Pinocchio outputs into the terms' buffer and derive the rest.

    Mu: (n, n) crba output (upper triangle valid). C_in: (n, n). g_in: (n,). p_in: (3,) tip
    position. J6, Jd6: (6, n) frame Jacobian and its time variation (rows 0..2 used). v: (n,).
    Writes the buffer of ``RobotTerms.zeros`` (2n² + 8n + 9,), row-major in the order of its
    packs: M (symmetric), C, g, nle = C v + g, J, J̇ (3, n), p, J̇ v, J v.
    """
    n = v.shape[0]
    nn = n * n
    o_C, o_g, o_nle = nn, 2 * nn, 2 * nn + n  # offsets of C, g, nle, J, J̇, p, J̇ v, J v
    o_J, o_Jd = 2 * nn + 2 * n, 2 * nn + 5 * n
    o_p, o_Jdv, o_pd = 2 * nn + 8 * n, 2 * nn + 8 * n + 3, 2 * nn + 8 * n + 6
    for r in range(3):
        flat[o_p + r] = p_in[r]
    for i in range(n):
        acc = g_in[i]
        for j in range(n):
            flat[i * n + j] = Mu[i, j] if i <= j else Mu[j, i]
            c = C_in[i, j]
            flat[o_C + i * n + j] = c
            acc += c * v[j]
        flat[o_g + i] = g_in[i]
        flat[o_nle + i] = acc
    for r in range(3):
        a = 0.0
        b = 0.0
        for j in range(n):
            x = J6[r, j]
            y = Jd6[r, j]
            flat[o_J + r * n + j] = x
            flat[o_Jd + r * n + j] = y
            a += x * v[j]
            b += y * v[j]
        flat[o_pd + r] = a
        flat[o_Jdv + r] = b

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
    mats: np.ndarray,
    vecs: np.ndarray,
    jac: np.ndarray,
    tip: np.ndarray,
) -> None:
    """Copy one step's Pinocchio outputs into the terms' arrays and derive the rest.

    Mu: (n, n) crba output (upper triangle valid). C_in: (n, n). g_in: (n,). p_in: (3,) tip
    position. J6, Jd6: (6, n) frame Jacobian and its time variation (rows 0..2 used). v: (n,).
    Writes (``RobotTerms.zeros``) mats = [M (symmetric), C], vecs = [g, nle = C v + g],
    jac = [J, J̇] (3, n), tip = [p, J̇ v, J v].
    """
    M, C, g, nle = mats[0], mats[1], vecs[0], vecs[1]
    J, Jdot, p, Jdot_v, pdot = jac[0], jac[1], tip[0], tip[1], tip[2]
    n = v.shape[0]
    for r in range(3):
        p[r] = p_in[r]
    for i in range(n):
        acc = g_in[i]
        for j in range(n):
            M[i, j] = Mu[i, j] if i <= j else Mu[j, i]
            c = C_in[i, j]
            C[i, j] = c
            acc += c * v[j]
        g[i] = g_in[i]
        nle[i] = acc
    for r in range(3):
        a = 0.0
        b = 0.0
        for j in range(n):
            x = J6[r, j]
            y = Jd6[r, j]
            J[r, j] = x
            Jdot[r, j] = y
            a += x * v[j]
            b += y * v[j]
        pdot[r] = a
        Jdot_v[r] = b

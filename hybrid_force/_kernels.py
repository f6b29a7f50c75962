"""Compiled arithmetic of the fast simulation step (Numba), one section per concept module.

The hot loop of :func:`hybrid_force.simulate` spends its time in a few hundred operations on
arrays of 3 to 30 numbers; from numpy each costs about a microsecond of call overhead, far
more than the arithmetic. Here the same formulas are written as loops and compiled once by
Numba (cached on disk), so each concept's algebra costs one call per step.

Every kernel here has a readable numpy or Python definition in its concept module, which stays
the reference: :mod:`hybrid_force.robot` (terms), :mod:`hybrid_force.surfaces` (Φ, ∇Φ, ∇²Φ,
d), :mod:`hybrid_force.constraint` (k = 1 rows), :mod:`hybrid_force.control` (eq. 4, 11,
29–30), :mod:`hybrid_force.clik` (eq. 27), :mod:`hybrid_force.paths` (helix, circle),
:mod:`hybrid_force.dynamics` (Baumgarte, the algebraic loop) and :mod:`hybrid_force.simulate`
(Euler, projection, the sample row). ``tests/test_kernels.py`` checks each kernel against its
reference, and ``tests/test_simulate.py`` the whole fast step against the reference step.

The simulator never calls the law's kernel, nor the controller the plant's. Built-in surfaces
and paths describe their closed form by a small array (``_descriptor``) that a kernel evaluates
where the Python code would call ``surface.evaluate`` or ``path.evaluate``; user-defined
surfaces and paths stay in Python. This
module is imported only by the fast paths (Numba takes about 0.5 s to import).
Conventions: outputs are preallocated arrays passed last and written in place.
"""

from __future__ import annotations

import math

import numba
import numpy as np

# error_model="numpy": a division by zero gives inf/nan (checked by the caller) instead of
# raising inside compiled code. No fastmath: the IEEE operation order is kept.
_jit = numba.njit(cache=True, error_model="numpy")


# --- robot (hybrid_force.robot.Robot.terms) --------------------------------------------------
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


# --- constraint (hybrid_force.constraint.Constraint, k = 1) ----------------------------------
@_jit
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


# --- control (hybrid_force.control.arimoto_law) ----------------------------------------------
@_jit
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
    u0, s, s0, s1, qdot_r, qddot_r0 = (
        vectors[0], vectors[1], vectors[2], vectors[3], vectors[4], vectors[5]
    )  # fmt: skip
    B, qddot_r_f = matrices[0], matrices[1]
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
    V = 0.0
    for i in range(n):
        ms = 0.0
        for j in range(n):
            ms += M[i, j] * s[j]
        V += s[i] * ms
    eF2 = 0.0
    for m in range(k):
        eF2 += e_F[m] * e_F[m]
    return 0.5 * V + 0.5 * beta * eF2


# --- clik (hybrid_force.clik.DesiredJointPath) ------------------------------------------------
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


@_jit
def clik_velocity(
    J6: np.ndarray,
    p: np.ndarray,
    sample: np.ndarray,
    cfg: np.ndarray,
    dq_post: np.ndarray,
    Jp: np.ndarray,
    W: np.ndarray,
    N: np.ndarray,
    x: np.ndarray,
    qd: np.ndarray,
) -> float:
    """q̇_d of eq. 27 at the current q_d, as ``DesiredJointPath._derivatives`` (first half).

    J6: (6, n) tip Jacobian (rows 0..2 used). p: (3,) tip position. sample: (3, 3) rows
    p_d, ṗ_d, p̈_d. cfg: (4,) γ, λ², redundant (0 or 1), k_n. dq_post: (n,) q_d ⊖ posture.
    Writes J⁻¹ or Jᵀ W into Jp (n, 3), W = (JJᵀ + λ²I)⁻¹ (redundant), N = I − JpJ,
    x = ṗ_d − γ(p − p_d) and q̇_d. Returns the cheap bound of cond(J Jᵀ) (inf if singular).
    """
    p_d, pdot_d = sample[0], sample[1]
    gamma, damping2, redundant, posture_gain = cfg[0], cfg[1], cfg[2] != 0.0, cfg[3]
    n = qd.shape[0]
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
        for r in range(3):
            for c in range(3):
                acc = 0.0
                for j in range(n):
                    acc += J6[r, j] * J6[c, j]
                JJt[r, c] = acc + (damping2 if r == c else 0.0)
        if _inv3_into(JJt, W) == 0.0:
            return np.inf
        cond = np.abs(JJt).max() * np.abs(W).max()
        for j in range(n):
            for c in range(3):
                Jp[j, c] = J6[0, j] * W[0, c] + J6[1, j] * W[1, c] + J6[2, j] * W[2, c]
    for j in range(n):
        qd[j] = Jp[j, 0] * x[0] + Jp[j, 1] * x[1] + Jp[j, 2] * x[2]
    if redundant and posture_gain > 0.0:
        for i in range(n):
            for j in range(n):
                N[i, j] = (1.0 if i == j else 0.0) - (
                    Jp[i, 0] * J6[0, j] + Jp[i, 1] * J6[1, j] + Jp[i, 2] * J6[2, j]
                )
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += N[i, j] * (-posture_gain * dq_post[j])
            qd[i] += acc
    return cond


@_jit
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
    _clik_qdd(J6, Jd6, Jp, W, N, x, qd, pdot_d, pddot_d, gamma, redundant, posture_gain,
              dq_post, qdd)  # fmt: skip
    if dt_pred > 0.0:
        taylor_step(q, qd, qdd, dt_pred, q_pred)


@_jit
def _clik_qdd(
    J6: np.ndarray,
    Jd6: np.ndarray,
    Jp: np.ndarray,
    W: np.ndarray,
    N: np.ndarray,
    x: np.ndarray,
    qd: np.ndarray,
    pdot_d: np.ndarray,
    pddot_d: np.ndarray,
    gamma: float,
    redundant: np.ndarray,
    posture_gain: np.ndarray,
    dq_post: np.ndarray,
    qdd: np.ndarray,
) -> None:
    n = qd.shape[0]
    xdot = np.empty(3)
    for r in range(3):
        acc = 0.0
        for j in range(n):
            acc += J6[r, j] * qd[j]
        xdot[r] = pddot_d[r] - gamma * (acc - pdot_d[r])
    if not redundant:
        y = np.empty(3)
        for r in range(3):
            acc = xdot[r]
            for j in range(n):
                acc -= Jd6[r, j] * qd[j]
            y[r] = acc
        for j in range(n):
            qdd[j] = Jp[j, 0] * y[0] + Jp[j, 1] * y[1] + Jp[j, 2] * y[2]
        return
    # Ẇ = −W (J̇Jᵀ + JJ̇ᵀ) W;  J̇⁺ = J̇ᵀW + JᵀẆ
    S = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            acc = 0.0
            for j in range(n):
                acc += Jd6[r, j] * J6[c, j] + J6[r, j] * Jd6[c, j]
            S[r, c] = acc
    # (explicit loops: numba's matmul would need SciPy's BLAS, which is not a dependency)
    WS = np.zeros((3, 3))
    for r in range(3):
        for c in range(3):
            for m in range(3):
                WS[r, c] += W[r, m] * S[m, c]
    Wdot = np.zeros((3, 3))
    for r in range(3):
        for c in range(3):
            acc = 0.0
            for m in range(3):
                acc += WS[r, m] * W[m, c]
            Wdot[r, c] = -acc
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


@_jit
def taylor_step(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, dt: float, out: np.ndarray) -> None:
    """out = q + q̇ dt + q̈ dt²/2 (Euclidean configuration spaces only)."""
    h = 0.5 * dt * dt
    for i in range(q.shape[0]):
        out[i] = q[i] + (qd[i] * dt + qdd[i] * h)


@_jit
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


# --- dynamics (hybrid_force.dynamics.constrained_acceleration) --------------------------------
@_jit
def baumgarte(
    drift: np.ndarray,
    rate: np.ndarray,
    value: np.ndarray,
    scale: np.ndarray,
    two_alpha: float,
    beta_sq: float,
    out: np.ndarray,
) -> None:
    """γ = drift + 2α A q̇ + β² Φ/s (k,), as ``Baumgarte.gamma`` (section 6.2)."""
    for m in range(out.shape[0]):
        out[m] = drift[m] + two_alpha * rate[m] + beta_sq * (value[m] / scale[m])


@_jit
def _solve_udut(U: np.ndarray, D: np.ndarray, b: np.ndarray, x: np.ndarray) -> None:
    """x = (U D Uᵀ)⁻¹ b with U (n, n) unit upper triangular and D (n,): Pinocchio's M."""
    n = b.shape[0]
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= U[i, j] * x[j]
        x[i] = acc
    for i in range(n):
        x[i] /= D[i]
    for i in range(n):
        acc = x[i]
        for j in range(i):
            acc -= U[j, i] * x[j]
        x[i] = acc


@_jit
def loop_resolve(
    U: np.ndarray,
    D: np.ndarray,
    A: np.ndarray,
    B: np.ndarray,
    ddq0: np.ndarray,
    f0: np.ndarray,
    ddq: np.ndarray,
    f: np.ndarray,
) -> bool:
    """Resolve the command u = u0 + B f from the KKT solution (q̈0, f0) at u = u0.

    With M = U D Uᵀ (the factorisation pinocchio.forwardDynamics leaves in data.U, data.D),
    X = M⁻¹Aᵀ, Y = M⁻¹B (n, k), G = A X and H = A Y (k, k), the constraint A q̈ = −γ gives
    (G + H) f = G f0 and q̈ = q̈0 + X (f − f0) + Y f. A: (k, n). B: (n, k). Writes q̈ (n,)
    and f (k,) [N]. Returns False when G + H is singular (no pivot above 1e-300).
    """
    n = ddq0.shape[0]
    k = f0.shape[0]
    X = np.empty((n, k))
    Y = np.empty((n, k))
    col = np.empty(n)
    sol = np.empty(n)
    for m in range(k):
        for i in range(n):
            col[i] = A[m, i]
        _solve_udut(U, D, col, sol)
        X[:, m] = sol
        for i in range(n):
            col[i] = B[i, m]
        _solve_udut(U, D, col, sol)
        Y[:, m] = sol
    S = np.empty((k, k))
    rhs = np.empty(k)
    for a in range(k):
        r = 0.0
        for c in range(k):
            g = 0.0
            h = 0.0
            for i in range(n):
                g += A[a, i] * X[i, c]
                h += A[a, i] * Y[i, c]
            S[a, c] = g + h
            r += g * f0[c]
        rhs[a] = r
    # Gaussian elimination with partial pivoting on the k × k system S f = rhs
    for c in range(k):
        piv = c
        for a in range(c + 1, k):
            if abs(S[a, c]) > abs(S[piv, c]):
                piv = a
        if not abs(S[piv, c]) > 1e-300:
            return False
        if piv != c:
            for j in range(k):
                S[c, j], S[piv, j] = S[piv, j], S[c, j]
            rhs[c], rhs[piv] = rhs[piv], rhs[c]
        for a in range(c + 1, k):
            ratio = S[a, c] / S[c, c]
            for j in range(c, k):
                S[a, j] -= ratio * S[c, j]
            rhs[a] -= ratio * rhs[c]
    for c in range(k - 1, -1, -1):
        acc = rhs[c]
        for j in range(c + 1, k):
            acc -= S[c, j] * f[j]
        f[c] = acc / S[c, c]
    for i in range(n):
        acc = ddq0[i]
        for m in range(k):
            acc += X[i, m] * (f[m] - f0[m]) + Y[i, m] * f[m]
        ddq[i] = acc
    return True


# --- simulate (hybrid_force.simulate: semi-implicit Euler and post-stabilisation, k = 1) -----
@_jit
def _put(row: np.ndarray, start: int, x: np.ndarray) -> int:
    for j in range(x.shape[0]):
        row[start + j] = x[j]
    return start + x.shape[0]


@_jit
def record_row(
    table: np.ndarray,
    i: int,
    t: float,
    q: np.ndarray,
    v: np.ndarray,
    q_d: np.ndarray,
    u0: np.ndarray,
    B: np.ndarray,
    f: np.ndarray,
    p: np.ndarray,
    p_d: np.ndarray,
    f_d: np.ndarray,
    phi: np.ndarray,
    V: float,
    phase: int,
    max_velocity: float,
    max_force: float,
) -> bool:
    """Write one sample into row i of the run's table (fields in the order of simulate._Log).

    The command column is u = u0 + B f (B: (n, k)). Returns True when q, v, f are finite,
    every |v_i| ≤ max_velocity and every |f_m| ≤ max_force.
    """
    row = table[i]
    row[0] = t
    c = _put(row, 1, q)
    c = _put(row, c, v)
    c = _put(row, c, q_d)
    n = u0.shape[0]
    for j in range(n):
        acc = u0[j]
        for m in range(f.shape[0]):
            acc += B[j, m] * f[m]
        row[c + j] = acc
    c = _put(row, c + n, p)
    c = _put(row, c, p_d)
    c = _put(row, c, f)
    c = _put(row, c, f_d)
    c = _put(row, c, phi)
    row[c] = V
    row[c + 1] = phase
    ok = True
    for j in range(q.shape[0]):
        ok = ok and math.isfinite(q[j])
    for j in range(v.shape[0]):
        ok = ok and abs(v[j]) <= max_velocity
    for m in range(f.shape[0]):
        ok = ok and abs(f[m]) <= max_force
    return ok


@_jit
def euler_step(
    q: np.ndarray,
    v: np.ndarray,
    ddq: np.ndarray,
    dt: float,
    v_out: np.ndarray,
    q_out: np.ndarray,
) -> None:
    """Semi-implicit Euler v⁺ = v + q̈ dt, q⁺ = q + v⁺ dt (Euclidean configuration spaces)."""
    for i in range(v.shape[0]):
        vi = v[i] + ddq[i] * dt
        v_out[i] = vi
        q_out[i] = q[i] + vi * dt


@_jit
def project_one(
    desc: np.ndarray,
    p: np.ndarray,
    grad: np.ndarray,
    phi: float,
    J6: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    q_out: np.ndarray,
    v_out: np.ndarray,
) -> float:
    """One Gauss–Newton step onto a surface and the velocity onto its tangent space, k = 1.

    desc: the surface's descriptor (:func:`surface_eval`), evaluated here at the tip p (3,);
    when empty, grad (3,) = ∇Φ and phi = Φ are given. J6: (6, n) tip Jacobian (rows 0..2).
    The row is A = n̂ᵀJ with n̂ = ∇Φ/‖∇Φ‖, the step length Φ/‖∇Φ‖ [m], A⁺ = Aᵀ/‖A‖² (as
    ``Constraint.normal_rows`` and ``_Plant.project``). Writes q_out = q − A⁺ Φ/‖∇Φ‖
    (Euclidean configuration spaces) and v_out = v − A⁺ (A v). Returns ‖∇Φ‖ (the caller
    checks it is not zero).
    """
    if desc.shape[0] > 0:
        phi, _ = surface_eval(desc, p, grad, np.zeros((0, 0)))
    n = q.shape[0]
    gn = math.sqrt(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2])
    n0, n1, n2 = grad[0] / gn, grad[1] / gn, grad[2] / gn
    dist = phi / gn
    row = np.empty(n)
    rr = 0.0
    rv = 0.0
    for j in range(n):
        r = n0 * J6[0, j] + n1 * J6[1, j] + n2 * J6[2, j]
        row[j] = r
        rr += r * r
        rv += r * v[j]
    for j in range(n):
        ap = row[j] / rr
        step = -(ap * dist)
        q_out[j] = q[j] + step
        v_out[j] = v[j] - ap * rv
    return gn


# --- surfaces (hybrid_force.surfaces: Cylinder, Sphere, Plane) --------------------------------
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


# --- paths (hybrid_force.paths._CircularPath.evaluate) ---------------------------------------
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


# --- controller momenta -----------------------------------------------------------------------
@_jit
def accumulate(
    x: np.ndarray, dx: np.ndarray, y: np.ndarray, dy: np.ndarray, dt: float, diff: np.ndarray
) -> None:
    """x += dx dt, y += dy dt, diff = x − y (the momenta F, F_d and e_F = F − F_d, eq. 3)."""
    for m in range(x.shape[0]):
        x[m] += dx[m] * dt
        y[m] += dy[m] * dt
        diff[m] = x[m] - y[m]

"""Compiled algebra of the pose CLIK's step (Numba): ``[tool] orientation = "normal"``.

The task rows, damped pseudo-inverse, q̇_d, q̈_d and the Newton correction of
:class:`hybrid_force.control.pose_clik.PoseJointPath`, roll free (m = 5) and held (m = 6).
Reference, the readable numpy version:
:class:`hybrid_force.control.pose_clik.ReferencePoseJointPath` (``_derivatives`` and
``_advance``); ``tests/test_pose_kernels.py`` checks each kernel against it. Pinocchio's
passes stay in the caller.

Shared arguments:

* J6, Jd6: (6, n) world-aligned tip Jacobian and its time variation; p (3,), R (3, 3): tip;
* sample: (3, 3) rows p_d, ṗ_d, p̈_d; goal: (4, 3) rows a_d, ȧ_d, ω_d, ω̇_d (ȧ_d unused
  with the roll held); R_d: (3, 3) the desired rotation (roll held; else unused);
* frame: (3, 3) rows â (the tool axis), ĉ₁, ĉ₂ (its complement) in the tip frame;
* cfg: (5,) γ, λ², posture (1: the null-space term is on), k_n, held (1: roll held);
* dq_post: (n,) q_d ⊖ posture.

Buffers written by :func:`pose_velocity` and read by :func:`pose_acceleration` and
:func:`pose_newton`: S (3, 3) (rows 0..1 roll free, I roll held), A (m, n), Ap (n, m),
W (m, m), N (n, n), y (m,), w (3,) = ω_d + γ e.

Compiled with :data:`hybrid_force._jit.jit`, whose module says why and by which conventions
(outputs preallocated and passed last, no fastmath; loops instead of np.dot, which would need
SciPy's BLAS).
"""

from __future__ import annotations

import numpy as np

from hybrid_force._jit import jit as _jit


@_jit
def _spd_inverse(G: np.ndarray, out: np.ndarray) -> bool:
    """out = G⁻¹ for a symmetric positive definite (m, m) G, by Cholesky (G = L Lᵀ).

    Returns False (out unchanged) when a pivot is not > 0 (G not positive definite)."""
    m = G.shape[0]
    L = np.zeros((m, m))
    for j in range(m):
        acc = G[j, j]
        for k in range(j):
            acc -= L[j, k] * L[j, k]
        if not acc > 0.0:
            return False
        d = np.sqrt(acc)
        L[j, j] = d
        for i in range(j + 1, m):
            acc = G[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            L[i, j] = acc / d
    # Linv = L⁻¹ (lower triangular), then G⁻¹ = Linvᵀ Linv
    Li = np.zeros((m, m))
    for j in range(m):
        Li[j, j] = 1.0 / L[j, j]
        for i in range(j + 1, m):
            acc = 0.0
            for k in range(j, i):
                acc -= L[i, k] * Li[k, j]
            Li[i, j] = acc / L[i, i]
    for r in range(m):
        for c in range(r, m):
            acc = 0.0
            for k in range(c, m):
                acc += Li[k, r] * Li[k, c]
            out[r, c] = acc
            out[c, r] = acc
    return True


@_jit
def _half_vee(M: np.ndarray, out: np.ndarray, scale: float) -> None:
    """out += scale · ½ vee(M − Mᵀ)."""
    out[0] += scale * 0.5 * (M[2, 1] - M[1, 2])
    out[1] += scale * 0.5 * (M[0, 2] - M[2, 0])
    out[2] += scale * 0.5 * (M[1, 0] - M[0, 1])


@_jit
def _orientation_error(R: np.ndarray, R_d: np.ndarray, out: np.ndarray) -> None:
    """out += ½ vee(R_d Rᵀ − R Rdᵀ) (``pose_clik._orientation_error``)."""
    M = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            M[i, j] = R_d[i, 0] * R[j, 0] + R_d[i, 1] * R[j, 1] + R_d[i, 2] * R[j, 2]
    _half_vee(M, out, 1.0)


@_jit
def _cross(a0: float, a1: float, a2: float, b: np.ndarray, out: np.ndarray) -> None:
    out[0] = a1 * b[2] - a2 * b[1]
    out[1] = a2 * b[0] - a0 * b[2]
    out[2] = a0 * b[1] - a1 * b[0]


@_jit
def _task_error(
    R: np.ndarray, frame: np.ndarray, a_d: np.ndarray, R_d: np.ndarray, held: bool, e: np.ndarray
) -> None:
    """e (3,): a × a_d (a = R â, roll free) or ½ Σ r_i × r_di (roll held)."""
    if held:
        e[0] = 0.0
        e[1] = 0.0
        e[2] = 0.0
        _orientation_error(R, R_d, e)
        return
    ax = frame[0]
    a0 = R[0, 0] * ax[0] + R[0, 1] * ax[1] + R[0, 2] * ax[2]
    a1 = R[1, 0] * ax[0] + R[1, 1] * ax[1] + R[1, 2] * ax[2]
    a2 = R[2, 0] * ax[0] + R[2, 1] * ax[1] + R[2, 2] * ax[2]
    _cross(a0, a1, a2, a_d, e)


@_jit
def pose_velocity(
    J6: np.ndarray,
    p: np.ndarray,
    R: np.ndarray,
    sample: np.ndarray,
    goal: np.ndarray,
    R_d: np.ndarray,
    frame: np.ndarray,
    cfg: np.ndarray,
    dq_post: np.ndarray,
    S: np.ndarray,
    A: np.ndarray,
    Ap: np.ndarray,
    W: np.ndarray,
    N: np.ndarray,
    y: np.ndarray,
    w: np.ndarray,
    qd: np.ndarray,
) -> float:
    """q̇_d = A⁺y + N z at (t, q_d), as ``ReferencePoseJointPath._derivatives`` (first half).

    Writes S, A, Ap = AᵀW, W = (AAᵀ + λ²I)⁻¹, N = I − ApA (posture on), y, w, q̇_d.
    Returns the cheap bound m² max|G| max|W| of cond(G), G = AAᵀ + λ²I (inf when G is not
    positive definite: then W, Ap and q̇_d are zero, as the reference's).
    """
    gamma, damping2, posture, gain, held = cfg[0], cfg[1], cfg[2] != 0.0, cfg[3], cfg[4] != 0.0
    n = J6.shape[1]
    m = A.shape[0]
    ms = m - 3
    p_d, pdot_d = sample[0], sample[1]
    # S = C Rᵀ (rows c_i = R ĉ_i) or I
    for i in range(3):
        for j in range(3):
            if held:
                S[i, j] = 1.0 if i == j else 0.0
            elif i < 2:
                C = frame[1 + i]
                S[i, j] = C[0] * R[j, 0] + C[1] * R[j, 1] + C[2] * R[j, 2]
            else:
                S[i, j] = 0.0
    for j in range(n):
        for r in range(3):
            A[r, j] = J6[r, j]
        for i in range(ms):
            A[3 + i, j] = S[i, 0] * J6[3, j] + S[i, 1] * J6[4, j] + S[i, 2] * J6[5, j]
    G = np.empty((m, m))
    gmax = 0.0
    for r in range(m):
        for c in range(m):
            acc = 0.0
            for j in range(n):
                acc += A[r, j] * A[c, j]
            if r == c:
                acc += damping2
            G[r, c] = acc
            if abs(acc) > gmax:
                gmax = abs(acc)
    ok = _spd_inverse(G, W)
    cond = np.inf
    if ok:
        wmax = 0.0
        for r in range(m):
            for c in range(m):
                if abs(W[r, c]) > wmax:
                    wmax = abs(W[r, c])
        cond = m * m * gmax * wmax
        for j in range(n):
            for c in range(m):
                acc = 0.0
                for r in range(m):
                    acc += A[r, j] * W[r, c]
                Ap[j, c] = acc
    else:
        W[:, :] = 0.0
        Ap[:, :] = 0.0
    e = np.empty(3)
    _task_error(R, frame, goal[0], R_d, held, e)
    w_d = goal[2]
    for k in range(3):
        w[k] = w_d[k] + gamma * e[k]
    for r in range(3):
        y[r] = pdot_d[r] - gamma * (p[r] - p_d[r])
    for i in range(ms):
        y[3 + i] = S[i, 0] * w[0] + S[i, 1] * w[1] + S[i, 2] * w[2]
    for j in range(n):
        acc = 0.0
        for r in range(m):
            acc += Ap[j, r] * y[r]
        qd[j] = acc
    if posture:
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for r in range(m):
                    acc += Ap[i, r] * A[r, j]
                N[i, j] = (1.0 if i == j else 0.0) - acc
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += N[i, j] * (-gain * dq_post[j])
            qd[i] += acc
    return cond


@_jit
def pose_acceleration(
    J6: np.ndarray,
    Jd6: np.ndarray,
    R: np.ndarray,
    sample: np.ndarray,
    goal: np.ndarray,
    R_d: np.ndarray,
    frame: np.ndarray,
    cfg: np.ndarray,
    dq_post: np.ndarray,
    S: np.ndarray,
    A: np.ndarray,
    Ap: np.ndarray,
    W: np.ndarray,
    N: np.ndarray,
    y: np.ndarray,
    w: np.ndarray,
    qd: np.ndarray,
    q: np.ndarray,
    dt_pred: float,
    qdd: np.ndarray,
    q_pred: np.ndarray,
) -> None:
    """q̈_d, the exact time derivative of q̇_d (second half of ``_derivatives``).

    Jd6 = J̇(q_d, q̇_d); the buffers as written by :func:`pose_velocity`. Writes q̈_d and, when
    dt_pred > 0, the next step's predictor q_pred = q + q̇_d dt + q̈_d dt²/2 (Euclidean
    configuration spaces only).
    """
    gamma, posture, gain, held = cfg[0], cfg[2] != 0.0, cfg[3], cfg[4] != 0.0
    n = J6.shape[1]
    m = A.shape[0]
    ms = m - 3
    pdot_d, pddot_d = sample[1], sample[2]
    # ω = J_ω q̇_d
    o0 = 0.0
    o1 = 0.0
    o2 = 0.0
    for j in range(n):
        o0 += J6[3, j] * qd[j]
        o1 += J6[4, j] * qd[j]
        o2 += J6[5, j] * qd[j]
    # Sw = S [ω]× (roll free), 0 (roll held)
    Sw = np.zeros((3, 3))
    if not held:
        for i in range(ms):
            s0, s1, s2 = S[i, 0], S[i, 1], S[i, 2]
            Sw[i, 0] = s1 * o2 - s2 * o1
            Sw[i, 1] = -s0 * o2 + s2 * o0
            Sw[i, 2] = s0 * o1 - s1 * o0
    # ė along q̇_d
    e_dot = np.zeros(3)
    if held:
        Rdot = np.empty((3, 3))  # [ω]× R
        Rd_dot = np.empty((3, 3))  # [ω_d]× R_d
        w_d = goal[2]
        for j in range(3):
            Rdot[0, j] = -o2 * R[1, j] + o1 * R[2, j]
            Rdot[1, j] = o2 * R[0, j] - o0 * R[2, j]
            Rdot[2, j] = -o1 * R[0, j] + o0 * R[1, j]
            Rd_dot[0, j] = -w_d[2] * R_d[1, j] + w_d[1] * R_d[2, j]
            Rd_dot[1, j] = w_d[2] * R_d[0, j] - w_d[0] * R_d[2, j]
            Rd_dot[2, j] = -w_d[1] * R_d[0, j] + w_d[0] * R_d[1, j]
        e1 = np.zeros(3)
        e2 = np.zeros(3)
        _orientation_error(Rdot, R_d, e1)
        _orientation_error(R, Rd_dot, e2)
        for k in range(3):
            e_dot[k] = e1[k] + e2[k]
    else:
        ax = frame[0]
        a = np.empty(3)
        for k in range(3):
            a[k] = R[k, 0] * ax[0] + R[k, 1] * ax[1] + R[k, 2] * ax[2]
        oa = np.empty(3)
        _cross(o0, o1, o2, a, oa)
        t1 = np.empty(3)
        _cross(oa[0], oa[1], oa[2], goal[0], t1)
        t2 = np.empty(3)
        _cross(a[0], a[1], a[2], goal[1], t2)
        for k in range(3):
            e_dot[k] = t1[k] + t2[k]
    w_dot = np.empty(3)
    for k in range(3):
        w_dot[k] = goal[3, k] + gamma * e_dot[k]
    # Ȧ = [J̇_p; S J̇_ω − Sw J_ω],  ẏ = [p̈_d − γ (J_p q̇_d − ṗ_d); S ẇ − Sw w]
    Adot = np.empty((m, n))
    for j in range(n):
        for r in range(3):
            Adot[r, j] = Jd6[r, j]
        for i in range(ms):
            Adot[3 + i, j] = (S[i, 0] * Jd6[3, j] + S[i, 1] * Jd6[4, j] + S[i, 2] * Jd6[5, j]) - (
                Sw[i, 0] * J6[3, j] + Sw[i, 1] * J6[4, j] + Sw[i, 2] * J6[5, j]
            )
    ydot = np.empty(m)
    for r in range(3):
        acc = 0.0
        for j in range(n):
            acc += J6[r, j] * qd[j]
        ydot[r] = pddot_d[r] - gamma * (acc - pdot_d[r])
    for i in range(ms):
        ydot[3 + i] = (S[i, 0] * w_dot[0] + S[i, 1] * w_dot[1] + S[i, 2] * w_dot[2]) - (
            Sw[i, 0] * w[0] + Sw[i, 1] * w[1] + Sw[i, 2] * w[2]
        )
    # Ẇ = −W (ȦAᵀ + AȦᵀ) W;  Ȧ⁺ = ȦᵀW + AᵀẆ
    T = np.empty((m, m))
    for r in range(m):
        for c in range(m):
            acc = 0.0
            for j in range(n):
                acc += Adot[r, j] * A[c, j] + A[r, j] * Adot[c, j]
            T[r, c] = acc
    WT = np.empty((m, m))
    for r in range(m):
        for c in range(m):
            acc = 0.0
            for k in range(m):
                acc += W[r, k] * T[k, c]
            WT[r, c] = acc
    Wdot = np.empty((m, m))
    for r in range(m):
        for c in range(m):
            acc = 0.0
            for k in range(m):
                acc += WT[r, k] * W[k, c]
            Wdot[r, c] = -acc
    Apd = np.empty((n, m))
    for j in range(n):
        for c in range(m):
            acc = 0.0
            for r in range(m):
                acc += Adot[r, j] * W[r, c] + A[r, j] * Wdot[r, c]
            Apd[j, c] = acc
    for j in range(n):
        acc = 0.0
        for r in range(m):
            acc += Apd[j, r] * y[r] + Ap[j, r] * ydot[r]
        qdd[j] = acc
    if posture:
        # Ṅ = −(Ȧ⁺A + A⁺Ȧ);  q̈_d += Ṅ z + N (−k_n q̇_d),  z = −k_n dq_post
        for i in range(n):
            acc = 0.0
            for j in range(n):
                nd = 0.0
                for r in range(m):
                    nd += Apd[i, r] * A[r, j] + Ap[i, r] * Adot[r, j]
                acc += -nd * (-gain * dq_post[j]) + N[i, j] * (-gain * qd[j])
            qdd[i] += acc
    if dt_pred > 0.0:
        h = 0.5 * dt_pred * dt_pred
        for i in range(q.shape[0]):
            q_pred[i] = q[i] + (qd[i] * dt_pred + qdd[i] * h)


@_jit
def pose_newton(
    p: np.ndarray,
    R: np.ndarray,
    sample: np.ndarray,
    goal: np.ndarray,
    R_d: np.ndarray,
    frame: np.ndarray,
    cfg: np.ndarray,
    S: np.ndarray,
    Ap: np.ndarray,
    q: np.ndarray,
    out: np.ndarray,
) -> None:
    """out = q + Ap r, r = [p_d − p; S e] at the predictor q (tip p, R), Euclidean spaces
    only; S and Ap are the previous step's (``ReferencePoseJointPath._advance``)."""
    held = cfg[4] != 0.0
    m = Ap.shape[1]
    r = np.empty(m)
    for k in range(3):
        r[k] = sample[0, k] - p[k]
    e = np.empty(3)
    _task_error(R, frame, goal[0], R_d, held, e)
    for i in range(m - 3):
        r[3 + i] = S[i, 0] * e[0] + S[i, 1] * e[1] + S[i, 2] * e[2]
    for i in range(q.shape[0]):
        acc = 0.0
        for k in range(m):
            acc += Ap[i, k] * r[k]
        out[i] = q[i] + acc

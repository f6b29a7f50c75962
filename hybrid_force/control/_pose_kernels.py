"""Compiled algebra of the pose CLIK's step (Numba): ``[tool] orientation = "normal"``.

The task rows, damped pseudo-inverse, q̇_d, q̈_d and the Newton correction of
:class:`hybrid_force.control.pose_clik.PoseJointPath`, roll free (m = 5) and held (m = 6).
The readable numpy version is the oracle ``ReferencePoseJointPath`` of
tests/oracles/control.py (``_derivatives`` and ``_advance``); ``tests/test_pose_kernels.py``
checks each kernel against it. Pinocchio's
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
from hybrid_force.control._kernels import add_posture, taylor_step
from hybrid_force.control._linalg_kernels import (
    cholesky,
    matvec_into,
    mul_into,
    rows3_dot,
)
from hybrid_force.geometry._kernels import surface_eval

_MIN_NORM = 1e-6  # tool._MIN_NORM: a direction built from a shorter vector is undefined


@_jit
def _spd_inverse(G: np.ndarray, out: np.ndarray) -> bool:
    """out = G⁻¹ for a symmetric positive definite (m, m) G, by Cholesky (G = L Lᵀ).

    Returns False (out unchanged) when a pivot is not > 0 (G not positive definite)."""
    m = G.shape[0]
    L = np.zeros((m, m))
    if not cholesky(G, L):
        return False
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
    """q̇_d = A⁺y + N z at (t, q_d), as the oracle's ``_derivatives`` (first half).

    Writes S, A, Ap = AᵀW, W = (AAᵀ + λ²I)⁻¹, N = I − ApA (posture on), y, w, q̇_d.
    Returns the cheap bound m² max|G| max|W| of cond(G), G = AAᵀ + λ²I (inf when G is not
    positive definite: then W, Ap and q̇_d are zero, as the oracle's).
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
    mul_into(A, A, G, False, True)
    gmax = 0.0
    for r in range(m):
        G[r, r] += damping2
        for c in range(m):
            if abs(G[r, c]) > gmax:
                gmax = abs(G[r, c])
    ok = _spd_inverse(G, W)
    cond = np.inf
    if ok:
        wmax = 0.0
        for r in range(m):
            for c in range(m):
                if abs(W[r, c]) > wmax:
                    wmax = abs(W[r, c])
        cond = m * m * gmax * wmax
        mul_into(A, W, Ap, True, False)
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
    matvec_into(Ap, y, qd)
    if posture:
        add_posture(Ap, A, dq_post, gain, N, qd)
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
    o0, o1, o2 = rows3_dot(J6, 3, qd)
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
    pdot = rows3_dot(J6, 0, qd)
    for r in range(3):
        ydot[r] = pddot_d[r] - gamma * (pdot[r] - pdot_d[r])
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
    mul_into(W, T, WT, False, False)
    Wdot = np.empty((m, m))
    mul_into(WT, W, Wdot, False, False)
    for r in range(m):
        for c in range(m):
            Wdot[r, c] = -Wdot[r, c]
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
        taylor_step(q, qd, qdd, dt_pred, q_pred)


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
    only; S and Ap are the previous step's (the oracle's ``_advance``)."""
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


# --- the desired direction (hybrid_force.control.tool.ToolTarget) ---------------------------------
@_jit
def _unit_jet(j: np.ndarray, out: np.ndarray) -> float:
    """out = u = v/‖v‖ as a jet (``tool._unit``); returns ‖v‖ (0: out is zero)."""
    v, dv, ddv = j[0], j[1], j[2]
    s = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if s == 0.0:
        out[:, :] = 0.0
        return 0.0
    u = np.empty(3)
    for k in range(3):
        u[k] = v[k] / s
    sd = u[0] * dv[0] + u[1] * dv[1] + u[2] * dv[2]
    du = np.empty(3)
    for k in range(3):
        du[k] = (dv[k] - sd * u[k]) / s
    sdd = (du[0] * dv[0] + du[1] * dv[1] + du[2] * dv[2]) + (
        u[0] * ddv[0] + u[1] * ddv[1] + u[2] * ddv[2]
    )
    for k in range(3):
        out[0, k] = u[k]
        out[1, k] = du[k]
        out[2, k] = (ddv[k] - 2.0 * sd * du[k] - sdd * u[k]) / s
    return s


@_jit
def _c3(a: np.ndarray, b: np.ndarray, k: int) -> float:
    """Component k of a × b."""
    if k == 0:
        return a[1] * b[2] - a[2] * b[1]
    if k == 1:
        return a[2] * b[0] - a[0] * b[2]
    return a[0] * b[1] - a[1] * b[0]


@_jit
def _cross_jet(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """out = a × b as a jet (Leibniz, ``tool._cross``)."""
    for k in range(3):
        out[0, k] = _c3(a[0], b[0], k)
        out[1, k] = _c3(a[1], b[0], k) + _c3(a[0], b[1], k)
        out[2, k] = _c3(a[2], b[0], k) + 2.0 * _c3(a[1], b[1], k) + _c3(a[0], b[2], k)


@_jit
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_jit
def _across_jet(a: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """out = v − (a·v) a as a jet (``tool._across``)."""
    s0 = _dot(a[0], v[0])
    s1 = _dot(a[1], v[0]) + _dot(a[0], v[1])
    s2 = _dot(a[2], v[0]) + 2.0 * _dot(a[1], v[1]) + _dot(a[0], v[2])
    for k in range(3):
        out[0, k] = v[0, k] - s0 * a[0, k]
        out[1, k] = v[1, k] - (s1 * a[0, k] + s0 * a[1, k])
        out[2, k] = v[2, k] - (s2 * a[0, k] + 2.0 * s1 * a[1, k] + s0 * a[2, k])


@_jit
def pose_goal(
    desc: np.ndarray,
    sample: np.ndarray,
    grad: np.ndarray,
    hess: np.ndarray,
    third: np.ndarray,
    tilt_axis: np.ndarray,
    travel: np.ndarray,
    tool: np.ndarray,
    R_fix: np.ndarray,
    goal: np.ndarray,
    R_d: np.ndarray,
) -> int:
    """The desired direction at one path sample: ``ToolTarget.axis`` (and ``frame``).

    desc: the surface's descriptor (a built-in quadric: ∇Φ, ∇²Φ evaluated here into grad
    (3,), hess (3, 3), third ignored), or empty: grad, hess and third = (d/dt ∇²Φ) ṗ_d given.
    tilt_axis: (3, 3) the jet [k, 0, 0] of the tilt axis (lean 1); travel: (3, 3) the
    path's direction jet (lean 2, roll held). tool: (4,) cos θ, sin θ, lean (0: none, 1: tilt axis,
    2: travel), held (1: roll held). R_fix: (3, 3) F(0)ᵀ R(q_d(0)) (roll held; I at t0).
    Writes goal (4, 3) rows a_d, ȧ_d, ω_d, ω̇_d and, roll held, R_d = F R_fix.
    Returns 0, or where the direction is undefined 1 (∇Φ = 0), 2 (the lean), 3 (the roll);
    the caller raises ``ToolTarget.undefined`` of that code.
    """
    p, pd, pdd = sample[0], sample[1], sample[2]
    if desc.shape[0] > 0:
        surface_eval(desc, p, grad, hess)
        third = np.zeros(3)
    gj = np.empty((3, 3))
    for r in range(3):
        gj[0, r] = grad[r]
        gj[1, r] = hess[r, 0] * pd[0] + hess[r, 1] * pd[1] + hess[r, 2] * pd[2]
        gj[2, r] = (hess[r, 0] * pdd[0] + hess[r, 1] * pdd[1] + hess[r, 2] * pdd[2]) + third[r]
    if not np.sqrt(_dot(grad, grad)) > 1e-12:
        return 1
    nj = np.empty((3, 3))
    _unit_jet(gj, nj)
    co, si, mode, held = tool[0], tool[1], tool[2], tool[3] != 0.0
    a = np.empty((3, 3))
    if si == 0.0:
        for r in range(3):
            for k in range(3):
                a[r, k] = -nj[r, k]
    else:
        raw = np.empty((3, 3))
        if mode == 1.0:
            _cross_jet(nj, tilt_axis, raw)
        else:
            _across_jet(nj, travel, raw)
        d = np.empty((3, 3))
        if not _unit_jet(raw, d) > _MIN_NORM:
            return 2
        for r in range(3):
            for k in range(3):
                a[r, k] = -co * nj[r, k] + si * d[r, k]
    for k in range(3):
        goal[0, k] = a[0, k]
    if not held:
        for k in range(3):
            goal[1, k] = a[1, k]
            goal[2, k] = _c3(a[0], a[1], k)
            goal[3, k] = _c3(a[0], a[2], k)
        return 0
    raw = np.empty((3, 3))
    _across_jet(a, travel, raw)
    x = np.empty((3, 3))
    if not _unit_jet(raw, x) > _MIN_NORM:
        return 3
    y = np.empty((3, 3))
    _cross_jet(a, x, y)
    for k in range(3):
        goal[2, k] = 0.5 * (_c3(x[0], x[1], k) + _c3(y[0], y[1], k) + _c3(a[0], a[1], k))
        goal[3, k] = 0.5 * (_c3(x[0], x[2], k) + _c3(y[0], y[2], k) + _c3(a[0], a[2], k))
    for i in range(3):
        for j in range(3):
            R_d[i, j] = x[0, i] * R_fix[0, j] + y[0, i] * R_fix[1, j] + a[0, i] * R_fix[2, j]
    return 0

"""Compiled algebra of the plant's step (Numba): Baumgarte stabilisation, the exact
resolution of the algebraic loop u = u0 + B f, semi-implicit Euler with projection onto the
surface (k = 1), and the row of the record.

References: :mod:`hybrid_force.sim.dynamics` and the numpy oracles of the tests
(tests/oracles/plant.py: the dense KKT solve and the oracle plant). The controller never calls
these kernels.

Compiled with :data:`hybrid_force._jit.jit`, whose module says why and by which conventions.
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force._jit import jit as _jit
from hybrid_force._jit import jit_inline as _inline
from hybrid_force.geometry._kernels import surface_eval


# --- dynamics (hybrid_force.sim.dynamics.ConstrainedDynamics) --------------------------------
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


@_inline
def solver_parts(
    ws: np.ndarray, n: int
) -> tuple[int, float, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """k, 2α [1/s], β² [1/s²] and the views q̈ (n,), f (k,), γ (k,), effort (n,) or (0,) of
    the constrained solve's buffer ws (``ConstrainedDynamics._ws``, 4 + 2n + 2k): ws[0] = k,
    ws[1] = the effort limits' count (n, or 0: none), ws[2] = 2α, ws[3] = β², then q̈, f, γ
    and n entries for the limits, in that order. One buffer, one argument: Numba's call
    costs ~0.14 µs per array argument."""
    k, ne = int(ws[0]), int(ws[1])
    o = 4
    ddq = ws[o : o + n]
    f = ws[o + n : o + n + k]
    gamma = ws[o + n + k : o + n + 2 * k]
    effort = ws[o + n + 2 * k : o + n + 2 * k + ne]
    return k, ws[2], ws[3], ddq, f, gamma, effort


@_inline
def _scalars_at(k: int, n: int) -> int:
    """Where the scalars (6, k) start in the flat array of ``ConstraintTerms.zeros(k, n)``
    (the layout of ``control._kernels.constraint_parts``: rows (4, k, n), cols (2, n, k),
    squares (2, n, n), scalars): the kernels here slice the few fields they read instead of
    building the four packs (each reshape costs a call)."""
    return 6 * k * n + 2 * n * n


@_jit
def kkt_inputs(cons: np.ndarray, ws: np.ndarray, nle: np.ndarray, data_nle: np.ndarray) -> None:
    """The inputs of ``pin.forwardDynamics`` in one call: γ (k,) as :func:`baumgarte` from the
    constraint's flat array cons (``ConstraintTerms._flat``: its drift, A q̇, Φ and s), with
    the gains of the solver's buffer ws (:func:`solver_parts`), written into its γ; and
    C q̇ + g (n,) copied into data_nle (the view of ``data.nle`` it reads)."""
    n = nle.shape[0]
    k, two_alpha, beta_sq, _, _, gamma, _ = solver_parts(ws, n)
    c = _scalars_at(k, n)  # Φ, d, s, A q̇, raw drift, drift: (k,) each
    drift, rate = cons[c + 5 * k : c + 6 * k], cons[c + 3 * k : c + 4 * k]
    baumgarte(drift, rate, cons[c : c + k], cons[c + 2 * k : c + 3 * k], two_alpha, beta_sq, gamma)
    for i in range(n):
        data_nle[i] = nle[i]


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


@_jit
def exceeds_effort(u0: np.ndarray, B: np.ndarray, f: np.ndarray, effort: np.ndarray) -> bool:
    """True when some |u_i| > effort_i for the command u = u0 + B f: u0, effort (n,) [N·m or
    N], B (n, k) (k = 0: u = u0), f (k,) [N]. A NaN in u is not beyond (as numpy's
    comparison); the saturated path of ``sim.rigid_contact`` runs only when this is True."""
    n, k = B.shape
    for i in range(n):
        u = u0[i]
        for m in range(k):
            u += B[i, m] * f[m]
        if abs(u) > effort[i]:
            return True
    return False


@_jit
def loop_checked(
    U: np.ndarray,
    D: np.ndarray,
    cons: np.ndarray,
    B: np.ndarray,
    ddq0: np.ndarray,
    f0: np.ndarray,
    u0: np.ndarray,
    ws: np.ndarray,
) -> int:
    """:func:`loop_resolve` and :func:`exceeds_effort` in one call, after forwardDynamics.

    cons: the constraint's flat array (``ConstraintTerms._flat``), whose A (k, n) is read.
    B (n, k) as in :func:`loop_resolve`; B with no column (the command does not depend on f):
    q̈ = q̈0 and f = f0, copied. ws: the solver's buffer (:func:`solver_parts`), whose q̈ (n,)
    and f (k,) [N] are written and whose effort limits (n,) [N·m or N] are checked (none
    held: no limit checked). Returns −1 when the loop has no unique solution (nothing
    checked), 1 when some |u_i| > effort_i for u = u0 + B f, else 0.
    """
    n = u0.shape[0]
    k, _, _, ddq, f, _, effort = solver_parts(ws, n)
    A = cons[2 * k * n : 3 * k * n].reshape((k, n))  # rows = [J_Φ, J_Φn, A, Ȧ] (k, n) each
    if B.shape[1] == 0:
        for i in range(ddq0.shape[0]):
            ddq[i] = ddq0[i]
        for m in range(f0.shape[0]):
            f[m] = f0[m]
    elif not loop_resolve(U, D, A, B, ddq0, f0, ddq, f):
        return -1
    if effort.shape[0] != 0 and exceeds_effort(u0, B, f, effort):
        return 1
    return 0


# --- simulate (hybrid_force.sim.loop: semi-implicit Euler and post-stabilisation, k = 1) ----------
@_jit
def _put(row: np.ndarray, start: int, x: np.ndarray) -> int:
    for j in range(x.shape[0]):
        row[start + j] = x[j]
    return start + x.shape[0]


#: entries of the record's buffer before its table (:func:`record_parts`)
RECORD_HEADER = 6


@_inline
def record_parts(
    buf: np.ndarray, i: int
) -> tuple[float, float, np.ndarray, np.ndarray, np.ndarray]:
    """max_velocity, max_force and the views of row i of the table (W,), of u_cmd (n,), or
    (0,) when the run has no effort limits, and of the law's log (m,), or (0,), in the
    record's buffer (``Record._buf``): buf[0] = max_velocity, buf[1] = max_force, buf[2] = N,
    buf[3] = W, buf[4] = the columns of u_cmd (n, or 0), buf[5] = the law's signals m, then
    the table's N rows, u_cmd's N rows and the log's N rows (none when 0). One buffer, one
    argument: Numba's call costs ~0.14 µs per array argument."""
    N, W, m, m_log = int(buf[2]), int(buf[3]), int(buf[4]), int(buf[5])
    o = RECORD_HEADER
    # row i's slices, not (N, W) and (N, n) views: a reshape costs a call per sample
    row = buf[o + i * W : o + (i + 1) * W]
    o += N * W
    u_cmd = buf[o + i * m : o + (i + 1) * m]
    o += N * m
    return buf[0], buf[1], row, u_cmd, buf[o + i * m_log : o + (i + 1) * m_log]


@_jit
def record_row(
    buf: np.ndarray,
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
    applied: np.ndarray,
    log_values: np.ndarray,
    log_index: np.ndarray,
) -> bool:
    """Write one sample into row i of the run's table (fields in the order of simulate._Log).

    buf: the record's buffer (:func:`record_parts`: the table, the commanded torques' table,
    the law's log and the limits checked). The command column is the applied torque:
    ``applied`` (n,) when the effort limits changed it, else (size 0) the command
    u = u0 + B f (B: (n, k)); u_cmd (N, n), the commanded torques' table of a run with effort
    limits, gets u0 + B f in its row i (0 rows: none). The law's log (N, m) gets
    log_values[log_index] (log_index (m,) int64 within log_values: ``Law.log_source``,
    checked by the record). Returns True when q, v, f are finite, every |v_i| ≤
    max_velocity and every |f_m| ≤ max_force.
    """
    max_velocity, max_force, row, u_cmd_row, log_row = record_parts(buf, i)
    row[0] = t
    c = _put(row, 1, q)
    c = _put(row, c, v)
    c = _put(row, c, q_d)
    n = u0.shape[0]
    limited = applied.shape[0] != 0
    commanded = u_cmd_row.shape[0] != 0
    for j in range(n):
        acc = u0[j]
        for m in range(f.shape[0]):
            acc += B[j, m] * f[m]
        row[c + j] = applied[j] if limited else acc
        if commanded:
            u_cmd_row[j] = acc
    c = _put(row, c + n, p)
    c = _put(row, c, p_d)
    c = _put(row, c, f)
    c = _put(row, c, f_d)
    c = _put(row, c, phi)
    row[c] = V
    row[c + 1] = phase
    for j in range(log_row.shape[0]):
        log_row[j] = log_values[log_index[j]]
    ok = True
    for j in range(q.shape[0]):
        ok = ok and math.isfinite(q[j])
    for j in range(v.shape[0]):
        ok = ok and abs(v[j]) <= max_velocity
    for m in range(f.shape[0]):
        ok = ok and abs(f[m]) <= max_force
    return ok


#: entries of the contact step's buffer before its arrays (:func:`step_parts`)
STEP_HEADER = 5


@_inline
def step_parts(
    ws: np.ndarray, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Views of the compiled contact step's buffer ws (``RigidContact._ws``,
    5 + 5n + len(desc)): ws[0] = the descriptor's length, ws[1] = Φ and ws[2:5] = ∇Φ (3,)
    given by a surface with no descriptor, then q_tmp, v_tmp (n,) (the Euler step's
    outputs), the two q_out (n,) (the projection's, used alternately), the constraint row
    (n,) and the surface's descriptor, in that order. Returns (grad, q_tmp, v_tmp, both
    q_out as one (2n,) slice, row, desc, ws[1:2]). One buffer, one argument: Numba's call
    costs ~0.14 µs per array argument."""
    nd = int(ws[0])
    o = STEP_HEADER
    q_tmp = ws[o : o + n]
    v_tmp = ws[o + n : o + 2 * n]
    q_out = ws[o + 2 * n : o + 4 * n]  # the two q_out one after the other (no reshape: a call)
    row = ws[o + 4 * n : o + 5 * n]
    desc = ws[o + 5 * n : o + 5 * n + nd]
    return ws[2:5], q_tmp, v_tmp, q_out, row, desc, ws[1:2]


@_jit
def euler_step(q: np.ndarray, v: np.ndarray, ddq: np.ndarray, dt: float, ws: np.ndarray) -> None:
    """Semi-implicit Euler v⁺ = v + q̈ dt, q⁺ = q + v⁺ dt (Euclidean configuration spaces),
    written into the v_tmp and q_tmp (n,) of the contact step's buffer ws
    (:func:`step_parts`)."""
    _, q_out, v_out, _, _, _, _ = step_parts(ws, v.shape[0])
    for i in range(v.shape[0]):
        vi = v[i] + ddq[i] * dt
        v_out[i] = vi
        q_out[i] = q[i] + vi * dt


@_jit
def project_one(p: np.ndarray, J6: np.ndarray, ws: np.ndarray, slot: int) -> float:
    """One Gauss–Newton step onto a surface, k = 1, and the constraint row it used.

    ws: the contact step's buffer (:func:`step_parts`): its surface descriptor
    (:func:`surface_eval`) is evaluated here at the tip p (3,), or when empty its ∇Φ (3,) and
    Φ are read; the step starts from its q_tmp (n,). J6: (6, n) tip Jacobian (rows 0..2).
    The row is A = n̂ᵀJ with n̂ = ∇Φ/‖∇Φ‖, the step length Φ/‖∇Φ‖ [m], A⁺ = Aᵀ/‖A‖² (as
    ``Constraint.normal_rows`` and ``_Plant.project``). Writes q_out[slot] = q − A⁺ Φ/‖∇Φ‖
    (Euclidean configuration spaces) and the row (n,) = A of ws, for the velocity's
    constraint impulse (``Plant._impulse``). Returns ‖∇Φ‖ (the caller checks it is not zero).
    """
    n = J6.shape[1]
    grad, q, _, outs, row_out, desc, given = step_parts(ws, n)
    q_out = outs[slot * n : (slot + 1) * n]
    phi = given[0]
    if desc.shape[0] > 0:
        phi, _ = surface_eval(desc, p, grad, np.zeros((0, 0)))
    gn = math.sqrt(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2])
    n0, n1, n2 = grad[0] / gn, grad[1] / gn, grad[2] / gn
    dist = phi / gn
    rr = 0.0
    for j in range(n):
        r = n0 * J6[0, j] + n1 * J6[1, j] + n2 * J6[2, j]
        row_out[j] = r
        rr += r * r
    for j in range(n):
        q_out[j] = q[j] - (row_out[j] / rr) * dist
    return gn

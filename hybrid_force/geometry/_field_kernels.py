"""Compiled evaluation of a tricubic B-spline field (the smooth Φ of a mesh part).

Reference: :mod:`hybrid_force.geometry.mesh_field`, which builds the coefficients and says
why the field is a B-spline. Compiled with :data:`hybrid_force._jit.jit`.
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force._jit import jit as _jit
from hybrid_force._jit import jit_inline


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
    work = np.empty((9, 4))
    return _field_eval_into(coef, origin, h, p, grad, hess, work)


@_jit
def field_hessian(
    coef: np.ndarray,
    origin: np.ndarray,
    h: float,
    p: np.ndarray,
    grad: np.ndarray,
    hess: np.ndarray,
) -> bool:
    """:func:`field_eval` into grad (3,) and hess (3, 3) when every coordinate of p is finite
    and within 1e150 m (True), else nothing written (False: the caller checks p itself and
    says why). Checked here, not in Python: a ∇²Φ off the tip is asked for twice a step."""
    for k in range(3):
        if not abs(p[k]) <= 1e150:
            return False
    work = np.empty((9, 4))
    _field_eval_into(coef, origin, h, p, grad, hess, work)
    return True


@_jit
def orientation_terms(
    coef: np.ndarray,
    origin: np.ndarray,
    h: float,
    step: float,
    sample: np.ndarray,
    out: np.ndarray,
) -> bool:
    """What a pointed tool's orientation needs of Φ at a path sample (3, 3) rows p_d [m],
    ṗ_d [m/s], p̈_d: out (5, 3) rows ∇Φ(p_d), ∇²Φ(p_d) (3 rows), and (d/dt ∇²Φ) ṗ_d by the
    central difference (∇²Φ(p_d + δ ṗ_d) − ∇²Φ(p_d − δ ṗ_d)) / (2δ) · ṗ_d, δ = step / ‖ṗ_d‖
    (zero when ṗ_d = 0): the arithmetic of ``control.tool.ToolTarget.surface_terms`` in one
    call. False, nothing written, when p_d or ṗ_d is not finite (the caller's own path then
    says why)."""
    for r in range(2):
        for k in range(3):
            if not abs(sample[r, k]) <= 1e150:
                return False
    grad = np.empty(3)
    hess = np.empty((3, 3))
    work = np.empty((9, 4))
    _field_eval_into(coef, origin, h, sample[0], grad, hess, work)
    for k in range(3):
        out[0, k] = grad[k]
        out[4, k] = 0.0
        for c in range(3):
            out[1 + k, c] = hess[k, c]
    speed2 = sample[1, 0] * sample[1, 0] + sample[1, 1] * sample[1, 1] + sample[1, 2] * sample[1, 2]
    if not speed2 > 0.0:
        return True
    delta = step / math.sqrt(speed2)
    q = np.empty(3)
    ahead = np.empty((3, 3))
    for k in range(3):
        q[k] = sample[0, k] + delta * sample[1, k]
    _field_eval_into(coef, origin, h, q, grad, ahead, work)
    for k in range(3):
        q[k] = sample[0, k] - delta * sample[1, k]
    _field_eval_into(coef, origin, h, q, grad, hess, work)
    for i in range(3):
        total = 0.0
        for j in range(3):
            total += (ahead[i, j] - hess[i, j]) / (2.0 * delta) * sample[1, j]
        out[4, i] = total
    return True


@jit_inline
def _cell(
    coef: np.ndarray, origin: np.ndarray, h: float, p: np.ndarray, work: np.ndarray
) -> tuple[bool, int, int, int, float, float, float]:
    """The grid cell of p and its B-spline weights: (outside the box, i0, j0, k0, and the
    offsets o [m] of p from the box's nearest point per axis), with the basis of each axis k
    and its first and second derivatives written into ``work[3k : 3k + 3]`` (:func:`_basis`).
    Outside the box Φ continues linearly from its nearest point (its callers add ∇Φ · o)."""
    bx, dx, sx = work[0], work[1], work[2]
    by, dy, sy = work[3], work[4], work[5]
    bz, dz, sz = work[6], work[7], work[8]
    outside = False
    o0 = o1 = o2 = 0.0
    i0 = j0 = k0 = 0
    for k in range(3):
        n = coef.shape[k] - 2
        u = (p[k] - origin[k]) / h
        top = float(n - 1)
        off = 0.0
        if u < 0.0:
            off = (u - 0.0) * h
            u = 0.0
            outside = True
        elif u > top:
            off = (u - top) * h
            u = top
            outside = True
        i = math.floor(u)
        if i > n - 2:
            i = n - 2
        if k == 0:
            i0, o0 = i, off
            _basis(u - i, bx, dx, sx)
        elif k == 1:
            j0, o1 = i, off
            _basis(u - i, by, dy, sy)
        else:
            k0, o2 = i, off
            _basis(u - i, bz, dz, sz)
    return outside, i0, j0, k0, o0, o1, o2


@jit_inline
def _sums(
    coef: np.ndarray, i0: int, j0: int, k0: int, work: np.ndarray, order: int
) -> tuple[float, float, float, float, float, float, float, float, float, float]:
    """The tricubic sums over the 4 × 4 × 4 coefficients of a cell, in grid units: Φ, then for
    ``order`` ≥ 1 ∇Φ (x, y, z) and for ``order`` 2 the Hessian (xx, yy, zz, xy, xz, yz), the
    others 0; ``work``: the weights of :func:`_cell`. One order of operations for every
    evaluation, so each gives the same bits as the full one (an inlined constant ``order``
    drops the sums it does not need)."""
    bx, dx, sx = work[0], work[1], work[2]
    by, dy, sy = work[3], work[4], work[5]
    bz, dz, sz = work[6], work[7], work[8]
    value = 0.0
    gx = gy = gz = 0.0
    hxx = hyy = hzz = hxy = hxz = hyz = 0.0
    for a in range(4):
        for b in range(4):
            # the sums over z first: 4 numbers per (a, b) shared by every derivative
            c0 = coef[i0 + a, j0 + b, k0]
            c1 = coef[i0 + a, j0 + b, k0 + 1]
            c2 = coef[i0 + a, j0 + b, k0 + 2]
            c3 = coef[i0 + a, j0 + b, k0 + 3]
            zb = c0 * bz[0] + c1 * bz[1] + c2 * bz[2] + c3 * bz[3]
            wbb = bx[a] * by[b]
            value += wbb * zb
            if order >= 1:
                zd = c0 * dz[0] + c1 * dz[1] + c2 * dz[2] + c3 * dz[3]
                gx += dx[a] * by[b] * zb
                gy += bx[a] * dy[b] * zb
                gz += wbb * zd
                if order >= 2:
                    zs = c0 * sz[0] + c1 * sz[1] + c2 * sz[2] + c3 * sz[3]
                    hxx += sx[a] * by[b] * zb
                    hyy += bx[a] * sy[b] * zb
                    hzz += wbb * zs
                    hxy += dx[a] * dy[b] * zb
                    hxz += dx[a] * by[b] * zd
                    hyz += bx[a] * dy[b] * zd
    return value, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz


@_jit
def _field_eval_into(
    coef: np.ndarray,
    origin: np.ndarray,
    h: float,
    p: np.ndarray,
    grad: np.ndarray,
    hess: np.ndarray,
    work: np.ndarray,
) -> float:
    """:func:`field_eval` with its basis weights in ``work`` (9, 4), allocated by the caller
    (once for the many evaluations of a chart's ray march)."""
    outside, i0, j0, k0, o0, o1, o2 = _cell(coef, origin, h, p, work)
    value, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz = _sums(coef, i0, j0, k0, work, 2)
    inv_h = 1.0 / h
    inv_h2 = inv_h * inv_h
    grad[0] = gx * inv_h
    grad[1] = gy * inv_h
    grad[2] = gz * inv_h
    if outside:
        value += grad[0] * o0 + grad[1] * o1 + grad[2] * o2
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
def _field_value_grad_into(
    coef: np.ndarray,
    origin: np.ndarray,
    h: float,
    p: np.ndarray,
    grad: np.ndarray,
    work: np.ndarray,
) -> float:
    """Φ(p) and ∇Φ(p) into grad, by the same operations in the same order as
    :func:`_field_eval_into` (the same bits) without the six Hessian sums: the Newton steps of
    a chart's ray need only Φ and its slope along the ray."""
    outside, i0, j0, k0, o0, o1, o2 = _cell(coef, origin, h, p, work)
    value, gx, gy, gz = _sums(coef, i0, j0, k0, work, 1)[:4]
    inv_h = 1.0 / h
    grad[0] = gx * inv_h
    grad[1] = gy * inv_h
    grad[2] = gz * inv_h
    if outside:
        value += grad[0] * o0 + grad[1] * o1 + grad[2] * o2
    return value


@_jit
def _field_value_into(
    coef: np.ndarray, origin: np.ndarray, h: float, p: np.ndarray, work: np.ndarray
) -> float:
    """Φ(p) alone, by the same operations in the same order as :func:`_field_eval_into` (the
    same bits): the ray march of a chart needs only the sign and size of Φ, and skipping the
    nine derivative sums saves most of an evaluation."""
    outside, i0, j0, k0, o0, o1, o2 = _cell(coef, origin, h, p, work)
    # the linear continuation outside the box needs ∇Φ at its nearest point
    value, gx, gy, gz = _sums(coef, i0, j0, k0, work, 1 if outside else 0)[:4]
    if outside:
        inv_h = 1.0 / h
        value += gx * inv_h * o0 + gy * inv_h * o1 + gz * inv_h * o2
    return value


@_jit
def field_eval_many(
    coef: np.ndarray, origin: np.ndarray, h: float, points: np.ndarray, out: np.ndarray
) -> None:
    """Φ at each row of points (m, 3) [m] into out (m,) (for checks and figures)."""
    grad = np.empty(3)
    hess = np.empty((3, 3))
    work = np.empty((9, 4))
    for r in range(points.shape[0]):
        out[r] = _field_eval_into(coef, origin, h, points[r], grad, hess, work)


@_jit
def _ray_frame(mode: int, frame: np.ndarray, u: float, v: float, rows: np.ndarray) -> None:
    """The ray P(s) = B(u, v) + s·D(u, v) of a mesh chart and its derivatives in (u, v).

    rows (12, 3): B, B_u, B_v, B_uu, B_uv, B_vv, D, D_u, D_v, D_uu, D_uv, D_vv.
    mode 0 (projection), frame rows (o, e_u, e_v, n): B = o + u e_u + v e_v, D = n.
    mode 1 (cylindrical), frame rows (c, e1, e2, a), (u, v) = (θ, h): B = c + h a,
    D = cos θ e1 + sin θ e2 (the radial direction).
    """
    for r in range(12):
        for k in range(3):
            rows[r, k] = 0.0
    if mode == 0:
        for k in range(3):
            rows[0, k] = frame[0, k] + u * frame[1, k] + v * frame[2, k]
            rows[1, k] = frame[1, k]
            rows[2, k] = frame[2, k]
            rows[6, k] = frame[3, k]
    else:
        co = math.cos(u)
        si = math.sin(u)
        for k in range(3):
            rows[0, k] = frame[0, k] + v * frame[3, k]
            rows[2, k] = frame[3, k]
            rows[6, k] = co * frame[1, k] + si * frame[2, k]
            rows[7, k] = -si * frame[1, k] + co * frame[2, k]
            rows[9, k] = -rows[6, k]


@_jit
def ray_chart_eval(coef: np.ndarray, params: np.ndarray, u: float, v: float) -> float:
    """:func:`ray_chart_of` with its settings and its output packed in params (38,): origin
    (3) [m], h [m], mode, s_start, s_end [m], the level c [m], frame (4, 3) row by row, then
    out (6, 3) row by row, written here (four arguments: each array costs the call about
    0.1 µs in Numba's dispatch, a tenth of a chart evaluation)."""
    origin = params[0:3]
    frame = params[8:20].reshape((4, 3))
    out = params[20:38].reshape((6, 3))
    return ray_chart_of(
        coef, origin, params[3], int(params[4]), frame, u, v, params[5], params[6], params[7], out
    )


@_jit
def ray_chart_of(
    coef: np.ndarray,
    origin: np.ndarray,
    h: float,
    mode: int,
    frame: np.ndarray,
    u: float,
    v: float,
    s_start: float,
    s_end: float,
    level: float,
    out: np.ndarray,
) -> float:
    """S(u, v) of a mesh chart: the first point where the ray P(s) = B + s·D, marched from
    s_start towards s_end (on the free side, Φ > c, at s_start), meets the level set Φ = c
    (c = ``level`` [m]: 0 for the part, r for the centre of a ball tool of radius r, whose
    surface is Φ − r = 0); and its derivatives in (u, v) by implicit differentiation of
    Φ(B + s(u, v) D) = c (the same equations: c is a constant).

    With G = ∇Φ(S), H = ∇²Φ(S), a = G·D and x, y ∈ {u, v}:
    s_x = −G·(B_x + s D_x)/a, S_x = B_x + s_x D + s D_x, and, from ∂_y(G·S_x) = 0,
    s_xy = −(S_yᵀ H S_x + G·K_xy)/a with K_xy = B_xy + s_x D_y + s_y D_x + s D_xy,
    S_xy = K_xy + s_xy D.

    The march: steps of max(0.9 Φ, h/4) (Φ is a distance to within the fit, so a step of
    0.9 Φ cannot cross the surface; h/4 bounds the count where the ray grazes it), then a
    safeguarded Newton-bisection on the bracket to |Φ| ≤ 1e-14 m. Deterministic: the same
    (u, v) gives the same bits whatever was evaluated before.

    out (6, 3): S, S_u, S_v, S_uu, S_uv, S_vv [m per unit of u, v]. Returns s, or
    NaN when the ray misses the part (no crossing before s_end), starts on the part's side
    (Φ ≤ 0 at s_start) or grazes it (|G·D| < 1e-3 |G|: the chart is singular there).
    """
    rows = np.empty((12, 3))
    _ray_frame(mode, frame, u, v, rows)
    grad = np.empty(3)
    hess = np.empty((3, 3))
    work = np.empty((9, 4))
    p = np.empty(3)
    direction = 1.0 if s_end >= s_start else -1.0
    span = abs(s_end - s_start)
    s = s_start
    for k in range(3):
        p[k] = rows[0, k] + s * rows[6, k]
    phi = _field_value_into(coef, origin, h, p, work) - level
    if not phi > 0.0:
        return math.nan
    lo = s
    hi = math.nan
    travelled = 0.0
    for _ in range(100000):
        step = 0.9 * phi
        if step < 0.25 * h:
            step = 0.25 * h
        travelled += step
        if travelled > span:
            travelled = span
        s_new = s_start + direction * travelled
        for k in range(3):
            p[k] = rows[0, k] + s_new * rows[6, k]
        phi_new = _field_value_into(coef, origin, h, p, work) - level
        if phi_new <= 0.0:
            hi = s_new
            break
        lo = s_new
        phi = phi_new
        if travelled >= span:
            break
    if math.isnan(hi):
        return math.nan
    # the bracket [lo (Φ > 0), hi (Φ ≤ 0)] along the ray: Newton, bisection where it leaves it
    s = hi
    for _ in range(200):
        for k in range(3):
            p[k] = rows[0, k] + s * rows[6, k]
        phi = _field_value_grad_into(coef, origin, h, p, grad, work) - level
        if abs(phi) <= 1e-14:
            break
        if phi > 0.0:
            lo = s
        else:
            hi = s
        slope = grad[0] * rows[6, 0] + grad[1] * rows[6, 1] + grad[2] * rows[6, 2]
        trial = s - phi / slope if slope != 0.0 else math.nan
        inside = (trial - lo) * (trial - hi) < 0.0
        s = trial if inside else 0.5 * (lo + hi)
        if abs(hi - lo) <= 1e-15 * (1.0 + abs(s)):
            break
    for k in range(3):
        p[k] = rows[0, k] + s * rows[6, k]
    _field_eval_into(coef, origin, h, p, grad, hess, work)
    a = grad[0] * rows[6, 0] + grad[1] * rows[6, 1] + grad[2] * rows[6, 2]
    gnorm = math.sqrt(grad[0] ** 2 + grad[1] ** 2 + grad[2] ** 2)
    if not abs(a) >= 1e-3 * gnorm:
        return math.nan
    sx = np.empty(2)
    for x in range(2):  # B_x rows 1, 2; D_x rows 7, 8
        dot = 0.0
        for k in range(3):
            dot += grad[k] * (rows[1 + x, k] + s * rows[7 + x, k])
        sx[x] = -dot / a
    for k in range(3):
        out[0, k] = p[k]
        for x in range(2):
            out[1 + x, k] = rows[1 + x, k] + sx[x] * rows[6, k] + s * rows[7 + x, k]
    pairs = ((0, 0), (0, 1), (1, 1))  # S_uu, S_uv, S_vv: rows 3, 4, 5 of B and 9, 10, 11 of D
    known = np.empty(3)
    for m in range(3):
        x, y = pairs[m]
        curvature = 0.0
        for i in range(3):
            row = 0.0
            for j in range(3):
                row += hess[i, j] * out[1 + x, j]
            curvature += out[1 + y, i] * row
        dot = 0.0
        for k in range(3):
            known[k] = (
                rows[3 + m, k]
                + sx[x] * rows[7 + y, k]
                + sx[y] * rows[7 + x, k]
                + s * rows[9 + m, k]
            )
            dot += grad[k] * known[k]
        sxy = -(curvature + dot) / a
        for k in range(3):
            out[3 + m, k] = known[k] + sxy * rows[6, k]
    return s

"""Compiled Preston removal under a contact patch (reference: :mod:`hybrid_force.sim.removal`).

Compiled with :data:`hybrid_force._jit.jit`.
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force._jit import jit as _jit
from hybrid_force._jit import jit_inline as _jit_inline
from hybrid_force.geometry._kernels import surface_eval as _surface_eval

HERTZ = 0
FLAT = 1
#: |d| [m] of a tip beyond which its patch's curvature is evaluated at its foot p − d n.
FOOT_TOL = 1e-9


@_jit
def _sliding_speed(
    vt0: float,
    vt1: float,
    vt2: float,
    omega: float,
    normal: np.ndarray,
    r0: float,
    r1: float,
    r2: float,
) -> float:
    """|v_t + ω n × r| [m/s]: the slip of the pad's point at r (3,) [m] from the patch centre."""
    s0 = vt0 + omega * (normal[1] * r2 - normal[2] * r1)
    s1 = vt1 + omega * (normal[2] * r0 - normal[0] * r2)
    s2 = vt2 + omega * (normal[0] * r1 - normal[1] * r0)
    return math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)


@_jit_inline
def _slot(key: int, mask: int) -> np.int64:
    """The first slot of bucket id ``key`` ≥ 0 in a table of mask + 1 (a power of two) slots:
    the bits of splitmix64's finaliser (the ids of neighbouring buckets spread out)."""
    x = np.uint64(key)
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    x = x ^ (x >> np.uint64(31))
    return np.int64(x & np.uint64(mask))


@_jit
def bucket_table(keys: np.ndarray) -> np.ndarray:
    """The hash table (T, 2) int64 of the B bucket ids ``keys`` (B,) ≥ 0: slot [id, its
    position in keys] or [−1, −1] empty; T the least power of two ≥ 2B (open addressing,
    linear probing: about 1.5 slots read per lookup at that load)."""
    size = 2
    while size < 2 * keys.shape[0]:
        size *= 2
    table = np.full((size, 2), -1, dtype=np.int64)
    mask = size - 1
    for b in range(keys.shape[0]):
        h = _slot(keys[b], mask)
        while table[h, 0] >= 0:
            h = (h + 1) & mask
        table[h, 0] = keys[b]
        table[h, 1] = b
    return table


@_jit_inline
def _bucket(table: np.ndarray, key: int) -> int:
    """The position of bucket id ``key`` among the grid's buckets (``table`` of
    :func:`bucket_table`), or −1 (no cell there)."""
    mask = table.shape[0] - 1
    h = _slot(key, mask)
    while True:
        k = table[h, 0]
        if k == key:
            return table[h, 1]
        if k < 0:
            return -1
        h = (h + 1) & mask


@_jit_inline
def _tangential(velocity: np.ndarray, normal: np.ndarray) -> tuple[float, float, float]:
    """v − (v · n) n: the part of velocity (3,) [m/s] along the surface of unit normal (3,)."""
    vn = velocity[0] * normal[0] + velocity[1] * normal[1] + velocity[2] * normal[2]
    return velocity[0] - vn * normal[0], velocity[1] - vn * normal[1], velocity[2] - vn * normal[2]


@_jit_inline
def _offset(points: np.ndarray, i: int, centre: np.ndarray) -> tuple[float, float, float]:
    """points[i] − centre [m]: cell i's place from centre (3,)."""
    return points[i, 0] - centre[0], points[i, 1] - centre[1], points[i, 2] - centre[2]


@_jit_inline
def _bucket_box(
    box: np.ndarray,
    dims: np.ndarray,
    centre: np.ndarray,
    reach: float,
    lo: np.ndarray,
    hi: np.ndarray,
) -> int:
    """The buckets (box, dims as in :func:`deposit`) of the cube of half-side ``reach`` [m]
    about centre (3,) [m]: their first and last index per axis lo, hi (3,) int64, written.
    Returns how many there are (0: the cube misses the grid; lo, hi are then partly set)."""
    size = box[3]
    for k in range(3):
        lo[k] = max(0, math.floor((centre[k] - reach - box[k]) / size))
        hi[k] = min(dims[k] - 1, math.floor((centre[k] + reach - box[k]) / size))
        if lo[k] > hi[k]:
            return 0
    return (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1)


@_jit_inline
def _gap(x: float, start: float, size: float) -> float:
    """The squared distance [m²] from x to the interval [start, start + size] [m]."""
    d = start - x if x < start else x - start - size if x > start + size else 0.0
    return d * d


@_jit_inline
def _cells_in_box(
    order: np.ndarray,
    table: np.ndarray,
    starts: np.ndarray,
    box: np.ndarray,
    dims: np.ndarray,
    centre: np.ndarray,
    reach: float,
    out: np.ndarray,
) -> int:
    """The cells (bucketed as in :func:`deposit`) of the buckets that the ball of radius
    ``reach`` [m] about centre (3,) [m] meets, bucket by bucket (x slowest, z fastest), in
    out (M,) int64; returns their count (each cell is in one bucket: at most M)."""
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    count = 0
    if _bucket_box(box, dims, centre, reach, lo, hi) == 0:
        return count
    size, r2 = box[3], reach * reach
    for bx in range(lo[0], hi[0] + 1):
        gx = _gap(centre[0], box[0] + bx * size, size)
        for by in range(lo[1], hi[1] + 1):
            gy = gx + _gap(centre[1], box[1] + by * size, size)
            for bz in range(lo[2], hi[2] + 1):
                if gy + _gap(centre[2], box[2] + bz * size, size) > r2:
                    continue  # the bucket is wholly farther than reach
                b = _bucket(table, (bx * dims[1] + by) * dims[2] + bz)
                if b < 0:
                    continue
                for s in range(starts[b], starts[b + 1]):
                    out[count] = order[s]
                    count += 1
    return count


PLANE_ROWS = 1
CYLINDER_ROWS = 2


@_jit_inline
def _first_at_least(col: np.ndarray, first: int, last: int, value: int) -> int:
    """The first position in [first, last) of lattice row cells (col: their columns, strictly
    increasing integers) whose column is ≥ value, or last. The columns' spacing of at least 1
    bounds it to [last − 1 + value − col[last − 1], first + value − col[first]] (one position
    where the row has no gap), searched by bisection."""
    if first >= last:
        return last
    lo = max(first, last - 1 + value - col[last - 1])
    hi = min(last, first + max(value - col[first], 0))
    while lo < hi:
        mid = (lo + hi) // 2
        if col[mid] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo


@_jit_inline
def _row_cells(
    rows: np.ndarray, col: np.ndarray, k: int, lo: int, hi: int, out: np.ndarray, count: int
) -> int:
    """Append to out (from ``count``) the cells of lattice row k whose column is in
    [lo, hi] (rows (nu + 1,): where each row's cells start; col (M,): their columns, sorted
    within a row); returns the new count."""
    first = _first_at_least(col, rows[k], rows[k + 1], lo)
    stop = _first_at_least(col, first, rows[k + 1], hi + 1)
    for i in range(first, stop):
        out[count] = i
        count += 1
    return count


#: where a cylinder's lattice holds sin(θ_e / 2), cos(θ_e / 2) of its row edges θ_e = u0 + e du
#: (e = 0 … nu, interleaved; ``RemovalGrid.lattice``)
HALF_ANGLES = 20


@_jit_inline
def _cells_in_rows(
    lattice: np.ndarray,
    rows: np.ndarray,
    col: np.ndarray,
    centre: np.ndarray,
    reach: float,
    out: np.ndarray,
) -> int:
    """The cells of a chart lattice (``RemovalGrid.lattice``, ``rows``, ``col``: a plane's or
    a cylinder's (u, v) cells, sorted by row u then column v) that may lie within ``reach``
    [m] of centre (3,) [m], in out (M,) int64; returns their count. Per row, the range of
    columns where the distance from the centre to the row's line (the centre's height off
    the surface and the row's chord, less half a cell) leaves room: a superset of the cells
    within reach, each cell once, found by bisection (no search among buckets). On a
    cylinder the chord to the row's edge θ_e nearest the centre's angle θ_c is
    2 √(R ρ) |sin((θ_e − θ_c)/2)|, the sine by angle subtraction from the lattice's table of
    the edges' half angles (:data:`HALF_ANGLES`): no sine per row."""
    u0, du, v0, dv, nu, period = (
        lattice[1],
        lattice[2],
        lattice[3],
        lattice[4],
        lattice[5],
        lattice[6],
    )
    w0, w1, w2 = centre[0] - lattice[7], centre[1] - lattice[8], centre[2] - lattice[9]
    x = w0 * lattice[10] + w1 * lattice[11] + w2 * lattice[12]
    y = w0 * lattice[13] + w1 * lattice[14] + w2 * lattice[15]
    z = w0 * lattice[16] + w1 * lattice[17] + w2 * lattice[18]
    r2 = reach * reach
    cylinder = lattice[0] == CYLINDER_ROWS
    half_sin = half_cos = 0.0
    if cylinder:  # (θ, h): the chord 2 √(R ρ) |sin(Δθ/2)| to the row at R, off by ρ − R
        radius = lattice[19]
        rho = math.sqrt(x * x + y * y)
        uc, vc, off2, ring = math.atan2(y, x), z, (rho - radius) ** 2, 4.0 * radius * rho
        room = r2 - off2
        if room <= 0.0:
            return 0
        span = math.pi if room >= ring else 2.0 * math.asin(math.sqrt(room / ring))
        half_sin, half_cos = math.sin(0.5 * uc), math.cos(0.5 * uc)
    else:  # a plane's (u, v) [m] and the height off it
        uc, vc, off2, ring = x, y, z * z, 0.0
        room = r2 - off2
        if room <= 0.0:
            return 0
        span = math.sqrt(room)
    n = int(nu)
    count = 0
    # the rows within span (+ half a cell) of uc, once each: uc shifted by whole periods
    # when the lattice is periodic (then uc − span … uc + span is less than one period)
    whole = period > 0.0 and 2.0 * (span + du) >= period
    shifts = 1 if period > 0.0 and not whole else 0
    for shift in range(-shifts, shifts + 1):
        us = uc + shift * period
        k_lo, k_hi = 0, n - 1
        if not whole:
            k_lo = max(0, math.ceil((us - span - u0) / du - 1.0))
            k_hi = min(n - 1, math.floor((us + span - u0) / du))
        for k in range(k_lo, k_hi + 1):
            d = u0 + (k + 0.5) * du - us
            if whole:  # the periodic difference, in [−period/2, period/2)
                d = (d + 0.5 * period) % period - 0.5 * period
            if abs(d) <= 0.5 * du:  # the row holds the centre's u
                chord2 = 0.0
            elif cylinder:  # the edge nearest θ_c: the row's first (d > 0) or its last
                e = HALF_ANGLES + 2 * (k if d > 0.0 else k + 1)
                s = lattice[e] * half_cos - lattice[e + 1] * half_sin  # ± sin((θ_e − θ_c)/2)
                chord2 = ring * s * s
            else:
                chord2 = (abs(d) - 0.5 * du) ** 2  # to the nearest point of the row's cells
            if chord2 >= room:
                continue
            half = math.sqrt(room - chord2)
            lo = math.ceil((vc - half - v0) / dv - 1.0)
            hi = math.floor((vc + half - v0) / dv)
            count = _row_cells(rows, col, k, lo, hi, out, count)
    return count


@_jit_inline
def _candidates(
    order: np.ndarray,
    table: np.ndarray,
    starts: np.ndarray,
    box: np.ndarray,
    dims: np.ndarray,
    lattice: np.ndarray,
    rows: np.ndarray,
    col: np.ndarray,
    centre: np.ndarray,
    reach: float,
    out: np.ndarray,
) -> int:
    """The cells that may lie within ``reach`` [m] of centre (3,) [m] (the arguments as in
    :func:`deposit`), in out (M,) int64: row by row on a chart lattice
    (:func:`_cells_in_rows`), else by the buckets (:func:`_cells_in_box`); returns their
    count."""
    if lattice.shape[0] > 0:
        return _cells_in_rows(lattice, rows, col, centre, reach, out)
    return _cells_in_box(order, table, starts, box, dims, centre, reach, out)


@_jit_inline
def _between(alpha: float, beta: float, lo: float, hi: float) -> tuple[float, float]:
    """The interval of y with lo ≤ α y + β ≤ hi: (−inf, inf) or empty (inf, −inf) for α ≈ 0."""
    if abs(alpha) < 1e-12:
        if lo <= beta <= hi:
            return -math.inf, math.inf
        return math.inf, -math.inf
    y1, y2 = (lo - beta) / alpha, (hi - beta) / alpha
    return (y1, y2) if y1 <= y2 else (y2, y1)


@_jit_inline
def _capsule_chord(
    x: float, xe: float, ye: float, ex: float, ey: float, length: float, a: float
) -> tuple[float, float]:
    """The interval of y [m] where the line at x [m] crosses the capsule of radius a [m] about
    the segment (0, 0)–(xe, ye) (unit direction (ex, ey), ``length`` [m]): the hull of its
    crossings of the two end discs and of the band between them (the capsule is convex, so
    their union is one interval); empty (lo > hi) if it misses."""
    lo, hi = math.inf, -math.inf
    a2 = a * a
    r = a2 - x * x
    if r >= 0.0:
        h = math.sqrt(r)
        lo, hi = -h, h
    r = a2 - (x - xe) ** 2
    if r >= 0.0:
        h = math.sqrt(r)
        lo, hi = min(lo, ye - h), max(hi, ye + h)
    # the band: |−x ey + y ex| ≤ a and 0 ≤ x ex + y ey ≤ length
    b_lo, b_hi = _between(ex, -x * ey, -a, a)
    s_lo, s_hi = _between(ey, x * ex, 0.0, length)
    b_lo, b_hi = max(b_lo, s_lo), min(b_hi, s_hi)
    if b_lo <= b_hi:
        lo, hi = min(lo, b_lo), max(hi, b_hi)
    return lo, hi


@_jit_inline
def _half_disc_area(tau: float, c: float, c2: float) -> float:
    """∫₀^τ √(c² − t²) dt = (τ √(c² − τ²) + c² asin(τ/c)) / 2 for |τ| ≤ c."""
    q = min(max(tau / c, -1.0), 1.0)
    return 0.5 * (tau * math.sqrt(max(c2 - tau * tau, 0.0)) + c2 * math.asin(q))


@_jit_inline
def _line_integral(t: float, length: float, c2: float, shape: int) -> float:
    """∫₀^length w(s) ds of the patch's profile along a segment, at a cell whose distance
    from the segment's line leaves the half chord c = √c2 [m] and whose foot on the line is
    at t [m] from the segment's start: the profile w = √(c² − (s − t)²) (Hertz, p/p₀ times
    a) or 1 (flat) where |s − t| < c. A zero length: the profile at the cell (a point)."""
    if length == 0.0:
        r = c2 - t * t
        if shape == HERTZ:
            return math.sqrt(r) if r > 0.0 else 0.0
        return 1.0 if r > 0.0 else 0.0
    c = math.sqrt(c2)
    lo, hi = -t, length - t
    if shape == HERTZ:
        if lo <= -c and hi >= c:  # the whole chord: no arcsine
            return 0.5 * math.pi * c2
        lo, hi = max(lo, -c), min(hi, c)
        if lo >= hi:
            return 0.0
        return _half_disc_area(hi, c, c2) - _half_disc_area(lo, c, c2)
    return max(min(hi, c) - max(lo, -c), 0.0)


@_jit
def deposit_segment(
    lattice: np.ndarray,
    rows: np.ndarray,
    col: np.ndarray,
    areas: np.ndarray,
    depth: np.ndarray,
    us: float,
    vs: float,
    xe: float,
    ye: float,
    a: float,
    shape: int,
    amount: float,
    index: np.ndarray,
    weight: np.ndarray,
) -> int:
    """Add the depth of a patch of radius a [m] slid along a straight segment of a plane's or
    a cylinder's chart lattice (``RemovalGrid.lattice``, ``rows``, ``col``; areas (M,) [m²],
    depth (M,) [m], written): from the chart point (us, vs) (u [m] or θ [rad], v [m]) by
    (xe, ye) [m] in the unrolled surface (x = u or R θ, y = v), with ``amount`` [m³]
    = k_p Σ F |v_t| dt of the samples it stands for. Each cell gets the line integral of the
    profile across its centre (:func:`_line_integral`, exact for a straight segment at a
    constant force), scaled so that Σ h_i A_i = amount exactly. index, weight (M,): scratch.
    The cylinder's capsule must span less than half its circumference. Returns the cells
    that received depth (0: none inside, nothing added)."""
    u0, du, v0, dv, nu, period = (
        lattice[1],
        lattice[2],
        lattice[3],
        lattice[4],
        lattice[5],
        lattice[6],
    )
    metric = lattice[19] if lattice[0] == CYLINDER_ROWS else 1.0
    length = math.sqrt(xe * xe + ye * ye)
    if length > 1e-9 * a:
        ex, ey = xe / length, ye / length
    else:
        length, ex, ey = 0.0, 1.0, 0.0
    a2 = a * a
    x_lo, x_hi = min(0.0, xe) - a, max(0.0, xe) + a
    n = int(nu)
    shifts = 1 if period > 0.0 else 0
    count = 0
    total = 0.0
    for shift in range(-shifts, shifts + 1):
        base = us + shift * period
        k_lo = max(0, math.ceil((base + x_lo / metric - u0) / du - 0.5))
        k_hi = min(n - 1, math.floor((base + x_hi / metric - u0) / du - 0.5))
        for k in range(k_lo, k_hi + 1):
            x = metric * (u0 + (k + 0.5) * du - base)  # the row's centre line
            lo, hi = _capsule_chord(x, xe, ye, ex, ey, length, a)
            if lo > hi:
                continue
            first = _first_at_least(col, rows[k], rows[k + 1], math.ceil((vs + lo - v0) / dv - 0.5))
            stop = _first_at_least(
                col, first, rows[k + 1], math.floor((vs + hi - v0) / dv - 0.5) + 1
            )
            tx, lx = x * ex, -x * ey
            for i in range(first, stop):
                y = v0 + (col[i] + 0.5) * dv - vs
                lateral = lx + y * ex
                c2 = a2 - lateral * lateral
                w = _line_integral(tx + y * ey, length, c2, shape) if c2 > 0.0 else 0.0
                total += w * areas[i]
                index[count] = i
                weight[count] = w
                count += 1 if w > 0.0 else 0
    if not total > 0.0:
        return 0
    scale = amount / total
    for c in range(count):
        depth[index[c]] += scale * weight[c]
    return count


@_jit
def deposit(
    points: np.ndarray,
    areas: np.ndarray,
    order: np.ndarray,
    table: np.ndarray,
    starts: np.ndarray,
    box: np.ndarray,
    dims: np.ndarray,
    lattice: np.ndarray,
    rows: np.ndarray,
    col: np.ndarray,
    depth: np.ndarray,
    centre: np.ndarray,
    normal: np.ndarray,
    vt: np.ndarray,
    feed: float,
    omega: float,
    a: float,
    shape: int,
    force: float,
    factor: float,
    index: np.ndarray,
    weight: np.ndarray,
) -> int:
    """Add one step's Preston depth k_p · p · |v| · dt to the cells under the patch.

    points (M, 3) [m], areas (M,) [m²]: the cells; order (M,), table (T, 2), starts (B + 1,):
    the cells sorted by bucket, the hash table of the ids (bx · dims₁ + by) · dims₂ + bz of the
    B buckets holding cells (:func:`bucket_table`) and where each one's cells start in
    ``order``; box = [origin (3), size] of the buckets, dims (3,) their counts per axis;
    lattice, rows, col: a plane's or a cylinder's chart lattice (``RemovalGrid.lattice``; the
    cells are then found row by row, :func:`_cells_in_rows`), or lattice empty (by the buckets);
    depth (M,) [m], written. centre (3,) [m] and unit normal (3,) of the patch, vt (3,) [m/s]
    the tangential velocity of the contact point (it slides at |vt + ω n × r|), omega [rad/s]
    the spindle's rate about the normal, feed [m/s] the slip where omega = 0 (|vt|, or a group's
    force-weighted mean, :func:`flush`), a [m] the patch radius, shape HERTZ (p ∝ √(1 − ρ²/a²))
    or FLAT (uniform), force [N], factor = k_p · dt [m²/N · s]; index (M,) int64 and weight
    (M,): scratch (the cells inside the patch and their p · |v| up to the scale).

    The cells' pressures follow the profile and are scaled so that Σ p_i A_i = F exactly (the
    discrete form of ∫p dA = F); a patch with no cell centre inside it puts F on the nearest
    cell of the buckets it covers. Returns the number of cells inside the patch (0: the patch
    fell between cell centres, or off the grid when no bucket was covered).
    """
    if force <= 0.0 or a <= 0.0:
        return 0
    vt0, vt1, vt2 = vt[0], vt[1], vt[2]
    # the candidates in ``index``, compacted in place to the cells inside (inside ≤ c)
    candidates = _candidates(
        order, table, starts, box, dims, lattice, rows, col, centre, a, index
    )  # fmt: skip
    a2 = a * a
    total = 0.0
    inside = 0
    # one scan of the candidates: the cells inside, their profile w and w · slip; without a
    # branch (a candidate outside has w = 0, adds nothing and is overwritten by the next)
    for c in range(candidates):
        i = index[c]
        r0, r1, r2 = _offset(points, i, centre)
        d2 = r0 * r0 + r1 * r1 + r2 * r2
        within = d2 < a2
        if shape == HERTZ:
            w = math.sqrt(max(1.0 - d2 / a2, 0.0)) if within else 0.0
        else:
            w = 1.0 if within else 0.0
        total += w * areas[i]
        if omega != 0.0:
            w *= _sliding_speed(vt0, vt1, vt2, omega, normal, r0, r1, r2)
        else:
            w *= feed
        index[inside] = i
        weight[inside] = w
        inside += 1 if within else 0
    if total > 0.0:
        scale = factor * force / total
        for c in range(inside):
            depth[index[c]] += scale * weight[c]
        return inside
    # the patch falls between cell centres: all of F on the nearest candidate (found again:
    # the scan overwrote them)
    nearest = -1
    nearest_d2 = math.inf
    candidates = _candidates(
        order, table, starts, box, dims, lattice, rows, col, centre, a, index
    )  # fmt: skip
    for c in range(candidates):
        r0, r1, r2 = _offset(points, index[c], centre)
        d2 = r0 * r0 + r1 * r1 + r2 * r2
        if d2 < nearest_d2:
            nearest_d2 = d2
            nearest = index[c]
    if nearest >= 0:
        r0, r1, r2 = _offset(points, nearest, centre)
        speed = feed if omega == 0.0 else _sliding_speed(vt0, vt1, vt2, omega, normal, r0, r1, r2)
        depth[nearest] += factor * force / areas[nearest] * speed
    return 0


@_jit
def patch_on_part(
    grad: np.ndarray,
    hess: np.ndarray,
    shape: int,
    radius: float,
    modulus: float,
    force: float,
    normal: np.ndarray,
) -> float:
    """The patch radius a [m] under ``force`` [N] where the part has gradient ∇Φ (3,) and
    Hessian ∇²Φ (3, 3); writes the unit normal (3,) ∇Φ/‖∇Φ‖. −1 where the part is concave
    with 1/R + κ ≤ 0 (Hertz does not apply), 0 for no force.

    The principal curvatures κ₁, κ₂ (> 0 convex) are the eigenvalues of the level set's
    shape operator Tᵀ ∇²Φ T / ‖∇Φ‖ (T: an orthonormal tangent basis); a HERTZ pad of radius R
    and modulus E* gives a = (3 F R_eff / 4E*)^(1/3), R_eff = 1/√((1/R + κ₁)(1/R + κ₂))
    (:class:`hybrid_force.sim.removal.HertzPad`); a FLAT pad a = R.
    """
    g = math.sqrt(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2])
    for k in range(3):
        normal[k] = grad[k] / g
    if force <= 0.0:
        return 0.0
    if shape == FLAT:
        return radius
    n0, n1, n2 = normal[0], normal[1], normal[2]
    # t1 ⟂ n from the world axis least along n, t2 = n × t1
    if abs(n0) <= abs(n1) and abs(n0) <= abs(n2):
        e0, e1, e2 = 1.0, 0.0, 0.0
    elif abs(n1) <= abs(n2):
        e0, e1, e2 = 0.0, 1.0, 0.0
    else:
        e0, e1, e2 = 0.0, 0.0, 1.0
    a0, a1, a2 = n1 * e2 - n2 * e1, n2 * e0 - n0 * e2, n0 * e1 - n1 * e0
    s = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    a0, a1, a2 = a0 / s, a1 / s, a2 / s
    b0, b1, b2 = n1 * a2 - n2 * a1, n2 * a0 - n0 * a2, n0 * a1 - n1 * a0
    m00 = m01 = m11 = 0.0
    for r in range(3):
        ha = hess[r, 0] * a0 + hess[r, 1] * a1 + hess[r, 2] * a2
        hb = hess[r, 0] * b0 + hess[r, 1] * b1 + hess[r, 2] * b2
        ar = a0 if r == 0 else a1 if r == 1 else a2
        br = b0 if r == 0 else b1 if r == 1 else b2
        m00 += ar * ha
        m01 += ar * hb
        m11 += br * hb
    m00, m01, m11 = m00 / g, m01 / g, m11 / g
    mean = 0.5 * (m00 + m11)
    half = math.sqrt(0.25 * (m00 - m11) ** 2 + m01 * m01)
    inv1 = 1.0 / radius + mean + half
    inv2 = 1.0 / radius + mean - half
    if not (inv1 > 0.0 and inv2 > 0.0):
        return -1.0
    r_eff = 1.0 / math.sqrt(inv1 * inv2)
    return (3.0 * force * r_eff / (4.0 * modulus)) ** (1.0 / 3.0)


GROUP = 36
"""The length of a group's state (:func:`observe`, :func:`flush`)."""
# the group's state: [0] samples, [1] Σ w, [2:5] Σ w c, [5:8] Σ w n, [8] Σ w a, [9] Σ F,
# [10] Σ F |v_t|, [11:14] Σ F v_t, [14] Σ F ω; its first sample's [15:18] c, [18:21] n, [21] a,
# [22:25] v_t, [25] ω (w = F |v_t| without a spindle, F with one); a segment (:func:`observe`
# with a deviation > 0): [26] 1, the start's chart point [27] u, [28] v, the direction
# [29:31] (ex, ey) in the unrolled surface, [31] the first sample's F, [32] the last sample's
# place s along (ex, ey) [m], [33:35] the segment's end (x, y) [m] from the start (the last
# sample's foot moved on by v_t dt), [35] the end's place s [m]
SEGMENT_FORCE = 0.005
"""A segment's samples' forces stay within SEGMENT_FORCE of its first sample's (relative): the
deposit spreads their force evenly along it (docs/removal.md, "Cost")."""
SEGMENT_LENGTH = 16.0
"""A segment is at most SEGMENT_LENGTH patch radii long (longer ones cost no less a sample)."""


@_jit_inline
def _chart_point(
    lattice: np.ndarray, centre: np.ndarray, vt: np.ndarray
) -> tuple[float, float, float, float]:
    """The chart point (u, v) of a foot centre (3,) [m] on a plane's or a cylinder's lattice
    (``RemovalGrid.lattice``: u [m] or θ [rad] in (−π, π], v [m]) and the velocity vt (3,)
    [m/s] in the unrolled surface (along x = u or R θ, along y = v)."""
    w0, w1, w2 = centre[0] - lattice[7], centre[1] - lattice[8], centre[2] - lattice[9]
    x = w0 * lattice[10] + w1 * lattice[11] + w2 * lattice[12]
    y = w0 * lattice[13] + w1 * lattice[14] + w2 * lattice[15]
    z = w0 * lattice[16] + w1 * lattice[17] + w2 * lattice[18]
    ax = vt[0] * lattice[10] + vt[1] * lattice[11] + vt[2] * lattice[12]
    ay = vt[0] * lattice[13] + vt[1] * lattice[14] + vt[2] * lattice[15]
    if lattice[0] == CYLINDER_ROWS:  # e_θ = −sin θ e1 + cos θ e2, along the axis
        theta = math.atan2(y, x)
        az = vt[0] * lattice[16] + vt[1] * lattice[17] + vt[2] * lattice[18]
        return theta, z, -math.sin(theta) * ax + math.cos(theta) * ay, az
    return x, y, ax, ay


@_jit_inline
def _segment_offset(
    group: np.ndarray, lattice: np.ndarray, u: float, v: float
) -> tuple[float, float]:
    """The chart point (u, v) from the open segment's start, in the unrolled surface [m] (a
    cylinder's angle taken within half a turn of the start's)."""
    du = u - group[27]
    if lattice[0] == CYLINDER_ROWS:
        du -= 2.0 * math.pi * round(du / (2.0 * math.pi))
        return lattice[19] * du, v - group[28]
    return du, v - group[28]


@_jit_inline
def _fits_segment(group: np.ndarray, x: float, y: float, force: float, deviation: float) -> bool:
    """Whether a sample whose foot is (x, y) [m] from the open segment's start (unrolled) and
    whose force is ``force`` [N] may join it: within ``deviation`` [m] of the line through the
    start along its first sample's direction, not behind the last sample by more than
    ``deviation`` nor ahead of where the last one was heading (v_t dt) by more than
    ``deviation`` and a quarter of its step (a path lost and found again farther on starts a
    new segment), within SEGMENT_LENGTH radii of the start, and its force within
    SEGMENT_FORCE of the first sample's."""
    if group[0] == 0.0:
        return True
    ex, ey = group[29], group[30]
    s = x * ex + y * ey
    lateral = -x * ey + y * ex
    last, end = group[32], group[35]
    return (
        abs(lateral) <= deviation
        and s >= last - deviation
        and s <= end + deviation + 0.25 * abs(end - last)
        and s <= SEGMENT_LENGTH * group[21]
        and abs(force - group[31]) <= SEGMENT_FORCE * group[31]
    )


@_jit_inline
def _fits(
    group: np.ndarray,
    centre: np.ndarray,
    normal: np.ndarray,
    vt: np.ndarray,
    omega: float,
    a: float,
    merge: float,
    spinning: bool,
) -> bool:
    """Whether a sample's patch (centre (3,) [m], unit normal (3,), tangential velocity vt
    (3,) [m/s], spindle rate omega [rad/s], radius a [m]) may join the open group: its centre
    and radius within ``merge`` [m] of the group's first sample's, its rim moved by the tilt
    a₀ |n − n₀| ≤ merge, and with a spindle (``spinning``) its slip changed by
    |Δv_t| + a₀ |Δω| ≤ (merge / a₀) (|v_t,0| + a₀ |ω₀|) (the relative change of the patch's
    place)."""
    if group[0] == 0.0:
        return True
    a0 = group[21]
    dc = 0.0
    dn = 0.0
    for k in range(3):
        dc += (centre[k] - group[15 + k]) ** 2
        dn += (normal[k] - group[18 + k]) ** 2
    m2 = merge * merge
    if dc > m2 or a0 * a0 * dn > m2 or abs(a - a0) > merge:
        return False
    if not spinning:
        return True  # the slip is one number, summed exactly (:func:`flush`)
    dv = 0.0
    v0 = 0.0
    for k in range(3):
        dv += (vt[k] - group[22 + k]) ** 2
        v0 += group[22 + k] ** 2
    change = math.sqrt(dv) + a0 * abs(omega - group[25])
    return change <= merge / a0 * (math.sqrt(v0) + a0 * abs(group[25]))


@_jit
def flush(
    group: np.ndarray,
    shape: int,
    factor: float,
    points: np.ndarray,
    areas: np.ndarray,
    order: np.ndarray,
    table: np.ndarray,
    starts: np.ndarray,
    box: np.ndarray,
    dims: np.ndarray,
    lattice: np.ndarray,
    rows: np.ndarray,
    col: np.ndarray,
    depth: np.ndarray,
    work: np.ndarray,
    index: np.ndarray,
    weight: np.ndarray,
) -> None:
    """Deposit the open group of samples (``group`` (GROUP,), emptied) as one patch
    (:func:`deposit`): at the w-weighted mean centre, normal and radius, with the summed
    force ΣF, the feed ΣF|v_t| / ΣF (the volume k_p Σ F |v_t| dt, exactly) and, with a
    spindle, the force-weighted mean v_t and ω; a segment (:func:`observe`) as the patch of
    the w-weighted mean radius slid along it (:func:`deposit_segment`), the same volume.
    work (9,): scratch."""
    if group[0] == 0.0:
        return
    w, total = group[1], group[9]
    group[0] = 0.0
    if not w > 0.0:
        return  # no slip (a tool at rest, no spindle): nothing removed
    if group[26] == 1.0:  # a segment: its line integral (no spindle: w = F |v_t|)
        inside = deposit_segment(
            lattice, rows, col, areas, depth, group[27], group[28], group[33], group[34],
            group[8] / w, shape, factor * group[10], index, weight,
        )  # fmt: skip
        if inside > 0:
            return
        # no cell centre within the patch anywhere along it: the point deposit at its mean
        # (all on the nearest cell)
    centre, normal, vt = work[0:3], work[3:6], work[6:9]
    g = math.sqrt(group[5] ** 2 + group[6] ** 2 + group[7] ** 2)
    for k in range(3):
        centre[k] = group[2 + k] / w
        normal[k] = group[5 + k] / g
        vt[k] = group[11 + k] / total
    deposit(
        points, areas, order, table, starts, box, dims, lattice, rows, col, depth, centre, normal,
        vt, group[10] / total, group[14] / total, group[8] / w, shape, total, factor, index, weight,
    )  # fmt: skip


@_jit_inline
def _segment_sample(
    group: np.ndarray,
    lattice: np.ndarray,
    centre: np.ndarray,
    normal: np.ndarray,
    vt: np.ndarray,
    feed: float,
    a: float,
    force: float,
    deviation: float,
    dt: float,
    shape: int,
    factor: float,
    points: np.ndarray,
    areas: np.ndarray,
    order: np.ndarray,
    table: np.ndarray,
    starts: np.ndarray,
    box: np.ndarray,
    dims: np.ndarray,
    rows: np.ndarray,
    col: np.ndarray,
    depth: np.ndarray,
    work: np.ndarray,
    index: np.ndarray,
    weight: np.ndarray,
) -> None:
    """A sample of a tool that does not spin (:func:`observe`'s arguments) joined to the open
    segment (``group``), which is first deposited (:func:`flush`) if the sample does not fit
    it (:func:`_fits_segment`)."""
    u, v, vx, vy = _chart_point(lattice, centre, vt)
    x, y = _segment_offset(group, lattice, u, v) if group[0] > 0.0 else (0.0, 0.0)
    if not _fits_segment(group, x, y, force, deviation):
        flush(
            group, shape, factor, points, areas, order, table, starts, box, dims, lattice, rows,
            col, depth, work, index, weight,
        )  # fmt: skip
    if group[0] == 0.0:
        group[:] = 0.0
        group[15:18] = centre
        group[18:21] = normal
        group[21] = a
        group[22:25] = vt
        group[26] = 1.0
        group[27], group[28] = u, v
        speed = math.sqrt(vx * vx + vy * vy)
        group[29], group[30] = (vx / speed, vy / speed) if speed > 0.0 else (1.0, 0.0)
        group[31] = force
        x = y = 0.0
    ex, ey = group[29], group[30]
    group[32] = x * ex + y * ey
    group[33], group[34] = x + vx * dt, y + vy * dt
    group[35] = group[33] * ex + group[34] * ey
    w = force * feed
    group[0] += 1.0
    group[1] += w
    for k in range(3):
        group[2 + k] += w * centre[k]
        group[5 + k] += w * normal[k]
        group[11 + k] += force * vt[k]
    group[8] += w * a
    group[9] += force
    group[10] += w


@_jit_inline
def _observe(
    desc: np.ndarray,
    p: np.ndarray,
    grad: np.ndarray,
    hess: np.ndarray,
    distance: float,
    velocity: np.ndarray,
    force: float,
    knobs: tuple[int, float, float, float, float, float, float, float, float],
    points: np.ndarray,
    areas: np.ndarray,
    order: np.ndarray,
    table: np.ndarray,
    starts: np.ndarray,
    box: np.ndarray,
    dims: np.ndarray,
    lattice: np.ndarray,
    rows: np.ndarray,
    col: np.ndarray,
    depth: np.ndarray,
    group: np.ndarray,
    work: np.ndarray,
    index: np.ndarray,
    weight: np.ndarray,
) -> float:
    """:func:`observe`, inlined into its callers (no call, no reference counting of its
    arrays: a third of a sample's cost), its scalars in ``knobs`` (shape, radius, modulus,
    omega, v_ref, factor, merge, deviation, dt)."""
    shape, radius, modulus, omega, v_ref, factor, merge, deviation, dt = knobs
    if force <= 0.0:
        return 0.0
    if desc.shape[0] > 0:
        _, distance = _surface_eval(desc, p, grad, hess)
        if abs(distance) > FOOT_TOL:
            # the part's curvature at the foot, not at p: off the part (a ball tool's centre
            # r away, a compliant contact's penetration) the level set through p has the
            # principal curvatures κ / (1 + d κ)
            g = math.sqrt(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2])
            foot = work[12:15]
            for k in range(3):
                foot[k] = p[k] - distance * grad[k] / g
            _surface_eval(desc, foot, grad, hess)
    normal = work[9:12]
    a = patch_on_part(grad, hess, shape, radius, modulus, force, normal)
    if a <= 0.0:
        return a
    centre, vt = work[12:15], work[15:18]
    for k in range(3):
        centre[k] = p[k] - distance * normal[k]
    vt[0], vt[1], vt[2] = _tangential(velocity, normal)
    feed = math.sqrt(vt[0] * vt[0] + vt[1] * vt[1] + vt[2] * vt[2])
    spinning = omega != 0.0
    if v_ref > 0.0:  # the spindle slows with the feed
        omega = omega * feed / v_ref
    if deviation > 0.0 and not spinning and lattice.shape[0] > 0:
        _segment_sample(
            group, lattice, centre, normal, vt, feed, a, force, deviation, dt, shape, factor,
            points, areas, order, table, starts, box, dims, rows, col, depth, work, index, weight,
        )  # fmt: skip
        return a
    if not _fits(group, centre, normal, vt, omega, a, merge, spinning):
        flush(
            group, shape, factor, points, areas, order, table, starts, box, dims, lattice, rows,
            col, depth, work, index, weight,
        )  # fmt: skip
    if group[0] == 0.0:
        group[:] = 0.0
        group[15:18] = centre
        group[18:21] = normal
        group[21] = a
        group[22:25] = vt
        group[25] = omega
    w = force if spinning else force * feed
    group[0] += 1.0
    group[1] += w
    for k in range(3):
        group[2 + k] += w * centre[k]
        group[5 + k] += w * normal[k]
        group[11 + k] += force * vt[k]
    group[8] += w * a
    group[9] += force
    group[10] += force * feed
    group[14] += force * omega
    return a


@_jit
def observe(
    desc: np.ndarray,
    p: np.ndarray,
    grad: np.ndarray,
    hess: np.ndarray,
    distance: float,
    velocity: np.ndarray,
    force: float,
    shape: int,
    radius: float,
    modulus: float,
    omega: float,
    v_ref: float,
    factor: float,
    merge: float,
    deviation: float,
    dt: float,
    points: np.ndarray,
    areas: np.ndarray,
    order: np.ndarray,
    table: np.ndarray,
    starts: np.ndarray,
    box: np.ndarray,
    dims: np.ndarray,
    lattice: np.ndarray,
    rows: np.ndarray,
    col: np.ndarray,
    depth: np.ndarray,
    group: np.ndarray,
    work: np.ndarray,
    index: np.ndarray,
    weight: np.ndarray,
) -> float:
    """One run step's removal: the patch at the tip p (3,) [m] with velocity (3,) [m/s]
    pressed with ``force`` [N], joined to the open group of samples (``group`` (GROUP,)),
    which is first deposited (:func:`flush`) when the patch has moved too far from it.

    desc: a built-in surface's descriptor (``Surface._descriptor``, whose ∇Φ, ∇²Φ and
    distance are evaluated here), or empty: grad (3,), hess (3, 3) and distance [m] are the
    caller's, at the foot. The patch is centred at the tip's foot p − d n on the surface, and
    its curvature (∇²Φ) is the part's there (for |d| > FOOT_TOL). v_ref > 0
    [m/s]: the spindle's schedule ω |v_t| / v_ref (the removal per unit length of a feed
    |v_t| is then that of the feed v_ref at ω); 0: ω throughout. merge [m]: the group's
    reach (:func:`_fits`; docs/removal.md, "Cost"). deviation [m] > 0 (a tool that does not
    spin, on a plane's or a cylinder's lattice): the samples are grouped into straight
    segments instead, within ``deviation`` of their line (:func:`_fits_segment`), each
    deposited as the patch slid along it (:func:`deposit_segment`); dt [s] the sample's
    span (where the last one heads). work (18,), index (M,) int64 and weight (M,): scratch.
    Returns the patch radius a [m] (0: no force; −1: Hertz does not apply, the part
    conforms; nothing is deposited then).
    """
    knobs = (shape, radius, modulus, omega, v_ref, factor, merge, deviation, dt)
    return _observe(
        desc, p, grad, hess, distance, velocity, force, knobs, points, areas, order, table,
        starts, box, dims, lattice, rows, col, depth, group, work, index, weight,
    )  # fmt: skip


@_jit
def mark_near(
    points: np.ndarray,
    order: np.ndarray,
    table: np.ndarray,
    starts: np.ndarray,
    box: np.ndarray,
    dims: np.ndarray,
    samples: np.ndarray,
    reach: float,
    out: np.ndarray,
) -> None:
    """out[i] = True for each cell i (points (M, 3) [m], bucketed as in :func:`deposit`)
    within ``reach`` [m] of one of the samples (S, 3) [m]; out (M,) bool, written."""
    r2 = reach * reach
    cells = np.empty(points.shape[0], dtype=np.int64)
    for s in range(samples.shape[0]):
        sample = samples[s]
        for c in range(_cells_in_box(order, table, starts, box, dims, sample, reach, cells)):
            d0, d1, d2 = _offset(points, cells[c], sample)
            if d0 * d0 + d1 * d1 + d2 * d2 < r2:
                out[cells[c]] = True


@_jit
def observe_batch(
    desc: np.ndarray,
    tips: np.ndarray,
    forces: np.ndarray,
    column: int,
    velocities: np.ndarray,
    first: int,
    count: int,
    shape: int,
    radius: float,
    modulus: float,
    omega: float,
    v_ref: float,
    factor: float,
    merge: float,
    deviation: float,
    dt: float,
    points: np.ndarray,
    areas: np.ndarray,
    order: np.ndarray,
    table: np.ndarray,
    starts: np.ndarray,
    box: np.ndarray,
    dims: np.ndarray,
    lattice: np.ndarray,
    rows: np.ndarray,
    col: np.ndarray,
    depth: np.ndarray,
    group: np.ndarray,
    work: np.ndarray,
    index: np.ndarray,
    weight: np.ndarray,
    tally: np.ndarray,
) -> None:
    """:func:`observe` for samples first … first + count − 1 of a run on a built-in surface
    (``desc``): tips (N, 3) [m] and forces (N, k) [N] the run's recorded columns (the force of
    surface ``column``), velocities (count, 3) [m/s] their J v; the open group carries over
    to the next call (:func:`flush` deposits it at the end). tally (2,): the samples that
    deposited and those where the part conformed, incremented."""
    grad = np.zeros(3)
    hess = np.zeros((3, 3))
    # the scalars as one tuple: a call of more than 30 arguments is compiled as f(*args),
    # which Numba cannot inline
    knobs = (shape, radius, modulus, omega, v_ref, factor, merge, deviation, dt)
    for s in range(min(count, velocities.shape[0])):  # (never more samples than J v rows)
        i = first + s
        force = forces[i, column]
        if not force > 0.0:
            continue
        a = _observe(
            desc, tips[i], grad, hess, 0.0, velocities[s], force, knobs, points, areas, order,
            table, starts, box, dims, lattice, rows, col, depth, group, work, index, weight,
        )  # fmt: skip
        if a < 0.0:
            tally[1] += 1
        else:
            tally[0] += 1

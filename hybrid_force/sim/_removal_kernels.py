"""Compiled Preston removal under a contact patch (reference: :mod:`hybrid_force.sim.removal`).

Compiled with :data:`hybrid_force._jit.jit`.
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force._jit import jit as _jit

HERTZ = 0
FLAT = 1


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


@_jit
def deposit(
    points: np.ndarray,
    areas: np.ndarray,
    order: np.ndarray,
    starts: np.ndarray,
    box: np.ndarray,
    dims: np.ndarray,
    depth: np.ndarray,
    centre: np.ndarray,
    normal: np.ndarray,
    velocity: np.ndarray,
    omega: float,
    a: float,
    shape: int,
    force: float,
    factor: float,
) -> int:
    """Add one step's Preston depth k_p · p · |v| · dt to the cells under the patch.

    points (M, 3) [m], areas (M,) [m²]: the cells; order (M,), starts (B + 1,): the cells
    sorted by bucket (CSR), box = [origin (3), size] of the buckets, dims (3,) their counts;
    depth (M,) [m], written. centre (3,) [m] and unit normal (3,) of the patch, velocity (3,)
    [m/s] of the contact point (its tangential part slides), omega [rad/s] the spindle's rate
    about the normal, a [m] the patch radius, shape HERTZ (p ∝ √(1 − ρ²/a²)) or FLAT
    (uniform), force [N], factor = k_p · dt [m²/N · s].

    The cells' pressures follow the profile and are scaled so that Σ p_i A_i = F exactly (the
    discrete form of ∫p dA = F); a patch with no cell centre inside it puts F on the nearest
    cell of the buckets it covers. Returns the number of cells inside the patch (0: the patch
    fell between cell centres, or off the grid when no bucket was covered).
    """
    if force <= 0.0 or a <= 0.0:
        return 0
    vn = velocity[0] * normal[0] + velocity[1] * normal[1] + velocity[2] * normal[2]
    vt0 = velocity[0] - vn * normal[0]
    vt1 = velocity[1] - vn * normal[1]
    vt2 = velocity[2] - vn * normal[2]
    size = box[3]
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    for k in range(3):
        lo[k] = max(0, math.floor((centre[k] - a - box[k]) / size))
        hi[k] = min(dims[k] - 1, math.floor((centre[k] + a - box[k]) / size))
        if lo[k] > hi[k]:
            return 0
    a2 = a * a
    total = 0.0
    inside = 0
    nearest = -1
    nearest_d2 = math.inf
    for pass_ in range(2):
        scale = 0.0 if pass_ == 0 else force / total if total > 0.0 else 0.0
        if pass_ == 1 and total <= 0.0:
            break
        for bx in range(lo[0], hi[0] + 1):
            for by in range(lo[1], hi[1] + 1):
                for bz in range(lo[2], hi[2] + 1):
                    bucket = (bx * dims[1] + by) * dims[2] + bz
                    for s in range(starts[bucket], starts[bucket + 1]):
                        i = order[s]
                        r0 = points[i, 0] - centre[0]
                        r1 = points[i, 1] - centre[1]
                        r2 = points[i, 2] - centre[2]
                        d2 = r0 * r0 + r1 * r1 + r2 * r2
                        if pass_ == 0 and d2 < nearest_d2:
                            nearest_d2 = d2
                            nearest = i
                        if d2 >= a2:
                            continue
                        w = math.sqrt(1.0 - d2 / a2) if shape == HERTZ else 1.0
                        if pass_ == 0:
                            total += w * areas[i]
                            inside += 1
                            continue
                        speed = _sliding_speed(vt0, vt1, vt2, omega, normal, r0, r1, r2)
                        depth[i] += factor * scale * w * speed
    if total > 0.0:
        return inside
    if nearest >= 0:
        # the patch falls between cell centres: all of F on the nearest cell
        r0 = points[nearest, 0] - centre[0]
        r1 = points[nearest, 1] - centre[1]
        r2 = points[nearest, 2] - centre[2]
        speed = _sliding_speed(vt0, vt1, vt2, omega, normal, r0, r1, r2)
        depth[nearest] += factor * force / areas[nearest] * speed
    return 0

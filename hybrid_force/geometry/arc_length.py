"""Arc length on a surface along a curve in its coordinates, and the curve's parameter as a C²
function of arc length, so that a path on a surface can move at an exact speed.

For a curve γ(σ) in the chart coordinates (u, v) and the chart S (:mod:`.charts`), the point
p(σ) = S(γ(σ)) moves at q(σ) = ‖p'(σ)‖ = ‖S_u u' + S_v v'‖ per unit of σ, and the arc length is
ℓ(σ) = ∫ q dσ. :func:`arc_length_map` tabulates its inverse σ(ℓ): on each piece of the curve at
``SUBDIVISIONS`` + 1 equally spaced σ, with ℓ from Gauss–Legendre quadrature and the exact
derivatives dσ/dℓ = 1 / q and d²σ/dℓ² = −q' / q³ (q' = p'·p'' / q), joined by quintic Hermite
pieces (:func:`.piecewise.blend_piece`). The map is C² (its pieces agree in value, first and
second derivative where they meet), so p(σ(ℓ)) is C² in ℓ with ‖dp/dℓ‖ = q σ'(ℓ) = 1 up to
the interpolation error of σ', O(h⁵) in the node spacing h: below 1e-8 relative on the paths
of benchmarks/study_surface_paths.py with 64 nodes per piece.
"""

from __future__ import annotations

import numpy as np

from hybrid_force.errors import PathError
from hybrid_force.geometry.charts import SurfaceChart
from hybrid_force.geometry.piecewise import PiecewiseCurve, blend_piece

__all__ = [
    "SUBDIVISIONS",
    "arc_length_map",
    "curve_derivatives",
    "piece_lengths",
    "surface_speeds",
]

SUBDIVISIONS = 64
"""Sub-intervals of each piece of a curve at which σ(ℓ) is tabulated (and ℓ integrated)."""

_GAUSS_NODES, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(16)
_STOP_RTOL = 1e-9
"""A curve whose ‖p'‖ falls below this times its largest nearly stops: refused."""


def curve_derivatives(
    chart: SurfaceChart, curve: PiecewiseCurve, k: int, x: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """p' = dp/dσ and p'' = d²p/dσ² on piece k at local parameters x (N,): two (N, 3)."""
    g, g1, g2 = curve.sample_piece(k, x)
    d = chart.derivatives(g[:, 0], g[:, 1])
    du, dv = g1[:, :1], g1[:, 1:]
    first = d[1] * du + d[2] * dv
    second = (
        d[3] * du**2 + 2.0 * d[4] * du * dv + d[5] * dv**2 + d[1] * g2[:, :1] + d[2] * g2[:, 1:]
    )
    return first, second


def surface_speeds(chart: SurfaceChart, curve: PiecewiseCurve, k: int, x: np.ndarray) -> np.ndarray:
    """q = ‖dp/dσ‖ on piece k at local parameters x (N,): (N,)."""
    return np.linalg.norm(curve_derivatives(chart, curve, k, x)[0], axis=1)


def _cumulative(chart: SurfaceChart, curve: PiecewiseCurve, k: int, cuts: np.ndarray) -> np.ndarray:
    """ℓ from the start of piece k to each local parameter of ``cuts`` (increasing, from 0)."""
    widths = np.diff(cuts)
    x = cuts[:-1, None] + 0.5 * widths[:, None] * (_GAUSS_NODES + 1.0)
    q = surface_speeds(chart, curve, k, x.ravel()).reshape(x.shape)
    return np.concatenate(([0.0], np.cumsum(0.5 * widths * (q @ _GAUSS_WEIGHTS))))


def piece_lengths(chart: SurfaceChart, curve: PiecewiseCurve) -> np.ndarray:
    """Arc length on the surface [m] of each piece of ``curve``: (m,), by Gauss–Legendre
    quadrature (16 nodes on each of ``SUBDIVISIONS`` equal sub-intervals of a piece)."""
    cuts = np.linspace(0.0, 1.0, SUBDIVISIONS + 1)
    lengths = np.diff(curve.breaks)
    return np.array([_cumulative(chart, curve, k, h * cuts)[-1] for k, h in enumerate(lengths)])


def arc_length_map(chart: SurfaceChart, curve: PiecewiseCurve) -> PiecewiseCurve:
    """σ(ℓ): the curve's parameter as a C² function of arc length ℓ [m] from its start, one
    column, breaks at the tabulated ℓ (see the module doc).

    Raises:
        PathError: the curve nearly stops somewhere (‖p'‖ → 0), so σ(ℓ) has no
            bounded derivative there.
    """
    lengths, pieces = [], []
    start_l = 0.0
    cuts = np.linspace(0.0, 1.0, SUBDIVISIONS + 1)
    fastest = 0.0
    for k, h in enumerate(np.diff(curve.breaks)):
        x = h * cuts
        ell = start_l + _cumulative(chart, curve, k, x)
        first, second = curve_derivatives(chart, curve, k, x)
        q = np.linalg.norm(first, axis=1)
        fastest = max(fastest, float(q.max()))
        if not float(q.min()) > _STOP_RTOL * fastest:
            raise PathError(
                f"the path nearly stops on the surface near parameter {curve.breaks[k]:.6g} "
                f"(speed {float(q.min()):.3g} per unit of the curve's parameter): move its points"
            )
        sigma = curve.breaks[k] + x
        slope = 1.0 / q  # dσ/dℓ, and d²σ/dℓ² = −q'/q³ with q' = p'·p''/q
        bend = -np.einsum("ij,ij->i", first, second) / q**4
        widths = np.diff(ell)
        lengths.extend(widths.tolist())
        nodes = np.stack((sigma, slope, bend), axis=1)[:, :, None]  # (n + 1, 3, 1)
        p0, d0, a0 = nodes[:-1, 0], nodes[:-1, 1], nodes[:-1, 2]
        p1, d1, a1 = nodes[1:, 0], nodes[1:, 1], nodes[1:, 2]
        pieces.append(blend_piece(p0, d0, p1, d1, widths, a0, a1))
        start_l = float(ell[-1])
    return PiecewiseCurve.join(lengths, np.concatenate(pieces))

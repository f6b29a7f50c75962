"""The removal map of a run with ``[removal]`` (``removal.png``): the depth removed [µm] on the
unrolled surface, the tip's path in contact drawn over it, the target region outlined.

Drawn by :func:`~hybrid_force.viz.run_figures.plot_result` when the result has the removal
arrays (``Result.removal_points``, ``removal_depth``, ``removal_target``; docs/removal.md).
The surface is unrolled by its chart (:func:`~hybrid_force.geometry.charts.chart_for`, with
the path's ``u_axis`` on a plane), each coordinate scaled by the chart's metric at the middle
of the grid (a plane's u and v as they are, a cylinder's angle times its radius): lengths on
the surface for a plane and a cylinder (developable: exact), the equirectangular map of a
sphere or an ellipsoid about the grid's middle. A mesh part's cells
are projected on their best-fit plane (principal axes). The cells are averaged into at most
400 × 400 bins.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from hybrid_force.geometry.charts import chart_for
from hybrid_force.geometry.surfaces import surface_from_dict
from hybrid_force.viz._style import _new_figure, _note

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["REMOVAL_FIGURE", "removal_figure", "unrolled"]

REMOVAL_FIGURE = "removal"
_MAX_BINS = 400


def _chart(meta: dict[str, Any]) -> Any:
    """The chart the removal grid was laid on, rebuilt from the run's meta (None for a mesh
    or a surface without one)."""
    removal = meta.get("removal") or {}
    surfaces = meta.get("surfaces") or []
    j = int(removal.get("surface", 0))
    if removal.get("grid") != "chart" or j >= len(surfaces):
        return None
    try:
        surface = surface_from_dict(surfaces[j])
        path = meta.get("path") or {}
        return chart_for(surface, path.get("u_axis") if isinstance(path, dict) else None)
    except Exception:  # a surface without a chart, or an older meta: the plane projection
        return None


def unrolled(points: np.ndarray, meta: dict[str, Any]) -> tuple[Any, str, str]:
    """A function (K, 3) [m] → (K, 2) [m] unrolling the surface the removal grid of ``points``
    (M, 3) lies on, and the labels of its two axes."""
    chart = _chart(meta)
    if chart is None:
        centre = points.mean(axis=0)
        _, _, vt = np.linalg.svd(points - centre, full_matrices=False)
        axes = vt[:2]

        def plane(p: np.ndarray) -> np.ndarray:
            out: np.ndarray = (np.asarray(p, dtype=float) - centre) @ axes.T
            return out

        return plane, "first principal axis [m]", "second principal axis [m]"
    uv = np.array([chart.coordinates(p) for p in points])
    mid = [0.0, 0.0]
    for c, period in enumerate(chart.periods):
        ref = float(uv[0, c])
        if period:  # next to the first cell, then about the middle of the grid
            uv[:, c] += period * np.round((ref - uv[:, c]) / period)
        mid[c] = 0.5 * float(uv[:, c].min() + uv[:, c].max())
    d = chart.derivatives(mid[0], mid[1])
    scale = [float(np.linalg.norm(d[1, 0])), float(np.linalg.norm(d[2, 0]))]

    def unroll(p: np.ndarray) -> np.ndarray:
        q = np.array([chart.coordinates(x) for x in np.asarray(p, dtype=float)])
        for c, period in enumerate(chart.periods):
            if period:
                q[:, c] += period * np.round((mid[c] - q[:, c]) / period)
        out: np.ndarray = q * np.array(scale)  # the chart's own coordinates, scaled
        return out

    labels = [f"{name} × {s:.3g} m/{unit} [m]" for name, s, unit in
              zip(chart.names, scale, chart.units, strict=True)]  # fmt: skip
    if chart.units == ("m", "m"):
        labels = [f"{name} [m]" for name in chart.names] if chart.names else labels
    return unroll, labels[0], labels[1]


def _binned(
    xy: np.ndarray, values: np.ndarray, bins: tuple[int, int], extent: np.ndarray
) -> np.ndarray:
    """The mean of ``values`` (M,) in each bin of the points xy (M, 2) (NaN where empty)."""
    total, _, _ = np.histogram2d(xy[:, 0], xy[:, 1], bins=bins, range=extent, weights=values)
    count, _, _ = np.histogram2d(xy[:, 0], xy[:, 1], bins=bins, range=extent)
    with np.errstate(invalid="ignore", divide="ignore"):
        out: np.ndarray = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return out


def removal_figure(result: Any, name: str = "") -> Figure | None:
    """The removal map of ``result`` (a :class:`~hybrid_force.result.Result`), or None when it
    has no removal arrays."""
    points = getattr(result, "removal_points", None)
    depth = getattr(result, "removal_depth", None)
    target = getattr(result, "removal_target", None)
    if points is None or depth is None:
        return None
    meta = dict(result.meta)
    fig = _new_figure(9.0, 6.5)
    ax = fig.add_subplot()
    unroll, xlabel, ylabel = unrolled(points, meta)
    xy = unroll(points)
    cell = float((meta.get("removal") or {}).get("resolution") or 0.0)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    # bins at least a cell wide (a finer bin would fall between cells' centres), at most 400
    width = np.maximum((hi - lo) / (_MAX_BINS - 1), cell if cell > 0 else 1e-12)
    nx, ny = (int(max(2, min(_MAX_BINS, math.floor(s) + 1))) for s in (hi - lo) / width)
    bins = (nx, ny)
    lo, hi = lo - 0.5 * width, lo - 0.5 * width + np.array(bins) * width
    span = hi - lo
    extent = np.array([[lo[0], hi[0]], [lo[1], hi[1]]])
    image = _binned(xy, depth * 1e6, bins, extent)
    mesh = ax.pcolormesh(
        np.linspace(lo[0], hi[0], bins[0] + 1),
        np.linspace(lo[1], hi[1], bins[1] + 1),
        np.ma.masked_invalid(image.T),
        cmap="viridis",
        shading="flat",
    )
    fig.colorbar(mesh, ax=ax, label="depth removed [µm]", shrink=0.8)
    if target is not None and np.any(target > 0):
        inside = _binned(xy, np.asarray(target, dtype=float), bins, extent)
        xc = lo[0] + (np.arange(bins[0]) + 0.5) * span[0] / bins[0]
        yc = lo[1] + (np.arange(bins[1]) + 0.5) * span[1] / bins[1]
        ax.contour(xc, yc, np.nan_to_num(inside.T), levels=[0.5], colors="w", linewidths=1.0,
                   linestyles="--")  # fmt: skip
        ax.plot([], [], color="w", ls="--", lw=1.0, label="target region")
    phase = np.asarray(result.phase)
    # a ball tool's centre is r off the part: draw where it touches (the patch's centre)
    ball = getattr(result, "contact_point", None)
    if ball is not None and np.ndim(ball) == 3:  # stacked surfaces: the removal surface's
        ball = np.asarray(ball)[:, int((meta.get("removal") or {}).get("surface", 0))]
    touch = np.asarray(result.p if ball is None else ball)[phase == 2]
    touch = touch[np.all(np.isfinite(touch), axis=1)]
    if touch.shape[0]:
        stride = max(1, touch.shape[0] // 4000)
        path = unroll(touch[::stride])
        label = "tip in contact" if ball is None else "contact point"
        ax.plot(path[:, 0], path[:, 1], color="tab:red", lw=0.8, label=label)
    else:
        _note(ax, "the tool never touched the surface")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    if max(span) < 4 * min(span):  # equal lengths, unless the map is a thin band
        ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(loc="upper right", fontsize=8, facecolor="0.85")
    removal = meta.get("removal") or {}
    uniformity = removal.get("removal_uniformity")
    coverage = removal.get("removal_coverage")
    volume = removal.get("removal_volume")
    parts = [f"V = {volume:.3g} m³" if volume is not None else ""]
    if uniformity is not None and coverage is not None:
        parts.append(f"uniformity {uniformity:.3f}, coverage {coverage:.3f}")
    title = f"{name or meta.get('name', 'run')}: material removed"
    ax.set_title(f"{title}\n{'; '.join(p for p in parts if p)}", fontsize=10)
    return fig

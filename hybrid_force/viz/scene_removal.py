"""The replay's removal layer: the depth a run with ``[removal]`` removed, as colours on the part.

The cells of the removal grid (``Result.removal_points`` (M, 3) [m], ``removal_depth`` (M,)
[m]; docs/removal.md) are drawn as one meshcat point cloud, ``/meshcat/replay/removal``: a
point at each cell's centre, coloured by its depth with the colormap of ``removal.png``
(matplotlib's viridis), linear from the least depth drawn (dark violet) to the greatest
(yellow). The depth is the final one, at the end of the run (the layer is not animated). A grid
of more than ``ReplaySettings.max_removal_points`` cells is averaged into cubic voxels (the
mean position and the mean depth of the cells in each), the voxel's edge grown until there are
few enough. The points are drawn after the translucent surfaces, so their colours are not
tinted by them. The colour scale, in µm, is the page's legend (:func:`legend`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # annotations only
    from hybrid_force.result import Result

__all__ = ["REMOVAL_NODE", "VIRIDIS", "RemovalLayer", "colormap", "legend", "removal_layer"]

#: The layer's node under the replay's root (``/meshcat/replay/removal``).
REMOVAL_NODE = "removal"

#: matplotlib's viridis (the colormap of removal.png) at 33 equally spaced values 0, 1/32, ...,
#: 1 (0xRRGGBB); :func:`colormap` interpolates linearly between them (within 3/255 of
#: matplotlib's own 256-colour lookup; tests/test_replay_removal.py checks it).
VIRIDIS: tuple[int, ...] = (
    0x440154, 0x470D60, 0x48186A, 0x482374, 0x472D7B, 0x453781, 0x424086, 0x3E4989,
    0x3B528B, 0x375B8D, 0x33638D, 0x2F6B8E, 0x2C728E, 0x297A8E, 0x26828E, 0x23898E,
    0x21918C, 0x1F988B, 0x1FA088, 0x22A785, 0x28AE80, 0x32B67A, 0x3FBC73, 0x4EC36B,
    0x5EC962, 0x70CF57, 0x84D44B, 0x98D83E, 0xADDC30, 0xC2DF23, 0xD8E219, 0xECE51B,
    0xFDE725,
)  # fmt: skip

#: A point is drawn this many grid spacings wide, so that neighbours overlap.
_POINT_WIDTH = 2.0


def _stops() -> np.ndarray:
    """(33, 3) the colormap's stops as RGB in [0, 1]."""
    c = np.array(VIRIDIS, dtype=np.int64)
    return np.column_stack([(c >> 16) & 0xFF, (c >> 8) & 0xFF, c & 0xFF]) / 255.0


def colormap(x: np.ndarray) -> np.ndarray:
    """(K, 3) RGB in [0, 1] of the values x (K,) in [0, 1] (clipped) on :data:`VIRIDIS`."""
    stops = _stops()
    s = np.linspace(0.0, 1.0, stops.shape[0])
    xc = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return np.column_stack([np.interp(xc, s, stops[:, j]) for j in range(3)])


@dataclass(frozen=True)
class RemovalLayer:
    """The points of the removal layer.

    Attributes:
        points: (K, 3) the points' positions in the run's world frame [m] (the cells' centres,
            or their voxels' mean positions when ``merged``).
        depth: (K,) the depth drawn at each point [m] (the cell's, or its voxel's mean).
        low: the colour scale's lower end, the least depth drawn [m] (viridis' first colour).
        high: its upper end, the greatest depth drawn [m] (viridis' last colour).
        spacing: the points' spacing [m] (the grid's resolution, or the voxel's edge).
        cells: M, the number of cells of the grid.
        merged: True when the cells were averaged into voxels (M > the settings' bound).
    """

    points: np.ndarray
    depth: np.ndarray
    low: float
    high: float
    spacing: float
    cells: int
    merged: bool

    @property
    def colors(self) -> np.ndarray:
        """(K, 3) RGB in [0, 1] of the points: viridis of (depth − low) / (high − low) (the
        middle colour when every depth is the same)."""
        span = self.high - self.low
        x = (self.depth - self.low) / span if span > 0 else np.full(self.depth.shape, 0.5)
        return colormap(x)


def _voxel_means(
    points: np.ndarray, depth: np.ndarray, edge: float
) -> tuple[np.ndarray, np.ndarray]:
    """The mean position (K, 3) [m] and mean depth (K,) [m] of the points (M, 3) in each cube
    of edge ``edge`` [m] of a grid anchored at their least corner."""
    keys = np.floor((points - points.min(axis=0)) / edge).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    k = counts.size
    mean_p = np.column_stack(
        [np.bincount(inverse, weights=points[:, j], minlength=k) for j in range(3)]
    )
    mean_d = np.bincount(inverse, weights=depth, minlength=k)
    return mean_p / counts[:, None], mean_d / counts


def removal_layer(result: Result, max_points: int) -> RemovalLayer | None:
    """The removal layer of ``result``, at most ``max_points`` points; None for a run without
    the removal arrays (or with an empty grid)."""
    points = result.removal_points
    depth = result.removal_depth
    if points is None or depth is None or points.shape[0] == 0:
        return None
    points = np.asarray(points, dtype=float)
    depth = np.asarray(depth, dtype=float)
    m = points.shape[0]
    removal = result.meta.get("removal")
    resolution = removal.get("resolution") if isinstance(removal, dict) else None
    if isinstance(resolution, int | float) and not isinstance(resolution, bool) and resolution > 0:
        spacing = float(resolution)
    else:  # an older meta: the spacing of M cells spread over the box's largest face
        extent = np.sort(np.ptp(points, axis=0))
        spacing = max(float(np.sqrt(extent[1] * extent[2] / m)), 1e-6)
    merged = m > max_points
    if merged:
        edge = spacing * float(np.sqrt(m / max_points))
        while True:
            p, d = _voxel_means(points, depth, edge)
            if p.shape[0] <= max_points:
                break
            edge *= 1.25
        points, depth, spacing = p, d, edge
    return RemovalLayer(
        points=points,
        depth=depth,
        low=float(depth.min()),
        high=float(depth.max()),
        spacing=spacing,
        cells=m,
        merged=merged,
    )


def draw_removal(vis: Any, layer: RemovalLayer) -> None:
    """Send ``layer`` to ``vis`` (the replay's root node) as one coloured point cloud.

    The points are an unlit ``PointsMaterial`` with per-vertex colours, ``_POINT_WIDTH``
    spacings wide; the material is flagged transparent (opacity 1) and its object given a
    render order after the surfaces', so that three.js draws it after them and over them.
    """
    import meshcat.geometry as mg

    class _Points(mg.GenericMaterial):  # three.js' PointsMaterial with every property set
        _type = "PointsMaterial"

    material = _Points(
        color=0xFFFFFF,
        vertexColors=True,
        transparent=True,
        opacity=1.0,
        size=_POINT_WIDTH * layer.spacing,
        sizeAttenuation=True,
    )
    geometry = mg.PointsGeometry(
        np.ascontiguousarray(layer.points.T, dtype=np.float32),
        color=np.ascontiguousarray(layer.colors.T, dtype=np.float32),
    )
    node = vis[REMOVAL_NODE]
    node.set_object(mg.Points(geometry, material))
    node["<object>"].set_property("renderOrder", 1)


def legend(layer: RemovalLayer) -> dict[str, Any]:
    """The layer's colour scale for the page's legend: its title, its ends [µm] and the
    colormap's stops (CSS colours, from the low end)."""
    note = f"{layer.cells} cells"
    if layer.merged:
        note += f", shown as {layer.points.shape[0]} voxels"
    return {
        "title": "depth removed at the end of the run [µm]",
        "low_um": layer.low * 1e6,
        "high_um": layer.high * 1e6,
        "colors": [f"#{c:06x}" for c in VIRIDIS],
        "note": f"viridis, {note}",
    }

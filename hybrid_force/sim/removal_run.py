"""Preston removal during a run: the grid laid on the part, one deposit per recorded sample,
and the removal metrics over the path's target region (docs/removal.md).

:class:`RemovalObserver` is built once per run that has ``[removal]`` (a run without it builds
nothing and calls nothing: :class:`~hybrid_force.sim.record.Record` holds None). At each
sample i < N − 1 (the left-rectangle rule: sample i stands for [t_i, t_i + dt)) it deposits
k_p · p · |v| · dt under the pad's patch (:func:`._removal_kernels.observe`), from

* the tip p (3,) [m] (the patch is centred at its foot on the surface, p − d n),
* the surface's normal n and Hessian ∇²Φ there (the principal curvatures of a Hertz patch),
* the tip's velocity J v (3,) [m/s] (its tangential part slides; a spindle adds ω n × ρ),
* the plant's contact force f_j [N] of the removal surface j (0 out of contact).

The removal surface j is the surface the desired path is laid on (``trajectory.surface`` of a
raster or waypoints path), else the first surface. The grid is laid on that surface's chart
(:func:`~hybrid_force.geometry.charts.chart_for`; the path's own chart for a path on a
surface) over the region the path covers plus a margin, or on its mesh's triangles
(subdivided to ``removal.resolution``) when the surface is a mesh.

The target region (the metrics' region): for a raster, the (u, v) rectangle it covers
(``origin`` to ``origin + size``); for any other path, the band of the cells within the
nominal contact radius a₀ of the desired path (a₀: the pad's patch radius at the desired
force, on the part's curvature at the path's start).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hybrid_force._lazy import LazyKernels
from hybrid_force.errors import ScenarioError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.charts import PlaneChart, SurfaceChart, chart_for
from hybrid_force.geometry.offset import OffsetChart, contact_points
from hybrid_force.geometry.raster import RasterPath
from hybrid_force.geometry.surface_base import principal_curvatures
from hybrid_force.geometry.surface_path import SurfacePath
from hybrid_force.sim.removal import HertzPad, Pad, RemovalGrid, RemovalSettings

__all__ = [
    "RemovalObserver",
    "check_removal",
    "removal_surface_index",
]

_K = LazyKernels("hybrid_force.sim._removal_kernels")
_HERTZ, _FLAT = 0, 1
MAX_CELLS = 4_000_000
"""The most cells a removal grid may have (about 200 MB of arrays)."""
BATCH = 256
"""Samples deposited by one compiled call on a built-in surface (RemovalObserver.observe)."""
_BATCH_BYTES = 24 * BATCH  # their velocities' bytes
MERGE = 0.25
"""Consecutive samples whose patches stay within MERGE · resolution of the first one's (centre,
radius, the rim's tilt; with a spindle, the slip too) are deposited as one patch at their mean
(docs/removal.md, "Cost": the profile's error is O(ℓ² p''/24), ℓ ≤ MERGE · resolution)."""
DEVIATION = 0.02
"""A tool that does not spin, on a plane's or a cylinder's chart: consecutive samples whose feet
stay within DEVIATION · resolution of a straight line (and whose force stays within 0.5 %) are
deposited as one segment, the patch slid along it (docs/removal.md, "Cost")."""
_CHECK_SAMPLES = 64  # path samples at which a Hertz pad's contact is checked before the run


def removal_surface_index(sc: Any) -> int:
    """The index of the surface the removal is recorded on: the path's own surface (a path on
    a surface; with a ball tool the path is on the part's offset, ``sc.tool_surfaces``), else
    0."""
    path = sc.path
    if isinstance(path, SurfacePath):
        for i, (part, centre) in enumerate(zip(sc.surfaces, sc.tool_surfaces, strict=True)):
            if path.surface is part or path.surface == centre:
                return i
    return 0


def _on_part(sc: Any, surface: Any, centres: np.ndarray) -> np.ndarray:
    """Where the tool touches the part ``surface`` when its centre is at each of ``centres``
    (S, 3) [m]: the centres themselves for a point tool, else their feet c − r n̂ (a ball of
    radius r = ``tool.radius``, :func:`~hybrid_force.geometry.offset.contact_points`), the rows
    without a normal left out."""
    r = float(sc.tool.radius)
    if r == 0.0:
        return centres
    feet = contact_points(surface, r, centres)
    return feet[np.all(np.isfinite(feet), axis=1)]


def _mesh_part(surface: Any) -> Any:
    part = getattr(surface, "part", None)
    ok = part is not None and hasattr(part, "vertices") and hasattr(part, "faces")
    return part if ok else None


def _chart(sc: Any, surface: Any) -> SurfaceChart | None:
    if isinstance(sc.path, SurfacePath):
        chart: SurfaceChart = sc.path.chart
        if sc.path.surface is surface:
            return chart
        # a ball tool's path is on the part's offset (geometry/offset): the grid goes on the
        # part's own chart, in the same coordinates (an offset's chart is S + r n̂ of the
        # part's; a built-in offset, R + r or a shifted plane, has the part's frame and axes)
        if isinstance(chart, OffsetChart):
            return chart.part
        return chart_for(surface, chart.axes[0] if isinstance(chart, PlaneChart) else None)
    try:
        return chart_for(surface)
    except Exception:  # no chart registered for the surface's type
        return None


def check_removal(sc: Any) -> None:
    """A Scenario's ``removal`` and ``tool.pad``, the one check of both (ScenarioError naming
    ``removal`` or ``tool.pad``): each given only with the other (alone it has no effect); no
    removal the run cannot record: a surface with neither a chart nor a mesh, and a Hertz pad
    on a part concave enough to conform (1/R + κ ≤ 0 somewhere on the desired path: Hertz
    contact does not apply)."""
    removal, pad = sc.removal, sc.tool.pad
    if removal is not None and not isinstance(removal, RemovalSettings):
        raise ScenarioError(
            "Scenario.removal must be None or a hybrid_force.sim.removal.RemovalSettings, "
            f"got {type(removal).__name__}"
        )
    if removal is not None and pad is None:
        raise ScenarioError(
            "removal (Preston's) needs the tool's contact pad (tool.pad, the [tool.pad] table: "
            "a hertz or flat pad)",
            key="removal",
        )
    if removal is None and pad is not None:
        raise ScenarioError(
            "tool.pad has no effect without removal (the [removal] table): add it, or remove "
            "the pad",
            key="tool.pad",
        )
    if removal is None:
        return
    surface = sc.surfaces[removal_surface_index(sc)]
    if _mesh_part(surface) is None and _chart(sc, surface) is None:
        raise ScenarioError(
            f"removal: the removal grid is laid on a surface's chart or mesh; "
            f"{type(surface).__name__} has neither (plane, cylinder, sphere, ellipsoid and mesh "
            "surfaces do)",
            key="removal",
        )
    if not isinstance(pad, HertzPad):
        return
    times = np.linspace(0.0, sc.sim.duration, _CHECK_SAMPLES)
    centres = np.array([sc.path.position(float(t)) for t in times], dtype=float)
    feet = contact_points(surface, float(sc.tool.radius), centres)
    for t, foot in zip(times, feet, strict=True):
        if not np.all(np.isfinite(foot)):
            continue
        _, grad, hess = surface.evaluate(np.ascontiguousarray(foot))
        k1, k2 = principal_curvatures(np.asarray(grad), np.asarray(hess))
        if not min(k1, k2) > -1.0 / pad.radius:
            raise ScenarioError(
                f"tool.pad.radius = {pad.radius:g} m: the part is concave at the desired path "
                f"(t = {t:.4g} s) with a radius of curvature {-1.0 / min(k1, k2):.4g} m <= the "
                "pad's: the pad conforms to the part, and Hertz contact does not apply (use a "
                'smaller radius or type = "flat")',
                key="tool.pad.radius",
                value=pad.radius,
            )


def _path_samples(sc: Any, spacing: float) -> np.ndarray:
    """Positions (S, 3) [m] of the desired path over [0, sim.duration], about ``spacing`` [m]
    apart (at most 50,000)."""
    duration = sc.sim.duration
    coarse = np.array([sc.path.position(float(t)) for t in np.linspace(0, duration, 2001)])
    length = float(np.linalg.norm(np.diff(coarse, axis=0), axis=1).sum())
    count = min(50_000, max(2001, math.ceil(1.5 * length / spacing) + 1))
    if count == 2001:
        return coarse
    return np.array([sc.path.position(float(t)) for t in np.linspace(0, duration, count)])


def _chart_box(
    chart: SurfaceChart, samples: np.ndarray, margin: float
) -> tuple[tuple[float, float], tuple[float, float], np.ndarray, tuple[float, float], bool]:
    """The (u, v) box of the path samples (S, 3) [m] on ``chart`` (periodic coordinates
    unwrapped along the path), grown by ``margin`` [m] on the surface; a periodic coordinate
    covers at most one period, a latitude at most [−π/2, π/2]. Also: the samples' (u, v)
    (S, 2) (in the box: wrapped into it when u spans a period), the margin in (u, v), and
    whether u spans one whole period."""
    uv = np.empty((samples.shape[0], 2))
    uv[0] = chart.coordinates(samples[0])
    for k in range(1, samples.shape[0]):
        uv[k] = chart.unwrap(chart.coordinates(samples[k]), (uv[k - 1, 0], uv[k - 1, 1]))
    d = chart.derivatives(uv[:, 0], uv[:, 1])
    out, reach, wrap = [], [], False
    for c in range(2):
        # the smallest metric along the path: the widest margin in coordinates
        metric = max(float(np.linalg.norm(d[1 + c], axis=1).min()), 1e-9)
        lo, hi = float(uv[:, c].min()) - margin / metric, float(uv[:, c].max()) + margin / metric
        period = chart.periods[c]
        if period and hi - lo >= period:
            lo, hi = float(uv[:, c].min()), float(uv[:, c].min()) + period
            uv[:, c] = lo + np.mod(uv[:, c] - lo, period)
            wrap = wrap or c == 0
        if chart.names[c] == "latitude":
            lo, hi = max(lo, -math.pi / 2), min(hi, math.pi / 2)
        out.append((lo, hi))
        reach.append(margin / metric)
    return out[0], out[1], uv, (reach[0], reach[1]), wrap


def _top_speed(sc: Any) -> float:
    """The desired path's largest speed ‖ṗ_d‖ [m/s] over [0, sim.duration] (sampled)."""
    top = max(
        float(np.linalg.norm(sc.path.evaluate(float(t))[1]))
        for t in np.linspace(0.0, sc.sim.duration, 2001)
    )
    if not top > 0.0:
        raise ScenarioError(
            'removal.spindle_schedule = "feed" scales the spindle by the feed over the '
            "path's top speed, and the desired path does not move",
            key="removal.spindle_schedule",
            value="feed",
        )
    return top


def _thinned(samples: np.ndarray, spacing: float) -> np.ndarray:
    """The samples (S, 3) [m] of a path kept about ``spacing`` [m] apart along it (the last
    kept too)."""
    step = np.linalg.norm(np.diff(samples, axis=0), axis=1)
    along = np.concatenate([[0.0], np.cumsum(step)])
    keep = np.unique(np.searchsorted(along, np.arange(0.0, along[-1], spacing)))
    return samples[np.append(keep, samples.shape[0] - 1)]


def _near(grid: RemovalGrid, samples: np.ndarray, reach: float, exact: bool = False) -> np.ndarray:
    """(M,) bool: the grid's cells within ``reach`` [m] of the path through the samples
    (S, 3): of a sample, the samples thinned to reach / 2 apart and the reach grown by
    reach / 32 (a point within r of the path between two samples δ apart is within
    √(r² + δ²/4) ≤ r + δ²/(8r) of one of them); ``exact``: the samples as given, within
    ``reach`` of one of them."""
    if not exact:
        samples = _thinned(samples, 0.5 * reach)
        reach *= 1.0 + 1.0 / 32.0
    out = np.zeros(grid.points.shape[0], dtype=bool)
    g = grid
    _K.mark_near(g.points, g.order, g.table, g.starts, g.box, g.dims, samples, float(reach), out)
    return out


def _mesh_grid(part: Any, samples: np.ndarray, margin: float, resolution: float) -> RemovalGrid:
    """Cells on the mesh's triangles within ``margin`` [m] of the path samples, each
    triangle split into s² equal ones (s = ⌈median edge / resolution⌉): their centroids and
    areas."""
    vertices = np.asarray(part.vertices, dtype=float)
    faces = np.asarray(part.faces)
    tri = vertices[faces]
    centroid = tri.mean(axis=1)
    edge = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2)
    # a triangle whose centroid is within the margin plus its longest edge may be reached
    longest = float(edge.max())
    candidates = RemovalGrid(centroid, np.ones(centroid.shape[0]), bucket=4.0 * longest)
    keep = np.flatnonzero(_near(candidates, samples, margin + longest))
    tri = tri[keep]
    s = max(1, math.ceil(float(np.median(edge[keep])) / resolution)) if keep.size else 1
    if tri.shape[0] * s * s > MAX_CELLS:
        raise ScenarioError(
            f"removal.resolution = {resolution:g} m splits the mesh near the path into "
            f"{tri.shape[0] * s * s} cells, more than {MAX_CELLS}: use a coarser resolution",
            key="removal.resolution",
            value=resolution,
        )
    # barycentric centroids of the s² sub-triangles: s(s+1)/2 upright, s(s−1)/2 upside down
    bary = [((i + 1 / 3) / s, (j + 1 / 3) / s) for i in range(s) for j in range(s - i)]
    bary += [((i + 2 / 3) / s, (j + 2 / 3) / s) for i in range(s) for j in range(s - 1 - i)]
    b = np.array(bary)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    points = tri[:, None, 0] + b[None, :, 0, None] * e1[:, None] + b[None, :, 1, None] * e2[:, None]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1) / (s * s)
    return RemovalGrid(
        points.reshape(-1, 3), np.repeat(area, b.shape[0]), bucket=4.0 * max(resolution, 1e-6)
    )


def nominal_radius(pad: Pad, force: float, grad: np.ndarray, hess: np.ndarray) -> float:
    """The patch radius a₀ [m] at ``force`` [N] where the part has gradient (3,), Hessian
    (3, 3) (its curvatures from :func:`.principal_curvatures`)."""
    if isinstance(pad, HertzPad):
        return pad.patch(force, *principal_curvatures(grad, hess))[0]
    return pad.radius


class RemovalObserver:
    """The removal of one run: its grid, the depth, and the deposit of each sample.

    Args:
        sc: the run (its ``removal`` and ``tool.pad`` set). N: its samples.

    Attributes:
        grid: the :class:`~hybrid_force.sim.removal.RemovalGrid` (cells, areas, depth).
        target: (M,) bool, the cells of the target region (module docstring).
        surface_index: the removal surface j. contact_radius: a₀ [m].
    """

    def __init__(self, sc: Any, N: int) -> None:
        removal: RemovalSettings = sc.removal
        pad: Pad = sc.tool.pad
        self.settings, self.pad = removal, pad
        j = self.surface_index = removal_surface_index(sc)
        surface = self.surface = sc.surfaces[j]
        f_d = float(abs(sc.control.f_d_for(len(sc.surfaces))[j]))
        start = _on_part(sc, surface, np.asarray([sc.path.position(0.0)], dtype=float))
        if len(start) == 0:
            raise ScenarioError(
                f"removal: surfaces[{j}] ({surface!r}) has no normal at the desired path's "
                f"start {np.round(sc.path.position(0.0), 6).tolist()} m, where the contact "
                "patch is laid",
                key="removal",
            )
        p0 = start[0]
        _, g0, h0 = surface.evaluate(np.ascontiguousarray(p0))
        a0 = self.contact_radius = nominal_radius(pad, f_d if f_d > 0 else 1.0, g0, h0)
        # the patch under 3× the desired force (a ∝ F^(1/3) for Hertz) stays on the grid
        a_max = nominal_radius(pad, 3.0 * f_d if f_d > 0 else 3.0, g0, h0)
        margin = 1.5 * a_max + 2.0 * removal.resolution
        samples = _on_part(sc, surface, _path_samples(sc, min(removal.resolution, 0.25 * a0)))
        self.samples = samples  # the desired contact points on the part
        part = _mesh_part(surface)
        self.chart: SurfaceChart | None = None
        if part is not None:
            self.grid = _mesh_grid(part, samples, margin, removal.resolution)
        else:
            chart = self.chart = _chart(sc, surface)
            assert chart is not None  # check_removal
            u_range, v_range, uv, reach, wrap = _chart_box(chart, samples, margin)
            self._check_cells(chart, u_range, v_range, reach, uv)
            # buckets about half a patch wide: a step looks up a few dozen of them
            bucket = max(0.5 * a0, 2.0 * removal.resolution)
            box = RemovalGrid.on_chart_near(
                chart, u_range, v_range, removal.resolution, uv, reach, wrap_u=wrap, bucket=bucket
            )
            # only the cells the patch can reach (on the surface, not in coordinates)
            self.grid = box.subset(_near(box, samples, margin))
        self.target = self._target(sc)
        self.target_kind = "rectangle" if isinstance(sc.path, RasterPath) else "band"
        quadric = isinstance(surface, Cylinder | Sphere | Plane)
        self._desc = np.asarray(surface._descriptor if quadric else np.zeros(0), dtype=float)
        self._python = not quadric  # ∇Φ, ∇²Φ from the surface's own methods
        self._grad, self._hess, self._work = np.zeros(3), np.zeros((3, 3)), np.zeros(18)
        # consecutive samples whose patch moved less than MERGE cells: one deposit
        self._merge = MERGE * removal.resolution
        # a tool that does not spin on a plane's or a cylinder's lattice: straight segments
        # (a cylinder's segment and its patch within a quarter turn: the rows' periodic shift)
        self._deviation = 0.0
        lattice = self.grid.lattice
        if lattice.shape[0] > 0 and removal.omega == 0.0:
            reach = (_K.SEGMENT_LENGTH + 2.0) * a_max + 4.0 * removal.resolution
            if lattice[0] == _K.PLANE_ROWS or reach < 0.5 * math.pi * lattice[19]:
                self._deviation = DEVIATION * removal.resolution
        self._dt = sc.sim.dt
        self._group = np.zeros(_K.GROUP)
        self._shape = _HERTZ if isinstance(pad, HertzPad) else _FLAT
        self._modulus = pad.modulus if isinstance(pad, HertzPad) else 0.0
        self._factor = removal.k_p * sc.sim.dt
        # the spindle's schedule "feed": ω |v_t| / v_ref, v_ref the desired path's top speed
        self.v_ref = 0.0
        if removal.spindle_schedule == "feed":
            self.v_ref = _top_speed(sc)
        self._last = N - 1
        # the batched deposit (:meth:`observe`): the bytes of J v (3 float64 each) of the
        # samples since ``_first`` (appending bytes costs a third of writing a row of an array)
        self._tips: np.ndarray | None = None
        self._forces: np.ndarray | None = None
        self._batched = False
        self._kept = bytearray()
        self._first = 0
        self.steps = 0  # samples that deposited
        self.conforming = 0  # samples where the part conformed to a Hertz pad (none deposited)

    def _check_cells(
        self,
        chart: SurfaceChart,
        u_range: tuple[float, float],
        v_range: tuple[float, float],
        reach: tuple[float, float],
        uv: np.ndarray,
    ) -> None:
        """Refuse a resolution that would make more than :data:`MAX_CELLS` cells along the
        path (its length times the band's width, over the cell's area)."""
        d = chart.derivatives(uv[:, 0], uv[:, 1])
        step = np.diff(uv, axis=0)
        tangent = d[1, 1:] * step[:, :1] + d[2, 1:] * step[:, 1:]
        length = float(np.linalg.norm(tangent, axis=1).sum())
        width = 2.0 * max(reach[0] * float(np.linalg.norm(d[1], axis=1).max()),
                          reach[1] * float(np.linalg.norm(d[2], axis=1).max()))  # fmt: skip
        res = self.settings.resolution
        cells = (length + width) * width / (res * res)
        if cells > MAX_CELLS:
            raise ScenarioError(
                f"removal.resolution = {res:g} m makes about {cells:.3g} cells along the "
                f"path, more than {MAX_CELLS}: use a coarser resolution",
                key="removal.resolution",
                value=res,
            )

    def _target(self, sc: Any) -> np.ndarray:
        grid, path = self.grid, sc.path
        if isinstance(path, RasterPath):
            chart = self.chart if self.chart is not None else chart_for(self.surface)
            if grid.uv is not None:
                uv = grid.uv.copy()
            else:  # a mesh part's cells: their coordinates in its [surface.chart]
                uv = np.array([chart.coordinates(x) for x in grid.points], dtype=float)
            lo = np.array(path.origin)
            hi = lo + np.array(path.size)
            for c, period in enumerate(chart.periods):
                if period:  # the cell's coordinate within half a period of the rectangle's
                    mid = 0.5 * (lo[c] + hi[c])
                    uv[:, c] += period * np.round((mid - uv[:, c]) / period)
            tol = 1e-12
            inside: np.ndarray = np.all((uv >= lo - tol) & (uv <= hi + tol), axis=1)
            return inside
        # the band swept by the nominal patch along the desired path (on the surface)
        d = np.array([abs(self.surface.distance(p)) for p in self.samples])
        on = self.samples[d <= max(1e-6, 0.1 * self.contact_radius)]
        return _near(grid, on, self.contact_radius, exact=True)

    def attach(self, tips: np.ndarray, forces: np.ndarray) -> None:
        """The run's record of the tip (N, 3) [m] and the forces (N, k) [N], which a run on a
        built-in surface reads in batches (:meth:`observe`)."""
        self._tips, self._forces = tips, forces
        self._batched = not self._python

    def observe(self, i: int, p: np.ndarray, pdot: np.ndarray, f: np.ndarray) -> None:
        """Sample i's deposit: tip p (3,) [m], its velocity J v (3,) [m/s], the contact
        forces f (k,) [N] (module docstring).

        On a built-in surface (∇Φ, ∇²Φ compiled) with :meth:`attach`-ed records, only J v is
        kept here, and every ``BATCH`` samples one compiled call deposits them all from the
        records (one call's fixed cost for many samples); :meth:`finish` deposits the rest.
        """
        if self._batched:
            kept = self._kept
            kept += pdot.tobytes()
            if len(kept) == _BATCH_BYTES:
                self._flush(i + 1)
            return
        force = float(f[self.surface_index])
        if i >= self._last or not force > 0.0:
            return
        grid, grad, hess, distance = self.grid, self._grad, self._hess, 0.0
        if self._python:
            _, g, h, distance = self.surface.evaluate_with_distance(p)
            if abs(distance) > _K.FOOT_TOL:  # the part's curvature at the foot (the kernel's)
                foot = p - distance * np.asarray(g) / float(np.linalg.norm(g))
                _, g, h = self.surface.evaluate(np.ascontiguousarray(foot))
            grad[:] = g
            hess[:] = h
        a = _K.observe(
            self._desc, p, grad, hess, distance, pdot, force, self._shape, self.pad.radius,
            self._modulus, self.settings.omega, self.v_ref, self._factor, self._merge,
            self._deviation, self._dt, grid.points,
            grid.areas, grid.order, grid.table, grid.starts, grid.box, grid.dims, grid.lattice,
            grid.rows, grid.col, grid.depth, self._group, self._work, grid.index, grid.weight,
        )  # fmt: skip
        if a < 0.0:
            self.conforming += 1
        else:
            self.steps += 1

    def _flush(self, stop: int) -> None:
        """Deposit the kept samples first … stop − 1 (not the run's last: left rectangles)."""
        first = self._first
        count = min(stop, self._last) - first
        if count > 0 and self._tips is not None and self._forces is not None:
            g, tally = self.grid, np.zeros(2, dtype=np.int64)
            # a copy (6 kB a batch): a view would export the bytes, and a compiling first
            # call may keep its arguments alive in a cycle past this call (a BufferError on
            # the next resize, seen once in the tests)
            velocities = np.frombuffer(self._kept, dtype=np.float64).reshape(-1, 3).copy()
            _K.observe_batch(
                self._desc, self._tips, self._forces, self.surface_index, velocities, first,
                count, self._shape, self.pad.radius, self._modulus, self.settings.omega, self.v_ref,
                self._factor, self._merge, self._deviation, self._dt, g.points, g.areas, g.order,
                g.table, g.starts, g.box,
                g.dims, g.lattice, g.rows, g.col, g.depth, self._group, self._work, g.index,
                g.weight, tally,
            )  # fmt: skip
            self.steps += int(tally[0])
            self.conforming += int(tally[1])
        self._kept.clear()
        self._first = stop

    def finish(self, filled: int) -> None:
        """Deposit the samples kept and not yet deposited, up to the ``filled`` recorded
        (the end of the run, or where it stopped)."""
        if self._batched and filled > self._first:
            self._flush(filled)
        g = self.grid
        _K.flush(
            self._group, self._shape, self._factor, g.points, g.areas, g.order, g.table, g.starts,
            g.box, g.dims, g.lattice, g.rows, g.col, g.depth, self._work, g.index, g.weight,
        )  # fmt: skip

    def summary(self) -> dict[str, Any]:
        """The removal metrics (docs/removal.md) and what they were measured on (JSON-able):
        removal_volume [m³] (the whole grid: Σ h_i A_i), over the target region the
        area-weighted removal_depth_mean, _std, _min, _max [m], removal_uniformity =
        1 − std/mean and removal_coverage (the area fraction with h ≥ mean / 2); None where
        not defined (no target cell, or no removal)."""
        grid, mask = self.grid, self.target
        out: dict[str, Any] = {"removal_volume": grid.volume}
        names = ("mean", "std", "min", "max")
        stats: dict[str, Any] = {f"removal_depth_{n}": None for n in names}
        stats.update(removal_uniformity=None, removal_coverage=None)
        if mask.any():
            w, h = grid.areas[mask], grid.depth[mask]
            mean = float(w @ h / w.sum())
            std = float(math.sqrt(max(float(w @ (h - mean) ** 2 / w.sum()), 0.0)))
            stats.update(
                removal_depth_mean=mean,
                removal_depth_std=std,
                removal_depth_min=float(h.min()),
                removal_depth_max=float(h.max()),
            )
            if mean > 0:
                stats["removal_uniformity"] = 1.0 - std / mean
                stats["removal_coverage"] = float(w[h >= 0.5 * mean].sum() / w.sum())
        out.update(stats)
        out.update(
            target=self.target_kind,
            target_area=float(grid.areas[mask].sum()),
            contact_radius=self.contact_radius,
            surface=self.surface_index,
            grid="mesh" if self.chart is None else "chart",
            cells=int(grid.points.shape[0]),
            target_cells=int(mask.sum()),
            steps=self.steps,
            conforming_steps=self.conforming,
            k_p=self.settings.k_p,
            spindle_speed=self.settings.spindle_speed,
            spindle_schedule=self.settings.spindle_schedule,
            v_ref=self.v_ref,
            resolution=self.settings.resolution,
            pad={"type": self.pad.kind, **vars(self.pad)},
        )
        return out

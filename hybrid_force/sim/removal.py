"""What polishing removes: the tool's contact patch (Hertz or flat pad) and Preston's law.

Preston (1927): the removal rate is ḣ = k_p · p · v, pressure p [Pa] times sliding speed v
[m/s], with Preston's coefficient k_p [m²/N]. The depth accumulates on a grid of cells laid on
the surface (:class:`RemovalGrid`), each step adding k_p p_i |v_i| dt to the cells under the
patch only (:func:`._removal_kernels.deposit`; a tool that does not spin, on a plane's or a
cylinder's chart, in straight segments of samples, :func:`._removal_kernels.deposit_segment`).

Pads:

* :class:`HertzPad` – an elastic pad of radius of curvature R [m] and effective modulus E* [Pa]
  pressed with F on a part (Hertz; Johnson, *Contact Mechanics*, 1985, §4.2 and §5.2): contact
  radius a = (3 F R_eff / 4E*)^(1/3), p(ρ) = p₀ √(1 − ρ²/a²), p₀ = 3F / (2πa²). The part's
  principal curvatures κ₁, κ₂ (> 0 convex, from ∇²Φ) give 1/R' = 1/R + κ₁, 1/R'' = 1/R + κ₂;
  an elliptical patch is replaced by the circle of the same area, R_eff = √(R'R'') (Johnson
  §4.2, the equivalent-radius approximation; within a few % of the ellipse's a·b for R'/R'' ≤ 5).
  Valid for small strains (a ≪ R), frictionless, elastic contact.
* :class:`FlatPad` – a flat pad of radius a [m] with a uniform pressure F / (πa²) (a compliant
  foam pad fully in contact; no edge peak).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from hybrid_force._lazy import LazyKernels
from hybrid_force.errors import ScenarioError
from hybrid_force.geometry.charts import CylinderChart, PlaneChart
from hybrid_force.geometry.paths import axis_frame
from hybrid_force.schema import check_fields, param

__all__ = [
    "PAD_TYPES",
    "FlatPad",
    "HertzPad",
    "Pad",
    "RemovalGrid",
    "RemovalSettings",
    "flat_profile",
    "hertz_profile",
]

_K = LazyKernels("hybrid_force.sim._removal_kernels")
_HERTZ, _FLAT = 0, 1


@dataclass(frozen=True)
class HertzPad:
    """An elastic pad (``[tool.pad] type = "hertz"``): ``radius`` R [m] of curvature,
    ``modulus`` E* [Pa] (effective: E* = 1 / ((1 − ν₁²)/E₁ + (1 − ν₂²)/E₂))."""

    kind: ClassVar[str] = "hertz"
    radius: float = param(unit="m", minimum=0.0, strict=True, doc="the pad's radius of curvature")
    modulus: float = param(
        unit="Pa", minimum=0.0, strict=True, doc="effective modulus E* of the pad on the part"
    )

    def __post_init__(self) -> None:
        check_fields(self, ScenarioError, "tool.pad.")

    def patch(self, force: float, kappa1: float = 0.0, kappa2: float = 0.0) -> tuple[float, float]:
        """(a [m], p₀ [Pa]) of the patch under ``force`` [N] on a part of principal curvatures
        κ₁, κ₂ [1/m] (> 0 convex; a concave part with 1/R + κ ≤ 0 conforms: refused)."""
        inv1, inv2 = 1.0 / self.radius + kappa1, 1.0 / self.radius + kappa2
        if not (inv1 > 0 and inv2 > 0):
            raise ScenarioError(
                f"tool.pad.radius = {self.radius:g} m: the part is concave with a radius of "
                f"curvature {1 / -min(kappa1, kappa2):.4g} m <= the pad's: Hertz contact does "
                "not apply (the pad conforms to the part)",
                key="tool.pad.radius",
                value=self.radius,
            )
        r_eff = 1.0 / math.sqrt(inv1 * inv2)
        if force <= 0:
            return 0.0, 0.0
        a = (3.0 * force * r_eff / (4.0 * self.modulus)) ** (1.0 / 3.0)
        return a, 3.0 * force / (2.0 * math.pi * a * a)


@dataclass(frozen=True)
class FlatPad:
    """A flat pad (``[tool.pad] type = "flat"``) of ``radius`` a [m]: uniform pressure
    F / (πa²)."""

    kind: ClassVar[str] = "flat"
    radius: float = param(
        unit="m", minimum=0.0, strict=True, doc="the flat pad's radius a (the contact radius)"
    )

    def __post_init__(self) -> None:
        check_fields(self, ScenarioError, "tool.pad.")

    def patch(self, force: float, kappa1: float = 0.0, kappa2: float = 0.0) -> tuple[float, float]:
        """(a [m], p [Pa]): the pad's radius and F / (πa²)."""
        a = self.radius
        return a, max(force, 0.0) / (math.pi * a * a)


Pad = HertzPad | FlatPad
"""The contact pads (``ToolSettings.pad``)."""

PAD_TYPES: dict[str, type[HertzPad] | type[FlatPad]] = {"hertz": HertzPad, "flat": FlatPad}
"""The ``[tool.pad]`` types, by their ``type`` key."""


@dataclass(frozen=True)
class RemovalSettings:
    """The ``[removal]`` table: Preston's law on a grid laid on the part (docs/removal.md).

    Needs a pad (``[tool.pad]``, :attr:`~hybrid_force.control.tool.ToolSettings.pad`).
    """

    k_p: float = param(unit="m²/N", minimum=0.0, strict=True, doc="Preston's coefficient")
    resolution: float = param(
        unit="m", minimum=0.0, strict=True, doc="cell size of the removal grid on the surface"
    )
    spindle_speed: float = param(
        0.0,
        unit="rpm",
        minimum=0.0,
        doc="the pad's rotation about the surface normal (0: a non-rotating tool)",
    )
    spindle_schedule: Literal["constant", "feed"] = param(
        "constant",
        doc="constant: the spindle_speed throughout; feed: scaled by the feed / the path's "
        "top speed (constant removal per unit length)",
    )

    def __post_init__(self) -> None:
        check_fields(self, ScenarioError, "removal.")
        if self.spindle_schedule != "constant" and self.spindle_speed == 0.0:
            raise ScenarioError(
                f'removal.spindle_schedule = "{self.spindle_schedule}" needs a spinning tool '
                "(removal.spindle_speed > 0): without one it has no effect",
                key="removal.spindle_schedule",
                value=self.spindle_schedule,
            )

    @property
    def omega(self) -> float:
        """The spindle's rate [rad/s]."""
        return self.spindle_speed * 2.0 * math.pi / 60.0


def hertz_profile(y: np.ndarray, a: float, p0: float, k_p: float) -> np.ndarray:
    """Depth h(y) [m] across a straight pass of a Hertz patch: k_p ∫ p dx = k_p p₀ π (a² − y²)/(2a).

    Independent of the feed: the time under the patch is the path length over the speed.
    """
    y = np.asarray(y, dtype=float)
    return np.where(np.abs(y) < a, k_p * p0 * math.pi * (a * a - y * y) / (2.0 * a), 0.0)


def flat_profile(y: np.ndarray, a: float, p: float, k_p: float) -> np.ndarray:
    """Depth h(y) [m] across a straight pass of a flat pad: 2 k_p p √(a² − y²)."""
    y = np.asarray(y, dtype=float)
    return np.where(np.abs(y) < a, 2.0 * k_p * p * np.sqrt(np.maximum(a * a - y * y, 0.0)), 0.0)


def _chart_lattice(
    chart: object, u_range: tuple[float, float], v_range: tuple[float, float], resolution: float
) -> tuple[int, int, float, float]:
    """The cell counts nu, nv over the (u, v) box of a chart and the cells' sides du, dv (in
    u, in v): cells about ``resolution`` [m] wide on the surface, by |S_u|, |S_v| at the
    box's middle."""
    mid_u, mid_v = 0.5 * sum(u_range), 0.5 * sum(v_range)
    _, su, sv = chart.derivatives(mid_u, mid_v)[:3, 0]  # type: ignore[attr-defined]
    nu = max(1, math.ceil((u_range[1] - u_range[0]) * np.linalg.norm(su) / resolution))
    nv = max(1, math.ceil((v_range[1] - v_range[0]) * np.linalg.norm(sv) / resolution))
    return nu, nv, (u_range[1] - u_range[0]) / nu, (v_range[1] - v_range[0]) / nv


class RemovalGrid:
    """Cells on the surface: centres (M, 3) [m], areas (M,) [m²], and the depth (M,) [m].

    The cells are sorted into cubic buckets of side ``bucket`` [m] so that a step visits only
    the buckets its patch overlaps; only the buckets holding cells are kept (in a hash table,
    ``table``): a helix's box is mostly empty.
    """

    def __init__(self, points: np.ndarray, areas: np.ndarray, bucket: float) -> None:
        self.points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        self.areas = np.ascontiguousarray(areas, dtype=np.float64).reshape(-1)
        if self.points.shape[0] != self.areas.shape[0] or self.points.shape[0] == 0:
            raise ValueError("RemovalGrid: points (M, 3) and areas (M,) with M > 0")
        self.depth = np.zeros(self.points.shape[0])
        # the deposit's scratch: the cells under the patch and their weights
        self.index = np.zeros(self.points.shape[0], dtype=np.int64)
        self.weight = np.zeros(self.points.shape[0])
        #: the cells' chart coordinates (M, 2), for a grid laid on a chart
        self.uv: np.ndarray | None = None
        origin = self.points.min(axis=0) - 1e-9
        dims = np.floor((self.points.max(axis=0) - origin) / bucket).astype(np.int64) + 1
        index = np.floor((self.points - origin) / bucket).astype(np.int64)
        flat = (index[:, 0] * dims[1] + index[:, 1]) * dims[2] + index[:, 2]
        self.order = np.argsort(flat, kind="stable").astype(np.int64)
        keys, counts = np.unique(flat, return_counts=True)
        #: the hash table of the buckets holding cells (:func:`._removal_kernels.bucket_table`)
        self.table = _K.bucket_table(keys.astype(np.int64))
        self.starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.box = np.array([*origin, bucket])
        self.dims = dims
        #: a plane's or a cylinder's chart lattice, where the cells are found row by row
        #: (:func:`._removal_kernels.deposit`): [kind, u0, du, v0, dv, nu, period, the chart's
        #: origin (3), its axes (3 × 3), radius] (a cylinder's then sin, cos of its rows' edges'
        #: half angles, (nu + 1) pairs), or empty (the buckets); rows (nu + 1,): where each
        #: lattice row's cells start, col (M,): their columns
        self.lattice = np.zeros(0)
        self.rows = np.zeros(1, dtype=np.int64)
        self.col = np.zeros(0, dtype=np.int64)
        #: the cells' lattice indices (M, 2) (iu, iv), for a grid laid on a chart
        self.ij: np.ndarray | None = None

    @classmethod
    def on_chart(
        cls,
        chart: object,
        u_range: tuple[float, float],
        v_range: tuple[float, float],
        resolution: float,
    ) -> RemovalGrid:
        """Cells of a chart S(u, v) (:mod:`hybrid_force.geometry.charts`) over a (u, v) box.

        The cell counts give cells about ``resolution`` [m] wide on the surface; each cell's
        area is |S_u × S_v| du dv at its centre (midpoint rule).
        """
        nu, nv, du, dv = _chart_lattice(chart, u_range, v_range, resolution)
        flat = np.arange(nu * nv, dtype=np.int64)
        lattice = (u_range[0], du, v_range[0], dv, nu, nv)
        return cls._of_chart_cells(chart, flat, lattice, 4.0 * resolution)

    @classmethod
    def on_chart_near(
        cls,
        chart: object,
        u_range: tuple[float, float],
        v_range: tuple[float, float],
        resolution: float,
        uv: np.ndarray,
        reach: tuple[float, float],
        wrap_u: bool = False,
        bucket: float | None = None,
    ) -> RemovalGrid:
        """The cells of :meth:`on_chart` within ``reach`` (in u, in v) of the chart points uv
        (S, 2), without building the others (a helix's box is mostly far from it).

        ``wrap_u``: u_range is one whole period (a cell's neighbour across its end is the
        first cell). ``bucket`` [m]: the buckets' side (default 4 × resolution).
        """
        nu, nv, du, dv = _chart_lattice(chart, u_range, v_range, resolution)
        iu = np.floor((np.asarray(uv[:, 0]) - u_range[0]) / du).astype(np.int64)
        iv = np.floor((np.asarray(uv[:, 1]) - v_range[0]) / dv).astype(np.int64)
        mu, mv = math.ceil(reach[0] / du), math.ceil(reach[1] / dv)
        # the points thinned to about half a reach apart, the reach grown by as much
        hu, hv = max(1, mu // 2), max(1, mv // 2)
        kept = [0]
        for k in range(1, iu.shape[0]):
            last = kept[-1]
            if abs(iu[k] - iu[last]) >= hu or abs(iv[k] - iv[last]) >= hv:
                kept.append(k)
        kept.append(iu.shape[0] - 1)
        centres = np.unique(np.column_stack([iu[kept], iv[kept]]), axis=0)
        mu, mv = mu + hu, mv + hv
        if nu * nv <= 100_000_000:  # a mask of the lattice, a rectangle set per point
            mask = np.zeros((nu, nv), dtype=bool)
            for cu, cv in centres.tolist():
                v0, v1 = max(0, cv - mv), min(nv, cv + mv + 1)
                if v0 >= v1:
                    continue
                if wrap_u:
                    lo_u, hi_u = cu - mu, cu + mu + 1
                    if hi_u - lo_u >= nu:
                        mask[:, v0:v1] = True
                        continue
                    for start in range(lo_u - lo_u % nu, hi_u, nu):  # the whole periods spanned
                        a, b = max(lo_u, start) - start, min(hi_u, start + nu) - start
                        mask[a:b, v0:v1] = True
                else:
                    mask[max(0, cu - mu) : min(nu, cu + mu + 1), v0:v1] = True
            flat = np.flatnonzero(mask)
        else:
            offsets = np.column_stack([a.ravel() for a in np.meshgrid(
                np.arange(-mu, mu + 1), np.arange(-mv, mv + 1), indexing="ij")])  # fmt: skip
            chosen: list[np.ndarray] = []
            chunk = max(1, 4_000_000 // offsets.shape[0])
            for start in range(0, centres.shape[0], chunk):
                cells = (centres[start : start + chunk, None, :] + offsets[None]).reshape(-1, 2)
                if wrap_u:
                    cells[:, 0] %= nu
                inside = (cells[:, 0] >= 0) & (cells[:, 0] < nu)
                inside &= (cells[:, 1] >= 0) & (cells[:, 1] < nv)
                chosen.append(np.unique(cells[inside, 0] * nv + cells[inside, 1]))
            flat = np.unique(np.concatenate(chosen)) if chosen else np.zeros(0, dtype=np.int64)
        lattice = (u_range[0], du, v_range[0], dv, nu, nv)
        return cls._of_chart_cells(
            chart, flat, lattice, 4.0 * resolution if bucket is None else bucket
        )

    @classmethod
    def _of_chart_cells(
        cls,
        chart: object,
        flat: np.ndarray,
        lattice: tuple[float, float, float, float, int, int],
        bucket: float,
    ) -> RemovalGrid:
        """The grid of the chart cells iu · nv + iv (flat (M,), increasing) of the lattice
        (u0, du, v0, dv, nu, nv): centred at (u0 + (iu + ½) du, v0 + (iv + ½) dv), of area
        |S_u × S_v| du dv at the centre [m²] (midpoint rule), buckets ``bucket`` [m]."""
        u0, du, v0, dv, nu, nv = lattice
        ij = np.column_stack([flat // nv, flat % nv])
        uu, vv = u0 + du * (ij[:, 0] + 0.5), v0 + dv * (ij[:, 1] + 0.5)
        d = chart.derivatives(uu, vv)  # type: ignore[attr-defined]
        areas = np.linalg.norm(np.cross(d[1], d[2]), axis=1) * du * dv
        grid = cls(d[0], areas, bucket=bucket)
        grid.uv = np.column_stack([uu, vv])
        grid._set_lattice(chart, ij, (u0, du, v0, dv, nu))
        return grid

    def _set_lattice(
        self, chart: object, ij: np.ndarray, lattice: tuple[float, float, float, float, int]
    ) -> None:
        """Keep the cells' lattice indices ij (M, 2) (rows iu increasing, columns iv
        increasing within a row) of (u0, du, v0, dv, nu); on a plane's or a cylinder's chart
        also the lattice for the row-by-row search (:attr:`lattice`)."""
        self.ij = ij
        u0, du, v0, dv, nu = lattice
        if isinstance(chart, PlaneChart):  # S = point + u e_u + v e_v
            e_u, e_v = chart.axes
            frame = [np.asarray(chart.surface.point, dtype=float), e_u, e_v, np.cross(e_u, e_v)]
            kind, period, radius = _K.PLANE_ROWS, 0.0, 0.0
        elif isinstance(chart, CylinderChart):  # S = c + h a + r (cos θ e1 + sin θ e2)
            frame = [np.asarray(chart.surface.center, dtype=float), *axis_frame(chart.surface.axis)]
            kind, period, radius = _K.CYLINDER_ROWS, 2.0 * math.pi, chart.surface.radius
        else:
            return
        head = [kind, u0, du, v0, dv, nu, period]
        parts = [np.array([*head, *np.concatenate(frame), radius], dtype=float)]
        if kind == _K.CYLINDER_ROWS:  # the rows' edges' half angles (_K.HALF_ANGLES)
            half = 0.5 * (u0 + du * np.arange(nu + 1))
            parts.append(np.column_stack([np.sin(half), np.cos(half)]).ravel())
        self.lattice = np.concatenate(parts)
        self.rows = np.searchsorted(ij[:, 0], np.arange(nu + 1)).astype(np.int64)
        self.col = np.ascontiguousarray(ij[:, 1], dtype=np.int64)

    @classmethod
    def on_mesh(cls, vertices: np.ndarray, faces: np.ndarray) -> RemovalGrid:
        """One cell per triangle: its centroid and area."""
        tri = np.asarray(vertices, dtype=float)[np.asarray(faces)]
        areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        edge = float(np.sqrt(np.median(areas)))
        return cls(tri.mean(axis=1), areas, bucket=4.0 * max(edge, 1e-6))

    def subset(self, keep: np.ndarray) -> RemovalGrid:
        """A grid of the cells ``keep`` (M,) bool of this one (their depth zero)."""
        grid = RemovalGrid(self.points[keep], self.areas[keep], bucket=float(self.box[3]))
        grid.uv = None if self.uv is None else self.uv[keep]
        if self.ij is not None:
            grid.ij = self.ij[keep]
        if self.lattice.shape[0] > 0:
            grid.lattice = self.lattice
            assert grid.ij is not None
            nu = self.rows.shape[0] - 1
            grid.rows = np.searchsorted(grid.ij[:, 0], np.arange(nu + 1)).astype(np.int64)
            grid.col = np.ascontiguousarray(grid.ij[:, 1], dtype=np.int64)
        return grid

    def add(
        self,
        pad: HertzPad | FlatPad,
        k_p: float,
        dt: float,
        centre: np.ndarray,
        normal: np.ndarray,
        velocity: np.ndarray,
        force: float,
        omega: float = 0.0,
        curvatures: tuple[float, float] = (0.0, 0.0),
    ) -> int:
        """One step of Preston removal (:func:`._removal_kernels.deposit`); the cells touched."""
        a, _ = pad.patch(force, *curvatures)
        shape = _HERTZ if isinstance(pad, HertzPad) else _FLAT
        n = np.ascontiguousarray(normal, dtype=np.float64)
        v = np.ascontiguousarray(velocity, dtype=np.float64)
        vn = v[0] * n[0] + v[1] * n[1] + v[2] * n[2]
        vt = v - vn * n  # the tangential part slides
        return int(
            _K.deposit(
                self.points,
                self.areas,
                self.order,
                self.table,
                self.starts,
                self.box,
                self.dims,
                self.lattice,
                self.rows,
                self.col,
                self.depth,
                np.ascontiguousarray(centre, dtype=np.float64),
                n,
                vt,
                math.sqrt(float(vt[0] * vt[0] + vt[1] * vt[1] + vt[2] * vt[2])),
                float(omega),
                float(a),
                shape,
                float(force),
                float(k_p) * float(dt),
                self.index,
                self.weight,
            )
        )

    @property
    def volume(self) -> float:
        """Σ depth_i A_i [m³]."""
        return float(self.depth @ self.areas)

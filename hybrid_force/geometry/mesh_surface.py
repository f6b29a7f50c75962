"""A workpiece given as a triangle mesh (``[surface] type = "mesh"``: STL, OBJ, PLY).

Φ(p) is the tricubic B-spline field of :mod:`.mesh_field` (a metric distance to within the
fit error, Φ > 0 on the free side), so ``distance`` is Φ itself and a tool of radius r follows
the offset surface Φ − r exactly (up to that fit). The mesh's triangles are kept for drawing.
Paths in surface coordinates use the part's ``chart`` (:mod:`.mesh_charts`).

A sweep builds the surface once on its own machine and sends it, field included, to its
workers (:func:`hybrid_force.scenario._builders.file_surfaces`): a worker never reads the mesh
file nor the cache folder.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force.errors import ModelWarning, SurfaceError
from hybrid_force.geometry.charts import register_chart
from hybrid_force.geometry.mesh_charts import (
    CylindricalChartSettings,
    MeshChart,
    ProjectionChartSettings,
    chart_settings,
)
from hybrid_force.geometry.mesh_field import (
    CREASE_ANGLE,
    FACETS,
    DistanceField,
    MeshPart,
    build_field,
    read_mesh,
)
from hybrid_force.geometry.mesh_patches import curved_patches
from hybrid_force.geometry.offset import PhiOffset
from hybrid_force.geometry.surface_base import (
    Surface,
    Vec3,
    _boolean,
    _point3,
    _vector3,
    _xyz,
    principal_curvatures,
    register_surface,
    tool_radius,
)
from hybrid_force.schema import param

__all__ = ["MeshOffset", "MeshSurface", "PartReport", "check_part"]

#: ‖∇Φ‖ below this: the normal is undefined (a distance field has ‖∇Φ‖ ≈ 1 near the surface).
_SINGULAR_GRADIENT = 1e-6
#: Within this many grid spacings of an open edge Φ is not trusted: the signed distance it is
#: fitted to jumps past the edge (its sign flips across the surface's extension), and the
#: interpolating cubic B-spline rings after a jump, by a factor −(2 − √3) ≈ −0.27 a node;
#: ∇²Φ, 1/h² more sensitive than Φ, is the last to settle. Measured on an open sine sheet
#: (benchmarks/study_open_mesh.py) at h = 10 and 5 mm: the curvature across the waves is 3.2
#: and 2.3 times the true one at 3 h and 4 h, within 4 % and 12 % at 6 h, within 1 % at 8 h.
UNTRUSTED_SPACINGS = 8.0
#: A concave radius of curvature beyond this many part diagonals is taken as flat (the fit's
#: round-off: 2e7 m on a flat 0.4 m sheet, tests/test_part_cli.py), not reported as a hollow.
FLAT_RADII = 1e4
_ORIGIN: Vec3 = (0.0, 0.0, 0.0)
_LARGEST = 1e150  # |coordinate| [m] of a point taken as it is (surface_base._MAX_POINT)


@register_surface
@dataclass(frozen=True, eq=False)
class MeshSurface(Surface):
    """The surface of a mesh part: Φ(p) = ±d(p), the smoothed signed distance [m].

    ``MeshSurface(file, ...)`` reads, places and fits the part (the field cached on disk,
    :func:`.mesh_field.build_field`); :meth:`from_file` also takes ``cache``. ``inside =
    False``: the tool works on the side the face normals point to (outside a closed part
    exported the usual way). Warns (ModelWarning) when the mesh is not watertight: the
    winding-number sign of Φ is then trusted only near the surface.
    """

    kind: ClassVar[str] = "mesh"
    # Φ is the (fitted) signed distance: a ball tool of radius r follows Φ − r (geometry/offset)
    metric_distance: ClassVar[str] = "phi"
    file: str = param(doc="STL, OBJ or PLY file of the part (relative to the scenario file)")
    scale: float = param(1.0, minimum=0.0, strict=True, doc="the file's units in metres")
    position: Vec3 = param(_ORIGIN, unit="m", doc="where the file's origin is put in the world")
    rpy: Vec3 = param(_ORIGIN, unit="rad", doc="roll, pitch, yaw of the part in the world")
    inside: bool = param(False, doc="the free side is the one the face normals point away from")
    resolution: float | None = param(
        None,
        unit="m",
        minimum=0.0,
        strict=True,
        doc="grid spacing of the smooth distance field (default: twice the facets' size, "
        "docs/mesh_parts.md)",
    )
    facets: str = param(
        "curved",
        choices=FACETS,
        doc="curved: Φ = 0 on patches bent through the vertices along their normals, the "
        "smooth part the mesh was cut from; flat: on the faces themselves (docs/mesh_parts.md)",
    )
    crease_angle: float = param(
        CREASE_ANGLE,
        unit="deg",
        minimum=0.0,
        maximum=180.0,
        acts_when=("facets", "curved"),
        doc="faces meeting at a larger angle keep a sharp edge between them",
    )
    chart: ProjectionChartSettings | CylindricalChartSettings | None = param(
        None,
        doc="[surface.chart]: the (u, v) of paths in surface coordinates",
        acts_when=("trajectory.type", "in", ("waypoints", "raster")),
    )
    part: MeshPart = dataclasses.field(default=None, repr=False)  # type: ignore[assignment]
    field: DistanceField = dataclasses.field(default=None, repr=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        owner = "MeshSurface"
        values = {
            "position": _point3(owner, "position", self.position),
            "rpy": _vector3(owner, "rpy", self.rpy),
            "inside": _boolean(owner, "inside", self.inside),
            "chart": chart_settings(self.chart),
            "file": str(self.file),
        }
        for name, value in values.items():
            object.__setattr__(self, name, value)
        if self.part is None or self.field is None:
            part, fitted = _fit(
                self.file,
                self.scale,
                self.position,
                self.rpy,
                self.inside,
                self.resolution,
                self.facets,
                self.crease_angle,
            )
            object.__setattr__(self, "part", part)
            object.__setattr__(self, "field", fitted)
        object.__setattr__(self, "scale", float(self.scale))
        object.__setattr__(self, "crease_angle", float(self.crease_angle))
        object.__setattr__(self, "path_tolerance", self.field.tolerance)

    @classmethod
    def from_file(
        cls,
        file: str | Path,
        *,
        scale: float = 1.0,
        position: tuple[float, float, float] = (0.0, 0.0, 0.0),
        rpy: tuple[float, float, float] = (0.0, 0.0, 0.0),
        inside: bool = False,
        resolution: float | None = None,
        facets: str = "curved",
        crease_angle: float = CREASE_ANGLE,
        chart: Any = None,
        cache: bool = True,
    ) -> MeshSurface:
        """Read, place and fit the mesh in ``file`` (``cache``: read and write the field's
        cache file, :func:`.build_field`)."""
        settings = (file, scale, position, rpy, inside, resolution, facets, crease_angle)
        part, fitted = _fit(*settings, cache=cache)
        return cls._of_part(*settings, chart, part, fitted)

    @classmethod
    def _of_part(
        cls,
        file: str | Path,
        scale: float,
        position: Vec3,
        rpy: Vec3,
        inside: bool,
        resolution: float | None,
        facets: str,
        crease_angle: float,
        chart: Any,
        part: MeshPart,
        fitted: DistanceField,
    ) -> MeshSurface:
        """The surface of the settings and the part read and fitted from them (no refit)."""
        return cls(
            file=str(file),
            scale=scale,
            position=position,
            rpy=rpy,
            inside=inside,
            resolution=resolution,
            facets=facets,
            crease_angle=crease_angle,
            chart=chart,
            part=part,
            field=fitted,
        )

    @classmethod
    def from_table(cls, values: dict[str, Any], folder: Path, table: str) -> MeshSurface:
        """The surface of a scenario's checked ``[surface]`` table ``values`` (its TOML keys),
        ``file`` relative to the scenario's ``folder``; refusals name ``table.key``."""
        file = Path(values["file"])
        target = file if file.is_absolute() else folder / file
        values = {f.name: f.default for f in dataclasses.fields(cls) if f.init} | values
        scale = values["scale"]
        position = tuple(values["position"])
        rpy = tuple(values["rpy"])
        inside = values["inside"]
        resolution = values["resolution"]
        facets = values["facets"]
        crease_angle = values["crease_angle"]
        part = read_mesh(
            target,
            scale=scale,
            position=position,
            rpy=rpy,
            key=f"{table}.file",
        )
        _warn_open(part, f"{table}.file", values["file"])
        fitted = build_field(
            part,
            resolution,
            inside=inside,
            facets=facets,
            crease_angle=crease_angle,
            key=f"{table}.resolution",
        )
        try:
            chart = chart_settings(values.get("chart"))
        except SurfaceError as exc:
            message = str(exc).replace("surface.chart", f"{table}.chart", 1)
            raise SurfaceError(message, key=f"{table}.chart", value=values.get("chart")) from None
        settings = (target, scale, position, rpy, inside, resolution, facets, crease_angle)
        return cls._of_part(*settings, chart, part, fitted)

    def __repr__(self) -> str:
        return f"MeshSurface('{self.file}', h={self.field.spacing:.4g} m)"

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(Φ [m], ∇Φ: (3,), ∇²Φ: (3, 3) [1/m]) at p: (3,) float64 [m]; fresh arrays."""
        return self.field.evaluate(p)

    def evaluate_with_distance(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
        """:meth:`evaluate` and d = Φ [m]."""
        value, grad, hess = self.field.evaluate(p)
        return value, grad, hess, value

    def _checked(self, p: ArrayLike, method: str) -> np.ndarray:
        """p as a float64 (3,) array (itself when it already is one, finite: the tool's
        orientation asks for ∇²Φ off the path twice a step), else checked by _xyz."""
        if type(p) is np.ndarray and p.shape == (3,) and p.dtype == np.float64:
            x, y, z = p.tolist()
            if abs(x) <= _LARGEST and abs(y) <= _LARGEST and abs(z) <= _LARGEST:
                return p
        return np.array(_xyz(p, self, method))

    def phi(self, p: ArrayLike) -> float:
        """Φ(p) [m]."""
        return self.field.evaluate(self._checked(p, "phi"))[0]

    def gradient(self, p: ArrayLike) -> np.ndarray:
        """∇Φ(p): (3,) (unit length to within the fit)."""
        return self.field.evaluate(self._checked(p, "gradient"))[1]

    def hessian(self, p: ArrayLike) -> np.ndarray:
        """∇²Φ(p): (3, 3) [1/m]."""
        if type(p) is np.ndarray and p.shape == (3,) and p.dtype == np.float64:
            # the hot path (the tool's orientation, twice a step): the kernel checks p is finite
            hess = self.field.hessian(p)
            if hess is not None:
                return hess
        return self.field.evaluate(self._checked(p, "hessian"))[2]

    def orientation_terms(
        self, sample: np.ndarray, step: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """What a pointed tool's orientation needs at a path sample (3, 3) rows p_d, ṗ_d, p̈_d:
        (∇Φ, ∇²Φ, (d/dt ∇²Φ) ṗ_d by a central difference over ±``step`` [m] along ṗ_d), in one
        compiled call (:meth:`.DistanceField.orientation_terms`; ``control.tool`` asks for it
        every step). None when the sample is not a finite float64 (3, 3) array: the caller
        then computes the terms itself, through the checked methods."""
        if type(sample) is np.ndarray and sample.shape == (3, 3) and sample.dtype == np.float64:
            return self.field.orientation_terms(sample, step)
        return None

    def distance(self, p: ArrayLike) -> float:
        """d = Φ [m] (the field is a signed distance)."""
        return self.phi(p)

    def normal(self, p: ArrayLike) -> np.ndarray:
        """∇Φ/‖∇Φ‖: (3,), to the free side."""
        x = self._checked(p, "normal")
        grad = self.field.evaluate(x)[1]
        norm = float(np.linalg.norm(grad))
        if not norm >= _SINGULAR_GRADIENT:
            raise SurfaceError(
                f"{self!r}.normal: ‖∇Φ‖ = {norm:.3g} at p = {x.tolist()} (on the part's medial "
                "axis, where the distance has no normal)"
            )
        return grad / norm

    def closest_point(self, p: ArrayLike) -> np.ndarray:
        """The foot point on Φ = 0: Newton steps x ← x − Φ ∇Φ/‖∇Φ‖² from p (≤ 20, to 1e-12 m)."""
        x = self._checked(p, "closest_point")
        for _ in range(20):
            value, grad, _ = self.field.evaluate(x)
            g2 = float(grad @ grad)
            if not g2 >= _SINGULAR_GRADIENT**2:
                raise SurfaceError(f"{self!r}.closest_point: ‖∇Φ‖ vanishes at {x.tolist()}")
            x = x - (value / g2) * grad
            if abs(value) <= 1e-12:
                break
        return x

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "mesh", "file", "scale", "position", "rpy", "inside", "resolution",
        "facets", "crease_angle", "chart"}`` (``resolution``: the spacing used; ``chart``: None
        or its settings)."""
        return {
            "type": self.kind,
            "file": self.file,
            "scale": self.scale,
            "position": list(self.position),
            "rpy": list(self.rpy),
            "inside": self.inside,
            "resolution": self.field.spacing,
            "facets": self.facets,
            "crease_angle": self.crease_angle,
            "chart": None if self.chart is None else self.chart.to_dict(),
        }

    def offset(self, radius: float) -> Surface:
        """The surface Φ − r = 0 of a ball tool's centre, r = ``radius`` [m] (:class:`MeshOffset`,
        with the part's chart laid on it); this very surface for r = 0."""
        r = tool_radius(radius)
        return self if r == 0.0 else MeshOffset(self, r)

    def concave_radius(self) -> tuple[float, np.ndarray | None]:
        """(the smallest concave radius of curvature [m] at the part's vertices, the vertex
        (3,) [m] where it is found, in the world) or (inf, None) when the part is nowhere
        concave: the hook a ball tool's check calls (:meth:`smallest_concave_radius`)."""
        return self._most_concave()

    def triangles(
        self, points: np.ndarray | None = None, margin: float = 0.0, max_faces: int = 200_000
    ) -> tuple[np.ndarray, np.ndarray]:
        """The part's own triangles for drawing: (vertices (V, 3) [m], faces (F, 3) indices).

        All of them, or for a mesh of more than ``max_faces`` faces only those with a vertex
        within ``margin`` [m] (at least 10 % of the motion's span) of the bounding box of
        ``points`` (M, 3) [m], the motion (a replay's page stays small)."""
        vertices, faces = self.part.vertices, self.part.faces
        if points is None or len(faces) <= max_faces or len(points) == 0:
            return vertices, faces
        low, high = points.min(axis=0), points.max(axis=0)
        pad = max(margin, 0.1 * float(np.linalg.norm(high - low)))
        near = np.all((vertices >= low - pad) & (vertices <= high + pad), axis=1)
        kept = faces[near[faces].any(axis=1)]
        used, inverse = np.unique(kept, return_inverse=True)
        return vertices[used], inverse.reshape(-1, 3)

    def open_edge_distance(self, points: ArrayLike) -> np.ndarray:
        """The distance (N,) [m] of each of ``points`` (N, 3) [m] to the part's nearest open
        edge (:attr:`.MeshPart.open_edges`, libigl's point–segment distance); inf for a
        watertight part."""
        x = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
        edges = self.part.open_edges
        if len(edges) == 0 or len(x) == 0:
            return np.full(len(x), math.inf)
        import igl

        squared, _, _ = igl.point_mesh_squared_distance(
            x, np.ascontiguousarray(self.part.vertices, dtype=np.float64), edges
        )
        return np.sqrt(np.asarray(squared, dtype=np.float64))

    @property
    def untrusted_width(self) -> float:
        """How near [m] an open edge Φ is not trusted: :data:`UNTRUSTED_SPACINGS` grid
        spacings (0 for a watertight part)."""
        return 0.0 if len(self.part.open_edges) == 0 else UNTRUSTED_SPACINGS * self.field.spacing

    def untrusted(self, points: ArrayLike) -> tuple[int, float] | None:
        """(the index of the first of ``points`` (N, 3) [m] within :attr:`untrusted_width` of an
        open edge, its distance to the edge [m]), or None: where a path comes that near, Φ
        follows the fit's jump rather than the part (the scenario warns)."""
        if self.untrusted_width == 0.0:
            return None
        distance = self.open_edge_distance(points)
        near = np.flatnonzero(distance < self.untrusted_width)
        return None if len(near) == 0 else (int(near[0]), float(distance[near[0]]))

    def smallest_concave_radius(self) -> float:
        """The smallest radius of curvature [m] of the part's concave regions, at its vertices.

        From the principal curvatures of Φ = 0 (the eigenvalues of the Hessian projected on the
        tangent plane, ∇Φ of unit length): a principal curvature κ < 0 is a concave direction
        (seen from the free side) of radius 1/|κ|; inf when there is none. A ball tool of
        radius r cannot reach the bottom where r exceeds it. A lower estimate: the fit's
        ripple at the facets' scale lowers it (on a 128 × 48 torus by 8 % with curved facets,
        25 % with flat ones, measured in tests/test_mesh_field.py), which errs on the side of
        a warning. Vertices within :attr:`untrusted_width` of an open edge are left out: the
        fit's jump there is no hollow of the part.
        """
        return self._most_concave()[0]

    def _most_concave(self) -> tuple[float, np.ndarray | None]:
        """(:meth:`smallest_concave_radius`, the vertex (3,) [m] where it is found, or None
        when the part is nowhere concave); found once (the part and its field are fixed)."""
        found: tuple[float, np.ndarray | None] = self.__dict__.get("_concave_found") or (
            self._search_concave()
        )
        self.__dict__["_concave_found"] = found  # a frozen dataclass: its own memo
        smallest, where = found
        return smallest, None if where is None else where.copy()

    def _search_concave(self) -> tuple[float, np.ndarray | None]:
        smallest, where = math.inf, None
        vertices = self.part.vertices
        if self.untrusted_width > 0.0:
            vertices = vertices[self.open_edge_distance(vertices) >= self.untrusted_width]
        for vertex in vertices:
            _, grad, hess = self.field.evaluate(np.ascontiguousarray(vertex))
            if float(np.linalg.norm(grad)) < _SINGULAR_GRADIENT:
                continue
            most = principal_curvatures(grad, hess)[1]
            # a radius beyond FLAT_RADII part diagonals is the fit's round-off on a flat face
            if most * self.part.diagonal * FLAT_RADII < -1.0 and 1.0 / -most < smallest:
                smallest, where = 1.0 / -most, np.array(vertex)
        return smallest, where


def _warn_open(part: MeshPart, key: str, file: object) -> None:
    if not part.watertight:
        warnings.warn(
            f"{key} = '{file}': the mesh is not watertight (some edges are not shared by "
            "exactly two faces); the sign of Φ is trusted only near the surface",
            ModelWarning,
            stacklevel=3,
        )


def _fit(
    file: str | Path,
    scale: float,
    position: tuple[float, ...],
    rpy: tuple[float, ...],
    inside: bool,
    resolution: float | None,
    facets: str,
    crease_angle: float,
    *,
    cache: bool = True,
) -> tuple[MeshPart, DistanceField]:
    part = read_mesh(file, scale=scale, position=position, rpy=rpy)  # type: ignore[arg-type]
    _warn_open(part, "surface.file", file)
    field = build_field(
        part,
        resolution,
        inside=bool(inside),
        facets=facets,
        crease_angle=crease_angle,
        cache=cache,
    )
    return part, field


class MeshOffset(PhiOffset):
    """Φ − r = 0 over a mesh part (:class:`~.offset.PhiOffset`), the surface of the centre of a
    ball tool of radius r, with the part's ``[surface.chart]`` laid on it directly: the ray of
    (u, v) is marched to Φ = r, where the ball dropped along the ray first touches the part (as
    a CAM tool drops a ball-end cutter). The part's point offset along its normal, S + r n̂, is
    not used: Φ is a distance only to its fit (‖∇Φ‖ within about 1 %), so that point lies on
    Φ = r only to about 1e-2 r."""

    @property
    def chart(self) -> ProjectionChartSettings | CylindricalChartSettings | None:
        """The part's chart settings."""
        return self.base.chart  # type: ignore[attr-defined]


register_chart(MeshSurface)(MeshChart)
register_chart(MeshOffset)(MeshChart)


@dataclass(frozen=True)
class PartReport:
    """What ``hybrid-force part --check`` prints about a mesh part and its fitted field.

    Lengths in metres; ``fit_*``: max |Φ − d| against the part's signed distance d at its
    vertices, at its face centres (d = 0 at both; the centres of the curved patches for
    ``facets = "curved"``) and at ``band_points`` random points within 2 h of the surface; d
    is the mesh's exact distance (libigl), or the patches' over its foot when curved
    (:mod:`.mesh_patches`); ``bend``: the largest height of a patch over its face (0 when
    flat); ``gradient_norm``: (min, max) of ‖∇Φ‖ in the band; ``concave_point``: the vertex
    (3,) [m] of ``smallest_concave_radius``, None if none. An open part: ``open_edges`` (how
    many), ``untrusted_width`` (:attr:`MeshSurface.untrusted_width`) and ``fit_inner``, the
    three fit errors over the points farther than that from every open edge (None when
    watertight, or when no point is that far); the gradient norm is then theirs too.
    """

    file: str
    faces: int
    vertices: int
    watertight: bool
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]]
    resolution: float
    default_resolution: bool
    facets: str
    bend: float
    grid: tuple[int, int, int]
    memory_bytes: int
    fit_vertices: float
    fit_face_centres: float
    fit_band: float
    band_points: int
    gradient_norm: tuple[float, float]
    smallest_concave_radius: float
    concave_point: tuple[float, float, float] | None
    build_seconds: float
    cache_file: str
    open_edges: int = 0
    untrusted_width: float = 0.0
    fit_inner: tuple[float, float, float] | None = None

    def lines(self) -> list[str]:
        """The report as text lines."""
        (x0, y0, z0), (x1, y1, z1) = self.bounds
        nx, ny, nz = self.grid
        concave = self.smallest_concave_radius
        return [
            f"file: {self.file}",
            f"faces: {self.faces:,} ({self.vertices:,} vertices), "
            + (
                "watertight"
                if self.watertight
                else "NOT watertight: the sign of Φ is trusted only near the surface"
            ),
            f"bounding box [m]: [{x0:.6g}, {y0:.6g}, {z0:.6g}] to [{x1:.6g}, {y1:.6g}, {z1:.6g}] "
            f"({x1 - x0:.4g} x {y1 - y0:.4g} x {z1 - z0:.4g})",
            f"resolution: {self.resolution:.4g} m"
            + (" (default: twice the facets' size, clamped)" if self.default_resolution else ""),
            f"facets: {self.facets}"
            + (f" (patches up to {self.bend:.3g} m off the faces)" if self.bend > 0 else ""),
            f"grid: {nx} x {ny} x {nz} = {nx * ny * nz:,} nodes, "
            f"{self.memory_bytes / 1e6:.3g} MB of coefficients",
            f"fit error max |Φ − d| [m]: vertices {self.fit_vertices:.3g}, face centres "
            f"{self.fit_face_centres:.3g}, band ±{2 * self.resolution:.3g} m "
            f"({self.band_points} points) {self.fit_band:.3g}",
            *self._open_lines(),
            f"‖∇Φ‖ in the band{' (away from the open edges)' if self.fit_inner else ''}: "
            f"{self.gradient_norm[0]:.4f} to {self.gradient_norm[1]:.4f}",
            "smallest concave radius of curvature"
            + (" (away from the open edges)" if self.open_edges else "")
            + ": "
            + (
                f"{concave:.4g} m at the vertex {[round(x, 6) for x in self.concave_point]} m"
                if math.isfinite(concave) and self.concave_point is not None
                else "none (no concave region)"
            ),
            f"build time: {self.build_seconds:.3g} s"
            + (" (read from the cache)" if self.build_seconds == 0.0 else ""),
            f"cache file: {self.cache_file or '(none)'}",
        ]

    def _open_lines(self) -> list[str]:
        if not self.open_edges:
            return []
        near = f"within {self.untrusted_width:.3g} m ({UNTRUSTED_SPACINGS:g} grid spacings)"
        line = f"open edges: {self.open_edges:,}; Φ is not trusted {near} of them"
        if self.fit_inner is None:
            return [line + " (no point of the part is farther)"]
        v, c, b = self.fit_inner
        return [
            line,
            f"fit error away from the open edges [m]: vertices {v:.3g}, face centres {c:.3g}, "
            f"band {b:.3g}",
        ]


def check_part(
    file: str | Path,
    *,
    resolution: float | None = None,
    scale: float = 1.0,
    facets: str = "curved",
    crease_angle: float = CREASE_ANGLE,
    band_points: int = 2000,
    seed: int = 0,
) -> PartReport:
    """Read and fit the part in ``file`` and measure the fit (:class:`PartReport`).

    The band's points: random face points (uniform in the barycentric square, folded) moved
    along the face normal by a uniform offset in [−2h, 2h]; their exact signed distance is
    libigl's (the same library the field's samples come from, but at points off the grid),
    to the patches over its feet for curved facets (:meth:`.CurvedPatches.signed_distance`).
    """
    import igl

    surface = MeshSurface.from_file(
        file, scale=scale, resolution=resolution, facets=facets, crease_angle=crease_angle
    )
    part, field = surface.part, surface.field
    curved = facets == "curved"
    patches = curved_patches(part.vertices, part.faces, crease_angle) if curved else None
    tri = part.vertices[part.faces]
    centres = tri.mean(axis=1)
    if patches is not None:
        everyone = np.arange(len(part.faces))
        centres = patches.points(everyone, np.full((len(everyone), 3), 1.0 / 3.0))
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(size=(2, band_points))
    fold = a + b > 1.0
    a[fold], b[fold] = 1.0 - a[fold], 1.0 - b[fold]
    pick = rng.integers(0, len(part.faces), band_points)
    t = tri[pick]
    on_face = t[:, 0] + a[:, None] * (t[:, 1] - t[:, 0]) + b[:, None] * (t[:, 2] - t[:, 0])
    normals = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    lengths = np.linalg.norm(normals, axis=1)
    keep = lengths > 0
    normals = normals[keep] / lengths[keep, None]
    offsets = rng.uniform(-2.0, 2.0, int(keep.sum())) * field.spacing
    band = on_face[keep] + offsets[:, None] * normals
    sign = -1.0 if surface.inside else 1.0
    exact, foot_face, foot, _ = igl.signed_distance(band, part.vertices, part.faces)
    exact = np.asarray(exact, dtype=np.float64)
    if patches is not None:
        foot_face = np.asarray(foot_face, dtype=np.int64)
        exact = patches.signed_distance(foot_face, np.asarray(foot), band, exact)
    band_error = np.abs(field.values(band) - sign * exact)
    vertex_error = np.abs(field.values(part.vertices))
    centre_error = np.abs(field.values(centres))
    norms = np.array([np.linalg.norm(field.evaluate(np.ascontiguousarray(p))[1]) for p in band])
    width, fit_inner = surface.untrusted_width, None
    if width > 0.0:  # an open part: the fit and the gradient away from its open edges too
        far = [surface.open_edge_distance(x) >= width for x in (part.vertices, centres, band)]
        if all(mask.any() for mask in far):
            fit_inner = tuple(
                float(e[mask].max())
                for e, mask in zip((vertex_error, centre_error, band_error), far, strict=True)
            )
            norms = norms[far[2]]
    nx, ny, nz = field.shape
    concave, where = surface.concave_radius()
    return PartReport(
        file=str(file),
        faces=len(part.faces),
        vertices=len(part.vertices),
        watertight=part.watertight,
        bounds=(
            tuple(float(x) for x in part.vertices.min(axis=0)),  # type: ignore[arg-type]
            tuple(float(x) for x in part.vertices.max(axis=0)),
        ),
        resolution=field.spacing,
        default_resolution=resolution is None,
        facets=facets,
        bend=0.0 if patches is None else patches.largest,
        grid=(nx, ny, nz),
        memory_bytes=int(field.coefficients.nbytes),
        fit_vertices=float(vertex_error.max()),
        fit_face_centres=float(centre_error.max()),
        fit_band=float(band_error.max()),
        band_points=len(band),
        gradient_norm=(float(norms.min()), float(norms.max())),
        smallest_concave_radius=concave,
        concave_point=None
        if where is None
        else (float(where[0]), float(where[1]), float(where[2])),
        build_seconds=field.build_seconds,
        cache_file=field.cache_file,
        open_edges=len(part.open_edges),
        untrusted_width=width,
        fit_inner=fit_inner,  # type: ignore[arg-type]
    )

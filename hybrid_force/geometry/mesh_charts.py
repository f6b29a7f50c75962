"""Charts of a mesh part (``[surface.chart]``): the (u, v) of surface paths laid on the part.

A mesh has no coordinates of its own, so its chart is a family of rays P(s) = B(u, v) +
s·D(u, v), and S(u, v) is the first point where the ray, marched from the free side, meets
Φ = 0 (the smooth field of :mod:`.mesh_field`). S lies on Φ = 0 to 1e-14 m, and its first and
second derivatives follow in closed form from Φ(S(u, v)) = 0 (implicit differentiation, written
out in :func:`._field_kernels.ray_chart_eval`, which evaluates all of it compiled):

* :class:`ProjectionChartSettings` (``type = "projection"``): (u, v) [m] in the plane through
  ``origin`` normal to ``normal``, along e_u (``u_axis`` projected on the plane; default the
  world x axis projected, world y if the normal is along x) and e_v = n × e_u; each point is
  projected along ``normal`` (towards the part) onto it, as CAM tools lay a raster over a part.
  The origin's plane must lie on the free side of the part (in front of it).
* :class:`CylindricalChartSettings` (``type = "cylindrical"``): (u, v) = (angle θ [rad],
  height h [m]) about the axis through ``center`` along ``axis`` (θ from e1 as a cylinder's
  chart, :mod:`.charts`), each point projected radially: from outside the part inwards (the
  outermost surface) when the outside is free, from the axis outwards when ``inside``. θ is
  periodic, so a raster along θ wraps round a closed part.

A (u, v) whose ray misses the part, starts inside it, or grazes it (|∇Φ·D| < 1e-3 |∇Φ|, where
S(u, v) is not smooth) raises PathError naming the chart and the point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force.errors import PathError, SurfaceError
from hybrid_force.geometry.charts import SurfaceChart, Vec3
from hybrid_force.geometry.paths import axis_frame
from hybrid_force.geometry.surface_base import _direction, _point3
from hybrid_force.schema import param

__all__ = ["CylindricalChartSettings", "MeshChart", "ProjectionChartSettings"]

_ORIGIN: Vec3 = (0.0, 0.0, 0.0)
_Z: Vec3 = (0.0, 0.0, 1.0)
_PARALLEL_TOL = 1e-6
_RECENT = 8  # (u, v) points derivatives_at remembers (then forgets them all)


@dataclass(frozen=True)
class ProjectionChartSettings:
    """``[surface.chart] type = "projection"``: (u, v) [m] in a plane, projected along its
    normal onto the part (the module doc)."""

    kind: ClassVar[str] = "projection"
    origin: Vec3 = param(unit="m", doc="a point of the plane of (u, v), on the free side")
    normal: Vec3 = param(doc="the projection direction, from the plane towards the part")
    u_axis: Vec3 | None = param(
        None, doc="the u direction (projected on the plane; default world x projected)"
    )

    def __post_init__(self) -> None:
        owner = "surface.chart"
        object.__setattr__(self, "origin", _point3(owner, "origin", self.origin))
        object.__setattr__(self, "normal", _direction(owner, "normal", self.normal))
        if self.u_axis is not None:
            object.__setattr__(self, "u_axis", _direction(owner, "u_axis", self.u_axis))

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "projection", "origin", "normal"[, "u_axis"]}``."""
        out: dict[str, Any] = {"type": self.kind, "origin": list(self.origin)}
        out["normal"] = list(self.normal)
        if self.u_axis is not None:
            out["u_axis"] = list(self.u_axis)
        return out


@dataclass(frozen=True)
class CylindricalChartSettings:
    """``[surface.chart] type = "cylindrical"``: (angle [rad], height [m]) about an axis,
    projected radially onto the part (the module doc)."""

    kind: ClassVar[str] = "cylindrical"
    center: Vec3 = param(unit="m", doc="a point of the axis (height 0)")
    axis: Vec3 = param(_Z, doc="the axis direction (height grows along it)")

    def __post_init__(self) -> None:
        owner = "surface.chart"
        object.__setattr__(self, "center", _point3(owner, "center", self.center))
        object.__setattr__(self, "axis", _direction(owner, "axis", self.axis))

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "cylindrical", "center", "axis"}``."""
        return {"type": self.kind, "center": list(self.center), "axis": list(self.axis)}


ChartSettings = ProjectionChartSettings | CylindricalChartSettings

CHART_TYPES: dict[str, type[ProjectionChartSettings] | type[CylindricalChartSettings]] = {
    "projection": ProjectionChartSettings,
    "cylindrical": CylindricalChartSettings,
}


def chart_settings(value: object) -> ChartSettings | None:
    """The chart settings of ``value``: None, a settings object, or a dict with ``type``
    (as a scenario's ``[surface.chart]`` or ``to_dict`` gives)."""
    if value is None or isinstance(value, (ProjectionChartSettings, CylindricalChartSettings)):
        return value
    if isinstance(value, dict) and value.get("type") in CHART_TYPES:
        params = {k: v for k, v in value.items() if k != "type"}
        cls = CHART_TYPES[str(value["type"])]
        try:
            return cls(**params)
        except TypeError as exc:
            raise SurfaceError(f"surface.chart: {exc}", key="chart", value=value) from None
    raise SurfaceError(
        f"surface.chart must be a table with type = 'projection' or 'cylindrical', got {value!r}",
        key="chart",
        value=value,
    )


class MeshChart(SurfaceChart):
    """The chart of a :class:`~.mesh_surface.MeshSurface`, from its ``chart`` settings, or of
    its :class:`~.mesh_surface.MeshOffset` by a ball tool's radius r (``surface.base`` the
    part, ``surface.radius`` r): the same rays, marched to Φ = r instead of Φ = 0.

    Raises:
        PathError: the surface has no chart settings, or a ``u_axis`` along the normal.
    """

    names: tuple[str, str]  # type: ignore[misc]
    units: tuple[str, str]  # type: ignore[misc]
    periods: tuple[float, float]  # type: ignore[misc]

    def __init__(self, surface: Any) -> None:
        part = getattr(surface, "base", surface)
        self._level = float(surface.radius) if part is not surface else 0.0
        settings = part.chart
        if settings is None:
            raise PathError(
                f"{surface!r} has no chart: a path in surface coordinates (a raster, or "
                "waypoints) on a mesh part needs a [surface.chart] table (type = "
                '"projection" or "cylindrical", docs/mesh_parts.md)',
                key="surface",
                value=part.file,
            )
        self.surface, self._part = surface, part
        self.settings = settings
        field = part.field
        self._coef, self._origin, self._h = field.coefficients, field.origin, field.spacing
        corners = field.origin + field.spacing * (np.array(field.shape) - 1) * np.array(
            [[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=float
        )
        self._frame = np.zeros((4, 3))
        if isinstance(settings, ProjectionChartSettings):
            n = np.array(settings.normal)
            if settings.u_axis is None:
                e_u = axis_frame(n)[0]
            else:
                raw = np.array(settings.u_axis)
                along = raw - float(raw @ n) * n
                if not np.linalg.norm(along) > _PARALLEL_TOL:
                    raise PathError(
                        f"surface.chart.u_axis = {list(settings.u_axis)} is along the normal "
                        f"{list(settings.normal)}: give a direction in the plane of (u, v)",
                        key="chart",
                        value=settings.to_dict(),
                    )
                e_u = along / np.linalg.norm(along)
            o = np.array(settings.origin)
            self._frame[:] = (o, e_u, np.cross(n, e_u), n)
            self._mode = 0
            self._start = 0.0
            self._end = float(((corners - o) @ n).max()) + 2.0 * field.spacing
            self.names, self.units, self.periods = ("u", "v"), ("m", "m"), (0.0, 0.0)
        else:
            e1, e2, a = axis_frame(np.array(settings.axis))
            c = np.array(settings.center)
            self._frame[:] = (c, e1, e2, a)
            self._mode = 1
            w = corners - c
            radial = w - np.outer(w @ a, a)
            far = float(np.linalg.norm(radial, axis=1).max()) + 2.0 * field.spacing
            self._start, self._end = (0.0, far) if part.inside else (far, 0.0)
            self.names, self.units = ("angle", "height"), ("rad", "m")
            self.periods = (2.0 * math.pi, 0.0)
        # the kernel's settings, then its output S, S_u, S_v, S_uu, S_uv, S_vv (ray_chart_eval)
        self._params = np.concatenate(
            [
                self._origin,
                [self._h, self._mode, self._start, self._end, self._level],
                self._frame.ravel(),
                np.zeros(18),
            ]
        )
        self._flat = self._params[20:]  # a view: the output as 18 numbers
        self._out = self._flat.reshape((6, 3))  # a view: the output's rows
        self._recent: dict[tuple[float, float], tuple[Vec3, Vec3, Vec3, Vec3, Vec3, Vec3]] = {}
        from hybrid_force.geometry import _field_kernels

        self._kernel = _field_kernels.ray_chart_eval

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the output's views (a copy would no longer see the kernel's
        writes) and the remembered points."""
        return {k: v for k, v in self.__dict__.items() if k not in ("_flat", "_out", "_recent")}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._flat = self._params[20:]
        self._out = self._flat.reshape((6, 3))
        self._recent = {}

    def _evaluate(self, u: float, v: float) -> np.ndarray:
        s = self._kernel(self._coef, self._params, u, v)
        if s != s:  # NaN: no point of the part on this ray
            raise self._miss(u, v)
        return self._out

    def _miss(self, u: float, v: float) -> PathError:
        frame = self._frame
        if self._mode == 0:
            base, d = frame[0] + u * frame[1] + v * frame[2], frame[3]
        else:
            base, d = frame[0] + v * frame[3], math.cos(u) * frame[1] + math.sin(u) * frame[2]
        start = base + self._start * d
        kind = self.settings.kind
        if self._part.field.evaluate(start)[0] <= self._level:
            side = "(Φ ≤ 0)" if self._level == 0.0 else f"(Φ ≤ tool.radius = {self._level:g} m)"
            why = f"its ray starts at {np.round(start, 6).tolist()}, on the part's side {side}" + (
                ": put chart.origin in front of the part" if self._mode == 0 else ""
            )
        else:
            why = (
                f"its ray from {np.round(start, 6).tolist()} along "
                f"{np.round(d if self._start < self._end else -d, 6).tolist()} misses the part "
                "or grazes it"
            )
        return PathError(
            f"surface.chart ({kind}): the point ({self.names[0]}, {self.names[1]}) = "
            f"({u:.6g}, {v:.6g}) is not on the part: {why}; keep the path's coordinates "
            "within the part as the chart sees it",
            key="chart",
            value=self.settings.to_dict(),
        )

    def derivatives(self, u: ArrayLike, v: ArrayLike) -> np.ndarray:
        """(6, N, 3): S, S_u, S_v, S_uu, S_uv, S_vv at N coordinate pairs."""
        uu = np.atleast_1d(np.asarray(u, dtype=float))
        vv = np.atleast_1d(np.asarray(v, dtype=float))
        out = np.empty((6, uu.shape[0], 3))
        for i in range(uu.shape[0]):
            out[:, i, :] = self._evaluate(float(uu[i]), float(vv[i]))
        return out

    def derivatives_at(self, u: float, v: float) -> tuple[Vec3, Vec3, Vec3, Vec3, Vec3, Vec3]:
        """:meth:`derivatives` at one (u, v), as tuples (the hot path).

        The last few (u, v) are remembered: a path at rest (its start, its end) asks for the
        same point three times a step, every step, and the ray march gives the same bits for
        the same (u, v) whatever was evaluated before, so a remembered answer is the answer."""
        key = (u, v)
        known = self._recent.get(key)
        if known is not None:
            return known
        s = self._kernel(self._coef, self._params, u, v)
        if s != s:  # NaN: no point of the part on this ray
            raise self._miss(u, v)
        # one flat list unpacked into tuples: a third of the cost of six rows' tuple()
        x, y, z, xu, yu, zu, xv, yv, zv, a, b, c, d, e, f, g, h, k = self._flat.tolist()
        result = ((x, y, z), (xu, yu, zu), (xv, yv, zv), (a, b, c), (d, e, f), (g, h, k))
        if len(self._recent) >= _RECENT:
            self._recent.clear()
        self._recent[key] = result
        return result

    def coordinates(self, p: ArrayLike) -> tuple[float, float]:
        """(u, v) of a point p (3,) [m]: its coordinates in the plane, or (θ, h) about the axis."""
        frame = self._frame
        w = np.asarray(p, dtype=float) - frame[0]
        if self._mode == 0:
            return float(w @ frame[1]), float(w @ frame[2])
        return math.atan2(float(w @ frame[2]), float(w @ frame[1])), float(w @ frame[3])

    def to_dict(self) -> dict[str, Any]:
        """The chart's settings (``{}``: they are the surface's ``chart`` key)."""
        return {}

"""A path through waypoints on a surface: a C² spline in the surface's coordinates, traversed
at a given speed, from rest to rest.

Construction (:class:`WaypointPath`):

1. The points, in world coordinates (``frame="world"``: each is projected onto the surface,
   its closest point, and the projection distance kept; a periodic coordinate, the cylinder's
   angle or the sphere's longitude, is taken the shorter way round from the previous point) or
   in the surface's own coordinates (``frame="surface"``, see :mod:`.charts`: used as given, so
   an angle may wind past 2π).
2. The natural cubic spline γ(σ) through them in (u, v) (:func:`.piecewise.natural_cubic_spline`)
   with knots σ_i spaced by the lengths on the surface of the straight lines in (u, v) between
   consecutive points (chord-length knots: on a plane the chords themselves, on a cylinder the
   helices between the points).
3. Traversed by arc length (:mod:`.arc_length`) under the :class:`.surface_path.TimeLaw`: rest
   at t = 0, a C² ramp up to ``speed`` over ``ramp`` seconds, cruise at exactly ``speed`` (to
   the 1e-8 of the arc-length map), a ramp down to rest at the last point, which is then held.

So the path lies on the surface by construction and passes waypoint i at
``junction_times[i]``: in the cruise, one waypoint to the next takes the arc length of the
spline between them divided by ``speed``.

Why rest to rest: an arm starts at rest, so ṗ_d(0) = 0 starts without a velocity error,
and a path that stops with p̈_d = 0 can be held for any ``sim.duration`` beyond its end
while staying C² and on the surface.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force import _checks as checks
from hybrid_force.errors import PathError, RunWarning, SurfaceError
from hybrid_force.geometry.arc_length import piece_lengths
from hybrid_force.geometry.charts import SurfaceChart, chart_for
from hybrid_force.geometry.paths import register_path
from hybrid_force.geometry.piecewise import PiecewiseCurve, line_piece, natural_cubic_spline
from hybrid_force.geometry.surface_base import MAX_LENGTH
from hybrid_force.geometry.surface_path import DEFAULT_RAMP, SurfacePath, one_of, positive
from hybrid_force.schema import param

__all__ = ["DEFAULT_PROJECTION_TOL", "MAX_WAYPOINTS", "REPEATED_TOL", "WaypointPath"]

MAX_WAYPOINTS = 1000
"""The most waypoints a path may have (docs/scenarios.md): each costs about 2 ms to build
(its spline piece and arc-length map), so 1000 take 2 s; a 1 MiB scenario could list 40,000."""

DEFAULT_PROJECTION_TOL = 1e-3
"""A world waypoint farther than this [m] from its surface is projected with a RunWarning."""
REPEATED_TOL = 1e-9
"""Two consecutive waypoints closer than this [m] on the surface are the same point (refused)."""


@dataclass(frozen=True)
class WaypointParameters:
    """The parameters of a waypoint path (the scenario's ``[trajectory] type = "waypoints"``)."""

    points: tuple[tuple[float, ...], ...] = param(
        unit="m or surface coordinates", doc="[[x, y, z], ...] (world) or [[u, v], ...] (surface)"
    )
    speed: float = param(unit="m/s", minimum=0.0, strict=True, doc="cruise speed")
    frame: Literal["world", "surface"] = param("world", doc="what the points are")
    surface: int = param(0, minimum=0, doc="index of the [[surfaces]] table it lies on")
    ramp: float = param(
        DEFAULT_RAMP, unit="s", minimum=0.0, strict=True, doc="start and stop ramps"
    )
    u_axis: tuple[float, float, float] | None = param(None, doc="a plane chart's u direction")
    projection_tol: float = param(
        DEFAULT_PROJECTION_TOL,
        unit="m",
        minimum=0.0,
        strict=True,
        acts_when=("frame", "world"),
        doc="a world point farther from the surface is projected with a warning",
    )


@register_path
class WaypointPath(SurfacePath):
    """Waypoints on a built-in surface joined by a C² spline (see the module doc).

    Args:
        surface: a Cylinder, Sphere or Plane (a FunctionSurface has no coordinates).
        points: (n, 3) world points [m] (``frame="world"``) or (n, 2) surface coordinates
            (``frame="surface"``: cylinder (angle [rad], height [m]), sphere (latitude,
            longitude) [rad], plane (u, v) [m]); n ≥ 2, no two consecutive points the same.
        speed: the cruise speed [m/s] > 0.
        frame: ``"world"`` or ``"surface"``.
        ramp: duration [s] > 0 of the start and stop ramps.
        u_axis: (3,) the u direction of a plane's coordinates (:class:`.charts.PlaneChart`).
        projection_tol: [m] > 0; a world point farther from the surface is projected with a
            :class:`~hybrid_force.errors.RunWarning`.

    Raises:
        PathError: bad values, naming the parameter (its ``key``), e.g. fewer than two
            points, repeated consecutive points, speed ≤ 0, a world point whose projection is
            undefined (on a cylinder's axis, at a sphere's centre), ``frame="surface"`` or
            ``"world"`` on a surface without a chart.

    Attributes:
        projection_distances: (n,) [m] how far each world point was from the surface
            (None for ``frame="surface"``).
        coordinates: (n, 2) the waypoints in surface coordinates.
    """

    TYPE: ClassVar[str] = "waypoints"
    PARAMS: ClassVar[type] = WaypointParameters
    REQUIRED = ("points", "speed")
    OPTIONAL = ("frame", "ramp", "u_axis", "projection_tol")
    DERIVED = ("projection_distances", *SurfacePath.DERIVED)

    def __init__(
        self,
        surface: Any,
        points: ArrayLike,
        speed: float,
        *,
        frame: str = WaypointParameters.frame,
        ramp: float = WaypointParameters.ramp,
        u_axis: ArrayLike | None = None,
        projection_tol: float = WaypointParameters.projection_tol,
    ) -> None:
        owner = "WaypointPath"
        one_of(owner, "frame", frame, ("world", "surface"))
        cruise = positive(owner, "speed", speed, "m/s")
        ramp_time = positive(owner, "ramp", ramp, "s")
        tol = positive(owner, "projection_tol", projection_tol, "m")
        chart = chart_for(surface, u_axis)
        given = _point_array(points, 3 if frame == "world" else 2, frame)
        if len(given) > MAX_WAYPOINTS:
            raise PathError(
                f"{owner}.points: {len(given)} waypoints, more than the {MAX_WAYPOINTS} a path "
                "may have (MAX_WAYPOINTS): fewer points, or a coarser spacing between them",
                key="points",
                value=f"<{len(given)} points>",
            )
        if frame == "world":
            coordinates, distances = _project(chart, given, points)
        else:
            coordinates, distances = given, None
        curve = _chord_length_spline(chart, coordinates, points)
        super().__init__(chart, curve, cruise, ramp_time)
        self.frame, self.points, self.speed, self.ramp = frame, given, cruise, ramp_time
        self.projection_tol = tol
        self.coordinates = coordinates
        self.projection_distances = distances
        params = {"points": given.tolist(), "speed": cruise, "frame": frame, "ramp": ramp_time}
        self._record({**params, "projection_tol": tol}, u_axis)
        if distances is not None and float(distances.max()) > tol:
            i = int(np.argmax(distances))
            warnings.warn(
                RunWarning(
                    f"{owner}: points[{i}] = {given[i].tolist()} is {distances[i]:.3g} m from "
                    f"{surface!r} (more than projection_tol = {tol:g} m); the path passes its "
                    f"closest point on the surface instead"
                ),
                stacklevel=2,
            )

    def _derived(self) -> dict[str, Any]:
        """``projection_distances`` [m] of world points, with the length and the timing."""
        out = super()._derived()
        if self.projection_distances is not None:
            out["projection_distances"] = self.projection_distances.tolist()
        return out


def _point_array(points: ArrayLike, width: int, frame: str) -> np.ndarray:
    what = "3 world coordinates [x, y, z]" if width == 3 else "2 surface coordinates [u, v]"
    valid = f'a list of at least 2 points of {what} (frame = "{frame}")'
    try:
        array = checks.array(points, "WaypointPath.points", PathError, valid=valid)
    except PathError as exc:
        raise PathError(str(exc), key="points", value=points) from None
    if array.ndim != 2 or array.shape[1] != width or array.shape[0] < 2:
        raise PathError(
            f"WaypointPath.points must be {valid}, got shape {array.shape}",
            key="points",
            value=points,
        )
    if float(np.abs(array).max()) > MAX_LENGTH:  # m or rad: squares of distances stay finite
        i = int(np.argmax(np.abs(array).max(axis=1)))
        raise PathError(
            f"WaypointPath.points[{i}] = {array[i].tolist()} is beyond MAX_LENGTH = {MAX_LENGTH:g}",
            key="points",
            value=points,
        )
    array.setflags(write=False)
    return array


def _project(
    chart: SurfaceChart, points: np.ndarray, given: object
) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) surface coordinates of the points' closest points, (n,) distances [m]."""
    surface = chart.surface
    coordinates = np.empty((points.shape[0], 2))
    distances = np.empty(points.shape[0])
    for i, p in enumerate(points):
        try:
            foot = surface.closest_point(p)
        except SurfaceError as exc:
            raise PathError(
                f"WaypointPath.points[{i}] = {p.tolist()}: its closest point on the surface is "
                f"undefined ({' '.join(str(exc).split())}); move the point off it",
                key="points",
                value=given,
            ) from None
        distances[i] = float(np.linalg.norm(p - foot))
        uv = chart.coordinates(foot)
        coordinates[i] = (
            uv if i == 0 else chart.unwrap(uv, (coordinates[i - 1, 0], coordinates[i - 1, 1]))
        )
    coordinates.setflags(write=False)
    return coordinates, distances


def _chord_length_spline(chart: SurfaceChart, uv: np.ndarray, given: object) -> PiecewiseCurve:
    """The natural spline through uv with knots spaced by the surface lengths of the straight
    (u, v) lines between the points; refuses two consecutive points that are the same."""
    steps = np.diff(uv, axis=0)
    straight = PiecewiseCurve.join(
        [1.0] * steps.shape[0], [line_piece(a, d) for a, d in zip(uv[:-1], steps, strict=True)]
    )
    lengths = piece_lengths(chart, straight)
    for i, length in enumerate(lengths):
        if not length >= REPEATED_TOL:
            raise PathError(
                f"WaypointPath.points[{i}] and points[{i + 1}] are the same point on the surface "
                f"({length:.3g} m apart, surface coordinates {uv[i].tolist()} and "
                f"{uv[i + 1].tolist()}); remove one of them",
                key="points",
                value=given,
            )
    return natural_cubic_spline(np.concatenate(([0.0], np.cumsum(lengths))), uv)

"""A raster: back-and-forth passes covering a rectangle of a surface's coordinates, joined by
turns that keep the path C², traversed at a given speed from rest to rest.

Construction (:class:`RasterPath`), in the surface coordinates (u, v) of :mod:`.charts`:

* The rectangle [u0, u0 + Lu] × [v0, v0 + Lv] (``origin`` = [u0, v0], ``size`` = [Lu, Lv]).
  The passes run along ``direction`` (``"u"``: along u, stepping in v; ``"v"``: the other way),
  the first from the origin forwards, the next back, and so on. There are
  n = ⌈L_across / spacing⌉ + 1 passes, evenly spaced L_across / (n − 1) ≤ ``spacing`` apart, so
  the first and the last lie on the rectangle's edges.
* Each pass is a straight line in (u, v): on the built-in charts a coordinate line (a circle or
  a line of the cylinder, a parallel or a meridian of the sphere, a line of the plane).
* Between two passes a turn: the quintic blend (:func:`.piecewise.blend_piece`) from the end
  of one pass to the start of the next, matching position, first and second derivative (0) at
  both ends, so γ, and with it p, ṗ, p̈, are continuous at every junction: a semicircle would
  be only C¹ (its curvature, the acceleration ‖ṗ‖²/ρ, would jump on and off). The turn keeps
  the pass's direction at its ends, so it swings beyond the rectangle's edge. Its parameter
  length L is the shortest for which the blend's own parametrisation never moves faster on the
  surface than the passes' (‖dS/dσ‖ ≤ 1, found by iteration from the chord): a longer blend
  swings out farther, a shorter one turns more sharply. On a plane, by hand, L = 1.875 × the
  pass spacing w (the blend's speed peaks at 1.875 w / L half way) and the turn swings
  0.3125 L = 0.586 w beyond the edge.
* That bound needs the passes' surface speed constant along them, as on the built-in charts'
  coordinate lines (checked on every pass, :func:`_uniform_along`). Where it varies (an
  ellipsoid's meridians, a triaxial ellipsoid's parallels, a projection over a curved part)
  the speed at a pass's end is no longer 1 and, where the speed grows beyond the edge, no L
  keeps the blend below it; there the turn's L makes its speed half way equal to the speed a
  pass would have at that point (:func:`_metric_turn`: on a plane the same L). The passes
  stay coordinate lines, and the path C² and at ``speed`` (the arc-length map).
* Traversed by arc length (:mod:`.arc_length`) under the time law
  (:class:`.surface_path.TimeLaw`): rest at t = 0 at the origin, ramp up, cruise at ``speed``
  over passes and turns alike, ramp down, rest at the end of the last pass, held after.

The sphere's passes along a parallel need it away from the poles (there a parallel has no
length): a rectangle reaching latitude ±π/2 with ``direction = "v"`` is refused.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force import _checks as checks
from hybrid_force.errors import PathError
from hybrid_force.geometry.arc_length import piece_lengths, surface_speeds
from hybrid_force.geometry.charts import SurfaceChart, chart_for
from hybrid_force.geometry.paths import register_path
from hybrid_force.geometry.piecewise import PiecewiseCurve, blend_piece, line_piece
from hybrid_force.geometry.surface_base import MAX_LENGTH
from hybrid_force.geometry.surface_path import DEFAULT_RAMP, SurfacePath, one_of, positive
from hybrid_force.schema import param

__all__ = ["MAX_PASSES", "RasterPath"]

MAX_PASSES = 1000
"""The most passes a raster may have (docs/scenarios.md): each pass and turn costs a few ms to
build, and a spacing tiny against the size (1e-5 across 0.2) would run for minutes first."""

_TURN_SAMPLES = 2001
"""Samples of ‖dS/dσ‖ along a turn at which its maximum is taken."""
_TURN_RTOL = 1e-12
_MAX_ITERATIONS = 200
_SINGULAR_RTOL = 1e-9
"""A pass whose ‖S_along‖ is below this times the largest pass's is degenerate (a pole)."""
_UNIFORM_SAMPLES = 65
"""Points of each pass at which the constancy of ‖S_along‖ is checked (:func:`_uniform_along`)."""
_UNIFORM_RTOL = 1e-12
"""‖S_along‖ varying less than this, relative, along every pass: the passes' speed is constant."""


@dataclass(frozen=True)
class RasterParameters:
    """The parameters of a raster path (the scenario's ``[trajectory] type = "raster"``)."""

    origin: tuple[float, ...] = param(
        unit="surface coordinates", doc="[u0, v0], the corner where the first pass starts"
    )
    size: tuple[float, ...] = param(unit="surface coordinates", doc="[Lu, Lv] > 0, the extent")
    spacing: float = param(
        unit="surface coordinate", minimum=0.0, strict=True, doc="largest pass spacing"
    )
    speed: float = param(unit="m/s", minimum=0.0, strict=True, doc="cruise speed")
    direction: Literal["u", "v"] = param("u", doc="the coordinate the passes run along")
    surface: int = param(0, minimum=0, doc="index of the [[surfaces]] table it lies on")
    ramp: float = param(
        DEFAULT_RAMP, unit="s", minimum=0.0, strict=True, doc="start and stop ramps"
    )
    u_axis: tuple[float, float, float] | None = param(None, doc="a plane chart's u direction")


@register_path
class RasterPath(SurfacePath):
    """Back-and-forth coverage of a coordinate rectangle of a built-in surface (module doc).

    Args:
        surface: a Cylinder, Sphere or Plane.
        origin: (2,) [u0, v0] the corner where the first pass starts [surface coordinates].
        size: (2,) [Lu, Lv] > 0, the rectangle's extent in u and v.
        spacing: > 0, the largest distance between two passes, in the coordinate across them
            (≤ the rectangle's extent across them).
        speed: the cruise speed [m/s] > 0.
        direction: ``"u"`` (passes along u) or ``"v"``.
        ramp: duration [s] > 0 of the start and stop ramps.
        u_axis: (3,) the u direction of a plane's coordinates (:class:`.charts.PlaneChart`).

    Raises:
        PathError: bad values, naming the parameter (its ``key``).

    Attributes:
        passes: the number of passes.
        pass_spacing: their spacing, L_across / (passes − 1) ≤ spacing.
        turn_lengths: (passes − 1,) the σ-length [m] of each turn.
    """

    TYPE: ClassVar[str] = "raster"
    PARAMS: ClassVar[type] = RasterParameters
    REQUIRED = ("origin", "size", "spacing", "speed")
    OPTIONAL = ("direction", "ramp", "u_axis")
    DERIVED = ("passes", "pass_spacing", *SurfacePath.DERIVED)

    def __init__(
        self,
        surface: Any,
        origin: ArrayLike,
        size: ArrayLike,
        spacing: float,
        speed: float,
        *,
        direction: str = RasterParameters.direction,
        ramp: float = RasterParameters.ramp,
        u_axis: ArrayLike | None = None,
    ) -> None:
        owner = "RasterPath"
        one_of(owner, "direction", direction, ("u", "v"))
        start = _pair(owner, "origin", origin, positive_values=False)
        extent = _pair(owner, "size", size, positive_values=True)
        step = positive(owner, "spacing", spacing, "surface coordinate")
        cruise = positive(owner, "speed", speed, "m/s")
        ramp_time = positive(owner, "ramp", ramp, "s")
        chart = chart_for(surface, u_axis)
        along = 0 if direction == "u" else 1
        across = 1 - along
        if step > extent[across]:
            raise PathError(
                f"{owner}.spacing = {step:g} is larger than the rectangle across the passes "
                f"(size[{across}] = {extent[across]:g} {chart.units[across]}, "
                f"{chart.names[across]}): at least two passes must fit",
                key="spacing",
                value=spacing,
            )
        passes_wanted = extent[across] / step - 1e-9  # a float: it may be huge
        if passes_wanted + 1 > MAX_PASSES:
            raise PathError(
                f"{owner}.spacing = {step:g} across size[{across}] = {extent[across]:g} "
                f"{chart.units[across]} makes {math.ceil(passes_wanted) + 1:.6g} passes, more "
                f"than the {MAX_PASSES} a raster may have: spacing must be at least "
                + checks.suggested(
                    extent[across] / (MAX_PASSES - 1),
                    lambda x: extent[across] / x - 1e-9 + 1 <= MAX_PASSES,
                ),
                key="spacing",
                value=spacing,
            )
        passes = max(2, math.ceil(passes_wanted) + 1)
        self.pass_spacing = extent[across] / (passes - 1)
        curve, self.turn_lengths = _raster_curve(
            chart, start, extent, along, passes, self.pass_spacing, given=size
        )
        super().__init__(chart, curve, cruise, ramp_time)
        self.origin, self.size, self.spacing, self.speed = start, extent, step, cruise
        self.direction, self.ramp, self.passes = direction, ramp_time, passes
        given = {"origin": list(start), "size": list(extent), "spacing": step, "speed": cruise}
        self._record({**given, "direction": direction, "ramp": ramp_time}, u_axis)

    def _derived(self) -> dict[str, Any]:
        """``passes``, ``pass_spacing``, with the length and the timing."""
        return {"passes": self.passes, "pass_spacing": self.pass_spacing, **super()._derived()}


def _pair(owner: str, name: str, value: object, positive_values: bool) -> tuple[float, float]:
    valid = "2 finite numbers > 0" if positive_values else "2 finite numbers [u, v]"
    try:
        array = checks.array(value, f"{owner}.{name}", PathError, valid=valid)
    except PathError as exc:
        raise PathError(str(exc), key=name, value=value) from None
    if array.shape != (2,) or (positive_values and not bool(np.all(array > 0.0))):
        raise PathError(
            f"{owner}.{name} must be {valid}, got {checks.shown(value)}", key=name, value=value
        )
    if float(np.abs(array).max()) > MAX_LENGTH:  # coordinates in m or rad: far beyond any use
        raise PathError(
            f"{owner}.{name} = {checks.shown(value)} is beyond MAX_LENGTH = {MAX_LENGTH:g}",
            key=name,
            value=value,
        )
    return float(array[0]), float(array[1])


def _raster_curve(
    chart: SurfaceChart,
    origin: tuple[float, float],
    size: tuple[float, float],
    along: int,
    passes: int,
    spacing: float,
    given: object,
) -> tuple[PiecewiseCurve, np.ndarray]:
    """The passes and turns as one curve, and the turns' σ-lengths."""
    unit = np.zeros(2)
    unit[along] = 1.0
    starts, slopes, scales = [], [], []
    for k in range(passes):
        start = np.array(origin, dtype=float)
        start[1 - along] += k * spacing
        sign = 1.0 if k % 2 == 0 else -1.0
        if sign < 0.0:
            start[along] += size[along]
        derivatives = chart.derivatives(start[0], start[1])
        scales.append(float(np.linalg.norm(derivatives[1 + along, 0])))
        starts.append(start)
        slopes.append(sign * unit)
    largest = max(scales)
    for k, scale in enumerate(scales):
        if not scale > _SINGULAR_RTOL * largest:
            raise PathError(
                f"RasterPath: pass {k} at {chart.names[1 - along]} = "
                f"{starts[k][1 - along]:.6g} has no length on the surface (a pole of the chart): "
                "keep the rectangle off it",
                key="size",
                value=given,
            )
    uniform = _uniform_along(chart, starts, slopes, size[along], along)
    lengths, pieces, turns = [], [], []
    for k in range(passes):
        slope = slopes[k] / scales[k]  # unit speed on the surface at the pass's start
        lengths.append(scales[k] * size[along])
        pieces.append(line_piece(starts[k], slope))
        if k + 1 < passes:
            end = starts[k] + slopes[k] * size[along]
            d1 = slopes[k + 1] / scales[k + 1]
            if uniform:
                turn_length, turn = _turn(chart, end, slope, starts[k + 1], d1)
            else:
                turn_length, turn = _metric_turn(chart, end, slope, starts[k + 1], d1, along)
            lengths.append(turn_length)
            pieces.append(turn)
            turns.append(turn_length)
    return PiecewiseCurve.join(lengths, pieces), np.array(turns)


def _uniform_along(
    chart: SurfaceChart, starts: list[np.ndarray], slopes: list[np.ndarray], size: float, along: int
) -> bool:
    """Whether ‖S_along‖ is constant along every pass (to :data:`_UNIFORM_RTOL`): the built-in
    charts' coordinate lines (plane, cylinder, sphere, a spheroid's parallels). Then σ moves
    at unit surface speed all along a pass, and a turn is bounded by that speed
    (:func:`_turn`); otherwise by the speed of the passes where it goes (:func:`_metric_turn`).
    """
    x = np.linspace(0.0, size, _UNIFORM_SAMPLES)[:, None]
    points = np.concatenate(
        [start + slope * x for start, slope in zip(starts, slopes, strict=True)]
    )
    speeds = np.linalg.norm(chart.derivatives(points[:, 0], points[:, 1])[1 + along], axis=1)
    per_pass = speeds.reshape(len(starts), _UNIFORM_SAMPLES)
    spread = per_pass.max(axis=1) - per_pass.min(axis=1)
    return bool(np.all(spread <= _UNIFORM_RTOL * per_pass.max(axis=1)))


def _turn(
    chart: SurfaceChart, p0: np.ndarray, d0: np.ndarray, p1: np.ndarray, d1: np.ndarray
) -> tuple[float, np.ndarray]:
    """The shortest blend from (p0, d0) to (p1, d1) with ‖dS/dσ‖ ≤ 1: (σ-length, piece).

    Iterates L ← L · max‖dS/dσ‖ from the straight chord in (u, v): the speed at both ends is 1
    and a longer blend is slower in its middle, so L only grows, to where the maximum is 1.
    """
    length = _chord_length(chart, p0, p1)
    s = np.linspace(0.0, 1.0, _TURN_SAMPLES)
    for _ in range(_MAX_ITERATIONS):
        piece = blend_piece(p0, d0, p1, d1, length)
        curve = PiecewiseCurve.join([length], [piece])
        fastest = float(np.max(surface_speeds(chart, curve, 0, s * length)))
        if fastest <= 1.0 + _TURN_RTOL:
            break
        length *= fastest
    return length, blend_piece(p0, d0, p1, d1, length)


def _chord_length(chart: SurfaceChart, p0: np.ndarray, p1: np.ndarray) -> float:
    """The surface length [m] of the straight chord from p0 to p1 in (u, v)."""
    chord = PiecewiseCurve.join([1.0], [line_piece(p0, p1 - p0)])
    return float(piece_lengths(chart, chord)[0])


def _metric_turn(
    chart: SurfaceChart,
    p0: np.ndarray,
    d0: np.ndarray,
    p1: np.ndarray,
    d1: np.ndarray,
    along: int,
) -> tuple[float, np.ndarray]:
    """The blend from (p0, d0) to (p1, d1) where the surface speed of the passes varies:
    (σ-length, piece).

    Its length L makes ‖dS/dσ‖ half way equal to the speed a pass would have there,
    ‖S_along(γ(½))‖ (|d0| + |d1|) / 2: on a plane that is the bound of :func:`_turn`
    (L = 1.875 w, the blend's speed peaking half way), and it stays defined where the speed
    along the passes grows beyond their ends, where no L keeps ‖dS/dσ‖ ≤ 1 (the speed at the
    ends is fixed, and beside them it is the pass's own, larger one). The root of
    ρ(L) = ‖dS/dσ‖ / reference − 1 is bracketed from the chord by doubling or halving L (the
    across part of the speed falls as 1/L), then found by regula falsi (Illinois) in log L:
    the fixed point L ← L (ρ + 1) alone can oscillate where the reference changes as fast
    as the swing grows.

    Raises:
        PathError: no bracket or no root within ``_MAX_ITERATIONS`` (a chart degenerate
            about the turn).
    """
    mean = 0.5 * (float(np.linalg.norm(d0)) + float(np.linalg.norm(d1)))
    half = np.array([0.5])

    def excess(x: float) -> float:
        """ρ(L) at L = e^x."""
        length = math.exp(x)
        curve = PiecewiseCurve.join([length], [blend_piece(p0, d0, p1, d1, length)])
        g = curve.sample_piece(0, half * length)[0]
        reference = float(np.linalg.norm(chart.derivatives(g[:, 0], g[:, 1])[1 + along, 0]))
        return float(surface_speeds(chart, curve, 0, half * length)[0]) / (reference * mean) - 1

    x0 = math.log(_chord_length(chart, p0, p1))
    f0 = excess(x0)
    step = math.log(2.0) if f0 > 0.0 else -math.log(2.0)
    x1, f1 = x0, f0
    for _ in range(_MAX_ITERATIONS):  # the bracket: ρ changes sign between x0 and x1
        if not math.isfinite(f1) or f1 == 0.0 or (f1 > 0.0) != (f0 > 0.0):
            break
        x0, f0 = x1, f1
        x1 = x0 + step
        f1 = excess(x1)
    for _ in range(_MAX_ITERATIONS):
        if not (math.isfinite(f0) and math.isfinite(f1)):
            break
        if abs(f1) <= _TURN_RTOL or f1 == 0.0:
            length = math.exp(x1)
            return length, blend_piece(p0, d0, p1, d1, length)
        if (f0 > 0.0) == (f1 > 0.0):
            break
        x = x1 - f1 * (x1 - x0) / (f1 - f0)
        f = excess(x)
        if (f > 0.0) == (f1 > 0.0):
            f0 *= 0.5  # Illinois: the end kept is weighted down
        else:
            x0, f0 = x1, f1
        x1, f1 = x, f
    raise PathError(
        f"RasterPath: the turn from {chart.names[0]}, {chart.names[1]} = {p0.tolist()} found "
        "no length on this chart (the surface speed about it degenerates): move the "
        "rectangle or change its spacing",
        key="spacing",
        value=float(np.max(np.abs(p1 - p0))),
    )

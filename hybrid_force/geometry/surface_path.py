"""A desired path on a surface: a curve in the surface's coordinates, traversed by a time law.

p_d(t) = S(γ(σ(t))): S the surface's chart (:mod:`.charts`), γ(σ) a C² piecewise polynomial
curve in (u, v) (:mod:`.piecewise`) whose parameter σ is arc length on the surface [m] at its
junctions, and σ(t) the rest-to-rest :class:`TimeLaw`. The path lies on the surface by
construction and its derivatives follow by the chain rule::

    p' = S_u u' + S_v v',    p'' = S_uu u'² + 2 S_uv u' v' + S_vv v'² + S_u u'' + S_v v'',
    ṗ = p' σ̇,               p̈ = p'' σ̇² + p' σ̈          (' = d/dσ, ˙ = d/dt).

γ ∈ C² and σ ∈ C² make p, ṗ, p̈ continuous for all t. The waypoint path
(:mod:`.waypoints`) and the raster (:mod:`.raster`) are built on :class:`SurfacePath`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from hybrid_force import _checks as checks
from hybrid_force.errors import BadInputError, PathParameterError, did_you_mean
from hybrid_force.geometry.charts import SurfaceChart
from hybrid_force.geometry.paths import Path
from hybrid_force.geometry.piecewise import PiecewiseCurve

__all__ = [
    "DEFAULT_RAMP",
    "SurfacePath",
    "TimeLaw",
    "piece_lengths",
    "positive",
    "surface_speeds",
]

DEFAULT_RAMP = 0.5
"""Default duration [s] of the start and stop ramps of a :class:`TimeLaw`."""

_GAUSS_NODES, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(16)
_SUBDIVISIONS = 8
"""Each piece is integrated as 8 sub-intervals of 16 Gauss–Legendre nodes."""


@dataclass(frozen=True)
class TimeLaw:
    """σ(t) from 0 to ``length`` starting and ending at rest, C² in t.

    With x = t / T_r (T_r = ``ramp``) and the cruise rate c = min(``speed``, length / T_r):

    * t ≤ 0: σ = 0; t ≥ duration: σ = length; σ̇ = σ̈ = 0 (the path holds its ends);
    * start ramp, 0 ≤ t ≤ T_r: σ̇ = c (3x² − 2x³), σ = c T_r (x³ − x⁴/2),
      σ̈ = (c / T_r) 6x(1 − x): σ̇ and σ̈ are 0 at t = 0 and σ̈ is 0 again at t = T_r;
    * cruise: σ̇ = c; the stop ramp mirrors the start ramp.

    Each ramp covers c T_r / 2, so duration = length / c + T_r. A path shorter than
    ``speed`` · T_r never reaches ``speed``: its peak rate is length / T_r (no cruise).
    The peak of |σ̈| is 1.5 c / T_r.

    Attributes:
        length: σ at the end [m], > 0.
        speed: the cruise rate [m/s], > 0.
        ramp: T_r [s], > 0.
    """

    length: float
    speed: float
    ramp: float = DEFAULT_RAMP
    rate: float = field(init=False)
    duration: float = field(init=False)

    def __post_init__(self) -> None:
        for name, unit in (("length", "m"), ("speed", "m/s"), ("ramp", "s")):
            value = checks.number(
                getattr(self, name), name, PathParameterError, minimum=0.0, strict=True, unit=unit
            )
            object.__setattr__(self, name, value)
        rate = min(self.speed, self.length / self.ramp)
        object.__setattr__(self, "rate", rate)
        object.__setattr__(self, "duration", self.length / rate + self.ramp)

    def _ramp(self, t: float) -> tuple[float, float, float]:
        x = t / self.ramp
        c = self.rate
        return (
            c * self.ramp * x * x * x * (1.0 - 0.5 * x),
            c * x * x * (3.0 - 2.0 * x),
            6.0 * c / self.ramp * x * (1.0 - x),
        )

    def sample(self, t: float) -> tuple[float, float, float]:
        """(σ [m], σ̇ [m/s], σ̈ [m/s²]) at t [s]."""
        if t <= 0.0:
            return 0.0, 0.0, 0.0
        if t >= self.duration:
            return self.length, 0.0, 0.0
        if t < self.ramp:
            return self._ramp(t)
        if t > self.duration - self.ramp:
            s, sd, sdd = self._ramp(self.duration - t)
            return self.length - s, sd, -sdd
        return self.rate * (0.5 * self.ramp + t - self.ramp), self.rate, 0.0

    def time_at(self, sigma: float) -> float:
        """The t [s] at which σ(t) = sigma (0 ≤ sigma ≤ length); bisection in the ramps."""
        if sigma <= 0.0:
            return 0.0
        if sigma >= self.length:
            return self.duration
        edge = 0.5 * self.rate * self.ramp
        if edge <= sigma <= self.length - edge:
            return self.ramp + (sigma - edge) / self.rate
        mirrored = sigma > self.length - edge
        target = self.length - sigma if mirrored else sigma
        lo, hi = 0.0, self.ramp
        for _ in range(200):  # σ is increasing on the ramp
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                break
            if self._ramp(mid)[0] < target:
                lo = mid
            else:
                hi = mid
        t = 0.5 * (lo + hi)
        return self.duration - t if mirrored else t


def surface_speeds(chart: SurfaceChart, curve: PiecewiseCurve, k: int, x: np.ndarray) -> np.ndarray:
    """‖dS(γ(σ))/dσ‖ on piece k at local parameters x (N,): (N,) [m per unit of σ]."""
    g, g1 = curve.sample_piece(k, x)
    d = chart.derivatives(g[:, 0], g[:, 1])
    return np.linalg.norm(d[1] * g1[:, :1] + d[2] * g1[:, 1:], axis=1)


def piece_lengths(chart: SurfaceChart, curve: PiecewiseCurve) -> np.ndarray:
    """Arc length on the surface [m] of each piece of ``curve``: (m,).

    ∫‖S_u u' + S_v v'‖ dσ by Gauss–Legendre quadrature (16 nodes on each of 8 equal
    sub-intervals of a piece): exact to rounding for the smooth integrands of the built-in
    charts unless the curve nearly stops within a piece.
    """
    cells = (np.arange(_SUBDIVISIONS)[:, None] + 0.5 * (_GAUSS_NODES + 1.0)) / _SUBDIVISIONS
    weights = np.tile(_GAUSS_WEIGHTS, _SUBDIVISIONS) / (2.0 * _SUBDIVISIONS)
    out = np.empty(curve.coeffs.shape[0])
    for k, h in enumerate(np.diff(curve.breaks)):
        out[k] = h * float(weights @ surface_speeds(chart, curve, k, h * cells.ravel()))
    return out


class SurfacePath(Path):
    """p_d(t) = S(γ(σ(t))) (see the module doc); subclasses build the curve and the time law.

    Args:
        chart: the surface's chart.
        curve: γ(σ) in the chart's coordinates, C², its parameter arc length at the junctions.
        law: σ(t), with ``law.length`` = ``curve.length``.
    """

    TYPE: ClassVar[str]
    REQUIRED: ClassVar[tuple[str, ...]]
    """The keys of :meth:`to_dict` that the constructor requires (after ``surface``)."""
    OPTIONAL: ClassVar[tuple[str, ...]]
    """Its optional keys (keyword arguments)."""
    DERIVED: ClassVar[tuple[str, ...]] = ("duration", "junction_times")
    """Keys of :meth:`to_dict` computed from the others (ignored by :meth:`from_dict`)."""

    def __init__(self, chart: SurfaceChart, curve: PiecewiseCurve, law: TimeLaw) -> None:
        self.chart, self.curve, self.law = chart, curve, law

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SurfacePath:
        """The path of :meth:`to_dict`'s output (``d["surface"]`` a built-in surface's dict).

        Raises:
            PathParameterError: a missing or unknown key, or a bad value.
        """
        from hybrid_force.geometry.surfaces import surface_from_dict

        params = {k: v for k, v in d.items() if k not in ("type", *cls.DERIVED)}
        valid = ("surface", *cls.REQUIRED, *cls.OPTIONAL)
        for key in params:
            if key not in valid:
                raise PathParameterError(
                    f"path.{key} is not a parameter of a {cls.TYPE} path"
                    f"{did_you_mean(str(key), valid)}; valid keys: {['type', *valid]}"
                )
        missing = [k for k in ("surface", *cls.REQUIRED) if k not in params]
        if missing:
            raise PathParameterError(
                f"{cls.TYPE} path is missing {missing}; required keys: "
                f"{['surface', *cls.REQUIRED]}, optional: {list(cls.OPTIONAL)}"
            )
        try:
            surface = surface_from_dict(params.pop("surface"))
        except BadInputError as exc:
            raise PathParameterError(f"path.surface: {exc}") from None
        required = [params.pop(k) for k in cls.REQUIRED]
        build: Any = cls  # each subclass's constructor: (surface, *required, **optional)
        return build(surface, *required, **params)

    @property
    def surface(self) -> object:
        """The surface the path lies on."""
        return self.chart.surface

    @property
    def duration(self) -> float:
        """The time [s] at which the path comes to rest at its end (then holds it)."""
        return self.law.duration

    @property
    def junction_times(self) -> np.ndarray:
        """(m + 1,) the times [s] at which the path passes the curve's junctions (waypoints,
        or the ends of passes and turns)."""
        return np.array([self.law.time_at(float(s)) for s in self.curve.breaks])

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p_d (3,) [m], ṗ_d (3,) [m/s], p̈_d (3,) [m/s²]) at t [s], by the chain rule."""
        sigma, rate, accel = self.law.sample(float(t))
        g, g1, g2 = self.curve.evaluate(sigma)
        s, su, sv, suu, suv, svv = self.chart.derivatives(g[0], g[1])[:, 0]
        du, dv = float(g1[0]), float(g1[1])
        first = su * du + sv * dv
        second = suu * (du * du) + suv * (2.0 * du * dv) + svv * (dv * dv)
        second += su * float(g2[0]) + sv * float(g2[1])
        return s, first * rate, second * (rate * rate) + first * accel

    def position(self, t: float) -> np.ndarray:
        """p_d(t) (3,) [m]."""
        g = self.curve.evaluate(self.law.sample(float(t))[0])[0]
        return self.chart.point(float(g[0]), float(g[1]))

    def _timing_dict(self) -> dict[str, object]:
        """The derived timing for ``to_dict`` (ignored when read back)."""
        return {
            "duration": self.duration,
            "junction_times": [round(float(t), 12) for t in self.junction_times],
        }

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(surface={self.surface!r}, length={self.curve.length:.6g} m, "
            f"duration={self.duration:.6g} s)"
        )


def positive(owner: str, name: str, value: object, unit: str) -> float:
    """``value`` as a finite float > 0, or PathParameterError naming ``owner.name`` (its key:
    ``name``)."""
    try:
        return checks.number(
            value, f"{owner}.{name}", PathParameterError, minimum=0.0, strict=True, unit=unit
        )
    except PathParameterError as exc:
        raise PathParameterError(str(exc), key=name, value=value) from None

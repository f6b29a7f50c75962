"""A desired path on a surface: a curve in the surface's coordinates, traversed by a time law.

p_d(t) = S(γ(σ(ℓ(t)))): S the surface's chart (:mod:`.charts`), γ(σ) a C² piecewise polynomial
curve in (u, v) (:mod:`.piecewise`), σ(ℓ) its parameter as a C² function of the arc length ℓ
on the surface (:mod:`.arc_length`), and ℓ(t) the rest-to-rest :class:`TimeLaw`. The path
lies on the surface by construction, moves at ‖ṗ_d‖ = ℓ̇ (the speed of the time law, to the
1e-8 of the arc-length map), and its derivatives follow by the chain rule::

    p' = S_u u' + S_v v',    p'' = S_uu u'² + 2 S_uv u' v' + S_vv v'² + S_u u'' + S_v v''
    dp/dℓ = p' σ_ℓ,          d²p/dℓ² = p'' σ_ℓ² + p' σ_ℓℓ          (' = d/dσ)
    ṗ = dp/dℓ ℓ̇,             p̈ = d²p/dℓ² ℓ̇² + dp/dℓ ℓ̈.

γ, σ(ℓ) and ℓ(t) all C² make p, ṗ, p̈ continuous for all t. The waypoint path
(:mod:`.waypoints`) and the raster (:mod:`.raster`) are built on :class:`SurfacePath`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force import _checks as checks
from hybrid_force.errors import BadInputError, PathError, did_you_mean
from hybrid_force.geometry.arc_length import SUBDIVISIONS, arc_length_map
from hybrid_force.geometry.charts import SurfaceChart, Vec3
from hybrid_force.geometry.paths import Path, path_time
from hybrid_force.geometry.piecewise import PiecewiseCurve
from hybrid_force.geometry.surfaces import surface_from_dict

__all__ = ["DEFAULT_RAMP", "SurfacePath", "TimeLaw", "one_of", "positive"]

_ARC_STEP = 1e-5  # [m] central difference of d²p/dℓ² (direction_jet)

DEFAULT_RAMP = 0.5
"""Default duration [s] of the start and stop ramps of a :class:`TimeLaw`."""


@dataclass(frozen=True)
class TimeLaw:
    """ℓ(t) from 0 to ``length`` starting and ending at rest, C² in t.

    With x = t / T_r (T_r = ``ramp``) and the cruise rate c = min(``speed``, length / T_r):

    * t ≤ 0: ℓ = 0; t ≥ duration: ℓ = length; ℓ̇ = ℓ̈ = 0 (the path holds its ends);
    * start ramp, 0 ≤ t ≤ T_r: ℓ̇ = c (3x² − 2x³), ℓ = c T_r (x³ − x⁴/2),
      ℓ̈ = (c / T_r) 6x(1 − x): ℓ̇ and ℓ̈ are 0 at t = 0 and ℓ̈ is 0 again at t = T_r;
    * cruise: ℓ̇ = c; the stop ramp mirrors the start ramp.

    Each ramp covers c T_r / 2, so duration = length / c + T_r. A path shorter than
    ``speed`` · T_r never reaches ``speed``: its peak rate is length / T_r (no cruise).
    The peak of |ℓ̈| is 1.5 c / T_r.

    Attributes:
        length: ℓ at the end [m], > 0.
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
                getattr(self, name), name, PathError, minimum=0.0, strict=True, unit=unit
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
        """(ℓ [m], ℓ̇ [m/s], ℓ̈ [m/s²]) at t [s]."""
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
        """The t [s] at which ℓ(t) = sigma (0 ≤ sigma ≤ length); bisection in the ramps."""
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
        for _ in range(200):  # ℓ is increasing on the ramp
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                break
            if self._ramp(mid)[0] < target:
                lo = mid
            else:
                hi = mid
        t = 0.5 * (lo + hi)
        return self.duration - t if mirrored else t


class SurfacePath(Path):
    """p_d(t) = S(γ(σ(ℓ(t)))) (see the module doc); subclasses build the curve.

    Args:
        chart: the surface's chart.
        curve: γ(σ) in the chart's coordinates, C².
        speed: the cruise speed [m/s] of the time law.
        ramp: the duration [s] of its start and stop ramps.

    Attributes:
        chart, curve, law: as above; ``law`` is the :class:`TimeLaw` over the curve's length.
        arc: σ(ℓ), the curve's parameter against the arc length (:mod:`.arc_length`).
    """

    TYPE: ClassVar[str]
    REQUIRED: ClassVar[tuple[str, ...]]
    """The keys of :meth:`to_dict` that the constructor requires (after ``surface``)."""
    OPTIONAL: ClassVar[tuple[str, ...]]
    """Its optional keys (keyword arguments)."""
    DERIVED: ClassVar[tuple[str, ...]] = ("length", "duration", "junction_times")
    """Keys of :meth:`to_dict` computed from the others (ignored by :meth:`from_dict`)."""

    def __init__(
        self, chart: SurfaceChart, curve: PiecewiseCurve, speed: float, ramp: float
    ) -> None:
        self.chart, self.curve = chart, curve
        self.arc = arc_length_map(chart, curve)
        self.law = TimeLaw(self.arc.length, speed, ramp)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SurfacePath:
        """The path of :meth:`to_dict`'s output (``d["surface"]`` a built-in surface's dict).

        Raises:
            PathError: a missing or unknown key, or a bad value.
        """

        params = {k: v for k, v in d.items() if k not in ("type", *cls.DERIVED)}
        valid = ("surface", *cls.REQUIRED, *cls.OPTIONAL)
        for key in params:
            if key not in valid:
                raise PathError(
                    f"path.{key} is not a parameter of a {cls.TYPE} path"
                    f"{did_you_mean(str(key), valid)}; valid keys: {['type', *valid]}"
                )
        missing = [k for k in ("surface", *cls.REQUIRED) if k not in params]
        if missing:
            raise PathError(
                f"{cls.TYPE} path is missing {missing}; required keys: "
                f"{['surface', *cls.REQUIRED]}, optional: {list(cls.OPTIONAL)}"
            )
        try:
            surface = surface_from_dict(params.pop("surface"))
        except BadInputError as exc:
            raise PathError(f"path.surface: {exc}") from None
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
        ends = self.arc.breaks[::SUBDIVISIONS]  # ℓ at the curve's breaks
        return np.array([self.law.time_at(float(ell)) for ell in ends])

    def _shape(self, ell: float) -> tuple[Vec3, list[float], list[float]]:
        """(p, dp/dℓ, d²p/dℓ²) at arc length ℓ [m] as floats, by the chain rule (module doc)."""
        (sigma,), (slope,), (bend,) = self.arc.evaluate(ell)
        (u, v), (du, dv), (ddu, ddv) = self.curve.evaluate(sigma)
        s, su, sv, suu, suv, svv = self.chart.derivatives_at(u, v)
        a, c = slope * slope, 2.0 * du * dv
        tangents, curvatures = [], []
        for i in range(3):
            first = su[i] * du + sv[i] * dv  # dp/dσ
            second = suu[i] * du * du + suv[i] * c + svv[i] * dv * dv + su[i] * ddu + sv[i] * ddv
            tangents.append(first * slope)  # dp/dℓ, of unit length
            curvatures.append(second * a + first * bend)
        return s, tangents, curvatures

    def _sample(self, t: float) -> tuple[Vec3, list[float], list[float]]:
        """(p, ṗ, p̈) at t as floats: ṗ = dp/dℓ ℓ̇, p̈ = d²p/dℓ² ℓ̇² + dp/dℓ ℓ̈ (module doc)."""
        ell, rate, accel = self.law.sample(t)
        return self._sample_at(self._shape(ell), rate, accel)

    @staticmethod
    def _sample_at(
        shape: tuple[Vec3, list[float], list[float]], rate: float, accel: float
    ) -> tuple[Vec3, list[float], list[float]]:
        """:meth:`_sample` from the shape at ℓ(t) and ℓ̇, ℓ̈."""
        s, tangent, curvature = shape
        b = rate * rate
        velocity = [tangent[i] * rate for i in range(3)]
        acceleration = [curvature[i] * b + tangent[i] * accel for i in range(3)]
        return s, velocity, acceleration

    def direction_jet(self, t: float) -> np.ndarray:
        """(3, 3) rows T, Ṫ, T̈: the unit tangent T = dp/dℓ at ℓ(t) and its time derivatives.

        Unlike ṗ_d = T ℓ̇, T is defined where the path is at rest (its start and end): the
        direction it leaves in, or arrives from. Ṫ = T' ℓ̇ and T̈ = T'' ℓ̇² + T' ℓ̈ (' = d/dℓ,
        T' = d²p/dℓ² in closed form, T'' its central difference over ±10 µm of arc, one-sided
        at the ends, error ~1e-10 relative on a smooth piece).
        """
        ell, rate, accel = self.law.sample(path_time(self, t))
        return self._direction_at(ell, self._shape(ell), rate, accel)

    def _direction_at(
        self, ell: float, shape: tuple[Vec3, list[float], list[float]], rate: float, accel: float
    ) -> np.ndarray:
        """:meth:`direction_jet` from ℓ(t), the shape there and ℓ̇, ℓ̈."""
        _, tangent, k = shape
        h, length = _ARC_STEP, self.law.length
        lo, hi = max(ell - h, 0.0), min(ell + h, length)
        k_hi, k_lo, span, b = self._shape(hi)[2], self._shape(lo)[2], hi - lo, rate * rate
        bend_rate = [(k_hi[i] - k_lo[i]) / span for i in range(3)]  # T'' = (d³p/dℓ³)
        rows = [k[i] * rate for i in range(3)], [bend_rate[i] * b + k[i] * accel for i in range(3)]
        return np.array([tangent, *rows])

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p_d (3,) [m], ṗ_d (3,) [m/s], p̈_d (3,) [m/s²]) at t [s], by the chain rule."""
        p, v, a = self._sample(path_time(self, t))
        return np.array(p), np.array(v), np.array(a)

    def evaluate_into(self, t: float, p: np.ndarray, v: np.ndarray, a: np.ndarray) -> None:
        """:meth:`evaluate` written into the (3,) arrays p, v, a (hot path)."""
        p[:], v[:], a[:] = self._sample(float(t))

    def evaluate_with_direction_into(self, t: float, sample: np.ndarray, jet: np.ndarray) -> None:
        """:meth:`evaluate` into the rows of sample (3, 3) and :meth:`direction_jet` into jet
        (3, 3), sharing the shape at ℓ(t) (the same numbers as the two calls)."""
        ell, rate, accel = self.law.sample(path_time(self, t))
        shape = self._shape(ell)
        sample[0], sample[1], sample[2] = self._sample_at(shape, rate, accel)
        jet[:] = self._direction_at(ell, shape, rate, accel)

    def position(self, t: float) -> np.ndarray:
        """p_d(t) (3,) [m]."""
        (sigma,), _, _ = self.arc.evaluate(self.law.sample(path_time(self, t))[0])
        (u, v), _, _ = self.curve.evaluate(sigma)
        return np.array(self.chart.derivatives_at(u, v)[0])

    def _record(self, params: dict[str, Any], u_axis: ArrayLike | None) -> None:
        """Keep the parameters :meth:`to_dict` writes, in their checked forms (``u_axis`` as
        given, only when given)."""
        if u_axis is not None:
            params["u_axis"] = np.asarray(u_axis, dtype=float).tolist()
        self._params = params

    def _derived(self) -> dict[str, Any]:
        """Values computed from the parameters that :meth:`to_dict` adds (subclasses extend)."""
        return {
            "length": self.arc.length,
            "duration": self.duration,
            "junction_times": [round(float(t), 12) for t in self.junction_times],
        }

    def to_dict(self) -> dict[str, Any]:
        """``{"type", "surface" (its dict), <the constructor's parameters>, <derived>}``; the
        derived keys (``DERIVED``: ``length`` [m], ``duration`` [s], ``junction_times`` [s],
        ...) are ignored when read back (:meth:`from_dict`)."""
        head = {"type": self.TYPE, "surface": self.chart.surface.to_dict()}
        return {**head, **self._params, **self._derived()}

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(surface={self.surface!r}, length={self.arc.length:.6g} m, "
            f"duration={self.duration:.6g} s)"
        )


def one_of(owner: str, name: str, value: object, choices: tuple[str, ...]) -> str:
    """``value`` if it is one of ``choices``, or PathError naming ``owner.name``."""
    if not isinstance(value, str) or value not in choices:
        shown = " or ".join(repr(c) for c in choices)
        raise PathError(
            f"{owner}.{name} must be {shown}, got {checks.shown(value)}", key=name, value=value
        )
    return value


def positive(owner: str, name: str, value: object, unit: str) -> float:
    """``value`` as a finite float > 0, or PathError naming ``owner.name`` (its key:
    ``name``)."""
    try:
        return checks.number(
            value, f"{owner}.{name}", PathError, minimum=0.0, strict=True, unit=unit
        )
    except PathError as exc:
        raise PathError(str(exc), key=name, value=value) from None

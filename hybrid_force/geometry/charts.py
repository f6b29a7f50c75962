"""Coordinate charts S(u, v) of the built-in surfaces, with their first and second derivatives.

A chart maps two surface coordinates (u, v) to a point S(u, v) (3,) [m] on the surface, so a
curve given in (u, v) lies on the surface by construction, and its world velocity and
acceleration follow by the chain rule. The charts (also the meaning of ``frame = "surface"``
in a scenario's ``[trajectory]``):

* :class:`CylinderChart` – (u, v) = (angle θ [rad], height h [m]):
  S = center + h·a + r (cos θ e1 + sin θ e2), with (e1, e2, a) = ``axis_frame(axis)`` of
  :mod:`.paths`: θ is measured from e1 (world x projected onto the plane ⟂ a) as a helix's
  phase is, h along the axis from the cylinder's ``center``.
* :class:`SphereChart` – (u, v) = (latitude φ [rad], longitude λ [rad]) about world z:
  S = center + r (cos φ cos λ, cos φ sin λ, sin φ); φ = 0 on the equator ⟂ z, λ = 0 towards
  world +x, increasing towards +y. At the poles (cos φ = 0) S_λ = 0: the chart is smooth there,
  but a curve that stays at a pole while λ changes does not move.
* :class:`PlaneChart` – (u, v) [m] along two in-plane unit axes from the plane's ``point``:
  S = point + u·e_u + v·e_v, e_v = n × e_u. By default e_u = ``axis_frame(n)``'s e1 (world x
  projected onto the plane, world y if n ∥ x); an explicit ``u_axis`` is projected onto the plane
  and normalised.

:func:`chart_for` picks the chart registered for a surface's class (:func:`register_chart`, in
the module that defines the chart); a user-defined :class:`FunctionSurface` has none.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable
from typing import Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force import _checks as checks
from hybrid_force.errors import PathError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.paths import axis_frame

__all__ = [
    "CylinderChart",
    "PlaneChart",
    "SphereChart",
    "SurfaceChart",
    "chart_for",
    "register_chart",
]

Vec3 = tuple[float, float, float]
_ZERO: Vec3 = (0.0, 0.0, 0.0)

_PARALLEL_TOL = 1e-6
"""A ``u_axis`` whose component in the plane is shorter than this times its length counts as
parallel to the normal (no in-plane direction)."""


class SurfaceChart(abc.ABC):
    """A chart S(u, v) of a surface: the point and its derivatives for arrays of (u, v)."""

    names: ClassVar[tuple[str, str]]
    """What u and v are ("angle", "height"), for messages and docs."""
    units: ClassVar[tuple[str, str]]
    """Their units ("rad", "m")."""
    periods: ClassVar[tuple[float, float]]
    """The period of u and of v [their unit] (0: not periodic)."""

    takes_u_axis: ClassVar[bool] = False
    """The chart's u direction may be given (``u_axis``, a plane's)."""

    surface: Any

    @abc.abstractmethod
    def derivatives(self, u: ArrayLike, v: ArrayLike) -> np.ndarray:
        """S and its derivatives at N coordinate pairs.

        Args:
            u, v: (N,) coordinates (or scalars, N = 1).

        Returns:
            (6, N, 3) [m per unit of the coordinates]: S, S_u, S_v, S_uu, S_uv, S_vv.
        """

    @abc.abstractmethod
    def derivatives_at(self, u: float, v: float) -> tuple[Vec3, Vec3, Vec3, Vec3, Vec3, Vec3]:
        """:meth:`derivatives` at one (u, v), as six 3-tuples of floats (the hot path)."""

    @abc.abstractmethod
    def coordinates(self, p: ArrayLike) -> tuple[float, float]:
        """(u, v) of a point p (3,) [m] on the surface (the inverse of the chart).

        A periodic coordinate is returned in (−π, π]; :meth:`unwrap` moves it next to another.
        """

    def point(self, u: float, v: float) -> np.ndarray:
        """S(u, v): (3,) [m]."""
        return np.array(self.derivatives_at(float(u), float(v))[0])

    def unwrap(self, uv: tuple[float, float], near: tuple[float, float]) -> tuple[float, float]:
        """``uv`` with each periodic coordinate shifted by whole periods to within half a period
        of ``near``'s (the shorter way round)."""
        out = []
        for x, ref, period in zip(uv, near, self.periods, strict=True):
            if period:
                x += period * round((ref - x) / period)
            out.append(x)
        return out[0], out[1]

    def to_dict(self) -> dict[str, Any]:
        """Parameters of the chart beyond its surface (``{"u_axis": ...}`` for a plane)."""
        return {}


C = TypeVar("C", bound=type[SurfaceChart])
_CHARTS: dict[type, type[SurfaceChart]] = {}


def register_chart(surface_type: type) -> Callable[[C], C]:
    """Class decorator: the chart of ``surface_type`` (and its subclasses) for :func:`chart_for`.
    The chart is built as ``chart(surface)``, or ``chart(surface, u_axis)`` when it sets
    ``takes_u_axis``."""

    def register(chart: C) -> C:
        _CHARTS[surface_type] = chart
        return chart

    return register


def _columns(u: ArrayLike, v: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    uu = np.atleast_1d(np.asarray(u, dtype=float))
    vv = np.atleast_1d(np.asarray(v, dtype=float))
    return uu[:, None], vv[:, None]


@register_chart(Cylinder)
class CylinderChart(SurfaceChart):
    """(θ [rad], h [m]) on a :class:`Cylinder`: S = c + h·a + r (cos θ e1 + sin θ e2)."""

    names = ("angle", "height")
    units = ("rad", "m")
    periods = (2.0 * math.pi, 0.0)

    def __init__(self, surface: Cylinder) -> None:
        self.surface = surface
        self._e1, self._e2, self._a = axis_frame(surface.axis)
        self._c = np.asarray(surface.center, dtype=float)
        self._lists = [x.tolist() for x in (self._e1, self._e2, self._a, self._c)]

    def derivatives(self, u: ArrayLike, v: ArrayLike) -> np.ndarray:
        """(6, N, 3): S, S_θ = r(−sin θ e1 + cos θ e2), S_h = a, S_θθ = −r(cos θ e1 + sin θ e2),
        S_θh = 0, S_hh = 0."""
        th, h = _columns(u, v)
        r = self.surface.radius
        radial = np.cos(th) * self._e1 + np.sin(th) * self._e2
        out = np.zeros((6, th.shape[0], 3))
        out[0] = self._c + h * self._a + r * radial
        out[1] = r * (np.cos(th) * self._e2 - np.sin(th) * self._e1)
        out[2] = self._a
        out[3] = -r * radial
        return out

    def derivatives_at(self, u: float, v: float) -> tuple[Vec3, Vec3, Vec3, Vec3, Vec3, Vec3]:
        """:meth:`derivatives` at one (θ, h)."""
        r, co, si = self.surface.radius, math.cos(u), math.sin(u)
        e1, e2, a, c = self._lists
        radial = [co * x + si * y for x, y in zip(e1, e2, strict=True)]
        s = (c[0] + v * a[0] + r * radial[0], c[1] + v * a[1] + r * radial[1],
             c[2] + v * a[2] + r * radial[2])  # fmt: skip
        su = (r * (co * e2[0] - si * e1[0]), r * (co * e2[1] - si * e1[1]),
              r * (co * e2[2] - si * e1[2]))  # fmt: skip
        suu = (-r * radial[0], -r * radial[1], -r * radial[2])
        return s, su, (a[0], a[1], a[2]), suu, _ZERO, _ZERO

    def coordinates(self, p: ArrayLike) -> tuple[float, float]:
        """θ = atan2(w·e2, w·e1), h = w·a with w = p − center."""
        w = np.asarray(p, dtype=float) - self._c
        return math.atan2(float(w @ self._e2), float(w @ self._e1)), float(w @ self._a)


@register_chart(Sphere)
class SphereChart(SurfaceChart):
    """(φ, λ) [rad] on a :class:`Sphere`: S = c + r (cos φ cos λ, cos φ sin λ, sin φ)."""

    names = ("latitude", "longitude")
    units = ("rad", "rad")
    periods = (0.0, 2.0 * math.pi)

    def __init__(self, surface: Sphere) -> None:
        self.surface = surface
        self._c = np.asarray(surface.center, dtype=float)

    def derivatives(self, u: ArrayLike, v: ArrayLike) -> np.ndarray:
        """(6, N, 3): S and its first and second derivatives in (φ, λ)."""
        phi, lam = _columns(u, v)
        r = self.surface.radius
        cp, sp, cl, sl = np.cos(phi), np.sin(phi), np.cos(lam), np.sin(lam)
        zero = np.zeros_like(cp)
        out = np.empty((6, cp.shape[0], 3))
        out[0] = self._c + r * np.hstack((cp * cl, cp * sl, sp))
        out[1] = r * np.hstack((-sp * cl, -sp * sl, cp))
        out[2] = r * np.hstack((-cp * sl, cp * cl, zero))
        out[3] = -r * np.hstack((cp * cl, cp * sl, sp))
        out[4] = r * np.hstack((sp * sl, -sp * cl, zero))
        out[5] = -r * np.hstack((cp * cl, cp * sl, zero))
        return out

    def derivatives_at(self, u: float, v: float) -> tuple[Vec3, Vec3, Vec3, Vec3, Vec3, Vec3]:
        """:meth:`derivatives` at one (φ, λ)."""
        r = self.surface.radius
        cx, cy, cz = self.surface.center
        cp, sp, cl, sl = math.cos(u), math.sin(u), math.cos(v), math.sin(v)
        x, y, z = r * cp * cl, r * cp * sl, r * sp  # S − c
        return (
            (cx + x, cy + y, cz + z),
            (-r * sp * cl, -r * sp * sl, r * cp),
            (-y, x, 0.0),
            (-x, -y, -z),
            (r * sp * sl, -r * sp * cl, 0.0),
            (-x, -y, 0.0),
        )

    def coordinates(self, p: ArrayLike) -> tuple[float, float]:
        """φ = atan2(w_z, √(w_x² + w_y²)), λ = atan2(w_y, w_x) with w = p − center."""
        wx, wy, wz = (np.asarray(p, dtype=float) - self._c).tolist()
        return math.atan2(wz, math.hypot(wx, wy)), math.atan2(wy, wx)


@register_chart(Plane)
class PlaneChart(SurfaceChart):
    """(u, v) [m] on a :class:`Plane`: S = point + u·e_u + v·e_v, e_v = n × e_u.

    Args:
        surface: the plane.
        u_axis: (3,) direction of e_u, projected onto the plane and normalised; None: e1 of
            ``axis_frame(normal)`` (world x projected onto the plane, world y if n ∥ x).

    Raises:
        PathError: a ``u_axis`` that is zero, not finite or (nearly) along the normal.
    """

    names = ("u", "v")
    units = ("m", "m")
    periods = (0.0, 0.0)
    takes_u_axis = True

    def __init__(self, surface: Plane, u_axis: ArrayLike | None = None) -> None:
        self.surface = surface
        n = np.asarray(surface.normal_vector, dtype=float)
        self._given = None if u_axis is None else _in_plane_axis(u_axis, n)
        e_u = axis_frame(n)[0] if self._given is None else self._given
        self._e_u, self._e_v = e_u, np.cross(n, e_u)
        self._o = np.asarray(surface.point, dtype=float)
        self._lists = [x.tolist() for x in (self._o, self._e_u, self._e_v)]

    @property
    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """(e_u, e_v): the unit in-plane axes (3,) each."""
        return self._e_u.copy(), self._e_v.copy()

    def derivatives(self, u: ArrayLike, v: ArrayLike) -> np.ndarray:
        """(6, N, 3): S, S_u = e_u, S_v = e_v, and zero second derivatives."""
        uu, vv = _columns(u, v)
        out = np.zeros((6, uu.shape[0], 3))
        out[0] = self._o + uu * self._e_u + vv * self._e_v
        out[1] = self._e_u
        out[2] = self._e_v
        return out

    def derivatives_at(self, u: float, v: float) -> tuple[Vec3, Vec3, Vec3, Vec3, Vec3, Vec3]:
        """:meth:`derivatives` at one (u, v)."""
        o, a, b = self._lists
        s = (o[0] + u * a[0] + v * b[0], o[1] + u * a[1] + v * b[1], o[2] + u * a[2] + v * b[2])
        return s, (a[0], a[1], a[2]), (b[0], b[1], b[2]), _ZERO, _ZERO, _ZERO

    def coordinates(self, p: ArrayLike) -> tuple[float, float]:
        """u = w·e_u, v = w·e_v with w = p − point."""
        w = np.asarray(p, dtype=float) - self._o
        return float(w @ self._e_u), float(w @ self._e_v)

    def to_dict(self) -> dict[str, Any]:
        """``{"u_axis": [x, y, z]}`` when one was given (as projected), else ``{}``."""
        return {} if self._given is None else {"u_axis": self._given.tolist()}


def _in_plane_axis(u_axis: ArrayLike, n: np.ndarray) -> np.ndarray:
    raw = checks.array(u_axis, "u_axis", PathError, valid="3 finite real numbers")
    if raw.shape != (3,):
        raise PathError(
            f"u_axis must be 3 numbers, got {checks.shown(u_axis)}", key="u_axis", value=u_axis
        )
    length = float(np.linalg.norm(raw))
    along = raw - float(raw @ n) * n
    size = float(np.linalg.norm(along))
    if not size > _PARALLEL_TOL * length:
        raise PathError(
            f"u_axis {raw.tolist()} has no component in the plane (normal {n.tolist()}): give a "
            "direction along the plane",
            key="u_axis",
            value=u_axis,
        )
    return along / size


def chart_for(surface: object, u_axis: ArrayLike | None = None) -> SurfaceChart:
    """The chart of a built-in surface (see the module doc).

    Args:
        surface: a surface with a registered chart (:class:`Cylinder`, :class:`Sphere`,
            :class:`Plane`, ...).
        u_axis: (3,) the u direction of a plane's chart; only for a plane.

    Raises:
        PathError: a surface with no chart (a user-defined FunctionSurface), or a
            ``u_axis`` for a surface that is not a plane.
    """
    chart = next((_CHARTS[c] for c in type(surface).__mro__ if c in _CHARTS), None)
    if chart is not None and u_axis is not None and not chart.takes_u_axis:
        raise PathError(
            f"u_axis is only for a plane's chart; {surface!r} has fixed coordinates",
            key="u_axis",
            value=u_axis,
        )
    if chart is not None:
        build: Callable[..., SurfaceChart] = chart
        return build(surface, u_axis) if chart.takes_u_axis else build(surface)
    raise PathError(
        f"surface {checks.shown(surface)} has no chart (surface coordinates): paths in surface "
        "coordinates and waypoints projected onto it need a surface with a chart (cylinder, "
        "sphere, plane, ...)",
        key="surface",
        value=surface,
    )

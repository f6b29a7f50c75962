"""The ellipsoid surface (``[surface] type = "ellipsoid"``) and its chart.

In the ellipsoid's own frame, q = Rᵀ(p − center) with R = R(rpy) (the URDF convention,
:func:`~hybrid_force.geometry.mesh_field.rpy_matrix`) and semi-axes (a, b, c) along its x, y, z:

    Φ(p) = ±(q_x²/a² + q_y²/b² + q_z²/c² − 1)   (dimensionless; + when the outside is free),
    ∇Φ = ±2 R D⁻² q,   ∇²Φ = ±2 R D⁻² Rᵀ (constant),   D = diag(a, b, c).

Φ is smooth everywhere and positive on the free side. The signed metric distance d and the
foot point are the exact closest point, found by Eberly's robust root solve ("Distance from a
Point to an Ellipse, an Ellipsoid, or a Hyperellipsoid", 2013): bisection on the Lagrange
parameter of the foot point x_i = a_i² y_i / (t + a_i²), with the degenerate cases (a point on
a principal plane) in closed form. The chart (:class:`EllipsoidChart`) is the latitude and
longitude of the scaled sphere: S = center + R (a cos φ cos λ, b cos φ sin λ, c sin φ).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force.errors import SurfaceError
from hybrid_force.geometry.charts import SurfaceChart, register_chart
from hybrid_force.geometry.mesh_field import rpy_matrix
from hybrid_force.geometry.surface_base import (
    _SINGULAR_RTOL,
    Surface,
    Vec3,
    _boolean,
    _length,
    _point3,
    _read_only,
    _vector3,
    _xyz,
    register_surface,
)
from hybrid_force.schema import param

__all__ = ["Ellipsoid", "EllipsoidChart", "ellipse_foot", "ellipsoid_foot"]

_ORIGIN: Vec3 = (0.0, 0.0, 0.0)
_MAX_BISECTIONS = 200
"""More than enough halvings for the bracket of the root to shrink to one float."""


@register_surface
@dataclass(frozen=True)
class Ellipsoid(Surface):
    """Ellipsoid of semi-axes (a, b, c) [m] around ``center`` [m], its axes turned by ``rpy``.

    Φ and its derivatives: the module doc. ``inside=True`` makes the interior the free side
    (Φ and d negated). ``normal`` raises SurfaceError at the centre.

    Parameters: semi_axes: (3,) [m] all > 0; center: (3,) [m]; rpy: (3,) [rad], roll, pitch,
    yaw of the ellipsoid's axes in the world; inside: which side is free.
    """

    kind: ClassVar[str] = "ellipsoid"
    # the exact foot point makes the distance exact: a ball tool follows d − r (geometry/offset)
    metric_distance: ClassVar[str] = "exact"

    semi_axes: Vec3 = param(unit="m", minimum=0.0, strict=True, doc="semi-axes a, b, c")
    center: Vec3 = param(_ORIGIN, unit="m", doc="centre")
    rpy: Vec3 = param(_ORIGIN, unit="rad", doc="roll, pitch, yaw of the ellipsoid's axes")
    inside: bool = param(False, doc="the inside is the free side")
    _R: np.ndarray = field(init=False, repr=False, compare=False)
    _sign: float = field(init=False, repr=False, compare=False)
    _hess: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        axes = _vector3("Ellipsoid", "semi_axes", self.semi_axes)
        for i, x in enumerate(axes):
            _length("Ellipsoid", f"semi_axes[{i}]", x)
        c = _point3("Ellipsoid", "center", self.center)
        rpy = _vector3("Ellipsoid", "rpy", self.rpy)
        side = _boolean("Ellipsoid", "inside", self.inside)
        if max(axes) > 1e6 * min(axes):
            raise SurfaceError(
                f"Ellipsoid: parameter 'semi_axes' = {list(axes)} spans more than 1e6 "
                "between its shortest and longest axis"
            )
        R = rpy_matrix(rpy)
        sign = -1.0 if side else 1.0
        inv2 = 1.0 / np.square(np.array(axes))
        values = {
            "semi_axes": axes,
            "center": c,
            "rpy": rpy,
            "inside": side,
            "_R": _read_only(R),
            "_sign": sign,
            "_hess": _read_only(2.0 * sign * (R * inv2) @ R.T),
        }
        for name, value in values.items():
            object.__setattr__(self, name, value)

    def _local(self, p: ArrayLike, method: str) -> np.ndarray:
        """q = Rᵀ(p − center): (3,) [m], p validated."""
        return np.asarray(self._R.T @ (np.array(_xyz(p, self, method)) - self.center))

    def _phi_local(self, q: np.ndarray) -> float:
        return self._sign * (float(np.sum(np.square(q / self.semi_axes))) - 1.0)

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(Φ, ∇Φ: (3,), ∇²Φ: (3, 3)) at p: float64 (3,) [m], fresh arrays (the compiled
        constraint kernel takes writable ones)."""
        q = self._R.T @ (p - self.center)
        scaled = q / np.square(self.semi_axes)
        phi = self._sign * (float(scaled @ q) - 1.0)
        return phi, 2.0 * self._sign * (self._R @ scaled), self._hess.copy()

    def phi(self, p: ArrayLike) -> float:
        """Φ(p), dimensionless (module doc)."""
        return self._phi_local(self._local(p, "phi"))

    def gradient(self, p: ArrayLike) -> np.ndarray:
        """∇Φ(p) = ±2 R D⁻² q: (3,) [1/m]."""
        q = self._local(p, "gradient")
        return np.asarray(2.0 * self._sign * (self._R @ (q / np.square(self.semi_axes))))

    def hessian(self, p: ArrayLike) -> np.ndarray:
        """∇²Φ = ±2 R D⁻² Rᵀ: (3, 3) [1/m²], constant."""
        _xyz(p, self, "hessian")
        return self._hess.copy()

    def _foot_local(self, q: np.ndarray) -> tuple[np.ndarray, float]:
        """(the foot point in the ellipsoid's frame (3,) [m], the unsigned distance [m])."""
        order = np.argsort(-np.asarray(self.semi_axes), kind="stable")  # e0 >= e1 >= e2
        e = np.asarray(self.semi_axes)[order]
        y = np.abs(q[order])
        x = ellipsoid_foot(float(e[0]), float(e[1]), float(e[2]), *y.tolist())
        foot = np.empty(3)
        foot[order] = np.copysign(x, q[order])
        return foot, float(np.linalg.norm(foot - q))

    def distance(self, p: ArrayLike) -> float:
        """Signed metric distance [m] to the exact closest point (> 0 on the free side)."""
        q = self._local(p, "distance")
        _, d = self._foot_local(q)
        outside = float(np.sum(np.square(q / self.semi_axes))) >= 1.0
        return self._sign * (d if outside else -d)

    def normal(self, p: ArrayLike) -> np.ndarray:
        """Unit normal ∇Φ/‖∇Φ‖: (3,), to the free side."""
        q = self._local(p, "normal")
        g = self._R @ (q / np.square(self.semi_axes))
        size = float(np.linalg.norm(g))
        if size <= _SINGULAR_RTOL / min(self.semi_axes):
            raise SurfaceError(
                f"{self!r}.normal: p = {np.asarray(p, dtype=float).tolist()} is at the "
                "ellipsoid's centre, where ∇Φ = 0 and the normal is undefined"
            )
        return np.asarray(self._sign * g / size)

    def closest_point(self, p: ArrayLike) -> np.ndarray:
        """The foot point on the surface nearest to p: (3,) [m]."""
        foot, _ = self._foot_local(self._local(p, "closest_point"))
        return np.asarray(self.center + self._R @ foot)

    def concave_radius(self) -> tuple[float, np.ndarray | None]:
        """Inside free: (c²/a, the end of the longest axis) with a the longest and c the shortest
        semi-axis, the smallest radius of curvature of the ellipsoid (in the plane of those two
        axes, at the end of the longest); outside free: (inf, None), it is convex."""
        if not self.inside:
            return math.inf, None
        axes = np.asarray(self.semi_axes)
        longest = int(np.argmax(axes))
        end = np.zeros(3)
        end[longest] = axes[longest]
        return float(axes.min() ** 2 / axes[longest]), np.asarray(self.center + self._R @ end)

    def patch(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """(19, 37, 3) [m]: the whole ellipsoid on a latitude-longitude grid."""
        phi = np.repeat(np.linspace(-0.5 * np.pi, 0.5 * np.pi, 19), 37)
        lam = np.tile(np.linspace(0.0, 2.0 * np.pi, 37), 19)
        grid: np.ndarray = EllipsoidChart(self).derivatives(phi, lam)[0]
        return grid.reshape(19, 37, 3)


@register_chart(Ellipsoid)
class EllipsoidChart(SurfaceChart):
    """(φ, λ) [rad] on an :class:`Ellipsoid`: S = c + R (a cos φ cos λ, b cos φ sin λ, c sin φ).

    φ = 0 on the ellipsoid's own xy plane, λ = 0 towards its own +x axis.
    """

    names = ("latitude", "longitude")
    units = ("rad", "rad")
    periods = (0.0, 2.0 * math.pi)

    def __init__(self, surface: Ellipsoid) -> None:
        self.surface = surface
        self._c = np.asarray(surface.center, dtype=float)
        self._R = surface._R
        self._axes = np.asarray(surface.semi_axes, dtype=float)

    def derivatives(self, u: ArrayLike, v: ArrayLike) -> np.ndarray:
        """(6, N, 3): S, S_φ, S_λ, S_φφ, S_φλ, S_λλ."""
        phi = np.atleast_1d(np.asarray(u, dtype=float))[:, None]
        lam = np.atleast_1d(np.asarray(v, dtype=float))[:, None]
        cp, sp, cl, sl = np.cos(phi), np.sin(phi), np.cos(lam), np.sin(lam)
        zero = np.zeros_like(cp)
        local = np.empty((6, cp.shape[0], 3))
        local[0] = np.hstack((cp * cl, cp * sl, sp))
        local[1] = np.hstack((-sp * cl, -sp * sl, cp))
        local[2] = np.hstack((-cp * sl, cp * cl, zero))
        local[3] = -local[0]
        local[4] = np.hstack((sp * sl, -sp * cl, zero))
        local[5] = np.hstack((-cp * cl, -cp * sl, zero))
        out: np.ndarray = (local * self._axes) @ self._R.T
        out[0] += self._c
        return out

    def derivatives_at(self, u: float, v: float) -> tuple[Vec3, Vec3, Vec3, Vec3, Vec3, Vec3]:
        """:meth:`derivatives` at one (φ, λ)."""
        rows = [(x, y, z) for x, y, z in self.derivatives(u, v)[:, 0, :].tolist()]
        return rows[0], rows[1], rows[2], rows[3], rows[4], rows[5]

    def coordinates(self, p: ArrayLike) -> tuple[float, float]:
        """(φ, λ) of the point of the scaled sphere: s = Rᵀ(p − c) / (a, b, c)."""
        s = (self._R.T @ (np.asarray(p, dtype=float) - self._c)) / self._axes
        return math.atan2(s[2], math.hypot(s[0], s[1])), math.atan2(s[1], s[0])


# --- Eberly's closest point --------------------------------------------------------------------
def _bisect(ratios: tuple[float, ...], z: tuple[float, ...], g: float) -> float:
    """The root s of Σ (r_i z_i / (s + r_i))² − 1 = 0 (the last ratio is 1), bracketed by
    [z_last − 1, 0] inside (g < 0) or [0, ‖r z‖ − 1] outside, by bisection to one float."""
    n = [r * zi for r, zi in zip(ratios, z, strict=True)]
    s0 = z[-1] - 1.0
    s1 = 0.0 if g < 0 else math.sqrt(sum(x * x for x in n)) - 1.0
    s = 0.0
    for _ in range(_MAX_BISECTIONS):
        s = 0.5 * (s0 + s1)
        if s in (s0, s1):
            break
        f = sum((x / (s + r)) ** 2 for x, r in zip(n, ratios, strict=True)) - 1.0
        if f > 0:
            s0 = s
        elif f < 0:
            s1 = s
        else:
            break
    return s


def ellipse_foot(e0: float, e1: float, y0: float, y1: float) -> tuple[float, float]:
    """The closest point (x0, x1) on the ellipse x0²/e0² + x1²/e1² = 1 (e0 ≥ e1 > 0) to
    (y0, y1) with y0, y1 ≥ 0 [m]."""
    if y1 > 0:
        if y0 > 0:
            z0, z1 = y0 / e0, y1 / e1
            g = z0 * z0 + z1 * z1 - 1.0
            if g == 0:
                return y0, y1
            r0 = (e0 / e1) ** 2
            s = _bisect((r0, 1.0), (z0, z1), g)
            if s + 1.0 == 0.0:  # z1 below the bracket's resolution: on the principal axis
                return ellipse_foot(e0, e1, y0, 0.0)
            return r0 * y0 / (s + r0), y1 / (s + 1.0)
        return 0.0, e1
    numer, denom = e0 * y0, e0 * e0 - e1 * e1
    if numer < denom:
        ratio = numer / denom
        return e0 * ratio, e1 * math.sqrt(1.0 - ratio * ratio)
    return e0, 0.0


def ellipsoid_foot(
    e0: float, e1: float, e2: float, y0: float, y1: float, y2: float
) -> tuple[float, float, float]:
    """The closest point (x0, x1, x2) on the ellipsoid Σ x_i²/e_i² = 1 (e0 ≥ e1 ≥ e2 > 0) to
    (y0, y1, y2) with every y_i ≥ 0 [m] (Eberly's algorithm; the module doc)."""
    if y2 > 0:
        if y1 > 0:
            if y0 > 0:
                z = (y0 / e0, y1 / e1, y2 / e2)
                g = z[0] ** 2 + z[1] ** 2 + z[2] ** 2 - 1.0
                if g == 0:
                    return y0, y1, y2
                r0, r1 = (e0 / e2) ** 2, (e1 / e2) ** 2
                s = _bisect((r0, r1, 1.0), z, g)
                if s + 1.0 == 0.0:  # z2 below the bracket's resolution: on the principal plane
                    return ellipsoid_foot(e0, e1, e2, y0, y1, 0.0)
                return r0 * y0 / (s + r0), r1 * y1 / (s + r1), y2 / (s + 1.0)
            x1, x2 = ellipse_foot(e1, e2, y1, y2)
            return 0.0, x1, x2
        if y0 > 0:
            x0, x2 = ellipse_foot(e0, e2, y0, y2)
            return x0, 0.0, x2
        return 0.0, 0.0, e2
    d0, d1 = e0 * e0 - e2 * e2, e1 * e1 - e2 * e2
    n0, n1 = e0 * y0, e1 * y1
    if n0 < d0 and n1 < d1:
        q0, q1 = n0 / d0, n1 / d1
        rest = 1.0 - q0 * q0 - q1 * q1
        if rest > 0:
            return e0 * q0, e1 * q1, e2 * math.sqrt(rest)
    x0, x1 = ellipse_foot(e0, e1, y0, y1)
    return x0, x1, 0.0

"""The built-in surfaces in closed form: :class:`Cylinder` (the paper's eq. 26), :class:`Sphere`
and :class:`Plane`.

Their Φ, derivatives, distance, normal and foot point are exact up to rounding, and each carries
the small descriptor the compiled kernels evaluate.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force.errors import SurfaceError
from hybrid_force.geometry.surface_base import (
    _SINGULAR_RTOL,
    Surface,
    Vec3,
    _boolean,
    _direction,
    _length,
    _point3,
    _read_only,
    _xyz,
    plane_basis,
    register_surface,
    tool_radius,
)
from hybrid_force.schema import param

_ORIGIN: Vec3 = (0.0, 0.0, 0.0)

__all__ = ["Cylinder", "Plane", "Sphere"]


# --- cylinder --------------------------------------------------------------------------------
class _RoundSurface(Surface):
    """A surface at distance r from a centre (sphere) or an axis (cylinder).

    With w the offset of p from the centre or axis (:meth:`_offset`) and ρ = ‖w‖:
    Φ = ±(ρ² − r²), ∇Φ = ±2w, d = ±(ρ − r) (+ when the outside is free, − when ``inside``);
    the Hessian ±2I or ±2(I − aaᵀ) is constant and stored as ``_hess``. ``normal`` and
    ``closest_point`` raise SurfaceError within 1e-9 · r of the centre or axis.
    Subclasses set radius, inside, _sign, _r2, _hess, _singular_where and :meth:`_offset`.
    """

    radius: float
    inside: bool
    _sign: float
    _r2: float
    _hess: np.ndarray
    _singular_where: ClassVar[str]
    _centre_word: ClassVar[str]
    metric_distance: ClassVar[str] = "exact"

    def _freeze(
        self, radius: float, center: Vec3, inside: bool, shape: np.ndarray, **extra: object
    ) -> None:
        """Set the validated parameters and the derived sign, r² and Hessian ±2·shape."""
        sign = -1.0 if inside else 1.0
        values = {"radius": radius, "center": center, **extra, "inside": inside}
        values.update(_sign=sign, _r2=radius * radius, _hess=_read_only(2.0 * sign * shape))
        axis = np.asarray(extra.get("axis", (0.0, 0.0, 0.0)), dtype=float)
        desc = np.array([0.0, *center, *axis, sign, radius * radius, radius])
        values.update(_descriptor=_read_only(desc))
        for name, value in values.items():
            object.__setattr__(self, name, value)

    @abc.abstractmethod
    def _offset(self, x: float, y: float, z: float) -> Vec3:
        """w: (3,) [m], the offset of p from the centre or the axis."""

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(Φ, ∇Φ: (3,), ∇²Φ: (3, 3)) at p: float64 (3,) [m] (eq. 26 for the default cylinder).

        Not validated; the Hessian is a shared read-only array.
        """
        wx, wy, wz = self._offset(*p.tolist())
        s = self._sign
        g = 2.0 * s
        return (
            s * (wx * wx + wy * wy + wz * wz - self._r2),
            np.array((g * wx, g * wy, g * wz)),
            self._hess,
        )

    def phi(self, p: ArrayLike) -> float:
        """Φ(p) = ±(ρ² − r²) [m²]."""
        wx, wy, wz = self._offset(*_xyz(p, self, "phi"))
        return self._sign * (wx * wx + wy * wy + wz * wz - self._r2)

    def gradient(self, p: ArrayLike) -> np.ndarray:
        """∇Φ(p) = ±2 w: (3,) [m]."""
        wx, wy, wz = self._offset(*_xyz(p, self, "gradient"))
        g = 2.0 * self._sign
        return np.array((g * wx, g * wy, g * wz))

    def hessian(self, p: ArrayLike) -> np.ndarray:
        """∇²Φ: (3, 3), constant."""
        _xyz(p, self, "hessian")
        return self._hess.copy()

    def distance(self, p: ArrayLike) -> float:
        """d = ±(ρ − r) [m], computed as Φ / (ρ + r) so that d = 0 exactly where Φ = 0."""
        wx, wy, wz = self._offset(*_xyz(p, self, "distance"))
        rho2 = wx * wx + wy * wy + wz * wz
        return self._sign * (rho2 - self._r2) / (math.sqrt(rho2) + self.radius)

    def _unit_offset(self, p: ArrayLike, method: str) -> tuple[Vec3, Vec3, float]:
        """(p as floats, w / ρ, ρ); raises at the centre or on the axis."""
        x, y, z = _xyz(p, self, method)
        wx, wy, wz = self._offset(x, y, z)
        rho = math.hypot(wx, wy, wz)
        if rho <= _SINGULAR_RTOL * self.radius:
            raise SurfaceError(
                f"{self!r}.{method}: p = [{x:.9g}, {y:.9g}, {z:.9g}] {self._singular_where} "
                f"(distance {rho:.3g} m <= {_SINGULAR_RTOL:g} * radius), where ∇Φ = 0 "
                "and the normal is undefined"
            )
        return (x, y, z), (wx / rho, wy / rho, wz / rho), rho

    def concave_radius(self) -> tuple[float, np.ndarray | None]:
        """(r, None) when the inside is free (concave everywhere, radius r), else (inf, None)."""
        return (self.radius if self.inside else math.inf), None

    def _offset_radius(self, radius: float) -> float | None:
        """The offset's radius r ± ``radius`` [m], None for ``radius`` = 0; SurfaceError naming
        ``tool.radius`` when the inside is free and the ball does not fit (radius ≥ r)."""
        t = tool_radius(radius)
        if t == 0.0:
            return None
        if not self.inside:
            return self.radius + t
        if t >= self.radius:
            raise SurfaceError(
                f"tool.radius = {radius!r} m is not smaller than the radius {self.radius:g} m of "
                f"{self!r}, whose inside is free: the tool's ball does not fit in it (its centre "
                f"cannot stay {t:g} m from the wall on the {self._centre_word}'s side), so there "
                f"is no surface for the tool centre to follow; use a tool of radius below "
                f"{self.radius:g} m",
                key="tool.radius",
                value=radius,
            )
        return self.radius - t

    def normal(self, p: ArrayLike) -> np.ndarray:
        """Unit normal ±w/ρ: (3,), to the free side (towards the centre or axis when ``inside``)."""
        _, (nx, ny, nz), _ = self._unit_offset(p, "normal")
        s = self._sign
        return np.array((s * nx, s * ny, s * nz))

    def closest_point(self, p: ArrayLike) -> np.ndarray:
        """Foot point p + (r − ρ) w/ρ: (3,) [m] (exact up to rounding)."""
        (x, y, z), (nx, ny, nz), rho = self._unit_offset(p, "closest_point")
        step = self.radius - rho
        return np.array((x + step * nx, y + step * ny, z + step * nz))


@register_surface
@dataclass(frozen=True)
class Cylinder(_RoundSurface):
    """Infinite circular cylinder of radius r [m] around the line through ``center`` along ``axis``.

    With w = p − c and w⊥ = w − (w·a)a its component across the unit axis a, ρ = ‖w⊥‖:

    - ``inside=False`` (outside free): Φ = ρ² − r², d = ρ − r; with the default centre and axis,
      Φ = x² + y² − r² exactly, the paper's eq. 26 (``Cylinder(0.4)``);
    - ``inside=True`` (inside free, the tool presses on the wall from within, section 6.4):
      Φ = r² − ρ², d = r − ρ.

    ∇Φ = ±2 w⊥, ∇²Φ = ±2 (I − a aᵀ). ``normal`` and ``closest_point`` raise
    SurfaceError within 1e-9 · r of the axis.

    Parameters: radius > 0 [m]; center: (3,) [m], any point on the axis; axis: (3,), any non-zero
    direction, normalised internally; inside: which side is free.
    """

    kind: ClassVar[str] = "cylinder"
    _singular_where: ClassVar[str] = "lies on the cylinder axis"
    _centre_word: ClassVar[str] = "axis"

    radius: float = param(unit="m", minimum=0.0, strict=True, doc="radius")
    center: Vec3 = param(_ORIGIN, unit="m", doc="a point on the axis")
    axis: Vec3 = param((0.0, 0.0, 1.0), doc="direction of the axis (normalised)")
    inside: bool = param(False, doc="the inside is the free side")
    _sign: float = field(init=False, repr=False, compare=False)
    _r2: float = field(init=False, repr=False, compare=False)
    _hess: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        r = _length("Cylinder", "radius", self.radius)
        c = _point3("Cylinder", "center", self.center)
        a = _direction("Cylinder", "axis", self.axis)
        side = _boolean("Cylinder", "inside", self.inside)
        aa = np.asarray(a)
        self._freeze(r, c, side, np.eye(3) - np.outer(aa, aa), axis=a)

    def offset(self, radius: float) -> Cylinder:
        """The exact offset by ``radius`` [m] (a ball-end tool's centre): the coaxial cylinder
        of radius r + ``radius`` (outside free) or r − ``radius`` (inside free, a pipe;
        SurfaceError naming ``tool.radius`` when the ball does not fit, ``radius`` ≥ r)."""
        r = self._offset_radius(radius)
        if r is None:
            return self
        return Cylinder(r, self.center, self.axis, self.inside)

    def _offset(self, x: float, y: float, z: float) -> Vec3:
        """w⊥ = (p − c) − ((p − c)·a) a: (3,) [m], the component of p − c across the axis."""
        cx, cy, cz = self.center
        ax, ay, az = self.axis
        wx = x - cx
        wy = y - cy
        wz = z - cz
        t = wx * ax + wy * ay + wz * az
        return (wx - t * ax, wy - t * ay, wz - t * az)

    def patch(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """(9, 37, 3) [m]: rings over the axial range of ``points``, padded (at least
        ``margin``)."""
        center, axis = np.array(self.center), np.array(self.axis)
        u, w = plane_basis(axis)
        along = (points - center) @ axis if points.size else np.zeros(1)
        lo, hi = float(along.min()), float(along.max())
        pad = max(margin, 0.08 * (hi - lo), 0.25 * self.radius if hi - lo < 1e-9 else 0.0)
        ss = np.linspace(lo - pad, hi + pad, 9)
        th = np.linspace(0.0, 2.0 * np.pi, 37)
        ring = self.radius * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * w)
        out: np.ndarray = center + ss[:, None, None] * axis + ring[None, :, :]
        return out


# --- sphere ----------------------------------------------------------------------------------
@register_surface
@dataclass(frozen=True)
class Sphere(_RoundSurface):
    """Sphere of radius r [m] around ``center``.

    With w = p − c: ``inside=False`` (outside free): Φ = ‖w‖² − r², d = ‖w‖ − r;
    ``inside=True`` (inside free): Φ = r² − ‖w‖², d = r − ‖w‖. ∇Φ = ±2w, ∇²Φ = ±2I.
    ``normal`` and ``closest_point`` raise SurfaceError within 1e-9 · r of the centre.
    """

    kind: ClassVar[str] = "sphere"
    _singular_where: ClassVar[str] = "is at the sphere's centre"
    _centre_word: ClassVar[str] = "centre"

    radius: float = param(unit="m", minimum=0.0, strict=True, doc="radius")
    center: Vec3 = param(_ORIGIN, unit="m", doc="centre")
    inside: bool = param(False, doc="the inside is the free side")
    _sign: float = field(init=False, repr=False, compare=False)
    _r2: float = field(init=False, repr=False, compare=False)
    _hess: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        r = _length("Sphere", "radius", self.radius)
        c = _point3("Sphere", "center", self.center)
        side = _boolean("Sphere", "inside", self.inside)
        self._freeze(r, c, side, np.eye(3))

    def offset(self, radius: float) -> Sphere:
        """The exact offset by ``radius`` [m]: the concentric sphere of radius r + ``radius``
        (outside free) or r − ``radius`` (inside free; SurfaceError naming ``tool.radius`` when
        the ball does not fit, ``radius`` ≥ r)."""
        r = self._offset_radius(radius)
        if r is None:
            return self
        return Sphere(r, self.center, self.inside)

    def _offset(self, x: float, y: float, z: float) -> Vec3:
        """w = p − c: (3,) [m]."""
        cx, cy, cz = self.center
        return (x - cx, y - cy, z - cz)

    def patch(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """(13, 37, 3) [m]: the cap around the mean direction of ``points`` from the centre,
        covering them with a margin (the whole sphere beyond a 150° cap)."""
        center, radius = np.array(self.center), self.radius
        amax, m = np.pi, np.array([0.0, 0.0, 1.0])
        if points.size:
            rel = points - center
            mean = rel.mean(axis=0)
            if np.linalg.norm(mean) > 1e-9 * max(radius, 1.0):
                m = mean / np.linalg.norm(mean)
                norms = np.linalg.norm(rel, axis=1)
                ok = norms > 1e-12
                cosang = np.clip((rel[ok] @ m) / norms[ok], -1.0, 1.0)
                reach = float(np.arccos(cosang).max()) if cosang.size else 0.0
                amax = reach * 1.15 + np.radians(8.0) + margin / radius
                if amax > np.radians(150.0):
                    amax = np.pi
        u, w = plane_basis(m)
        th = np.linspace(0.0, amax, 13)
        ps = np.linspace(0.0, 2.0 * np.pi, 37)
        dirs = np.cos(th)[:, None, None] * m + np.sin(th)[:, None, None] * (
            np.cos(ps)[None, :, None] * u + np.sin(ps)[None, :, None] * w
        )
        out: np.ndarray = center + radius * dirs
        return out


# --- plane -----------------------------------------------------------------------------------
@register_surface
@dataclass(frozen=True, init=False)
class Plane(Surface):
    """Plane through ``point`` [m] with unit ``normal`` n pointing to the free side.

    Φ = n·(p − point) = d [m], ∇Φ = n, ∇²Φ = 0. The normal is normalised internally.
    """

    kind: ClassVar[str] = "plane"
    metric_distance: ClassVar[str] = "phi"

    point: Vec3 = param(unit="m", doc="a point of the plane")
    normal_vector: Vec3 = param(key="normal", doc="normal to the free side (normalised)")
    _grad: np.ndarray = field(init=False, repr=False, compare=False)
    _hess: np.ndarray = field(init=False, repr=False, compare=False)

    def __init__(self, point: ArrayLike, normal: ArrayLike) -> None:
        o = _point3("Plane", "point", point)
        n = _direction("Plane", "normal", normal)
        for name, value in (
            ("point", o),
            ("normal_vector", n),
            ("_grad", _read_only(np.array(n))),
            ("_hess", _read_only(np.zeros((3, 3)))),
            ("_descriptor", _read_only(np.array([1.0, *o, *n]))),
        ):
            object.__setattr__(self, name, value)

    def __repr__(self) -> str:
        return f"Plane(point={self.point!r}, normal={self.normal_vector!r})"

    def offset(self, radius: float) -> Plane:
        """The exact offset by ``radius`` [m]: the parallel plane through point + ``radius`` n."""
        t = tool_radius(radius)
        if t == 0.0:
            return self
        (ox, oy, oz), (nx, ny, nz) = self.point, self.normal_vector
        return Plane((ox + t * nx, oy + t * ny, oz + t * nz), self.normal_vector)

    def _phi(self, x: float, y: float, z: float) -> float:
        ox, oy, oz = self.point
        nx, ny, nz = self.normal_vector
        return nx * (x - ox) + ny * (y - oy) + nz * (z - oz)

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(Φ, ∇Φ: (3,), ∇²Φ: (3, 3)) at p: float64 (3,) [m]; not validated.

        ∇Φ and ∇²Φ are shared read-only arrays.
        """
        return self._phi(*p.tolist()), self._grad, self._hess

    def phi(self, p: ArrayLike) -> float:
        """Φ(p) = n·(p − point) [m]."""
        return self._phi(*_xyz(p, self, "phi"))

    def gradient(self, p: ArrayLike) -> np.ndarray:
        """∇Φ = n: (3,), constant."""
        _xyz(p, self, "gradient")
        return self._grad.copy()

    def hessian(self, p: ArrayLike) -> np.ndarray:
        """∇²Φ = 0: (3, 3)."""
        _xyz(p, self, "hessian")
        return np.zeros((3, 3))

    def distance(self, p: ArrayLike) -> float:
        """d = Φ = n·(p − point) [m]."""
        return self._phi(*_xyz(p, self, "distance"))

    def normal(self, p: ArrayLike) -> np.ndarray:
        """n: (3,), the same everywhere."""
        _xyz(p, self, "normal")
        return self._grad.copy()

    def closest_point(self, p: ArrayLike) -> np.ndarray:
        """Foot point p − d n: (3,) [m]."""
        x, y, z = _xyz(p, self, "closest_point")
        d = self._phi(x, y, z)
        nx, ny, nz = self.normal_vector
        return np.array((x - d * nx, y - d * ny, z - d * nz))

    def patch(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """(11, 11, 3) [m]: the patch under ``points``, padded (at least ``margin``)."""
        point, normal = np.array(self.point), np.array(self.normal_vector)
        u, w = plane_basis(normal)
        if points.size:
            a, b = (points - point) @ u, (points - point) @ w
            a0, a1, b0, b1 = float(a.min()), float(a.max()), float(b.min()), float(b.max())
        else:
            a0 = a1 = b0 = b1 = 0.0
        pad = max(margin, 0.1 * max(a1 - a0, b1 - b0, 0.1))
        aa = np.linspace(a0 - pad, a1 + pad, 11)
        bb = np.linspace(b0 - pad, b1 + pad, 11)
        out: np.ndarray = point + aa[:, None, None] * u + bb[None, :, None] * w
        return out

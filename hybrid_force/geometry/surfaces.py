"""Rigid surfaces Φ(p) = 0 that the tool of the arm stays on (paper eq. 1).

Pure geometry, no robot: every surface gives, at a task-space point p: (3,) [m],

- Φ(p) (``phi``), its gradient ∇Φ: (3,) and Hessian ∇²Φ: (3, 3); ``evaluate`` returns all three in
  one call and is the hot path of the simulation;
- a signed *metric* distance d(p) [m] (Φ itself is not a distance: the paper's cylinder, eq. 26,
  has Φ = x² + y² − r², in m²), used by the phase switching of section 6.4 (max_dist = 0.05 m,
  contact at d ≤ 1e-5 m);
- the unit normal ∇Φ/‖∇Φ‖ and the foot point on the surface.

Orientation. Every surface has a *free side*, where the tool is, and Φ > 0, d > 0 there. The
contact force f of the whole toolkit acts along the unit normal pointing to the free side, so
f > 0 always means "the tool presses on the surface". Cylinders and spheres carry an ``inside``
flag: ``inside=False`` (default) makes the outside free, with Φ exactly the paper's eq. 26 for
``Cylinder(0.4)``; ``inside=True`` negates Φ so the interior is free (section 6.4 of the paper,
where the tool starts inside the cylinder and presses on its wall from within). A plane's normal
points to its free side; a :class:`FunctionSurface`'s Φ must be positive on its free side.

Built in: :class:`Cylinder`, :class:`Sphere`, :class:`Plane`; user-defined:
:class:`FunctionSurface`.
:func:`surface_from_dict` inverts ``to_dict`` for the built-ins.
"""

from __future__ import annotations

import abc
import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force import _checks as checks
from hybrid_force.errors import (
    DimensionError,
    SingularConfigurationError,
    SurfaceError,
    SurfaceParameterError,
    did_you_mean,
)

__all__ = [
    "Cylinder",
    "FunctionSurface",
    "Plane",
    "Sphere",
    "Surface",
    "surface_from_dict",
]

#: An axis or normal shorter than this [m or unitless] counts as zero-length.
_MIN_DIRECTION_NORM = 1e-12
#: A cylinder's normal is undefined within ``_SINGULAR_RTOL * radius`` of its axis, a sphere's
#: within ``_SINGULAR_RTOL * radius`` of its centre (there ‖∇Φ‖ = 2ρ < 2e-9 · radius).
_SINGULAR_RTOL = 1e-9
#: Default finite-difference steps of :class:`FunctionSurface` [m], see its docstring.
_DEFAULT_STEP = 6.0e-6
_DEFAULT_HESSIAN_STEP = 1.2e-4
_DEFAULT_SINGULAR_TOL = 1e-12

Vec3 = tuple[float, float, float]


# --- validation helpers ----------------------------------------------------------------------
def _fmt(value: object) -> str:
    """Short readable form of a bad value for an error message."""
    if isinstance(value, np.ndarray):
        return np.array2string(value, precision=6, separator=", ")
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _positive_float(owner: str, name: str, value: object, unit: str = "m") -> float:
    """Check that ``value`` is a finite real number > 0 (not a bool) and return it as a float."""
    what = f"{owner}: parameter '{name}'"
    return checks.number(value, what, SurfaceParameterError, minimum=0.0, strict=True, unit=unit)


def _vector3(owner: str, name: str, value: object) -> Vec3:
    """Check that ``value`` is 3 finite real numbers [m] and return them as a float tuple."""
    what = f"{owner}: parameter '{name}'"
    array = checks.array(value, what, SurfaceParameterError, valid="3 finite real numbers")
    if array.shape != (3,):
        raise SurfaceParameterError(
            f"{what} must have shape (3,), got shape {array.shape}: {checks.shown(value)}"
        )
    x, y, z = array.tolist()
    return (x, y, z)


def _direction(owner: str, name: str, value: object) -> Vec3:
    """Check a direction (axis, normal) and return it normalised to unit length.

    A vector whose norm is already 1 to within 4 ulp is kept as given, so that unit vectors
    written by ``to_dict`` come back bit for bit.
    """
    x, y, z = _vector3(owner, name, value)
    norm = math.hypot(x, y, z)
    if not norm >= _MIN_DIRECTION_NORM:
        raise SurfaceParameterError(
            f"{owner}: parameter '{name}' must be a non-zero direction "
            f"(norm >= {_MIN_DIRECTION_NORM:g}), got {_fmt(value)} with norm {norm:g}"
        )
    if abs(norm - 1.0) <= 4.0 * np.finfo(np.float64).eps:
        return (x, y, z)
    return (x / norm, y / norm, z / norm)


def _boolean(owner: str, name: str, value: object) -> bool:
    """Check that ``value`` is a bool (Python or numpy), not a truthy 1 or "yes"."""
    return checks.flag(value, f"{owner}: parameter '{name}'", SurfaceParameterError)


def _xyz(p: ArrayLike, owner: object, method: str) -> Vec3:
    """Return the point p as three finite Python floats, or raise naming ``owner.method``.

    The message (with the owner's repr) is only built on error: this runs on every call.
    """
    if type(p) is np.ndarray and p.shape == (3,) and p.dtype == np.float64:
        x, y, z = p.tolist()
    else:
        try:
            array = np.asarray(p, dtype=np.float64)
        except (TypeError, ValueError, OverflowError) as exc:
            raise DimensionError(
                f"{owner!r}.{method}: point p must be 3 numbers [m], got {_fmt(p)} ({exc})"
            ) from exc
        if array.shape != (3,):
            raise DimensionError(
                f"{owner!r}.{method}: point p must have shape (3,), got shape {array.shape}: "
                f"{_fmt(p)}"
            )
        x, y, z = array.tolist()
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise SurfaceError(f"{owner!r}.{method}: point p must be finite, got [{x}, {y}, {z}]")
    return (x, y, z)


def _read_only(array: np.ndarray) -> np.ndarray:
    """Mark ``array`` read-only (shared constant derivative returned by ``evaluate``)."""
    array.flags.writeable = False
    return array


# --- interface -------------------------------------------------------------------------------
class Surface(abc.ABC):
    """A rigid surface Φ(p) = 0 (paper eq. 1), Φ > 0 on the free side (where the tool is).

    Points p are (3,) arrays in metres, in the world frame. Units of Φ depend on the surface
    (m² for the cylinder and sphere, m for the plane); ``distance`` is always in metres.
    """

    kind: ClassVar[str]
    # The closed form as a small read-only float array that compiled code evaluates
    # (hybrid_force._kernels.surface_eval): [0, c (3), a (3), sign, r², r] for a cylinder
    # or sphere (a = 0), [1, point (3), n (3)] for a plane; empty when there is none (Python).
    _descriptor: ClassVar[np.ndarray] = np.zeros(0)

    @abc.abstractmethod
    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """Return (Φ, ∇Φ: (3,), ∇²Φ: (3, 3)) at p: (3,) float64 array [m], in one call.

        The hot path, called every simulation step: p is not validated (it must be a float64
        (3,) ndarray). Derivatives that do not depend on p (a cylinder's Hessian, a plane's
        gradient) are returned as shared *read-only* arrays: copy them before writing.
        """

    def evaluate_with_distance(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
        """:meth:`evaluate` and :meth:`distance` at p in one call (not validated).

        Returns (Φ, ∇Φ: (3,), ∇²Φ: (3, 3), d [m]); shared arrays as in :meth:`evaluate`.
        """
        return (*self.evaluate(p), self.distance(p))

    @abc.abstractmethod
    def phi(self, p: ArrayLike) -> float:
        """Φ(p) at p: (3,) [m]; > 0 on the free side."""

    @abc.abstractmethod
    def gradient(self, p: ArrayLike) -> np.ndarray:
        """∇Φ(p): (3,), a fresh array."""

    @abc.abstractmethod
    def hessian(self, p: ArrayLike) -> np.ndarray:
        """∇²Φ(p): (3, 3), a fresh symmetric array."""

    @abc.abstractmethod
    def distance(self, p: ArrayLike) -> float:
        """Signed metric distance [m] from p to the surface; > 0 on the free side, 0 where Φ = 0."""

    @abc.abstractmethod
    def normal(self, p: ArrayLike) -> np.ndarray:
        """Unit normal ∇Φ/‖∇Φ‖: (3,), pointing to the free side.

        Raises SingularConfigurationError where ∇Φ (nearly) vanishes.
        """

    @abc.abstractmethod
    def closest_point(self, p: ArrayLike) -> np.ndarray:
        """Foot point on the surface nearest to p: (3,) [m]."""

    @abc.abstractmethod
    def to_dict(self) -> dict[str, Any]:
        """JSON-able description ``{"type": kind, ...parameters as floats / lists}``."""


# --- cylinder --------------------------------------------------------------------------------
class _RoundSurface(Surface):
    """A surface at distance r from a centre (sphere) or an axis (cylinder).

    With w the offset of p from the centre or axis (:meth:`_offset`) and ρ = ‖w‖:
    Φ = ±(ρ² − r²), ∇Φ = ±2w, d = ±(ρ − r) (+ when the outside is free, − when ``inside``);
    the Hessian ±2I or ±2(I − aaᵀ) is constant and stored as ``_hess``. ``normal`` and
    ``closest_point`` raise SingularConfigurationError within 1e-9 · r of the centre or axis.
    Subclasses set radius, inside, _sign, _r2, _hess, _singular_where and :meth:`_offset`.
    """

    radius: float
    _sign: float
    _r2: float
    _hess: np.ndarray
    _singular_where: ClassVar[str]

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
            raise SingularConfigurationError(
                f"{self!r}.{method}: p = [{x:.9g}, {y:.9g}, {z:.9g}] {self._singular_where} "
                f"(distance {rho:.3g} m <= {_SINGULAR_RTOL:g} * radius), where ∇Φ = 0 "
                "and the normal is undefined"
            )
        return (x, y, z), (wx / rho, wy / rho, wz / rho), rho

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


@dataclass(frozen=True, init=False)
class Cylinder(_RoundSurface):
    """Infinite circular cylinder of radius r [m] around the line through ``center`` along ``axis``.

    With w = p − c and w⊥ = w − (w·a)a its component across the unit axis a, ρ = ‖w⊥‖:

    - ``inside=False`` (outside free): Φ = ρ² − r², d = ρ − r; with the default centre and axis,
      Φ = x² + y² − r² exactly, the paper's eq. 26 (``Cylinder(0.4)``);
    - ``inside=True`` (inside free, the tool presses on the wall from within, section 6.4):
      Φ = r² − ρ², d = r − ρ.

    ∇Φ = ±2 w⊥, ∇²Φ = ±2 (I − a aᵀ). ``normal`` and ``closest_point`` raise
    SingularConfigurationError within 1e-9 · r of the axis.

    Parameters: radius > 0 [m]; center: (3,) [m], any point on the axis; axis: (3,), any non-zero
    direction, normalised internally; inside: which side is free.
    """

    kind: ClassVar[str] = "cylinder"
    _singular_where: ClassVar[str] = "lies on the cylinder axis"

    radius: float
    center: Vec3
    axis: Vec3
    inside: bool
    _sign: float = field(init=False, repr=False, compare=False)
    _r2: float = field(init=False, repr=False, compare=False)
    _hess: np.ndarray = field(init=False, repr=False, compare=False)

    def __init__(
        self,
        radius: float,
        center: ArrayLike = (0.0, 0.0, 0.0),
        axis: ArrayLike = (0.0, 0.0, 1.0),
        inside: bool = False,
    ) -> None:
        r = _positive_float("Cylinder", "radius", radius)
        c = _vector3("Cylinder", "center", center)
        a = _direction("Cylinder", "axis", axis)
        side = _boolean("Cylinder", "inside", inside)
        aa = np.asarray(a)
        self._freeze(r, c, side, np.eye(3) - np.outer(aa, aa), axis=a)

    def _offset(self, x: float, y: float, z: float) -> Vec3:
        """w⊥ = (p − c) − ((p − c)·a) a: (3,) [m], the component of p − c across the axis."""
        cx, cy, cz = self.center
        ax, ay, az = self.axis
        wx = x - cx
        wy = y - cy
        wz = z - cz
        t = wx * ax + wy * ay + wz * az
        return (wx - t * ax, wy - t * ay, wz - t * az)

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "cylinder", "radius", "center", "axis" (unit), "inside"}``."""
        return {
            "type": self.kind,
            "radius": self.radius,
            "center": list(self.center),
            "axis": list(self.axis),
            "inside": self.inside,
        }


# --- sphere ----------------------------------------------------------------------------------
@dataclass(frozen=True, init=False)
class Sphere(_RoundSurface):
    """Sphere of radius r [m] around ``center``.

    With w = p − c: ``inside=False`` (outside free): Φ = ‖w‖² − r², d = ‖w‖ − r;
    ``inside=True`` (inside free): Φ = r² − ‖w‖², d = r − ‖w‖. ∇Φ = ±2w, ∇²Φ = ±2I.
    ``normal`` and ``closest_point`` raise SingularConfigurationError within 1e-9 · r of the centre.
    """

    kind: ClassVar[str] = "sphere"
    _singular_where: ClassVar[str] = "is at the sphere's centre"

    radius: float
    center: Vec3
    inside: bool
    _sign: float = field(init=False, repr=False, compare=False)
    _r2: float = field(init=False, repr=False, compare=False)
    _hess: np.ndarray = field(init=False, repr=False, compare=False)

    def __init__(
        self,
        radius: float,
        center: ArrayLike = (0.0, 0.0, 0.0),
        inside: bool = False,
    ) -> None:
        r = _positive_float("Sphere", "radius", radius)
        c = _vector3("Sphere", "center", center)
        side = _boolean("Sphere", "inside", inside)
        self._freeze(r, c, side, np.eye(3))

    def _offset(self, x: float, y: float, z: float) -> Vec3:
        """w = p − c: (3,) [m]."""
        cx, cy, cz = self.center
        return (x - cx, y - cy, z - cz)

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "sphere", "radius", "center", "inside"}``."""
        return {
            "type": self.kind,
            "radius": self.radius,
            "center": list(self.center),
            "inside": self.inside,
        }


# --- plane -----------------------------------------------------------------------------------
@dataclass(frozen=True, init=False)
class Plane(Surface):
    """Plane through ``point`` [m] with unit ``normal`` n pointing to the free side.

    Φ = n·(p − point) = d [m], ∇Φ = n, ∇²Φ = 0. The normal is normalised internally.
    """

    kind: ClassVar[str] = "plane"

    point: Vec3
    normal_vector: Vec3
    _grad: np.ndarray = field(init=False, repr=False, compare=False)
    _hess: np.ndarray = field(init=False, repr=False, compare=False)

    def __init__(self, point: ArrayLike, normal: ArrayLike) -> None:
        o = _vector3("Plane", "point", point)
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

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "plane", "point", "normal" (unit)}``."""
        return {"type": self.kind, "point": list(self.point), "normal": list(self.normal_vector)}


# --- user-defined ----------------------------------------------------------------------------
PointFunction = Callable[[np.ndarray], Any]


def _callable_name(function: Callable[..., Any]) -> str:
    return getattr(function, "__qualname__", None) or type(function).__name__


@dataclass(frozen=True, init=False, repr=False)
class FunctionSurface(Surface):
    """A surface Φ(p) = 0 given by Python callables of p: (3,) float64 [m].

    ``phi(p) -> float`` must be positive on the free side (where the tool is) and smooth near the
    surface. ``gradient(p) -> (3,)``, ``hessian(p) -> (3, 3)`` and ``distance(p) -> float`` [m,
    signed like Φ] are optional:

    - missing gradient: central differences of Φ with step h = ``step`` (default 6e-6 m ≈ ε^(1/3),
      ε = 2.2e-16), truncation error h²/6 · |∂³Φ| plus rounding ε · |Φ| / h: for a Φ of unit scale
      (values and derivatives up to third order ≲ 1 on lengths ≈ 1 m) about 5e-11 per component,
      below 1e-10. The step is measured exactly ((p + h) − (p − h)) to remove representation error.
    - missing Hessian, gradient given: central differences of the gradient with the same step,
      symmetrised; error as for the gradient (≲ 1e-10 at unit scale).
    - missing Hessian and gradient: second differences of Φ with step k = ``hessian_step``
      (default 1.2e-4 m ≈ ε^(1/4)); truncation k²/12 · |∂⁴Φ| (diagonal) or k²/6 · |∂⁴Φ|
      (off-diagonal) plus rounding 4ε · |Φ| / k² (diagonal) or ε · |Φ| / k² (off-diagonal): about
      6e-8 at unit scale, below 1e-7.
    - missing distance: first order, d ≈ Φ / ‖∇Φ‖. Exact for a Φ with ‖∇Φ‖ = 1 (a true signed
      distance, e.g. a plane n·p − c); otherwise correct to O(d²): for ‖p‖² − r², Φ/‖∇Φ‖ − d =
      −d² / (2‖p‖).

    "|Φ|" in the rounding terms means the size of the terms Φ is computed from (a Φ computed
    with cancellation carries their rounding error). For a Φ of magnitude S varying over lengths L,
    scale both steps by L; the errors then scale as S/L (gradient) and S/L² (Hessian).

    ``closest_point`` is first order (one Newton step p − Φ ∇Φ/‖∇Φ‖²); it lies on the surface
    to O(d²). ``normal``, ``closest_point`` and the first-order ``distance`` raise
    SingularConfigurationError where ‖∇Φ‖ < ``singular_tol`` (same units as ∇Φ).
    ``to_dict`` gives ``{"type": "function"}`` only: a function surface cannot be rebuilt
    from a dict.

    Results of the callables are checked: a non-finite Φ raises SurfaceError, a gradient not
    of shape (3,) or a Hessian not of shape (3, 3) raises DimensionError, naming the callable.
    """

    kind: ClassVar[str] = "function"

    phi_function: PointFunction
    gradient_function: PointFunction | None
    hessian_function: PointFunction | None
    distance_function: PointFunction | None
    step: float
    hessian_step: float
    singular_tol: float

    def __init__(
        self,
        phi: PointFunction,
        gradient: PointFunction | None = None,
        hessian: PointFunction | None = None,
        distance: PointFunction | None = None,
        *,
        step: float = _DEFAULT_STEP,
        hessian_step: float = _DEFAULT_HESSIAN_STEP,
        singular_tol: float = _DEFAULT_SINGULAR_TOL,
    ) -> None:
        owner = "FunctionSurface"
        if not callable(phi):
            raise SurfaceParameterError(
                f"FunctionSurface: parameter 'phi' must be a callable phi(p) -> float, "
                f"got {_fmt(phi)}"
            )
        for name, function in (
            ("gradient", gradient),
            ("hessian", hessian),
            ("distance", distance),
        ):
            if function is not None and not callable(function):
                raise SurfaceParameterError(
                    f"FunctionSurface: parameter '{name}' must be a callable of p or None, "
                    f"got {_fmt(function)}"
                )
        for name, value in (
            ("phi_function", phi),
            ("gradient_function", gradient),
            ("hessian_function", hessian),
            ("distance_function", distance),
            ("step", _positive_float(owner, "step", step)),
            ("hessian_step", _positive_float(owner, "hessian_step", hessian_step)),
            ("singular_tol", _positive_float(owner, "singular_tol", singular_tol, unit="∇Φ")),
        ):
            object.__setattr__(self, name, value)

    def __repr__(self) -> str:
        parts = [f"phi={_callable_name(self.phi_function)}"]
        if self.gradient_function is not None:
            parts.append(f"gradient={_callable_name(self.gradient_function)}")
        else:
            parts.append(f"gradient=<central differences, step={self.step:g}>")
        if self.hessian_function is not None:
            parts.append(f"hessian={_callable_name(self.hessian_function)}")
        elif self.gradient_function is not None:
            parts.append(f"hessian=<central differences of gradient, step={self.step:g}>")
        else:
            parts.append(f"hessian=<second differences of phi, step={self.hessian_step:g}>")
        if self.distance_function is not None:
            parts.append(f"distance={_callable_name(self.distance_function)}")
        else:
            parts.append("distance=<first order phi/|grad phi|>")
        return f"FunctionSurface({', '.join(parts)})"

    # -- calls of the user's functions, with their results checked --
    def _call_scalar(self, function: PointFunction, name: str, p: np.ndarray) -> float:
        raw = function(p)
        if isinstance(raw, bool | np.bool_) or not isinstance(raw, numbers.Real | np.ndarray):
            value = math.nan
        else:
            try:
                value = float(raw)
            except (TypeError, ValueError, OverflowError):  # arrays of size != 1, 10**400
                value = math.nan
        if not math.isfinite(value):
            raise SurfaceError(
                f"{self!r}: {name} returned {_fmt(raw)} at p = {_fmt(p)}; it must be a finite "
                "real number"
            )
        return value

    def _call_phi(self, p: np.ndarray) -> float:
        return self._call_scalar(self.phi_function, "phi", p)

    def _call_vector(self, function: PointFunction, name: str, p: np.ndarray) -> np.ndarray:
        raw = function(p)
        try:
            value = np.array(raw, dtype=np.float64)
        except (TypeError, ValueError, OverflowError) as exc:
            raise SurfaceError(
                f"{self!r}: {name} returned {_fmt(raw)} at p = {_fmt(p)}; it must be real "
                f"numbers ({exc})"
            ) from exc
        shape = (3,) if name != "hessian" else (3, 3)
        if value.shape != shape:
            raise DimensionError(
                f"{self!r}: {name} returned shape {value.shape} at p = {_fmt(p)}, expected {shape}"
            )
        if not np.all(np.isfinite(value)):
            raise SurfaceError(
                f"{self!r}: {name} returned non-finite values at p = {_fmt(p)}: {_fmt(value)}"
            )
        return value

    # -- finite differences --
    def _fd_gradient(self, p: np.ndarray) -> np.ndarray:
        """Central differences of Φ, error O(h²) (see the class docstring)."""
        h = self.step
        grad = np.empty(3)
        for i in range(3):
            forward = p.copy()
            backward = p.copy()
            forward[i] += h
            backward[i] -= h
            grad[i] = (self._call_phi(forward) - self._call_phi(backward)) / (
                forward[i] - backward[i]
            )
        return grad

    def _fd_hessian_from_gradient(self, p: np.ndarray) -> np.ndarray:
        """Central differences of the user's gradient, symmetrised; error O(h²)."""
        assert self.gradient_function is not None
        h = self.step
        hess = np.empty((3, 3))
        for i in range(3):
            forward = p.copy()
            backward = p.copy()
            forward[i] += h
            backward[i] -= h
            hess[:, i] = (
                self._call_vector(self.gradient_function, "gradient", forward)
                - self._call_vector(self.gradient_function, "gradient", backward)
            ) / (forward[i] - backward[i])
        return 0.5 * (hess + hess.T)

    def _fd_hessian_from_phi(self, p: np.ndarray, phi0: float) -> np.ndarray:
        """Second differences of Φ with step k, error O(k²) (see the class docstring)."""
        k = self.hessian_step
        steps = [(p[i] + k) - p[i] for i in range(3)]  # exactly representable steps
        hess = np.empty((3, 3))

        def shifted(di: int, si: float, dj: int | None = None, sj: float = 0.0) -> float:
            q = p.copy()
            q[di] += si * steps[di]
            if dj is not None:
                q[dj] += sj * steps[dj]
            return self._call_phi(q)

        for i in range(3):
            hess[i, i] = (shifted(i, 1.0) - 2.0 * phi0 + shifted(i, -1.0)) / (steps[i] * steps[i])
            for j in range(i + 1, 3):
                value = (
                    shifted(i, 1.0, j, 1.0)
                    - shifted(i, 1.0, j, -1.0)
                    - shifted(i, -1.0, j, 1.0)
                    + shifted(i, -1.0, j, -1.0)
                ) / (4.0 * steps[i] * steps[j])
                hess[i, j] = value
                hess[j, i] = value
        return hess

    def _gradient_at(self, p: np.ndarray) -> np.ndarray:
        if self.gradient_function is not None:
            return self._call_vector(self.gradient_function, "gradient", p)
        return self._fd_gradient(p)

    def _hessian_at(self, p: np.ndarray, phi0: float | None = None) -> np.ndarray:
        if self.hessian_function is not None:
            return self._call_vector(self.hessian_function, "hessian", p)
        if self.gradient_function is not None:
            return self._fd_hessian_from_gradient(p)
        return self._fd_hessian_from_phi(p, self._call_phi(p) if phi0 is None else phi0)

    def _point(self, p: ArrayLike, method: str) -> np.ndarray:
        return np.array(_xyz(p, self, method))

    # -- interface --
    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(Φ, ∇Φ: (3,), ∇²Φ: (3, 3)) at p: float64 (3,) [m]; derivatives as documented above."""
        phi0 = self._call_phi(p)
        return phi0, self._gradient_at(p), self._hessian_at(p, phi0)

    def phi(self, p: ArrayLike) -> float:
        """Φ(p), the user's function."""
        return self._call_phi(self._point(p, "phi"))

    def gradient(self, p: ArrayLike) -> np.ndarray:
        """∇Φ(p): (3,), supplied or by central differences."""
        return self._gradient_at(self._point(p, "gradient"))

    def hessian(self, p: ArrayLike) -> np.ndarray:
        """∇²Φ(p): (3, 3), supplied or by finite differences."""
        return self._hessian_at(self._point(p, "hessian"))

    def _unit_gradient(self, q: np.ndarray, method: str) -> tuple[np.ndarray, float]:
        grad = self._gradient_at(q)
        norm = float(np.linalg.norm(grad))
        if norm < self.singular_tol:
            raise SingularConfigurationError(
                f"{self!r}.{method}: ‖∇Φ‖ = {norm:.3g} < singular_tol = {self.singular_tol:g} "
                f"at p = {_fmt(q)}; the normal is undefined there"
            )
        return grad / norm, norm

    def distance(self, p: ArrayLike) -> float:
        """Signed distance [m]: the user's, or Φ/‖∇Φ‖ (first order, see the class docstring)."""
        q = self._point(p, "distance")
        if self.distance_function is not None:
            return self._call_scalar(self.distance_function, "distance", q)
        phi0 = self._call_phi(q)
        if phi0 == 0.0:
            return 0.0
        _, norm = self._unit_gradient(q, "distance")
        return phi0 / norm

    def normal(self, p: ArrayLike) -> np.ndarray:
        """∇Φ/‖∇Φ‖: (3,), to the free side."""
        unit, _ = self._unit_gradient(self._point(p, "normal"), "normal")
        return unit

    def closest_point(self, p: ArrayLike) -> np.ndarray:
        """First-order foot point p − Φ ∇Φ/‖∇Φ‖²: (3,) [m]; on the surface to O(d²)."""
        q = self._point(p, "closest_point")
        phi0 = self._call_phi(q)
        unit, norm = self._unit_gradient(q, "closest_point")
        return q - (phi0 / norm) * unit

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "function"}``: not round-trippable (the callables are not serialised)."""
        return {"type": self.kind}


# --- from a dict -----------------------------------------------------------------------------
_BUILT_INS: dict[str, tuple[type[Surface], tuple[str, ...], tuple[str, ...]]] = {
    # type: (class, required keys, optional keys)
    "cylinder": (Cylinder, ("radius",), ("center", "axis", "inside")),
    "sphere": (Sphere, ("radius",), ("center", "inside")),
    "plane": (Plane, ("point", "normal"), ()),
}


def surface_from_dict(d: Mapping[str, Any]) -> Surface:
    """Build a built-in surface from ``to_dict``'s output (the inverse of ``to_dict``).

    ``d["type"]`` is one of "cylinder", "sphere", "plane"; the other keys are the constructor's
    parameters (lists for vectors). Raises SurfaceParameterError on an unknown type, on the
    non-serialisable "function" type, on missing or unknown keys, and on bad parameter values.
    """
    if not isinstance(d, Mapping):
        raise SurfaceParameterError(
            f"surface_from_dict: expected a dict with a 'type' key, got {_fmt(d)}"
        )
    valid = ", ".join(repr(name) for name in _BUILT_INS)
    if "type" not in d:
        raise SurfaceParameterError(
            f"surface_from_dict: missing key 'type' in {_fmt(dict(d))}; valid types: {valid}"
        )
    kind = d["type"]
    if kind == FunctionSurface.kind:
        raise SurfaceParameterError(
            "surface_from_dict: type 'function' cannot be rebuilt from a dict (its Python "
            f"callables are not serialised); build a FunctionSurface in code. Valid types: {valid}"
        )
    if not isinstance(kind, str) or kind not in _BUILT_INS:
        hint = did_you_mean(kind, _BUILT_INS) if isinstance(kind, str) else ""
        raise SurfaceParameterError(
            f"surface_from_dict: unknown surface type {kind!r}{hint}; valid types: {valid}"
        )
    cls, required, optional = _BUILT_INS[kind]
    params = {key: value for key, value in d.items() if key != "type"}
    missing = [key for key in required if key not in params]
    if missing:
        raise SurfaceParameterError(
            f"surface_from_dict: {kind} is missing parameter(s) "
            f"{', '.join(repr(key) for key in missing)}; required: {', '.join(required)}"
        )
    allowed = required + optional
    unknown = [key for key in params if key not in allowed]
    if unknown:
        key = str(unknown[0])
        raise SurfaceParameterError(
            f"surface_from_dict: unknown parameter {unknown[0]!r} for {kind}"
            f"{did_you_mean(key, allowed)}; valid parameters: {', '.join(allowed)}"
        )
    return cls(**params)

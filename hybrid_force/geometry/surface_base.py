"""The surface interface Φ(p) (paper eq. 1), the registry of surface types, and the checks
their implementations share.

:class:`Surface` is what the controller and the simulation use. A surface type registers
itself in its own module with :func:`register_surface` under its TOML ``type``; its
parameters are its dataclass fields declared with :func:`hybrid_force.schema.param` (the
scenario reader, ``to_dict`` and ``surface_from_dict`` read them there). The helpers below
check constructor parameters (raising SurfaceError naming the class, the parameter
and the value) and points p (BadInputError or SurfaceError naming the surface and the method).
"""

from __future__ import annotations

import abc
import contextlib
import contextvars
import dataclasses
import importlib
import math
import pkgutil
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import ArrayLike

import hybrid_force.geometry as package
from hybrid_force import _checks as checks
from hybrid_force.errors import BadInputError, SurfaceError
from hybrid_force.schema import Param, declared, specs

__all__ = [
    "MAX_LENGTH",
    "Surface",
    "plane_basis",
    "principal_curvatures",
    "register_offset",
    "register_surface",
    "surface_parameters",
    "surface_types",
    "tool_radius",
]

MAX_LENGTH = 1e6
"""The largest |coordinate| of a surface's point or centre and the largest radius [m]
(docs/scenarios.md): far beyond any arm's reach, and small enough that squares and products
of distances stay finite (a centre of 1e300 m made Φ(p) NaN)."""

#: An axis or normal shorter than this [m or unitless] counts as zero-length.
_MIN_DIRECTION_NORM = 1e-12
#: A cylinder's normal is undefined within ``_SINGULAR_RTOL * radius`` of its axis, a sphere's
#: within ``_SINGULAR_RTOL * radius`` of its centre (there ‖∇Φ‖ = 2ρ < 2e-9 · radius).
_SINGULAR_RTOL = 1e-9
#: The largest |coordinate| [m] of a point a surface evaluates: its square stays finite.
_MAX_POINT = 1e150
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
    return checks.number(value, what, SurfaceError, minimum=0.0, strict=True, unit=unit)


def _length(owner: str, name: str, value: object) -> float:
    """A positive length [m] of at most :data:`MAX_LENGTH` (a radius)."""
    out = _positive_float(owner, name, value)
    if out > MAX_LENGTH:
        raise SurfaceError(
            f"{owner}: parameter '{name}' must be at most MAX_LENGTH = {MAX_LENGTH:g} m, got "
            f"{_fmt(value)}"
        )
    return out


def _point3(owner: str, name: str, value: object) -> Vec3:
    """A point [m] (3 finite numbers), each coordinate within ±:data:`MAX_LENGTH`."""
    point = _vector3(owner, name, value)
    if max(abs(x) for x in point) > MAX_LENGTH:
        raise SurfaceError(
            f"{owner}: parameter '{name}' must have coordinates within ±MAX_LENGTH = "
            f"{MAX_LENGTH:g} m, got {_fmt(value)}"
        )
    return point


def _vector3(owner: str, name: str, value: object) -> Vec3:
    """Check that ``value`` is 3 finite real numbers [m] and return them as a float tuple."""
    what = f"{owner}: parameter '{name}'"
    array = checks.array(value, what, SurfaceError, valid="3 finite real numbers")
    if array.shape != (3,):
        raise SurfaceError(
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
        raise SurfaceError(
            f"{owner}: parameter '{name}' must be a non-zero direction "
            f"(norm >= {_MIN_DIRECTION_NORM:g}), got {_fmt(value)} with norm {norm:g}"
        )
    if abs(norm - 1.0) <= 4.0 * np.finfo(np.float64).eps:
        return (x, y, z)
    return (x / norm, y / norm, z / norm)


def _boolean(owner: str, name: str, value: object) -> bool:
    """Check that ``value`` is a bool (Python or numpy), not a truthy 1 or "yes"."""
    return checks.flag(value, f"{owner}: parameter '{name}'", SurfaceError)


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
            raise BadInputError(
                f"{owner!r}.{method}: point p must be 3 numbers [m], got {_fmt(p)} ({exc})"
            ) from exc
        if array.shape != (3,):
            raise BadInputError(
                f"{owner!r}.{method}: point p must have shape (3,), got shape {array.shape}: "
                f"{_fmt(p)}"
            )
        x, y, z = array.tolist()
    if not (abs(x) <= _MAX_POINT and abs(y) <= _MAX_POINT and abs(z) <= _MAX_POINT):
        # also refuses nan and inf; beyond 1e150 m the squares in Φ overflow (Φ would be nan)
        raise SurfaceError(
            f"{owner!r}.{method}: point p must be finite, each coordinate within ±"
            f"{_MAX_POINT:g} m, got [{x}, {y}, {z}]"
        )
    return (x, y, z)


def plane_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (u, w) with (u, w, n) a right-handed orthonormal frame, n: (3,) unit.

    u is the world axis least aligned with n, projected on the plane normal to n, so that for
    n = ±z the pair is (x, ±y) (the drawings' in-plane axes)."""
    e = np.eye(3)[int(np.argmin(np.abs(n)))]
    u = e - (e @ n) * n
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


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

        Raises SurfaceError where ∇Φ (nearly) vanishes.
        """

    @abc.abstractmethod
    def closest_point(self, p: ArrayLike) -> np.ndarray:
        """Foot point on the surface nearest to p: (3,) [m]."""

    #: What :meth:`distance` is, which decides how :meth:`offset` treats a tool of radius r:
    #: ``"phi"``: Φ itself is the signed metric distance [m] (‖∇Φ‖ = 1), so Φ − r is the
    #: offset; ``"exact"``: ``distance`` is the exact metric distance to an exact
    #: ``closest_point`` (Φ is not), so the offset is d − r with the distance's own
    #: derivatives; ``""``: not a metric distance (first order, or unknown): no offset.
    metric_distance: ClassVar[str] = ""

    def offset(self, radius: float) -> Surface:
        """The offset surface Φ_r = 0 at metric distance ``radius`` [m] from this one on its
        free side: the locus of the centre of a ball of that radius touching it (a ball-end
        tool, ``tool.radius``). ``radius = 0``: this very surface.

        The default is the generic offset registered for :attr:`metric_distance`
        (:func:`register_offset`: Φ − r or d − r, :mod:`hybrid_force.geometry.offset`); it
        refuses (SurfaceError naming ``tool.radius`` and the value) a surface whose distance
        is not a metric one. The built-in surfaces override it with their exact offset of the
        same type.
        """
        r = tool_radius(radius)
        if r == 0.0:
            return self
        import_geometry()  # the generic offsets register themselves in their module
        build = _OFFSETS.get(self.metric_distance)
        if build is None:
            raise SurfaceError(
                f"tool.radius = {radius!r} m needs a surface whose distance is a metric one (the "
                f"tool centre follows the surface at distance r from the part); {self!r} does "
                "not declare its distance metric (a first-order Φ/‖∇Φ‖ is not): use "
                "tool.radius = 0, or a surface that declares a metric distance (a "
                "FunctionSurface with metric=True)",
                key="tool.radius",
                value=radius,
            )
        return build(self, r)

    def concave_radius(self) -> tuple[float, np.ndarray | None]:
        """(the smallest radius of curvature [m] where the surface is concave seen from its
        free side, a point (3,) [m] where it is that small or None when it is so everywhere);
        (inf, None) when it is nowhere concave or not known. A ball tool of a larger radius
        cannot reach the bottom there (:func:`~hybrid_force.geometry.offset.tool_surfaces`)."""
        return math.inf, None

    def to_dict(self) -> dict[str, Any]:
        """JSON-able description ``{"type": kind, ...parameters as floats / lists}`` (its
        declared parameters, :func:`surface_parameters`)."""
        return parameters_dict(self)

    def patch(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray | None:
        """A grid of points on the surface covering the part near ``points`` (M, 3) [m], at
        least ``margin`` [m] beyond them where the surface is open: (n, m, 3) [m], rows and
        columns joined as a quad mesh (the replay and the run figures draw it). None: this
        surface cannot be drawn (the default)."""
        return None


def principal_curvatures(grad: np.ndarray, hess: np.ndarray) -> tuple[float, float]:
    """(κ₁ ≥ κ₂) [1/m] of the level set of Φ with gradient (3,) and Hessian (3, 3) [1/m]: the
    eigenvalues of Tᵀ ∇²Φ T / ‖∇Φ‖ (T an orthonormal tangent basis); > 0 convex seen from
    the free side (where ∇Φ points)."""
    g = float(np.linalg.norm(grad))
    n = grad / g
    e = np.eye(3)[int(np.argmin(np.abs(n)))]
    t1 = np.cross(n, e)
    t1 /= np.linalg.norm(t1)
    t = np.stack([t1, np.cross(n, t1)])
    k = np.linalg.eigvalsh(t @ hess @ t.T / g)
    return float(k[1]), float(k[0])


def tool_radius(radius: object) -> float:
    """A tool's radius [m] as a float, checked: a finite number in [0, MAX_LENGTH]
    (SurfaceError naming ``tool.radius`` and the value)."""
    r = checks.number(radius, "tool.radius", SurfaceError, minimum=0.0, unit="m")
    if r > MAX_LENGTH:
        raise SurfaceError(
            f"tool.radius = {radius!r} m must be at most MAX_LENGTH = {MAX_LENGTH:g} m",
            key="tool.radius",
            value=radius,
        )
    return r


# --- registry --------------------------------------------------------------------------------
_OFFSETS: dict[str, Callable[[Surface, float], Surface]] = {}


def register_offset(metric: str) -> Callable[[OffsetT], OffsetT]:
    """Class decorator: the generic offset ``cls(surface, radius)`` of the surfaces whose
    :attr:`Surface.metric_distance` is ``metric`` (the default :meth:`Surface.offset`)."""

    def register(cls: OffsetT) -> OffsetT:
        _OFFSETS[metric] = cls
        return cls

    return register


_SURFACE_TYPES: dict[str, type[Surface]] = {}
_found = False
S = TypeVar("S", bound=type[Surface])
OffsetT = TypeVar("OffsetT", bound=Callable[[Surface, float], Surface])


def register_surface(cls: S) -> S:
    """Class decorator: register a surface type under its ``kind`` (its TOML ``type``)."""
    _SURFACE_TYPES[cls.kind] = cls
    return cls


def import_geometry() -> None:
    """Import every public module of :mod:`hybrid_force.geometry` once, so that each surface
    and path type defined (and registered) in any of them is known without being listed."""
    global _found
    if not _found:
        _found = True

        for info in pkgutil.iter_modules(package.__path__):
            if not info.name.startswith("_"):
                importlib.import_module(f"{package.__name__}.{info.name}")


def surface_types() -> dict[str, type[Surface]]:
    """Every registered surface type by its ``kind``, in registration order (every geometry
    module imported first: :func:`import_geometry`)."""
    import_geometry()
    return _SURFACE_TYPES


def surface_parameters(cls: type) -> list[tuple[str, dataclasses.Field[Any], Param]]:
    """The parameters a surface type declares (its :func:`~hybrid_force.schema.param`
    fields): (key, field, Param) in order; the key is the TOML key and the constructor's."""
    return [(spec.key or f.name, f, spec) for f, spec in specs(cls) if declared(f) and spec.toml]


def parameters_dict(surface: Surface) -> dict[str, Any]:
    """``{"type": kind, key: value}`` of a declared surface, vectors as lists (JSON-able)."""
    out: dict[str, Any] = {"type": surface.kind}
    for key, f, _ in surface_parameters(type(surface)):
        value = getattr(surface, f.name)
        out[key] = list(value) if isinstance(value, tuple) else value
    return out


_PREBUILT: contextvars.ContextVar[Mapping[str, tuple[dict[str, Any], Surface]] | None] = (
    contextvars.ContextVar("prebuilt_surfaces", default=None)
)


@contextlib.contextmanager
def prebuilt_surfaces(built: Mapping[str, tuple[dict[str, Any], Surface]]) -> Iterator[None]:
    """While open, :func:`surface_from_table` takes a surface table named in ``built``
    ({table name: (its checked values, the surface)}) from there when its values are the
    same: a sweep's worker, which may not see the files a mesh part was built from."""
    token = _PREBUILT.set(built)
    try:
        yield
    finally:
        _PREBUILT.reset(token)


def surface_from_table(
    cls: type[Surface], name: str, values: dict[str, Any], folder: Path
) -> Surface:
    """Surface type ``cls`` from table ``name``'s checked ``values``: ``cls(**values)``, or
    ``cls.from_table(values, folder, name)`` for a type built from a file relative to
    ``folder`` (a mesh part), unless :func:`prebuilt_surfaces` holds it."""
    from_table = getattr(cls, "from_table", None)
    if from_table is None:
        return cls(**values)
    given = (_PREBUILT.get() or {}).get(name)
    if given is not None and given[0] == values:
        return given[1]
    return from_table(values, folder, name)

"""Desired task-space paths p_d(t).

A path gives the desired tool position p_d(t) (3,) [m] together with its velocity
ṗ_d(t) (3,) [m/s] and acceleration p̈_d(t) (3,) [m/s²]; the closed-loop inverse
kinematics of the paper (eq. 27) turns it into a desired joint path q_d(t).

* :class:`Helix` – a circular helix about an arbitrary axis; :func:`paper_helix` is
  the helix of eq. 25, (0.4 cos t, 0.4 sin t, 10 + t/10).
* :class:`Circle` – a circle in an arbitrary plane (a helix that does not rise).
* :class:`FunctionPath` – any path given as Python callables of t; missing
  derivatives come from fourth-order central finite differences.
* paths on a surface, in its own coordinates: waypoints joined by a C² spline
  (:mod:`.waypoints`) and a back-and-forth raster (:mod:`.raster`), both
  :class:`~hybrid_force.geometry.surface_path.SurfacePath`.
* :func:`check_on_surface` (in :mod:`.on_surface`) – the worst |d| of a path against a
  surface over a time span, so a scenario can verify that its desired path lies on the
  obstacle (the paper requires p_d to lie on Φ(p) = 0, eq. 26).

Helix and circle share one parametrisation (section 6.1 generalised)::

    p(t) = c + rise·t·a + r (cos θ e1 + sin θ e2),   θ = phase + omega·t,

with a the unit axis (the circle's plane normal) and (e1, e2, a) the right-handed
orthonormal frame of :func:`axis_frame`: e1 is world x projected onto the plane ⟂ a
and normalised (world y if a is (anti)parallel to x), e2 = a × e1. The phase is
measured from e1, and omega > 0 turns counter-clockwise seen from the tip of a.
For a = z, phase 0 starts on +x and the motion matches eq. 25.

Paths round-trip through plain dictionaries (:meth:`Path.to_dict`,
:func:`path_from_dict`) so that scenario and result files can store them.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Mapping
from dataclasses import KW_ONLY, dataclass, field
from typing import Any, ClassVar, TypeVar

import numpy as np

from hybrid_force import _checks as checks
from hybrid_force._lazy import LazyKernels
from hybrid_force.errors import PathError, did_you_mean
from hybrid_force.geometry.surface_base import MAX_LENGTH, import_geometry
from hybrid_force.schema import MISSING_VALUE, declared, default_of, param, specs

_K = LazyKernels("hybrid_force.geometry._kernels")

__all__ = [
    "Circle",
    "FunctionPath",
    "Helix",
    "Path",
    "axis_frame",
    "paper_helix",
    "path_from_dict",
    "path_time",
]

_AXIS_MIN_NORM = 1e-12
"""An axis or normal shorter than this [any unit] counts as zero."""

_PARALLEL_TOL = 1e-6
"""If world x projected onto the plane ⟂ a is shorter than this, a counts as ∥ x."""

_UNITS = {"omega": "rad/s", "rise": "m/s", "phase": "rad"}
"""Units of the scalar parameters of a helix or circle, shown in error messages."""


# --- helpers -------------------------------------------------------------------------------------
def path_time(path: object, t: object) -> float:
    """The time ``t`` [s] at which a path is evaluated, as a float; PathError
    (key ``t``) for a non-finite or non-real one, instead of a raw math or numpy error."""
    if isinstance(t, float) and math.isfinite(t):  # the common case, without the generic check
        return float(t)
    what = f"{type(path).__name__}: the time t at which it is evaluated"
    try:
        return checks.number(t, what, PathError, unit="s")
    except PathError as exc:  # the same message, with its key
        raise PathError(str(exc), key="t", value=t) from None


def _finite_float(owner: str, name: str, value: object, unit: str = "") -> float:
    """Return ``value`` (a real number, not a bool) as a finite float or raise
    :class:`PathError` naming ``owner.name``."""
    return checks.number(value, f"{owner}.{name}", PathError, unit=unit)


def _vector3(owner: str, name: str, value: object) -> tuple[float, float, float]:
    """Return ``value`` as a finite 3-vector of real numbers (tuple of floats) or raise."""
    what = f"{owner}.{name}"
    arr = checks.array(value, what, PathError, valid="3 finite real numbers")
    if arr.shape != (3,):
        raise PathError(
            f"{what} must be 3 finite numbers (shape (3,)), got {checks.shown(value)} "
            f"with shape {arr.shape}"
        )
    return (float(arr[0]), float(arr[1]), float(arr[2]))


def _unit3(owner: str, name: str, value: object) -> np.ndarray:
    """Return ``value`` normalised to unit length (3,) or raise if zero or non-finite."""
    vec = np.array(_vector3(owner, name, value))
    with np.errstate(over="ignore"):
        norm = float(np.linalg.norm(vec))
    if norm == math.inf:  # the squares overflowed (1e300 entries): scale first, same direction
        vec = vec / float(np.abs(vec).max())
        norm = float(np.linalg.norm(vec))
    if not norm >= _AXIS_MIN_NORM:
        raise PathError(
            f"{owner}.{name} must be a non-zero direction (length >= {_AXIS_MIN_NORM:g}), "
            f"got {value!r} with length {norm:g}"
        )
    return vec / norm


def axis_frame(axis: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Right-handed orthonormal frame (e1, e2, a) for a direction ``axis``.

    axis: (3,) any non-zero finite vector (it is normalised to a).
    e1 = world x projected onto the plane ⟂ a and normalised; if a is (anti)parallel to
    world x (projection shorter than 1e-6) world y is used instead. e2 = a × e1, so
    e1 × e2 = a. Returns three (3,) unit vectors [-].

    Raises PathError for a zero or non-finite axis.
    """
    a = _unit3("axis_frame", "axis", axis)
    ref = np.array([1.0, 0.0, 0.0])
    e1 = ref - float(a @ ref) * a
    if float(np.linalg.norm(e1)) < _PARALLEL_TOL:
        ref = np.array([0.0, 1.0, 0.0])
        e1 = ref - float(a @ ref) * a
    e1 /= np.linalg.norm(e1)
    # A second Gram-Schmidt pass keeps e1 ⟂ a to rounding even when x is nearly ∥ a.
    e1 -= float(a @ e1) * a
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    e2 /= np.linalg.norm(e2)
    return e1, e2, a


# --- the path interface --------------------------------------------------------------------------
_JERK_STEP = 1e-5  # [s] central difference of p̈_d (Path.direction_jet)


class Path(abc.ABC):
    """A desired task-space path p_d(t) with its first two time derivatives."""

    TYPE: ClassVar[str] = ""
    """Its TOML ``type`` (a registered path type: :func:`register_path`)."""

    # The closed form as a small read-only float array that compiled code evaluates
    # (hybrid_force._kernels.path_sample): [0, phase, ω, basis (12)] for a helix or a circle;
    # empty when there is none (evaluated in Python).
    _descriptor: ClassVar[np.ndarray] = np.zeros(0)

    @abc.abstractmethod
    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (p_d (3,) [m], ṗ_d (3,) [m/s], p̈_d (3,) [m/s²]) at time t [s].

        The arrays are fresh copies; the caller may modify them.
        """

    def position(self, t: float) -> np.ndarray:
        """Return p_d(t) (3,) [m] only."""
        return self.evaluate(t)[0]

    def evaluate_into(self, t: float, p: np.ndarray, v: np.ndarray, a: np.ndarray) -> None:
        """Write p_d, ṗ_d, p̈_d at t [s] into the (3,) arrays p, v, a (hot path).

        The default copies the result of :meth:`evaluate`; analytic paths override it.
        """
        p[:], v[:], a[:] = self.evaluate(t)

    def evaluate_with_direction_into(self, t: float, sample: np.ndarray, jet: np.ndarray) -> None:
        """:meth:`evaluate_into` the rows of sample (3, 3) and :meth:`direction_jet` into jet
        (3, 3) at t [s] (hot path; a path on a surface shares the work of the two)."""
        self.evaluate_into(t, sample[0], sample[1], sample[2])
        jet[:] = self.direction_jet(t)

    def direction_jet(self, t: float) -> np.ndarray:
        """(3, 3) rows w, ẇ, ẅ with w along the direction of travel at t [s]; only the
        direction of w and its rates are meaningful (callers normalise it).

        The default is w = ṗ_d (rows ṗ_d, p̈_d, p⃛_d, p⃛_d a central difference of p̈_d, step
        1e-5 s, error ~1e-10 relative for a smooth path): undefined where the path stops.
        Paths on a surface override it with their unit tangent, defined at rest too.
        """
        t = path_time(self, t)
        _, v, a = self.evaluate(t)
        h = _JERK_STEP
        return np.array([v, a, (self.evaluate(t + h)[2] - self.evaluate(t - h)[2]) / (2.0 * h)])

    @abc.abstractmethod
    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-able dict ``{"type": ..., <parameters>}`` for :func:`path_from_dict`."""


# --- registry ----------------------------------------------------------------------------------
_PATH_TYPES: dict[str, type[Path]] = {}
P = TypeVar("P", bound=type[Path])


def register_path(cls: P) -> P:
    """Class decorator: register a path type under its ``TYPE`` (the TOML ``type``). Its
    parameters are its :func:`~hybrid_force.schema.param` fields, or those of its ``PARAMS``
    dataclass (a path on a surface: :func:`path_parameters`)."""
    _PATH_TYPES[cls.TYPE] = cls
    return cls


def path_types() -> dict[str, type[Path]]:
    """Every registered path type by its ``TYPE`` (every geometry module imported first)."""
    import_geometry()
    return _PATH_TYPES


def path_parameters(cls: type) -> type:
    """The dataclass that declares a path type's parameters: its ``PARAMS``, or itself."""
    declaration: type = getattr(cls, "PARAMS", cls)
    return declaration


class _CircularPath(Path):
    """Shared evaluation of Helix and Circle: p = c + rise·t·a + r(cos θ e1 + sin θ e2)."""

    # Set in _setup(): B (4, 3) with rows r·e1, r·e2, rise·a, c, so that
    # p = [cos θ, sin θ, t, 1] @ B, ṗ = [−ω sin θ, ω cos θ, 1, 0] @ B,
    # p̈ = [−ω² cos θ, −ω² sin θ, 0, 0] @ B.
    _basis: np.ndarray
    _frame: tuple[np.ndarray, np.ndarray, np.ndarray]

    center: tuple[float, float, float]
    radius: float
    omega: float
    phase: float

    def _validate(self, direction: str, scalars: tuple[str, ...]) -> None:
        """Check center, radius > 0, the direction field and the scalar fields, store them as
        floats, and build the frame and basis (rise along the direction: 0 for a circle)."""
        owner = type(self).__name__
        center = _vector3(owner, "center", self.center)
        radius = checks.number(
            self.radius, f"{owner}.radius", PathError, minimum=0.0, strict=True, unit="m"
        )
        raw = getattr(self, direction)
        vector = _vector3(owner, direction, raw)
        unit = _unit3(owner, direction, raw)
        for name in scalars:
            value = _finite_float(owner, name, getattr(self, name), unit=_UNITS[name])
            object.__setattr__(self, name, value)
        # the surfaces' bound on magnitudes: p(t), r ω² and r ω³ stay finite (ω = 1e300 gave
        # NaN), and a phase keeps the resolution of ω t (1e300 rad swallowed it)
        sizes = {"center": max(abs(x) for x in center), "radius": radius}
        sizes.update((name, abs(getattr(self, name))) for name in scalars)
        for name, size in sizes.items():
            if size > MAX_LENGTH:
                raise PathError(
                    f"{owner}.{name} = {checks.shown(getattr(self, name))} is beyond "
                    f"MAX_LENGTH = {MAX_LENGTH:g} {_UNITS.get(name, 'm')}",
                    key=name,
                    value=getattr(self, name),
                )
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "radius", radius)
        object.__setattr__(self, direction, vector)
        self._setup(center, radius, unit, getattr(self, "rise", 0.0))

    def _setup(
        self, center: tuple[float, float, float], radius: float, axis: np.ndarray, rise: float
    ) -> None:
        e1, e2, a = axis_frame(axis)
        for v in (e1, e2, a):
            v.setflags(write=False)
        basis = np.vstack([radius * e1, radius * e2, rise * a, np.asarray(center)])
        basis.setflags(write=False)
        object.__setattr__(self, "_frame", (e1, e2, a))
        object.__setattr__(self, "_basis", basis)
        desc = np.array([0.0, self.phase, self.omega, *basis.ravel()])
        desc.setflags(write=False)
        object.__setattr__(self, "_descriptor", desc)

    def to_dict(self) -> dict[str, Any]:
        """``{"type", <its declared parameters>}`` (vectors as lists) for :func:`path_from_dict`."""
        out: dict[str, Any] = {"type": self.TYPE}
        for f, _ in specs(type(self)):
            if declared(f):
                value = getattr(self, f.name)
                out[f.name] = list(value) if isinstance(value, tuple) else value
        return out

    @property
    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The right-handed orthonormal frame (e1, e2, a), each (3,) [-], read-only arrays."""
        return self._frame

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (p (3,) [m], ṗ (3,) [m/s], p̈ (3,) [m/s²]) at t [s], analytically."""
        t = path_time(self, t)
        w = self.omega
        th = self.phase + w * t
        co = math.cos(th)
        si = math.sin(th)
        wc = w * co
        ws = w * si
        coeff = np.array(((co, si, t, 1.0), (-ws, wc, 1.0, 0.0), (-w * wc, -w * ws, 0.0, 0.0)))
        p, v, acc = coeff @ self._basis
        return p, v, acc

    def evaluate_into(self, t: float, p: np.ndarray, v: np.ndarray, a: np.ndarray) -> None:
        """:meth:`evaluate` written into p, v, a (3,) in one compiled call (hot path)."""
        _K.circular_path(self._basis, self.phase, self.omega, float(t), p, v, a)

    def position(self, t: float) -> np.ndarray:
        """Return p(t) (3,) [m]."""
        t = path_time(self, t)
        th = self.phase + self.omega * t
        return np.array((math.cos(th), math.sin(th), t, 1.0)) @ self._basis

    def direction_jet(self, t: float) -> np.ndarray:
        """ṗ, p̈ and p⃛ = r ω³ (sin θ e1 − cos θ e2) in closed form: (3, 3) [m/s, m/s², m/s³]."""
        t = path_time(self, t)
        _, v, a = self.evaluate(t)
        e1, e2, _ = self._frame
        th = self.phase + self.omega * t
        jerk = self.radius * self.omega**3 * (math.sin(th) * e1 - math.cos(th) * e2)
        return np.array([v, a, jerk])


@register_path
@dataclass(frozen=True)
class Helix(_CircularPath):
    """Circular helix p(t) = c + rise·t·a + r(cos θ e1 + sin θ e2), θ = phase + omega·t.

    center: (3,) [m] the point on the axis at t = 0.
    radius: [m] > 0.
    axis: (3,) [-] direction of the helix axis (any non-zero length, normalised to a).
    omega: [rad/s] angular rate; > 0 turns counter-clockwise seen from the tip of a.
    rise: [m/s] speed along a (may be 0 or negative).
    phase: [rad] angle at t = 0, measured from e1 (see :func:`axis_frame`).

    Eq. 25 is ``Helix((0, 0, 10), 0.4, omega=1, rise=0.1)`` (:func:`paper_helix`).
    """

    TYPE: ClassVar[str] = "helix"

    center: tuple[float, float, float] = param(unit="m", doc="the point on the axis at t = 0")
    radius: float = param(unit="m", minimum=0.0, strict=True, doc="radius")
    _: KW_ONLY
    axis: tuple[float, float, float] = param((0.0, 0.0, 1.0), doc="direction of the axis")
    omega: float = param(unit="rad/s", doc="angular rate (> 0: counter-clockwise about a)")
    rise: float = param(unit="m/s", doc="speed along the axis")
    phase: float = param(0.0, unit="rad", doc="angle at t = 0, from e1")
    _basis: np.ndarray = field(init=False, repr=False, compare=False)
    _frame: tuple[np.ndarray, np.ndarray, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._validate("axis", ("omega", "rise", "phase"))


@register_path
@dataclass(frozen=True)
class Circle(_CircularPath):
    """Circle p(t) = c + r(cos θ e1 + sin θ e2), θ = phase + omega·t, in the plane ⟂ normal.

    center: (3,) [m]; radius: [m] > 0; normal: (3,) [-] normal of the circle's plane
    (any non-zero length); omega: [rad/s], > 0 turns counter-clockwise seen from the tip
    of the normal; phase: [rad] angle at t = 0 measured from e1 (see :func:`axis_frame`).
    """

    TYPE: ClassVar[str] = "circle"

    center: tuple[float, float, float] = param(unit="m", doc="centre")
    radius: float = param(unit="m", minimum=0.0, strict=True, doc="radius")
    normal: tuple[float, float, float] = param(doc="normal of the circle's plane")
    omega: float = param(unit="rad/s", doc="angular rate (> 0: counter-clockwise about n)")
    phase: float = param(0.0, unit="rad", doc="angle at t = 0, from e1")
    _basis: np.ndarray = field(init=False, repr=False, compare=False)
    _frame: tuple[np.ndarray, np.ndarray, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._validate("normal", ("omega", "phase"))


def paper_helix() -> Helix:
    """The desired path of eq. 25: p_d(t) = (0.4 cos t, 0.4 sin t, 10 + t/10) [m].

    It lies on the cylinder x² + y² = 0.4² of eq. 26.
    """
    return Helix(center=(0.0, 0.0, 10.0), radius=0.4, axis=(0.0, 0.0, 1.0), omega=1.0, rise=0.1)


# --- paths given as Python functions -------------------------------------------------------------
_VecFn = Callable[[float], Any]

DEFAULT_FD_STEP = 1e-3
"""Default finite-difference step h [s] of :class:`FunctionPath`."""


class FunctionPath(Path):
    """A path given by Python callables of t [s], each returning a (3,) array-like.

    position(t) -> p (3,) [m]; velocity(t) -> ṗ (3,) [m/s] and acceleration(t) -> p̈
    (3,) [m/s²] are optional. A missing derivative is computed by fourth-order
    central finite differences with step h = ``step`` [s] (default 1e-3 s):

    * ṗ ≈ [p(t−2h) − 8p(t−h) + 8p(t+h) − p(t+2h)] / (12h),
      error ≤ h⁴/30·max|p⁽⁵⁾| + 1.5·ε·max|p|/h  (ε = 2.2e-16);
    * p̈, if ``velocity`` is given, by the same stencil applied to ṗ,
      error ≤ h⁴/30·max|p⁽⁶⁾| + 1.5·ε·max|ṗ|/h;
    * p̈, if only ``position`` is given,
      ≈ [−p(t−2h) + 16p(t−h) − 30p(t) + 16p(t+h) − p(t+2h)] / (12h²),
      error ≤ h⁴/90·max|p⁽⁶⁾| + 5.4·ε·max|p|/h².

    The maxima are over [t−2h, t+2h]. With the default h = 1e-3 s and the paper's helix
    (|p| ≈ 10 m, derivatives ≤ 1) that is about 4e-12 m/s for ṗ and 1.2e-8 m/s² for p̈
    (rounding-dominated; measured errors are smaller). The callables must be defined on
    [t−2h, t+2h], also for t near the start of a run. Each evaluation costs up to 9 calls
    of ``position`` plus the given derivatives, so give analytic derivatives in hot loops.

    A non-finite or wrongly shaped result raises :class:`PathError` naming the
    callable and t. A FunctionPath cannot be written to a dict (:meth:`to_dict` raises).
    """

    TYPE: ClassVar[str] = "function"

    def __init__(
        self,
        position: _VecFn,
        velocity: _VecFn | None = None,
        acceleration: _VecFn | None = None,
        *,
        step: float = DEFAULT_FD_STEP,
    ) -> None:
        for name, fn, required in (
            ("position", position, True),
            ("velocity", velocity, False),
            ("acceleration", acceleration, False),
        ):
            if (fn is not None or required) and not callable(fn):
                raise PathError(
                    f"FunctionPath.{name} must be a callable of t returning 3 numbers, "
                    f"got {checks.shown(fn)}"
                )
        h = checks.number(step, "FunctionPath.step", PathError, minimum=0.0, strict=True, unit="s")
        self._position_fn = position
        self._velocity_fn = velocity
        self._acceleration_fn = acceleration
        self.step = h

    def __repr__(self) -> str:
        def name(fn: object) -> str:
            return "None" if fn is None else getattr(fn, "__qualname__", repr(fn))

        return (
            f"FunctionPath(position={name(self._position_fn)}, "
            f"velocity={name(self._velocity_fn)}, "
            f"acceleration={name(self._acceleration_fn)}, step={self.step!r})"
        )

    @staticmethod
    def _call(kind: str, fn: _VecFn, t: float) -> np.ndarray:
        raw = fn(t)
        try:
            out = np.array(raw, dtype=float)
        except (TypeError, ValueError, OverflowError) as exc:
            raise PathError(
                f"FunctionPath.{kind}({t!r}) must return 3 numbers, got {raw!r} ({exc})"
            ) from exc
        if out.shape != (3,):
            raise PathError(
                f"FunctionPath.{kind}({t!r}) must return shape (3,), got shape {out.shape}"
            )
        if not np.all(np.isfinite(out)):
            raise PathError(
                f"FunctionPath.{kind}({t!r}) returned a non-finite value {out.tolist()}"
            )
        return out

    def _first_derivative(self, kind: str, fn: _VecFn, t: float) -> np.ndarray:
        h = self.step
        fm2 = self._call(kind, fn, t - 2.0 * h)
        fm1 = self._call(kind, fn, t - h)
        fp1 = self._call(kind, fn, t + h)
        fp2 = self._call(kind, fn, t + 2.0 * h)
        return (fm2 - fp2 + 8.0 * (fp1 - fm1)) / (12.0 * h)

    def position(self, t: float) -> np.ndarray:
        """Return p_d(t) (3,) [m]."""
        return self._call("position", self._position_fn, path_time(self, t))

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (p (3,) [m], ṗ (3,) [m/s], p̈ (3,) [m/s²]); see the class doc for accuracy."""
        t = path_time(self, t)
        p = self._call("position", self._position_fn, t)
        if self._velocity_fn is not None:
            v = self._call("velocity", self._velocity_fn, t)
        else:
            v = self._first_derivative("position", self._position_fn, t)
        if self._acceleration_fn is not None:
            a = self._call("acceleration", self._acceleration_fn, t)
        elif self._velocity_fn is not None:
            a = self._first_derivative("velocity", self._velocity_fn, t)
        else:
            h = self.step
            fn = self._position_fn
            fm2 = self._call("position", fn, t - 2.0 * h)
            fm1 = self._call("position", fn, t - h)
            fp1 = self._call("position", fn, t + h)
            fp2 = self._call("position", fn, t + 2.0 * h)
            a = (16.0 * (fm1 + fp1) - (fm2 + fp2) - 30.0 * p) / (12.0 * h * h)
        return p, v, a

    def to_dict(self) -> dict[str, Any]:
        """Not available: Python callables cannot be stored in a scenario or result file."""
        raise PathError(
            f"{self!r} holds Python callables and cannot be written to a dict; "
            f"serialisable path types are {sorted(path_types())}"
        )


def path_from_dict(d: Mapping[str, Any]) -> Path:
    """Build a path from ``{"type": "helix" | "circle" | "waypoints" | "raster", <parameters>}``
    (inverse of to_dict; a waypoint or raster dict holds its surface's dict).

    Raises PathError for an unknown type, missing or unknown keys, or bad values.
    """
    if not isinstance(d, Mapping):
        raise PathError(
            f"path must be a table/dict with a 'type' key, got {d!r} ({type(d).__name__})"
        )
    if "type" not in d:
        raise PathError(
            f"path dict has no 'type' key; valid types: {sorted(path_types())}; got {dict(d)!r}"
        )
    kind = d["type"]
    types = path_types()
    names = sorted(types)
    if not isinstance(kind, str) or kind not in types:
        hint = did_you_mean(kind, names) if isinstance(kind, str) else ""
        raise PathError(f"path.type {kind!r} is unknown{hint}; valid types: {names}")
    cls = types[kind]
    from_dict = getattr(cls, "from_dict", None)
    if from_dict is not None:  # a path on a surface holds its surface's dict
        built: Path = from_dict(d)
        return built
    declared_fields = [(f.name, default_of(f)) for f, _ in specs(cls) if declared(f)]
    required = [name for name, default in declared_fields if default is MISSING_VALUE]
    optional = [name for name, default in declared_fields if default is not MISSING_VALUE]
    valid = (*required, *optional)
    params = {k: v for k, v in d.items() if k != "type"}
    for key in params:
        if key not in valid:
            raise PathError(
                f"path.{key} is not a parameter of a {kind} path{did_you_mean(str(key), valid)}; "
                f"valid keys: {['type', *valid]}"
            )
    missing = [k for k in required if k not in params]
    if missing:
        raise PathError(
            f"{kind} path is missing {missing}; required keys: {required}, optional: {optional}"
        )
    return cls(**params)

"""A user-defined surface: Φ(p) given by Python callables, the missing derivatives by finite
differences of documented accuracy.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force.errors import BadInputError, SurfaceError
from hybrid_force.geometry.surface_base import (
    Surface,
    _boolean,
    _fmt,
    _positive_float,
    _xyz,
    tool_radius,
)

__all__ = ["FunctionSurface"]

#: Default finite-difference steps of :class:`FunctionSurface` [m], see its docstring.
_DEFAULT_STEP = 6.0e-6
_DEFAULT_HESSIAN_STEP = 1.2e-4
_DEFAULT_SINGULAR_TOL = 1e-12


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
    SurfaceError where ‖∇Φ‖ < ``singular_tol`` (same units as ∇Φ).
    ``to_dict`` gives ``{"type": "function"}`` only: a function surface cannot be rebuilt
    from a dict.

    ``metric=True`` declares the distance an exact signed metric distance [m]: the ``distance``
    callable's when given, else Φ itself (‖∇Φ‖ = 1, e.g. a plane n·p − c). Only then does
    :meth:`offset` (a ball-end tool, ``tool.radius`` > 0) accept the surface: the tool centre
    follows d − r = 0. The first-order Φ/‖∇Φ‖ is not a metric distance, so a surface that does
    not declare one is refused a tool radius.

    Results of the callables are checked: a non-finite Φ raises SurfaceError, a gradient not
    of shape (3,) or a Hessian not of shape (3, 3) raises BadInputError, naming the callable.
    """

    kind: ClassVar[str] = "function"

    phi_function: PointFunction
    gradient_function: PointFunction | None
    hessian_function: PointFunction | None
    distance_function: PointFunction | None
    step: float
    hessian_step: float
    singular_tol: float
    metric: bool

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
        metric: bool = False,
    ) -> None:
        owner = "FunctionSurface"
        if not callable(phi):
            raise SurfaceError(
                f"FunctionSurface: parameter 'phi' must be a callable phi(p) -> float, "
                f"got {_fmt(phi)}"
            )
        for name, function in (
            ("gradient", gradient),
            ("hessian", hessian),
            ("distance", distance),
        ):
            if function is not None and not callable(function):
                raise SurfaceError(
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
            ("metric", _boolean(owner, "metric", metric)),
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
        if self.metric:
            parts.append("metric=True")
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
            raise BadInputError(
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
            raise SurfaceError(
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

    def offset(self, radius: float) -> Surface:
        """The offset by ``radius`` [m] (a ball-end tool's centre, module
        :mod:`~hybrid_force.geometry.offset`), a FunctionSurface too: Φ − r with the user's
        derivatives when Φ is the metric distance, else d − r of the ``distance`` callable
        (derivatives by finite differences). SurfaceError naming ``tool.radius`` without
        ``metric=True``."""
        r = tool_radius(radius)
        if r == 0.0:
            return self
        if not self.metric:
            raise SurfaceError(
                f"tool.radius = {radius!r} m needs a metric distance (the tool centre follows "
                f"the surface at distance r from the part); {self!r} does not declare one (its "
                "distance is first order): give FunctionSurface(..., metric=True) when Φ, or "
                "the distance callable, is the exact signed distance [m], or use tool.radius = 0",
                key="tool.radius",
                value=radius,
            )
        given = self.distance_function
        source = self.phi_function if given is None else given

        def shifted(p: np.ndarray) -> float:
            return self._call_scalar(source, "distance" if given else "phi", p) - r

        shifted.__qualname__ = f"{_callable_name(source)} - {r!r}"
        same = given is None  # Φ is the distance: its derivatives are the offset's
        return FunctionSurface(
            shifted,
            self.gradient_function if same else None,
            self.hessian_function if same else None,
            shifted,
            step=self.step,
            hessian_step=self.hessian_step,
            singular_tol=self.singular_tol,
            metric=True,
        )

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "function"}``: not round-trippable (the callables are not serialised)."""
        return {"type": self.kind}

"""Tests of hybrid_force.geometry.function_surface: a surface given by Python callables.

References: hand-derived derivatives of a wavy surface, the built-in sphere and plane, and the
exact distance of a ball (the first-order distance's error is −d²/(2‖p‖) by a Taylor expansion).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hybrid_force.errors import BadInputError, SurfaceError
from hybrid_force.geometry.builtin_surfaces import Plane, Sphere
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.surfaces import surface_from_dict

A = 0.7


def wavy_phi(p: np.ndarray) -> float:
    """Φ = z − A sin x cos y + 0.1 x² (unit scale, non-polynomial)."""
    x, y, z = p
    return float(z - A * math.sin(x) * math.cos(y) + 0.1 * x * x)


def wavy_gradient(p: np.ndarray) -> np.ndarray:
    x, y, _ = p
    return np.array([-A * math.cos(x) * math.cos(y) + 0.2 * x, A * math.sin(x) * math.sin(y), 1.0])


def wavy_hessian(p: np.ndarray) -> np.ndarray:
    x, y, _ = p
    hxx = A * math.sin(x) * math.cos(y) + 0.2
    hxy = A * math.cos(x) * math.sin(y)
    hyy = A * math.sin(x) * math.cos(y)
    return np.array([[hxx, hxy, 0.0], [hxy, hyy, 0.0], [0.0, 0.0, 0.0]])


def test_function_surface_numerical_derivatives_within_documented_accuracy() -> None:
    rng = np.random.default_rng(8)
    numeric = FunctionSurface(wavy_phi)
    from_gradient = FunctionSurface(wavy_phi, gradient=wavy_gradient)
    exact = FunctionSurface(wavy_phi, wavy_gradient, wavy_hessian)
    worst = {"gradient": 0.0, "hessian_from_phi": 0.0, "hessian_from_gradient": 0.0}
    for p in rng.uniform(-1, 1, (100, 3)):
        worst["gradient"] = max(
            worst["gradient"], float(np.max(np.abs(numeric.gradient(p) - wavy_gradient(p))))
        )
        worst["hessian_from_phi"] = max(
            worst["hessian_from_phi"],
            float(np.max(np.abs(numeric.hessian(p) - wavy_hessian(p)))),
        )
        worst["hessian_from_gradient"] = max(
            worst["hessian_from_gradient"],
            float(np.max(np.abs(from_gradient.hessian(p) - wavy_hessian(p)))),
        )
        phi, grad, hess = exact.evaluate(p)
        assert phi == wavy_phi(p)
        np.testing.assert_array_equal(grad, wavy_gradient(p))
        np.testing.assert_array_equal(hess, wavy_hessian(p))
        phi, grad, hess = numeric.evaluate(p)
        assert phi == wavy_phi(p)
        np.testing.assert_array_equal(grad, numeric.gradient(p))
        np.testing.assert_array_equal(hess, numeric.hessian(p))
        np.testing.assert_array_equal(hess, hess.T)
    # documented: gradient < 1e-10, Hessian from Φ < 1e-7, Hessian from gradient < 1e-10
    assert worst["gradient"] < 1e-10
    assert worst["hessian_from_phi"] < 1e-7
    assert worst["hessian_from_gradient"] < 1e-10


def test_function_surface_matches_builtin_sphere() -> None:
    rng = np.random.default_rng(9)
    sphere = Sphere(1.0, center=(0.1, -0.2, 0.3))
    wrapped = FunctionSurface(sphere.phi)
    for p in rng.uniform(-1, 1, (50, 3)):
        np.testing.assert_allclose(wrapped.gradient(p), sphere.gradient(p), rtol=0, atol=1e-10)
        np.testing.assert_allclose(wrapped.hessian(p), sphere.hessian(p), rtol=0, atol=1e-7)
        np.testing.assert_allclose(wrapped.normal(p), sphere.normal(p), rtol=0, atol=1e-9)


def test_function_surface_first_order_distance() -> None:
    rng = np.random.default_rng(10)
    r = 0.8
    ball = FunctionSurface(lambda p: float(p @ p) - r * r)
    for p in rng.normal(size=(50, 3)):
        rho = float(np.linalg.norm(p))
        d = rho - r
        # Φ/‖∇Φ‖ = (ρ² − r²)/(2ρ) = d(2ρ − d)/(2ρ) = d − d²/(2ρ): error −d²/(2ρ), i.e. O(d²)
        assert ball.distance(p) == pytest.approx(d - d * d / (2 * rho), rel=1e-9, abs=1e-12)
    # a Φ with ‖∇Φ‖ = 1 is its own distance: the first-order value is exact
    n = np.array([1.0, -2.0, 2.0]) / 3.0  # unit: the norm is 3
    slab = FunctionSurface(lambda p: float(n @ p) - 0.3)
    plane = Plane(0.3 * n, n)
    for p in rng.normal(size=(50, 3)):
        assert slab.distance(p) == pytest.approx(plane.distance(p), rel=1e-9, abs=1e-13)
        foot = slab.closest_point(p)
        np.testing.assert_allclose(foot, plane.closest_point(p), atol=1e-9)
    # a supplied distance is used as given
    exact_ball = FunctionSurface(ball.phi_function, distance=lambda p: float(np.linalg.norm(p)) - r)
    assert exact_ball.distance([0.0, 0.0, 2.0]) == pytest.approx(1.2, abs=1e-15)
    # d = 0 exactly where Φ = 0
    assert ball.distance([0.8, 0.0, 0.0]) == 0.0


def test_function_surface_closest_point_is_first_order() -> None:
    ball = FunctionSurface(lambda p: float(p @ p) - 1.0)
    p = np.array([0.0, 0.6, 0.8])
    for d in (1e-1, 1e-2, 1e-3):
        q = (1.0 + d) * p
        foot = ball.closest_point(q)
        # lands on the surface to O(d²), along the normal
        assert abs(ball.phi(foot)) < 1.5 * d * d
        assert np.linalg.norm(np.cross(q - foot, p)) < 1e-9


def test_function_surface_errors() -> None:
    ball = FunctionSurface(lambda p: float(p @ p) - 1.0)
    with pytest.raises(SurfaceError, match="singular_tol"):
        ball.normal([0.0, 0.0, 0.0])
    with pytest.raises(SurfaceError):
        ball.distance([0.0, 0.0, 0.0])
    with pytest.raises(SurfaceError, match="phi returned nan"):
        FunctionSurface(lambda p: math.nan).phi([0.0, 0.0, 0.0])
    with pytest.raises(BadInputError, match=r"gradient returned shape \(2,\)"):
        FunctionSurface(wavy_phi, gradient=lambda p: np.zeros(2)).gradient([0.0, 0.0, 0.0])
    with pytest.raises(BadInputError, match=r"hessian returned shape \(3,\)"):
        FunctionSurface(wavy_phi, hessian=lambda p: np.zeros(3)).hessian([0.0, 0.0, 0.0])
    assert ball.to_dict() == {"type": "function"}
    with pytest.raises(SurfaceError):
        surface_from_dict(ball.to_dict())
    assert "phi=wavy_phi" in repr(FunctionSurface(wavy_phi))
    assert "hessian=wavy_hessian" in repr(FunctionSurface(wavy_phi, wavy_gradient, wavy_hessian))

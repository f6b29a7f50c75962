"""The pieces of the paths on surfaces: the charts of the built-in surfaces, the natural cubic
spline and the quintic blend, and the rest-to-rest time law."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hybrid_force.errors import PathError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.charts import PlaneChart, chart_for
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.piecewise import blend_piece, natural_cubic_spline
from hybrid_force.geometry.surface_path import TimeLaw

SURFACES = [
    Cylinder(0.4),
    Cylinder(0.7, center=(0.3, -0.2, 1.0), axis=(1.0, 2.0, 2.0), inside=True),
    Sphere(0.5, center=(0.0, 0.0, 5.0)),
    Sphere(1.3, center=(1.0, 2.0, -1.0), inside=True),
    Plane((0.0, 0.0, 5.0), (0.0, 0.0, 1.0)),
    Plane((1.0, -1.0, 2.0), (1.0, 1.0, 3.0)),
]


def _random_coordinates(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    return rng.uniform(-1.4, 1.4, n), rng.uniform(-3.0, 3.0, n)


@pytest.mark.parametrize("surface", SURFACES, ids=repr)
def test_chart_points_lie_on_the_surface_and_invert(
    surface: object, rng: np.random.Generator
) -> None:
    chart = chart_for(surface)
    u, v = _random_coordinates(rng, 50)
    points = chart.derivatives(u, v)[0]
    for p, uu, vv in zip(points, u, v, strict=True):
        assert abs(surface.distance(p)) < 1e-12  # type: ignore[attr-defined]
        back = chart.unwrap(chart.coordinates(p), (uu, vv))
        np.testing.assert_allclose(back, (uu, vv), rtol=0, atol=1e-12)


@pytest.mark.parametrize("surface", SURFACES, ids=repr)
def test_chart_derivatives_are_central_differences(
    surface: object, rng: np.random.Generator
) -> None:
    chart = chart_for(surface)
    h = 1e-5  # truncation h²/6·|S'''| ≈ 1e-11·r, rounding ε·|S|/h ≈ 1e-10
    for u, v in zip(*_random_coordinates(rng, 20), strict=True):
        d = chart.derivatives(u, v)[:, 0]
        du = (chart.derivatives(u + h, v) - chart.derivatives(u - h, v))[:, 0] / (2 * h)
        dv = (chart.derivatives(u, v + h) - chart.derivatives(u, v - h))[:, 0] / (2 * h)
        for exact, difference in (
            (d[1], du[0]),  # S_u
            (d[2], dv[0]),  # S_v
            (d[3], du[1]),  # S_uu
            (d[4], dv[1]),  # S_uv = ∂S_u/∂v
            (d[4], du[2]),  # = ∂S_v/∂u
            (d[5], dv[2]),  # S_vv
        ):
            np.testing.assert_allclose(exact, difference, rtol=0, atol=1e-8)


@pytest.mark.parametrize("surface", SURFACES, ids=repr)
def test_the_scalar_chart_is_the_vectorised_one(surface: object, rng: np.random.Generator) -> None:
    chart = chart_for(surface)
    u, v = _random_coordinates(rng, 20)
    many = chart.derivatives(u, v)
    for i, (uu, vv) in enumerate(zip(u, v, strict=True)):
        np.testing.assert_allclose(chart.derivatives_at(uu, vv), many[:, i], rtol=0, atol=1e-15)


def test_charts_by_hand() -> None:
    # the paper's cylinder: S(θ, h) = (r cos θ, r sin θ, h), θ from world x as a helix's phase
    cylinder = chart_for(Cylinder(0.4))
    np.testing.assert_allclose(cylinder.point(math.pi / 2, 7.0), [0.0, 0.4, 7.0], atol=1e-15)
    # sphere: latitude from the equator ⟂ z, longitude from +x towards +y
    sphere = chart_for(Sphere(0.5, center=(0.0, 0.0, 5.0)))
    np.testing.assert_allclose(sphere.point(0.0, math.pi / 2), [0.0, 0.5, 5.0], atol=1e-15)
    np.testing.assert_allclose(sphere.point(-math.pi / 2, 1.0), [0.0, 0.0, 4.5], atol=1e-15)
    # plane: e_u = world x projected onto the plane (world y if the normal is along x)
    flat = chart_for(Plane((0.0, 0.0, 5.0), (0.0, 0.0, 2.0)))
    np.testing.assert_allclose(flat.point(0.3, -0.2), [0.3, -0.2, 5.0], atol=1e-15)
    wall = chart_for(Plane((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0)))
    assert isinstance(wall, PlaneChart)
    e_u, e_v = wall.axes
    np.testing.assert_allclose(e_u, [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(e_v, np.cross([-1.0, 0.0, 0.0], e_u), atol=1e-15)  # n × e_u


def test_a_plane_chart_takes_a_u_axis_projected_onto_the_plane() -> None:
    chart = chart_for(Plane((0.0, 0.0, 5.0), (0.0, 0.0, 1.0)), u_axis=(0.0, 2.0, 7.0))
    e_u, e_v = chart.axes  # type: ignore[attr-defined]
    np.testing.assert_allclose(e_u, [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(e_v, [-1.0, 0.0, 0.0], atol=1e-15)
    assert chart.to_dict() == {"u_axis": [0.0, 1.0, 0.0]}
    with pytest.raises(PathError, match=r"u_axis.*no component in the plane") as info:
        chart_for(Plane((0.0, 0.0, 5.0), (0.0, 0.0, 1.0)), u_axis=(0.0, 0.0, -3.0))
    assert info.value.key == "u_axis"
    with pytest.raises(PathError, match="u_axis is only for a plane"):
        chart_for(Cylinder(0.4), u_axis=(1.0, 0.0, 0.0))


def test_a_user_defined_surface_has_no_chart() -> None:
    surface = FunctionSurface(lambda p: float(p @ p) - 1.0)
    with pytest.raises(PathError, match="has no chart"):
        chart_for(surface)


def test_natural_spline_by_hand() -> None:
    # knots 0, 1, 2 through 0, 1, 0: 4 M1 = 6 (−1 − 1), M1 = −3; first piece
    # γ = 1.5 x − 0.5 x³ (γ(1) = 1, γ'' = −3x), so γ(0.5) = 0.6875
    curve = natural_cubic_spline(np.array([0.0, 1.0, 2.0]), np.array([[0, 0], [1, 2], [0, 0.0]]))
    g, g1, g2 = curve.evaluate(0.5)
    np.testing.assert_allclose(g, [0.6875, 1.375], atol=1e-15)
    np.testing.assert_allclose(g1, [1.5 - 1.5 * 0.25, 2 * (1.5 - 1.5 * 0.25)], atol=1e-15)
    np.testing.assert_allclose(g2, [-1.5, -3.0], atol=1e-15)


def test_natural_spline_interpolates_is_c2_and_keeps_lines(rng: np.random.Generator) -> None:
    knots = np.cumsum(rng.uniform(0.1, 2.0, 9))
    points = rng.normal(size=(9, 2))
    curve = natural_cubic_spline(knots, points)
    for k, (t, p) in enumerate(zip(knots, points, strict=True)):
        np.testing.assert_allclose(curve.evaluate(t)[0], p, atol=1e-13)
        if 0 < k < len(knots) - 1:  # the left piece at its end meets the right piece's start
            left = curve.coeffs[k - 1]
            h = knots[k] - knots[k - 1]
            limits = [
                sum(left[j] * h**j for j in range(6)),
                sum(j * left[j] * h ** (j - 1) for j in range(1, 6)),
                sum(j * (j - 1) * left[j] * h ** (j - 2) for j in range(2, 6)),
            ]
            for left_limit, right in zip(limits, curve.evaluate(t), strict=True):
                np.testing.assert_allclose(left_limit, right, atol=1e-11)
    for end in (knots[0], knots[-1]):
        np.testing.assert_allclose(curve.evaluate(end)[2], 0.0, atol=1e-12)
    line = natural_cubic_spline(knots, 0.5 + np.outer(knots, [2.0, -1.0]))
    for t in rng.uniform(knots[0], knots[-1], 20):
        g, g1, g2 = line.evaluate(t)
        np.testing.assert_allclose(g, [0.5 + 2 * t, 0.5 - t], atol=1e-12)
        np.testing.assert_allclose(g1, [2.0, -1.0], atol=1e-12)
        np.testing.assert_allclose(g2, 0.0, atol=1e-12)


@pytest.mark.parametrize("bends", [(0.0, 0.0), (np.array([2.0, -1.0]), np.array([0.5, 3.0]))])
def test_blend_matches_value_slope_and_bend_at_its_ends(bends: tuple) -> None:
    p0, d0, p1, d1 = np.array([1.0, 2.0]), np.array([3.0, 0.0]), np.array([1.0, 2.5]), -np.ones(2)
    length = 0.7
    c = blend_piece(p0, d0, p1, d1, length, *bends)
    j = np.arange(6)
    for x, p, d, a in ((0.0, p0, d0, bends[0]), (length, p1, d1, bends[1])):
        np.testing.assert_allclose(c.T @ (x**j), p, atol=1e-14)
        np.testing.assert_allclose(c[1:].T @ (j[1:] * x ** (j[1:] - 1)), d, atol=1e-13)
        second = c[2:].T @ (j[2:] * (j[2:] - 1) * x ** (j[2:] - 2))
        np.testing.assert_allclose(second, np.broadcast_to(a, (2,)), atol=1e-12)


@pytest.mark.parametrize(("length", "speed", "ramp"), [(2.0, 0.5, 0.4), (0.05, 0.5, 0.4)])
def test_time_law(length: float, speed: float, ramp: float, rng: np.random.Generator) -> None:
    law = TimeLaw(length, speed, ramp)
    rate = min(speed, length / ramp)  # a path too short for the ramps never reaches speed
    assert law.duration == pytest.approx(length / rate + ramp, rel=1e-15)
    assert law.sample(-1.0) == (0.0, 0.0, 0.0)
    assert law.sample(law.duration + 1.0) == (length, 0.0, 0.0)
    h = 1e-5
    for t in rng.uniform(0.0, law.duration, 50):
        s, sd, sdd = law.sample(t)
        assert sd == pytest.approx(
            (law.sample(t + h)[0] - law.sample(t - h)[0]) / (2 * h), abs=1e-8
        )
        assert sdd == pytest.approx(
            (law.sample(t + h)[1] - law.sample(t - h)[1]) / (2 * h), abs=1e-6
        )
        assert 0.0 <= sd <= rate * (1 + 1e-15)
        assert law.time_at(s) == pytest.approx(t, abs=1e-9)
    assert law.sample(ramp)[1] == pytest.approx(rate, rel=1e-15)
    assert law.sample(law.duration / 2)[0] == pytest.approx(length / 2, rel=1e-12)  # symmetric
    for t in (0.0, ramp, law.duration - ramp, law.duration):  # σ, σ̇, σ̈ continuous
        before, after = np.array(law.sample(t - 1e-9)), np.array(law.sample(t + 1e-9))
        np.testing.assert_allclose(before, after, atol=1e-7)

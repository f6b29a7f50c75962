"""Tests of hybrid_force.geometry.surfaces against independent references.

References used: central finite differences written here (not the module's), direct geometric
constructions (projection onto the axis, points placed on the surface by a parametrisation,
brute-force sampling of the surface), hand-derived derivatives of a non-polynomial Φ, and
the paper's eq. 26 written out literally.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hybrid_force.errors import BadInputError, SurfaceError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.geometry.surfaces import surface_from_dict

EPS = np.finfo(np.float64).eps


# --- independent references ------------------------------------------------------------------
def fd_gradient(f: Callable[[np.ndarray], float], p: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences of a scalar function, (3,)."""
    g = np.zeros(3)
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        g[i] = (f(p + e) - f(p - e)) / (2 * h)
    return g


def fd_hessian_of_phi(
    f: Callable[[np.ndarray], float], p: np.ndarray, h: float = 1e-4
) -> np.ndarray:
    """Second central differences of a scalar function, (3, 3)."""
    hess = np.zeros((3, 3))
    eye = np.eye(3) * h
    for i in range(3):
        for j in range(3):
            hess[i, j] = (
                f(p + eye[i] + eye[j])
                - f(p + eye[i] - eye[j])
                - f(p - eye[i] + eye[j])
                + f(p - eye[i] - eye[j])
            ) / (4 * h * h)
    return hess


def fd_jacobian(
    f: Callable[[np.ndarray], np.ndarray], p: np.ndarray, h: float = 1e-6
) -> np.ndarray:
    """Central differences of a vector function, column i = ∂f/∂p_i."""
    cols = []
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        cols.append((f(p + e) - f(p - e)) / (2 * h))
    return np.stack(cols, axis=1)


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def perpendicular_basis(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors u, v with (a, u, v) orthonormal."""
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = unit(np.cross(a, helper))
    return u, np.cross(a, u)


def reference_distance(surface: Surface, raw: dict, p: np.ndarray) -> float:
    """Signed distance from the raw (un-normalised) parameters, computed geometrically."""
    if isinstance(surface, Cylinder):
        a = unit(np.asarray(raw["axis"], dtype=float))
        c = np.asarray(raw["center"], dtype=float)
        foot_on_axis = c + np.dot(p - c, a) * a
        radial = np.linalg.norm(p - foot_on_axis) - raw["radius"]
        return -radial if raw["inside"] else radial
    if isinstance(surface, Sphere):
        radial = np.linalg.norm(p - np.asarray(raw["center"], dtype=float)) - raw["radius"]
        return -radial if raw["inside"] else radial
    assert isinstance(surface, Plane)
    n = unit(np.asarray(raw["normal"], dtype=float))
    return float(np.dot(p - np.asarray(raw["point"], dtype=float), n))


def surface_points(raw: dict, kind: str, rng: np.random.Generator, count: int) -> np.ndarray:
    """Points placed exactly (up to rounding) on the surface by a parametrisation, (count, 3)."""
    if kind == "cylinder":
        a = unit(np.asarray(raw["axis"], dtype=float))
        c = np.asarray(raw["center"], dtype=float)
        u, v = perpendicular_basis(a)
        theta = rng.uniform(0, 2 * np.pi, count)
        t = rng.uniform(-2, 2, count)
        return (
            c
            + t[:, None] * a
            + raw["radius"] * (np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * v)
        )
    if kind == "sphere":
        directions = rng.normal(size=(count, 3))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        return np.asarray(raw["center"], dtype=float) + raw["radius"] * directions
    n = unit(np.asarray(raw["normal"], dtype=float))
    u, v = perpendicular_basis(n)
    s, t = rng.uniform(-2, 2, (2, count))
    return np.asarray(raw["point"], dtype=float) + s[:, None] * u + t[:, None] * v


def random_raw(kind: str, rng: np.random.Generator) -> dict:
    """Random constructor parameters; directions deliberately not of unit length."""
    if kind == "cylinder":
        return {
            "radius": float(rng.uniform(0.05, 2.0)),
            "center": rng.uniform(-1, 1, 3).tolist(),
            "axis": (rng.normal(size=3) * rng.uniform(0.1, 10)).tolist(),
            "inside": bool(rng.integers(2)),
        }
    if kind == "sphere":
        return {
            "radius": float(rng.uniform(0.05, 2.0)),
            "center": rng.uniform(-1, 1, 3).tolist(),
            "inside": bool(rng.integers(2)),
        }
    return {
        "point": rng.uniform(-1, 1, 3).tolist(),
        "normal": (rng.normal(size=3) * rng.uniform(0.1, 10)).tolist(),
    }


def build(kind: str, raw: dict) -> Surface:
    cls = {"cylinder": Cylinder, "sphere": Sphere, "plane": Plane}[kind]
    return cls(**raw)


def random_point_near(surface: Surface, raw: dict, rng: np.random.Generator) -> np.ndarray:
    anchor = np.asarray(raw.get("center", raw.get("point")), dtype=float)
    return anchor + rng.uniform(-2.5, 2.5, 3)


KINDS = ["cylinder", "sphere", "plane"]


# --- paper eq. 26 ------------------------------------------------------------------------------
def test_default_cylinder_is_exactly_paper_eq_26() -> None:
    cyl = Cylinder(0.4)
    rng = np.random.default_rng(26)
    for p in rng.uniform(-3, 3, (200, 3)):
        x, y, _ = p.tolist()
        expected = x**2 + y**2 - 0.4**2
        assert cyl.phi(p) == expected
        assert cyl.evaluate(p)[0] == expected
        np.testing.assert_array_equal(cyl.gradient(p), [2 * x, 2 * y, 0.0])
    np.testing.assert_array_equal(cyl.hessian(np.zeros(3) + 0.1), np.diag([2.0, 2.0, 0.0]))
    # inside=True is exactly the negation
    inner = Cylinder(0.4, inside=True)
    p = np.array([0.1, 0.1, 2.0])  # the paper's section 6.4 start, inside the cylinder
    assert inner.phi(p) == -(0.1**2 + 0.1**2 - 0.4**2)
    assert inner.distance(p) == pytest.approx(0.4 - math.hypot(0.1, 0.1), abs=1e-15)
    assert inner.distance(p) > 0 and cyl.distance(p) < 0


# --- derivatives against finite differences ---------------------------------------------------
@pytest.mark.parametrize("kind", KINDS)
def test_derivatives_match_finite_differences(kind: str) -> None:
    rng = np.random.default_rng(1)
    worst_g = worst_h = worst_hg = 0.0
    for _ in range(15):
        raw = random_raw(kind, rng)
        surface = build(kind, raw)
        for _ in range(10):
            p = random_point_near(surface, raw, rng)
            scale = 1.0 + float(np.dot(p, p))
            g_err = np.max(np.abs(surface.gradient(p) - fd_gradient(surface.phi, p)))
            h_err = np.max(np.abs(surface.hessian(p) - fd_hessian_of_phi(surface.phi, p)))
            hg_err = np.max(np.abs(surface.hessian(p) - fd_jacobian(surface.gradient, p)))
            worst_g = max(worst_g, g_err / scale)
            worst_h = max(worst_h, h_err / scale)
            worst_hg = max(worst_hg, hg_err / scale)
    # rounding-limited (Φ is at most quadratic): ε·scale/h and 4ε·scale/h²
    assert worst_g < 1e-8
    assert worst_h < 1e-5
    assert worst_hg < 1e-8


@pytest.mark.parametrize("kind", KINDS)
def test_evaluate_equals_phi_gradient_hessian(kind: str) -> None:
    rng = np.random.default_rng(2)
    for _ in range(20):
        raw = random_raw(kind, rng)
        surface = build(kind, raw)
        p = random_point_near(surface, raw, rng)
        phi, grad, hess = surface.evaluate(p)
        assert type(phi) is float
        assert phi == surface.phi(p)
        np.testing.assert_array_equal(grad, surface.gradient(p))
        np.testing.assert_array_equal(hess, surface.hessian(p))
        assert grad.shape == (3,) and hess.shape == (3, 3)
        np.testing.assert_array_equal(hess, hess.T)
        # the public per-quantity methods return fresh, writable arrays
        assert surface.gradient(p).flags.writeable and surface.hessian(p).flags.writeable
        # shared constants from evaluate cannot be corrupted by a caller
        if not hess.flags.writeable:
            with pytest.raises(ValueError):
                hess[0, 0] = 1.0
            assert surface.evaluate(p)[2][0, 0] == surface.hessian(p)[0, 0]


# --- distance ----------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", KINDS)
def test_distance_matches_geometry(kind: str) -> None:
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(20):
        raw = random_raw(kind, rng)
        surface = build(kind, raw)
        for _ in range(20):
            p = random_point_near(surface, raw, rng)
            d = surface.distance(p)
            worst = max(worst, abs(d - reference_distance(surface, raw, p)))
            assert np.sign(d) == np.sign(surface.phi(p))
    assert worst < 1e-13


@pytest.mark.parametrize("kind", KINDS)
def test_phi_zero_iff_distance_zero(kind: str) -> None:
    rng = np.random.default_rng(4)
    for _ in range(10):
        raw = random_raw(kind, rng)
        surface = build(kind, raw)
        on = surface_points(raw, kind, rng, 50)
        for q in on:
            assert abs(surface.phi(q)) < 1e-12
            assert abs(surface.distance(q)) < 1e-12
        # step off along the geometric normal by a known signed amount
        for q in on[:20]:
            n = surface.normal(q)
            limit = 0.5 * raw.get("radius", 1.0)
            delta = float(rng.choice([-1, 1]) * rng.uniform(1e-6, limit))
            off = q + delta * n
            assert surface.distance(off) == pytest.approx(delta, rel=1e-9, abs=1e-13)
            assert abs(surface.phi(off)) > 1e-9
            assert np.sign(surface.phi(off)) == np.sign(delta)


def test_phi_and_distance_exactly_zero_together() -> None:
    # Φ = 0.25 − 0.25 = 0 exactly at these points, so d must be exactly 0 as well
    assert Cylinder(0.5).phi([0.5, 0.0, 7.0]) == 0.0
    assert Cylinder(0.5).distance([0.5, 0.0, 7.0]) == 0.0
    assert Cylinder(0.5, inside=True).distance([0.0, -0.5, -3.0]) == 0.0
    assert Sphere(0.5, center=(1, 1, 1)).distance([1.0, 1.5, 1.0]) == 0.0
    assert Plane((0, 0, 1), (0, 0, 3)).distance([5.0, -2.0, 1.0]) == 0.0
    # and for arbitrary points the zero sets and the signs agree exactly
    rng = np.random.default_rng(5)
    for kind in KINDS:
        for _ in range(5):
            raw = random_raw(kind, rng)
            surface = build(kind, raw)
            for q in surface_points(raw, kind, rng, 100):
                assert (surface.phi(q) == 0.0) == (surface.distance(q) == 0.0)
                assert np.sign(surface.phi(q)) == np.sign(surface.distance(q))


@pytest.mark.parametrize("cls", [Cylinder, Sphere])
def test_inside_flag_sets_the_free_side(cls: type) -> None:
    outer = cls(0.3, center=(0.2, -0.1, 0.5))
    inner = cls(0.3, center=(0.2, -0.1, 0.5), inside=True)
    near_centre = np.array([0.25, -0.1, 0.5])  # 0.05 from the centre / axis
    far = np.array([1.2, 0.9, 0.5])
    assert outer.distance(near_centre) == pytest.approx(-0.25, abs=1e-15)
    assert inner.distance(near_centre) == pytest.approx(0.25, abs=1e-15)
    assert outer.distance(far) > 0 > inner.distance(far)
    assert outer.phi(near_centre) < 0 < inner.phi(near_centre)
    # the normal points to the free side: towards the centre for inside=True
    np.testing.assert_allclose(inner.normal(near_centre), [-1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(outer.normal(near_centre), [1.0, 0.0, 0.0], atol=1e-15)


def test_plane_sign_and_normalisation() -> None:
    plane = Plane(point=(1.0, 2.0, 3.0), normal=(0.0, 0.0, -5.0))
    assert plane.normal_vector == (0.0, 0.0, -1.0)
    assert plane.distance([7.0, 7.0, 1.0]) == 2.0  # below the plane is the free side
    assert plane.distance([7.0, 7.0, 4.0]) == -1.0
    np.testing.assert_array_equal(plane.closest_point([7.0, 7.0, 1.0]), [7.0, 7.0, 3.0])


# --- normal and closest point -----------------------------------------------------------------
@pytest.mark.parametrize("kind", KINDS)
def test_normal_and_closest_point(kind: str) -> None:
    rng = np.random.default_rng(6)
    worst_on = worst_par = worst_len = 0.0
    for _ in range(15):
        raw = random_raw(kind, rng)
        surface = build(kind, raw)
        samples = surface_points(raw, kind, rng, 2000)
        for _ in range(10):
            p = random_point_near(surface, raw, rng)
            n = surface.normal(p)
            assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-15)
            np.testing.assert_allclose(n, unit(fd_gradient(surface.phi, p)), atol=1e-7)
            foot = surface.closest_point(p)
            offset = p - foot
            worst_on = max(worst_on, abs(surface.distance(foot)))
            worst_par = max(worst_par, float(np.linalg.norm(np.cross(offset, n))))
            d = surface.distance(p)
            worst_len = max(worst_len, abs(float(np.linalg.norm(offset)) - abs(d)))
            # p − foot points along +n on the free side, along −n on the other
            assert np.dot(offset, n) == pytest.approx(d, abs=1e-12)
            # no sampled surface point is closer than the foot point
            nearest_sample = float(np.min(np.linalg.norm(samples - p, axis=1)))
            assert nearest_sample >= abs(d) - 1e-12
    assert worst_on < 1e-14 * 10
    assert worst_par < 1e-13
    assert worst_len < 1e-13


# --- serialisation ----------------------------------------------------------------------------
@pytest.mark.parametrize("kind", KINDS)
def test_to_dict_round_trip(kind: str) -> None:
    rng = np.random.default_rng(7)
    for _ in range(200):
        raw = random_raw(kind, rng)
        surface = build(kind, raw)
        description = json.loads(json.dumps(surface.to_dict()))
        assert description["type"] == kind == surface.kind
        again = surface_from_dict(description)
        assert again == surface
        assert repr(again) == repr(surface)
        assert hash(again) == hash(surface)
    cyl = Cylinder(0.4, axis=(0, 0, 2))
    assert cyl.to_dict() == {
        "type": "cylinder",
        "radius": 0.4,
        "center": [0.0, 0.0, 0.0],
        "axis": [0.0, 0.0, 1.0],
        "inside": False,
    }


def test_surfaces_are_immutable_with_readable_repr() -> None:
    cyl = Cylinder(0.4, center=[1, 2, 3], axis=np.array([0, 3.0, 4.0]), inside=True)
    assert (
        repr(cyl)
        == "Cylinder(radius=0.4, center=(1.0, 2.0, 3.0), axis=(0.0, 0.6, 0.8), inside=True)"
    )
    assert isinstance(cyl.center, tuple) and isinstance(cyl.radius, float)
    with pytest.raises(AttributeError):
        cyl.radius = 1.0  # type: ignore[misc]
    assert repr(Sphere(1)) == "Sphere(radius=1.0, center=(0.0, 0.0, 0.0), inside=False)"
    assert (
        repr(Plane((0, 0, 0), (0, 2, 0))) == "Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0))"
    )


def test_surface_from_dict_errors() -> None:
    with pytest.raises(SurfaceError, match=r"did you mean 'cylinder'.*'sphere'.*'plane'"):
        surface_from_dict({"type": "cylindr", "radius": 1.0})
    with pytest.raises(SurfaceError, match="'function' cannot be rebuilt"):
        surface_from_dict({"type": "function"})
    with pytest.raises(SurfaceError, match="missing key 'type'"):
        surface_from_dict({"radius": 1.0})
    with pytest.raises(SurfaceError, match=r"missing parameter.*'radius'"):
        surface_from_dict({"type": "sphere"})
    with pytest.raises(SurfaceError, match=r"unknown parameter 'radiuss'.*'radius'"):
        surface_from_dict({"type": "sphere", "radius": 1.0, "radiuss": 2.0})
    with pytest.raises(SurfaceError, match="Plane: parameter 'normal'"):
        surface_from_dict({"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 0]})
    with pytest.raises(SurfaceError, match="expected a dict"):
        surface_from_dict([1, 2, 3])  # type: ignore[arg-type]


# --- bad input --------------------------------------------------------------------------------
BAD_PARAMETERS = [
    # (constructor, kwargs, class name, parameter name, value text)
    (Cylinder, {"radius": 0.0}, "Cylinder", "radius", "0.0"),
    (Cylinder, {"radius": -0.4}, "Cylinder", "radius", "-0.4"),
    (Cylinder, {"radius": math.nan}, "Cylinder", "radius", "nan"),
    (Cylinder, {"radius": math.inf}, "Cylinder", "radius", "inf"),
    (Cylinder, {"radius": "0.4"}, "Cylinder", "radius", "'0.4'"),
    (Cylinder, {"radius": True}, "Cylinder", "radius", "True"),
    (Cylinder, {"radius": 1.0, "center": (0, 0)}, "Cylinder", "center", "(2,)"),
    (Cylinder, {"radius": 1.0, "center": [[0, 0, 0]]}, "Cylinder", "center", "(1, 3)"),
    (Cylinder, {"radius": 1.0, "center": (0, 0, math.nan)}, "Cylinder", "center", "nan"),
    (Cylinder, {"radius": 1.0, "center": "abc"}, "Cylinder", "center", "'abc'"),
    (Cylinder, {"radius": 1.0, "axis": (0, 0, 0)}, "Cylinder", "axis", "(0, 0, 0)"),
    (Cylinder, {"radius": 1.0, "axis": (1e-13, 0, 0)}, "Cylinder", "axis", "1e-13"),
    (Cylinder, {"radius": 1.0, "axis": (math.inf, 0, 1)}, "Cylinder", "axis", "inf"),
    (Cylinder, {"radius": 1.0, "axis": (0, 1)}, "Cylinder", "axis", "(2,)"),
    (Cylinder, {"radius": 1.0, "inside": "yes"}, "Cylinder", "inside", "'yes'"),
    (Sphere, {"radius": -1}, "Sphere", "radius", "-1"),
    (Sphere, {"radius": None}, "Sphere", "radius", "None"),
    (Sphere, {"radius": 1.0, "center": (0, 0, math.inf)}, "Sphere", "center", "inf"),
    (Sphere, {"radius": 1.0, "center": (1, 2, 3, 4)}, "Sphere", "center", "(4,)"),
    (Sphere, {"radius": 1.0, "inside": 1}, "Sphere", "inside", "1"),
    (Plane, {"point": (0, 0), "normal": (0, 0, 1)}, "Plane", "point", "(2,)"),
    (Plane, {"point": (math.nan, 0, 0), "normal": (0, 0, 1)}, "Plane", "point", "nan"),
    (Plane, {"point": (0, 0, 0), "normal": (0, 0, 0)}, "Plane", "normal", "(0, 0, 0)"),
    (Plane, {"point": (0, 0, 0), "normal": (0, -math.inf, 0)}, "Plane", "normal", "inf"),
    (Plane, {"point": (0, 0, 0), "normal": [1, 0]}, "Plane", "normal", "(2,)"),
    (FunctionSurface, {"phi": None}, "FunctionSurface", "phi", "None"),
    (FunctionSurface, {"phi": 3.0}, "FunctionSurface", "phi", "3.0"),
    (FunctionSurface, {"phi": abs, "gradient": 5}, "FunctionSurface", "gradient", "5"),
    (FunctionSurface, {"phi": abs, "hessian": "h"}, "FunctionSurface", "hessian", "'h'"),
    (FunctionSurface, {"phi": abs, "distance": 1}, "FunctionSurface", "distance", "1"),
    (FunctionSurface, {"phi": abs, "step": 0.0}, "FunctionSurface", "step", "0.0"),
    (FunctionSurface, {"phi": abs, "step": -1e-6}, "FunctionSurface", "step", "-1e-06"),
    (
        FunctionSurface,
        {"phi": abs, "hessian_step": math.nan},
        "FunctionSurface",
        "hessian_step",
        "nan",
    ),
    (FunctionSurface, {"phi": abs, "singular_tol": 0}, "FunctionSurface", "singular_tol", "0"),
]


@pytest.mark.parametrize(("cls", "kwargs", "owner", "name", "value"), BAD_PARAMETERS)
def test_bad_parameters_raise_naming_class_parameter_and_value(
    cls: type, kwargs: dict, owner: str, name: str, value: str
) -> None:
    with pytest.raises(SurfaceError) as info:
        cls(**kwargs)
    message = str(info.value)
    assert owner in message
    assert f"'{name}'" in message
    assert value in message


@pytest.mark.parametrize("surface", [Cylinder(1.0), Sphere(1.0), Plane((0, 0, 0), (0, 0, 1))])
def test_bad_points_raise(surface: Surface) -> None:
    with pytest.raises(BadInputError, match=r"shape \(2,\)"):
        surface.phi([0.0, 1.0])
    with pytest.raises(BadInputError, match=r"shape \(3, 1\)"):
        surface.distance(np.zeros((3, 1)))
    with pytest.raises(SurfaceError, match="finite"):
        surface.gradient([0.0, math.nan, 1.0])
    with pytest.raises(SurfaceError, match="finite"):
        surface.normal([math.inf, 0.0, 1.0])


def test_normal_on_axis_or_centre_is_singular() -> None:
    cyl = Cylinder(0.4, center=(1, 1, 0), axis=(1, 1, 1))
    on_axis = np.array([1.0, 1.0, 0.0]) + 2.5 * np.array([1.0, 1.0, 1.0])
    for method in (cyl.normal, cyl.closest_point):
        with pytest.raises(SurfaceError, match=r"axis.*p = \[3.5, 3.5, 2.5\]"):
            method(on_axis)
    # still defined: Φ, ∇Φ = 0, d = −r
    assert cyl.distance(on_axis) == pytest.approx(-0.4, abs=1e-15)
    np.testing.assert_allclose(cyl.gradient(on_axis), 0.0, atol=1e-14)
    # just off the axis (1e-6 m ≫ 1e-9 r) the normal is defined and exact
    u, _ = perpendicular_basis(unit(np.array([1.0, 1.0, 1.0])))
    np.testing.assert_allclose(cyl.normal(on_axis + 1e-6 * u), u, atol=1e-9)
    sphere = Sphere(0.2, center=(0.1, 0.2, 0.3), inside=True)
    with pytest.raises(SurfaceError, match="centre"):
        sphere.normal([0.1, 0.2, 0.3])
    with pytest.raises(SurfaceError, match="centre"):
        sphere.closest_point([0.1, 0.2, 0.3])


# --- property-based ---------------------------------------------------------------------------
finite = st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False)
vectors = st.tuples(finite, finite, finite)
directions = vectors.filter(lambda v: math.hypot(*v) > 0.05)
radii = st.floats(0.05, 3.0)


@st.composite
def surfaces(draw: st.DrawFn) -> tuple[str, dict]:
    kind = draw(st.sampled_from(KINDS))
    if kind == "cylinder":
        raw = {
            "radius": draw(radii),
            "center": list(draw(vectors)),
            "axis": list(draw(directions)),
            "inside": draw(st.booleans()),
        }
    elif kind == "sphere":
        raw = {"radius": draw(radii), "center": list(draw(vectors)), "inside": draw(st.booleans())}
    else:
        raw = {"point": list(draw(vectors)), "normal": list(draw(directions))}
    return kind, raw


@settings(deadline=None, max_examples=60)
@given(surfaces(), vectors)
def test_property_derivatives_distance_and_foot(spec: tuple[str, dict], offset: tuple) -> None:
    kind, raw = spec
    surface = build(kind, raw)
    anchor = np.asarray(raw.get("center", raw.get("point")), dtype=float)
    p = anchor + np.asarray(offset)
    scale = 1.0 + float(np.dot(p, p))
    np.testing.assert_allclose(surface.gradient(p), fd_gradient(surface.phi, p), atol=1e-8 * scale)
    np.testing.assert_allclose(
        surface.hessian(p), fd_hessian_of_phi(surface.phi, p), atol=1e-5 * scale
    )
    d = surface.distance(p)
    assert d == pytest.approx(reference_distance(surface, raw, p), abs=1e-13 * scale)
    assert np.sign(d) == np.sign(surface.phi(p))
    try:
        n = surface.normal(p)
    except SurfaceError:
        assert kind != "plane"
        return
    foot = surface.closest_point(p)
    assert abs(surface.distance(foot)) < 1e-13 * scale
    assert np.linalg.norm(np.cross(p - foot, n)) < 1e-12 * scale
    assert np.dot(p - foot, n) == pytest.approx(d, abs=1e-12 * scale)


@settings(deadline=None, max_examples=40)
@given(surfaces(), st.integers(0, 2**32 - 1))
def test_property_on_surface_iff_zero(spec: tuple[str, dict], seed: int) -> None:
    kind, raw = spec
    surface = build(kind, raw)
    rng = np.random.default_rng(seed)
    for q in surface_points(raw, kind, rng, 5):
        assert abs(surface.phi(q)) < 1e-12 * (1.0 + float(np.dot(q, q)))
        assert abs(surface.distance(q)) < 1e-12 * (1.0 + float(np.dot(q, q)))
        assert (surface.phi(q) == 0.0) == (surface.distance(q) == 0.0)
    assert surface_from_dict(json.loads(json.dumps(surface.to_dict()))) == surface

"""hybrid_force.geometry.paths: eq. 25, analytic derivatives, frames, on-surface check, I/O."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hybrid_force.errors import BadInputError, PathError, SurfaceError
from hybrid_force.geometry import on_surface
from hybrid_force.geometry.builtin_surfaces import Cylinder
from hybrid_force.geometry.on_surface import OnSurfaceReport, check_on_surface
from hybrid_force.geometry.paths import (
    Circle,
    FunctionPath,
    Helix,
    axis_frame,
    paper_helix,
    path_from_dict,
)

EPS = np.finfo(float).eps
HYP = settings(derandomize=True, deadline=None, max_examples=150)


class _ZCylinder:
    """Stand-in surface: cylinder of radius r about the world z axis, d = ρ − r."""

    def __init__(self, radius: float) -> None:
        self.radius = radius

    def distance(self, p: np.ndarray) -> float:
        return math.hypot(float(p[0]), float(p[1])) - self.radius


def _fd_derivative(fun, t: float, h: float) -> np.ndarray:
    """Second-order central difference (f(t+h) − f(t−h)) / 2h, independent of the module."""
    return (np.asarray(fun(t + h)) - np.asarray(fun(t - h))) / (2.0 * h)


def _random_unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


# --- eq. 25 ---------------------------------------------------------------------------------------
def test_paper_helix_is_eq_25_literally() -> None:
    h = paper_helix()
    rng = np.random.default_rng(25)
    for t in np.concatenate([[0.0, 1.0, math.pi, 20.0], rng.uniform(-30.0, 60.0, 200)]):
        p, v, a = h.evaluate(float(t))
        # eq. 25 and its derivatives, written out by hand
        np.testing.assert_allclose(
            p, [0.4 * math.cos(t), 0.4 * math.sin(t), t / 10 + 10], rtol=0, atol=1e-14
        )
        np.testing.assert_allclose(
            v, [-0.4 * math.sin(t), 0.4 * math.cos(t), 0.1], rtol=0, atol=1e-15
        )
        np.testing.assert_allclose(
            a, [-0.4 * math.cos(t), -0.4 * math.sin(t), 0.0], rtol=0, atol=1e-15
        )
        np.testing.assert_allclose(h.position(float(t)), p, rtol=0, atol=1e-14)
    assert h == Helix((0, 0, 10), 0.4, axis=(0, 0, 1), omega=1, rise=0.1, phase=0)


def test_evaluate_returns_fresh_arrays() -> None:
    h = paper_helix()
    p, v, a = h.evaluate(0.3)
    p[:] = 99.0
    v[:] = 99.0
    a[:] = 99.0
    p2, v2, a2 = h.evaluate(0.3)
    assert abs(p2[0] - 0.4 * math.cos(0.3)) < 1e-15
    assert abs(v2[2] - 0.1) < 1e-15
    assert abs(a2[2]) < 1e-15
    with pytest.raises(dataclasses.FrozenInstanceError):
        h.radius = 1.0  # type: ignore[misc]


# --- analytic derivatives against finite differences ------------------------------------------
def _check_derivatives(path, t: float, scale: float) -> tuple[float, float]:
    """Max abs errors of ṗ and p̈ against central differences of p and ṗ (h = 1e-5 s)."""
    h = 1e-5
    _, v, a = path.evaluate(t)
    v_fd = _fd_derivative(lambda s: path.evaluate(s)[0], t, h)
    a_fd = _fd_derivative(lambda s: path.evaluate(s)[1], t, h)
    ev = float(np.max(np.abs(v - v_fd)))
    ea = float(np.max(np.abs(a - a_fd)))
    # truncation h²/6·|p'''| plus rounding ~ ε·|p|/h; scale bounds |p| and the derivatives
    tol = 1e-9 * scale
    assert ev < tol, (ev, tol)
    assert ea < tol, (ea, tol)
    return ev, ea


_axis = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 1e-3)
_x_like = st.sampled_from(
    [(1.0, 0.0, 0.0), (-2.0, 0.0, 0.0), (1.0, 1e-9, 0.0), (-1.0, 0.0, 1e-7), (1.0, 3e-6, -1e-6)]
)


@HYP
@given(
    center=st.tuples(*[st.floats(-5.0, 5.0)] * 3),
    radius=st.floats(0.01, 2.0),
    axis=st.one_of(_axis, _x_like),
    omega=st.floats(-3.0, 3.0),
    rise=st.floats(-1.0, 1.0),
    phase=st.floats(-7.0, 7.0),
    t=st.floats(-10.0, 10.0),
)
def test_helix_derivatives_match_finite_differences(center, radius, axis, omega, rise, phase, t):
    h = Helix(center, radius, axis=axis, omega=omega, rise=rise, phase=phase)
    scale = 1.0 + np.max(np.abs(center)) + radius * (1 + abs(omega)) ** 4 + abs(rise) * 10
    _check_derivatives(h, t, scale)


@HYP
@given(
    center=st.tuples(*[st.floats(-5.0, 5.0)] * 3),
    radius=st.floats(0.01, 2.0),
    normal=st.one_of(_axis, _x_like),
    omega=st.floats(-3.0, 3.0),
    phase=st.floats(-7.0, 7.0),
    t=st.floats(-10.0, 10.0),
)
def test_circle_derivatives_match_finite_differences(center, radius, normal, omega, phase, t):
    c = Circle(center, radius, normal, omega, phase)
    scale = 1.0 + np.max(np.abs(center)) + radius * (1 + abs(omega)) ** 4
    _check_derivatives(c, t, scale)
    # a circle stays in its plane and at its radius
    p, v, a = c.evaluate(t)
    n = np.asarray(normal) / np.linalg.norm(normal)
    assert abs(float((p - np.asarray(center)) @ n)) < 1e-12 * (1 + np.max(np.abs(center)))
    assert abs(float(np.linalg.norm(p - np.asarray(center))) - radius) < 1e-12 * (1 + radius)
    assert abs(float(v @ n)) < 1e-12 and abs(float(a @ n)) < 1e-12


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_derivatives_fixed_seeds(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(50):
        axis = _random_unit(rng) * rng.uniform(0.1, 10.0)
        center = rng.uniform(-3.0, 3.0, 3)
        r, w, rise, ph = (
            rng.uniform(0.1, 1.5),
            rng.uniform(-2, 2),
            rng.uniform(-1, 1),
            rng.uniform(-4, 4),
        )
        t = float(rng.uniform(-10, 10))
        scale = 1.0 + 3.0 + r * (1 + abs(w)) ** 4 + 10
        _check_derivatives(Helix(center, r, axis=axis, omega=w, rise=rise, phase=ph), t, scale)
        _check_derivatives(Circle(center, r, axis, w, ph), t, scale)


def test_helix_without_rise_is_the_circle() -> None:
    rng = np.random.default_rng(7)
    for _ in range(20):
        axis, center = _random_unit(rng), rng.normal(size=3)
        h = Helix(center, 0.7, axis=axis, omega=1.3, rise=0.0, phase=0.4)
        c = Circle(center, 0.7, axis, 1.3, 0.4)
        t = float(rng.uniform(-5, 5))
        for x, y in zip(h.evaluate(t), c.evaluate(t), strict=True):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-15)


# --- the frame (e1, e2, a) ---------------------------------------------------------------------
def _assert_right_handed_orthonormal(e1, e2, a, axis) -> None:
    frame = np.column_stack([e1, e2, a])
    np.testing.assert_allclose(frame.T @ frame, np.eye(3), rtol=0, atol=1e-14)
    assert abs(np.linalg.det(frame) - 1.0) < 1e-14
    np.testing.assert_allclose(np.cross(e1, e2), a, rtol=0, atol=1e-14)
    np.testing.assert_allclose(a, np.asarray(axis) / np.linalg.norm(axis), rtol=0, atol=1e-15)


@HYP
@given(axis=st.one_of(_axis, _x_like))
def test_frame_is_orthonormal_and_right_handed(axis) -> None:
    e1, e2, a = axis_frame(axis)
    _assert_right_handed_orthonormal(e1, e2, a, axis)
    # e1 is world x projected onto the plane ⟂ a (world y when a ∥ x), same orientation
    x_perp = np.array([1.0, 0.0, 0.0]) - a[0] * a
    if np.linalg.norm(x_perp) >= 1e-6:
        np.testing.assert_allclose(e1, x_perp / np.linalg.norm(x_perp), rtol=0, atol=1e-9)
    else:
        y_perp = np.array([0.0, 1.0, 0.0]) - a[1] * a
        np.testing.assert_allclose(e1, y_perp / np.linalg.norm(y_perp), rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    ("axis", "e1", "e2"),
    [
        ((0, 0, 1), (1, 0, 0), (0, 1, 0)),  # eq. 25: phase 0 on +x, counter-clockwise from +z
        ((0, 0, -3), (1, 0, 0), (0, -1, 0)),
        ((1, 0, 0), (0, 1, 0), (0, 0, 1)),  # x-parallel: world y is the reference
        ((-1, 0, 0), (0, 1, 0), (0, 0, -1)),
        ((0, 1, 0), (1, 0, 0), (0, 0, -1)),
    ],
)
def test_frame_by_hand(axis, e1, e2) -> None:
    f1, f2, a = axis_frame(axis)
    np.testing.assert_allclose(f1, e1, atol=1e-15)
    np.testing.assert_allclose(f2, e2, atol=1e-15)
    _assert_right_handed_orthonormal(f1, f2, a, axis)


def test_phase_and_turning_direction_for_random_axes() -> None:
    rng = np.random.default_rng(11)
    for _ in range(30):
        axis = _random_unit(rng) * 2.0
        c = rng.normal(size=3)
        h = Helix(c, 0.5, axis=axis, omega=1.7, rise=0.2, phase=0.0)
        e1, e2, a = h.frame
        _assert_right_handed_orthonormal(e1, e2, a, axis)
        np.testing.assert_allclose(h.position(0.0), c + 0.5 * e1, atol=1e-15)
        # quarter turn later (θ = π/2) the radial direction is e2, and the axis rose by rise·t
        tq = (math.pi / 2) / 1.7
        np.testing.assert_allclose(h.position(tq), c + 0.2 * tq * a + 0.5 * e2, atol=1e-14)
        # omega > 0 is counter-clockwise seen from the tip of a: (p − axis point) × ṗ · a > 0
        p, v, _ = h.evaluate(0.9)
        radial = p - c - 0.2 * 0.9 * a
        assert float(np.cross(radial, v) @ a) == pytest.approx(0.5**2 * 1.7, rel=1e-12)


# --- check_on_surface --------------------------------------------------------------------------
def test_paper_helix_lies_on_the_paper_cylinder() -> None:
    rep = check_on_surface(paper_helix(), _ZCylinder(0.4), 0.0, 20.0)
    assert isinstance(rep, OnSurfaceReport)
    assert rep.worst_distance < 1e-12
    assert 0.0 <= rep.time_of_worst <= 20.0
    np.testing.assert_allclose(rep.point_of_worst, paper_helix().position(rep.time_of_worst))


def test_paper_helix_on_the_real_cylinder() -> None:
    rep = check_on_surface(paper_helix(), Cylinder(0.4), 0.0, 20.0)
    assert rep.worst_distance < 1e-12


@pytest.mark.parametrize("samples", [5, 2001])
def test_shifted_helix_reported_off_by_the_shift(samples: int) -> None:
    # Paper helix moved by δ along x: ρ(t)² = δ² + 0.16 + 0.8 δ cos t, so on t ∈ [1, 5]
    # |d| = |ρ − 0.4| peaks at t = π with ρ = 0.4 − δ: worst |d| = δ,
    # at p = (δ − 0.4, 0, 10 + π/10).
    # t = π is not a sample time, so the refinement has to find it.
    delta = 0.05
    path = Helix((delta, 0.0, 10.0), 0.4, omega=1.0, rise=0.1)
    rep = check_on_surface(path, _ZCylinder(0.4), 1.0, 5.0, samples=samples)
    assert rep.worst_distance == pytest.approx(delta, abs=1e-14)
    assert rep.time_of_worst == pytest.approx(math.pi, abs=1e-6)
    np.testing.assert_allclose(
        rep.point_of_worst, [delta - 0.4, 0.0, 10.0 + math.pi / 10], rtol=0, atol=1e-6
    )


def test_shifted_helix_on_the_real_cylinder() -> None:
    path = Helix((0.0, 0.03, 10.0), 0.4, omega=1.0, rise=0.1)
    # shift along y: the wall is nearest at θ = −π/2 ≡ 3π/2 (inside by 0.03)
    rep = check_on_surface(path, Cylinder(0.4), 3.0, 6.0, samples=101)
    assert rep.worst_distance == pytest.approx(0.03, abs=1e-14)
    assert rep.time_of_worst == pytest.approx(1.5 * math.pi, abs=1e-6)


def test_worst_at_the_end_of_the_span() -> None:
    # straight line leaving the cylinder radially: d(t) = t, worst at t1
    line = FunctionPath(lambda t: (0.4 + t, 0.0, 1.0))
    rep = check_on_surface(line, _ZCylinder(0.4), 0.0, 2.0, samples=7)
    assert rep.worst_distance == pytest.approx(2.0, abs=1e-14)
    assert rep.time_of_worst == pytest.approx(2.0, abs=1e-12)


def test_check_on_surface_bad_input() -> None:
    h, cyl = paper_helix(), _ZCylinder(0.4)
    with pytest.raises(PathError, match="t1"):
        check_on_surface(h, cyl, 1.0, 1.0)
    with pytest.raises(PathError, match="t1"):
        check_on_surface(h, cyl, 2.0, 1.0)
    with pytest.raises(PathError, match="t0"):
        check_on_surface(h, cyl, float("nan"), 1.0)
    with pytest.raises(PathError, match="t1"):
        check_on_surface(h, cyl, 0.0, float("inf"))
    for bad in (1, 0, -3, 2.5, True):
        with pytest.raises(PathError, match="samples"):
            check_on_surface(h, cyl, 0.0, 1.0, samples=bad)
    with pytest.raises(PathError, match="distance"):
        check_on_surface(h, object(), 0.0, 1.0)

    class _NanSurface:
        def distance(self, p: np.ndarray) -> float:
            return float("nan")

    with pytest.raises(SurfaceError, match="non-finite distance"):
        check_on_surface(h, _NanSurface(), 0.0, 1.0)


def _counting_scans(monkeypatch: pytest.MonkeyPatch) -> list[tuple[float, float]]:
    """Record the (t0, t1) of every scan check_on_surface makes (not of its cached answers)."""
    scans: list[tuple[float, float]] = []
    scan = on_surface._scan

    def counted(path, surface, a, b, n):  # type: ignore[no-untyped-def]
        scans.append((a, b))
        return scan(path, surface, a, b, n)

    monkeypatch.setattr(on_surface, "_scan", counted)
    return scans


# --- FunctionPath ------------------------------------------------------------------------------
def _helix_fns():
    def pos(t):
        return (0.4 * math.cos(t), 0.4 * math.sin(t), t / 10 + 10)

    def vel(t):
        return (-0.4 * math.sin(t), 0.4 * math.cos(t), 0.1)

    def acc(t):
        return (-0.4 * math.cos(t), -0.4 * math.sin(t), 0.0)

    return pos, vel, acc


def test_function_path_numerical_derivatives_within_documented_accuracy() -> None:
    pos, vel, acc = _helix_fns()
    rng = np.random.default_rng(31)
    h = 1e-3
    only_p = FunctionPath(pos)
    p_and_v = FunctionPath(pos, vel)
    full = FunctionPath(pos, vel, acc)
    for t in rng.uniform(0.0, 20.0, 100):
        t = float(t)
        pmax = 10.0 + (abs(t) + 2 * h) / 10  # max |p| component on [t − 2h, t + 2h]
        # documented bounds (class docstring), with the derivatives of eq. 25 bounded by 0.4
        # and, for safety, a factor 4 plus the rounding of t ± h (ε|t|·|ṗ|·(sum of weights)/h)
        bound_v = 4 * (h**4 / 30 * 0.4 + 1.5 * EPS * pmax / h + 1.5 * EPS * abs(t) * 0.4 / h)
        bound_a_from_v = 4 * (h**4 / 30 * 0.4 + 1.5 * EPS * 0.4 / h + 1.5 * EPS * abs(t) * 0.4 / h)
        bound_a_from_p = 4 * (
            h**4 / 90 * 0.4 + 5.4 * EPS * pmax / h**2 + 5.4 * EPS * t * 0.4 / h**2
        )
        p, v, a = only_p.evaluate(t)
        np.testing.assert_allclose(p, pos(t), rtol=0, atol=0)
        assert np.max(np.abs(v - vel(t))) < bound_v
        assert np.max(np.abs(a - acc(t))) < bound_a_from_p
        _, v2, a2 = p_and_v.evaluate(t)
        np.testing.assert_allclose(v2, vel(t), rtol=0, atol=0)
        assert np.max(np.abs(a2 - acc(t))) < bound_a_from_v
        p3, v3, a3 = full.evaluate(t)
        for got, want in zip((p3, v3, a3), (pos(t), vel(t), acc(t)), strict=True):
            np.testing.assert_array_equal(got, want)


def test_function_path_stencils_are_exact_on_polynomials() -> None:
    # the fourth-order stencils differentiate polynomials of degree ≤ 4 exactly (up to rounding)
    fp = FunctionPath(lambda t: (t**4, t**3 - 2 * t, 3 * t**2 + 1), step=0.01)
    for t in (-1.3, 0.0, 0.7, 2.0):
        _, v, a = fp.evaluate(t)
        np.testing.assert_allclose(v, [4 * t**3, 3 * t**2 - 2, 6 * t], rtol=0, atol=1e-11)
        np.testing.assert_allclose(a, [12 * t**2, 6 * t, 6.0], rtol=0, atol=1e-8)


def test_function_path_matches_helix_class() -> None:
    pos, _, _ = _helix_fns()
    fp, hx = FunctionPath(pos), paper_helix()
    for t in (0.0, 1.0, 7.5):
        for x, y in zip(fp.evaluate(t), hx.evaluate(t), strict=True):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-7)


def test_function_path_bad_input() -> None:
    with pytest.raises(PathError, match="position"):
        FunctionPath(None)  # type: ignore[arg-type]
    with pytest.raises(PathError, match="velocity"):
        FunctionPath(lambda t: (0, 0, 0), velocity=3.0)  # type: ignore[arg-type]
    for bad in (0.0, -1e-3, float("nan")):
        with pytest.raises(PathError, match="step"):
            FunctionPath(lambda t: (0, 0, 0), step=bad)
    nan_at_2 = FunctionPath(lambda t: (t, 0.0, math.nan if t > 2 else 0.0))
    nan_at_2.evaluate(1.0)
    with pytest.raises(PathError, match=r"position\(2\.5\).*non-finite"):
        nan_at_2.evaluate(2.5)
    with pytest.raises(PathError, match=r"shape \(2,\)"):
        FunctionPath(lambda t: (t, 0.0)).evaluate(0.0)
    with pytest.raises(PathError, match="acceleration"):
        FunctionPath(lambda t: (t, 0, 0), acceleration=lambda t: "abc").evaluate(0.0)
    with pytest.raises(PathError, match="cannot be written"):
        FunctionPath(lambda t: (t, 0, 0)).to_dict()


# --- dicts -------------------------------------------------------------------------------------
def test_dict_round_trip() -> None:
    rng = np.random.default_rng(5)
    paths = [
        paper_helix(),
        Helix(rng.normal(size=3), 0.3, axis=rng.normal(size=3), omega=-2.0, rise=0.05, phase=1.0),
        Circle(np.array([0.5, 0.0, 0.3]), 0.2, (1, 1, 0), 0.5),
        Circle((0, 0, 0), 1.0, (0, 0, 1), 1.0, phase=-0.3),
    ]
    for path in paths:
        d = path.to_dict()
        back = path_from_dict(json.loads(json.dumps(d)))
        assert type(back) is type(path)
        assert back == path
        for t in (0.0, 1.234):
            for x, y in zip(back.evaluate(t), path.evaluate(t), strict=True):
                np.testing.assert_array_equal(x, y)
    assert paper_helix().to_dict() == {
        "type": "helix",
        "center": [0.0, 0.0, 10.0],
        "radius": 0.4,
        "axis": [0.0, 0.0, 1.0],
        "omega": 1.0,
        "rise": 0.1,
        "phase": 0.0,
    }
    # optional keys take their defaults
    assert (
        path_from_dict(
            {"type": "helix", "center": [0, 0, 10], "radius": 0.4, "omega": 1, "rise": 0.1}
        )
        == paper_helix()
    )


def test_path_from_dict_bad_input() -> None:
    with pytest.raises(PathError, match=r"did you mean 'helix'.*circle"):
        path_from_dict({"type": "helx", "center": [0, 0, 0], "radius": 1})
    with pytest.raises(PathError, match="no 'type'"):
        path_from_dict({"center": [0, 0, 0]})
    with pytest.raises(PathError, match=r"missing \['rise'\]"):
        path_from_dict({"type": "helix", "center": [0, 0, 0], "radius": 1, "omega": 1})
    with pytest.raises(PathError, match=r"path\.radus.*did you mean 'radius'"):
        path_from_dict({"type": "circle", "radus": 1})
    with pytest.raises(PathError, match="table/dict"):
        path_from_dict([1, 2, 3])  # type: ignore[arg-type]
    with pytest.raises(PathError, match=r"Circle\.radius.*-2"):
        path_from_dict(
            {"type": "circle", "center": [0, 0, 0], "radius": -2, "normal": [0, 0, 1], "omega": 1}
        )


# --- bad parameters ----------------------------------------------------------------------------
_GOOD_HELIX = {"center": (0, 0, 0), "radius": 0.4, "axis": (0, 0, 1), "omega": 1, "rise": 0.1}
_GOOD_CIRCLE = {"center": (0, 0, 0), "radius": 0.4, "normal": (0, 0, 1), "omega": 1}


@pytest.mark.parametrize(
    ("cls", "good", "name", "value"),
    [
        (Helix, _GOOD_HELIX, "radius", 0.0),
        (Helix, _GOOD_HELIX, "radius", -0.4),
        (Helix, _GOOD_HELIX, "radius", float("nan")),
        (Helix, _GOOD_HELIX, "radius", float("inf")),
        (Helix, _GOOD_HELIX, "radius", "big"),
        (Helix, _GOOD_HELIX, "axis", (0.0, 0.0, 0.0)),
        (Helix, _GOOD_HELIX, "axis", (float("nan"), 0.0, 1.0)),
        (Helix, _GOOD_HELIX, "axis", (0.0, 1.0)),
        (Helix, _GOOD_HELIX, "center", (float("inf"), 0.0, 0.0)),
        (Helix, _GOOD_HELIX, "omega", float("nan")),
        (Helix, _GOOD_HELIX, "rise", float("-inf")),
        (Helix, _GOOD_HELIX, "phase", float("nan")),
        (Circle, _GOOD_CIRCLE, "radius", -1.0),
        (Circle, _GOOD_CIRCLE, "normal", (0, 0, 0)),
        (Circle, _GOOD_CIRCLE, "normal", (0, float("inf"), 1)),
        (Circle, _GOOD_CIRCLE, "center", (0, 0, float("nan"))),
        (Circle, _GOOD_CIRCLE, "omega", float("inf")),
        (Circle, _GOOD_CIRCLE, "phase", float("nan")),
    ],
)
def test_bad_parameters_are_named(cls, good, name, value) -> None:
    kwargs = {**good, name: value}
    with pytest.raises(PathError) as info:
        cls(**kwargs)
    msg = str(info.value)
    assert f"{cls.__name__}.{name}" in msg
    assert repr(value) in msg or str(value) in msg
    assert isinstance(info.value, BadInputError)


def test_axis_frame_rejects_zero_axis() -> None:
    with pytest.raises(PathError, match="axis"):
        axis_frame((0.0, 0.0, 0.0))


def test_direction_jet_closed_form_against_central_differences() -> None:
    """A helix's p⃛ in closed form against the base class's central difference of p̈."""
    from hybrid_force.geometry.paths import Circle, Helix, Path

    for path in (
        Helix([0.1, 0.2, 0.3], 0.4, axis=[1.0, 2.0, 2.0], omega=1.3, rise=0.05, phase=0.7),
        Circle([0.0, 0.0, 1.0], 0.2, [0.0, 1.0, 1.0], omega=-2.0),
    ):
        for t in (0.0, 0.4, 3.3):
            jet = path.direction_jet(t)
            _, v, a = path.evaluate(t)
            np.testing.assert_array_equal(jet[:2], [v, a])
            np.testing.assert_allclose(jet[2], Path.direction_jet(path, t)[2], atol=1e-8)

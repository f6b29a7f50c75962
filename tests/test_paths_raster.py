"""Raster paths on a surface (hybrid_force.geometry.raster) and ``type = "raster"``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_continuous_at, assert_derivatives_are_differences, path_breaks

from hybrid_force.errors import PathError, ScenarioError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.charts import chart_for
from hybrid_force.geometry.ellipsoid import Ellipsoid
from hybrid_force.geometry.paths import path_from_dict
from hybrid_force.geometry.piecewise import blend_piece
from hybrid_force.geometry.raster import RasterPath, _metric_turn
from hybrid_force.phases import CONTACT
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

SCENARIOS = Path(__file__).parents[1] / "scenarios"
FLOOR = Plane((0.0, 0.0, 5.0), (0.0, 0.0, 1.0))  # e_u = x, e_v = y from its point

CASES = {  # surface, origin, size, spacing, direction
    "plane": (FLOOR, (0.5, -0.1), (0.3, 0.2), 0.1, "u"),
    "tilted plane": (Plane((1.0, 0.0, 0.0), (1.0, 2.0, 2.0)), (0.0, 0.0), (0.2, 0.25), 0.1, "v"),
    "cylinder": (Cylinder(0.4), (-0.3, 7.0), (0.6, 0.3), 0.1, "u"),
    "cylinder across": (Cylinder(0.4, inside=True), (-0.3, 7.0), (0.6, 0.3), 0.2, "v"),
    "sphere": (Sphere(0.5, center=(0.0, 0.0, 5.0)), (-0.8, -0.3), (0.4, 0.6), 0.1, "v"),
    "sphere across": (Sphere(0.5, center=(0.0, 0.0, 5.0)), (-0.8, -0.3), (0.4, 0.6), 0.1, "u"),
}


@pytest.fixture(params=list(CASES), scope="module")
def raster(request: pytest.FixtureRequest) -> RasterPath:
    surface, origin, size, spacing, direction = CASES[request.param]
    return RasterPath(surface, origin, size, spacing, 0.1, direction=direction, ramp=0.3)


def test_on_the_surface_by_construction(raster: RasterPath, rng: np.random.Generator) -> None:
    for t in rng.uniform(-1.0, raster.duration + 1.0, 300):
        assert abs(raster.surface.distance(raster.position(t))) < 1e-9  # type: ignore[attr-defined]


def test_derivatives_are_differences_and_continuous_at_every_junction(
    raster: RasterPath, rng: np.random.Generator
) -> None:
    assert len(raster.junction_times) == 2 * raster.passes  # pass, turn, pass, ..., pass
    assert_derivatives_are_differences(raster, rng)
    assert_continuous_at(raster, path_breaks(raster))


def test_moves_at_the_speed_outside_the_ramps(raster: RasterPath) -> None:
    for t in np.linspace(raster.law.ramp, raster.duration - raster.law.ramp, 2000):
        assert np.linalg.norm(raster.evaluate(t)[1]) == pytest.approx(0.1, rel=1e-8)


def test_a_plane_raster_by_hand() -> None:
    # passes at y = −0.1, 0, 0.1 between x = 0.5 and 0.8; each turn the quintic
    # (x, y) = (0.8 + L(s − 2s³ + s⁴), −0.1 + w(10s³ − 15s⁴ + 6s⁵)), s ∈ [0, 1], w = 0.1, whose
    # parametric speed peaks at 1.875 w / L half way: L = 1.875 w; symmetric about s = 1/2,
    # where it swings out to x = 0.8 + 0.3125 L
    path = RasterPath(FLOOR, (0.5, -0.1), (0.3, 0.2), 0.1, 0.1, ramp=0.3)
    assert path.passes == 3
    w, big_l = 0.1, 0.1875
    np.testing.assert_allclose(path.turn_lengths, [big_l, big_l], rtol=1e-9)
    s = np.linspace(0.0, 1.0, 200001)
    turn = np.stack((big_l * (s - 2 * s**3 + s**4), w * (10 * s**3 - 15 * s**4 + 6 * s**5)), 1)
    turn_length = np.linalg.norm(np.diff(turn, axis=0), axis=1).sum()
    assert path.duration == pytest.approx((3 * 0.3 + 2 * turn_length) / 0.1 + 0.3, rel=1e-9)
    times = path.junction_times
    assert times[2] - times[1] == pytest.approx(turn_length / 0.1, rel=1e-9)
    corners = [(0.5, -0.1), (0.8, -0.1), (0.8, 0.0), (0.5, 0.0), (0.5, 0.1), (0.8, 0.1)]
    for t, (x, y) in zip(times, corners, strict=True):
        np.testing.assert_allclose(path.position(t), [x, y, 5.0], atol=1e-12)
    middle = path.position(0.5 * (times[1] + times[2]))
    np.testing.assert_allclose(middle, [0.8 + 0.3125 * big_l, -0.05, 5.0], atol=1e-9)


def test_passes_are_evenly_spaced_at_most_spacing_apart() -> None:
    path = RasterPath(FLOOR, (0.0, 0.0), (0.3, 0.25), 0.1, 0.1)
    assert path.passes == 4  # ⌈0.25 / 0.1⌉ + 1
    assert path.pass_spacing == pytest.approx(0.25 / 3, rel=1e-15)
    ends = [path.position(t)[1] for t in path.junction_times[::2]]
    np.testing.assert_allclose(ends, [0.0, 0.25 / 3, 0.5 / 3, 0.25], atol=1e-12)
    assert RasterPath(FLOOR, (0.0, 0.0), (0.3, 0.2), 0.2, 0.1).passes == 2


def test_dict_round_trip() -> None:
    path = RasterPath(Sphere(0.5), (0.1, 0.2), (0.3, 0.4), 0.15, 0.2, direction="v", ramp=0.4)
    data = path.to_dict()
    assert data["passes"] == 3  # ⌈0.3 / 0.15⌉ + 1 across, in latitude
    again = path_from_dict(data)
    assert again.to_dict() == data
    for t in np.linspace(0.0, path.duration, 7):
        np.testing.assert_array_equal(again.evaluate(t), path.evaluate(t))


@pytest.mark.parametrize(
    ("surface", "args", "kwargs", "key", "match"),
    [
        (FLOOR, ((0, 0), (0.3, 0.2), 0.3, 0.1), {}, "spacing", r"spacing = 0\.3 is larger"),
        (FLOOR, ((0, 0), (0.3, 0.4), 0.35, 0.1), {"direction": "v"}, "spacing", r"size\[0\]"),
        (FLOOR, ((0, 0), (0.3, 0.0), 0.1, 0.1), {}, "size", "2 finite numbers > 0"),
        (FLOOR, ((0, 0, 0), (0.3, 0.2), 0.1, 0.1), {}, "origin", "2 finite numbers"),
        (FLOOR, ((0, 0), (0.3, 0.2), -0.1, 0.1), {}, "spacing", "positive"),
        (FLOOR, ((0, 0), (0.3, 0.2), 0.1, 0.0), {}, "speed", "positive"),
        (FLOOR, ((0, 0), (0.3, 0.2), 0.1, 0.1), {"direction": "w"}, "direction", "'u' or 'v'"),
        (
            Sphere(0.5),
            ((1.0, 0.0), (math.pi / 2 - 1.0, 0.4), 0.1, 0.1),
            {"direction": "v"},
            "size",
            "no length on the surface",
        ),
    ],
)
def test_bad_rasters_are_refused_naming_the_parameter(
    surface: object, args: tuple, kwargs: dict, key: str, match: str
) -> None:
    with pytest.raises(PathError, match=match) as info:
        RasterPath(surface, *args, **kwargs)
    assert info.value.key == key


# --- a chart whose speed along the passes varies: a triaxial ellipsoid -----------------------
AXES = np.array([0.3, 0.2, 0.15])
CENTER = np.array([0.1, -0.2, 0.3])
TRIAXIAL = Ellipsoid(tuple(AXES), center=tuple(CENTER))
TRIAXIAL_CASES = {  # origin, size, spacing [rad], direction: latitude φ and longitude λ
    "along latitude": ((-0.5, 0.3), (1.0, 1.0), 0.25, "u"),
    "along longitude": ((-0.5, 0.3), (1.0, 1.0), 0.25, "v"),
}


def _ellipsoid_point(phi: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """S(φ, λ) of TRIAXIAL written out here: c + (a cos φ cos λ, b cos φ sin λ, c sin φ)."""
    local = np.stack((np.cos(phi) * np.cos(lam), np.cos(phi) * np.sin(lam), np.sin(phi)), -1)
    return CENTER + AXES * local


def _ellipsoid_coordinates(p: np.ndarray) -> np.ndarray:
    """(φ, λ) of points on TRIAXIAL, (N, 3) → (N, 2), inverting :func:`_ellipsoid_point`."""
    s = (p - CENTER) / AXES
    return np.stack((np.arcsin(np.clip(s[:, 2], -1, 1)), np.arctan2(s[:, 1], s[:, 0])), -1)


@pytest.fixture(params=list(TRIAXIAL_CASES), scope="module")
def triaxial(request: pytest.FixtureRequest) -> RasterPath:
    origin, size, spacing, direction = TRIAXIAL_CASES[request.param]
    return RasterPath(TRIAXIAL, origin, size, spacing, 0.05, direction=direction, ramp=0.3)


def test_the_varying_speed_turn_is_the_plane_turn_on_a_plane() -> None:
    # _metric_turn sets the blend's speed half way to the passes': on a plane, by hand (as in
    # test_a_plane_raster_by_hand), 1.875 w / L = 1, so L = 1.875 w whatever the chart's axes
    chart = chart_for(Plane((1.0, 0.0, 0.0), (1.0, 2.0, 2.0)))
    w = 0.07
    p0, p1 = np.array([0.3, 0.1]), np.array([0.3, 0.1 + w])
    d0, d1 = np.array([1.0, 0.0]), np.array([-1.0, 0.0])
    length, piece = _metric_turn(chart, p0, d0, p1, d1, along=0)
    assert length == pytest.approx(1.875 * w, rel=1e-12)
    np.testing.assert_allclose(piece, blend_piece(p0, d0, p1, d1, 1.875 * w), atol=1e-12)


def test_a_triaxial_raster_stays_on_the_surface(triaxial: RasterPath) -> None:
    # the speed along a pass varies by tens of % (its chart's metric): no constant-speed turn
    for t in np.linspace(-0.5, triaxial.duration + 0.5, 2001):
        p = triaxial.position(t)
        assert abs(float(np.sum(np.square((p - CENTER) / AXES))) - 1.0) < 1e-12
        assert abs(TRIAXIAL.distance(p)) < 1e-12
    # the turns are short, as on a plane (1.875 times the metric spacing, 0.2 m · 0.25 rad
    # across at most): not the ~1e20 the constant-speed bound gave on this chart
    assert np.all(triaxial.turn_lengths < 1.875 * 0.3 * 0.25)


def test_a_triaxial_raster_moves_at_the_speed_by_differences(triaxial: RasterPath) -> None:
    h = 1e-4
    times = np.linspace(triaxial.law.ramp + h, triaxial.duration - triaxial.law.ramp - h, 3001)
    for t in times:
        difference = (triaxial.position(t + h) - triaxial.position(t - h)) / (2.0 * h)
        assert np.linalg.norm(difference) == pytest.approx(0.05, rel=1e-6)
        assert np.linalg.norm(triaxial.evaluate(t)[1]) == pytest.approx(0.05, rel=5e-8)


def test_a_triaxial_raster_is_c2_at_its_turns(
    triaxial: RasterPath, rng: np.random.Generator
) -> None:
    # one-sided differences of p from each side of a junction, ṗ and p̈ both to O(h²): a
    # turn only C¹ (a semicircle) would jump p̈ by ‖ṗ‖²/ρ ≈ 0.05²/0.05 = 0.05 m/s²
    h = 1e-3
    for t in triaxial.junction_times[1:-1]:
        left = [triaxial.position(t - j * h) for j in range(4)]
        right = [triaxial.position(t + j * h) for j in range(4)]
        v_left = (3.0 * left[0] - 4.0 * left[1] + left[2]) / (2.0 * h)
        v_right = (-3.0 * right[0] + 4.0 * right[1] - right[2]) / (2.0 * h)
        a_left = (2.0 * left[0] - 5.0 * left[1] + 4.0 * left[2] - left[3]) / h**2
        a_right = (2.0 * right[0] - 5.0 * right[1] + 4.0 * right[2] - right[3]) / h**2
        np.testing.assert_allclose(v_left, v_right, rtol=0, atol=1e-6)
        np.testing.assert_allclose(a_left, a_right, rtol=0, atol=2e-4)
        assert np.linalg.norm(a_left) > 1e-3  # the turn does bend: the check is not vacuous
    assert_derivatives_are_differences(triaxial, rng)
    assert_continuous_at(triaxial, path_breaks(triaxial))


def test_a_triaxial_raster_keeps_the_spacing(triaxial: RasterPath) -> None:
    origin, size, spacing, direction = TRIAXIAL_CASES[
        "along latitude" if triaxial.direction == "u" else "along longitude"
    ]
    along = 0 if direction == "u" else 1
    assert triaxial.passes == 5 and triaxial.pass_spacing == pytest.approx(spacing)  # 1 / 0.25
    times = triaxial.junction_times
    for k in range(triaxial.passes):
        inner = np.linspace(times[2 * k], times[2 * k + 1], 101)
        points = np.array([triaxial.position(t) for t in inner])
        uv = _ellipsoid_coordinates(points)
        # a pass is the coordinate line at origin + k·spacing across, over the whole extent
        np.testing.assert_allclose(uv[:, 1 - along], origin[1 - along] + k * spacing, atol=1e-9)
        ends = sorted((uv[0, along], uv[-1, along]))
        np.testing.assert_allclose(ends, [origin[along], origin[along] + size[along]], atol=1e-9)
        if k == 0:
            continue
        # with distance: each point's distance to the previous pass, the coordinate line
        # sampled densely from the closed form, is the metric length of the coordinate curve
        # across between them (the polyline of 2001 points: the chart's skew is small here)
        line = np.linspace(origin[along] - 0.1, origin[along] + size[along] + 0.1, 20001)
        fixed = np.full_like(line, origin[1 - along] + (k - 1) * spacing)
        previous = _ellipsoid_point(*((line, fixed) if along == 0 else (fixed, line)))
        for p, (u, v) in zip(points[::10], uv[::10], strict=True):
            nearest = float(np.min(np.linalg.norm(previous - p, axis=1)))
            across = np.linspace(0.0, -spacing, 2001) + (v if along == 0 else u)
            still = np.full_like(across, u if along == 0 else v)
            curve = _ellipsoid_point(*((still, across) if along == 0 else (across, still)))
            metric = float(np.linalg.norm(np.diff(curve, axis=0), axis=1).sum())
            assert 0.9 * metric < nearest <= metric + 1e-9


def test_a_wide_turn_where_the_speed_changes_fast_across_it() -> None:
    # two passes along latitude 1.14 rad of longitude apart on a turned triaxial ellipsoid: the
    # turn swings far, where the passes' speed changes as fast as the swing grows (the
    # fixed point L ← L·ratio oscillated there); the turn is still found, and the path is C²
    # and at its speed
    turned = Ellipsoid(tuple(AXES), center=tuple(CENTER), rpy=(0.3, 0.2, -0.4))
    path = RasterPath(turned, (-0.48, 1.97), (0.39, 1.14), 1.14, 0.05, ramp=0.3)
    assert path.passes == 2 and 0.0 < path.turn_lengths[0] < 1.875 * 0.3 * 1.14
    h = 1e-4
    for t in np.linspace(0.3 + h, path.duration - 0.3 - h, 400):
        assert abs(turned.distance(path.position(t))) < 1e-12
        difference = (path.position(t + h) - path.position(t - h)) / (2.0 * h)
        assert np.linalg.norm(difference) == pytest.approx(0.05, rel=1e-6)
    assert_continuous_at(path, path_breaks(path))


# --- scenario files --------------------------------------------------------------------------
SPHERE_RASTER = {  # on rtr_sphere's sphere, from its start [0.4, 0, 4.7]: latitude asin(−0.6)
    "type": "raster",
    "origin": [math.asin(-0.6), 0.0],
    "size": [0.2, 0.1],
    "spacing": 0.05,
    "direction": "v",
    "speed": 0.1,
    "ramp": 0.2,
}


def test_a_raster_scenario_loads_and_runs_on_the_surface() -> None:
    scenario = load_scenario(
        SCENARIOS / "rtr_sphere.toml", {"trajectory": SPHERE_RASTER, "sim.duration": 1.0}
    )
    path = scenario.path
    assert isinstance(path, RasterPath)
    assert path.junction_times[1] < 0.8  # the run reaches the first turn
    result = simulate(scenario)
    assert result.status == "ok"
    sphere = scenario.surfaces[0]
    assert max(abs(sphere.distance(p)) for p in result.p) < 1e-9
    assert np.all(result.phase == CONTACT)
    assert np.abs(result.p - result.p_d).max() < 1e-3
    np.testing.assert_allclose(result.f[-1], 10.0, atol=1e-3)


def test_the_loader_names_file_key_and_value(tmp_path: Path) -> None:
    file = tmp_path / "x.toml"
    file.write_text((SCENARIOS / "rtr_plane.toml").read_text())
    raster = {**SPHERE_RASTER, "origin": [0.6, 0.0], "spacing": 0.5}
    with pytest.raises(ScenarioError, match=r"x\.toml: trajectory\.spacing = 0\.5: .*larger"):
        load_scenario(file, {"trajectory": raster})
    with pytest.raises(ScenarioError, match=r"x\.toml: trajectory\.origin = \[0\.6\]: .*2 finite"):
        load_scenario(file, {"trajectory": {**raster, "origin": [0.6], "spacing": 0.05}})
    with pytest.raises(ScenarioError, match=r"x\.toml: trajectory\.direction = \"w\": must be"):
        load_scenario(file, {"trajectory": {**raster, "direction": "w"}})

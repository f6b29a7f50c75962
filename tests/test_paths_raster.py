"""Raster paths on a surface (hybrid_force.geometry.raster) and ``type = "raster"``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_continuous_at, assert_derivatives_are_differences, path_breaks

from hybrid_force.errors import PathError, ScenarioError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.paths import path_from_dict
from hybrid_force.geometry.raster import RasterPath
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

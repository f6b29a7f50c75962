"""Waypoint paths on a surface (hybrid_force.geometry.waypoints) and ``type = "waypoints"``."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_continuous_at, assert_derivatives_are_differences, path_breaks

from hybrid_force.errors import PathError, RunWarning, ScenarioError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.charts import chart_for
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.paths import path_from_dict
from hybrid_force.geometry.waypoints import WaypointPath
from hybrid_force.phases import CONTACT
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

SCENARIOS = Path(__file__).parents[1] / "scenarios"
FLOOR = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))  # (u, v) = (x, y)

CASES = {  # surface, waypoints in its coordinates
    "cylinder": (Cylinder(0.4), [[0.0, 7.0], [0.5, 7.1], [1.5, 7.0], [2.0, 7.3], [8.0, 7.2]]),
    "tilted cylinder": (
        Cylinder(0.3, center=(0.1, 0.2, 0.3), axis=(1.0, 0.0, 1.0), inside=True),
        [[0.0, 0.0], [-1.0, 0.2], [-1.2, 0.5], [-2.5, 0.6]],
    ),
    "sphere": (
        Sphere(0.5, center=(0.0, 0.0, 5.0)),
        [[-0.6, 0.0], [-0.5, 0.4], [-0.7, 0.9], [-0.3, 1.5], [1.5, 2.0]],
    ),
    "plane": (
        Plane((0.0, 0.0, 5.0), (1.0, 1.0, 1.0)),
        [[0.6, 0.0], [0.65, 0.1], [0.55, 0.2], [0.6, 0.3], [0.6, 1.3]],
    ),
}


@pytest.fixture(params=list(CASES), scope="module")
def case(request: pytest.FixtureRequest) -> tuple[object, np.ndarray, WaypointPath]:
    surface, points = CASES[request.param]
    return surface, np.array(points), WaypointPath(surface, points, 0.2, frame="surface", ramp=0.3)


def test_on_the_surface_by_construction(case: tuple, rng: np.random.Generator) -> None:
    surface, _, path = case
    for t in rng.uniform(-1.0, path.duration + 1.0, 300):
        assert abs(surface.distance(path.position(t))) < 1e-9


def test_passes_the_waypoints_at_their_times(case: tuple) -> None:
    surface, points, path = case
    chart = chart_for(surface)
    assert len(path.junction_times) == len(points)
    assert path.junction_times[0] == 0.0
    assert path.junction_times[-1] == pytest.approx(path.duration, rel=1e-14)
    for t, (u, v) in zip(path.junction_times, points, strict=True):
        np.testing.assert_allclose(path.position(t), chart.point(u, v), rtol=0, atol=1e-9)


def test_derivatives_are_differences_and_continuous(case: tuple, rng: np.random.Generator) -> None:
    path = case[2]
    assert_derivatives_are_differences(path, rng)
    assert_continuous_at(path, path_breaks(path))


def test_starts_and_ends_at_rest_and_holds_the_end(case: tuple) -> None:
    path = case[2]
    end = path.position(path.duration)
    for t in (-1.0, 0.0, path.duration, path.duration + 5.0):
        _, v, a = path.evaluate(t)
        np.testing.assert_array_equal(v, 0.0)
        np.testing.assert_allclose(a, 0.0, atol=1e-15)
    np.testing.assert_array_equal(path.position(path.duration + 5.0), end)


def test_moves_at_the_speed_outside_the_ramps(case: tuple) -> None:
    path = case[2]
    for t in np.linspace(path.law.ramp, path.duration - path.law.ramp, 500):
        assert np.linalg.norm(path.evaluate(t)[1]) == pytest.approx(0.2, rel=1e-8)
    for t in np.linspace(0.0, path.law.ramp, 50):  # the ramp: ‖ṗ‖ = speed (3x² − 2x³)
        x = t / path.law.ramp
        assert np.linalg.norm(path.evaluate(t)[1]) == pytest.approx(
            0.2 * x * x * (3 - 2 * x), abs=1e-9
        )


def test_three_points_on_a_plane_by_hand() -> None:
    # the natural spline with chord-length knots h0, h1 through P0, P1, P2: M1 = 3(s1 − s0) /
    # (h0 + h1) (s the chord slopes), pieces P0 + b0 x + M1 x³ / (6 h0) and
    # P1 + b1 x + M1 x² / 2 − M1 x³ / (6 h1); the path takes their lengths at the speed
    points = np.array([[0.0, 0.0], [0.3, 0.1], [0.4, 0.4]])
    h0, h1 = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s0, s1 = (points[1] - points[0]) / h0, (points[2] - points[1]) / h1
    m1 = 3.0 * (s1 - s0) / (h0 + h1)
    x0, x1 = np.linspace(0.0, h0, 20001)[:, None], np.linspace(0.0, h1, 20001)[:, None]
    first = points[0] + (s0 - h0 * m1 / 6) * x0 + m1 * x0**3 / (6 * h0)
    second = points[1] + (s1 - h1 * m1 / 3) * x1 + m1 * x1**2 / 2 - m1 * x1**3 / (6 * h1)
    l0, l1 = (np.linalg.norm(np.diff(c, axis=0), axis=1).sum() for c in (first, second))
    path = WaypointPath(FLOOR, points, 0.1, frame="surface", ramp=0.2)
    assert path.duration == pytest.approx((l0 + l1) / 0.1 + 0.2, rel=1e-8)
    assert path.junction_times[1] == pytest.approx(l0 / 0.1 + 0.1, rel=1e-8)  # in the cruise


def test_two_points_on_a_cylinder_give_a_helix_at_the_speed() -> None:
    # a straight line in (θ, h) is a helix: length √((rΔθ)² + Δh²) by hand, and the spline
    # through two points moves along it at a constant rate, so ‖ṗ‖ = speed in the cruise
    path = WaypointPath(Cylinder(0.4), [[0.0, 7.0], [3.0, 8.0]], 0.25, frame="surface", ramp=0.5)
    length = math.hypot(0.4 * 3.0, 1.0)
    assert path.duration == pytest.approx(length / 0.25 + 0.5, rel=1e-12)
    for t in np.linspace(0.5, path.duration - 0.5, 30):
        p, v, _ = path.evaluate(t)
        assert np.linalg.norm(v) == pytest.approx(0.25, rel=1e-12)
        theta = math.atan2(p[1], p[0]) % (2 * math.pi)
        assert (p[2] - 7.0) / theta == pytest.approx(1.0 / 3.0, rel=1e-9)  # the helix' pitch


def test_world_points_are_projected_and_the_distances_reported() -> None:
    plane = Plane((0.0, 0.0, 5.0), (0.0, 0.0, 1.0))
    points = [[0.6, 0.0, 5.0], [0.7, 0.2, 5.0004], [0.5, 0.4, 4.99]]
    with pytest.warns(RunWarning, match=r"points\[2\].*0\.01 m from Plane.*projection_tol"):
        path = WaypointPath(plane, points, 0.1)
    assert path.projection_distances is not None
    np.testing.assert_allclose(path.projection_distances, [0.0, 4e-4, 0.01], atol=1e-12)
    assert path.to_dict()["projection_distances"] == pytest.approx([0.0, 4e-4, 0.01], abs=1e-12)
    for t, p in zip(path.junction_times, points, strict=True):
        np.testing.assert_allclose(path.position(t), [p[0], p[1], 5.0], atol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        WaypointPath(plane, points[:2], 0.1)  # within projection_tol = 1 mm: no warning
        WaypointPath(plane, points, 0.1, projection_tol=0.02)


def test_world_points_on_a_cylinder_go_the_shorter_way_round() -> None:
    # θ = 3 and θ = −3 are 0.28 rad apart across θ = π, 5.7 rad the other way
    points = [[0.4 * math.cos(a), 0.4 * math.sin(a), 7.0] for a in (3.0, -3.0)]
    path = WaypointPath(Cylinder(0.4), points, 0.1)
    middle = path.position(path.duration / 2)
    np.testing.assert_allclose(middle, [-0.4, 0.0, 7.0], atol=1e-12)
    assert path.duration == pytest.approx(0.4 * (2 * math.pi - 6.0) / 0.1 + path.law.ramp)


def test_dict_round_trip() -> None:
    plane = Plane((0.0, 0.0, 5.0), (0.0, 0.0, 1.0))
    path = WaypointPath(
        plane, [[0.0, 0.0], [0.1, 0.3], [0.4, 0.1]], 0.1, frame="surface", u_axis=(1.0, 1.0, 0.0)
    )
    data = path.to_dict()
    again = path_from_dict(data)
    assert again.to_dict() == data
    for t in np.linspace(0.0, path.duration, 7):
        np.testing.assert_array_equal(again.evaluate(t), path.evaluate(t))
    with pytest.raises(PathError, match="not a parameter of a waypoints path"):
        path_from_dict({**data, "colour": "red"})


@pytest.mark.parametrize(
    ("surface", "points", "kwargs", "key", "match"),
    [
        (Cylinder(0.4), [[0.0, 7.0]], {"frame": "surface"}, "points", "at least 2 points"),
        (Cylinder(0.4), [[0.0, 7.0, 1.0]], {}, "points", "shape"),
        (
            Cylinder(0.4),
            [[0.0, 7.0], [1.0, 7.0], [1.0, 7.0]],
            {"frame": "surface"},
            "points",
            r"points\[1\] and points\[2\] are the same point",
        ),
        (
            Sphere(0.5),
            [[0.5 * math.pi, 0.0], [0.5 * math.pi, 2.0]],  # the pole, whatever the longitude
            {"frame": "surface"},
            "points",
            "same point",
        ),
        (Cylinder(0.4), [[0.4, 0, 7], [0.0, 0.0, 8.0]], {}, "points", r"points\[1\].*undefined"),
        (Sphere(0.5), [[0.0, 0.0, 0.0], [0.5, 0, 0]], {}, "points", r"points\[0\].*undefined"),
        (Cylinder(0.4), [[0.0, 7.0], [1.0, 7.0]], {"frame": "chart"}, "frame", "'world' or"),
        (
            Plane((0, 0, 0), (0, 0, 1)),
            [[0.0, 0.0, 0.0], [1.0, 0, 0]],
            {"speed": 0.0},
            "speed",
            "speed",
        ),
        (
            Plane((0, 0, 0), (0, 0, 1)),
            [[0.0, 0.0, 0.0], [1.0, 0, 0]],
            {"ramp": -1.0},
            "ramp",
            "ramp",
        ),
    ],
)
def test_bad_waypoints_are_refused_naming_the_parameter(
    surface: object, points: list, kwargs: dict, key: str, match: str
) -> None:
    kwargs = {"speed": 0.1, **kwargs}
    with pytest.raises(PathError, match=match) as info:
        WaypointPath(surface, points, **kwargs)
    assert info.value.key == key


def test_a_user_defined_surface_is_refused() -> None:
    ball = FunctionSurface(lambda p: float(p @ p) - 1.0)
    for frame, point in (("surface", [0.0, 0.0]), ("world", [1.0, 0.0, 0.0])):
        with pytest.raises(PathError, match="has no chart"):
            WaypointPath(ball, [point, point], 0.1, frame=frame)


# --- scenario files --------------------------------------------------------------------------
PLANE_WAYPOINTS = {  # on rtr_plane's plane z = 5, from its circle's start [0.6, 0, 5]
    "type": "waypoints",
    "frame": "surface",
    "points": [[0.6, 0.0], [0.65, 0.05], [0.6, 0.1], [0.5, 0.1]],
    "speed": 0.1,
    "ramp": 0.2,
}
IN_CONTACT = {"control.supervisor": False, "initial.tip": [0.6, 0.0, 5.0], "sim.duration": 1.0}


def test_a_waypoint_scenario_loads_and_runs_on_the_surface() -> None:
    scenario = load_scenario(
        SCENARIOS / "rtr_plane.toml", {"trajectory": PLANE_WAYPOINTS, **IN_CONTACT}
    )
    assert isinstance(scenario.path, WaypointPath)
    result = simulate(scenario)
    assert result.status == "ok"
    plane = scenario.surfaces[0]
    assert max(abs(plane.distance(p)) for p in result.p) < 1e-9
    assert np.all(result.phase == CONTACT)
    assert np.abs(result.p - result.p_d).max() < 1e-3  # it follows the path
    assert np.linalg.norm(result.p_d[-1] - result.p_d[0]) > 0.05  # and the path moved
    np.testing.assert_allclose(result.f[-1], 10.0, atol=1e-3)
    assert result.meta["path"]["type"] == "waypoints"


def _load(tmp_path: Path, trajectory: str, surface: str = "") -> None:
    surface = surface or '[surface]\ntype = "cylinder"\nradius = 0.4\n'
    file = tmp_path / "x.toml"
    file.write_text(
        f'name = "x"\n[robot]\nmodel = "rtr"\n{surface}[trajectory]\n{trajectory}\n'
        "[initial]\ntip = [0.4, 0.0, 7.0]\nseed = [0.0, 6.0, 2.0]\n[sim]\nduration = 1.0\n"
    )
    load_scenario(file)


@pytest.mark.parametrize(
    ("trajectory", "message"),
    [
        (
            'type = "waypoints"\npoints = [[0.4, 0.0, 7.0]]\nspeed = 0.1',
            r"x\.toml: trajectory\.points = \[\[0\.4, 0\.0, 7\.0\]\]: .*at least 2 points",
        ),
        (
            'type = "waypoints"\nframe = "surface"\npoints = [[0, 7], [0.1, 7], [0.1, 7]]\n'
            "speed = 0.1",
            r"x\.toml: trajectory\.points = \[\[0, 7\], .*points\[1\] and points\[2\] are the same",
        ),
        (
            'type = "waypoints"\npoints = [[0.4, 0.0, 7.0], [0.0, 0.4, 7.0]]\nspeed = 0',
            r"x\.toml: trajectory\.speed = 0: .*positive",
        ),
        (
            'type = "waypoints"\npoints = [[0.4, 0.0, 7.0], [0.0, 0.0, 7.2]]\nspeed = 0.1',
            r"x\.toml: trajectory\.points = .*points\[1\] = \[0\.0, 0\.0, 7\.2\]: its closest "
            r"point on the surface is undefined.*cylinder axis",
        ),
        (
            'type = "waypoints"\npoints = [[0.4, 0.0, 7.0], [0.0, 0.4, 7.0]]\nspeed = 0.1\n'
            "surface = 1",
            r"x\.toml: trajectory\.surface = 1: must be the index of a surface, 0 to 0",
        ),
        (
            'type = "waypoints"\npoints = "A to B"\nspeed = 0.1',
            r'x\.toml: trajectory\.points = "A to B": must be an array of points',
        ),
        (
            'type = "waypoints"\npoints = [[0.4, 0.0, 7.0], [0.0, 0.4, 7.0]]\nspeed = 0.1\n'
            "u_axis = [1, 0, 0]",
            r"x\.toml: trajectory\.u_axis = \[1, 0, 0\]: u_axis is only for a plane",
        ),
    ],
)
def test_the_loader_names_file_key_and_value(tmp_path: Path, trajectory: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        _load(tmp_path, trajectory)


def test_the_loader_warns_of_a_far_projection_naming_file_and_key(tmp_path: Path) -> None:
    trajectory = 'type = "waypoints"\npoints = [[0.4, 0.0, 7.0], [0.0, 0.45, 7.05]]\nspeed = 0.1'
    with pytest.warns(RunWarning, match=r"x\.toml: trajectory\.points = .*0\.05 m from"):
        _load(tmp_path, trajectory)

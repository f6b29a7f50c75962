"""The ellipsoid surface: Φ and its derivatives, the exact distance and foot point, its chart,
a scenario on it and its drawing in the replay."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from test_replay import embedded_commands

from hybrid_force.errors import ScenarioError, SurfaceError
from hybrid_force.geometry.builtin_surfaces import Sphere
from hybrid_force.geometry.charts import chart_for
from hybrid_force.geometry.ellipsoid import Ellipsoid, EllipsoidChart
from hybrid_force.geometry.on_surface import check_on_surface
from hybrid_force.geometry.paths import Circle
from hybrid_force.geometry.raster import RasterPath
from hybrid_force.geometry.surfaces import surface_from_dict
from hybrid_force.geometry.waypoints import WaypointPath
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate
from hybrid_force.viz import replay

I3 = np.eye(3)
TILTED = Ellipsoid((0.5, 0.3, 0.2), center=(0.1, -0.2, 0.3), rpy=(0.4, -0.3, 0.7))


def _points(rng: np.random.Generator, surface: Ellipsoid, n: int, spread: float) -> np.ndarray:
    return np.asarray(surface.center) + spread * rng.normal(size=(n, 3))


@pytest.mark.parametrize("inside", [False, True])
def test_gradient_and_hessian_are_finite_differences(inside: bool) -> None:
    e = Ellipsoid((0.5, 0.3, 0.2), center=(0.1, -0.2, 0.3), rpy=(0.4, -0.3, 0.7), inside=inside)
    rng = np.random.default_rng(1)
    h = 1e-6
    for p in _points(rng, e, 10, 0.4):
        phi, g, hess = e.evaluate(p)
        assert phi == pytest.approx(e.phi(p), abs=1e-15)
        fd = np.array([(e.phi(p + h * d) - e.phi(p - h * d)) / (2 * h) for d in np.eye(3)])
        np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(e.gradient(p), g, rtol=1e-14)
        fd2 = np.array(
            [(e.gradient(p + h * d) - e.gradient(p - h * d)) / (2 * h) for d in np.eye(3)]
        )
        np.testing.assert_allclose(hess, fd2.T, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(e.hessian(p), hess.T)
        assert (phi > 0) == (e.distance(p) > 0)


def _sampled_distance(surface: Ellipsoid, p: np.ndarray) -> float:
    """The least distance from p to a dense sampling of the surface: a 301 × 601 grid of
    (latitude, longitude), then a 101 × 101 grid over the cells around its 20 best samples."""
    chart = EllipsoidChart(surface)
    phi, lam = np.linspace(-np.pi / 2, np.pi / 2, 301), np.linspace(-np.pi, np.pi, 601)
    u, v = np.repeat(phi, lam.size), np.tile(lam, phi.size)
    near = np.linalg.norm(chart.derivatives(u, v)[0] - p, axis=1)
    best = float(near.min())
    for i in np.argsort(near)[:20]:
        du, dv = (
            np.linspace(-1, 1, 101) * (phi[1] - phi[0]),
            np.linspace(-1, 1, 101) * (lam[1] - lam[0]),
        )
        uu, vv = np.repeat(u[i] + du, dv.size), np.tile(v[i] + dv, du.size)
        best = min(best, float(np.linalg.norm(chart.derivatives(uu, vv)[0] - p, axis=1).min()))
    return best


def test_distance_matches_a_dense_sampling_of_the_surface() -> None:
    rng = np.random.default_rng(2)
    for p in _points(rng, TILTED, 12, 0.35):
        sampled = _sampled_distance(TILTED, p)
        d = TILTED.distance(p)
        assert abs(d) <= sampled + 1e-12  # never farther than a sample
        assert abs(d) == pytest.approx(sampled, abs=1e-6)  # the samples are 5e-5 m apart
        assert np.sign(d) == np.sign(TILTED.phi(p))


def test_a_round_ellipsoid_is_the_sphere() -> None:
    rng = np.random.default_rng(3)
    e = Ellipsoid((0.4, 0.4, 0.4), center=(0.2, 0.0, -0.1), rpy=(0.3, 0.2, 0.1))
    s = Sphere(0.4, center=(0.2, 0.0, -0.1))
    for p in _points(rng, e, 20, 0.5):
        assert e.distance(p) == pytest.approx(s.distance(p), abs=1e-12)
        np.testing.assert_allclose(e.closest_point(p), s.closest_point(p), atol=1e-12)
        np.testing.assert_allclose(e.normal(p), s.normal(p), atol=1e-12)


def test_foot_point_is_on_the_surface_along_the_normal() -> None:
    rng = np.random.default_rng(4)
    points = np.vstack(
        [
            _points(rng, TILTED, 20, 0.4),
            np.asarray(TILTED.center) + TILTED._R[:, 2] * 0.05,  # on a principal axis, inside
            np.asarray(TILTED.center) + TILTED._R @ [0.3, 0.1, 0.0],  # on a principal plane
        ]
    )
    for p in points:
        foot = TILTED.closest_point(p)
        assert abs(TILTED.phi(foot)) < 1e-12
        assert abs(TILTED.distance(foot)) < 1e-12
        assert np.linalg.norm(foot - p) == pytest.approx(abs(TILTED.distance(p)), abs=1e-14)
        if np.linalg.norm(foot - p) > 1e-9:
            n = TILTED.normal(foot)
            np.testing.assert_allclose(np.cross(n, p - foot), 0.0, atol=1e-12)
            assert np.sign(n @ (p - foot)) == np.sign(TILTED.distance(p))


def test_inside_flips_signs() -> None:
    flipped = Ellipsoid((0.5, 0.3, 0.2), center=(0.1, -0.2, 0.3), rpy=(0.4, -0.3, 0.7), inside=True)
    rng = np.random.default_rng(5)
    for p in _points(rng, TILTED, 10, 0.4):
        assert flipped.phi(p) == -TILTED.phi(p)
        assert flipped.distance(p) == -TILTED.distance(p)
        np.testing.assert_allclose(flipped.gradient(p), -TILTED.gradient(p))
        np.testing.assert_allclose(flipped.normal(p), -TILTED.normal(p))
        np.testing.assert_allclose(flipped.closest_point(p), TILTED.closest_point(p))


def test_parameters_round_trip_and_are_checked() -> None:
    assert surface_from_dict(json.loads(json.dumps(TILTED.to_dict()))) == TILTED
    with pytest.raises(SurfaceError, match=r"semi_axes\[1\]"):
        Ellipsoid((0.5, 0.0, 0.2))
    with pytest.raises(SurfaceError, match="semi_axes"):
        Ellipsoid((0.5, 0.2))  # type: ignore[arg-type]


def test_chart_lies_on_the_surface_and_inverts() -> None:
    chart = chart_for(TILTED)
    assert isinstance(chart, EllipsoidChart)
    u = np.array([-1.2, -0.3, 0.0, 0.8])
    v = np.array([-2.5, 0.1, 1.0, 3.0])
    jet = chart.derivatives(u, v)
    for i in range(u.size):
        assert abs(TILTED.phi(jet[0, i])) < 1e-12
        assert chart.coordinates(jet[0, i]) == pytest.approx((u[i], v[i]), abs=1e-12)
        at = chart.derivatives_at(float(u[i]), float(v[i]))
        np.testing.assert_allclose(np.array(at), jet[:, i], atol=1e-15)
        h = 1e-6
        du = (chart.point(u[i] + h, v[i]) - chart.point(u[i] - h, v[i])) / (2 * h)
        np.testing.assert_allclose(jet[1, i], du, atol=1e-8)


def test_every_path_type_lies_on_it() -> None:
    spheroid = Ellipsoid((0.5, 0.5, 0.3), center=(0.0, 0.0, 1.0))
    circle = Circle((0.0, 0.0, 1.0), 0.5, (0.0, 0.0, 1.0), 0.5)
    assert check_on_surface(circle, spheroid, 0.0, 5.0).worst_distance < 1e-12
    waypoints = WaypointPath(TILTED, [[0.0, 0.0], [0.3, 0.5], [0.2, 1.0]], 0.05, frame="surface")
    off = [waypoints.position(t) + 5e-4 * TILTED.normal(waypoints.position(t)) for t in (0, 2, 4)]
    world = WaypointPath(TILTED, off, 0.05)  # world points 0.5 mm off, projected onto it
    np.testing.assert_allclose(world.projection_distances, 5e-4, rtol=1e-9)
    for path in (waypoints, world):
        assert check_on_surface(path, TILTED, 0.0, 5.0).worst_distance < 1e-9
    # a raster along the longitude of a spheroid (a = b, its passes' speed constant), turned
    # by rpy (a triaxial one, whose passes' speed varies: tests/test_paths_raster.py)
    turned = Ellipsoid((0.5, 0.5, 0.2), center=(0.1, -0.2, 0.3), rpy=(0.4, -0.3, 0.7))
    raster = RasterPath(turned, [-0.3, -0.2], [0.6, 0.4], 0.2, 0.05, direction="v")
    assert check_on_surface(raster, turned, 0.0, 5.0).worst_distance < 1e-9


def _scenario(tmp_path: Path, trajectory: str, tip: list[float]) -> Path:
    text = f"""
name = "rtr_ellipsoid"

[robot]
model = "rtr"

[surface]
type = "ellipsoid"
semi_axes = [0.5, 0.5, 0.35]
center = [0.0, 0.0, 5.0]
rpy = [0.1, 0.0, 0.3]

[trajectory]
{trajectory}

[initial]
tip = {tip}
seed = [0.0, 3.0, 2.0]

[control]
supervisor = false
f_d = 10.0

[sim]
duration = 0.2
"""
    path = tmp_path / "rtr_ellipsoid.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    "trajectory",
    [
        'type = "waypoints"\nframe = "surface"\npoints = [[-0.6, 0.2], [-0.55, 0.4], [-0.6, 0.6]]'
        "\nspeed = 0.05",
        'type = "raster"\norigin = [-0.7, 0.0]\nsize = [0.1, 0.3]\nspacing = 0.05\nspeed = 0.05'
        '\ndirection = "v"',
    ],
    ids=["waypoints", "raster"],
)
def test_a_scenario_on_it_runs_and_the_replay_draws_it(trajectory: str, tmp_path: Path) -> None:
    surface = Ellipsoid((0.5, 0.5, 0.35), center=(0.0, 0.0, 5.0), rpy=(0.1, 0.0, 0.3))
    if "waypoints" in trajectory:
        path = WaypointPath(
            surface, [[-0.6, 0.2], [-0.55, 0.4], [-0.6, 0.6]], 0.05, frame="surface"
        )
    else:
        path = RasterPath(surface, [-0.7, 0.0], [0.1, 0.3], 0.05, 0.05, direction="v")
    tip = [round(float(x), 12) for x in path.position(0.0)]
    scenario = load_scenario(_scenario(tmp_path, trajectory, tip))
    assert isinstance(scenario.surfaces[0], Ellipsoid)
    result = simulate(scenario)
    assert result.meta["status"] == "ok"
    assert np.all(np.isfinite(result.f))
    assert np.max(np.abs(result.phi)) < 1e-3
    commands = embedded_commands(replay.html(result))
    drawn = [c for c in commands if c["path"] == "/meshcat/replay/surfaces/surface_0"]
    assert drawn and drawn[0]["type"] == "set_object"


def test_a_bad_ellipsoid_table_names_the_key(tmp_path: Path) -> None:
    path = _scenario(
        tmp_path, 'type = "waypoints"\npoints = [[0, 0], [0, 1]]\nspeed = 0.1', [0, 0, 0]
    )
    text = path.read_text().replace("semi_axes = [0.5, 0.5, 0.35]", "semi_axes = [0.6, -0.5, 0.4]")
    path.write_text(text)
    with pytest.raises(ScenarioError, match=r"surface\.semi_axes = \[0\.6, -0\.5, 0\.4\]"):
        load_scenario(path)


@pytest.mark.parametrize("tiny", [1.44e-18, 1e-30, 5e-324])
def test_a_point_a_rounding_error_off_a_principal_plane_has_its_foot(tiny: float) -> None:
    """Inside, off the principal plane x2 = 0 by less than the bracket [z2 − 1, 0] resolves
    (z2 − 1 rounds to −1: a point rotated onto the plane by a matrix product): the foot is the
    plane's, on the surface, p − foot along the normal (it divided by s + 1 = 0); the same for
    the ellipse and its axis."""
    from hybrid_force.geometry.ellipsoid import ellipse_foot, ellipsoid_foot

    e, y = (0.5, 0.3, 0.2), (0.3, 0.1, tiny)
    x = np.array(ellipsoid_foot(*e, *y))
    assert np.all(np.isfinite(x))
    assert (x**2 / np.square(e)).sum() == pytest.approx(1.0, abs=1e-14)
    normal = x / np.square(e)  # ∇ of Σ x_i²/e_i² / 2
    np.testing.assert_allclose(np.cross(normal, np.array(y) - x), 0.0, atol=1e-14)
    # the in-plane closed form of the y2 = 0 case: x_i = e_i² y_i / (e_i² − e2²), i = 0, 1
    d = np.square(e[:2]) - e[2] ** 2
    np.testing.assert_allclose(x[:2], np.square(e[:2]) * y[:2] / d, atol=1e-15)
    x0, x1 = ellipse_foot(0.5, 0.3, 0.3, tiny)
    assert x0 == pytest.approx(0.5**2 * 0.3 / (0.5**2 - 0.3**2), abs=1e-15)
    assert (x0 / 0.5) ** 2 + (x1 / 0.3) ** 2 == pytest.approx(1.0, abs=1e-14)

"""A ball-end tool (``tool.radius``) on paths laid over a part and with Preston removal.

References: the exact sphere (a mesh chart at the ball's level lies at R + r), the point
tool's run on a plane (a ball of radius r touches a plane where a point tool r lower does),
and the part's own Φ (the removal cells lie on the part, not on the centre's offset).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

from hybrid_force.geometry.charts import chart_for
from hybrid_force.geometry.mesh_charts import CylindricalChartSettings, ProjectionChartSettings
from hybrid_force.geometry.mesh_surface import MeshOffset, MeshSurface
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

REPO = Path(__file__).resolve().parents[1]
RADIUS, BALL = 0.3, 0.01

pytestmark = pytest.mark.usefixtures("field_cache")  # tests/conftest.py


@pytest.fixture(scope="module")
def sphere(tmp_path_factory: pytest.TempPathFactory) -> MeshSurface:
    path = tmp_path_factory.mktemp("ball") / "sphere.stl"
    trimesh.creation.icosphere(subdivisions=5, radius=RADIUS).export(path)
    return MeshSurface.from_file(path, resolution=0.0105, cache=False)


@pytest.mark.parametrize("kind", ["projection", "cylindrical"])
def test_a_mesh_chart_under_a_ball_tool_lies_on_the_centres_surface(
    sphere: MeshSurface, kind: str
) -> None:
    """S(u, v) of the offset's chart is on Φ = r (where the dropped ball touches), at R + r from
    the sphere's centre, and on the ray of (u, v): the same coordinates as the part's chart."""
    if kind == "projection":
        settings: object = ProjectionChartSettings((0.0, 0.0, 0.6), (0.1, 0.0, -1.0), (1, 1, 0))
        points = [(0.05, 0.02), (-0.1, 0.12)]
    else:
        settings = CylindricalChartSettings((0.01, 0.0, 0.0), (0.0, 0.2, 1.0))
        points = [(0.3, 0.05), (-2.5, -0.12)]
    part = MeshSurface(
        file=sphere.file, resolution=sphere.resolution, chart=settings, part=sphere.part,
        field=sphere.field,
    )  # fmt: skip
    centre = part.offset(BALL)
    assert isinstance(centre, MeshOffset)
    chart, own = chart_for(centre), chart_for(part)
    for u, v in points:
        s = np.array(chart.derivatives_at(u, v)[0])
        assert abs(part.phi(s) - BALL) <= 1e-13
        assert abs(centre.phi(s)) <= 1e-13
        assert np.linalg.norm(s) == pytest.approx(RADIUS + BALL, abs=2e-4)
        np.testing.assert_allclose(chart.coordinates(s), own.coordinates(s), atol=1e-12)
        np.testing.assert_allclose(chart.unwrap(chart.coordinates(s), (u, v)), (u, v), atol=1e-12)


def _polish(overrides: dict[str, object]) -> object:
    base = {"sim.duration": 1.5}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = load_scenario(REPO / "scenarios" / "ur5_plane_polish.toml", base | overrides)
        return simulate(sc)


def test_a_ball_tool_on_a_plane_removes_what_the_point_tool_removes() -> None:
    """On a plane the ball of radius r centred r above the point tool's path touches where the
    point tool does: the same grid, and the same depth to the loops' tracking (~1e-6)."""
    point = _polish({})
    ball = _polish({"tool.radius": 0.005, "initial.tip": [0.4, 0.1, 0.305]})
    for r in (point, ball):
        assert r.meta["removal"]["removal_volume"] > 0.0  # type: ignore[attr-defined]
    np.testing.assert_array_equal(ball.removal_points, point.removal_points)  # type: ignore[attr-defined]
    peak = float(point.removal_depth.max())  # type: ignore[attr-defined]
    assert np.abs(ball.removal_depth - point.removal_depth).max() <= 1e-4 * peak  # type: ignore[attr-defined]
    assert np.all(np.abs(ball.removal_points[:, 2] - 0.3) <= 1e-15)  # type: ignore[attr-defined]


def test_removal_under_a_ball_tool_on_a_cylinder_is_laid_on_the_part() -> None:
    """paper_contact with a 5 mm ball: the cells lie on the cylinder R = 0.4 (not on R + r),
    and the removed volume is k_p Σ F |v_t| dt of the recorded force and the tip's velocity."""
    r = 0.005
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = load_scenario(
            REPO / "scenarios" / "paper_contact.toml",
            {
                "sim.duration": 1.0, "initial.tip": [0.4 + r, 0.0, 10.0], "tool.radius": r,
                "trajectory.radius": 0.4 + r,
                "tool.pad": {"type": "hertz", "radius": 0.02, "modulus": 5e6},
                "removal": {"k_p": 1e-13, "resolution": 3e-4},
            },
        )  # fmt: skip
        result = simulate(sc)
    cells = result.removal_points
    radial = np.linalg.norm(cells[:, :2], axis=1)
    assert np.abs(radial - 0.4).max() <= 1e-12
    dt, total = sc.sim.dt, 0.0
    for i in range(result.n_samples - 1):
        force = float(np.atleast_1d(result.f[i])[0])
        if force <= 0.0:
            continue
        v = sc.robot.jacobian(result.q[i]) @ result.v[i]
        n = np.array([*result.p[i, :2], 0.0]) / np.linalg.norm(result.p[i, :2])
        total += force * float(np.linalg.norm(v - (v @ n) * n)) * dt
    assert result.meta["removal"]["removal_volume"] == pytest.approx(1e-13 * total, rel=5e-3)


def test_a_raster_on_a_mesh_part_targets_its_chart_rectangle(tmp_path: Path) -> None:
    """The target region of a raster on a mesh part is the (u, v) rectangle, as on a built-in
    surface: with a projection chart along n = −z with e_u = x, so e_v = n × e_u = −y, the cells
    whose (x − x₀, y₀ − y) fall within it (computed here from the cells' positions alone)."""
    from hybrid_force.sim.removal_run import RemovalObserver

    trimesh.creation.icosphere(subdivisions=4, radius=0.1).export(tmp_path / "ball.ply")
    text = """
    name = "ur5_ball"
    [robot]
    model = "ur5"
    tip = "tool0"
    [surface]
    type = "mesh"
    file = "ball.ply"
    position = [0.5, 0.1, 0.2]
    [surface.chart]
    type = "projection"
    origin = [0.5, 0.1, 0.5]
    normal = [0.0, 0.0, -1.0]
    u_axis = [1.0, 0.0, 0.0]
    [trajectory]
    type = "raster"
    origin = [-0.02, -0.02]
    size = [0.04, 0.03]
    spacing = 0.006
    speed = 0.03
    [initial]
    tip = [0.48, 0.08, 0.33]
    seed = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]
    [tool]
    radius = 0.005
    [tool.pad]
    type = "hertz"
    radius = 0.02
    modulus = 5e6
    [removal]
    k_p = 1e-13
    resolution = 1e-3
    [sim]
    duration = 8.0
    """
    path = tmp_path / "ball.toml"
    path.write_text("\n".join(line.strip() for line in text.splitlines()))
    sc = load_scenario(path)
    observer = RemovalObserver(sc, 101)
    x = observer.grid.points[:, 0] - 0.5
    y = 0.1 - observer.grid.points[:, 1]
    tol = 1e-9  # cells exactly on an edge are not made by this grid
    inside = (x >= -0.02 - tol) & (x <= 0.02 + tol) & (y >= -0.02 - tol) & (y <= 0.01 + tol)
    assert observer.target_kind == "rectangle"
    assert inside.sum() > 1000 and (~inside).sum() > 100  # the grid reaches beyond it
    np.testing.assert_array_equal(observer.target, inside)
    # the cells lie on the part (Φ = 0, not on the ball centre's Φ = r)
    phi = np.array([sc.surfaces[0].phi(p) for p in observer.grid.points[::50]])
    assert np.abs(phi).max() <= 2e-4


def test_a_ball_tools_patch_takes_the_parts_curvature_at_the_foot() -> None:
    """A ball of radius r on a sphere of radius R: the Hertz patch is sized by the part's
    curvature 1/R at the contact (R_eff = 1/(1/R_pad + 1/R)), not by the curvature 1/(R + r)
    of the sphere through the ball's centre: the cells that receive depth reach a(1/R) to a
    cell, and a(1/(R + r)) lies more than a cell beyond."""
    from hybrid_force.sim.removal import HertzPad
    from hybrid_force.sim.removal_run import RemovalObserver

    R, r, cell, force = 0.5, 0.05, 5e-5, 10.0
    pad = {"type": "hertz", "radius": 1.0, "modulus": 5e6}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = load_scenario(
            REPO / "scenarios" / "rtr_sphere.toml",
            {
                "sim.duration": 0.1, "tool.radius": r, "initial.tip": [0.44, 0.0, 4.67],
                "trajectory.center": [0.0, 0.0, 4.67], "trajectory.radius": 0.44,
                "tool.pad": pad, "removal": {"k_p": 1e-13, "resolution": cell},
            },
        )  # fmt: skip
    observer = RemovalObserver(sc, 101)
    centre = np.array([0.0, 0.0, 5.0])
    u = np.array([0.8, 0.0, -0.6])  # the path's start, seen from the sphere's centre
    foot, tip = centre + R * u, centre + (R + r) * u
    observer.observe(0, tip, np.array([0.0, 0.1, 0.0]), np.array([force]))
    observer.finish(1)
    touched = observer.grid.points[observer.grid.depth > 0.0]
    reach = float(np.linalg.norm(touched - foot, axis=1).max())
    at_foot = HertzPad(1.0, 5e6).patch(force, 1.0 / R, 1.0 / R)[0]
    at_tip = HertzPad(1.0, 5e6).patch(force, 1.0 / (R + r), 1.0 / (R + r))[0]
    assert at_foot - 2 * cell <= reach <= at_foot
    assert at_tip - at_foot > 2 * cell

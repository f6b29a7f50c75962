"""The ``[tool]`` table: the desired tool direction, its refusals, and runs that point the tool.

Independent references:
- the desired axis a_d(t) against hand formulas (the sphere's centre direction, the cylinder's
  radius) and its derivatives ȧ_d, ä_d against central differences of a_d(t) on a cylinder, a
  sphere, a plane and a non-quadric function surface (whose ∇³Φ enters ä_d), with and without
  a tilt; the frame of a held roll: ω, ω̇ against central differences of F(t);
- the tilt: the angle between a_d and −n is the asked tilt, leaning towards the travel (a_d,
  n, ṗ_d coplanar, a_d·ṗ_d of the tilt's sign) or about the tilt axis (a_d ⟂ the axis);
- refusals: messages naming the key, the arm and its joint count; the singular pose found by
  the loader at the sample where the arm is stretched (elbow angle 0, found here by Newton);
- runs: the shipped ur5_sphere_normal and panda_pipe_tilt after settling, the tool angle of the
  result recomputed from q by forward kinematics and the hand formula of a_d.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hybrid_force.control.tool import ToolSettings, ToolTarget
from hybrid_force.errors import ControlError, ScenarioError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.paths import Circle, Helix, paper_helix
from hybrid_force.geometry.raster import RasterPath
from hybrid_force.geometry.waypoints import WaypointPath
from hybrid_force.model.loading import load_robot
from hybrid_force.model.robot import Robot
from hybrid_force.result import Result
from hybrid_force.scenario.loader import load_scenario

REPO_ROOT = Path(__file__).resolve().parents[1]
H = 1e-5  # [s] central-difference step


# --- settings -------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"axis": [0, 0, 0]}, "tool.axis"),
        ({"axis": [1, 0]}, "tool.axis"),
        ({"orientation": "up"}, "tool.orientation"),
        ({"orientation": "normal", "roll": "fixed"}, "tool.roll"),
        ({"orientation": "normal", "tilt": math.pi / 2}, "tool.tilt"),
        ({"orientation": "normal", "tilt": float("nan")}, "tool.tilt"),
        ({"orientation": "normal", "tilt_axis": [0, 0, 0]}, "tool.tilt_axis"),
        ({"tilt": 0.1}, "tool.tilt"),  # a tilt needs orientation = "normal"
        ({"roll": "held"}, "tool.roll"),
        ({"tilt_axis": [1, 0, 0]}, "tool.tilt_axis"),
    ],
)
def test_bad_settings_name_their_key(kwargs: dict, key: str) -> None:
    with pytest.raises(ControlError, match=key.replace(".", r"\.")) as info:
        ToolSettings(**kwargs)
    assert info.value.key == key


def test_free_orientation_keeps_the_compiled_position_clik(rtr: Robot) -> None:
    """orientation = "free" (the default) builds the paper's compiled CLIK, not the pose one."""
    from hybrid_force.control.clik import DesiredJointPath, inverse_kinematics
    from hybrid_force.control.constraint import Constraint
    from hybrid_force.control.pose_clik import PoseJointPath
    from hybrid_force.control.supervisor import ControlSettings, HybridController

    q0 = inverse_kinematics(rtr, [0.4, 0.0, 10.0], seed=[0.0, 9.0, 2.0])
    settings = ControlSettings(supervisor=False)
    for tool in (None, ToolSettings()):
        law = HybridController(
            rtr, Constraint(Cylinder(0.4)), paper_helix(), q0, settings, tool=tool
        )
        assert type(law.clik) is DesiredJointPath and not isinstance(law.clik, PoseJointPath)


def test_settings_store_unit_axes() -> None:
    tool = ToolSettings(axis=[0, 0, 2], orientation="normal", tilt_axis=[3, 4, 0])
    assert tool.axis == (0.0, 0.0, 1.0) and tool.tilt_axis == (0.6, 0.8, 0.0)
    assert ToolSettings().task_size == 3 and tool.task_size == 5
    assert ToolSettings(orientation="normal", roll="held").task_size == 6


# --- the desired direction --------------------------------------------------------------------
def _wavy() -> FunctionSurface:
    """z = 0.1 sin(3x) + 0.3 (not a quadric: ∇²Φ varies along the path)."""

    def phi(p: np.ndarray) -> float:
        return float(p[2] - 0.1 * math.sin(3 * p[0]) - 0.3)

    def grad(p: np.ndarray) -> np.ndarray:
        return np.array([-0.3 * math.cos(3 * p[0]), 0.0, 1.0])

    def hess(p: np.ndarray) -> np.ndarray:
        out = np.zeros((3, 3))
        out[0, 0] = 0.9 * math.sin(3 * p[0])
        return out

    return FunctionSurface(phi, gradient=grad, hessian=hess)


SPHERE = Sphere(0.3, [0.45, 0.1, 0.0])
SPHERE_PATH = Circle([0.45, 0.1, 0.2], math.sqrt(0.05), [0, 0, 1], omega=0.5)
PIPE = Cylinder(0.15, [0.45, 0.0, 0.4], [1.0, 0.0, 0.0], inside=True)
PIPE_PATH = Helix([0.39, 0.0, 0.4], 0.15, axis=[1.0, 0.0, 0.0], omega=0.4, rise=0.01, phase=-2.2)
PLANE = Plane([0.0, 0.0, 0.3], [0.2, 0.0, 1.0])
CASES = {
    "cylinder": (Cylinder(0.4), paper_helix(), {}),
    "pipe-tilt": (PIPE, PIPE_PATH, {"tilt": -0.25}),
    "sphere-tilt": (SPHERE, SPHERE_PATH, {"tilt": 0.3}),
    "plane-tilt-axis": (PLANE, Circle([0.4, 0.1, 0.3], 0.1, [0, 0, 1], 0.7), {
        "tilt": 0.2, "tilt_axis": [0.0, 1.0, 0.5]}),
    "function-surface": (_wavy(), Circle([0.4, 0.1, 0.3], 0.1, [0, 0.3, 1], 0.9), {"tilt": 0.1}),
    "pipe-waypoints-tilt": (PIPE, WaypointPath(PIPE, [[-2.17, -0.06], [-1.8, -0.04], [-1.4, -0.05]],
        0.05, frame="surface", ramp=0.25), {"tilt": 0.26}),
    "sphere-raster-tilt": (SPHERE, RasterPath(SPHERE, (0.6, -0.3), (0.2, 0.6), 0.1, 0.05,
        direction="v", ramp=0.25), {"tilt": -0.2}),
}  # fmt: skip


def _target(case: str, **extra: object) -> ToolTarget:
    surface, path, kwargs = CASES[case]
    return ToolTarget(ToolSettings(orientation="normal", **kwargs, **extra), surface, path)


def test_axis_is_the_inward_normal_by_hand() -> None:
    sphere = ToolTarget(ToolSettings(orientation="normal"), SPHERE, SPHERE_PATH)
    cyl = _target("cylinder")
    for t in (0.0, 0.7, 3.1):
        c = np.array(SPHERE.center)
        expected = (c - SPHERE_PATH.position(t)) / 0.3
        np.testing.assert_allclose(sphere.axis(t)[0], expected, atol=1e-14)
        p = paper_helix().position(t)
        np.testing.assert_allclose(cyl.axis(t)[0], -np.array([p[0], p[1], 0.0]) / 0.4, atol=1e-14)


@pytest.mark.parametrize("case", list(CASES))
def test_axis_derivatives_match_finite_differences(case: str) -> None:
    target = _target(case)
    for t in (0.3, 1.7, 4.4):
        a = target.axis(t)
        assert abs(np.linalg.norm(a[0]) - 1.0) < 1e-14
        fd1 = (target.axis(t + H)[0] - target.axis(t - H)[0]) / (2 * H)
        fd2 = (target.axis(t + H)[1] - target.axis(t - H)[1]) / (2 * H)
        np.testing.assert_allclose(a[1], fd1, atol=1e-8 * (1 + np.abs(a[1]).max()))
        np.testing.assert_allclose(a[2], fd2, atol=1e-7 * (1 + np.abs(a[2]).max()))


@pytest.mark.parametrize(
    "case",
    ["sphere-tilt", "pipe-tilt", "plane-tilt-axis", "pipe-waypoints-tilt", "sphere-raster-tilt"],
)
def test_frame_rates_match_finite_differences(case: str) -> None:
    target = _target(case, roll="held")
    for t in (0.2, 2.5):
        F, w, w_dot = target.frame(t)
        np.testing.assert_allclose(F.T @ F, np.eye(3), atol=1e-14)
        assert np.linalg.det(F) == pytest.approx(1.0, abs=1e-14)
        np.testing.assert_allclose(F[:, 2], target.axis(t)[0], atol=1e-15)
        Fdot = (target.frame(t + H)[0] - target.frame(t - H)[0]) / (2 * H)
        W = Fdot @ F.T  # [ω]×
        np.testing.assert_allclose(W, -W.T, atol=1e-8)
        np.testing.assert_allclose(w, [W[2, 1], W[0, 2], W[1, 0]], atol=1e-8)
        fd = (target.frame(t + H)[1] - target.frame(t - H)[1]) / (2 * H)
        np.testing.assert_allclose(w_dot, fd, atol=1e-7)


@pytest.mark.parametrize("tilt", [0.26179938779914941, -0.4, 1.2])
@pytest.mark.parametrize("case", ["sphere-tilt", "pipe-tilt", "plane-tilt-axis"])
def test_tilt_is_the_asked_angle_from_the_inward_normal(case: str, tilt: float) -> None:
    surface, path, kwargs = CASES[case]
    settings = ToolSettings(orientation="normal", **{**kwargs, "tilt": tilt})
    target = ToolTarget(settings, surface, path)
    for t in (0.0, 1.1, 5.0):
        p, v, _ = path.evaluate(t)
        n = surface.normal(p)
        a = target.axis(t)[0]
        angle = math.atan2(np.linalg.norm(np.cross(a, -n)), float(a @ -n))
        assert angle == pytest.approx(abs(tilt), abs=1e-12)
        if settings.tilt_axis is None:  # towards the travel: in the plane of n and ṗ_d
            assert abs(np.linalg.det(np.array([a, n, v]))) < 1e-12 * np.linalg.norm(v)
            assert np.sign(a @ v) == np.sign(tilt)
        else:  # about the tilt axis projected on the tangent plane
            k = np.array(settings.tilt_axis)
            assert abs(a @ (k - (k @ n) * n)) < 1e-12


@pytest.mark.parametrize("case", ["pipe-waypoints-tilt", "sphere-raster-tilt"])
def test_lean_and_roll_are_defined_where_a_surface_path_rests(case: str) -> None:
    """ṗ_d = 0 at a surface path's start and end: the lean towards the travel and the held
    roll's frame use the direction it leaves in or arrives from, the limit from inside."""
    target = _target(case, roll="held")
    path = target.path
    for rest, inside in ((0.0, 1e-5), (path.duration, path.duration - 1e-5)):
        assert np.linalg.norm(path.evaluate(rest)[1]) < 1e-9
        np.testing.assert_allclose(target.axis(rest)[0], target.axis(inside)[0], atol=1e-6)
        np.testing.assert_allclose(target.frame(rest)[0], target.frame(inside)[0], atol=1e-6)
        a, (_, v, _) = target.axis(inside)[0], path.evaluate(inside)
        n = target.normal(inside)[0][0]
        assert np.sign(a @ v) == np.sign(target.settings.tilt)  # leaning to or from the travel
        assert abs(np.linalg.det(np.array([a, n, v]))) < 1e-9 * np.linalg.norm(v)


def test_undefined_lean_direction_names_the_time() -> None:
    from hybrid_force.errors import ReachError

    plane = Plane([0.0, 0.0, 0.3], [0.0, 0.0, 1.0])
    tool = ToolSettings(orientation="normal", tilt=0.2, tilt_axis=[0.0, 0.0, 1.0])  # along n
    target = ToolTarget(tool, plane, Circle([0.4, 0.1, 0.3], 0.1, [0, 0, 1], 0.7))
    with pytest.raises(ReachError, match=r"t = 1\.5 s.*tilt_axis"):
        target.axis(1.5)


def test_the_compiled_goal_reports_an_undefined_lean_with_the_targets_error() -> None:
    """pose_goal's status code names the same ReachError as ToolTarget (what PoseJointPath
    raises from the compiled path: ToolTarget.undefined)."""
    from hybrid_force.control import _pose_kernels
    from hybrid_force.control.tool import LEAN_UNDEFINED
    from hybrid_force.errors import ReachError

    plane = Plane([0.0, 0.0, 0.3], [0.0, 0.0, 1.0])
    tool = ToolSettings(orientation="normal", tilt=0.2, tilt_axis=[0.0, 0.0, 1.0])  # along n
    path = Circle([0.4, 0.1, 0.3], 0.1, [0, 0, 1], 0.7)
    target = ToolTarget(tool, plane, path)
    sample = np.array(path.evaluate(1.5))
    desc, code, tilt_axis, _ = target.kernel_inputs()
    status = _pose_kernels.pose_goal(
        desc, sample, np.zeros(3), np.zeros((3, 3)), np.zeros(3), tilt_axis, np.zeros((3, 3)),
        code, np.eye(3), np.zeros((4, 3)), np.eye(3),
    )  # fmt: skip
    assert status == LEAN_UNDEFINED
    with pytest.raises(ReachError) as expected:
        target.axis(1.5)
    assert str(target.undefined(status, 1.5, sample[0])) == str(expected.value)


# --- refusals ---------------------------------------------------------------------------------
def _reduced(robot: Robot, keep: int) -> Robot:
    """The UR5 with its last joints locked at 0: an arm of ``keep`` joints, tip tool0."""
    model = robot.model
    lock = list(range(keep + 1, model.njoints))
    reduced = pin.buildReducedModel(model, lock, pin.neutral(model))
    return Robot(reduced, name=f"ur5-{keep}", urdf_path=robot.urdf_path, tip="tool0")


def test_arms_with_too_few_joints_are_refused(ur5: Robot) -> None:
    from hybrid_force.control.constraint import Constraint
    from hybrid_force.control.supervisor import HybridController
    from hybrid_force.sim.settings import Scenario

    four, five = _reduced(ur5, 4), _reduced(ur5, 5)
    assert (four.nv, five.nv) == (4, 5)
    normal = ToolSettings(orientation="normal")
    for arm in (four,):
        with pytest.raises(ControlError, match=r"tool\.orientation.*'ur5-4' has 4 joints") as info:
            normal.check_arm(arm)
        assert info.value.key == "tool.orientation"
        path = Circle([0.3, 0.1, 0.3], 0.05, [0, 0, 1], 0.5)
        with pytest.raises(ControlError, match=r"'ur5-4' has 4 joints"):
            HybridController(arm, Constraint([SPHERE]), path, np.zeros(4), tool=normal)
        with pytest.raises(ControlError, match=r"'ur5-4' has 4 joints"):
            Scenario(arm, [SPHERE], path, np.zeros(4), tool=normal)
    normal.check_arm(five)  # 5 rows: five joints suffice
    with pytest.raises(ControlError, match=r"tool\.roll.*6 joints.*'ur5-5' has 5 joints") as info:
        ToolSettings(orientation="normal", roll="held").check_arm(five)
    assert info.value.key == "tool.roll"


def _cli(capsys: pytest.CaptureFixture[str], path: Path, out: Path) -> tuple[int, str]:
    from hybrid_force.cli import main

    capsys.readouterr()
    status = main(["run", str(path), "--out", str(out), "--quiet"])
    return status, capsys.readouterr().err


def test_loader_refuses_orientation_on_a_three_joint_arm(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = (REPO_ROOT / "scenarios" / "paper_contact.toml").read_text()
    path = tmp_path / "rtr_tool.toml"
    path.write_text(text + '\n[tool]\norientation = "normal"\n')
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.key == "tool.orientation"
    status, err = _cli(capsys, path, tmp_path / "out")
    assert status == 2
    for message in (str(info.value), err):
        assert 'tool.orientation = "normal"' in message
        assert "'rtr' has 3 joints" in message
    assert not (tmp_path / "out").exists()
    assert load_scenario(path, {"tool.orientation": "free"}).tool.orientation == "free"


def _stretched_ur5(ur5: Robot, y: float, z: float) -> np.ndarray:
    """The UR5 stretched (elbow q3 = 0) with its tool pointing down (q4 = −π/2 − q2,
    q5 = −π/2) and its tip at height z, lateral y: (q1, q2) by Newton on the FK."""

    def q_of(x: np.ndarray) -> np.ndarray:
        return np.array([x[0], x[1], 0.0, -math.pi / 2 - x[1], -math.pi / 2, 0.0])

    def tip(x: np.ndarray) -> np.ndarray:
        return ur5.tip_position(q_of(x))[1:]

    x = np.array([0.0, -0.4])
    for _ in range(30):
        J = np.array([(tip(x + e) - tip(x - e)) / 2e-7 for e in np.eye(2) * 1e-7]).T
        x = x - np.linalg.solve(J, tip(x) - [y, z])
    q = q_of(x)
    assert np.abs(tip(x) - [y, z]).max() < 1e-12
    data = ur5.new_data()
    pin.forwardKinematics(ur5.model, data, q)
    axis = pin.updateFramePlacement(ur5.model, data, ur5.tip_id).rotation[:, 2]
    np.testing.assert_allclose(axis, [0.0, 0.0, -1.0], atol=1e-9)
    return q


def test_loader_finds_a_singular_pose_on_the_path(
    ur5: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The tool pointing down into a plane, the circle's far side where the arm is stretched
    (the edge of the reachable poses): θ = −3 + 0.5 t reaches it at t = 6 s, a sample."""
    p_far = ur5.tip_position(_stretched_ur5(ur5, 0.1, 0.3))
    r = 0.1
    start = [p_far[0] - r + r * math.cos(-3.0), 0.1 + r * math.sin(-3.0), 0.3]
    text = f"""name = "stretch"
[robot]
model = "ur5"
tip = "tool0"
[surface]
type = "plane"
point = [0.0, 0.0, 0.3]
normal = [0.0, 0.0, 1.0]
[trajectory]
type = "circle"
center = [{float(p_far[0]) - r!r}, 0.1, 0.3]
radius = {r}
normal = [0.0, 0.0, 1.0]
omega = 0.5
phase = -3.0
[initial]
tip = {[float(x) for x in start]}
seed = [0.0, -1.0, 1.0, -1.57, -1.57, 0.0]
[tool]
orientation = "normal"
[control]
supervisor = false
[sim]
duration = 12.0
"""
    path = tmp_path / "stretch.toml"
    path.write_text(text)
    assert load_scenario(path, {"sim.duration": 5.5}).tool.controlled
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    status, err = _cli(capsys, path, tmp_path / "out")
    assert status == 2
    for message in (str(info.value), err):
        assert "tool pose" in message and "singular configuration at t = 6 s" in message
        assert "tool.orientation" in message


# --- runs -------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def sphere_run() -> Result:
    return _simulate("ur5_sphere_normal")


@pytest.fixture(scope="module")
def pipe_run() -> Result:
    return _simulate("panda_pipe_tilt")


def _simulate(name: str) -> Result:
    from hybrid_force.sim.loop import simulate

    # the whole run: the path moves, passes its turns or waypoints, and stops after settling
    sc = load_scenario(REPO_ROOT / "scenarios" / f"{name}.toml")
    assert sc.sim.dt == 1e-3 and sc.sensor.ideal and sc.sim.settle_time == 5.0
    return simulate(sc)


@pytest.mark.parametrize("which", ["sphere_run", "pipe_run"])
def test_target_after_settling(which: str, request: pytest.FixtureRequest) -> None:
    result: Result = request.getfixturevalue(which)
    m = result.metrics()
    assert result.status == "ok" and np.all(result.phase == 2)
    assert m.tool_angle_max_settled is not None and m.tool_angle_max_settled <= 1e-4
    assert m.position_error_max_axis is not None and max(m.position_error_max_axis) <= 1e-5
    assert m.force_error_max_settled is not None and m.force_error_max_settled <= 1e-3
    settled = result.t >= 5.0
    assert m.tool_angle_max_settled == pytest.approx(float(result.tool_angle[settled].max()))
    assert m.tool_angle_final == result.tool_angle[-1]


def _actual_axis(robot: Robot, q: np.ndarray) -> np.ndarray:
    data = robot.new_data()
    pin.forwardKinematics(robot.model, data, q)
    return pin.updateFramePlacement(robot.model, data, robot.tip_id).rotation[:, 2]


def test_tool_angle_recomputed_from_q(sphere_run: Result, pipe_run: Result) -> None:
    ur5, panda = load_robot("ur5"), load_robot("panda")
    c = np.array([0.45, 0.1, 0.0])
    for i in (0, 1234, 7999):
        a = _actual_axis(ur5, sphere_run.q[i])
        a_d = (c - sphere_run.p_d[i]) / 0.3  # towards the sphere's centre
        angle = math.atan2(np.linalg.norm(np.cross(a, a_d)), a @ a_d)
        assert sphere_run.tool_angle[i] == pytest.approx(angle, abs=1e-12)
    # the Panda's tool leans 15° from the pipe's outward radius, towards the travel
    for i in (3000, 7999):
        a = _actual_axis(panda, pipe_run.q[i])
        p = pipe_run.p[i]
        out = np.array([0.0, p[1], p[2] - 0.4]) / np.hypot(p[1], p[2] - 0.4)
        v = np.gradient(pipe_run.p_d[i - 1 : i + 2], axis=0)[1]
        lean = math.atan2(np.linalg.norm(np.cross(a, out)), a @ out)
        assert lean == pytest.approx(math.radians(15.0), abs=1e-4)
        assert (a - (a @ out) * out) @ v > 0  # leaning towards the travel


def test_tool_angle_saved_and_absent_for_free_runs(sphere_run: Result, tmp_path: Path) -> None:
    from hybrid_force.sim.loop import simulate

    saved = Result.load(sphere_run.truncated(50).save(tmp_path / "tool.npz"))
    np.testing.assert_array_equal(saved.tool_angle, sphere_run.tool_angle[:50])
    assert saved.meta["tool"]["orientation"] == "normal"
    free = simulate(load_scenario(REPO_ROOT / "scenarios" / "paper_contact.toml",
                                  {"sim.duration": 0.02}))  # fmt: skip
    assert free.tool_angle is None and free.meta["tool"]["orientation"] == "free"
    path = free.save(tmp_path / "free.npz")
    with np.load(path) as npz:
        assert "tool_angle" not in npz.files
    summary = Result.load(path).summary()
    assert summary["tool_angle_final"] is None and summary["tool_angle_max_settled"] is None


def test_metrics_of_the_tool_angle_by_hand() -> None:
    t = np.arange(11) * 1.0
    n = t.size
    angle = np.array([9, 8, 7, 6, 5, 4.0, 0.5, 0.25, np.nan, 0.75, 0.125])
    zeros, p = np.zeros(n), np.zeros((n, 3))
    result = Result(
        t=t, q=p, v=p, q_d=p, u=p, p=p, p_d=p, f=zeros, f_d=zeros, phi=zeros, V=zeros,
        phase=np.zeros(n, dtype=np.int64), tool_angle=angle,
    )  # fmt: skip
    m = result.metrics(settle_time=5.0)
    assert m.tool_angle_max_settled == 4.0 and m.tool_angle_final == 0.125
    assert result.metrics(settle_time=6.0).tool_angle_max_settled == 0.75


def test_figure_only_for_runs_with_a_tool_angle(sphere_run: Result, tmp_path: Path) -> None:
    from hybrid_force.viz.figure_names import FIGURE_NAMES
    from hybrid_force.viz.run_figures import plot_result

    short = sphere_run.truncated(2000)
    written = plot_result(short, tmp_path / "tool")
    assert [p.stem for p in written] == [*FIGURE_NAMES, "tool_angle"]
    no_tool = Result(**{
        name: getattr(short, name)
        for name in ("t", "q", "v", "q_d", "u", "p", "p_d", "f", "f_d", "phi", "V", "phase")
    }, meta=short.meta)  # fmt: skip
    assert [p.stem for p in plot_result(no_tool, tmp_path / "free")] == list(FIGURE_NAMES)


def test_replay_draws_the_tool_axis(sphere_run: Result) -> None:
    from test_replay import animation_tracks, embedded_commands

    from hybrid_force.viz.replay_view import ReplaySettings
    from hybrid_force.viz.scene import Replay

    short = sphere_run.truncated(1001)
    replay = Replay(short, ReplaySettings(fps=5.0))
    node = replay.node_paths()["tool_axis"]
    assert node == "/meshcat/replay/tool_axis"
    commands = embedded_commands(replay.html())
    assert f"{node}/rod" in {c["path"] for c in commands if c["type"] == "set_object"}
    track = animation_tracks(commands)[node]
    ur5 = load_robot("ur5")
    for frame, quat in track[".quaternion"][1]:
        q = np.array([np.interp(frame / 5.0, short.t, short.q[:, j]) for j in range(6)])
        x, y, z, w = quat
        R = pin.Quaternion(w, x, y, z).toRotationMatrix()
        # the rod runs from the tip back along the tool axis: its +y is −a
        np.testing.assert_allclose(R[:, 1], -_actual_axis(ur5, q), atol=1e-6)
        pos = dict(track[".position"][1])[frame]
        np.testing.assert_allclose(pos, ur5.tip_position(q), atol=1e-6)
    free = Result(**{k: getattr(short, k) for k in ("t", "q", "v", "q_d", "u", "p", "p_d", "f",
                  "f_d", "phi", "V", "phase")}, meta={**short.meta, "tool": None})  # fmt: skip
    assert Replay(free, ReplaySettings(fps=5.0)).node_paths()["tool_axis"] is None

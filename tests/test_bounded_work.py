"""Issue 27, class 7: every computation before a run is bounded, and refused in seconds
(exit 2, naming the key) beyond its documented maximum."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hybrid_force.control.force_loop import max_stable_gain, spectral_radius
from hybrid_force.errors import PathError
from hybrid_force.geometry.builtin_surfaces import Sphere
from hybrid_force.geometry.raster import MAX_PASSES, RasterPath

REPO_ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = REPO_ROOT / "scenarios"


def _cli(*args: str | Path, cwd: Path = REPO_ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hybrid_force.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=120,
        check=False,
    )


def _refused(proc: subprocess.CompletedProcess[str], *named: str) -> str:
    """Exit 2, one ``error:`` line on stderr naming each of ``named``; returns the line."""
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    for word in named:
        assert word in lines[0], lines[0]
    return lines[0]


# --- the force-delay stability bound: O(1) in the delay --------------------------------------
def _bisected_bound(alpha: float, delay: int) -> float:
    """The old method, the oracle: bisection on the companion matrix's eigenvalues (∝ d³)."""
    low, high = 0.0, 2.0 / alpha
    for _ in range(60):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if spectral_radius(mid, alpha, delay) < 1.0 else (low, mid)
    return low


def test_the_closed_form_bound_agrees_with_the_eigenvalues_on_random_cases() -> None:
    rng = np.random.default_rng(27)
    for _ in range(25):
        alpha = float(rng.uniform(0.005, 0.995))
        delay = int(rng.integers(1, 40))
        assert max_stable_gain(alpha, delay) == pytest.approx(
            _bisected_bound(alpha, delay), rel=1e-9
        ), (alpha, delay)


@pytest.mark.parametrize(("alpha", "delay"), [(0.27, 1), (0.27, 3), (0.01, 2), (0.9, 7)])
def test_the_closed_form_bound_puts_a_root_on_the_unit_circle(alpha: float, delay: int) -> None:
    a = max_stable_gain(alpha, delay)
    assert (
        spectral_radius(a * (1 - 1e-7), alpha, delay)
        < 1.0
        < spectral_radius(a * (1 + 1e-7), alpha, delay)
    )


def test_the_bound_of_a_long_delay_takes_no_time() -> None:
    start = time.perf_counter()
    bounds = [max_stable_gain(0.3, d) for d in (400, 10**5, 10**12)]
    assert time.perf_counter() - start < 1.0
    # a long delay takes back all the filter gave: a* → 1 from above
    assert all(1.0 <= b < 1.01 for b in bounds) and bounds == sorted(bounds, reverse=True)


def test_a_400_period_delay_is_checked_in_seconds_by_the_cli(tmp_path: Path) -> None:
    out = tmp_path / "out"
    start = time.perf_counter()
    proc = _cli(
        "run",
        SCENARIOS / "paper_contact.toml",
        "--set",
        "sensor.force_delay=400",
        "--set",
        "sensor.force_cutoff=50",
        "--set",
        "control.beta=100",
        "--out",
        out,
    )
    assert time.perf_counter() - start < 10.0  # the eigenvalue check took 99 s
    _refused(proc, "paper_contact.toml", "control.beta", "sensor.force_delay = 400")
    assert not out.exists()


# --- raster passes -----------------------------------------------------------------------------
def test_a_raster_of_more_than_max_passes_is_refused_before_it_is_built() -> None:
    start = time.perf_counter()
    with pytest.raises(PathError, match="20001 passes") as info:
        RasterPath(Sphere(0.3), [0.6, -0.3], [0.2, 0.6], 1e-5, 0.04, direction="v")
    assert time.perf_counter() - start < 1.0
    assert info.value.key == "spacing" and info.value.value == 1e-5
    smallest = float(str(info.value).rsplit("at least ", 1)[1])  # 4 digits, rounded up
    assert 0.2 / (MAX_PASSES - 1) <= smallest < 1.001 * 0.2 / (MAX_PASSES - 1)


@pytest.mark.parametrize("size", [0.2, 0.3, 1.0 / 7.0])
def test_the_smallest_spacing_a_message_gives_is_accepted_when_copied(
    monkeypatch: pytest.MonkeyPatch, size: float
) -> None:
    from hybrid_force.geometry import raster

    monkeypatch.setattr(raster, "MAX_PASSES", 7)  # the rule at a size that builds in no time
    with pytest.raises(PathError, match="more than the 7 a raster may have") as info:
        RasterPath(Sphere(0.3), [0.6, -0.3], [size, 0.6], 1e-3, 0.04, direction="v")
    suggested = float(str(info.value).rsplit(" ", 1)[-1])
    assert suggested == pytest.approx(size / 6, rel=1e-3)
    path = RasterPath(Sphere(0.3), [0.6, -0.3], [size, 0.6], suggested, 0.04, direction="v")
    assert path.passes == 7


def test_a_tiny_raster_spacing_is_refused_by_the_cli_naming_the_key(tmp_path: Path) -> None:
    out = tmp_path / "out"
    start = time.perf_counter()
    proc = _cli(
        "run",
        SCENARIOS / "ur5_sphere_normal.toml",
        "--set",
        "trajectory.spacing=1e-5",
        "--out",
        out,
    )
    assert time.perf_counter() - start < 10.0
    _refused(proc, "ur5_sphere_normal.toml", "trajectory.spacing", "1e-05", str(MAX_PASSES))
    assert not out.exists()


# --- model size: counted before any parser sees the file ---------------------------------------
_INERTIAL = (
    '<inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" '
    'izz="0.1"/></inertial>'
)


def _chain_urdf(path: Path, joints: int, fixed: int = 0) -> Path:
    """A serial chain of ``joints`` revolute joints, each link 0.1 m long, then ``fixed``
    fixed joints (a sensor frame each)."""
    parts = ['<robot name="chain">', f'<link name="l0">{_INERTIAL}</link>']
    for i in range(1, joints + fixed + 1):
        parts.append(f'<link name="l{i}">{_INERTIAL}</link>')
        kind = "revolute" if i <= joints else "fixed"
        parts.append(
            f'<joint name="j{i}" type="{kind}"><parent link="l{i - 1}"/><child link="l{i}"/>'
            '<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>'
            '<limit lower="-3" upper="3" effort="10" velocity="1"/></joint>'
        )
    parts.append("</robot>")
    path.write_text("\n".join(parts))
    return path


@pytest.mark.parametrize("joints", [1200, 5000])
def test_a_long_chain_is_refused_by_robots_check_in_seconds(tmp_path: Path, joints: int) -> None:
    from hybrid_force.model.urdf_text import MAX_JOINTS

    urdf = _chain_urdf(tmp_path / f"chain{joints}.urdf", joints)
    start = time.perf_counter()
    proc = _cli("robots", "--check", urdf)
    assert time.perf_counter() - start < 10.0
    assert proc.returncode > 0  # not killed by a signal (negative): 5,000 crashed Pinocchio
    _refused(proc, str(urdf), f"MAX_JOINTS = {MAX_JOINTS}")


def test_fixed_joints_count_against_the_element_bound_not_the_joint_bound(
    tmp_path: Path,
) -> None:
    from hybrid_force import load_robot
    from hybrid_force.model.urdf_text import MAX_ELEMENTS

    # 3 moving joints and 300 fixed ones (frames): loads, with 3 joints
    robot = load_robot(_chain_urdf(tmp_path / "frames.urdf", 3, fixed=300), tip="l3")
    assert robot.nv == 3
    # 5,000 fixed joints: refused before Pinocchio's recursive parser, not a crash
    urdf = _chain_urdf(tmp_path / "many.urdf", 3, fixed=5000)
    proc = _cli("robots", "--check", urdf)
    assert proc.returncode > 0
    _refused(proc, str(urdf), f"MAX_ELEMENTS = {MAX_ELEMENTS}")


def test_nested_mjcf_replicates_are_refused_before_they_are_copied(tmp_path: Path) -> None:
    from hybrid_force import load_robot
    from hybrid_force.errors import RobotError

    body = (
        '<body name="b" pos="0.1 0 0"><joint name="j" type="hinge" axis="0 0 1"/>'
        '<inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/></body>'
    )
    mjcf = tmp_path / "replicated.xml"
    mjcf.write_text(
        '<mujoco model="m"><worldbody><replicate count="1000" offset="0 0.1 0">'
        f'<replicate count="1000" offset="0.1 0 0">{body}</replicate></replicate>'
        "</worldbody></mujoco>"
    )
    start = time.perf_counter()
    with pytest.raises(RobotError, match=r"replicate count='1000'.*MAX_ELEMENTS"):
        load_robot(mjcf)
    assert time.perf_counter() - start < 10.0


def test_a_chain_at_the_maximum_loads(tmp_path: Path) -> None:
    from hybrid_force import load_robot
    from hybrid_force.model.urdf_text import MAX_JOINTS

    robot = load_robot(_chain_urdf(tmp_path / "chain.urdf", MAX_JOINTS))
    assert robot.nv == MAX_JOINTS


def test_a_deep_mjcf_chain_is_refused_before_pinocchio_parses_it(tmp_path: Path) -> None:
    from hybrid_force import load_robot
    from hybrid_force.errors import RobotError

    bodies = 400
    inner = "".join(
        f'<body name="b{i}" pos="0 0 0.1"><joint name="j{i}" type="hinge" axis="0 1 0"/>'
        '<inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>'
        for i in range(bodies)
    )
    mjcf = tmp_path / "deep.xml"
    mjcf.write_text(
        f'<mujoco model="m"><worldbody>{inner}{"</body>" * bodies}</worldbody></mujoco>'
    )
    with pytest.raises(RobotError, match="more than 100 moving joints") as info:
        load_robot(mjcf)
    assert str(mjcf) in str(info.value)
    # nested deeper than any model, without a joint: the depth is the limit
    empty = tmp_path / "nested.xml"
    empty.write_text(
        f"<mujoco><worldbody>{'<frame>' * 5000}{'</frame>' * 5000}</worldbody></mujoco>"
    )
    with pytest.raises(RobotError, match="nest more than 256 deep"):
        load_robot(empty)


def test_a_model_file_beyond_the_byte_limit_is_refused_unread(tmp_path: Path) -> None:
    from hybrid_force import load_robot
    from hybrid_force.errors import RobotError
    from hybrid_force.model.urdf_text import MAX_MODEL_BYTES

    big = tmp_path / "big.urdf"
    with big.open("wb") as fh:  # sparse: nothing is written but the size
        fh.truncate(MAX_MODEL_BYTES + 1)
    with pytest.raises(RobotError, match="MAX_MODEL_BYTES") as info:
        load_robot(big)
    assert str(big) in str(info.value)


# --- waypoints ---------------------------------------------------------------------------------
def test_more_than_max_waypoints_are_refused_before_the_spline_is_built() -> None:
    from hybrid_force.geometry.builtin_surfaces import Cylinder
    from hybrid_force.geometry.waypoints import MAX_WAYPOINTS, WaypointPath

    pipe = Cylinder(0.15, [0.45, 0.0, 0.4], [1.0, 0.0, 0.0], inside=True)
    points = np.c_[np.linspace(-2.17, -1.0, 40 * MAX_WAYPOINTS), np.full(40 * MAX_WAYPOINTS, -0.05)]
    start = time.perf_counter()
    with pytest.raises(PathError, match=f"more than the {MAX_WAYPOINTS}") as info:
        WaypointPath(pipe, points, 0.02, frame="surface")
    assert time.perf_counter() - start < 1.0  # building them took about 70 s
    assert info.value.key == "points"


def test_a_force_delay_beyond_its_maximum_is_refused_naming_the_key() -> None:
    from hybrid_force.errors import ScenarioError
    from hybrid_force.scenario.loader import load_scenario
    from hybrid_force.sim.sensors import MAX_FORCE_DELAY

    with pytest.raises(ScenarioError, match=r"sensor\.force_delay = 1000000000") as info:
        load_scenario(SCENARIOS / "paper_contact.toml", {"sensor.force_delay": 10**9})
    assert str(MAX_FORCE_DELAY) in str(info.value)

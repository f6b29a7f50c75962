"""Models the toolkit cannot simulate are refused with a RobotError naming file and cause.

Every model here is a small URDF written inline, so the expected verdict follows from the text:
no moving joint (nv = 0), a floating or planar joint, a mimic joint on the chain to the tip,
a moving joint that moves nothing with inertia (M(q0) singular). The command line turns each
refusal into exit status 2 and one ``error:`` line naming ``robot.model`` (checked in-process
and, for nv = 0, in a subprocess: a status, not a signal). Also: a mimic finger off the tip's
chain is locked where its master puts it, and a continuous joint is one unbounded angle.
"""

from __future__ import annotations

import math
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hybrid_force.cli import main as cli_main
from hybrid_force.errors import BadInputError, RobotError
from hybrid_force.model.loading import load_robot
from hybrid_force.model.urdf_check import check_urdf


# --- tiny URDF builder -------------------------------------------------------------------------
def _link(name: str, mass: float | None = None, inertia: float | None = None) -> str:
    """A link; with ``mass``, a body at its origin with diag(inertia) [kg m²] (default mass/10)."""
    if mass is None:
        return f'<link name="{name}"/>'
    i = mass / 10 if inertia is None else inertia
    return (
        f'<link name="{name}"><inertial><origin xyz="0.25 0 0"/><mass value="{mass!r}"/>'
        f'<inertia ixx="{i!r}" ixy="0" ixz="0" iyy="{i!r}" iyz="0" izz="{i!r}"/>'
        "</inertial></link>"
    )


def _joint(
    name: str,
    jtype: str,
    parent: str,
    child: str,
    *,
    xyz: str = "0 0 0",
    axis: str = "0 0 1",
    limit: str | None = '<limit lower="-2" upper="2" effort="10" velocity="3"/>',
    extra: str = "",
) -> str:
    body = f'<parent link="{parent}"/><child link="{child}"/><origin xyz="{xyz}"/>'
    if jtype != "fixed":
        body += f'<axis xyz="{axis}"/>'
    if limit is not None and jtype in ("revolute", "prismatic", "continuous"):
        body += limit
    return f'<joint name="{name}" type="{jtype}">{body}{extra}</joint>'


def _robot(*parts: str) -> str:
    return '<?xml version="1.0"?>\n<robot name="t">' + "".join(parts) + "</robot>\n"


def _two_link_arm(b_mass: float | None = 1.0, b_inertia: float | None = None) -> str:
    """world -j1 (revolute z)-> a -j2 (revolute y, 0.5 m out)-> b -tip_joint-> tip."""
    return _robot(
        _link("world"),
        _link("a", 2.0),
        _link("b", b_mass, b_inertia),
        _link("tip"),
        _joint("j1", "revolute", "world", "a"),
        _joint("j2", "revolute", "a", "b", xyz="0.5 0 0", axis="0 1 0"),
        _joint("tip_joint", "fixed", "b", "tip", xyz="0.5 0 0"),
    )


def _write(tmp_path: Path, text: str, name: str = "arm.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _refusal(path: Path, tip: str | None = None) -> str:
    """The message of the RobotError that load_robot raises for ``path``."""
    with pytest.raises(RobotError) as info:
        load_robot(path, tip=tip)
    message = str(info.value)
    assert str(path) in message  # every message names the file
    return message


def test_the_builder_makes_a_loadable_arm(tmp_path: Path) -> None:
    """The reference: the healthy two-link arm loads (so each refusal below is its cause's)."""
    robot = load_robot(_write(tmp_path, _two_link_arm()))
    assert (robot.nq, robot.nv, robot.tip) == (2, 2, "tip")
    np.testing.assert_allclose(robot.tip_position(np.zeros(2)), [1.0, 0.0, 0.0], atol=1e-15)


# --- nv = 0 ------------------------------------------------------------------------------------
NO_MOVING_JOINT = {
    "all-fixed": _robot(
        _link("world"),
        _link("a", 1.0),
        _link("b", 1.0),
        _joint("f1", "fixed", "world", "a"),
        _joint("f2", "fixed", "a", "b", xyz="0.5 0 0"),
    ),
    "one-fixed": _robot(_link("world"), _link("a", 1.0), _joint("f1", "fixed", "world", "a")),
    "no-joint": _robot(_link("lonely", 1.0)),
}


@pytest.mark.parametrize("case", NO_MOVING_JOINT)
def test_no_moving_joint_is_refused(tmp_path: Path, case: str) -> None:
    message = _refusal(_write(tmp_path, NO_MOVING_JOINT[case]))
    assert "no moving joint" in message
    assert "nv = 0" in message
    expected = {"all-fixed": "all 2 joints are fixed", "one-fixed": "its only joint is fixed"}
    assert expected.get(case, "it has no joint") in message


def test_no_moving_joint_exits_2_in_a_subprocess(tmp_path: Path, repo_root: Path) -> None:
    """The whole command: a status 2 and one error line, never a signal (segfault)."""
    _write(tmp_path, NO_MOVING_JOINT["all-fixed"], "fixed.urdf")
    scenario = _scenario(tmp_path, repo_root, "fixed.urdf")
    out = tmp_path / "out"
    command = ["run", str(scenario), "--out", str(out), "--quiet"]
    proc = subprocess.run(
        [sys.executable, "-m", "hybrid_force.cli", *command],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), proc.stderr
    assert 'robot.model = "fixed.urdf"' in lines[0] and "no moving joint" in lines[0]
    assert not out.exists() or not any(out.iterdir())


# --- the command line, in-process --------------------------------------------------------------
def _scenario(tmp_path: Path, repo_root: Path, model: str) -> Path:
    """scenarios/paper_contact.toml with [robot] model = ``model``, written in tmp_path."""
    text = (repo_root / "scenarios" / "paper_contact.toml").read_text()
    assert text.count('model = "rtr"') == 1
    path = tmp_path / "scenario.toml"
    path.write_text(text.replace('model = "rtr"', f'model = "{model}"'))
    return path


@pytest.mark.parametrize(
    ("text", "cause"),
    [
        (NO_MOVING_JOINT["all-fixed"], "no moving joint"),
        (_two_link_arm(b_mass=None), "mass matrix M(q0) at the neutral configuration is singular"),
    ],
    ids=["nv-0", "singular-mass"],
)
def test_cli_refuses_with_one_error_line(
    tmp_path: Path, repo_root: Path, capsys: pytest.CaptureFixture[str], text: str, cause: str
) -> None:
    _write(tmp_path, text, "bad.urdf")
    scenario = _scenario(tmp_path, repo_root, "bad.urdf")
    out = tmp_path / "out"
    code = cli_main(["run", str(scenario), "--out", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert code == 2
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("error:")
    assert 'robot.model = "bad.urdf"' in lines[0]
    assert str(scenario) in lines[0] and cause in lines[0]
    assert not out.exists() or not any(out.iterdir())


# --- floating and planar joints ----------------------------------------------------------------
@pytest.mark.parametrize("jtype", ["floating", "planar"])
def test_floating_or_planar_root_is_refused(tmp_path: Path, jtype: str) -> None:
    text = _robot(
        _link("world"),
        _link("base", 3.0),
        _link("arm", 1.0),
        _joint("root", jtype, "world", "base"),
        _joint("j1", "revolute", "base", "arm"),
    )
    message = _refusal(_write(tmp_path, text))
    assert f"joint 'root' (parent link 'world', child link 'base') is a {jtype} joint" in message
    assert "fixed-base arms only" in message
    # independent: Pinocchio itself would have built a free-flyer / planar joint there
    kind = {"floating": "JointModelFreeFlyer", "planar": "JointModelPlanar"}[jtype]
    assert pin.buildModelFromXML(text).joints[1].shortname() == kind


def test_floating_joint_deeper_in_the_tree_is_refused(tmp_path: Path) -> None:
    text = _two_link_arm().replace("</robot>", "") + (
        _link("payload", 0.5) + _joint("loose", "floating", "tip", "payload") + "</robot>"
    )
    message = _refusal(_write(tmp_path, text))
    assert "joint 'loose'" in message and "floating joint" in message


# --- mimic joints ------------------------------------------------------------------------------
def test_mimic_joint_on_the_chain_is_refused(tmp_path: Path) -> None:
    text = _two_link_arm().replace(
        '<joint name="j2" type="revolute">',
        '<joint name="j2" type="revolute"><mimic joint="j1" multiplier="2" offset="0"/>',
    )
    message = _refusal(_write(tmp_path, text))
    assert "mimic joints on the arm's chain are not supported" in message
    assert "Pinocchio 4's forward and impulse dynamics refuse them" in message
    assert "'j2' (mimics 'j1')" in message and "tip frame 'tip'" in message


def _gripper(tmp_path: Path) -> Path:
    """The two-link arm with two prismatic fingers on link a; finger2 mimics finger1.

    finger2 slides along −y from (0.1, −0.02, 0): offset 0.01 m, multiplier −1, so with
    finger1 at its neutral 0 m the mimic rule puts finger2 at 0.01 m, i.e. its link at
    (0.1, −0.03, 0) in the world at q = 0.
    """
    text = _two_link_arm().replace("</robot>", "") + (
        _link("finger1", 0.1)
        + _link("finger2", 0.1)
        + _joint("f1", "prismatic", "a", "finger1", xyz="0.1 0.02 0", axis="0 1 0")
        + _joint(
            "f2",
            "prismatic",
            "a",
            "finger2",
            xyz="0.1 -0.02 0",
            axis="0 -1 0",
            extra='<mimic joint="f1" multiplier="-1" offset="0.01"/>',
        )
        + "</robot>"
    )
    return _write(tmp_path, text, "gripper.urdf")


def test_mimic_finger_off_the_chain_is_locked_where_its_master_puts_it(tmp_path: Path) -> None:
    path = _gripper(tmp_path)
    # lock_off_chain=False: only the mimic joint is locked (by default f1 would be too)
    robot = load_robot(path, tip="tip", lock_off_chain=False)
    assert sorted(robot.model.names) == ["f1", "j1", "j2", "universe"]  # f2 locked, f1 kept
    assert robot.nq == robot.nv == 3
    data = robot.new_data()
    pin.framesForwardKinematics(robot.model, data, robot.neutral())
    finger2 = data.oMf[robot.model.getFrameId("finger2")].translation
    np.testing.assert_allclose(finger2, [0.1, -0.03, 0.0], atol=1e-15)
    # locking keeps every link's mass: 2 + 1 + 0.1 + 0.1 kg
    assert sum(i.mass for i in robot.model.inertias) == pytest.approx(3.2, abs=1e-12)
    # and the tip kinematics are the two-link arm's
    np.testing.assert_allclose(robot.tip_position(np.zeros(3)), [1.0, 0.0, 0.0], atol=1e-15)


def test_mimic_finger_as_the_tip_is_on_the_chain(tmp_path: Path) -> None:
    """The same file with the tip on finger2: its mimic joint is on the chain, refused."""
    path = _gripper(tmp_path)
    assert load_robot(path).tip == "tip"  # the default (last body frame) is off the fingers
    message = _refusal(path, tip="finger2")
    assert "'f2' (mimics 'f1')" in message and "tip frame 'finger2'" in message


def test_mimic_naming_no_moving_joint_is_malformed(tmp_path: Path) -> None:
    text = _two_link_arm().replace(
        '<joint name="j2" type="revolute">',
        '<joint name="j2" type="revolute"><mimic joint="tip_joint"/>',
    )
    with pytest.raises(RobotError, match=r"'j2' has <mimic joint='tip_joint'>, which names no"):
        check_urdf(_write(tmp_path, text))


# --- a singular mass matrix at q0 ---------------------------------------------------------------
def test_massless_moving_link_is_refused_naming_its_joint(tmp_path: Path) -> None:
    """Link b has no <inertial>: j2 moves nothing (M[1, 1] = 0 by hand), j1 moves link a."""
    message = _refusal(_write(tmp_path, _two_link_arm(b_mass=None)))
    assert "M(q0) at the neutral configuration is singular" in message
    assert "joint(s) 'j2' carry no inertia" in message  # j2 alone: j1 moves link a


def test_point_mass_on_the_joint_axis_is_refused(tmp_path: Path) -> None:
    """b is a point mass on j2's axis (inertia 0, centre at the joint): j2 moves no inertia.

    Its subtree has a mass, so the message names the joint through M's near-null direction.
    """
    text = _two_link_arm(b_mass=1.0, b_inertia=0.0).replace(
        '<origin xyz="0.25 0 0"/><mass value="1.0"/>', '<origin xyz="0 0 0"/><mass value="1.0"/>'
    )
    message = _refusal(_write(tmp_path, text))
    assert "is singular" in message
    assert "moving joint(s) 'j2' together move nothing with inertia" in message


def test_mass_check_is_relative_to_the_arm_scale(tmp_path: Path) -> None:
    """A healthy arm 1e6 times lighter loads; a link 1e-13 times lighter than the rest does not."""
    light = (
        _two_link_arm()
        .replace('value="2.0"', 'value="2e-06"')
        .replace('value="1.0"', 'value="1e-06"')
    )
    light = light.replace('"0.2"', '"2e-07"').replace('"0.1"', '"1e-07"')
    robot = load_robot(_write(tmp_path, light, "light.urdf"))
    eig = np.linalg.eigvalsh(robot.mass_matrix(robot.neutral()))
    assert 0 < eig[0] < 1e-6  # small in absolute terms, yet accepted
    almost = _two_link_arm(b_mass=1e-13, b_inertia=1e-14)
    message = _refusal(_write(tmp_path, almost, "almost.urdf"))
    assert "is singular" in message and "'j2'" in message


def test_refusals_are_bad_input() -> None:
    assert issubclass(RobotError, BadInputError)


# --- continuous joints -------------------------------------------------------------------------
def test_continuous_joint_is_one_unbounded_angle(tmp_path: Path) -> None:
    text = _two_link_arm().replace(
        _joint("j1", "revolute", "world", "a"),
        _joint("j1", "continuous", "world", "a", limit='<limit effort="7" velocity="4"/>'),
    )
    text = text.replace(
        _joint("j2", "revolute", "a", "b", xyz="0.5 0 0", axis="0 1 0"),
        _joint("j2", "continuous", "a", "b", xyz="0.5 0 0", axis="0 1 0", limit=None),
    )
    robot = load_robot(_write(tmp_path, text))
    assert [j.shortname() for j in robot.model.joints][1:] == ["JointModelRZ", "JointModelRY"]
    assert (robot.nq, robot.nv) == (2, 2) and robot.euclidean
    lower, upper = robot.position_limits
    np.testing.assert_array_equal(lower, [-math.inf, -math.inf])
    np.testing.assert_array_equal(upper, [math.inf, math.inf])
    np.testing.assert_array_equal(robot.effort_limits, [7.0, math.inf])  # j2: no <limit>
    np.testing.assert_array_equal(robot.model.velocityLimit, [4.0, math.inf])
    # the angle is the coordinate: 10 rad about z is 10 − 2π·1 rad, by hand (l = 1 m)
    q = np.array([10.0, 0.0])
    np.testing.assert_allclose(
        robot.tip_position(q), [math.cos(10.0), math.sin(10.0), 0.0], atol=1e-14
    )


def test_rtr_base_passes_10_rad_in_a_run_without_warnings(repo_root: Path) -> None:
    """The paper's 6.3 run at 4 rad/s for 3 s: q1 reaches 12 rad, the tip still on the helix."""
    from hybrid_force import load_scenario, simulate

    scenario = load_scenario(
        repo_root / "scenarios" / "paper_contact.toml",
        {"trajectory.omega": 4.0, "sim.duration": 3.0},
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = simulate(scenario)
    assert result.status == "ok"
    q1 = result.q[:, 0]
    assert q1.max() > 10.0
    assert np.all(np.diff(q1) > 0)  # one unwrapped angle, turning steadily
    # the tip at the end, by hand from q (the RTR's p(q), l2 = 0.9 m, l3 = 1 m) ...
    q = result.q[-1]
    r = math.cos(q[2]) + 0.9
    by_hand = [math.cos(q[0]) * r, math.sin(q[0]) * r, math.sin(q[2]) + q[1]]
    np.testing.assert_allclose(result.p[-1], by_hand, atol=1e-12)
    # ... is on the helix of eq. 25 at 4 rad/s: (0.4 cos 4t, 0.4 sin 4t, 10 + 0.1 t)
    t = result.t[-1]
    helix = [0.4 * math.cos(4 * t), 0.4 * math.sin(4 * t), 10.0 + 0.1 * t]
    np.testing.assert_allclose(result.p[-1], helix, atol=1e-3)

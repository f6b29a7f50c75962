"""``initial.q`` and ``initial.seed`` for an arm whose joints off the tip's chain are locked.

The SO-101 of example-robot-data (5 arm joints and a gripper jaw): a scenario may list the 5
moving joints or all 6 of the file; with 6, the gripper is held at its value there. The
independent reference: Pinocchio's forward kinematics of the full (unlocked) model at the
6 values, for the jaw link (merged into the wrist by the locking) and for the tip.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hybrid_force import load_robot
from hybrid_force.errors import RobotError, ScenarioError
from hybrid_force.scenario.loader import load_scenario

SO101 = Path(pin.__file__).parents[4] / "share/example-robot-data/robots/so_arm_description"
SO101_URDF = SO101 / "urdf" / "so101.urdf"
JAW = "moving_jaw_so101_v1_link"
POINT = np.array([0.03, 0.0, 0.0])  # off the jaw's axis: it moves with the jaw's angle
ARM_Q = [-5.6e-05, 0.047547, -0.339091, 1.495502, 0.000477]  # tip 2 cm above z = 0.1 m

pytestmark = pytest.mark.skipif(not SO101_URDF.is_file(), reason="no so101.urdf")

SCENARIO = """
name = "so101_plane"
[robot]
model = "{model}"
[surface]
type = "plane"
point = [0.0, 0.0, 0.1]
normal = [0.0, 0.0, 1.0]
[trajectory]
type = "circle"
center = [0.25, 0.0, 0.1]
radius = 0.03
normal = [0.0, 0.0, 1.0]
omega = 0.3
phase = 0.0
[initial]
{initial}
[control]
supervisor = true
f_d = 1.0
[sim]
duration = 0.2
"""


def _scenario(tmp_path: Path, initial: str) -> Path:
    path = tmp_path / "so101.toml"
    path.write_text(SCENARIO.format(model=SO101_URDF, initial=initial))
    return path


def _full_model(q: list[float], frame: str) -> pin.SE3:
    """The frame's placement by the full (unlocked) model's forward kinematics."""
    model = pin.buildModelFromUrdf(str(SO101_URDF))
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.array(q))
    return data.oMf[model.getFrameId(frame)].copy()


@pytest.mark.parametrize("key", ["q", "seed"])
def test_every_joint_of_the_file_holds_the_locked_one_where_it_says(
    tmp_path: Path, key: str
) -> None:
    full = [*ARM_Q, 0.9]  # the gripper jaw opened to 0.9 rad
    if key == "q":
        initial = f"q = {full}"
    else:
        tip = _full_model(full, "gripper_frame_link").translation
        initial = f"tip = {tip.tolist()}\nseed = {full}"
    sc = load_scenario(_scenario(tmp_path, initial))
    robot = sc.robot
    assert robot.nq == 5 and robot.locked_joints == {"gripper": 0.9}
    assert robot.file_joints[-1] == "gripper" and len(robot.file_joints) == 6
    assert robot.reference["locked_positions"] == {"gripper": 0.9}
    if key == "q":
        np.testing.assert_array_equal(sc.q0, ARM_Q)
    data = robot.new_data()
    pin.framesForwardKinematics(robot.model, data, sc.q0)
    jaw = data.oMf[robot.model.getFrameId(JAW)].act(POINT)
    np.testing.assert_allclose(jaw, _full_model([*sc.q0, 0.9], JAW).act(POINT), atol=1e-12)
    closed = _full_model([*sc.q0, 0.0], JAW).act(POINT)
    assert np.linalg.norm(jaw - closed) > 1e-3  # the jaw's value moved it
    tip = _full_model([*sc.q0, 0.9], "gripper_frame_link").translation
    np.testing.assert_allclose(robot.tip_position(sc.q0), tip, atol=1e-12)
    again = load_robot(**robot.reference)  # what a result stores re-loads the same arm
    assert again.locked_joints == {"gripper": 0.9}


def test_the_moving_joints_only_keep_the_default_lock(tmp_path: Path) -> None:
    sc = load_scenario(_scenario(tmp_path, f"q = {ARM_Q}"))
    assert sc.robot.locked_joints == {"gripper": 0.0} and "locked_positions" not in (
        sc.robot.reference
    )


def test_a_wrong_count_names_the_locked_joints_and_lock_off_chain(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError) as info:
        load_scenario(_scenario(tmp_path, f"q = {ARM_Q[:4]}"))
    message = str(info.value)
    assert "initial.q" in message and "must have 5 numbers (its moving joints) or 6" in message
    assert "got 4" in message and "locked joints: gripper (held at 0)" in message
    assert "robot.lock_off_chain" in message


def test_a_locked_value_outside_the_joints_range_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match=r"initial\.q.*'gripper'.*position 3 is outside"):
        load_scenario(_scenario(tmp_path, f"q = {[*ARM_Q, 3.0]}"))


def test_locked_positions_must_name_locked_joints() -> None:
    with pytest.raises(RobotError, match=r"names 'elbow_flex', which this load .* does not lock"):
        load_robot(SO101_URDF, locked_positions={"elbow_flex": 0.1})
    with pytest.raises(RobotError, match=r"finite numbers; got 'gripper': nan"):
        load_robot(SO101_URDF, locked_positions={"gripper": float("nan")})


def _link(name: str, mass: float = 1.0) -> str:
    return (
        f'<link name="{name}"><inertial><origin xyz="0.1 0 0"/><mass value="{mass}"/>'
        '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
    )


def _joint(name: str, parent: str, child: str, damping: float, kind: str = "revolute") -> str:
    limit = '<limit lower="-2" upper="2" effort="5" velocity="3"/>' if kind != "continuous" else ""
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0.2 0 0"/><axis xyz="0 1 0"/>{limit}'
        f'<dynamics damping="{damping}" friction="{damping / 10}"/></joint>'
    )


def test_urdf_damping_and_friction_survive_locking_in_order(tmp_path: Path) -> None:
    """<dynamics damping friction> of each joint is model.damping / model.friction by name,
    the gripper branch locked between the arm's joints, a continuous joint included."""
    damping = {"j1": 0.1, "g1": 9.0, "j2": 0.2, "j3": 0.3}
    urdf = "".join(
        [
            '<robot name="branch">',
            _link("base"), _link("l1"), _link("finger", 0.1), _link("l2"), _link("l3"),
            _joint("j1", "base", "l1", damping["j1"]),
            _joint("g1", "l1", "finger", damping["g1"]),
            _joint("j2", "l1", "l2", damping["j2"], "continuous"),
            _joint("j3", "l2", "l3", damping["j3"]),
            "</robot>",
        ]
    )  # fmt: skip
    path = tmp_path / "branch.urdf"
    path.write_text(urdf)
    full = load_robot(path, tip="l3", lock_off_chain=False)
    robot = load_robot(path, tip="l3")
    assert list(full.model.names[1:]) == list(full.file_joints) == ["j1", "g1", "j2", "j3"]
    assert robot.locked_joints == {"g1": 0.0} and robot.file_joints == full.file_joints
    for arm in (full, robot):
        names = list(arm.model.names[1:])
        np.testing.assert_array_equal(arm.model.damping, [damping[n] for n in names])
        np.testing.assert_allclose(arm.model.friction, [damping[n] / 10 for n in names])


def test_the_controllers_own_model_holds_the_locked_joint_alike(tmp_path: Path) -> None:
    text = _scenario(tmp_path, f"q = {[*ARM_Q, 0.9]}").read_text()
    path = tmp_path / "own.toml"
    path.write_text(text.replace("[control]\n", f'[control]\nmodel = "{SO101_URDF}"\n'))
    sc = load_scenario(path)
    assert sc.controller_model is not None
    assert sc.controller_model.locked_joints == sc.robot.locked_joints == {"gripper": 0.9}

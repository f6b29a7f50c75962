"""The pose CLIK (eq. 27 extended to the tool axis, hybrid_force.control.pose_clik).

Independent references:
- the tip position and tool axis of q_d(t) measured with the robot's own forward kinematics
  against p_d(t) and a hand formula of the desired axis (the sphere's centre direction; the
  pipe's outward radius turned by the tilt towards the travel), all along 2 s of advance(1e-3);
- q̇_d against central differences of the integrated q_d(t), q̈_d against central differences
  of q̇_d(t) (the null-space part included), on the UR5 and the Panda, roll free and held;
- roll held: the tip frame's angle about the axis, measured from the direction of travel across
  the axis, stays what it was at t = 0 (FK);
- the pose inverse kinematics: its residual measured by FK.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from test_clik import DT, history

from hybrid_force.control.clik import inverse_kinematics
from hybrid_force.control.pose_clik import PoseJointPath, pose_inverse_kinematics
from hybrid_force.control.tool import ToolSettings, ToolTarget
from hybrid_force.errors import ControlError, ReachError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Sphere
from hybrid_force.geometry.paths import Circle, Helix
from hybrid_force.model.robot import Robot

UR5_SEED = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
PANDA_SEED = np.array([0.0, -0.5, 0.0, -2.3, 0.0, 1.8, 0.8])
TILT = math.radians(15.0)

# UR5: circle of latitude 0.2 m above the centre of the sphere of radius 0.3 of the shipped
# scenarios/ur5_sphere_normal.toml; Panda: helix on the bottom of the pipe of radius 0.15
# along world x of scenarios/panda_pipe_tilt.toml (closed-form paths, fast turns).
SPHERE = Sphere(0.3, [0.45, 0.1, 0.0])
SPHERE_PATH = Circle([0.45, 0.1, 0.2], math.sqrt(0.3**2 - 0.2**2), [0, 0, 1], omega=0.5)
PIPE = Cylinder(0.15, [0.45, 0.0, 0.4], [1.0, 0.0, 0.0], inside=True)
PIPE_PATH = Helix([0.39, 0.0, 0.4], 0.15, axis=[1.0, 0.0, 0.0], omega=0.4, rise=0.01, phase=-2.2)


def _sphere_axis(t: float) -> np.ndarray:
    """Into the sphere from outside: towards its centre."""
    return (np.array(SPHERE.center) - SPHERE_PATH.position(t)) / SPHERE.radius


def _pipe_axis(t: float) -> np.ndarray:
    """Out of the pipe's axis (into the wall), turned by TILT towards the travel ṗ_d."""
    p, v, _ = PIPE_PATH.evaluate(t)
    out = np.array([0.0, p[1], p[2] - 0.4]) / 0.15  # the wall's outward radius (−n inside)
    travel = v - (v @ out) * out
    travel /= np.linalg.norm(travel)
    return math.cos(TILT) * out + math.sin(TILT) * travel


CASES = {
    "ur5": ("ur5", SPHERE, SPHERE_PATH, UR5_SEED, 0.0, _sphere_axis),
    "panda": ("panda", PIPE, PIPE_PATH, PANDA_SEED, TILT, _pipe_axis),
}


def _tip(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    data = robot.new_data()
    pin.forwardKinematics(robot.model, data, q)
    M = pin.updateFramePlacement(robot.model, data, robot.tip_id)
    return M.translation.copy(), M.rotation.copy()


def _start(robot: Robot, which: str, roll: str) -> tuple[PoseJointPath, ToolTarget]:
    _, surface, path, seed, tilt, _ = CASES[which]
    tool = ToolSettings(orientation="normal", tilt=tilt, roll=roll)
    target = ToolTarget(tool, surface, path)
    q0 = inverse_kinematics(robot, path.position(0.0), seed=seed)
    q0 = pose_inverse_kinematics(robot, target, 0.0, q0)
    return PoseJointPath(robot, path, target, q0), target


def _run(robot: Robot, which: str, roll: str, seconds: float = 2.0):
    """(des, t, q, qd, qdd) of 2 s of advance(DT) (test_clik's helper)."""
    return history(_start(robot, which, roll)[0], seconds)


RUNS = [("ur5", "free"), ("ur5", "held"), ("panda", "free"), ("panda", "held")]


@pytest.fixture(scope="module", params=RUNS, ids=[f"{a}-{r}" for a, r in RUNS])
def run(request: pytest.FixtureRequest, ur5: Robot, panda: Robot):
    which, roll = request.param
    robot = ur5 if which == "ur5" else panda
    return (which, roll, *_run(robot, which, roll))


def test_pose_ik_residual_by_forward_kinematics(ur5: Robot, panda: Robot) -> None:
    for which, robot in (("ur5", ur5), ("panda", panda)):
        _, surface, path, seed, tilt, axis_of = CASES[which]
        target = ToolTarget(ToolSettings(orientation="normal", tilt=tilt), surface, path)
        for t in (0.0, 1.3, 4.0):
            q = inverse_kinematics(robot, path.position(t), seed=seed)
            q = pose_inverse_kinematics(robot, target, t, q)
            p, R = _tip(robot, q)
            assert np.linalg.norm(p - path.position(t)) < 1e-12
            assert np.linalg.norm(R[:, 2] - axis_of(t)) < 1e-9


def test_tracks_position_and_axis(run) -> None:
    which, _, des, ts, qs, _, _ = run
    axis_of = CASES[which][5]
    path = CASES[which][2]
    worst_p = worst_a = 0.0
    for t, q in zip(ts[::50], qs[::50], strict=True):
        p, R = _tip(des.robot, q)
        worst_p = max(worst_p, float(np.linalg.norm(p - path.position(t))))
        worst_a = max(worst_a, float(np.linalg.norm(R[:, 2] - axis_of(t))))
    assert worst_p < 1e-9
    assert worst_a < 1e-9


def test_qd_matches_finite_differences_of_q(run) -> None:
    *_, qs, qds, _ = run
    fd = (qs[2:] - qs[:-2]) / (2 * DT)
    assert np.abs(fd - qds[1:-1]).max() / (1 + np.abs(qds).max()) < 1e-5


def test_qdd_matches_finite_differences_of_qd(run) -> None:
    """q̈_d is the exact time derivative of q̇_d: it carries ä_d (∇²Φ, p̈_d), the rotation of
    the task rows and the null-space part; FD error O(dt²) ≈ 1e-7 relative."""
    *_, qds, qdds = run
    fd = (qds[2:] - qds[:-2]) / (2 * DT)
    assert np.abs(fd - qdds[1:-1]).max() / (1 + np.abs(qdds).max()) < 1e-5


def test_held_roll_keeps_the_start_roll_relative_to_the_travel(run) -> None:
    which, roll, des, ts, qs, _, _ = run
    if roll != "held":
        pytest.skip("roll free: the rotation about the axis is the posture's")
    path = CASES[which][2]
    angles = []
    for t, q in zip(ts[::100], qs[::100], strict=True):
        _, R = _tip(des.robot, q)
        a, x_tip = R[:, 2], R[:, 0]
        v = path.evaluate(t)[1]
        travel = v - (v @ a) * a
        travel /= np.linalg.norm(travel)
        angles.append(math.atan2(float(np.cross(travel, x_tip) @ a), float(travel @ x_tip)))
    assert np.ptp(angles) < 1e-9


def test_start_off_the_pose_and_arm_too_small(ur5: Robot, rtr: Robot) -> None:
    _, target = _start(ur5, "ur5", "free")
    q = inverse_kinematics(ur5, SPHERE_PATH.position(0.0), seed=UR5_SEED)  # position only
    with pytest.raises(ReachError, match=r"not on the start pose"):
        PoseJointPath(ur5, SPHERE_PATH, target, q)
    with pytest.raises(ControlError, match=r"'rtr' has 3 joints") as info:
        PoseJointPath(rtr, SPHERE_PATH, target, np.zeros(3))
    assert info.value.key == "tool.orientation"


def test_the_pose_path_time_is_i_dt(ur5: Robot) -> None:
    """The pose CLIK's t is t0 + i·dt (issue 28 item 6), not a sum of its steps."""
    des, _ = _start(ur5, "ur5", "free")
    for _ in range(300):
        des.advance(DT)
    assert des.t == 300 * DT

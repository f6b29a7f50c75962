"""Closed-loop inverse kinematics the paper's "Newton algorithm", eq. 27.

Independent references:
- inverse_kinematics: the residual ‖p(q) − target‖ measured with the robot's own forward
  kinematics, and the RTR closed-form inverse kinematics;
- DesiredJointPath: the task error ‖k(q_d) − p_d‖ after 2 s of advance(1e-3) on the paper's
  helix (RTR) and on a circle inside the Panda's workspace; q̇_d against central differences of
  the integrated q_d(t), q̈_d against central differences of q̇_d(t) (non-redundant arm); the
  task-space identity J q̈_d + J̇ q̇_d = p̈_d − γ (J q̇_d − ṗ_d) with J, J̇ q̇_d from the robot layer.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from hybrid_force.control.clik import (
    ClikSettings,
    DesiredJointPath,
    StepClock,
    inverse_kinematics,
)
from hybrid_force.errors import ControlError, ReachError
from hybrid_force.geometry.paths import Circle, Path, paper_helix
from hybrid_force.model.robot import Robot

L2, L3 = 0.9, 1.0
DT = 1e-3
PANDA_SEED = np.array([0.0, -0.5, 0.0, -2.3, 0.0, 1.8, 0.8])


# --- inverse kinematics -----------------------------------------------------------------------
def test_ik_reaches_points_rtr(rtr: Robot) -> None:
    rng = np.random.default_rng(41)
    q = inverse_kinematics(rtr, [0.4, 0.0, 7.0], seed=[0.0, 6.0, 2.0])
    assert np.linalg.norm(rtr.tip_position(q) - [0.4, 0.0, 7.0]) < 1e-12
    # closed form: q1 = 0, c3 = (0.4 − l2)/l3 = −0.5 with the seed's elbow-up branch, q2 = 7 − s3
    np.testing.assert_allclose(q, [0.0, 7.0 - np.sqrt(0.75), 2 * np.pi / 3], atol=1e-9)
    for _ in range(10):
        target = np.array([*rng.uniform(-1.2, 1.2, 2), rng.uniform(2, 12)])
        r = np.hypot(*target[:2])
        if not 0.2 < r < 1.8:
            continue
        seed = np.array([np.arctan2(target[1], target[0]) + 0.3, target[2] - 0.5, 1.5])
        q = inverse_kinematics(rtr, target, seed=seed)
        assert np.linalg.norm(rtr.tip_position(q) - target) < 1e-12


def test_ik_reaches_points_panda(panda: Robot) -> None:
    for target in ([0.4, 0.0, 0.4], [0.5, 0.1, 0.4], [0.3, -0.2, 0.6]):
        q = inverse_kinematics(panda, target, seed=PANDA_SEED)
        assert q.shape == (7,)
        assert np.linalg.norm(panda.tip_position(q) - target) < 1e-12


def test_ik_out_of_reach_raises_with_point(rtr: Robot) -> None:
    with pytest.raises(ReachError, match=r"5\.0") as info:
        inverse_kinematics(rtr, [5.0, 0.0, 7.0], seed=[0.0, 6.0, 2.0])
    message = str(info.value)
    assert "rtr" in message and "out of reach" in message


# --- the desired joint path ---------------------------------------------------------------------
def _run(robot: Robot, path: Path, q0: np.ndarray, seconds: float = 2.0):
    """Advance a DesiredJointPath for `seconds`; return it and the history (t, q, qd, qdd)."""
    return history(DesiredJointPath(robot, path, q0), seconds)


def history(des: Any, seconds: float) -> tuple[Any, ...]:
    """Advance a desired joint path ``des`` by DT for `seconds`: (des, t, q, qd, qdd)."""
    ts, qs, qds, qdds = [des.t], [des.q.copy()], [des.qd.copy()], [des.qdd.copy()]
    for _ in range(round(seconds / DT)):
        des.advance(DT)
        ts.append(des.t)
        qs.append(des.q.copy())
        qds.append(des.qd.copy())
        qdds.append(des.qdd.copy())
    return des, np.array(ts), np.array(qs), np.array(qds), np.array(qdds)


def _check_task_identity(robot: Robot, path: Path, t: float, q, qd, qdd, gamma: float) -> float:
    """J q̈_d + J̇ q̇_d = p̈_d − γ (J q̇_d − ṗ_d): returns the relative error."""
    _, pdot_d, pddot_d = path.evaluate(t)
    J = robot.jacobian(q)
    lhs = J @ qdd + robot.drift(q, qd)
    rhs = pddot_d - gamma * (J @ qd - pdot_d)
    return float(np.abs(lhs - rhs).max() / (1 + np.abs(rhs).max()))


@pytest.fixture(scope="module")
def rtr_run(rtr: Robot):
    path = paper_helix()
    q0 = inverse_kinematics(rtr, path.position(0.0), seed=[0.0, 9.0, 2.0])
    return (path, *_run(rtr, path, q0))


@pytest.fixture(scope="module")
def panda_run(panda: Robot):
    path = Circle(center=(0.4, 0.0, 0.4), radius=0.1, normal=(0.0, 0.0, 1.0), omega=1.0)
    q0 = inverse_kinematics(panda, path.position(0.0), seed=PANDA_SEED)
    return (path, *_run(panda, path, q0))


@pytest.mark.parametrize("which", ["rtr_run", "panda_run"])
def test_tracks_path_after_2s(which: str, request: pytest.FixtureRequest) -> None:
    path, des, ts, qs, _, _ = request.getfixturevalue(which)
    assert ts[-1] == pytest.approx(2.0, abs=1e-9)
    assert des.task_error() < 1e-6
    robot = des.robot
    # independent measurement of the error all along the run
    worst = max(
        np.linalg.norm(robot.tip_position(q) - path.position(t))
        for t, q in zip(ts, qs, strict=True)
    )
    assert worst < 1e-6


def _qd_fd_error(run) -> float:
    _, _, _, qs, qds, _ = run
    fd = (qs[2:] - qs[:-2]) / (2 * DT)
    return float(np.abs(fd - qds[1:-1]).max() / (1 + np.abs(qds).max()))


def test_qd_matches_finite_differences_of_q_rtr(rtr_run) -> None:
    assert _qd_fd_error(rtr_run) < 1e-5


def test_qd_task_part_matches_finite_differences_of_q_panda(panda_run) -> None:
    """J (FD(q_d) − q̇_d) is O(dt²): the tip part of q̇_d is the derivative of q_d."""
    _, des, _, qs, qds, _ = panda_run
    fd = (qs[2:] - qs[:-2]) / (2 * DT)
    for i in (1, 700, 1500, len(qs) - 2):
        J = des.robot.jacobian(qs[i])
        assert np.abs(J @ (fd[i - 1] - qds[i])).max() < 1e-6


def test_qd_matches_finite_differences_of_q_panda(panda_run) -> None:
    assert _qd_fd_error(panda_run) < 1e-5


@pytest.mark.parametrize("which", ["rtr_run", "panda_run"])
def test_qdd_matches_finite_differences_of_qd(which: str, request: pytest.FixtureRequest) -> None:
    """q̈_d is the exact time derivative of q̇_d (null-space part included for the Panda)."""
    _, _, _, _, qds, qdds = request.getfixturevalue(which)
    fd = (qds[2:] - qds[:-2]) / (2 * DT)
    err = np.abs(fd - qdds[1:-1]).max() / (1 + np.abs(qdds).max())
    assert err < 1e-5


@pytest.mark.parametrize("which", ["rtr_run", "panda_run"])
def test_task_space_acceleration_identity(which: str, request: pytest.FixtureRequest) -> None:
    path, des, ts, qs, qds, qdds = request.getfixturevalue(which)
    gamma = des.settings.gamma
    for i in (0, 1, 500, 1333, len(ts) - 1):
        err = _check_task_identity(des.robot, path, ts[i], qs[i], qds[i], qdds[i], gamma)
        assert err < 1e-9


def test_panda_task_acceleration_matches_fd_of_task_velocity(panda_run) -> None:
    """Redundant arm: J q̈_d matches J · FD(q̇_d) (only the null-space part is approximate)."""
    _, des, _, qs, qds, qdds = panda_run
    fd = (qds[2:] - qds[:-2]) / (2 * DT)
    for i in (1, 700, 1500):
        J = des.robot.jacobian(qs[i])
        np.testing.assert_allclose(J @ qdds[i], J @ fd[i - 1], atol=1e-5)


# --- bad input ------------------------------------------------------------------------------------
def test_singular_jacobian_on_path_raises(rtr: Robot) -> None:
    """RTR with q3 = 0 (arm stretched, det J = −r s3 l3 = 0): ReachError naming t and q_d."""
    q0 = np.array([0.0, 5.0, 0.0])
    p0 = rtr.tip_position(q0)
    np.testing.assert_allclose(p0, [L2 + L3, 0.0, 5.0], atol=1e-14)
    probe = Circle(center=(0.0, 0.0, 0.0), radius=0.1, normal=(1.0, 0.0, 0.0), omega=1.0)
    # shift the circle so that it starts at the tip: p_d(0) = p0
    center = p0 - probe.position(0.0)
    path = Circle(center=tuple(center), radius=0.1, normal=(1.0, 0.0, 0.0), omega=1.0)
    np.testing.assert_allclose(path.position(0.0), p0, atol=1e-12)
    with pytest.raises(ReachError, match=r"singular.*t = 0") as info:
        DesiredJointPath(rtr, path, q0)
    assert "q_d" in str(info.value)


@pytest.mark.parametrize(
    "kwargs", [{"gamma": 0.0}, {"gamma": -7.0}, {"damping": -1.0}, {"posture_gain": np.nan}]
)
def test_bad_settings(kwargs: dict[str, float]) -> None:
    with pytest.raises(ControlError, match=next(iter(kwargs))):
        ClikSettings(**kwargs)


# --- the path clock (issue 28 item 6) -----------------------------------------------------------
def test_the_path_time_is_i_dt_not_a_sum_of_steps(rtr: Robot) -> None:
    """After i steps t is exactly i·dt (t0 = 0), and p_d is eq. 25 at that time: a sum of
    steps drifts (3.4e-12 s after 20 s at 1 ms), which moves p_d by ~1e-12 m."""
    clock, summed = StepClock(), 0.0
    for i in range(1, 20001):
        clock.tick(DT)
        summed += DT
        assert clock.t == i * DT
    assert abs(summed - 20.0) > 1e-12  # what the old clock did
    shifted = StepClock(0.5)
    for _ in range(3):
        shifted.tick(0.25)
    assert shifted.t == 0.5 + 3 * 0.25
    path = paper_helix()
    q0 = inverse_kinematics(rtr, path.position(0.0), seed=[0.0, 6.0, 2.0])
    des = DesiredJointPath(rtr, path, q0)
    for _ in range(2000):
        des.advance(DT)
    assert des.t == 2000 * DT
    np.testing.assert_array_equal(des.p_d, path.position(2000 * DT))


@pytest.mark.parametrize("arm", ["rtr", "ur5", "panda"])
def test_frame_jacobian_sets_the_frame_placement(arm: str, request: pytest.FixtureRequest) -> None:
    """The CLIKs read the tip at q_d from data.oMf after getFrameJacobian alone (no
    updateFramePlacement): Pinocchio's getFrameJacobian by frame id sets data.oMf[frame] with
    the same product. Checked bit for bit against updateFramePlacement on another Data."""
    import pinocchio as pin

    robot: Robot = request.getfixturevalue(arm)
    model, fid = robot.model, robot.tip_id
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = robot.neutral() + rng.uniform(-1.0, 1.0, robot.nq)  # (Euclidean arms)
        ref, got = model.createData(), model.createData()
        pin.computeJointJacobians(model, ref, q)
        pin.updateFramePlacement(model, ref, fid)
        pin.computeJointJacobians(model, got, q)
        got.oMf[fid] = pin.SE3(pin.Quaternion(rng.standard_normal(4)).normalized().matrix(),
                               rng.standard_normal(3))  # fmt: skip
        pin.getFrameJacobian(model, got, fid, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_array_equal(got.oMf[fid].homogeneous, ref.oMf[fid].homogeneous)

"""The start of ``initial.tip`` within the joint limits (scenario/_builders.py).

Independent references: the joint limits of the URDF (Pinocchio's model), forward kinematics
of the start found (the tip, and the tool axis against the sphere's centre direction), and
the 2π renaming of a revolute angle checked by forward kinematics (the same placement).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hybrid_force.errors import ReachError, RunWarning
from hybrid_force.model.loading import load_robot
from hybrid_force.model.robot import Robot
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.start import _start_in_limits, _start_solver, _wrapped_into_limits

# The z1 from its neutral seed reaches this point of a sphere with joints 2 and 4 beyond
# their limits (joint2 = 9.49 rad, limit 2.97; joint4 = −2.24, limit −1.52).
Z1_SPHERE = """
name = "z1_sphere"
[robot]
model = "z1"
[surface]
type = "sphere"
radius = 0.24
center = [0.36, 0.08, 0.0]
inside = false
[trajectory]
type = "raster"
origin = [0.6, -0.3]
size = [0.2, 0.6]
spacing = 0.1
direction = "v"
speed = 0.04
[initial]
tip = [0.5492335748875524, 0.02146319564405676, 0.13551419361480848]
[tool]
orientation = "normal"
[control]
supervisor = false
[sim]
duration = 0.5
"""


def _inside(robot: Robot, q: np.ndarray) -> bool:
    lower, upper = robot.position_limits
    return bool(np.all((lower <= q) & (q <= upper)))


def test_a_start_outside_the_limits_is_replaced_by_one_inside(tmp_path: Path) -> None:
    file = tmp_path / "z1.toml"
    file.write_text(Z1_SPHERE)
    sc = load_scenario(file)
    robot = sc.robot
    assert _inside(robot, sc.q0)
    solve = _start_solver(sc.tool, robot, sc.surfaces, sc.path, sc.robot.tip_position(sc.q0))
    assert not _inside(robot, _wrapped_into_limits(robot, solve(robot.neutral())))  # the case
    data = robot.new_data()
    pin.forwardKinematics(robot.model, data, sc.q0)
    placement = pin.updateFramePlacement(robot.model, data, robot.tip_id)
    tip = np.array([0.5492335748875524, 0.02146319564405676, 0.13551419361480848])
    np.testing.assert_allclose(placement.translation, tip, atol=1e-9)
    towards_centre = (np.array([0.36, 0.08, 0.0]) - tip) / 0.24
    np.testing.assert_allclose(placement.rotation[:, 2], towards_centre, atol=1e-8)


def test_revolute_angles_are_renamed_by_two_pi() -> None:
    ur5 = load_robot("ur5")
    lower, _ = ur5.position_limits
    assert np.all(np.isfinite(lower))  # the UR5's joints are revolute with ±2π limits
    q = np.array([0.3, -1.2, 1.4, -1.0, -1.5, 0.2])
    shifted = q.copy()
    shifted[2] += 3 * 2 * math.pi  # outside [−2π, 2π]: the same pose
    wrapped = _wrapped_into_limits(ur5, shifted)
    assert _inside(ur5, wrapped)
    assert (wrapped[2] - q[2]) / (2 * math.pi) == pytest.approx(
        round((wrapped[2] - q[2]) / (2 * math.pi))
    )
    np.testing.assert_array_equal(np.delete(wrapped, 2), np.delete(q, 2))
    np.testing.assert_allclose(ur5.tip_position(wrapped), ur5.tip_position(q), atol=1e-12)
    assert _start_in_limits(ur5, q, None, None, "initial.tip") is not None  # inside: kept
    np.testing.assert_array_equal(_start_in_limits(ur5, q, None, None, "initial.tip"), q)


def test_no_start_within_the_limits_warns_naming_the_joints() -> None:
    z1 = load_robot("z1")
    lower, _ = z1.position_limits
    outside = z1.neutral()
    outside[3] = lower[3] - 0.5  # joint4 below its limit (not reachable by 2π: range < 2π)

    def never(seed: np.ndarray) -> np.ndarray:
        raise ReachError("out of reach")

    with pytest.warns(RunWarning, match=r"initial\.tip: .*joint4 = .*outside the joint limits"):
        kept = _start_in_limits(z1, outside, never, None, "initial.tip")
    np.testing.assert_array_equal(kept, outside)

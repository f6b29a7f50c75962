"""Load a robot and inspect it: joints, limits, tip and the mass matrix at a configuration.

Two arms: the paper's RTR arm bundled with the package (``robots/rtr.urdf``) and the UR5 of
the example-robot-data package (any name listed by ``hybrid-force robots``, or the path of a
URDF, xacro or MJCF file, loads the same way). For each it prints the joints with their
position, velocity and effort limits, the tip frame and where it is at the configuration q0,
and the joint-space mass matrix M(q0) with its eigenvalues (M is symmetric positive definite
for any arm whose links all have mass).

Run from anywhere:

    python examples/inspect_robot.py            # the RTR arm and the UR5
    python examples/inspect_robot.py panda z1   # other arms
"""

from __future__ import annotations

import sys

import numpy as np

from hybrid_force import load_robot


def inspect(name: str) -> None:
    robot = load_robot(name)
    lower, upper = robot.position_limits
    print(f"{name}: {robot.nq} joints, tip frame {robot.tip!r}, model file {robot.urdf_path}")
    print(f"  {'joint':<22} {'lower':>9} {'upper':>9} {'velocity':>9} {'effort':>9}")
    joints = robot.model.names[1:]  # Pinocchio's joint 0 is the universe
    for i, joint in enumerate(joints):
        print(
            f"  {joint:<22} {lower[i]:9.3f} {upper[i]:9.3f} "
            f"{robot.velocity_limits[i]:9.3f} {robot.effort_limits[i]:9.1f}"
        )
    # q0: the middle of every bounded range, 0 for an unbounded joint
    bounded = np.isfinite(lower) & np.isfinite(upper)
    q0 = np.zeros(robot.nq)
    q0[bounded] = (lower[bounded] + upper[bounded]) / 2
    M = robot.mass_matrix(q0)
    eigenvalues = np.linalg.eigvalsh(M)
    with np.printoptions(precision=4, suppress=True, linewidth=100):
        print(f"  q0 = {q0}")
        print(f"  tip position p(q0) = {robot.tip_position(q0)} m")
        print(f"  gravity torque g(q0) = {robot.gravity(q0)}")
        print(f"  mass matrix M(q0) [kg, kg·m, kg·m²]:\n{M}")
        print(f"  eigenvalues of M(q0): {eigenvalues}")
    print(f"  M symmetric: {np.allclose(M, M.T, rtol=0, atol=1e-12)}")
    print(f"  smallest eigenvalue of M(q0): {eigenvalues[0]:.6g}")


def main(names: list[str]) -> None:
    for name in names or ["rtr", "ur5"]:
        inspect(name)


if __name__ == "__main__":
    main(sys.argv[1:])

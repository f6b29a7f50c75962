"""Benchmark of the pose CLIK ([tool] orientation = "normal") against the position-only CLIK.

Run from the repository root:

    python benchmarks/bench_pose_clik.py [--steps N]

Reports, on one machine (timings depend on its load: the uptime line is printed):

1. the time per step [µs] of the desired joint path alone (``advance(1e-3)``, median over 3
   repetitions of N steps): the compiled position-only
   :class:`~hybrid_force.control.clik.DesiredJointPath`, and the compiled
   :class:`~hybrid_force.control.pose_clik.PoseJointPath` with the roll free (5 rows) and held
   (6 rows), for the UR5 on the sphere of ``scenarios/ur5_sphere_normal.toml`` and the Panda in
   the pipe of ``scenarios/panda_pipe_tilt.toml`` (15° tilt towards the travel);
2. the full closed loop's steps per second (2 s of each shipped scenario, best of 3, the two
   alternating) with its ``[tool]`` table and with ``tool.orientation = "free"`` (the
   Scenario built in Python: the loader refuses the tool keys inert with it), and their ratio.

Not part of the test suite.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hybrid_force.control.clik import DesiredJointPath  # noqa: E402
from hybrid_force.control.pose_clik import PoseJointPath  # noqa: E402
from hybrid_force.control.supervisor import HybridController  # noqa: E402
from hybrid_force.control.tool import ToolSettings  # noqa: E402
from hybrid_force.scenario.loader import load_scenario  # noqa: E402
from hybrid_force.sim.loop import simulate  # noqa: E402

SCENARIOS = ("ur5_sphere_normal", "panda_pipe_tilt")


def _per_step(path: DesiredJointPath | PoseJointPath, steps: int) -> float:
    """Median time per advance(1e-3) [µs] over 3 repetitions of ``steps`` steps."""
    times = []
    for _ in range(3):
        start = time.perf_counter()
        for _ in range(steps):
            path.advance(1e-3)
        times.append((time.perf_counter() - start) / steps * 1e6)
    return statistics.median(times)


def _joint_path(
    name: str, orientation: str, roll: str = "free"
) -> DesiredJointPath | PoseJointPath:
    """The desired joint path the controller of the shipped scenario builds."""
    sc = load_scenario(ROOT / "scenarios" / f"{name}.toml")
    tool = sc.tool
    if orientation == "free":
        tool = ToolSettings(axis=tool.axis)
    else:
        tool = ToolSettings(axis=tool.axis, orientation="normal", tilt=tool.tilt, roll=roll)
    from hybrid_force.control.constraint import Constraint

    law = HybridController(sc.robot, Constraint(sc.surfaces), sc.path, sc.q0, sc.control, tool=tool)
    return law.clik


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    args = parser.parse_args()
    print(f"load average: {os.getloadavg()}")
    print(f"\n1. desired joint path, time per step [µs] (median of 3 × {args.steps} steps)")
    print(
        f"{'scenario':<20} {'position (compiled)':>20} {'pose, roll free':>16} {'pose, held':>12}"
    )
    for name in SCENARIOS:
        _per_step(_joint_path(name, "free"), 10)  # load the compiled kernels
        row = [
            _per_step(_joint_path(name, "free"), args.steps),
            _per_step(_joint_path(name, "normal", "free"), args.steps),
            _per_step(_joint_path(name, "normal", "held"), args.steps),
        ]
        print(f"{name:<20} {row[0]:>20.1f} {row[1]:>16.1f} {row[2]:>12.1f}")
    print("\n2. closed loop, steps per second (2 s simulated, best of 3)")
    print(f"{'scenario':<20} {'[tool] as shipped':>18} {'orientation free':>17} {'ratio':>6}")
    for name in SCENARIOS:
        shipped = load_scenario(ROOT / "scenarios" / f"{name}.toml", {"sim.duration": 2.0})
        free = dataclasses.replace(shipped, tool=ToolSettings(axis=shipped.tool.axis))
        rates = [0.0, 0.0]
        for _ in range(3):
            for i, sc in enumerate((shipped, free)):
                rates[i] = max(rates[i], simulate(sc).meta["steps_per_second"])
        print(f"{name:<20} {rates[0]:>18.0f} {rates[1]:>17.0f} {rates[0] / rates[1]:>6.2f}")


if __name__ == "__main__":
    main()

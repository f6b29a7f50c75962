"""The ``[tool]`` targets on arms, surfaces and paths beyond the two shipped scenarios.

Each case is a scenario built here from the shipped ones (scenarios/ur5_sphere_normal.toml,
scenarios/panda_pipe_tilt.toml): a raster or waypoints on a sphere (outside), a pipe (inside)
or a tilted plane, placed in front of the arm and scaled by its reach against the UR5's, the
tool along the normal (with a tilt towards the travel on some), default gains, dt = 1 ms,
ideal sensing, starting in contact at the path's start. It prints, after settling (t ≥ 5 s):
the largest position error per axis, |f − f_d| and the tool angle, against the targets of
the ``[tool]`` table (1e-5 m, 1e-3 N, 1e-4 rad), or the error a case is refused with.

    python benchmarks/study_tool_paths.py            # all cases (~2 min on 2 cores)
    python benchmarks/study_tool_paths.py ur10 z1    # only the arms named
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

from hybrid_force.errors import BadInputError
from hybrid_force.geometry.paths import path_from_dict
from hybrid_force.geometry.surfaces import surface_from_dict
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

# name: (reach scale against the UR5, seed of the start; None: the neutral configuration)
ARMS = {
    "ur3": (0.6, [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]),
    "ur5": (1.0, [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]),
    "ur10": (1.5, [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]),
    "panda": (1.0, [0.0, -0.5, 0.0, -2.3, 0.0, 1.8, 0.8]),
    "xarm7": (0.9, None),
    "z1": (0.8, None),
}
TARGETS = (1e-5, 1e-3, 1e-4)


def _cases(s: float) -> dict[str, tuple[str, str, str]]:
    """(surface table, trajectory table, tool table) per case, lengths scaled by s."""
    sphere = f"""type = "sphere"
radius = {0.3 * s}
center = [{0.45 * s}, {0.1 * s}, 0.0]
inside = false"""
    pipe = f"""type = "cylinder"
radius = {0.15 * s}
center = [{0.45 * s}, 0.0, {0.4 * s}]
axis = [1.0, 0.0, 0.0]
inside = true"""
    plane = f"""type = "plane"
point = [{0.5 * s}, 0.0, {0.1 * s}]
normal = [0.3, 0.0, 1.0]"""
    raster_sphere = """type = "raster"
origin = [0.6, -0.3]
size = [0.2, 0.6]
spacing = 0.1
direction = "v"
speed = 0.04"""
    waypoints_pipe = f"""type = "waypoints"
frame = "surface"
points = [[-2.17, {-0.06 * s}], [-1.9, {-0.05 * s}], [-1.6, {-0.03 * s}], [-1.3, {-0.03 * s}]]
speed = 0.02"""
    raster_plane = f"""type = "raster"
origin = [{-0.1 * s}, {-0.1 * s}]
size = [{0.2 * s}, {0.15 * s}]
spacing = {0.05 * s}
speed = 0.04"""
    waypoints_world = f"""type = "waypoints"
frame = "world"
points = [[{0.55 * s}, {-0.1 * s}, 0.2], [{0.6 * s}, 0.0, 0.2], [{0.55 * s}, {0.1 * s}, 0.2]]
speed = 0.03"""
    normal = 'orientation = "normal"'
    tilt = 'orientation = "normal"\ntilt = 0.2617993877991494'
    return {
        "sphere raster normal": (sphere, raster_sphere, normal),
        "sphere raster tilt": (sphere, raster_sphere, tilt),
        "pipe waypoints tilt": (pipe, waypoints_pipe, tilt),
        "plane raster normal": (plane, raster_plane, normal),
        "sphere world waypoints normal": (sphere, waypoints_world, normal),
    }


def _scenario(arm: str, case: str, surface: str, traj: str, tool: str, seed: object) -> str:
    sdict = _table(surface)
    tdict = {**_table(traj), "surface": surface_from_dict(sdict).to_dict()}
    start = path_from_dict(tdict).position(0.0)
    seed_line = "" if seed is None else f"seed = {seed}"
    return f"""name = "{arm}_{case.replace(" ", "_")}"
[robot]
model = "{arm}"
[surface]
{surface}
[trajectory]
{traj}
[initial]
tip = {start.tolist()}
{seed_line}
[tool]
{tool}
[control]
supervisor = false
f_d = 10.0
[sim]
duration = 12.0
"""


def _table(text: str) -> dict[str, object]:
    import tomllib

    return tomllib.loads(text)


def main(arms: list[str]) -> None:
    print(f"{'arm':6} {'case':30} {'status':8} {'pos/axis [m]':>12} {'|f-fd| [N]':>10} "
          f"{'angle [rad]':>11} {'wall [s]':>8}")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        for arm in arms:
            scale, seed = ARMS[arm]
            for case, (surface, traj, tool) in _cases(scale).items():
                file = Path(tmp) / f"{arm}_{case.replace(' ', '_')}.toml"
                file.write_text(_scenario(arm, case, surface, traj, tool, seed))
                start = time.perf_counter()
                try:
                    result = simulate(load_scenario(file))
                except BadInputError as exc:
                    print(f"{arm:6} {case:30} refused  {' '.join(str(exc).split())[:150]}")
                    continue
                m = result.metrics()
                pos = max(m.position_error_max_axis or [math.nan])
                values = (pos, m.force_error_max_settled, m.tool_angle_max_settled)
                met = all(v is not None and v <= t for v, t in zip(values, TARGETS, strict=True))
                wall = time.perf_counter() - start
                status = result.status if met else "MISSED"
                print(f"{arm:6} {case:30} {status:8} {pos:12.2e} {values[1]:10.2e} "
                      f"{values[2]:11.2e} {wall:8.1f}")  # fmt: skip
                sys.stdout.flush()


if __name__ == "__main__":
    main(sys.argv[1:] or list(ARMS))

"""Study: how fast the paths on surfaces really move, and how well the RTR arm follows them.

Prints, in Markdown, for waypoint paths (``frame = "surface"``) and rasters on the built-in
surfaces (the cases of tests/test_paths_waypoints.py and tests/test_paths_raster.py, speed
0.1 m/s, ramp 0.3 s): the largest |‖ṗ_d‖ / speed − 1| outside the ramps, the largest ‖p̈_d‖,
the largest |d| from the surface over the whole path (sampled every 1 ms) and the cost of one
evaluation of p_d, ṗ_d, p̈_d.

Then two 4 s runs of the RTR arm starting in contact: waypoints on rtr_plane's plane and a
raster on rtr_sphere's sphere, with the largest ‖p − p_d‖, |f − f_d| and |d| over the run.

Run from the repository root:

    python benchmarks/study_surface_paths.py

Not part of the test suite (the tests check the properties; this measures the numbers of
docs/scenarios.md, ``[trajectory]``).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from hybrid_force import simulate
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.raster import RasterPath
from hybrid_force.geometry.surface_path import SurfacePath
from hybrid_force.geometry.waypoints import WaypointPath
from hybrid_force.scenario.loader import load_scenario

SCENARIOS = Path(__file__).parents[1] / "scenarios"
SPEED, RAMP = 0.1, 0.3
_BUFFERS = (np.zeros(3), np.zeros(3), np.zeros(3))
SPHERE = Sphere(0.5, center=(0.0, 0.0, 5.0))
WAYPOINTS = {
    "cylinder": (Cylinder(0.4), [[0.0, 7.0], [0.5, 7.1], [1.5, 7.0], [2.0, 7.3], [8.0, 7.2]]),
    "sphere": (SPHERE, [[-0.6, 0.0], [-0.5, 0.4], [-0.7, 0.9], [-0.3, 1.5], [1.5, 2.0]]),
    "plane": (
        Plane((0.0, 0.0, 5.0), (1.0, 1.0, 1.0)),
        [[0.6, 0.0], [0.65, 0.1], [0.55, 0.2], [0.6, 0.3], [0.6, 1.3]],
    ),
}
RASTERS = {
    "plane": (Plane((0.0, 0.0, 5.0), (0.0, 0.0, 1.0)), (0.5, -0.1), (0.3, 0.2), 0.1, "u"),
    "cylinder, passes along the angle": (Cylinder(0.4), (-0.3, 7.0), (0.6, 0.3), 0.1, "u"),
    "cylinder, passes along the axis": (Cylinder(0.4), (-0.3, 7.0), (0.6, 0.3), 0.2, "v"),
    "sphere, passes along parallels": (SPHERE, (-0.8, -0.3), (0.4, 0.6), 0.1, "v"),
    "sphere, passes along meridians": (SPHERE, (-0.8, -0.3), (0.4, 0.6), 0.1, "u"),
}


def _row(name: str, path: SurfacePath) -> str:
    times = np.arange(0.0, path.duration, 1e-3)
    samples = [path.evaluate(t) for t in times]
    speed = np.array([np.linalg.norm(v) for _, v, _ in samples]) / SPEED
    cruise = (times >= RAMP) & (times <= path.duration - RAMP)
    accel = max(float(np.linalg.norm(a)) for _, _, a in samples)
    off = max(abs(path.surface.distance(p)) for p, _, _ in samples)  # type: ignore[attr-defined]
    error = float(np.abs(speed[cruise] - 1.0).max())
    start = time.perf_counter()
    for t in times[:1000]:
        path.evaluate_into(t, *_BUFFERS)
    cost = (time.perf_counter() - start) / 1000 * 1e6
    return f"| {name} | {error:.1e} | {accel:.3g} | {off:.1e} | {cost:.0f} |"


def _run(name: str, scenario_file: str, trajectory: dict, tip: list[float]) -> str:
    overrides = {
        "trajectory": trajectory,
        "control.supervisor": False,
        "initial.tip": tip,
        "sim.duration": 4.0,
    }
    scenario = load_scenario(SCENARIOS / scenario_file, overrides)
    result = simulate(scenario)
    surface = scenario.surfaces[0]
    track = np.linalg.norm(result.p - result.p_d, axis=1).max()
    force = np.abs(result.f - 10.0).max()
    off = max(abs(surface.distance(p)) for p in result.p)
    return f"| {name} | {result.status} | {track:.2g} | {force:.2g} | {off:.1g} |"


def main() -> None:
    print("| path | \\|‖ṗ_d‖ / speed − 1\\| | max ‖p̈_d‖ [m/s²] | max \\|d\\| [m] | µs per call |")
    print("|---|---|---|---|---|")
    for name, (surface, points) in WAYPOINTS.items():
        path = WaypointPath(surface, points, SPEED, frame="surface", ramp=RAMP)
        print(_row(f"waypoints, {name}", path))
    for name, (surface, origin, size, spacing, direction) in RASTERS.items():
        raster = RasterPath(surface, origin, size, spacing, SPEED, direction=direction, ramp=RAMP)
        print(_row(f"raster, {name}", raster))
    print()
    print(
        "| 4 s run, in contact | status | max ‖p − p_d‖ [m] | max \\|f − f_d\\| [N] | max \\|d\\| |"
    )
    print("|---|---|---|---|---|")
    plane = {
        "type": "waypoints",
        "frame": "surface",
        "points": [[0.6, 0.0], [0.65, 0.05], [0.6, 0.1], [0.5, 0.1]],
        "speed": SPEED,
        "ramp": RAMP,
    }
    print(_run("waypoints on rtr_plane's plane", "rtr_plane.toml", plane, [0.6, 0.0, 5.0]))
    latitude = math.asin(-0.6)
    raster = {
        "type": "raster",
        "origin": [latitude, 0.0],
        "size": [0.2, 0.1],
        "spacing": 0.05,
        "direction": "v",
        "speed": SPEED,
        "ramp": RAMP,
    }
    print(_run("raster on rtr_sphere's sphere", "rtr_sphere.toml", raster, [0.4, 0.0, 4.7]))


if __name__ == "__main__":
    main()

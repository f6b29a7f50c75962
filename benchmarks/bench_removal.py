"""Benchmark: the cost of Preston removal ([tool.pad] + [removal], docs/removal.md) in a run.

Run from the repository root:

    python benchmarks/bench_removal.py [--repeats N] [--json PATH]

For each setup, the same scenario runs with removal off and on, alternating (off, on, off,
on, ...) so that a change of the machine's load hits both alike; each run's
``meta["steps_per_second"]`` (the stepping loop, from its second step) gives its time per
step. Reported: the median over repetitions of (time per step on) / (time per step off) of
each pair, and the set-up time of the grid (the whole simulate() minus the loop). Setups:

* ``rtr_plane_pass``: the RTR arm (3 joints, the cheapest step, so the worst ratio) on
  rtr_plane's plane, a straight pass at 0.05 m/s in contact, Hertz pad (a = 3.1 mm at 10 N),
  0.3 mm cells (a / 10: about 340 cells under the patch);
* ``rtr_plane_fine``: the same with 0.1 mm cells (a / 31: about 3,000 cells under the patch,
  the resolution of the profile tests);
* ``rtr_cylinder``: paper_contact's helix on the cylinder (quadric: the compiled surface),
  Hertz pad, 0.3 mm cells;
* ``ur5_plane``: the UR5 circle on a plane (6 joints), Hertz pad, 0.3 mm cells.

Not part of the test suite; timings depend on the machine's load.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
import warnings
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from hybrid_force.scenario.loader import load_scenario  # noqa: E402
from hybrid_force.sim.loop import simulate  # noqa: E402

PAD = {"type": "hertz", "radius": 0.02, "modulus": 5e6}
PASS = {
    "trajectory": {
        "type": "waypoints",
        "frame": "surface",
        "points": [[0.6, -0.05], [0.6, 0.05]],
        "speed": 0.05,
        "ramp": 0.2,
    },
    "initial.tip": [0.6, -0.05, 5.0],
    "control.supervisor": False,
    "sim.duration": 2.0,
}
SETUPS: dict[str, tuple[str, dict[str, Any], float]] = {
    "rtr_plane_pass": ("rtr_plane.toml", PASS, 3e-4),
    "rtr_plane_fine": ("rtr_plane.toml", PASS, 1e-4),
    "rtr_cylinder": (
        "paper_contact.toml",
        {"sim.duration": 2.0, "initial.tip": [0.4, 0.0, 10.0]},
        3e-4,
    ),
    "ur5_plane": ("ur5_plane.toml", {"sim.duration": 3.0}, 3e-4),
}


def _run(file: str, overrides: dict[str, Any]) -> tuple[float, float]:
    """(seconds per loop step, seconds of the whole simulate())."""
    sc = load_scenario(REPO / "scenarios" / file, overrides)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = simulate(sc)
    whole = time.perf_counter() - start
    return 1.0 / float(result.meta["steps_per_second"]), whole


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    report: dict[str, Any] = {}
    for name, (file, overrides, resolution) in SETUPS.items():
        on = {**overrides, "tool.pad": PAD, "removal": {"k_p": 1e-13, "resolution": resolution}}
        _run(file, {**on, "sim.duration": 0.05})  # compile and load the kernels once
        pairs, setup = [], []
        for _ in range(args.repeats):
            off_step, off_whole = _run(file, overrides)
            on_step, on_whole = _run(file, on)
            pairs.append(on_step / off_step)
            # the grid's set-up: the whole call's extra time beyond the loop's extra time
            steps = round(float(overrides.get("sim.duration", 0.0)) / 1e-3) + 1
            setup.append((on_whole - off_whole) - (on_step - off_step) * steps)
        report[name] = {
            "ratio_median": statistics.median(pairs),
            "ratio_min": min(pairs),
            "ratio_max": max(pairs),
            "ratios": pairs,
            "setup_seconds_median": statistics.median(setup),
        }
        r = report[name]
        print(
            f"{name:16s} on/off time per step: median {r['ratio_median']:.3f} "
            f"(min {r['ratio_min']:.3f}, max {r['ratio_max']:.3f}, {args.repeats} pairs); "
            f"grid set-up {r['setup_seconds_median']:.2f} s"
        )
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

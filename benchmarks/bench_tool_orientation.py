"""Benchmark: the tool's orientation against the same arm and path without it (issue 32).

For ur5_sphere_normal (the tool along the normal) and panda_pipe_tilt (tilted 15°), the
scenario as shipped and the same document without its ``[tool]`` table (``orientation =
"free"``: the position CLIK only), both shortened to ``--duration`` s, run alternately in one
process (tool, free, tool, free, ...) after one warm-up run each; ``meta["steps_per_second"]``
of each run (the stepping loop). Reported: the medians, the best runs and the median of the
pairs' ratios (tool / free). Run from the repository root:

    python benchmarks/bench_tool_orientation.py [--pairs 5] [--duration 2]

Not part of the test suite; timings depend on the machine's load.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hybrid_force.scenario.loader import (  # noqa: E402
    read_scenario_document,
    scenario_from_document,
)
from hybrid_force.sim.loop import simulate  # noqa: E402

SCENARIOS = ("ur5_sphere_normal.toml", "panda_pipe_tilt.toml")


def _scenario(name: str, duration: float, tool: bool) -> object:
    path = ROOT / "scenarios" / name
    doc = read_scenario_document(path, {"sim.duration": duration})
    if not tool:
        doc.pop("tool", None)
    return scenario_from_document(doc, origin=str(path), base_dir=path.parent)


def main(argv: list[str] | None = None) -> int:
    """Print one line per scenario; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--duration", type=float, default=2.0, help="simulated s per run")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    for name in SCENARIOS:
        with_tool = _scenario(name, args.duration, tool=True)
        free = _scenario(name, args.duration, tool=False)
        simulate(with_tool)  # type: ignore[arg-type]
        simulate(free)  # type: ignore[arg-type]
        rates: dict[str, list[float]] = {"tool": [], "free": []}
        for _ in range(args.pairs):
            for key, scenario in (("tool", with_tool), ("free", free)):
                result = simulate(scenario)  # type: ignore[arg-type]
                rates[key].append(float(result.meta["steps_per_second"]))
        ratios = [a / b for a, b in zip(rates["tool"], rates["free"], strict=True)]
        print(
            f"{name}: tool {statistics.median(rates['tool']):.0f} steps/s (best "
            f"{max(rates['tool']):.0f}), free {statistics.median(rates['free']):.0f} (best "
            f"{max(rates['free']):.0f}); tool / free, paired median "
            f"{statistics.median(ratios):.3f} ({min(ratios):.3f}-{max(ratios):.3f}), "
            f"{args.pairs} pairs of {args.duration:g} s"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Run a scenario file from Python, read its metrics and draw its figures.

Loads ``scenarios/paper_contact.toml`` (the paper's section 6.3: the RTR arm follows a helix on
the cylinder of radius 0.4 m pressing with f_d = 10 N), shortened to a few seconds with an
override (the same syntax as ``hybrid-force run --set sim.duration=4``), simulates it, prints
how the errors end, saves the result and writes the paper's figures as PNG files.

Run from anywhere (OUT defaults to a new temporary folder; nothing is written elsewhere):

    python examples/run_and_plot.py [--out OUT] [--duration SECONDS]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from hybrid_force import load_scenario, plot_result, simulate

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "paper_contact.toml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: temp)")
    parser.add_argument("--duration", type=float, default=4.0, help="simulated time [s]")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="hybrid_force_example_"))

    scenario = load_scenario(SCENARIO, {"sim.duration": args.duration})
    result = simulate(scenario)
    metrics = result.metrics(settle_time=args.duration / 2)
    print(f"{scenario.name}: {result.n_samples} samples, status {result.status}")
    print(f"desired force f_d at the end: {result.f_d[-1]:.6g} N")
    print(f"final force error |f - f_d|: {metrics.final_force_error:.3g} N")
    print(f"final position error ||p - p_d||: {metrics.final_position_error:.3g} m")
    print(f"largest force error after t = {metrics.settle_time:g} s: ", end="")
    print(f"{metrics.force_error_max_settled:.3g} N")

    print(f"result: {result.save(out / 'result.npz')}")
    for path in plot_result(result, out):
        print(f"figure: {path}")


if __name__ == "__main__":
    main()

"""Study: where does the hybrid controller converge on paper_contact (section 6.3)?

Sweeps scenarios/paper_contact.toml over K_d (``control.kd_rate`` κ, K_d = κ·M(q0)) × Λ
(``control.Lambda``) × the controller's model mass error (``sim.model_mass_factor`` 0.8, 1.0,
1.2, i.e. ±20 %), writes the sweep to ``--out`` (resumable: rerun to complete it), one heat
map of the final position error over κ × Λ per mass factor to ``docs/figures/sweep_*.png``, and
prints the result tables in Markdown (pasted into docs/sweep.md).

Run from the repository root:

    python benchmarks/study_paper_contact.py [--duration 10] [--workers N] [--scheduler local]

Same sweep with the command line: see docs/sweep.md.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

from hybrid_force.studies.sweep import run_sweep
from hybrid_force.studies.table import read_sweep_csv
from hybrid_force.studies.variants import expand
from hybrid_force.viz.sweep_plots import plot_sweep

REPO = Path(__file__).resolve().parents[1]
KD_RATES = (10, 30, 100, 300)
LAMBDAS = (2, 5, 10, 20)
MASS_FACTORS = (0.8, 1.0, 1.2)
METRICS = ("final_position_error", "final_force_error")


def _fmt(text: str, status: str) -> str:
    if status != "ok":
        return status
    if not text:
        return "–"
    value = float(text)
    return f"{value:.1e}" if math.isfinite(value) else text


def main(argv: list[str] | None = None) -> int:
    """Run (or resume) the study, write the figures, print the tables; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default=str(REPO / "scenarios" / "paper_contact.toml"))
    parser.add_argument("--duration", type=float, default=10.0, help="simulated time [s]")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--scheduler", default=None)
    parser.add_argument("--out", default=str(REPO / "runs" / "study_paper_contact"))
    parser.add_argument("--figures", default=str(REPO / "docs" / "figures"))
    args = parser.parse_args(argv)

    grid = {
        "control.kd_rate": list(KD_RATES),
        "control.Lambda": list(LAMBDAS),
        "sim.model_mass_factor": list(MASS_FACTORS),
        "sim.duration": [args.duration],
    }
    variants = expand(grid, {}, 0, 0)
    t0 = time.monotonic()
    csv_path = run_sweep(
        args.scenario,
        variants,
        workers=args.workers,
        scheduler=args.scheduler,
        out_dir=args.out,
        progress=True,
        arguments={"grid": grid, "script": "benchmarks/study_paper_contact.py"},
    )
    wall = time.monotonic() - t0
    columns, rows = read_sweep_csv(csv_path)
    print(f"{len(rows)} runs in {wall:.0f} s wall (this invocation), {csv_path}")
    sps = [float(r["steps_per_second"]) for r in rows if r["steps_per_second"]]
    if sps:
        print(f"control loop: median {sorted(sps)[len(sps) // 2]:.0f} steps/s per worker")
    figures = Path(args.figures)
    for m in MASS_FACTORS:
        sub = [r for r in rows if float(r["sim.model_mass_factor"]) == m]
        sub_csv = Path(args.out) / f"sweep_mass_{m:g}.csv"
        with sub_csv.open("w", newline="", encoding="utf-8") as fh:
            writer = csv.DictWriter(fh, fieldnames=columns, lineterminator="\n")
            writer.writeheader()
            writer.writerows(sub)
        png = plot_sweep(
            sub_csv,
            figures / f"sweep_final_position_error_mass_{m:g}.png",
            x="control.kd_rate",
            y="control.Lambda",
            metric="final_position_error",
        )
        print(f"wrote {png}")
    for metric in METRICS:
        unit = "m" if "position" in metric else "N"
        print(f"\n{metric} [{unit}] after {args.duration:g} s (κ = control.kd_rate, Λ)\n")
        header = "| κ [1/s] | Λ [1/s] | " + " | ".join(f"mass × {m:g}" for m in MASS_FACTORS)
        print(header + " |")
        print("|" + "---|" * (2 + len(MASS_FACTORS)))
        for kd in KD_RATES:
            for lam in LAMBDAS:
                cells = []
                for m in MASS_FACTORS:
                    match = [
                        r
                        for r in rows
                        if float(r["control.kd_rate"]) == kd
                        and float(r["control.Lambda"]) == lam
                        and float(r["sim.model_mass_factor"]) == m
                    ]
                    r = match[0]
                    cells.append(_fmt(r[metric], r["status"]))
                print(f"| {kd} | {lam} | " + " | ".join(cells) + " |")
    warned = [r for r in rows if r.get("warnings")]
    if warned:
        print(f"\n{len(warned)} run(s) warned, e.g. {warned[0]['run_id']}: {warned[0]['warnings']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark of ``hybrid-force sweep``: how its wall time scales with the number of workers.

Run from the repository root (after ``pip install .``):

    python benchmarks/bench_sweep.py [--runs 16] [--duration 5] [--workers 1,2]
                                     [--dask] [--json PATH]

For each number of workers it runs, as a user would, one command in a fresh process,

    hybrid-force sweep scenarios/paper_contact.toml --grid control.Lambda=<R values>
        --grid sim.duration=<D> --workers W --out <tmp> --quiet

(R runs of D simulated seconds, the paper's section 6.3) and reports the wall time of the
command, runs per second, the speed-up over one worker, the median and largest per-run time of
the rows (``wall_time``: a worker's first run pays for its imports and the compiled kernels) and
whether every row's metrics are identical, bit for bit, to those of one worker. It also times the
fixed cost of a command: a sweep of one 0.01 s run (the Numba cache warm, which the first
measurement makes sure of). With ``--dask`` the same with ``--scheduler local``.

Not part of the test suite; timings depend on the machine's load (the JSON records it).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENARIO = REPO / "scenarios" / "paper_contact.toml"
#: Columns of sweep.csv that are not results of the run (they may differ between engines).
_NOT_RESULTS = ("wall_time", "steps_per_second", "warnings")


def sweep(out: Path, runs: int, duration: float, workers: int, dask: bool) -> float:
    """Run one sweep command in a fresh process; return its wall time [s]."""
    lambdas = ",".join(f"{5.0 + 15.0 * i / max(runs - 1, 1):.6g}" for i in range(runs))
    argv = [
        sys.executable, "-m", "hybrid_force.cli", "sweep", str(SCENARIO),
        "--grid", f"control.Lambda={lambdas}", "--grid", f"sim.duration={duration:g}",
        "--workers", str(workers), "--out", str(out), "--quiet",
    ]  # fmt: skip
    if dask:
        argv += ["--scheduler", "local"]
    t0 = time.perf_counter()
    proc = subprocess.run(argv, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"sweep failed ({proc.returncode}): {proc.stderr.strip()}")
    return wall


def rows(out: Path) -> list[dict[str, str]]:
    with (out / "sweep.csv").open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def results_of(table: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k not in _NOT_RESULTS} for r in table]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--workers", default=None, help="e.g. 1,2,4 (default: 1..cores)")
    parser.add_argument("--dask", action="store_true", help="also with --scheduler local")
    parser.add_argument("--json", default=str(REPO / "benchmarks" / "results" / "sweep.json"))
    args = parser.parse_args()
    cores = os.cpu_count() or 1
    counts = (
        [int(w) for w in args.workers.split(",")] if args.workers else list(range(1, cores + 1))
    )
    report: dict[str, object] = {
        "command": " ".join(sys.argv),
        "cores": cores,
        "loadavg_start": os.getloadavg(),
        "runs": args.runs,
        "duration_s": args.duration,
    }
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        sweep(base / "warm", 1, 0.01, 1, False)  # fills the Numba cache if it is empty
        fixed = [sweep(base / f"fixed{i}", 1, 0.01, 1, False) for i in range(3)]
        report["fixed_cost_s"] = min(fixed)
        print(f"fixed cost of a command (one 0.01 s run, best of 3): {min(fixed):.2f} s")
        engines = [("pool", False)] + ([("dask", True)] if args.dask else [])
        reference: list[dict[str, str]] | None = None
        table_rows = []
        print("| engine | workers | wall [s] | runs/s | speed-up | per run, median [s] | "
              "per run, largest [s] | rows identical |")  # fmt: skip
        print("|---|---|---|---|---|---|---|---|")
        one_worker: dict[str, float] = {}
        for engine, dask in engines:
            for w in counts:
                out = base / f"{engine}{w}"
                wall = sweep(out, args.runs, args.duration, w, dask)
                table = rows(out)
                per_run = [float(r["wall_time"]) for r in table]
                same = None
                if reference is None:
                    reference = results_of(table)
                else:
                    same = results_of(table) == reference
                one_worker.setdefault(engine, wall)
                entry = {
                    "engine": engine,
                    "workers": w,
                    "wall_s": wall,
                    "runs_per_s": args.runs / wall,
                    "speed_up": one_worker[engine] / wall,
                    "per_run_median_s": statistics.median(per_run),
                    "per_run_max_s": max(per_run),
                    "rows_identical_to_first": same,
                }
                table_rows.append(entry)
                print(
                    f"| {engine} | {w} | {wall:.2f} | {args.runs / wall:.2f} | "
                    f"{one_worker[engine] / wall:.2f} | {statistics.median(per_run):.2f} | "
                    f"{max(per_run):.2f} | {'-' if same is None else same} |"
                )
        report["sweeps"] = table_rows
    report["loadavg_end"] = os.getloadavg()
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()

"""The fixed cost of a command against importing its three heavy libraries (issue 32, item 4).

Run from the repository root:

    python benchmarks/bench_fixed_cost.py [--runs 10] [--tree PATH ...] [--json PATH]

Times, each in a fresh process, in turn (A B A B ...; one untimed run of each first, which
also fills the Numba cache):

* A: ``hybrid-force run scenarios/paper_contact.toml --set sim.duration=0.01 --out TMP`` (the
  console script's own two lines, ``from hybrid_force.cli import main; sys.exit(main())``,
  with the code of each ``--tree``: default this checkout);
* B: ``python -c "import numpy, pinocchio, numba"``,

and prints, per tree, the wall and CPU (user + sys) seconds of each (best, median) and the
ratio A/B of each pair (median, min, max), with the load average before and after. The issue's
target: A/B ≤ 1.5. Not part of the test suite.

Bytecode: B's libraries come with their ``.pyc`` files (pip compiles a package it installs),
so by default (``--bytecode cached``) the tree is byte-compiled first (``compileall``, as pip
installs it) and PYTHONDONTWRITEBYTECODE is removed from the children's environment. With
``--bytecode none`` the environment is kept: where it sets PYTHONDONTWRITEBYTECODE (this
workplace's machines do) and the tree has no ``.pyc``, A compiles the package's ~100 modules
from source on every run (about 0.4 s, the largest part of A − B measured that way).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BASELINE = [sys.executable, "-c", "import numpy, pinocchio, numba"]
ENTRY = "import sys; from hybrid_force.cli import main; sys.exit(main())"


def _timed(argv: list[str], env: dict[str, str], cwd: Path) -> tuple[float, float]:
    """Wall and CPU (user + sys of the child) seconds of one run of ``argv``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(argv, env=env, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{argv} failed ({done.returncode}):\n{done.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def measure(tree: Path, runs: int, bytecode: str = "cached") -> dict[str, Any]:
    """``runs`` pairs (command, baseline) in turn, after one untimed run of each."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    if bytecode == "cached":
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        subprocess.run(
            [sys.executable, "-m", "compileall", "-q", str(tree / "hybrid_force")], check=True
        )
    with tempfile.TemporaryDirectory(prefix="bench_fixed_") as tmp:
        command = [sys.executable, "-c", ENTRY, "run", str(tree / "scenarios/paper_contact.toml")]
        command += ["--set", "sim.duration=0.01", "--out", str(Path(tmp) / "out")]
        _timed(command, env, tree)
        _timed(BASELINE, env, tree)
        load = [list(os.getloadavg())]
        a: list[tuple[float, float]] = []
        b: list[tuple[float, float]] = []
        for _ in range(runs):
            a.append(_timed(command, env, tree))
            b.append(_timed(BASELINE, env, tree))
        load.append(list(os.getloadavg()))
    wall = [x[0] / y[0] for x, y in zip(a, b, strict=True)]
    cpu = [x[1] / y[1] for x, y in zip(a, b, strict=True)]
    return {
        "tree": str(tree),
        "runs": runs,
        "bytecode": bytecode,
        "PYTHONDONTWRITEBYTECODE": env.get("PYTHONDONTWRITEBYTECODE"),
        "command_wall_s": [x[0] for x in a],
        "command_cpu_s": [x[1] for x in a],
        "baseline_wall_s": [y[0] for y in b],
        "baseline_cpu_s": [y[1] for y in b],
        "ratio_wall": {"median": statistics.median(wall), "min": min(wall), "max": max(wall)},
        "ratio_cpu": {"median": statistics.median(cpu), "min": min(cpu), "max": max(cpu)},
        "loadavg": load,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--tree", type=Path, action="append", help="default: this checkout")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument(
        "--bytecode", choices=("cached", "none"), default="cached",
        help="byte-compile the tree first and let Python use .pyc files (default), or keep "
        "the environment as it is",
    )  # fmt: skip
    args = parser.parse_args(argv)
    trees = [t.resolve() for t in args.tree] if args.tree else [ROOT]
    results = []
    for rnd in range(2 if len(trees) > 1 else 1):  # two rounds: each tree early and late
        for tree in trees if rnd == 0 else trees[::-1]:
            r = measure(tree, args.runs, args.bytecode)
            results.append(r)
            la, lb = r["loadavg"]
            print(
                f"{tree} (load {la[0]:.2f} -> {lb[0]:.2f}), {r['runs']} pairs, bytecode "
                f"{r['bytecode']}:"
            )
            for name in ("command", "baseline"):
                w, c = r[f"{name}_wall_s"], r[f"{name}_cpu_s"]
                print(
                    f"  {name:<9} wall best {min(w):.3f} s, median {statistics.median(w):.3f} s;"
                    f" cpu best {min(c):.3f} s, median {statistics.median(c):.3f} s"
                )
            for kind in ("wall", "cpu"):
                x = r[f"ratio_{kind}"]
                print(
                    f"  command / baseline, {kind}: median {x['median']:.2f}, "
                    f"min {x['min']:.2f}, max {x['max']:.2f}"
                )
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The fixed cost of a command against importing its three heavy libraries (issue 32, item 4).

Run from the repository root:

    python benchmarks/bench_fixed_cost.py [--runs 10] [--tree PATH ...] [--json PATH]
                                          [--bytecode cached|none] [--interleave]
                                          [--phases N]

Times, each in a fresh process, in turn (A B A B ...; one untimed run of each first, which
also fills the Numba cache):

* A: ``hybrid-force run scenarios/paper_contact.toml --set sim.duration=0.01 --out TMP`` (the
  console script's own two lines, ``from hybrid_force.cli import console; sys.exit(console())``
  with the function each ``--tree``'s pyproject.toml names, and its code; default this
  checkout);
* B: ``python -c "import numpy, pinocchio, numba"``,

and prints, per tree, the wall and CPU (user + sys) seconds of each (best, median) and the
ratio A/B of each pair (median, min, max), with the load average before and after. The issue's
target: A/B ≤ 1.5. Not part of the test suite.

``--interleave`` (with several ``--tree``): instead of a block of pairs per tree, ``--runs``
rounds of A of each tree, each followed by a B (A1 B A2 B ...): the ratio A/B per tree as
above, and each tree's A over the first tree's A of the same round, paired (median).

``--phases N``: instead, where A's time goes: N runs of A per tree (the trees in turn), each
with a timer around its phases (wrappers set before ``main`` runs: the imports, ``load_scenario``
and its ``load_robot``, Numba's import and set-up at the first ``jit``, the ``_kernels``
modules' imports, the kernels' cache loads and how many, the rest of ``simulate``, writing
result.npz and summary.json, and the exit after ``main`` returns), medians per tree.

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
import tomllib
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BASELINE = [sys.executable, "-c", "import numpy, pinocchio, numba"]


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


#: A's run with a timer around each phase (``--phases``): argv[1] the output folder, argv[2]
#: the wall clock (time.time()) when the parent started it; prints one JSON line of seconds.
PHASES = r"""
import time
T = {"start": time.time()}
import sys
spawned = float(sys.argv[2])
acc = {}
def add(key, t0):
    acc[key] = acc.get(key, 0.0) + time.perf_counter() - t0
t0 = time.perf_counter()
import numpy, pinocchio
add("import numpy, pinocchio", t0)
t0 = time.perf_counter()
from hybrid_force import _jit, _lazy, cli, run_output
from hybrid_force.model import scenario_robot
add("import hybrid_force.cli (after numpy, pinocchio)", t0)
loads = [0, 0]  # [set up, cache loads]
jit = _jit.jit
def first_jit(func):
    if loads[0]:  # a module bound this name before the first call returned
        return jit(func)
    t0 = time.perf_counter()
    compiled = jit(func)
    add("numba import and set-up (first jit)", t0)
    loads[0] = -1
    from numba.core import dispatcher
    compile = dispatcher.Dispatcher.compile
    def timed_compile(self, sig):
        t0 = time.perf_counter()
        try:
            return compile(self, sig)
        finally:
            add("kernel cache loads", t0)
            loads[1] += 1
    dispatcher.Dispatcher.compile = timed_compile
    _jit.jit = jit
    return compiled
_jit.jit = first_jit
def timed(owner, name, key):
    func = getattr(owner, name)
    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return func(*args, **kwargs)
        finally:
            add(key, t0)
    setattr(owner, name, wrapper)
timed(_lazy.LazyKernels, "__getattr__", "_kernels imports")
timed(cli, "load_scenario", "load_scenario")
timed(scenario_robot, "load_robot", "load_robot")
timed(cli, "simulate", "simulate")
timed(run_output.RunOutput, "save", "write result.npz, summary.json")
run = cli.main
def timed_main(argv=None):
    t0 = time.perf_counter()
    status = run(["run", "scenarios/paper_contact.toml", "--set", "sim.duration=0.01",
                  "--out", sys.argv[1], "--quiet"])
    add("main", t0)
    import json
    acc["start to first statement"] = T["start"] - spawned
    acc["kernels loaded"] = loads[1]
    acc["main returned (wall clock)"] = time.time()
    print(json.dumps(acc), flush=True)
    return status
cli.main = timed_main  # the console script's function (argv[3]) calls it
sys.exit(getattr(cli, sys.argv[3])())
"""


def console_script(tree: Path) -> tuple[str, str]:
    """(module, function) of ``tree``'s ``hybrid-force`` console script (its pyproject.toml)."""
    scripts = tomllib.loads((tree / "pyproject.toml").read_text())["project"]["scripts"]
    module, _, function = scripts["hybrid-force"].partition(":")
    return module, function


def phases(tree: Path, out: Path, env: dict[str, str]) -> dict[str, float]:
    """One run of A with :data:`PHASES`' timers: seconds per phase (exclusive where nested)."""
    spawned = time.time()
    done = subprocess.run(
        [sys.executable, "-c", PHASES, str(out), repr(spawned), console_script(tree)[1]],
        env=env, cwd=tree, capture_output=True, text=True,
    )  # fmt: skip
    ended = time.time()
    if done.returncode != 0:
        raise SystemExit(f"the phases run failed ({done.returncode}):\n{done.stderr}")
    t = json.loads(done.stdout.splitlines()[-1])
    numba = t.get("numba import and set-up (first jit)", 0.0)
    kernels = t.get("_kernels imports", 0.0)
    loads = t.get("kernel cache loads", 0.0)
    robot = t.get("load_robot", 0.0)
    return {
        "start (interpreter, site)": t["start to first statement"],
        "import numpy, pinocchio": t["import numpy, pinocchio"],
        "import hybrid_force.cli": t["import hybrid_force.cli (after numpy, pinocchio)"],
        "load_scenario: load_robot": robot,
        "load_scenario: the rest": t["load_scenario"] - robot,
        "numba import and set-up": numba,
        "_kernels modules (their jit)": kernels - numba,
        "kernel cache loads": loads,
        "kernels loaded": t["kernels loaded"],
        "simulate: the rest (10 steps)": t["simulate"] - kernels - loads,
        "write result.npz, summary.json": t["write result.npz, summary.json"],
        "main: the rest": t["main"]
        - t["load_scenario"]
        - t["simulate"]
        - t["write result.npz, summary.json"],
        "exit after main": ended - t["main returned (wall clock)"],
        "total (wall)": ended - spawned,
    }


def measure_phases(trees: list[Path], runs: int, bytecode: str) -> dict[str, Any]:
    """``runs`` timed runs of A per tree, the trees in turn, after one untimed run of each."""
    envs = {tree: _environment(tree, bytecode) for tree in trees}
    rows: dict[Path, list[dict[str, float]]] = {tree: [] for tree in trees}
    with tempfile.TemporaryDirectory(prefix="bench_fixed_") as tmp:
        for tree in trees:
            phases(tree, Path(tmp) / "out", envs[tree])
        for _ in range(runs):
            for tree in trees:
                rows[tree].append(phases(tree, Path(tmp) / "out", envs[tree]))
    names = list(rows[trees[0]][0])
    medians = {
        str(tree): {n: statistics.median(r[n] for r in rows[tree]) for n in names} for tree in trees
    }
    width = max(len(n) for n in names)
    print(f"{'phase (median of ' + str(runs) + ' runs) [s]':<{width}}  " + "  ".join(
        f"{tree.name:>10}" for tree in trees))  # fmt: skip
    for n in names:
        cells = [medians[str(tree)][n] for tree in trees]
        text = [f"{c:10.0f}" if n == "kernels loaded" else f"{c:10.3f}" for c in cells]
        print(f"{n:<{width}}  " + "  ".join(text))
    return {"runs": runs, "bytecode": bytecode, "medians": medians, "loadavg": os.getloadavg()}


def _environment(tree: Path, bytecode: str) -> dict[str, str]:
    """The children's environment for ``tree``; with ``cached``, the tree byte-compiled."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    if bytecode == "cached":
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        subprocess.run(
            [sys.executable, "-m", "compileall", "-q", str(tree / "hybrid_force")], check=True
        )
    return env


def measure(tree: Path, runs: int, bytecode: str = "cached") -> dict[str, Any]:
    """``runs`` pairs (command, baseline) in turn, after one untimed run of each."""
    env = _environment(tree, bytecode)
    with tempfile.TemporaryDirectory(prefix="bench_fixed_") as tmp:
        module, function = console_script(tree)
        entry = f"import sys; from {module} import {function}; sys.exit({function}())"
        command = [sys.executable, "-c", entry, "run", str(tree / "scenarios/paper_contact.toml")]
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


def measure_interleaved(trees: list[Path], runs: int, bytecode: str) -> dict[str, Any]:
    """``runs`` rounds, each A of every tree followed by its B (A1 B A2 B ...), after one
    untimed run of each: per tree the ratio A/B of each pair, and each tree's A over the first
    tree's A of the same round (the trees paired, not only each against its baseline)."""
    envs = {tree: _environment(tree, bytecode) for tree in trees}
    with tempfile.TemporaryDirectory(prefix="bench_fixed_") as tmp:
        commands = {}
        for tree in trees:
            module, function = console_script(tree)
            entry = f"import sys; from {module} import {function}; sys.exit({function}())"
            commands[tree] = [sys.executable, "-c", entry, "run"]
            commands[tree] += [str(tree / "scenarios/paper_contact.toml"), "--set"]
            commands[tree] += ["sim.duration=0.01", "--out", str(Path(tmp) / "out")]
            _timed(commands[tree], envs[tree], tree)
            _timed(BASELINE, envs[tree], tree)
        load = [list(os.getloadavg())]
        pairs: dict[Path, list[tuple[tuple[float, float], tuple[float, float]]]] = {
            tree: [] for tree in trees
        }
        for _ in range(runs):
            for tree in trees:
                a = _timed(commands[tree], envs[tree], tree)
                pairs[tree].append((a, _timed(BASELINE, envs[tree], tree)))
        load.append(list(os.getloadavg()))
    first = trees[0]
    out: dict[str, Any] = {"runs": runs, "bytecode": bytecode, "loadavg": load, "trees": {}}
    for tree in trees:
        row: dict[str, Any] = {}
        for k, kind in enumerate(("wall", "cpu")):
            over_b = [a[k] / b[k] for a, b in pairs[tree]]
            over_first = [p[0][k] / q[0][k] for p, q in zip(pairs[tree], pairs[first], strict=True)]
            row[f"ratio_{kind}"] = [statistics.median(over_b), min(over_b), max(over_b)]
            row[f"over_first_{kind}"] = statistics.median(over_first)
            row[f"command_{kind}_s"] = [a[k] for a, _ in pairs[tree]]
            row[f"baseline_{kind}_s"] = [b[k] for _, b in pairs[tree]]
        out["trees"][str(tree)] = row
    la, lb = load
    print(
        f"{runs} rounds, trees interleaved (load {la[0]:.2f} -> {lb[0]:.2f}), bytecode {bytecode}:"
    )
    for tree in trees:
        row = out["trees"][str(tree)]
        print(f"  {tree}:")
        for kind in ("wall", "cpu"):
            m, lo, hi = row[f"ratio_{kind}"]
            print(
                f"    command / baseline, {kind}: median {m:.2f} (min {lo:.2f}, max {hi:.2f});"
                f" command / {first.name}'s command: median {row[f'over_first_{kind}']:.2f}"
            )
    return out


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
    parser.add_argument(
        "--phases", type=int, default=0, metavar="N",
        help="instead: N runs of the command per tree with a timer around each phase",
    )  # fmt: skip
    parser.add_argument(
        "--interleave", action="store_true",
        help="with several --tree: every round runs each tree's command and a baseline in "
        "turn (A1 B A2 B ...), and reports each tree's command over the first tree's, paired",
    )  # fmt: skip
    args = parser.parse_args(argv)
    trees = [t.resolve() for t in args.tree] if args.tree else [ROOT]
    if args.interleave:
        table = measure_interleaved(trees, args.runs, args.bytecode)
        if args.json is not None:
            args.json.write_text(json.dumps(table, indent=1) + "\n")
        return 0
    if args.phases:
        table = measure_phases(trees, args.phases, args.bytecode)
        if args.json is not None:
            args.json.write_text(json.dumps(table, indent=1) + "\n")
        return 0
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

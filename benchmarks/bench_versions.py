"""Steps per second of one scenario under two source trees, alternating, in one run.

Run from the repository root, with a checkout of the older commit beside it:

    git worktree add /tmp/old <commit>
    python benchmarks/bench_versions.py /tmp/old . [--scenario paper_contact] [--rounds 9]

Each round runs the scenario (``sim.duration`` = 10 s by default) once in a fresh process per
tree, old then new then old ... (the order flips every round), and reads the loop's own
``meta["steps_per_second"]`` (kernels loaded, start-up excluded). Prints each tree's median and
the ratio new / old of the medians, and the median of the per-round ratios (the two runs of a
round are close in time, so a shared machine's load moves that ratio less). Not a test.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

_CHILD = """
import sys, warnings
import hybrid_force
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    sc = load_scenario(sys.argv[1], {"sim.duration": float(sys.argv[2])})
    simulate(sc)  # warm: the kernels load (or compile) once per process
    print(hybrid_force.__file__, simulate(sc).meta["steps_per_second"])
"""


def _rate(tree: Path, scenario: Path, duration: float) -> float:
    """steps/s of one run in a fresh process importing the package of ``tree``.

    The child runs in ``tree``: ``python -c`` puts its working directory first on sys.path,
    before PYTHONPATH, so a child started in another checkout would import that one's package
    (and an editable install's path comes after both). The child names the package it ran.
    """
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, str(scenario), str(duration)],
        env=env, cwd=tree, capture_output=True, text=True, check=True,
    )  # fmt: skip
    package, rate = out.stdout.split()[-2:]
    if not Path(package).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"the run for {tree} imported {package}, not the tree's package")
    return float(rate)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", type=Path, help="source tree of the older version")
    parser.add_argument("new", type=Path, help="source tree of the newer version")
    parser.add_argument("--scenario", default="paper_contact")
    parser.add_argument("--duration", type=float, default=10.0, help="simulated s (10)")
    parser.add_argument("--rounds", type=int, default=9)
    args = parser.parse_args()
    old, new = args.old.resolve(), args.new.resolve()
    scenario = new / "scenarios" / f"{args.scenario}.toml"
    rates: dict[str, list[float]] = {"old": [], "new": []}
    for r in range(args.rounds):
        order = (("old", old), ("new", new)) if r % 2 == 0 else (("new", new), ("old", old))
        for name, tree in order:
            rates[name].append(_rate(tree, scenario, args.duration))
    m_old, m_new = statistics.median(rates["old"]), statistics.median(rates["new"])
    paired = statistics.median(n / o for n, o in zip(rates["new"], rates["old"], strict=True))
    print(f"{args.scenario}, {args.rounds} rounds of {args.duration:g} s")
    print(f"  old {old}: median {m_old:,.0f} steps/s")
    print(f"  new {new}: median {m_new:,.0f} steps/s")
    print(f"  new / old: {m_new / m_old:.3f} of the medians, {paired:.3f} paired median")


if __name__ == "__main__":
    main()

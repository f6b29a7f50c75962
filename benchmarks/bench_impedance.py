"""Steps per second of the ``impedance`` law, compiled and numpy, against ``arimoto`` (issue 32).

Run from the repository root:

    python benchmarks/bench_impedance.py [--repeats N]

For scenarios/paper_contact.toml and scenarios/ur5_plane.toml (``control.law`` set, 2 s runs):
``meta["steps_per_second"]`` (the stepping loop only) of arimoto, of impedance with its numpy
oracle (ImpedanceLaw of tests/oracles/laws.py: the law as it was before its kernel) and of the
compiled impedance law, run alternately in this one process, after a short warm-up run of
each. Prints each one's best of N rounds (default 3) and its ratio to arimoto's best, and, in
brackets, the median over the rounds of its ratio to arimoto in the same round (the three runs
of a round are close in time, so a shared machine's load moves that ratio less). Not part of
the test suite.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import warnings
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import hybrid_force.control.laws.impedance as impedance  # noqa: E402
from hybrid_force import simulate  # noqa: E402
from hybrid_force.scenario.loader import load_scenario  # noqa: E402

sys.path.insert(0, str(ROOT / "tests"))
from oracles.laws import ImpedanceLaw  # noqa: E402  (the numpy oracle of the tests)

_BUILD = impedance.build
_COMPILED = impedance.ImpedanceWorkspace


def _reference_build(context: Any) -> Any:
    impedance.ImpedanceWorkspace = ImpedanceLaw  # type: ignore[misc]
    try:
        return _BUILD(context)
    finally:
        impedance.ImpedanceWorkspace = _COMPILED  # type: ignore[misc]


VARIANTS = {
    "arimoto": ("arimoto", _BUILD),
    "impedance (numpy)": ("impedance", _reference_build),
    "impedance (compiled)": ("impedance", _BUILD),
}


def _rate(name: str, law: str, build: Any, duration: float) -> float:
    impedance.build = build  # type: ignore[assignment]
    try:
        sc = load_scenario(ROOT / "scenarios" / f"{name}.toml", {
            "control.law": law, "sim.duration": duration,
        })  # fmt: skip
        return float(simulate(sc).meta["steps_per_second"])
    finally:
        impedance.build = _BUILD


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    warnings.simplefilter("ignore")  # the runs' effort-limit notes
    for name in ("paper_contact", "ur5_plane"):
        for law, build in VARIANTS.values():
            _rate(name, law, build, 0.05)  # warm-up: compile or load the kernels
        rounds = [
            {label: _rate(name, law, build, 2.0) for label, (law, build) in VARIANTS.items()}
            for _ in range(args.repeats)
        ]
        base = max(r["arimoto"] for r in rounds)
        cells = []
        for label in VARIANTS:
            best = max(r[label] for r in rounds)
            median = statistics.median(r[label] / r["arimoto"] for r in rounds)
            cells.append(f"{label} {best:6.0f}/s {best / base:.2f}x [{median:.2f}x]")
        print(f"{name:14s} " + "   ".join(cells), flush=True)


if __name__ == "__main__":
    main()

"""Steps per second of the raibert_craig law, compiled and numpy, against arimoto (issue 32).

Run from the repository root:

    python benchmarks/bench_raibert_craig.py [--reps 3] [--duration 2.0]

For paper_contact and ur5_plane, in one process: a run of each case first (compilation, caches),
then ``reps`` rounds that run ``arimoto``, ``raibert_craig`` (compiled:
``RaibertCraigWorkspace``) and ``raibert_craig`` with its numpy oracle (tests/oracles/laws.py)
(``RaibertCraigLaw`` in the compiled loop) one after the other; the best ``steps_per_second``
of each case and its ratio to arimoto's are printed. The machine's load moves the numbers;
the ratios, measured alternating, move less.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import hybrid_force.control.laws.raibert_craig as rc
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from oracles.laws import RaibertCraigLaw

_SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
_CASES = (("arimoto", "arimoto", False), ("raibert_craig", "raibert_craig", False))
_NUMPY = ("raibert_craig numpy", "raibert_craig", True)


def _run(name: str, law: str, numpy: bool, duration: float) -> float:
    sc = load_scenario(
        _SCENARIOS / f"{name}.toml", overrides={"control.law": law, "sim.duration": duration}
    )
    compiled = rc.RaibertCraigWorkspace
    if numpy:
        setattr(rc, "RaibertCraigWorkspace", RaibertCraigLaw)  # noqa: B010
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the UR5's first torque reaches its effort limit
            return float(simulate(sc).meta["steps_per_second"])
    finally:
        setattr(rc, "RaibertCraigWorkspace", compiled)  # noqa: B010


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=3)
    parser.add_argument("--duration", type=float, default=2.0, help="simulated time [s]")
    args = parser.parse_args()
    cases = (*_CASES, _NUMPY)
    for name in ("paper_contact", "ur5_plane"):
        for _, law, numpy in cases:
            _run(name, law, numpy, 0.05)
        best = dict.fromkeys((label for label, _, _ in cases), 0.0)
        for _ in range(args.reps):
            for label, law, numpy in cases:
                best[label] = max(best[label], _run(name, law, numpy, args.duration))
        base = best["arimoto"]
        shown = "  ".join(f"{k}: {v / 1e3:.2f}k ({v / base:.2f}x)" for k, v in best.items())
        print(f"{name}: {shown}", flush=True)


if __name__ == "__main__":
    main()

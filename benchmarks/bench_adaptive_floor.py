"""The adaptive law's Pinocchio floor against the paper's law's step (issue 32).

Run from the repository root:

    python benchmarks/bench_adaptive_floor.py [--case ur5] [--runs 5]

``arimoto_adaptive`` makes three joint-torque regressor passes and one kinetic-energy regressor
pass a step (``hybrid_force/control/laws/_arimoto_adaptive_kernels.py``). This times each of
those Pinocchio calls alone on the case's controller model (best of 15 batches of 20,000), and
the calls that could stand in for one (rnea; writing θ̂ into the model's inertias, which an
rnea with the estimates would need), then runs the paper's law on the same case (``--runs``
runs of 2 s, bench_loop's case, best) and reports the bound

    arimoto step / (arimoto step + the passes)

that the adaptive law's steps/s cannot exceed, relative to arimoto's, whatever the rest costs.
Not part of the test suite.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))


def main(argv: list[str] | None = None) -> int:
    import bench_loop

    from hybrid_force.model.regressor import SlotineLiRegressor, dynamic_parameters
    from hybrid_force.scenario.loader import read_scenario_document, scenario_from_document

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="ur5", choices=sorted(bench_loop.LAW_CASES))
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args(argv)

    name, overrides = bench_loop.LAW_CASES[args.case]
    path = ROOT / name
    doc = read_scenario_document(path, {**overrides, "control.law": "arimoto"})
    robot = scenario_from_document(doc, origin=str(path), base_dir=path.parent).robot
    reg = SlotineLiRegressor(robot.model)
    model, data, model0 = reg.model, reg.data, reg.model0
    rng = np.random.default_rng(0)
    q = pin.neutral(model) + rng.uniform(-1.0, 1.0, model.nq) * (model.nq == model.nv)
    v, a = rng.normal(size=model.nv), rng.normal(size=model.nv)
    theta = dynamic_parameters(model)
    inertias, build = model0.inertias, pin.Inertia.FromDynamicParameters

    def write_inertias() -> None:
        for j in range(1, model.njoints):
            inertias[j] = build(theta[10 * (j - 1) : 10 * j])

    rows = {
        "computeJointTorqueRegressor (gravity)": lambda: pin.computeJointTorqueRegressor(
            model, data, q, v, a
        ),
        "computeJointTorqueRegressor (no gravity)": lambda: pin.computeJointTorqueRegressor(
            model0, data, q, v, a
        ),
        "computeKineticEnergyRegressor": lambda: pin.computeKineticEnergyRegressor(
            model0, data, q, v
        ),
        "rnea": lambda: pin.rnea(model, data, q, v, a),
        "forwardKinematics (q, v, a)": lambda: pin.forwardKinematics(model, data, q, v, a),
        f"the {model.njoints - 1} links' inertias from θ̂": write_inertias,
    }
    # best of 15 batches of 20,000 calls, after 500 (bench_loop's timer)
    times = {label: bench_loop._best_us(call, 500, 20_000, 15) for label, call in rows.items()}
    passes = (
        times["computeJointTorqueRegressor (gravity)"]
        + 2 * times["computeJointTorqueRegressor (no gravity)"]
        + times["computeKineticEnergyRegressor"]
    )
    rates = [bench_loop._law_run(args.case, "arimoto", 2.0) for _ in range(args.runs + 1)][1:]
    best = max(r["steps_per_second"] for r in rates)
    step = 1e6 / best
    print(f"case {args.case} (nv = {model.nv}), load {os.getloadavg()[0]:.2f}")
    for label, us in times.items():
        print(f"  {label:44s} {us:6.2f} µs")
    print(f"  the adaptive law's passes (3 regressors + 1 kinetic energy) {passes:6.2f} µs a step")
    print(f"  arimoto: {best:,.0f} steps/s (best of {args.runs} runs of 2 s), {step:.1f} µs a step")
    print(f"  bound on arimoto_adaptive / arimoto: {step / (step + passes):.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

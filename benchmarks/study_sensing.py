"""Study: the paper's section 6.3 run when the controller sees only its sensors.

Runs scenarios/paper_contact.toml (10 s) with a sampled controller and prints, in Markdown, the
RMS and the largest error after settling (t ≥ 5 s) of the TRUE contact force |f − f_d| and of
the tip position ‖p − p_d‖ for:

* ideal sensing (the exact loop, the reference);
* a 1 kHz controller on a 10 kHz plant;
* the force measured one and two control periods late;
* white force noise σ = 0.1, 0.5, 2 N through a 50 Hz first-order low-pass (seed 0);
* a 1 N force bias;

and a second table: β at 0.7, 0.9 and 1.1 of the loader's stability bound
(:mod:`hybrid_force.control.force_loop`) for the force read one period late, and for a 50 Hz
low-pass without delay, with the largest |f − f_d| over the last second of a 3 s run (through
the Python API: the loader refuses β beyond the bound).

Run from the repository root:

    python benchmarks/study_sensing.py

Not part of the test suite (the tests check the targets on shorter runs).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from hybrid_force import simulate
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.sensors import SensorSettings

CASES: tuple[tuple[str, dict[str, Any], dict[str, Any]], ...] = (
    ("ideal sensing, 1 kHz", {}, {}),
    ("controller 1 kHz, plant 10 kHz", {"sim.dt": 1e-4, "control.rate": 1000.0}, {}),
    ("force 1 period late", {}, {"force_delay": 1}),
    ("force 2 periods late", {}, {"force_delay": 2}),
    ("force noise σ = 0.1 N, 50 Hz low-pass", {}, {"force_noise": 0.1, "force_cutoff": 50.0}),
    ("force noise σ = 0.5 N, 50 Hz low-pass", {}, {"force_noise": 0.5, "force_cutoff": 50.0}),
    ("force noise σ = 2 N, 50 Hz low-pass", {}, {"force_noise": 2.0, "force_cutoff": 50.0}),
    ("force bias 1 N", {}, {"force_bias": 1.0}),
)


def main() -> None:
    print(
        "| case | RMS \\|f − f_d\\| [N] | max \\|f − f_d\\| [N] | RMS ‖p − p_d‖ [m] "
        "| max ‖p − p_d‖ [m] |"
    )
    print("|---|---|---|---|---|")
    for label, overrides, sensor in CASES:
        scenario = load_scenario(
            "scenarios/paper_contact.toml", {"sim.duration": 10.0, **overrides}
        )
        scenario = dataclasses.replace(scenario, sensor=SensorSettings(**sensor))
        result = simulate(scenario)
        late = result.t >= 5.0
        ef = np.abs(result.f - result.f_d)[late]
        ep = np.linalg.norm(result.p - result.p_d, axis=1)[late]
        print(
            f"| {label} | {np.sqrt(np.mean(ef**2)):.2g} | {ef.max():.2g} | "
            f"{np.sqrt(np.mean(ep**2)):.2g} | {ep.max():.2g} |"
        )


def bound_study() -> None:
    from hybrid_force.control.force_loop import beta_bound, inverse_effective_mass

    print()
    print("| sensor | β / bound | β | max \\|f − f_d\\| over t ≥ 2 s [N] | events |")
    print("|---|---|---|---|---|")
    for label, sensor, alpha in (
        ("force 1 period late", {"force_delay": 1}, 1.0),
        ("50 Hz low-pass", {"force_cutoff": 50.0}, 1.0 - float(np.exp(-2 * np.pi * 50e-3))),
    ):
        base = load_scenario("scenarios/paper_contact.toml", {"sim.duration": 3.0})
        base = dataclasses.replace(base, sensor=SensorSettings(**sensor))
        w = inverse_effective_mass(base.robot, base.surfaces, [base.q0], "tip")
        bound = beta_bound(w, 1.0, alpha, sensor.get("force_delay", 0))
        for fraction in (0.7, 0.9, 1.1):
            control = dataclasses.replace(base.control, beta=fraction * bound)
            result = simulate(dataclasses.replace(base, control=control))
            late = result.t >= 2.0
            error = float(np.abs(result.f - result.f_d)[late].max())
            kinds = sorted({e["kind"] for e in result.events})
            print(
                f"| {label} | {fraction} | {fraction * bound:.3g} | {error:.2g} | "
                f"{', '.join(kinds)} |"
            )


if __name__ == "__main__":
    main()
    bound_study()

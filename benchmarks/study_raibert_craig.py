"""Study: the raibert_craig law on the shipped scenarios, and where the original form fails.

Prints four Markdown tables (numbers quoted in docs/laws_raibert_craig.md):

1. every shipped contact scenario (its own duration, settled from t = 5 s): the largest
   position error ‖p − p_d‖ and force error |f − f_d| after settling, and the events (impacts,
   releases), for the default law (corrected, with the projection P), the original with P, the
   two published forms (decouple = false), the 1981 feed-forward (gravity only) and the
   default sampled at 500 Hz with 0.1 N force noise; arimoto for comparison;
2. the contact vibration's growth rate σ [1/s] along the steep-plane run (gains set at the
   folded start, the arm stretched out step by step): the energy balance of
   hybrid_force.studies.hybrid_stability (eq. 1) and the closed loop linearised by central
   differences (contact 1e8 N/m), for the four combinations;
3. the steep-plane run itself (compliant contact 1e6 N/m, 6 s): the largest |f − f_d| in
   each second, the run's status, and where the force first left f_d by more than 1 N;
4. the growth rate at the stretched-out configuration when the plant carries 5 kg more on
   link 3, 0.1 m further out, than the controller's model (a tool the model lacks).

Run from the repository root (about 5 minutes on 2 shared cores):

    python benchmarks/study_raibert_craig.py
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from hybrid_force import simulate
from hybrid_force.errors import RunFailedError
from hybrid_force.model.loading import load_robot
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.studies.hybrid_stability import (
    FOLDED,
    STEEP_NORMAL,
    closed_loop_matrix,
    contact_mode_growth,
    steep_plane_scenario,
)

SCENARIOS = ("paper_contact", "paper_approach", "rtr_plane", "rtr_sphere", "ur5_plane")
LAW = "control.raibert_craig"
CASES: tuple[tuple[str, dict[str, Any]], ...] = (
    ("default (corrected, P)", {}),
    ("original, P", {f"{LAW}.form": "original"}),
    ("corrected, published", {f"{LAW}.decouple": False}),
    ("original, published", {f"{LAW}.form": "original", f"{LAW}.decouple": False}),
    ("default, gravity only", {f"{LAW}.feedforward": "gravity"}),
    ("default, 500 Hz, 0.1 N noise", {"sensor.force_noise": 0.1, "control.rate": 500.0}),
)
COMBOS = tuple(
    (f"{form}, {'P' if decouple else 'published'}", {"form": form, "decouple": decouple})
    for form in ("original", "corrected")
    for decouple in (False, True)
)


def _run(scenario: Any) -> tuple[Any, str]:
    """The result (also of a failed run) and its status."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return simulate(scenario), "ok"
        except RunFailedError as exc:
            return exc.result, f"failed ({exc.result.meta.get('reason') if exc.result else '?'})"


def scenario_table() -> None:
    print("| scenario | case | max ‖p − p_d‖ [m] | max \\|f − f_d\\| [N] | events |")
    print("|---|---|---|---|---|")
    for name in SCENARIOS:
        cases = (*((f"{label}", {"control.law": "raibert_craig", **o}) for label, o in CASES),
                 ("arimoto", {}))  # fmt: skip
        for label, overrides in cases:
            result, status = _run(load_scenario(f"scenarios/{name}.toml", overrides))
            m = result.metrics()
            kinds = [e["kind"] for e in result.events if e["kind"] in ("impact", "release")]
            speeds = [e["speed"] for e in result.events if e["kind"] == "impact"]
            events = ", ".join(f"{kinds.count(k)} {k}" for k in sorted(set(kinds)))
            if speeds:
                events += f" (max {max(speeds):.2g} m/s)"
            position, force = m.position_error_max_settled, m.force_error_max_settled
            print(
                f"| {name} | {label} | {position:.2g} | {force:.2g} | "
                f"{events or '-'}{'' if status == 'ok' else ', ' + status} |"
            )


def growth_table() -> None:
    robot = load_robot("rtr")
    print()
    print("| q₃ [rad] | tip from column [m] | " + " | ".join(c for c, _ in COMBOS) + " |")
    print("|---|---|" + "---|" * len(COMBOS))
    for q3 in (2.094, 1.6, 1.2, 0.9, 0.7, 0.6, 0.5, 0.45):
        q = np.array([0.0, 5.0, q3])
        cells = []
        for _, options in COMBOS:
            jacobian, ctrl = closed_loop_matrix(robot, q, FOLDED, STEEP_NORMAL, options, 1e8)
            eig = np.linalg.eigvals(jacobian)
            fast = eig[np.argmax(np.abs(eig.imag))].real
            gains = ctrl.law.gains  # type: ignore[attr-defined]
            sigma = contact_mode_growth(
                gains, robot.mass_matrix(q), robot.jacobian(q), STEEP_NORMAL
            )
            cells.append(f"{sigma:+.1f} / {fast:+.1f}")
        print(f"| {q3} | {0.9 + np.cos(q3):.2f} | " + " | ".join(cells) + " |")


def steep_plane_table() -> None:
    robot = load_robot("rtr")
    print()
    print(
        "| case | status | max \\|f − f_d\\| in s 0–1, 1–2, … 5–6 [N] | first > 1 N after 0.5 s |"
    )
    print("|---|---|---|---|")
    for label, options in COMBOS:
        result, status = _run(steep_plane_scenario(options, robot=robot))
        error = np.abs(result.f - 10.0)
        per_second = [
            f"{error[(result.t >= s) & (result.t < s + 1)].max():.2g}"
            for s in range(6)
            if np.any((result.t >= s) & (result.t < s + 1))
        ]
        late = np.flatnonzero((error > 1.0) & (result.t > 0.5))
        onset = "-"
        if late.size:
            i = late[0]
            onset = (
                f"t = {result.t[i]:.2f} s, q₃ = {result.q[i, 2]:.2f} rad, "
                f"{np.hypot(*result.p[i, :2]):.2f} m out"
            )
        print(f"| {label} | {status} | {', '.join(per_second)} | {onset} |")


def model_error_table() -> None:
    model = load_robot("rtr")
    text = Path("robots/rtr.urdf").read_text()
    link3 = '<origin xyz="0.5 0 0" rpy="0 0 0"/>\n      <mass value="20"/>'
    assert link3 in text
    heavier = text.replace(link3, '<origin xyz="0.6 0 0" rpy="0 0 0"/>\n      <mass value="25"/>')
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "rtr_with_tool.urdf"
        path.write_text(heavier)
        plant = load_robot(path, tip="tip")
    print()
    print("| q₃ [rad] | " + " | ".join(c for c, _ in COMBOS) + " |")
    print("|---|" + "---|" * len(COMBOS))
    for q3 in (2.094, 1.2, 0.7, 0.5, 0.4):
        q = np.array([0.0, 5.0, q3])
        cells = []
        for _, options in COMBOS:
            jacobian, _ = closed_loop_matrix(
                model, q, FOLDED, STEEP_NORMAL, options, 1e8, plant=plant
            )
            eig = np.linalg.eigvals(jacobian)
            cells.append(f"{eig[np.argmax(np.abs(eig.imag))].real:+.1f}")
        print(f"| {q3} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    scenario_table()
    growth_table()
    steep_plane_table()
    model_error_table()

"""The study of docs/laws.md: every registered law on the same arms, surfaces and sensors.

Runs ``hybrid_force.studies.compare.run_compare`` (what ``hybrid-force compare`` runs) on

* table 1, ideal sensing, rigid contact: the flat obstacle of the authors' earlier comparison
  on the RTR (scenarios/rtr_plane.toml) and on a 7-joint Panda
  (benchmarks/scenarios/panda_plane.toml), the paper's cylinder (section 6.3, 6.4), and
  section 6.3 with the controller's masses 10 % low (``sim.model_mass_factor = 0.9``);
  the published "classic" Raibert-Craig form (``form = "original"``, ``decouple = false``) is
  added as its own row;
* table 2, the same with a real sensor and friction: force noise σ = 0.1 N, a 500 Hz
  controller, Coulomb friction μ = 0.3 (``contact.friction``, regularised over 2 mm/s);

and prints the two tables as Markdown (the numbers of docs/laws.md), with the raw rows as JSON
in ``--out`` (default runs/study_laws). About 10 min on 2 cores::

    python benchmarks/study_laws.py [--workers 2] [--out runs/study_laws]
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

from hybrid_force.studies.compare import run_compare

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "RTR, plane": ("scenarios/rtr_plane.toml", {}),
    "Panda, plane": ("benchmarks/scenarios/panda_plane.toml", {}),
    "RTR, cylinder (6.3)": ("scenarios/paper_contact.toml", {}),
    "RTR, cylinder approach (6.4)": ("scenarios/paper_approach.toml", {}),
    "RTR, cylinder (6.3), masses -10 %": (
        "scenarios/paper_contact.toml",
        {"sim.model_mass_factor": 0.9},
    ),
}
REAL = {
    "sensor.force_noise": 0.1,
    "control.rate": 500.0,
    "contact.friction": 0.3,
    "contact.friction_velocity": 2e-3,  # ε: at 1e-3 m/s the Panda would need dt < 0.6 ms
}
CLASSIC = {"control.raibert_craig.form": "original", "control.raibert_craig.decouple": False}
SHOWN = (
    ("force_error_rms_settled", "RMS |f−f_d| [N]"),
    ("force_error_max_settled", "max |f−f_d| [N]"),
    ("impact_force_peak", "peak f at impact [N]"),
    ("path_error_rms_settled", "RMS path error [m]"),
    ("path_error_max_settled", "max path error [m]"),
    ("out_of_contact_fraction", "time off"),
    ("time_to_settle", "settle [s]"),
    ("torque_max", "max |u|"),
)


def _rows(
    scenario: str, overrides: dict, out: Path, workers: int, laws: list[str] | None = None
) -> list[dict]:
    table = run_compare(
        ROOT / scenario,
        laws,
        out_dir=out,
        overrides=overrides,
        workers=workers,
        progress=False,
        figures=False,
    )
    with open(table, newline="") as f:
        return list(csv.DictReader(f))


def _cell(row: dict, key: str) -> str:
    if row["status"] != "ok":
        return row["status"] if key == SHOWN[0][0] else ""
    text = row.get(key, "")
    return "" if text in ("", "None") else f"{float(text):.3g}"


def _table(title: str, cases: dict[str, list[dict]]) -> str:
    lines = [f"**{title}**", "", "| case | law | " + " | ".join(h for _, h in SHOWN) + " |"]
    lines.append("|" + "---|" * (len(SHOWN) + 2))
    for case, rows in cases.items():
        for row in rows:
            cells = " | ".join(_cell(row, key) for key, _ in SHOWN)
            lines.append(f"| {case} | {row['law']} | {cells} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("runs/study_laws"))
    args = parser.parse_args()
    raw: dict[str, dict[str, list[dict]]] = {}
    for label, extra in (("ideal sensing, rigid contact", {}), ("sensor and friction", REAL)):
        cases: dict[str, list[dict]] = {}
        for i, (case, (scenario, overrides)) in enumerate(CASES.items()):
            out = args.out / ("real" if extra else "ideal") / f"case{i}"
            rows = _rows(scenario, {**overrides, **extra}, out, args.workers)
            classic = _rows(
                scenario, {**overrides, **extra, **CLASSIC}, out / "classic", 1, ["raibert_craig"]
            )
            classic[0]["law"] = "raibert_craig (published original)"
            cases[case] = rows + classic
        raw[label] = cases
        print(_table(label, cases), end="\n\n", flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "study_laws.json").write_text(json.dumps(raw, indent=1))


if __name__ == "__main__":
    main()

"""'ok' means it happened (issue 27, class 5): what a run did not do as asked is reported,
measured, through one channel: summary.json["warnings"] (one line each), stderr (one line
each, no source excerpt), the summary's n_warnings/touched/chatter/force_settled and the
sweep row's columns of the same names."""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from hybrid_force import simulate
from hybrid_force.cli import main
from hybrid_force.errors import RunWarning
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.run_checks import CHATTER_PAIRS, run_behaviour, warning_notes

ROOT = Path(__file__).resolve().parents[1]
PLANE = ROOT / "scenarios" / "rtr_plane.toml"
CONTACT = ROOT / "scenarios" / "paper_contact.toml"

# osc_hybrid on rtr_plane with a controller model twice the plant's: the doubled gravity
# compensation lifts the tool, which never reaches the plane
NEVER_TOUCHES = ("control.law=osc_hybrid", "sim.model_mass_factor=2.0", "sim.duration=1.0")
# plain impedance (no force tracking) on a compliant plane: two springs in series, the force
# stays at f_d k_e / (k_e + k_n) ≈ 6.5 N for f_d = 10 N
OFFSET = (
    "control.law=impedance", "control.impedance.force_tracking=false",
    "contact.model=compliant", "contact.stiffness=5e4", "sim.duration=2.0",
)  # fmt: skip


def _cli(
    capsys: pytest.CaptureFixture[str], out: Path, scenario: Path, sets: tuple[str, ...]
) -> tuple[int, dict, str]:
    args = ["run", str(scenario), "--quiet", "--out", str(out)]
    for s in sets:
        args += ["--set", s]
    with warnings.catch_warnings():
        warnings.simplefilter("always", RunWarning)
        code = main(args)
    err = capsys.readouterr().err
    return code, json.loads((out / "summary.json").read_text()), err


def test_behaviour_from_a_recorded_trajectory() -> None:
    """Chatter counts releases each followed by a touch after the force first settled."""
    t = np.linspace(0.0, 1.0, 101)
    contact = np.ones(101, dtype=bool)
    contact[[30, 31, 50, 60, 70]] = False  # four releases, each touched again
    f = np.where(contact, 10.0, 0.0)[:, None]
    flags, notes = run_behaviour(t, f, np.array([10.0]), np.zeros((101, 1)), contact)
    assert flags == {"touched": True, "chatter": 4, "force_settled": True}
    assert CHATTER_PAIRS <= 4 and notes == [
        "the tool chattered on the surface: 4 releases and re-touches between t = 0.3 s and "
        "t = 0.71 s, after the force first settled at t = 0 s"
    ]
    contact[:] = True
    flags, notes = run_behaviour(t, f * 0 + 8.0, np.array([10.0]), np.zeros((101, 1)), contact)
    assert flags["force_settled"] is False and "RMS |f − f_d| = 2 N" in notes[0]


def test_an_approach_that_never_touches_is_reported(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, summary, err = _cli(capsys, tmp_path / "out", PLANE, NEVER_TOUCHES)
    assert code == 0 and summary["status"] == "ok"
    assert summary["touched"] is False and summary["n_warnings"] == len(summary["warnings"]) == 1
    (note,) = summary["warnings"]
    assert note.startswith("the tool never touched the surface: its closest approach was ")
    assert "so f_d = 10 N was never applied" in note
    lines = [x for x in err.splitlines() if "never touched" in x]
    assert lines == [f"warning: run 'rtr_plane': {note}"]


def test_a_force_error_that_never_settles_is_reported(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, summary, err = _cli(capsys, tmp_path / "out", PLANE, OFFSET)
    assert code == 0
    assert summary["touched"] is True and summary["force_settled"] is False
    assert summary["chatter"] == 0
    (note,) = summary["warnings"]
    assert note.startswith("the force error did not settle: RMS |f − f_d| = 3.5")
    assert "over the last 0.4 s (t >= 1.6 s), above the tolerance 1 N" in note
    assert f"warning: run 'rtr_plane': {note}" in err.splitlines()


def test_a_tool_that_chatters_is_reported() -> None:
    """osc_hybrid beyond its sampled force bound (k_P = 1.3 > 1.01, built past the loader)
    with the supervisor: the force oscillation throws the tool off and it lands again."""
    base = load_scenario(
        CONTACT,
        {"control.law": "osc_hybrid", "sensor.force_delay": 1, "sim.duration": 0.5,
         "control.supervisor": True},
    )  # fmt: skip
    options = {"osc_hybrid": {"force_p": 1.3}}
    sc = dataclasses.replace(base, control=dataclasses.replace(base.control, options=options))
    with pytest.warns(RunWarning) as record:
        r = simulate(sc)
    assert any("chattered" in str(w.message) for w in record)
    summary = r.summary()
    assert summary["status"] == "ok" and summary["chatter"] >= CHATTER_PAIRS
    assert any(w.startswith("the tool chattered on the surface: ") for w in summary["warnings"])


class _Warns:
    """A user controller that holds gravity and raises a Python warning at every tick."""

    def __init__(self, robot: object) -> None:
        self.robot = robot

    def command(self, t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray) -> np.ndarray:
        warnings.warn("the model is\n  uncertain here", RuntimeWarning, stacklevel=1)
        return self.robot.gravity(q) - 50.0 * v  # type: ignore[attr-defined]


def test_python_warnings_of_a_run_become_one_line_each_with_their_time() -> None:
    sc = load_scenario(CONTACT, {"sim.duration": 0.01})
    with pytest.warns(RunWarning) as record:
        r = simulate(sc, controller=_Warns(sc.robot))
    notes = [w for w in r.meta["warnings"] if "RuntimeWarning" in w]
    assert notes == ["at t = 0 s (11 times): RuntimeWarning: the model is uncertain here"]
    shown = [str(w.message) for w in record if "RuntimeWarning" in str(w.message)]
    assert shown == [f"run 'paper_contact': {notes[0]}"]  # once, one line, no source line
    assert r.summary()["n_warnings"] == len(r.meta["warnings"])


def test_warning_notes_group_repeats_and_keep_a_message_that_says_its_time() -> None:
    class W:
        def __init__(self, message: str, category: type[Warning]) -> None:
            self.message, self.category = message, category

    caught = [W("x", RuntimeWarning), W("x", RuntimeWarning), W("at t = 2 s it", RunWarning)]
    assert warning_notes(caught, [0.5, 0.7, 2.0]) == [
        "at t = 0.5 s (2 times): RuntimeWarning: x",
        "at t = 2 s it",
    ]


def test_the_sweep_row_has_the_warnings_and_the_flags() -> None:
    from hybrid_force.studies.tasks import run_one

    params = dict(s.split("=", 1) for s in NEVER_TOUCHES)
    values = {k: (2.0 if k == "sim.model_mass_factor" else 1.0 if k == "sim.duration" else v)
              for k, v in params.items()}  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        row = run_one(str(PLANE), values, None)
    assert row["status"] == "ok"
    assert row["n_warnings"] == 1 and row["touched"] is False
    assert "never touched the surface" in row["warnings"]

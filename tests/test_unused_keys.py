"""No setting is silently unused (issue 27, class 6): a key that has no effect in the chosen
configuration is refused (exit 2, naming the file, the key, its value and what would make it
act), a key no configuration reads is warned about and left out; the run's meta records only
the settings the run used."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from hybrid_force.cli import main
from hybrid_force.result import load_result

ROOT = Path(__file__).resolve().parents[1]
CONTACT = ROOT / "scenarios" / "paper_contact.toml"
APPROACH = ROOT / "scenarios" / "paper_approach.toml"


def _run(
    capsys: pytest.CaptureFixture[str], out: Path, *sets: str, scenario: Path = CONTACT
) -> tuple[int, str]:
    args = ["run", str(scenario), "--quiet", "--out", str(out)]
    for s in ("sim.duration=0.02", *sets):
        args += ["--set", s]
    code = main(args)
    return code, capsys.readouterr().err


@pytest.mark.parametrize(
    ("sets", "key", "shown", "needs"),
    [
        (["contact.stiffness=1e5"], "contact.stiffness", "100000.0", 'contact.model = "compliant"'),
        (["contact.exponent=1.5"], "contact.exponent", "1.5", 'contact.model = "compliant"'),
        (["contact.friction_velocity=0.01"], "contact.friction_velocity", "0.01",
         "contact.friction > 0"),
        (["tool.axis=[1, 0, 0]"], "tool.axis", "[1, 0, 0]", 'tool.orientation = "normal"'),
        (["control.osc_hybrid.omega=30"], "control.osc_hybrid", '{"omega": 30}',
         'control.law = "osc_hybrid"'),
        (["control.law=osc_hybrid", "control.beta=0.02"], "control.beta", "0.02",
         "control.law = one of ['arimoto', 'arimoto_adaptive']"),
        (["control.law=osc_hybrid", "control.Kd=300"], "control.Kd", "300", "control.law = one of"),
        (["control.law=raibert_craig", "control.raibert_craig.ki=30", "control.gamma=15"],
         "control.gamma", "15", "without the key that replaces it (ki)"),
        (["control.Kd=300", "control.kd_rate=50"], "control.kd_rate", "50",
         "without the key that replaces it (Kd"),
        (["control.approach_rate=5"], "control.approach_rate", "5", "control.supervisor = true"),
        (["control.max_dist=0.1"], "control.max_dist", "0.1", "control.supervisor = true"),
        (["contact.model=compliant", "sim.dt=1e-4", "sim.baumgarte_alpha=40"],
         "sim.baumgarte_alpha", "40", 'contact.model = "rigid"'),
        (["contact.model=compliant", "sim.dt=1e-4", "sim.unilateral=false"],
         "sim.unilateral", "false", 'contact.model = "rigid"'),
        (["control.law=impedance", "control.impedance.force_tracking=false",
          "control.impedance.force_rate=5"], "control.impedance.force_rate", "5",
         "control.impedance.force_tracking = true"),
    ],
)  # fmt: skip
def test_a_key_without_effect_is_refused(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    sets: list[str],
    key: str,
    shown: str,
    needs: str,
) -> None:
    code, err = _run(capsys, tmp_path / "out", *sets)
    assert code == 2
    assert f"paper_contact.toml: {key} = {shown}: has no effect in this configuration" in err
    assert "; it acts only with " in err and needs in err
    assert err.count("\n") == 1  # one line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "sets",
    [
        ["contact.model=compliant", "contact.stiffness=1e6", "sim.dt=1e-4"],
        ["contact.friction=0.1", "contact.friction_velocity=0.01"],
        [
            "control.law=osc_hybrid",
            "control.osc_hybrid.omega=25",
            "control.supervisor=true",
            "control.Lambda=8",
        ],
        ["control.law=raibert_craig", "control.gamma=15", "control.kd_rate=50"],
    ],
)
def test_the_same_key_acts_where_its_condition_holds(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, sets: list[str]
) -> None:
    code, err = _run(capsys, tmp_path / "out", *sets)
    assert code == 0, err


def test_approach_settings_act_with_the_supervisor(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, err = _run(
        capsys, tmp_path / "out", "control.approach_rate=5", "control.max_dist=0.1",
        scenario=APPROACH,
    )  # fmt: skip
    assert code == 0, err


@pytest.mark.filterwarnings("always::hybrid_force.errors.RunWarning")
def test_control_P_is_warned_about_and_left_out_of_the_run(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, err = _run(capsys, tmp_path / "out", "control.P=0.4")
    assert code == 0
    line = next(x for x in err.splitlines() if "control.P" in x)
    assert (
        line.startswith("warning: ")
        and "control.P = 0.4 has no effect in any configuration" in line
    )
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["warnings"][0] == line.removeprefix("warning: ") and summary["n_warnings"] == 1
    result = load_result(tmp_path / "out" / "result.npz")
    assert "P" not in result.meta["scenario"]["control"]
    assert "P" not in result.meta["gains"]


def test_the_meta_records_only_what_the_run_used(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, err = _run(capsys, tmp_path / "osc", "control.law=osc_hybrid")
    assert code == 0, err
    meta = load_result(tmp_path / "osc" / "result.npz").meta
    assert not {"Kd", "beta", "gamma", "Lambda", "P"} & set(meta["gains"])
    assert not {"max_dist", "approach_rate"} & set(meta["gains"])  # supervisor = false
    assert meta["contact"] == {"model": "rigid", "friction": 0.0}
    assert meta["tool"] == {"orientation": "free"}
    summary = json.loads((tmp_path / "osc" / "summary.json").read_text())
    assert summary["status"] == "ok"
    code, err = _run(capsys, tmp_path / "soft", "contact.model=compliant", "sim.dt=1e-4")
    meta = load_result(tmp_path / "soft" / "result.npz").meta
    assert {"stiffness", "damping", "exponent"} <= set(meta["contact"])
    assert not {"baumgarte_alpha", "baumgarte_beta", "unilateral"} & set(meta["settings"])
    code, err = _run(capsys, tmp_path / "paper")
    paper = load_result(tmp_path / "paper" / "result.npz").meta["gains"]
    assert {"Kd", "Lambda", "beta", "gamma"} <= set(paper) and "P" not in paper


@pytest.mark.parametrize("path", sorted((ROOT / "scenarios").glob("*.toml")), ids=lambda p: p.stem)
def test_no_shipped_scenario_sets_an_inert_key(path: Path) -> None:
    """Loading refuses a key without effect where it is given and warns about one that never
    acts: a shipped scenario loads with neither."""
    from hybrid_force.scenario.loader import load_scenario

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_scenario(path)
    assert not [w for w in caught if "has no effect" in str(w.message)]


def test_compare_gives_each_law_the_overrides_that_act_with_it() -> None:
    """``compare --set`` is for every law: a law's own table and the paper's gains go only to
    the runs that read them, which the loader would otherwise refuse."""
    from hybrid_force.studies.compare import _variants

    overrides = {"control.osc_hybrid.omega": 30.0, "control.beta": 0.02, "sim.duration": 1.0}
    arimoto, osc = _variants(["arimoto", "osc_hybrid"], overrides)
    assert arimoto == {"control.law": "arimoto", "control.beta": 0.02, "sim.duration": 1.0}
    assert osc == {
        "control.law": "osc_hybrid",
        "control.osc_hybrid.omega": 30.0,
        "sim.duration": 1.0,
    }

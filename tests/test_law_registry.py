"""The law registry: every law builds from a scenario, its settings are checked by key, and
the command line lists them (hybrid_force.control.laws.base)."""

from __future__ import annotations

import numpy as np
import pytest

from hybrid_force.cli import main
from hybrid_force.control.laws.base import LAWS, Option, check_options, law_names
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.errors import ControlError, ScenarioError
from hybrid_force.scenario.loader import load_scenario

SCENARIO = "scenarios/paper_contact.toml"


def test_every_law_has_a_one_line_summary_and_a_loadable_factory() -> None:
    assert law_names()[0] == "arimoto"
    for name, spec in LAWS.items():
        assert spec.name == name
        assert spec.summary and "\n" not in spec.summary
        assert callable(spec.load())
        for key, option in spec.options.items():
            assert option.kind in ("number", "choice", "bool"), (name, key)
            assert option.doc, (name, key)


def test_unknown_law_is_refused_with_the_valid_names() -> None:
    with pytest.raises(ControlError) as info:
        ControlSettings(law="arimotto")
    assert "arimoto" in str(info.value)
    assert info.value.key == "control.law"


def test_options_are_checked_by_key_and_value() -> None:
    with pytest.raises(ControlError) as info:
        check_options({"arimoto": {"kp": 1.0}})
    assert info.value.key == "control.arimoto.kp"
    with pytest.raises(ControlError):
        check_options({"nolaw": {}})
    with pytest.raises(ControlError):
        check_options({"arimoto": 3})


def test_an_option_value_is_checked_against_its_kind() -> None:
    from hybrid_force.control.laws.base import _check_option

    number = Option("a gain [1/s]")
    assert _check_option("control.x.k", 2, number) == 2.0
    for bad in (0.0, -1.0, float("nan"), True, "2"):
        with pytest.raises(ControlError):
            _check_option("control.x.k", bad, number)
    choice = Option("form", kind="choice", choices=("a", "b"))
    assert _check_option("control.x.form", "b", choice) == "b"
    with pytest.raises(ControlError, match="valid: a, b"):
        _check_option("control.x.form", "c", choice)
    with pytest.raises(ControlError):
        _check_option("control.x.flag", 1, Option("flag", kind="bool"))


def test_a_law_table_in_a_scenario_names_the_file_and_key(tmp_path) -> None:
    with pytest.raises(ScenarioError) as info:
        load_scenario(SCENARIO, overrides={"control.arimoto.kp": 1.0})
    assert info.value.key == "control.arimoto.kp"
    assert "paper_contact.toml" in str(info.value)
    with pytest.raises(ScenarioError, match=r"control\.arimoto"):
        load_scenario(SCENARIO, overrides={"control.arimoto": 3})


@pytest.mark.parametrize("name", law_names())
def test_every_law_runs_the_paper_contact_scenario_for_a_moment(name: str) -> None:
    """Each registered law builds from the paper's scenario and keeps the tool on the surface
    for 0.05 s with finite torques (its convergence is tested in its own module)."""
    from hybrid_force.sim.loop import simulate

    sc = load_scenario(SCENARIO, overrides={"control.law": name, "sim.duration": 0.05})
    result = simulate(sc)
    assert result.meta["controller"]["law"] == name
    assert np.all(np.isfinite(result.u))
    assert result.meta["contact_at_end"] is True


def test_laws_command_lists_every_law(capsys) -> None:
    assert main(["laws"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == list(law_names())

"""The law registry: every law builds from a scenario, its settings are checked by key, and
the command line lists them (hybrid_force.control.laws.base)."""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np
import pytest

from hybrid_force.cli import main
from hybrid_force.control.laws.base import LAWS, LawOptions, check_options, law_names
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.errors import ControlError, ScenarioError
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.schema import param, specs

SCENARIO = "scenarios/paper_contact.toml"


def test_every_law_has_a_one_line_summary_and_a_loadable_factory() -> None:
    assert law_names()[0] == "arimoto"
    for name, spec in LAWS.items():
        assert spec.name == name
        assert spec.summary and "\n" not in spec.summary
        assert callable(spec.factory)
        for key, doc in spec.describe():
            assert doc and "\n" not in doc, (name, key)
        if spec.options is not None:
            assert issubclass(spec.options, LawOptions)
            assert spec.options.law == name
            spec.options()  # the defaults pass the law's own checks
            for f, p in specs(spec.options):
                assert p.doc, (name, f.name)


def test_a_law_registers_itself_in_its_own_module() -> None:
    """Each entry is created where its law is defined (the factory's module)."""
    for name, spec in LAWS.items():
        assert spec.factory.__module__ == f"hybrid_force.control.laws.{name}"


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


@dataclasses.dataclass(frozen=True)
class _Table(LawOptions):
    law: ClassVar[str] = "x"

    k: float = param(1.0, unit="1/s", minimum=0.0, strict=True, doc="a gain")
    form: str = param("a", choices=("a", "b"), doc="form")
    flag: bool = param(True, doc="flag")


def test_an_option_value_is_checked_against_its_kind() -> None:
    assert _Table(k=2).k == 2.0 and isinstance(_Table(k=2).k, float)
    for bad in (0.0, -1.0, float("nan"), True, "2"):
        with pytest.raises(ControlError) as info:
            _Table(k=bad)  # type: ignore[arg-type]
        assert info.value.key == "control.x.k"
    assert _Table(form="b").form == "b"
    with pytest.raises(ControlError, match="one of 'a', 'b'"):
        _Table(form="c")
    with pytest.raises(ControlError):
        _Table(flag=1)  # type: ignore[arg-type]


def test_a_law_settings_dataclass_checks_its_fields_and_names_the_key() -> None:
    options = LAWS["osc_hybrid"].options
    assert options is not None
    with pytest.raises(ControlError) as info:
        options(omega=-1.0)
    assert info.value.key == "control.osc_hybrid.omega"
    assert options(omega=3).omega == 3.0 and isinstance(options(omega=3).omega, float)


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


def test_laws_options_show_each_key_with_its_unit_and_default(capsys) -> None:
    assert main(["laws", "--options"]) == 0
    out = capsys.readouterr().out
    assert (
        "control.osc_hybrid.omega: task-space bandwidth ω: K_p = ω², K_v = 2ζω [rad/s]; default 20"
        in out
    )
    assert "control.raibert_craig.form: " in out and 'default "corrected"' in out
    assert "control.impedance.force_tracking: " in out and "default true" in out

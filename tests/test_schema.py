"""The dataclass is the schema: the generic check and reader, the JSON Schema of a scenario
file (``hybrid-force schema``) and the key tables of docs/scenarios.md, all from param()."""

from __future__ import annotations

import copy
import json
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import jsonschema
import pytest

from hybrid_force._file_errors import _Context
from hybrid_force.cli import main
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.control.tool import ToolSettings
from hybrid_force.errors import BadInputError, ScenarioError
from hybrid_force.scenario._tables import settings_tables, typed_tables
from hybrid_force.schema import check_fields, param, specs, value_kind
from hybrid_force.schema_docs import json_schema, markdown_tables, with_generated_tables
from hybrid_force.settings_reader import read_settings
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.dynamics import Baumgarte
from hybrid_force.sim.sensors import SensorSettings
from hybrid_force.sim.settings import SimSettings

REPO = Path(__file__).resolve().parents[1]
SETTINGS = (SimSettings, ControlSettings, SensorSettings, ContactSettings, ToolSettings, Baumgarte)


@dataclass(frozen=True)
class _Options:
    """A settings dataclass as a law's options would be one."""

    gain: float = param(2.0, unit="1/s", minimum=0.0, strict=True, doc="a gain")
    mode: Literal["a", "b"] = param("a", doc="a mode")
    steps: int = param(3, minimum=1, doc="a count")

    def __post_init__(self) -> None:
        check_fields(self, ScenarioError, "control.mine.")


@pytest.mark.parametrize("cls", SETTINGS, ids=[c.__name__ for c in SETTINGS])
def test_every_toml_field_has_a_known_kind_and_a_doc(cls: type) -> None:
    for f, spec in specs(cls):
        if spec.toml and "hybrid_force" in f.metadata:
            assert value_kind(cls, f)[0] != "any", f.name
            assert spec.doc, f.name
    cls()  # the defaults pass their own check


def test_the_generic_check_names_the_key_and_the_value() -> None:
    assert _Options(gain=3).gain == 3.0 and isinstance(_Options(gain=3).gain, float)
    with pytest.raises(ScenarioError, match=r"control\.mine\.gain must be a positive") as info:
        _Options(gain=0.0)
    assert info.value.key == "control.mine.gain" and info.value.value == 0.0
    with pytest.raises(ScenarioError, match=r"control\.mine\.mode must be one of 'a', 'b'"):
        _Options(mode="c")  # type: ignore[arg-type]
    with pytest.raises(ScenarioError, match=r"control\.mine\.steps must be an integer >= 1"):
        _Options(steps=0)


def test_one_reader_for_any_settings_dataclass() -> None:
    """A law's options dataclass plugs into the same reader as [sim]."""
    ctx = _Context("x.toml")
    assert read_settings(ctx, "control.mine", _Options, {"gain": 4, "mode": "b"}) == _Options(
        gain=4.0, mode="b"
    )
    with pytest.raises(
        ScenarioError, match=r"x\.toml: control\.mine\.gian = 1: unknown key.*'gain'"
    ):
        read_settings(ctx, "control.mine", _Options, {"gian": 1})
    with pytest.raises(ScenarioError, match=r'x\.toml: control\.mine\.mode = "c": must be one of'):
        read_settings(ctx, "control.mine", _Options, {"mode": "c"})
    with pytest.raises(
        ScenarioError, match=r"x\.toml: control\.mine\.gain = -1: must be a positive"
    ):
        read_settings(ctx, "control.mine", _Options, {"gain": -1})
    sim = read_settings(ctx, "sim", SimSettings, {"baumgarte_alpha": 10.0})
    assert sim.baumgarte == Baumgarte(alpha=10.0)
    assert isinstance(sim, SimSettings)
    assert issubclass(ScenarioError, BadInputError)


def _scenarios() -> list[Path]:
    return sorted((REPO / "scenarios").glob("*.toml"))


@pytest.fixture(scope="module")
def validator() -> jsonschema.Draft202012Validator:
    schema = json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


@pytest.mark.parametrize("path", _scenarios(), ids=lambda p: p.stem)
def test_the_json_schema_accepts_every_shipped_scenario(
    path: Path, validator: jsonschema.Draft202012Validator
) -> None:
    errors = [e.message for e in validator.iter_errors(tomllib.loads(path.read_text()))]
    assert not errors, errors


@pytest.mark.parametrize(
    ("where", "value"),
    [
        (("sim", "dtt"), 1e-3),  # unknown key
        (("sim", "dt"), "fast"),  # wrong type
        (("sim", "dt"), 0.0),  # out of range
        (("sim", "integrator"), "rk5"),  # not a choice
        (("surface", "type"), "torus"),  # unknown type
        (("control", "f_d"), [1.0, "x"]),
        (("nonsense",), {}),  # unknown table
    ],
)
def test_the_json_schema_rejects_a_bad_scenario(
    where: tuple[str, ...], value: object, validator: jsonschema.Draft202012Validator
) -> None:
    doc = copy.deepcopy(tomllib.loads((REPO / "scenarios" / "rtr_sphere.toml").read_text()))
    node = doc
    for key in where[:-1]:
        node = node.setdefault(key, {})
    node[where[-1]] = value
    assert list(validator.iter_errors(doc))
    missing = {k: v for k, v in doc.items() if k != "robot"}
    assert list(validator.iter_errors(missing))


def test_the_schema_command_prints_the_json_schema(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["schema"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed == json_schema()
    assert printed["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert {"cylinder", "sphere", "plane"} <= {
        option["properties"]["type"]["const"]
        for option in printed["properties"]["surface"]["oneOf"]
    }


def test_the_docs_key_tables_are_the_generated_ones(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """docs/scenarios.md's key tables are generated (``hybrid-force schema --update-docs``):
    this fails when the docs and the dataclasses disagree."""
    text = (REPO / "docs" / "scenarios.md").read_text(encoding="utf-8")
    names = re.findall(r"<!-- generated: (\S+) -->", text)
    tables = markdown_tables()
    assert names and set(names) <= set(tables), set(names) - set(tables)
    assert {"control", "sim", "sensor", "contact", "tool"} <= set(names)
    assert with_generated_tables(text) == text, (
        "run: hybrid-force schema --update-docs docs/scenarios.md"
    )
    copy_ = tmp_path / "scenarios.md"
    copy_.write_text(text.replace("| `dt` |", "| `dt_old` |"), encoding="utf-8")
    assert main(["schema", "--update-docs", str(copy_)]) == 0
    assert copy_.read_text(encoding="utf-8") == text
    assert main(["schema", "--markdown"]) == 0
    assert "<!-- generated: sim -->" in capsys.readouterr().out


def test_every_table_of_the_reader_is_in_the_reference() -> None:
    tables = settings_tables()
    assert {
        "robot", "initial", "control", "tool", "sim", "sensor", "contact", "removal"
    } == set(tables)  # fmt: skip
    assert "baumgarte_alpha" in tables["sim"] and "model_mass_factor" in tables["sim"]
    typed = typed_tables()
    assert {"helix", "circle", "waypoints", "raster"} <= set(typed["trajectory"])
    assert typed["surface"]["plane"]["normal"].required

"""The scenario file's vocabulary: its tables and the keys of each, read from the settings
dataclasses' declarations (:func:`~hybrid_force.settings_reader.keys_of`), for the loader,
the JSON Schema and the docs' key tables alike."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from hybrid_force._file_errors import _Context
from hybrid_force.control.laws.base import law_names, law_spec
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.control.tool import ToolSettings
from hybrid_force.errors import ScenarioError
from hybrid_force.geometry.paths import path_parameters, path_types
from hybrid_force.geometry.surface_base import surface_types
from hybrid_force.schema import Param, default_of, specs
from hybrid_force.settings_reader import Key, keys_of
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.removal import RemovalSettings
from hybrid_force.sim.sensors import SensorSettings
from hybrid_force.sim.settings import SimSettings

TOP: dict[str, Key] = {"name": Key("str", True), "description": Key("str")}
TABLES = (
    "robot", "surface", "surfaces", "trajectory", "initial", "control", "sensor", "contact", "sim",
    "tool", "removal",
)  # fmt: skip
SETTINGS: dict[str, type] = {
    "sim": SimSettings, "sensor": SensorSettings, "contact": ContactSettings, "tool": ToolSettings,
}  # fmt: skip
"""The tables read into a settings dataclass as they are ([control] holds more: the laws')."""

_ROBOT: dict[str, Key] = {
    "model": Key("str", True),
    "tip": Key("str"),
    "package_dirs": Key("str_list"),
    "xacro_args": Key("str_table"),
    "lock_off_chain": Key("bool"),
    "xacro_trust": Key("bool"),
}
_INITIAL = {"tip": Key("vec3"), "seed": Key("vector"), "q": Key("vector"), "v": Key("vector")}


def control_keys() -> dict[str, Key]:
    """The keys of [control]: ControlSettings' fields, ``model`` and each law's table."""
    keys = keys_of(ControlSettings)
    keys["law"] = dataclasses.replace(keys["law"], kind="choice", choices=law_names())
    keys["model"] = Key("str", param=Param("the controller's own model of the arm (the plant's)"))
    doc = "the law's own settings ([control.<law>], `hybrid-force laws --options`)"
    laws = {name: Key("table", param=Param(doc, acts_when=("law", name))) for name in law_names()}
    return {**keys, **laws}


def law_keys(law: str) -> dict[str, Key]:
    """The keys of ``[control.<law>]``: the law's options dataclass's (none without one)."""
    options = law_spec(law).options
    return {} if options is None else keys_of(options)


def sim_keys() -> dict[str, Key]:
    """The keys of [sim]: SimSettings' and ``model_mass_factor`` (ControlSettings.mass_factor)."""
    f, spec = next((f, spec) for f, spec in specs(ControlSettings) if f.name == "mass_factor")
    return {
        **keys_of(SimSettings),
        "model_mass_factor": Key("number", param=spec, default=default_of(f)),
    }


def settings_tables() -> dict[str, dict[str, Key]]:
    """The keys of every table with a fixed set of keys, by table name."""
    own = {name: keys_of(cls) for name, cls in SETTINGS.items()}
    own |= {"sim": sim_keys(), "removal": keys_of(RemovalSettings)}
    return {"robot": _ROBOT, "initial": _INITIAL, "control": control_keys(), **own}


class TypeKeys(Mapping[str, dict[str, Key]]):
    """The keys of each registered type of a typed table ([surface], [trajectory]) by type
    name, each type's read from its declaration when looked up: a scenario looks up the types
    it names, not the dozen others (reading one costs about 0.5 ms)."""

    def __init__(self, declarations: Mapping[str, type]) -> None:
        self._declarations = dict(declarations)  # the types registered now

    def __getitem__(self, kind: str) -> dict[str, Key]:
        return keys_of(self._declarations[kind])

    def __iter__(self) -> Iterator[str]:
        return iter(self._declarations)

    def __len__(self) -> int:
        return len(self._declarations)


def type_keys(table: str) -> TypeKeys:
    """The keys of each registered type of ``table`` (``"surface"`` or ``"trajectory"``)."""
    if table == "surface":
        return TypeKeys(surface_types())
    return TypeKeys({kind: path_parameters(cls) for kind, cls in path_types().items()})


def typed_tables() -> dict[str, dict[str, dict[str, Key]]]:
    """The keys of each registered surface and path type: {"surface": {type: keys}, ...}."""
    return {table: dict(type_keys(table)) for table in ("surface", "trajectory")}


MAX_NESTING = 100
"""The deepest a scenario's tables and arrays may nest (a scenario needs 3): deeper data is
refused before anything copies, formats or serialises it (each recurses once per level)."""


_SHOWN_KEYS = 8  # how much of a too deep dotted key a message shows


def check_nesting(doc: Mapping[str, Any], ctx: _Context) -> None:
    """Refuse data nested deeper than :data:`MAX_NESTING`, naming the dotted key where it
    goes too deep (shortened). Walks with an explicit stack: no recursion."""
    stack: list[tuple[object, tuple[str, ...], int]] = [(doc, (), 0)]
    while stack:
        value, path, depth = stack.pop()
        if isinstance(value, dict):
            items: Iterable[tuple[str, object]] = ((str(k), v) for k, v in value.items())
        elif isinstance(value, list):
            items = ((str(i), v) for i, v in enumerate(value))
        else:
            continue
        if depth >= MAX_NESTING:
            shown = ".".join(path[:_SHOWN_KEYS])
            raise ScenarioError(
                f"{ctx.file}: {shown}...: tables or arrays nested more than MAX_NESTING = "
                f"{MAX_NESTING} levels deep; a scenario's own nest 3 (is "
                f"{'.'.join(path[:2])!r} a key of the format? docs/scenarios.md)",
                key=".".join(path[:2]),
                file=ctx.file,
            )
        for key, item in items:
            stack.append((item, (*path, key) if len(path) < _SHOWN_KEYS else path, depth + 1))

"""The scenario file's vocabulary: the keys of each table, their kinds of value, and the
checks and messages every table shares (:class:`_Context`, :func:`_check_table`, :func:`_wrap`).

A message names the file, the ``table.key`` and the offending value, the format
:mod:`hybrid_force.scenario.loader` documents.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from typing import Any

from hybrid_force._file_errors import _Context, _fmt, _wrap
from hybrid_force.control.laws.base import check_options, law_names
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.control.tool import ToolSettings
from hybrid_force.errors import BadInputError, ScenarioError, did_you_mean
from hybrid_force.geometry.paths import path_parameters, path_types
from hybrid_force.geometry.surface_base import surface_types
from hybrid_force.model.xacro_files import xacro_argument_text
from hybrid_force.schema import (
    Key,
    Param,
    arguments,
    default_of,
    json_key,
    json_table,
    keys_of,
    markdown_row,
    specs,
    with_tables,
)
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.removal import PAD_TYPES, RemovalSettings
from hybrid_force.sim.sensors import SensorSettings
from hybrid_force.sim.settings import SimSettings

# --- schema --------------------------------------------------------------------------------------
_TOP: dict[str, Key] = {"name": Key("str", True), "description": Key("str")}
_TABLES = (
    "robot", "surface", "surfaces", "trajectory", "initial", "control", "sensor", "contact", "sim",
    "tool", "removal",
)  # fmt: skip

_ROBOT: dict[str, Key] = {
    "model": Key("str", True),
    "tip": Key("str"),
    "package_dirs": Key("str_list"),
    "xacro_args": Key("str_table"),
    "lock_off_chain": Key("bool"),
    "xacro_trust": Key("bool"),
}

_INITIAL: dict[str, Key] = {
    "tip": Key("vec3"),
    "seed": Key("vector"),
    "q": Key("vector"),
    "v": Key("vector"),
}


def control_keys() -> dict[str, Key]:
    """The keys of [control]: ControlSettings' declared fields, ``law`` one of the registered
    laws, ``model`` (the controller's own model) and each law's table ``[control.<law>]``."""

    keys = keys_of(ControlSettings)
    keys["law"] = dataclasses.replace(keys["law"], kind="choice", choices=law_names())
    keys["model"] = Key("str", param=Param("the controller's own model of the arm (the plant's)"))
    table = Param("the law's own settings ([control.<law>], `hybrid-force laws --options`)")
    return {**keys, **{name: Key("law_table", param=table) for name in law_names()}}


def sim_keys() -> dict[str, Key]:
    """The keys of [sim]: SimSettings' declared fields (Baumgarte's flattened in) and the
    controller's ``model_mass_factor`` (ControlSettings.mass_factor), which [sim] holds."""

    mass = {f.name: (f, spec) for f, spec in specs(ControlSettings)}["mass_factor"]
    factor = Key("number", param=mass[1], default=default_of(mass[0]))
    return {**keys_of(SimSettings), "model_mass_factor": factor}


MAX_NESTING = 100
"""The deepest a scenario's tables and arrays may nest (docs/scenarios.md): a scenario needs
3 (``[[surfaces]]``, a table in it, an array in that). Shallower absurd data is refused by
its key's own check; deeper data here, before anything copies, formats or serialises it
(each of which recurses once per level, up to Python's limit of about 1,000)."""


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


# --- messages ------------------------------------------------------------------------------------
def _type_name(value: object) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"


def _suggest(word: str, choices: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"``: difflib's match, else a case-insensitive or prefix one."""
    options = list(choices)
    hint = did_you_mean(word, options)
    if hint:
        return hint
    low = word.lower()
    for option in options:
        o = option.lower()
        if o == low or (len(o) >= 3 and low.startswith(o)) or (len(low) >= 3 and o.startswith(low)):
            return f" (did you mean '{option}'?)"
    return ""


# --- type checks ---------------------------------------------------------------------------------
def _is_number(x: object) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _check_value(ctx: _Context, key: str, value: object, spec: Key) -> object:
    """Check one value against its spec; return it as Python data (floats for numbers)."""
    kind = spec.kind
    if kind == "str":
        if not isinstance(value, str):
            raise ctx.error(key, value, f"must be a string, got {_type_name(value)}")
        return value
    if kind == "str_list":
        if not isinstance(value, list):
            raise ctx.error(key, value, f"must be an array of strings, got {_type_name(value)}")
        for i, x in enumerate(value):
            if not isinstance(x, str) or not x:
                raise ctx.error(
                    key, value, f"must be an array of non-empty strings; element {i} is "
                    f"{_type_name(x) if not isinstance(x, str) else 'empty'}",
                )  # fmt: skip
        return list(value)
    if kind == "str_table":
        if not isinstance(value, dict):
            raise ctx.error(
                key, value, f'must be a table of texts {{name = "value"}}, got {_type_name(value)}'
            )
        out: dict[str, str] = {}
        for name, x in value.items():
            if _is_number(x):
                _number(ctx, f"{key}.{name}", x)  # refuses a number that is not finite
            elif not isinstance(x, (str, bool)):
                raise ctx.error(
                    f"{key}.{name}", x, f"must be a text (a string), got {_type_name(x)}"
                )
            out[name] = xacro_argument_text(x)
        return out
    if kind == "law_table":
        if not isinstance(value, dict):
            raise ctx.error(key, value, f"must be a table [{key}], got {_type_name(value)}")
        law = key.rsplit(".", 1)[-1]
        try:
            return check_options({law: value})[law]
        except BadInputError as exc:
            raise ScenarioError(
                f"{ctx.file}: {exc}", key=exc.key, value=exc.value, file=ctx.file
            ) from None
    if kind == "bool":
        if not isinstance(value, bool):
            raise ctx.error(key, value, f"must be true or false, got {_type_name(value)}")
        return value
    if kind == "choice":
        if not isinstance(value, str) or value not in spec.choices:
            hint = _suggest(value, spec.choices) if isinstance(value, str) else ""
            raise ctx.error(key, value, f"must be one of {list(spec.choices)}{hint}")
        return value
    if kind == "number":
        return _in_range(ctx, key, value, _number(ctx, key, value), spec.param)
    if kind == "integer":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ctx.error(key, value, f"must be a whole number, got {_type_name(value)}")
        return value
    if kind == "vec3":
        vec = _vector(ctx, key, value, "3 numbers")
        if len(vec) != 3:
            raise ctx.error(key, value, f"must be 3 numbers [x, y, z], got {len(vec)}")
        return vec
    if kind == "vector":
        return _vector(ctx, key, value, "an array of numbers")
    if kind == "points":
        what = "an array of points, each an array of numbers ([[x, y, z], ...] or [[u, v], ...])"
        if not isinstance(value, list) or not all(isinstance(row, list) for row in value):
            raise ctx.error(key, value, f"must be {what}")
        return [_vector(ctx, key, row, what) for row in value]
    if kind == "number_or_vector":
        if _is_number(value) or isinstance(value, bool):
            return _number(ctx, key, value)
        return _vector(ctx, key, value, "a number or an array of numbers")
    if kind == "matrix":
        if isinstance(value, list) and value and all(isinstance(r, list) for r in value):
            rows = [_vector(ctx, key, r, "a matrix (array of arrays of numbers)") for r in value]
            if len({len(r) for r in rows}) != 1:
                raise ctx.error(key, value, "the rows of the matrix have different lengths")
            return rows
        if isinstance(value, list):
            return _vector(ctx, key, value, "a number, an array or a matrix of numbers")
        return _number(ctx, key, value)
    raise AssertionError(kind)  # pragma: no cover


def _number(ctx: _Context, key: str, value: object) -> float:
    if isinstance(value, bool):
        raise ctx.error(key, value, "must be a number, got a boolean")
    if not _is_number(value):
        raise ctx.error(key, value, f"must be a number, got {_type_name(value)}")
    try:
        out = float(value)  # type: ignore[arg-type]
    except OverflowError:  # an integer beyond float range, e.g. 10**400
        out = math.inf
    if not math.isfinite(out):
        raise ctx.error(key, value, "must be a finite number")
    return out


def _in_range(ctx: _Context, key: str, raw: object, value: float, spec: Param | None) -> float:
    """``value`` (``raw`` as written) within its declared range (``"must be > 0 [s]"``)."""
    if spec is None:
        return value
    low, high, strict = spec.minimum, spec.maximum, spec.strict
    unit = f" [{spec.unit}]" if spec.unit else ""
    if (
        low is not None
        and high is not None
        and not (low < value < high or (not strict and low <= value <= high))
    ):
        ends = "()" if strict else "[]"
        raise ctx.error(key, raw, f"must be in {ends[0]}{low:g}, {high:g}{ends[1]}{unit}")
    if low is not None and (value <= low if strict else value < low):
        rule = (
            "a positive number (> 0)"
            if strict and low == 0
            else f"{'>' if strict else '>='} {low:g}"
        )
        raise ctx.error(key, raw, f"must be {rule}{unit}")
    return value


def _vector(ctx: _Context, key: str, value: object, what: str) -> list[float]:
    if not isinstance(value, list):
        raise ctx.error(key, value, f"must be {what}, got {_type_name(value)}")
    out: list[float] = []
    for i, x in enumerate(value):
        if isinstance(x, bool) or not _is_number(x):
            raise ctx.error(key, value, f"must be {what}; element {i} is {_type_name(x)}")
        try:
            xf = float(x)
        except OverflowError:
            xf = math.inf
        if not math.isfinite(xf):
            raise ctx.error(key, value, f"must be {what}; element {i} is not finite")
        out.append(xf)
    return out


def _check_table(
    ctx: _Context, name: str, table: object, schema: Mapping[str, Key]
) -> dict[str, Any]:
    """Check a table's keys (unknown, missing) and values; return the checked values."""
    if not isinstance(table, dict):
        raise ctx.error(name, table, f"must be a table [{name}], got {_type_name(table)}")
    prefix = f"{name}." if name else ""
    label = f"[{name}]" if name else "the top level"
    out: dict[str, Any] = {}
    for key, value in table.items():
        if key not in schema:
            raise ctx.error(
                f"{prefix}{key}",
                value,
                f"unknown key{_suggest(key, schema)}; valid keys of {label}: {', '.join(schema)}",
            )
        out[key] = _check_value(ctx, f"{prefix}{key}", value, schema[key])
    for key, spec in schema.items():
        if spec.required and key not in table:
            raise ctx.table_error(
                f"{prefix}{key}",
                f"missing required key; {label} has {_fmt(sorted(table))}, required: "
                f"{', '.join(k for k, s in schema.items() if s.required)}",
            )
    return out


def read_settings(
    ctx: _Context, name: str, cls: type, table: object, values: Mapping[str, Any] | None = None
) -> Any:
    """The one reader of a settings table: [name] → an instance of dataclass ``cls`` (its
    keys, kinds, ranges and defaults from the fields' :func:`~hybrid_force.schema.param`),
    every refusal naming the file, ``name.key`` and the value. ``values``: the table already
    checked (by :func:`_check_table` against :func:`declared_keys` and extra keys)."""
    if values is None:
        values = _check_table(ctx, name, table, keys_of(cls))
    try:
        return cls(**arguments(cls, values))
    except BadInputError as exc:
        raise _wrap(ctx, name, values, exc) from None


def _typed_table(
    ctx: _Context, name: str, table: object, types: Mapping[str, Mapping[str, Key]]
) -> tuple[str, dict[str, Any]]:
    """A table with a ``type`` key selecting its schema; returns (type, checked values)."""
    if not isinstance(table, dict):
        raise ctx.error(name, table, f"must be a table, got {_type_name(table)}")
    if "type" not in table:
        raise ctx.table_error(
            f"{name}.type", f"missing required key; valid types: {', '.join(types)}"
        )
    kind = table["type"]
    if not isinstance(kind, str) or kind not in types:
        hint = _suggest(kind, types) if isinstance(kind, str) else ""
        raise ctx.error(
            f"{name}.type", kind, f"unknown type{hint}; valid types: {', '.join(types)}"
        )
    rest = {k: v for k, v in table.items() if k != "type"}
    schema = types[kind]
    for key in rest:
        if key not in schema:
            article = "an" if kind[0] in "aeiou" else "a"
            raise ctx.error(
                f"{name}.{key}",
                rest[key],
                f"unknown key for {article} {kind}{_suggest(key, schema)}; valid keys: type, "
                f"{', '.join(schema)}",
            )
    return kind, _check_table(ctx, name, rest, schema)


# --- the reference: JSON Schema and docs tables, from the same keys ----------------------------
def settings_tables() -> dict[str, dict[str, Key]]:
    """The keys of every table with a fixed set of keys, by table name."""

    return {
        "robot": _ROBOT,
        "initial": _INITIAL,
        "control": control_keys(),
        "tool": keys_of(ToolSettings),
        "sim": sim_keys(),
        "sensor": keys_of(SensorSettings),
        "contact": keys_of(ContactSettings),
        "removal": keys_of(RemovalSettings),
    }


def typed_tables() -> dict[str, dict[str, dict[str, Key]]]:
    """The keys of each registered surface and path type: {"surface": {type: keys}, ...}."""

    return {
        "surface": {kind: keys_of(cls) for kind, cls in surface_types().items()},
        "trajectory": {kind: keys_of(path_parameters(cls)) for kind, cls in path_types().items()},
        "tool.pad": {kind: keys_of(cls) for kind, cls in PAD_TYPES.items()},
    }


def json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a scenario file (``hybrid-force schema``), from the
    same declarations the reader uses."""
    typed = {
        name: {"oneOf": [json_table(keys, kind) for kind, keys in types.items()]}
        for name, types in typed_tables().items()
    }
    tables = {name: json_table(keys) for name, keys in settings_tables().items()}
    tables["tool"]["properties"]["pad"] = typed["tool.pad"]  # [tool.pad], a typed sub-table
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "hybrid_force scenario file (docs/scenarios.md)",
        **json_table(_TOP),
        "properties": {
            **{name: json_key(key) for name, key in _TOP.items()},
            "surface": typed["surface"],
            "surfaces": {"type": "array", "minItems": 1, "items": typed["surface"]},
            "trajectory": typed["trajectory"],
            **tables,
        },
        "required": [*(k for k, v in _TOP.items() if v.required), "robot", "trajectory", "initial"],
    }


def markdown_tables() -> dict[str, str]:
    """The key tables of docs/scenarios.md, by the name of their marker
    (``<!-- generated: NAME -->`` ... ``<!-- end generated -->``)."""
    head = "| key | type | default | meaning |\n|---|---|---|---|"
    out = {
        name: "\n".join([head, *(markdown_row(k, key) for k, key in keys.items())])
        for name, keys in settings_tables().items()
        if name not in ("robot", "initial")
    }
    for table, types in typed_tables().items():
        for kind, keys in types.items():
            rows = [markdown_row(k, key) for k, key in keys.items()]
            out[f"{table}.{kind}"] = "\n".join([head, *rows])
    return out


def with_generated_tables(text: str) -> str:
    """``text`` (docs/scenarios.md) with every generated block replaced by its table."""
    return with_tables(text, markdown_tables())

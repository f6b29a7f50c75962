"""The reference of the scenario format, generated from the declarations the reader reads
(:func:`~hybrid_force.settings_reader.keys_of` of every table): the JSON Schema of
``hybrid-force schema`` (for editors that read a ``#:schema`` line) and the key tables of
docs/scenarios.md (``hybrid-force schema --update-docs``)."""

from __future__ import annotations

import dataclasses
import json
import re
from collections.abc import Mapping
from typing import Any

from hybrid_force.scenario._tables import TOP, settings_tables, typed_tables
from hybrid_force.schema import MISSING_VALUE, Param
from hybrid_force.settings_reader import Key

__all__ = ["json_schema", "markdown_tables", "with_generated_tables"]

_NUMBERS = {"type": "array", "items": {"type": "number"}}
_JSON: dict[str, dict[str, Any]] = {
    "str": {"type": "string"},
    "bool": {"type": "boolean"},
    "number": {"type": "number"},
    "integer": {"type": "integer"},
    "vec3": {**_NUMBERS, "minItems": 3, "maxItems": 3},
    "vector": _NUMBERS,
    "points": {"type": "array", "items": _NUMBERS},
    "number_or_vector": {"oneOf": [{"type": "number"}, _NUMBERS]},
    "matrix": {"oneOf": [{"type": "number"}, _NUMBERS, {"type": "array", "items": _NUMBERS}]},
    "str_list": {"type": "array", "items": {"type": "string", "minLength": 1}},
    "str_table": {
        "type": "object",
        "additionalProperties": {"type": ["string", "number", "boolean"]},
    },
    "table": {"type": "object"},
}
_TYPE_TEXT = {
    "str": "string",
    "vec3": "3 numbers",
    "vector": "numbers",
    "points": "array of points",
    "number_or_vector": "number or numbers",
    "matrix": "number, numbers or matrix",
    "typed_table": "table",
}


def _json_key(key: Key) -> dict[str, Any]:
    if key.kind == "typed_table" and key.tables is not None:
        out: dict[str, Any] = {"oneOf": [_json_table(k, kind) for kind, k in key.tables.items()]}
    else:
        out = {"enum": list(key.choices)} if key.choices else dict(_JSON[key.kind])
    spec = key.param
    if spec is not None:
        out["description"] = spec.doc + (f" [{spec.unit}]" if spec.unit else "")
        if spec.minimum is not None and key.kind == "number":
            out["exclusiveMinimum" if spec.strict else "minimum"] = spec.minimum
        if spec.maximum is not None and key.kind == "number":
            out["exclusiveMaximum"] = spec.maximum
    if key.default is not MISSING_VALUE and key.default is not None:
        out["default"] = json.loads(json.dumps(key.default, default=list))
    return out


def _json_table(keys: Mapping[str, Key], kind: str | None = None) -> dict[str, Any]:
    properties = {name: _json_key(key) for name, key in keys.items()}
    required = [name for name, key in keys.items() if key.required]
    if kind is not None:
        properties = {"type": {"const": kind}, **properties}
        required = ["type", *required]
    return {
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": False,
    }


def json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a scenario file."""
    typed = {
        name: {"oneOf": [_json_table(keys, kind) for kind, keys in types.items()]}
        for name, types in typed_tables().items()
    }
    tables = {name: _json_table(keys) for name, keys in settings_tables().items()}
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "hybrid_force scenario file (docs/scenarios.md)",
        **_json_table(TOP),
        "properties": {
            **{name: _json_key(key) for name, key in TOP.items()},
            "surface": typed["surface"],
            "surfaces": {"type": "array", "minItems": 1, "items": typed["surface"]},
            "trajectory": typed["trajectory"],
            **tables,
        },
        "required": [*(k for k, v in TOP.items() if v.required), "robot", "trajectory", "initial"],
    }


def _toml_text(value: object) -> str:
    """A default as TOML writes it: ``20``, ``1e-05``, ``true``, ``"euler"``, ``[0, 0, 1]``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_toml_text(x) for x in value) + "]"
    if dataclasses.is_dataclass(value):
        return ""
    return json.dumps(value, ensure_ascii=False)


def _markdown_row(name: str, key: Key) -> str:
    spec = key.param or Param()
    if key.choices:
        kind = " or ".join(f'`"{c}"`' for c in key.choices)
    else:
        kind = _TYPE_TEXT.get(key.kind, key.kind)
    low, high = spec.minimum, spec.maximum
    if low is not None and high is not None:
        kind += f" in {'(' if spec.strict else '['}{low:g}, {high:g}{')' if spec.strict else ']'}"
    elif low is not None:
        kind += f" {'>' if spec.strict else '>='} {low:g}"
    if key.required:
        default = "required"
    elif key.default is MISSING_VALUE:
        default = ""
    else:
        default = "none" if key.default is None else f"`{_toml_text(key.default)}`"
    meaning = spec.doc + (f" [{spec.unit}]" if spec.unit else "")
    return f"| `{name}` | {kind} | {default} | {meaning} |"


def markdown_tables() -> dict[str, str]:
    """The key tables of docs/scenarios.md, by the name of their marker
    (``<!-- generated: NAME -->`` ... ``<!-- end generated -->``): ``table``, ``table.type``
    and a typed subtable's ``table[.type].key.subtype``."""
    head = "| key | type | default | meaning |\n|---|---|---|---|"
    named = {
        name: keys for name, keys in settings_tables().items() if name not in ("robot", "initial")
    }
    for table, types in typed_tables().items():
        named.update({f"{table}.{kind}": keys for kind, keys in types.items()})
    out: dict[str, str] = {}
    for name, keys in named.items():
        out[name] = "\n".join([head, *(_markdown_row(k, key) for k, key in keys.items())])
        for key_name, key in keys.items():  # a typed subtable [name.key] of its own types
            for sub, sub_keys in (key.tables or {}).items():
                rows = [_markdown_row(k, x) for k, x in sub_keys.items()]
                out[f"{name}.{key_name}.{sub}"] = "\n".join([head, *rows])
    return out


_MARKER = re.compile(r"(<!-- generated: (\S+) -->\n)(.*?)(\n<!-- end generated -->)", re.S)


def with_generated_tables(text: str) -> str:
    """``text`` (docs/scenarios.md) with each block ``<!-- generated: NAME -->`` ...
    ``<!-- end generated -->`` holding its table."""
    tables = markdown_tables()
    return _MARKER.sub(lambda m: m[1] + tables.get(m[2], f"(no table {m[2]})") + m[4], text)

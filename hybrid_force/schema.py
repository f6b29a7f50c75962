"""The dataclass is the schema: a settings field carries its unit, range, choices and doc.

A settings dataclass declares each field once, with :func:`param`::

    @dataclass(frozen=True)
    class SimSettings:
        dt: float = param(1e-3, unit="s", minimum=0.0, strict=True, doc="time step")

The TOML reader (:mod:`hybrid_force.scenario`), the ``__post_init__`` checks, the key tables
of docs/scenarios.md and the JSON Schema (``hybrid-force schema``) all read this metadata
(:func:`spec_of`, :func:`specs`): a default, unit or range is written here and nowhere else.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import re
import types
import typing
from collections.abc import Callable, Iterator, Mapping
from dataclasses import MISSING, dataclass
from typing import TYPE_CHECKING, Any, Literal

from hybrid_force import _checks as checks

if TYPE_CHECKING:
    from hybrid_force.errors import BadInputError

__all__ = [
    "MISSING_VALUE",
    "Param",
    "check_fields",
    "declared",
    "default_of",
    "param",
    "spec_of",
    "specs",
    "value_kind",
]


class _Required:
    """The default of a field that has none (it is required)."""

    def __repr__(self) -> str:
        return "<required>"


MISSING_VALUE: Any = _Required()
"""What :func:`default_of` returns for a required field (no default)."""

_KEY = "hybrid_force"


@dataclass(frozen=True)
class Param:
    """What a field accepts, beside its type and default.

    Attributes:
        doc: one line: what it is (no unit, no default: both are shown from here).
        unit: its unit ("s", "N", "m", "rad", "rad/s or m/s"; "" when dimensionless).
        minimum, maximum: the range of a number (None: unbounded on that side).
        strict: the range's ends are excluded.
        choices: the values a text may take (empty: any).
        key: the TOML key, when it differs from the field name (e.g. ``baumgarte_alpha``).
        toml: False: the field is set from Python only (no TOML key).
    """

    doc: str = ""
    unit: str = ""
    minimum: float | None = None
    maximum: float | None = None
    strict: bool = False
    choices: tuple[Any, ...] = ()
    key: str | None = None
    toml: bool = True


def param(
    default: Any = MISSING,
    *,
    default_factory: Callable[[], Any] | Any = MISSING,
    doc: str = "",
    unit: str = "",
    minimum: float | None = None,
    maximum: float | None = None,
    strict: bool = False,
    choices: tuple[Any, ...] = (),
    key: str | None = None,
    toml: bool = True,
) -> Any:
    """A dataclass field with its :class:`Param` metadata (``dataclasses.field`` otherwise)."""
    meta = {_KEY: Param(doc, unit, minimum, maximum, strict, tuple(choices), key, toml)}
    if default_factory is not MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def spec_of(f: dataclasses.Field[Any]) -> Param:
    """The :class:`Param` of a field (an empty one when it was declared without :func:`param`)."""
    found = f.metadata.get(_KEY)
    return found if isinstance(found, Param) else Param()


def declared(f: dataclasses.Field[Any]) -> bool:
    """The field was declared with :func:`param`."""
    return isinstance(f.metadata.get(_KEY), Param)


def default_of(f: dataclasses.Field[Any]) -> Any:
    """A field's default (its factory called), or :data:`MISSING_VALUE` when it has none."""
    if f.default is not MISSING:
        return f.default
    if f.default_factory is not MISSING:
        return f.default_factory()
    return MISSING_VALUE


def specs(cls: type) -> Iterator[tuple[dataclasses.Field[Any], Param]]:
    """The fields of a dataclass with their :class:`Param`, in declaration order."""
    for f in dataclasses.fields(cls):
        yield f, spec_of(f)


@functools.cache
def _kinds(cls: type) -> dict[str, tuple[str, tuple[Any, ...]]]:
    return {f.name: _kind(typing.get_type_hints(cls)[f.name]) for f in dataclasses.fields(cls)}


def value_kind(cls: type, f: dataclasses.Field[Any]) -> tuple[str, tuple[Any, ...]]:
    """(kind, choices) of a field's TOML value, from its type: "bool", "integer", "number",
    "str", "choice" (a ``Literal``: its values), "vec3" (3 floats), "vector" (floats),
    "points" (a list of vectors),
    "number_or_vector" (``float | tuple[float, ...]``), "matrix" (``float | np.ndarray``: a
    number, a vector or a matrix), "table" (a nested settings dataclass, whose fields are keys
    of the same table), "typed_table" (a union of settings dataclasses each with a ``kind``: a
    subtable ``[table.key]`` whose ``type`` is one of the kinds; the choices are the classes)
    or "any" (the table's own code reads it). ``X | None`` is read as X."""
    return _kinds(cls)[f.name]


def _kinded(hint: Any) -> bool:
    """A settings dataclass with a ``kind`` (the ``type`` of its subtable)."""
    return dataclasses.is_dataclass(hint) and isinstance(getattr(hint, "kind", None), str)


def _kind(hint: Any) -> tuple[str, tuple[Any, ...]]:
    args = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        rest = tuple(a for a in args if a is not type(None))
        if len(rest) == 1:
            return _kind(rest[0])
        if float in rest and tuple[float, ...] in rest:
            return "number_or_vector", ()
        if float in rest and any(getattr(a, "__name__", "") == "ndarray" for a in rest):
            return "matrix", ()
        if all(_kinded(a) for a in rest):
            return "typed_table", rest  # a subtable [table.key] whose ``type`` picks the class
        return "any", ()
    if typing.get_origin(hint) is Literal:
        return "choice", args
    if typing.get_origin(hint) is tuple:
        if args == (float, float, float):
            return "vec3", ()
        if args == (float, ...):
            return "vector", ()
        if args == (tuple[float, ...], ...):
            return "points", ()
    if dataclasses.is_dataclass(hint):
        return "table", ()
    simple = {bool: "bool", int: "integer", float: "number", str: "str"}
    return simple.get(hint, "any"), ()


def check_fields(obj: Any, error: type[BadInputError], prefix: str) -> None:
    """The generic check of a settings dataclass, from its fields' :class:`Param`: each
    number finite and within its range (stored as a float), each integer whole and within
    its range, each flag a bool, each text one of its choices. A field whose default is None
    may be None. Other kinds are left to the class. Raises ``error`` naming the field as
    ``prefix`` + its key (``"sim.dt"``), with its value and what is valid."""

    cls = type(obj)
    for f, spec in specs(cls):
        value = getattr(obj, f.name)
        if not declared(f) or (value is None and default_of(f) is None):
            continue
        kind, choices = value_kind(cls, f)
        what = f"{prefix}{spec.key or f.name}"
        try:
            value = _check_one(checks, kind, choices, spec, value, what, error)
        except error as exc:
            raise error(str(exc), key=what, value=value) from None
        object.__setattr__(obj, f.name, value)


def _check_one(
    checks: Any,
    kind: str,
    choices: tuple[Any, ...],
    spec: Param,
    value: Any,
    what: str,
    error: type[BadInputError],
) -> Any:
    """One field's value checked by its kind and :class:`Param` (:func:`check_fields`)."""
    low, high = spec.minimum, spec.maximum
    if kind == "number":
        return checks.number(
            value, what, error, minimum=low, strict=spec.strict, maximum=high, unit=spec.unit
        )
    if kind == "integer":
        return checks.integer(
            value,
            what,
            error,
            minimum=int(low if low is not None else -(2**63)),
            maximum=None if high is None else int(high),
        )
    if kind == "bool":
        return checks.flag(value, what, error)
    if kind == "choice" or spec.choices:
        return checks.one_of(value, what, error, [str(c) for c in spec.choices or choices])
    return value


# --- a table's keys, read from the declarations --------------------------------------------------
@dataclass(frozen=True)
class Key:
    """One key of a table: its kind of value and whether it is required.

    kinds: "str", "number", "integer" (a whole number), "bool", "vec3" (3 numbers), "vector"
    (a list of numbers),
    "number_or_vector", "matrix" (a number, a list of numbers or a list of lists of numbers),
    "points" (a list of lists of numbers),
    "choice" (one of ``choices``), "str_list" (a list of non-empty strings), "str_table" (a
    table of texts: strings, or numbers and booleans turned into their TOML text),
    "law_table" (a control law's own settings, checked against the law's keys),
    "typed_table" (a subtable with a ``type`` key choosing its keys, ``tables``).
    ``param``: the field's declaration, whose range a number is checked against.
    """

    kind: str
    required: bool = False
    choices: tuple[str, ...] = ()
    param: Param | None = None
    default: Any = MISSING_VALUE
    tables: Mapping[str, Mapping[str, Key]] | None = None
    """A "typed_table" key's subtable keys, by its ``type``."""


def keys_of(cls: type) -> dict[str, Key]:
    """The keys of a table read into dataclass ``cls``: one per field declared with
    :func:`~hybrid_force.schema.param` (its ``key`` or name), its kind from the field's type,
    required when the field has no default; a nested settings dataclass's keys are the
    table's own (``sim.baumgarte_alpha``)."""
    out: dict[str, Key] = {}
    for f, spec in specs(cls):
        if declared(f) and spec.toml:
            kind, choices = value_kind(cls, f)
            if kind == "table":
                out.update(keys_of(typing.get_type_hints(cls)[f.name]))
                continue
            default = default_of(f)
            if kind == "typed_table":
                tables = {c.kind: keys_of(c) for c in choices}
                out[spec.key or f.name] = Key(
                    kind, default is MISSING_VALUE, (), spec, default, tables
                )
                continue
            keyed = Key(
                kind, default is MISSING_VALUE, tuple(spec.choices or choices), spec, default
            )
            out[spec.key or f.name] = keyed
    return out


def arguments(cls: type, values: Mapping[str, Any]) -> dict[str, Any]:
    """The keyword arguments of ``cls`` from a table's checked ``values`` (by TOML key):
    each given key under its field's name, a nested settings dataclass built from its own."""
    out: dict[str, Any] = {}
    for f, spec in specs(cls):
        if not (declared(f) and spec.toml):
            continue
        kind, choices = value_kind(cls, f)
        if kind == "table":
            nested = typing.get_type_hints(cls)[f.name]
            given = arguments(nested, values)
            if given:
                out[f.name] = nested(**given)
        elif kind == "typed_table" and isinstance(values.get(spec.key or f.name), Mapping):
            sub = dict(values[spec.key or f.name])
            chosen = next(c for c in choices if c.kind == sub.pop("type"))
            out[f.name] = chosen(**arguments(chosen, sub))
        elif (spec.key or f.name) in values:
            out[f.name] = values[spec.key or f.name]
    return out


# --- the reference: JSON Schema and Markdown tables of the same keys ----------------------------
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
    "law_table": {"type": "object"},
}


def json_key(key: Key) -> dict[str, Any]:
    if key.kind == "typed_table" and key.tables is not None:
        out: dict[str, Any] = {"oneOf": [json_table(k, kind) for kind, k in key.tables.items()]}
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


def json_table(keys: Mapping[str, Key], kind: str | None = None) -> dict[str, Any]:
    properties = {name: json_key(key) for name, key in keys.items()}
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


_TYPE_TEXT = {
    "str": "string",
    "bool": "bool",
    "number": "number",
    "integer": "integer",
    "vec3": "3 numbers",
    "vector": "numbers",
    "points": "array of points",
    "number_or_vector": "number or numbers",
    "matrix": "number, numbers or matrix",
    "law_table": "table",
    "typed_table": "table",
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


def markdown_row(name: str, key: Key) -> str:
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
    elif key.default is None:
        default = "none"
    else:
        default = f"`{_toml_text(key.default)}`"
    meaning = spec.doc + (f" [{spec.unit}]" if spec.unit else "")
    return f"| `{name}` | {kind} | {default} | {meaning} |"


_MARKER = re.compile(r"(<!-- generated: (\S+) -->\n)(.*?)(\n<!-- end generated -->)", re.S)


def with_tables(text: str, tables: dict[str, str]) -> str:
    """``text`` with each block ``<!-- generated: NAME -->`` ... ``<!-- end generated -->``
    holding ``tables[NAME]``."""
    return _MARKER.sub(lambda m: m[1] + tables.get(m[2], f"(no table {m[2]})") + m[4], text)

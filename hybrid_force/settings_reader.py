"""The one reader of a scenario file's tables: a TOML table → its settings dataclass, its keys,
kinds, ranges, defaults and the rules of when a key acts all read from the fields'
:func:`~hybrid_force.schema.param` (:func:`keys_of`). Every refusal names the file, the
``table.key`` and the value as written (``x.toml: sim.dt = "1e-3": must be a number [s], got
a string``)."""

from __future__ import annotations

import math
import typing
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from hybrid_force._file_errors import _Context, _fmt, _wrap
from hybrid_force.errors import BadInputError, RunWarning, did_you_mean
from hybrid_force.model.xacro_files import xacro_argument_text
from hybrid_force.schema import MISSING_VALUE, Param, declared, default_of, specs, value_kind

__all__ = ["Key", "check_acting", "check_table", "keys_of", "read_settings", "typed_table"]


@dataclass(frozen=True)
class Key:
    """One key of a table: its kind of value (:func:`~hybrid_force.schema.value_kind`'s, and
    "str_list": non-empty strings, "str_table": texts by name, "table": a sub-table read by
    its own keys, "typed_table": a sub-table whose ``type`` picks its keys, ``tables``), whether
    it is required, its choices, declaration and default."""

    kind: str
    required: bool = False
    choices: tuple[str, ...] = ()
    param: Param | None = None
    default: Any = MISSING_VALUE
    tables: Mapping[str, Mapping[str, Key]] | None = None


def keys_of(cls: type) -> dict[str, Key]:
    """The keys of dataclass ``cls``'s table: one per TOML field (its ``key`` or name), kind
    from its type, required when it has no default; a nested settings dataclass's keys are
    the table's own (``sim.baumgarte_alpha``), acting when the nested field does."""
    out: dict[str, Key] = {}
    for f, spec in specs(cls):
        if declared(f) and spec.toml:
            kind, choices = value_kind(cls, f)
            if kind == "table":
                for name, key in keys_of(typing.get_type_hints(cls)[f.name]).items():
                    rule = key.param.acts_when if key.param else ()
                    inherited = Param(**{**vars(key.param), "acts_when": rule or spec.acts_when})
                    out[name] = Key(key.kind, key.required, key.choices, inherited, key.default)
                continue
            default = default_of(f)
            tables = {c.kind: keys_of(c) for c in choices} if kind == "typed_table" else None
            choices = () if tables else tuple(spec.choices or choices)
            key = Key(kind, default is MISSING_VALUE, choices, spec, default, tables)
            out[spec.key or f.name] = key
    return out


def arguments(cls: type, values: Mapping[str, Any]) -> dict[str, Any]:
    """The keyword arguments of ``cls`` from a table's checked ``values`` (by TOML key), a
    nested settings dataclass built from its own keys."""
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
            kind = sub.pop("type")
            chosen = next(c for c in choices if c.kind == kind)
            out[f.name] = chosen(**arguments(chosen, sub))
        elif (spec.key or f.name) in values:
            out[f.name] = values[spec.key or f.name]
    return out


def type_name(value: object) -> str:
    """A TOML value's kind in words ("a string", "an array")."""
    for kind, name in ((bool, "a boolean"), (int | float, "a number"), (str, "a string")):
        if isinstance(value, kind):
            return name
    names: dict[type, str] = {list: "an array", dict: "a table"}
    return names.get(type(value), f"a {type(value).__name__}")


def suggest(word: str, choices: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"``: difflib's match, else a case-insensitive or prefix one."""
    options = list(choices)
    hint = did_you_mean(word, options)
    low = word.lower()
    for option in options if not hint else ():
        o = option.lower()
        if o == low or (len(o) >= 3 and low.startswith(o)) or (len(low) >= 3 and o.startswith(low)):
            return f" (did you mean '{option}'?)"
    return hint


_VECTORS = {
    "vec3": "3 numbers",
    "vector": "an array of numbers",
    "number_or_vector": "a number or an array of numbers",
    "matrix": "a number, an array or a matrix of numbers",
    "points": "an array of points, each an array of numbers ([[x, y, z], ...] or [[u, v], ...])",
}
_TYPES: dict[str, tuple[type, str]] = {
    "str": (str, "a string"),
    "bool": (bool, "true or false"),
    "str_list": (list, "an array of strings"),
    "str_table": (dict, 'a table of texts {name = "value"}'),
}


def check_value(ctx: _Context, key: str, value: Any, spec: Key) -> Any:
    """One value checked against its key (kind, choices, range); returned as Python data
    (floats for numbers, lists of floats for vectors, texts for a ``str_table``)."""
    kind = spec.kind
    if kind in ("number", "integer") or (kind in _VECTORS and not isinstance(value, list)):
        if kind in ("vec3", "vector", "points"):
            raise ctx.error(key, value, f"must be {_VECTORS[kind]}, got {type_name(value)}")
        what = _VECTORS[kind] if kind == "number_or_vector" else "a number"
        return _number(ctx, key, value, spec.param, kind == "integer", what)
    if kind in _VECTORS:
        return _vectors(ctx, key, value, kind)
    if kind == "choice":
        if not isinstance(value, str) or value not in spec.choices:
            hint = suggest(value, spec.choices) if isinstance(value, str) else ""
            raise ctx.error(key, value, f"must be one of {list(spec.choices)}{hint}")
        return value
    if kind == "typed_table" and spec.tables is not None:
        chosen, values = typed_table(ctx, key, value, spec.tables)
        return {"type": chosen, **values}
    if kind == "table":
        if not isinstance(value, dict):
            raise ctx.error(key, value, f"must be a table [{key}], got {type_name(value)}")
        return value
    expected, what = _TYPES[kind]
    fits = isinstance(value, expected)  # (not narrowing ``value``: its kind says what it is)
    if not fits:
        raise ctx.error(key, value, f"must be {what}, got {type_name(value)}")
    if kind == "str_list":
        for i, x in enumerate(value):
            if not isinstance(x, str) or not x:
                problem = type_name(x) if not isinstance(x, str) else "empty"
                raise ctx.error(
                    key, value, f"must be an array of non-empty strings; element {i} is {problem}"
                )
        return list(value)
    if kind == "str_table":
        for name, x in value.items():
            if not isinstance(x, str | bool):
                _number(ctx, f"{key}.{name}", x, None, False, "a text (a string)")
        return {name: xacro_argument_text(x) for name, x in value.items()}
    return value


def _number(
    ctx: _Context,
    key: str,
    value: object,
    spec: Param | None,
    whole: bool,
    what: str = "a number",
) -> Any:
    """A finite number (a whole one when ``whole``) within ``spec``'s range, as a float."""
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or (whole and isinstance(value, float))
    ):
        need = "a whole number" if whole else what
        raise ctx.error(key, value, f"must be {need}, got {type_name(value)}")
    if whole:
        return value
    try:
        x = float(value)
    except OverflowError:  # an integer beyond float range, e.g. 10**400
        x = math.inf
    if not math.isfinite(x):
        raise ctx.error(key, value, "must be a finite number")
    if spec is None:
        return x
    low, high, strict = spec.minimum, spec.maximum, spec.strict
    unit = f" [{spec.unit}]" if spec.unit else ""
    if (
        low is not None
        and high is not None
        and not (low < x < high or (not strict and low <= x <= high))
    ):
        ends = "()" if strict else "[]"
        raise ctx.error(key, value, f"must be in {ends[0]}{low:g}, {high:g}{ends[1]}{unit}")
    if low is not None and (x <= low if strict else x < low):
        rule = (
            "a positive number (> 0)"
            if strict and low == 0
            else f"{'>' if strict else '>='} {low:g}"
        )
        raise ctx.error(key, value, f"must be {rule}{unit}")
    return x


def _vectors(ctx: _Context, key: str, value: list[Any], kind: str) -> Any:
    """A list of numbers, or of lists of numbers (``points``, a ``matrix``), as floats."""
    what = _VECTORS[kind]
    if kind == "matrix" and value and all(isinstance(r, list) for r in value):
        what, kind = "a matrix (array of arrays of numbers)", "points"
    if kind == "points":
        if not all(isinstance(row, list) for row in value):
            raise ctx.error(key, value, f"must be {what}")
        rows = [_vector(ctx, key, row, what) for row in value]
        if what.startswith("a matrix") and len({len(r) for r in rows}) != 1:
            raise ctx.error(key, value, "the rows of the matrix have different lengths")
        return rows
    vec = _vector(ctx, key, value, what)
    if kind == "vec3" and len(vec) != 3:
        raise ctx.error(key, value, f"must be 3 numbers [x, y, z], got {len(vec)}")
    return vec


def _vector(ctx: _Context, key: str, value: object, what: str) -> list[float]:
    if not isinstance(value, list):
        raise ctx.error(key, value, f"must be {what}, got {type_name(value)}")
    out: list[float] = []
    for i, x in enumerate(value):
        if isinstance(x, bool) or not isinstance(x, int | float):
            raise ctx.error(key, value, f"must be {what}; element {i} is {type_name(x)}")
        try:
            out.append(float(x))
        except OverflowError:
            out.append(math.inf)
        if not math.isfinite(out[-1]):
            raise ctx.error(key, value, f"must be {what}; element {i} is not finite")
    return out


def check_table(
    ctx: _Context, name: str, table: object, schema: Mapping[str, Key], label: str = ""
) -> dict[str, Any]:
    """A table's keys (unknown ones with a did-you-mean, missing required ones) and values
    checked; returns the checked values by key. ``label``: the unknown key's "for a plane"."""
    if not isinstance(table, dict):
        raise ctx.error(name, table, f"must be a table [{name}], got {type_name(table)}")
    prefix = f"{name}." if name else ""
    where = f"[{name}]" if name else "the top level"
    for key, value in table.items():
        if key not in schema:
            valid = (
                f"valid keys: type, {', '.join(schema)}"
                if label
                else (f"valid keys of {where}: {', '.join(schema)}")
            )
            raise ctx.error(
                f"{prefix}{key}", value, f"unknown key{label}{suggest(key, schema)}; {valid}"
            )
    out = {
        key: check_value(ctx, f"{prefix}{key}", value, schema[key]) for key, value in table.items()
    }
    for key, spec in schema.items():
        if spec.required and key not in table:
            raise ctx.table_error(
                f"{prefix}{key}",
                f"missing required key; {where} has {_fmt(sorted(table))}, required: "
                f"{', '.join(k for k, s in schema.items() if s.required)}",
            )
    return out


def read_settings(
    ctx: _Context, name: str, cls: type, table: object, values: Mapping[str, Any] | None = None
) -> Any:
    """[name] → an instance of dataclass ``cls``; ``values``: the table already checked
    (:func:`check_table`). The constructor's refusal names its key."""
    if values is None:
        values = check_table(ctx, name, table, keys_of(cls))
    try:
        return cls(**arguments(cls, values))
    except BadInputError as exc:
        raise _wrap(ctx, name, values, exc) from None


def typed_table(
    ctx: _Context, name: str, table: object, types: Mapping[str, Mapping[str, Key]]
) -> tuple[str, dict[str, Any]]:
    """A table whose ``type`` key selects its keys; returns (type, checked values)."""
    if not isinstance(table, dict):
        raise ctx.error(name, table, f"must be a table, got {type_name(table)}")
    if "type" not in table:
        raise ctx.table_error(
            f"{name}.type", f"missing required key; valid types: {', '.join(types)}"
        )
    kind = table["type"]
    if not isinstance(kind, str) or kind not in types:
        hint = suggest(kind, types) if isinstance(kind, str) else ""
        raise ctx.error(
            f"{name}.type", kind, f"unknown type{hint}; valid types: {', '.join(types)}"
        )
    rest = {k: v for k, v in table.items() if k != "type"}
    label = f" for {'an' if kind[0] in 'aeiou' else 'a'} {kind}"
    return kind, check_table(ctx, name, rest, types[kind], label)


def no_effect(ctx: _Context, key: str, value: object, needs: str) -> BadInputError:
    """The refusal of a key given where it has no effect (it acts only with ``needs``)."""
    return ctx.error(
        key,
        value,
        f"has no effect in this configuration; it acts only with {needs}: remove it, or set "
        "what makes it act",
    )


def check_acting(
    ctx: _Context,
    doc: dict[str, Any],
    values: Mapping[str, dict[str, Any]],
    tables: Mapping[str, Mapping[str, Key]],
) -> None:
    """The rules of the keys that act only in some configurations, read from their
    declarations (:class:`~hybrid_force.schema.Param` ``acts_when``, ``inert``).

    ``values``: each table's checked values by its name (``"contact"``,
    ``"control.impedance"``); ``tables``: the keys of each. A key given where its rule does
    not hold is refused (naming the file, key, value and what makes it act); a key no
    configuration reads is warned about and removed from ``values`` and ``doc`` (in place: the
    run's recorded scenario then does not list it)."""
    for table, given in values.items():
        node: Any = doc  # the table as written
        for part in table.split("."):  # "surfaces.1": the second [[surfaces]] table
            node = node[int(part)] if isinstance(node, list) else node.get(part, {})
        for key in list(given):
            spec = tables[table][key].param if key in tables[table] else None  # trajectory.type
            if spec is not None and spec.inert:
                del given[key]
                warnings.warn(
                    RunWarning(
                        f"{ctx.file}: {table}.{key} = {_fmt(node.pop(key))} has no effect in any "
                        f"configuration ({spec.inert}); it is left out of the run's settings"
                    ),
                    stacklevel=3,
                )
            elif spec is not None and spec.acts_when:
                other, *op, wanted = spec.acts_when
                where, _, name = other.rpartition(".") if "." in other else (table, "", other)
                got = values.get(where, {})
                now = got[name] if name in got else tables[where][name].default
                if op == ["in"]:
                    acts, shown = now in wanted, " or ".join(_fmt(w) for w in wanted)
                    needs = f"{where}.{name} = {shown}"
                else:
                    acts = now > wanted if op == [">"] else now == wanted
                    needs = f"{where}.{name} {op[0] if op else '='} {_fmt(wanted)}"
                if not acts:
                    raise no_effect(ctx, f"{table}.{key}", node[key], needs)

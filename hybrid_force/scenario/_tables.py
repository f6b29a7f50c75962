"""The scenario file's vocabulary: the keys of each table, their kinds of value, and the
checks and messages every table shares (:class:`_Context`, :func:`_check_table`, :func:`_wrap`),
with ``--set`` overrides (:func:`parse_override`).

A message names the file, the ``table.key`` and the offending value, the format
:mod:`hybrid_force.scenario.loader` documents.
"""

from __future__ import annotations

import json
import math
import re
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from hybrid_force.control.laws.base import check_options, law_names
from hybrid_force.control.tool import ORIENTATIONS, ROLLS
from hybrid_force.errors import BadInputError, ScenarioError, did_you_mean


# --- schema --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Key:
    """One key of a table: its kind of value and whether it is required.

    kinds: "str", "number", "integer" (a whole number), "bool", "vec3" (3 numbers), "vector"
    (a list of numbers),
    "number_or_vector", "matrix" (a number, a list of numbers or a list of lists of numbers),
    "points" (a list of lists of numbers),
    "choice" (one of ``choices``), "str_list" (a list of non-empty strings), "str_table" (a
    table of texts: strings, or numbers and booleans turned into their TOML text),
    "law_table" (a control law's own settings, checked against the law's keys).
    """

    kind: str
    required: bool = False
    choices: tuple[str, ...] = ()


_TOP: dict[str, _Key] = {"name": _Key("str", True), "description": _Key("str")}
_TABLES = (
    "robot", "surface", "surfaces", "trajectory", "initial", "control", "sensor", "contact", "sim",
    "tool",
)  # fmt: skip

_ROBOT: dict[str, _Key] = {
    "model": _Key("str", True),
    "tip": _Key("str"),
    "package_dirs": _Key("str_list"),
    "xacro_args": _Key("str_table"),
    "lock_off_chain": _Key("bool"),
}

_SURFACE_TYPES = ("cylinder", "sphere", "plane")
_SURFACE: dict[str, dict[str, _Key]] = {
    "cylinder": {
        "radius": _Key("number", True),
        "center": _Key("vec3"),
        "axis": _Key("vec3"),
        "inside": _Key("bool"),
    },
    "sphere": {"radius": _Key("number", True), "center": _Key("vec3"), "inside": _Key("bool")},
    "plane": {"point": _Key("vec3", True), "normal": _Key("vec3", True)},
}

_PATH_TYPES = ("helix", "circle", "waypoints", "raster")
_TRAJECTORY: dict[str, dict[str, _Key]] = {
    "helix": {
        "center": _Key("vec3", True),
        "radius": _Key("number", True),
        "axis": _Key("vec3"),
        "omega": _Key("number", True),
        "rise": _Key("number", True),
        "phase": _Key("number"),
    },
    "circle": {
        "center": _Key("vec3", True),
        "radius": _Key("number", True),
        "normal": _Key("vec3", True),
        "omega": _Key("number", True),
        "phase": _Key("number"),
    },
    # paths on a surface (hybrid_force.geometry.waypoints, .raster): `surface` is the index of
    # the [[surfaces]] table they lie on
    "waypoints": {
        "points": _Key("points", True),
        "speed": _Key("number", True),
        "frame": _Key("choice", choices=("world", "surface")),
        "surface": _Key("integer"),
        "ramp": _Key("number"),
        "u_axis": _Key("vec3"),
        "projection_tol": _Key("number"),
    },
    "raster": {
        "origin": _Key("vector", True),
        "size": _Key("vector", True),
        "spacing": _Key("number", True),
        "speed": _Key("number", True),
        "direction": _Key("choice", choices=("u", "v")),
        "surface": _Key("integer"),
        "ramp": _Key("number"),
        "u_axis": _Key("vec3"),
    },
}

_INITIAL: dict[str, _Key] = {
    "tip": _Key("vec3"),
    "seed": _Key("vector"),
    "q": _Key("vector"),
    "v": _Key("vector"),
}

_CONTROL: dict[str, _Key] = {
    "Kd": _Key("matrix"),
    "kd_rate": _Key("number"),
    "Lambda": _Key("number"),
    "beta": _Key("number"),
    "gamma": _Key("number"),
    "f_d": _Key("number_or_vector"),
    "clik_gain": _Key("number"),
    "max_dist": _Key("number"),
    "contact_tol": _Key("number"),
    "P": _Key("number"),
    "approach_rate": _Key("number"),
    "supervisor": _Key("bool"),
    "rate": _Key("number"),
    "law": _Key("choice", choices=law_names()),
    "model": _Key("str"),
    # [control.<law>]: each law's own settings (hybrid_force.control.laws.base.LAWS)
    **{name: _Key("law_table") for name in law_names()},
}

_TOOL: dict[str, _Key] = {
    "axis": _Key("vec3"),
    "orientation": _Key("choice", choices=ORIENTATIONS),
    "tilt": _Key("number"),
    "tilt_axis": _Key("vec3"),
    "roll": _Key("choice", choices=ROLLS),
}

_SIM: dict[str, _Key] = {
    "duration": _Key("number"),
    "dt": _Key("number"),
    "integrator": _Key("choice", choices=("euler", "rk4")),
    "baumgarte_alpha": _Key("number"),
    "baumgarte_beta": _Key("number"),
    "model_mass_factor": _Key("number"),
    "settle_time": _Key("number"),
    "unilateral": _Key("bool"),
    "normalization": _Key("choice", choices=("tip", "joint")),
    "seed": _Key("integer"),
    "torque_limits": _Key("bool"),
    "joint_limits": _Key("choice", choices=("report", "stop")),
    "joint_friction_velocity": _Key("number"),
}

_CONTACT: dict[str, _Key] = {
    "model": _Key("choice", choices=("rigid", "compliant")),
    "stiffness": _Key("number"),
    "damping": _Key("number"),
    "exponent": _Key("number"),
    "friction": _Key("number"),
    "friction_velocity": _Key("number"),
}

_SENSOR: dict[str, _Key] = {
    "force_noise": _Key("number"),
    "force_bias": _Key("number"),
    "force_cutoff": _Key("number"),
    "force_delay": _Key("integer"),
    "joint_noise": _Key("number"),
    "velocity_noise": _Key("number"),
}


# --- messages ------------------------------------------------------------------------------------
def _fmt(value: object) -> str:
    """A value as it would be written in TOML (JSON is close enough), shortened."""
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= 100 else text[:97] + "..."


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


class _Context:
    """Builds error messages for one file: ``<file>: <table.key> = <value>: <problem>``."""

    def __init__(self, file: str) -> None:
        self.file = file

    def error(self, key: str, value: object, problem: str) -> ScenarioError:
        return ScenarioError(
            f"{self.file}: {key} = {_fmt(value)}: {problem}", key=key, value=value, file=self.file
        )

    def table_error(self, key: str, problem: str) -> ScenarioError:
        return ScenarioError(f"{self.file}: {key}: {problem}", key=key, file=self.file)


# --- overrides -----------------------------------------------------------------------------------
def parse_override(text: str) -> tuple[str, object]:
    """Split ``"table.key=value"`` into ``("table.key", value)``.

    The value is parsed as a TOML value (``tomllib.loads(f"v = {value}")``), so ``0.5``,
    ``1e-3``, ``true``, ``[1, 2, 3]`` and ``"text"`` have their TOML types; anything that is
    not valid TOML (``rk4``, ``__import__('os')``) stays the raw string. Nothing is evaluated.

    Raises ScenarioError when there is no ``=`` or the key is empty.
    """
    if not isinstance(text, str) or "=" not in text:
        raise ScenarioError(f"override {text!r} must look like table.key=value (e.g. sim.dt=1e-3)")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise ScenarioError(f"override {text!r} has an empty key; use table.key=value")
    raw = raw.strip()
    try:
        value: object = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    except RecursionError:
        raise ScenarioError(f"override {key!r}: its value is nested too deeply") from None
    return key, value


def _apply_overrides(doc: dict[str, Any], overrides: Mapping[str, object], ctx: _Context) -> None:
    """Set ``doc[table][key] = value`` for each ``"table.key"`` (in place).

    ``"name"`` sets a top-level key; ``"surfaces.<i>.key"`` a key of the i-th [[surfaces]].
    A missing table is created (validation then reports it if it is unknown).
    """
    for dotted, value in overrides.items():
        parts = str(dotted).split(".")
        node: Any = doc
        where: list[str] = []
        for part in parts[:-1]:
            where.append(part)
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise ctx.table_error(
                        ".".join(where),
                        f"override {dotted!r}: index {part!r} is not one of "
                        f"0..{len(node) - 1} of this array of tables",
                    )
                node = node[int(part)]
                continue
            if not isinstance(node, dict):
                raise ctx.table_error(
                    ".".join(where[:-1]), f"override {dotted!r}: this is not a table"
                )
            node = node.setdefault(part, {})
        if not isinstance(node, dict):
            raise ctx.table_error(".".join(where), f"override {dotted!r}: this is not a table")
        node[parts[-1]] = value


# --- type checks ---------------------------------------------------------------------------------
def _is_number(x: object) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _check_value(ctx: _Context, key: str, value: object, spec: _Key) -> object:
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
        return _number(ctx, key, value)
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
    ctx: _Context, name: str, table: object, schema: Mapping[str, _Key]
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


def _typed_table(
    ctx: _Context, name: str, table: object, types: Mapping[str, Mapping[str, _Key]]
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
            raise ctx.error(
                f"{name}.{key}",
                rest[key],
                f"unknown key for a {kind}{_suggest(key, schema)}; valid keys: type, "
                f"{', '.join(schema)}",
            )
    return kind, _check_table(ctx, name, rest, schema)


def _wrap(
    ctx: _Context, table: str, values: Mapping[str, Any], exc: BaseException
) -> ScenarioError:
    """Re-raise a constructor's BadInputError naming the file and the key it is about."""
    message = " ".join(str(exc).split())
    for key in sorted(values, key=len, reverse=True):
        if re.search(rf"(?<![A-Za-z_]){re.escape(key)}(?![A-Za-z_])", message):
            return ctx.error(f"{table}.{key}", values[key], message)
    shown = ", ".join(f"{table}.{k} = {_fmt(v)}" for k, v in values.items())
    return ScenarioError(f"{ctx.file}: {shown or table}: {message}")


def xacro_argument_text(value: object) -> str:
    """The text a ``robot.xacro_args`` value passes to xacro: a string as is, a boolean as
    ``true``/``false``, an integer in decimal, a float as Python's shortest repr (``0.7``)."""
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    raise TypeError(f"a xacro argument must be a string, number or boolean, got {value!r}")

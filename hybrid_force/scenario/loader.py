"""Scenario files: one TOML file describes one run (robot, surfaces, path, start, gains, sim).

:func:`load_scenario` reads a file, applies ``--set``-style overrides, validates every table
and key, and returns the :class:`hybrid_force.sim.loop.Scenario` that
:func:`hybrid_force.sim.loop.simulate` runs. The format is documented in docs/scenarios.md.

Validation is done up front so a bad file fails in milliseconds, not after a long run. Every
problem raises :class:`~hybrid_force.errors.ScenarioError` whose message names the file, the
``table.key`` and the offending value, e.g.::

    scenarios/x.toml: surface.radius = "0.4": must be a number [m], got a string

Checked: TOML syntax (with tomllib's line and column), unknown tables and keys (with a
did-you-mean), missing required keys, types and shapes, parameter ranges (by the constructors
of the surfaces, paths and settings), the desired path lying on every surface over
[0, sim.duration] (within 1e-6 m), the start in reach (inverse kinematics), the start on the
surface when the run starts in contact (``control.supervisor = false``), and the gains.

No Python code or expression is ever evaluated: values are plain TOML data, and a string
where a number is expected is an error, whatever it contains.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hybrid_force.control.controller import LAWS
from hybrid_force.errors import (
    BadInputError,
    FrameError,
    ReachError,
    RobotError,
    ScenarioError,
    did_you_mean,
)

if TYPE_CHECKING:  # annotations only: the loader imports these where it builds them
    from hybrid_force.geometry.paths import Path as DesiredPath
    from hybrid_force.geometry.surfaces import Surface
from hybrid_force.geometry.paths import (
    ON_SURFACE_TOL,  # re-exported: the loader's and Scenario's rule
)

__all__ = [
    "ON_SURFACE_TOL",
    "RobotTable",
    "load_scenario",
    "parse_override",
    "read_scenario_document",
    "resolve_robot_table",
    "scenario_from_document",
    "xacro_argument_text",
]

MAX_FILE_BYTES = 1 << 20
"""Largest scenario file read [bytes]: a scenario is a page of text, never megabytes."""

PATH_CHECK_STEP = 0.02
"""Spacing [s] of the samples at which the loader follows the desired path by inverse
kinematics (at most :data:`PATH_CHECK_SAMPLES` samples over [0, sim.duration])."""
PATH_CHECK_SAMPLES = 1000


# --- schema --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Key:
    """One key of a table: its kind of value and whether it is required.

    kinds: "str", "number", "integer" (a whole number), "bool", "vec3" (3 numbers), "vector"
    (a list of numbers),
    "number_or_vector", "matrix" (a number, a list of numbers or a list of lists of numbers),
    "choice" (one of ``choices``), "str_list" (a list of non-empty strings), "str_table" (a
    table of texts: strings, or numbers and booleans turned into their TOML text).
    """

    kind: str
    required: bool = False
    choices: tuple[str, ...] = ()


_TOP: dict[str, _Key] = {"name": _Key("str", True), "description": _Key("str")}
_TABLES = (
    "robot", "surface", "surfaces", "trajectory", "initial", "control", "sensor", "contact", "sim",
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

_PATH_TYPES = ("helix", "circle")
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
    "law": _Key("choice", choices=LAWS),
    "model": _Key("str"),
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


# --- the loader ----------------------------------------------------------------------------------
def _read(path: Path, ctx: _Context) -> dict[str, Any]:
    try:
        with path.open("rb") as fh:
            raw = fh.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError:
        raise ScenarioError(f"scenario file not found: {ctx.file}") from None
    except OSError as exc:
        raise ScenarioError(f"cannot read scenario file {ctx.file}: {exc}") from None
    if len(raw) > MAX_FILE_BYTES:
        raise ScenarioError(
            f"{ctx.file}: larger than {MAX_FILE_BYTES} bytes; a scenario file is a page of text"
        )
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{ctx.file}: not UTF-8 text ({exc})") from None
    return _parse_toml(text, ctx.file)


def _parse_toml(text: str, where: str) -> dict[str, Any]:
    """tomllib.loads with its failures as one-line ScenarioErrors (syntax, absurd nesting)."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{where}: TOML syntax error: {exc}") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise ScenarioError(
            f"{where}: arrays or tables nested too deeply (hundreds of levels); "
            "a scenario needs at most three"
        ) from None


def load_scenario(
    path: str | Path, overrides: Mapping[str, object] | None = None
) -> Any:  # -> hybrid_force.sim.loop.Scenario
    """Read, override, validate a scenario file and return a ``Scenario`` ready to simulate.

    Args:
        path: the TOML file (format: docs/scenarios.md).
        overrides: ``{"table.key": value}`` (e.g. from :func:`parse_override`), applied to
            the file's data before validation; they replace or add keys.

    Returns:
        :class:`hybrid_force.sim.loop.Scenario` with ``source`` = the file's data with the
        overrides applied (JSON-able).

    Raises:
        ScenarioError: any problem with the file; the message names the file, the
            ``table.key`` and the value.
    """
    file = Path(path)
    ctx = _Context(str(path))
    doc = _read(file, ctx)
    if overrides:
        _apply_overrides(doc, overrides, ctx)
    return _build(doc, file, ctx)


def read_scenario_document(
    path: str | Path, overrides: Mapping[str, object] | None = None
) -> dict[str, Any]:
    """The TOML data of a scenario file with the overrides applied, not yet validated.

    What :func:`scenario_from_document` takes: a sweep sends it to workers that may not see
    the file. ScenarioError for an unreadable file, bad TOML or an override that does not fit.
    """
    ctx = _Context(str(path))
    doc = _read(Path(path), ctx)
    if overrides:
        _apply_overrides(doc, overrides, ctx)
    return doc


def scenario_from_document(
    doc: Mapping[str, Any], *, origin: str = "<scenario>", base_dir: str | Path = "."
) -> Any:  # -> hybrid_force.sim.loop.Scenario
    """Validate scenario data (as :func:`read_scenario_document` returns) into a Scenario.

    Args:
        doc: the scenario's tables (a deep copy is taken; it is not modified).
        origin: how error messages name the scenario (a file name).
        base_dir: folder against which a relative ``robot.model`` path resolves.

    Raises:
        ScenarioError: as :func:`load_scenario`, naming ``origin``.
    """
    ctx = _Context(origin)
    return _build(copy.deepcopy(dict(doc)), Path(base_dir) / Path(origin).name, ctx)


def _build(doc: dict[str, Any], file: Path, ctx: _Context) -> Any:
    from hybrid_force.sim.loop import Scenario

    for key, value in doc.items():
        if key not in _TOP and key not in _TABLES:
            raise ctx.error(
                key,
                value,
                f"unknown top-level key or table{_suggest(key, [*_TOP, *_TABLES])}; valid: "
                f"{', '.join([*_TOP, *_TABLES])}",
            )
    top = _check_table(ctx, "", {k: v for k, v in doc.items() if k in _TOP}, _TOP)
    name = top["name"]
    if not (re.fullmatch(Scenario.NAME_PATTERN, name) and len(name) <= Scenario.NAME_MAX_LENGTH):
        raise ctx.error(
            "name",
            name,
            f"must be a simple name of 1 to {Scenario.NAME_MAX_LENGTH} letters, digits, '_', "
            "'-', '.' (not starting with '.' or '-'): it names the output folder runs/<name>/",
        )
    for table in ("robot", "trajectory", "initial"):
        if table not in doc:
            raise ctx.table_error(f"[{table}]", "missing required table")

    robot = _robot(doc["robot"], file, ctx)
    surfaces, surface_tables = _surfaces(doc, ctx)
    path, traj = _trajectory(doc["trajectory"], ctx)
    control_values = _check_table(ctx, "control", doc.get("control", {}), _CONTROL)
    sim_values = _check_table(ctx, "sim", doc.get("sim", {}), _SIM)
    sim = _sim_settings(sim_values, ctx)
    control = _control_settings(control_values, sim_values, robot, len(surfaces), ctx)
    sensor = _sensor_settings(doc.get("sensor", {}), ctx)
    contact = _contact_settings(doc.get("contact", {}), sim, ctx)
    controller_model = _controller_model(control_values, robot, file, ctx)
    _check_control_rate(control, sim, control_values, ctx)
    _check_path_on_surfaces(path, traj, surfaces, surface_tables, sim.duration, ctx)
    q0, v0, start_key, start_value = _initial(doc["initial"], robot, ctx)
    _check_start(robot, q0, surfaces, control, start_key, start_value, ctx)
    _check_controller(robot, surfaces, path, q0, control, sim, control_values, ctx)
    configurations = _check_path_followable(robot, path, traj, q0, sim.duration, ctx)
    _check_sampled_force_loop(
        robot, surfaces, configurations, control, sim, sensor, control_values, ctx
    )
    _check_contact_step(robot, surfaces, [q0, *configurations], control, sim, contact, ctx)
    try:
        return Scenario(
            robot=robot,
            surfaces=surfaces,
            path=path,
            q0=q0,
            v0=v0,
            control=control,
            sim=sim,
            name=name,
            description=top.get("description", ""),
            source=json.loads(json.dumps(doc)),
            sensor=sensor,
            controller_model=controller_model,
            contact=contact,
        )
    except BadInputError as exc:  # a rule across tables (e.g. stacked surfaces need no approach)
        raise ScenarioError(f"{ctx.file}: {' '.join(str(exc).split())}") from None


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


@dataclass(frozen=True)
class RobotTable:
    """A scenario's ``[robot]`` table, checked and resolved as the loader resolves it.

    Attributes:
        values: the checked values of the table (``xacro_args`` as texts).
        model: ``robot.model`` as written.
        target: the registry name, or the model file's path (relative ones joined to the
            scenario file's folder; the file exists).
        kind: ``"name"`` (a registry arm), ``"urdf"``, ``"xacro"`` or ``"mjcf"``.
        package_dirs: ``robot.package_dirs`` as absolute folders (each exists).
        xacro_args: ``robot.xacro_args`` as ``{name: text}``.
    """

    values: dict[str, Any]
    model: str
    target: str | Path
    kind: str
    package_dirs: tuple[str, ...]
    xacro_args: dict[str, str]


def resolve_robot_table(
    doc: Mapping[str, Any], path: str | Path, origin: str | None = None
) -> RobotTable:
    """Check a scenario's ``[robot]`` table and find the files it names, without loading
    the arm (what a sweep sends to its workers).

    Args:
        doc: the scenario's data (as :func:`read_scenario_document` returns).
        path: the scenario file (relative model paths and package folders join its folder).
        origin: how messages name the scenario (default: ``path``).

    Raises:
        ScenarioError: as :func:`load_scenario` for the ``[robot]`` table: a missing table,
            key, model file or package folder, a wrong type, xacro arguments for a model that
            is not a .xacro file.
    """
    ctx = _Context(str(path) if origin is None else origin)
    if "robot" not in doc:
        raise ctx.table_error("[robot]", "missing required table")
    return _robot_table(doc["robot"], Path(path), ctx)


def _model_target(model: str, key: str, file: Path, ctx: _Context) -> tuple[str | Path, str]:
    """A model reference of a scenario: (the registry name, "name") or (the model file,
    resolved against the scenario's folder, its kind "urdf", "xacro" or "mjcf")."""
    from hybrid_force.model.robot import _is_path, model_kind

    if not _is_path(model):
        return model, "name"
    candidate = Path(model)
    target = candidate if candidate.is_absolute() else file.parent / candidate
    kind = model_kind(target)
    if not target.is_file():
        label = {"urdf": "URDF", "xacro": "xacro", "mjcf": "MJCF"}[kind]
        raise ctx.error(
            key,
            model,
            f"{label} file not found (paths are relative to the scenario file): {target}",
        )
    return target, kind


def _robot_table(table: object, file: Path, ctx: _Context) -> RobotTable:
    values = _check_table(ctx, "robot", table, _ROBOT)
    raw = table if isinstance(table, dict) else {}
    model: str = values["model"]
    target, kind = _model_target(model, "robot.model", file, ctx)
    dirs = []
    for folder_text in values.get("package_dirs", []):
        folder = Path(folder_text)
        folder = folder if folder.is_absolute() else file.parent / folder
        if not folder.is_dir():
            raise ctx.error(
                "robot.package_dirs",
                raw.get("package_dirs"),
                f"folder not found (paths are relative to the scenario file): {folder}",
            )
        dirs.append(os.path.abspath(folder))
    args = values.get("xacro_args", {})
    if args and kind != "xacro":
        raise ctx.error(
            "robot.xacro_args",
            raw.get("xacro_args"),
            f"robot.model = {_fmt(model)} is not a .xacro file: only a xacro model takes arguments",
        )
    return RobotTable(values, model, target, kind, tuple(dirs), dict(args))


def _robot(table: object, file: Path, ctx: _Context) -> Any:
    from hybrid_force.model.robot import load_robot

    resolved = _robot_table(table, file, ctx)
    values = resolved.values
    try:
        return load_robot(
            resolved.target,
            tip=values.get("tip"),
            package_dirs=resolved.package_dirs,
            xacro_args=resolved.xacro_args or None,
            lock_off_chain=values.get("lock_off_chain"),
        )
    except FrameError as exc:
        raise ctx.error("robot.tip", values.get("tip"), " ".join(str(exc).split())) from None
    except RobotError as exc:
        raise ctx.error("robot.model", resolved.model, " ".join(str(exc).split())) from None


def _surfaces(doc: Mapping[str, Any], ctx: _Context) -> tuple[list[Any], list[tuple[str, dict]]]:
    from hybrid_force.geometry.surfaces import Cylinder, Plane, Sphere

    if "surface" in doc and "surfaces" in doc:
        raise ctx.table_error(
            "surface, surfaces", "give either one [surface] table or [[surfaces]], not both"
        )
    if "surface" in doc:
        tables = [("surface", doc["surface"])]
    elif "surfaces" in doc:
        items = doc["surfaces"]
        if not isinstance(items, list) or not items:
            raise ctx.error("surfaces", items, "must be a non-empty array of tables [[surfaces]]")
        tables = [(f"surfaces.{i}", t) for i, t in enumerate(items)]
    else:
        raise ctx.table_error("[surface]", "missing required table ([surface] or [[surfaces]])")
    surfaces: list[Any] = []
    checked: list[tuple[str, dict]] = []
    for name, table in tables:
        kind, values = _typed_table(ctx, name, table, _SURFACE)
        s: Surface
        try:
            if kind == "cylinder":
                s = Cylinder(
                    values["radius"],
                    values.get("center", [0.0, 0.0, 0.0]),
                    values.get("axis", [0.0, 0.0, 1.0]),
                    inside=values.get("inside", False),
                )
            elif kind == "sphere":
                s = Sphere(
                    values["radius"],
                    values.get("center", [0.0, 0.0, 0.0]),
                    inside=values.get("inside", False),
                )
            else:
                s = Plane(values["point"], values["normal"])
        except BadInputError as exc:
            raise _wrap(ctx, name, values, exc) from None
        surfaces.append(s)
        checked.append((name, {"type": kind, **values}))
    return surfaces, checked


def _trajectory(table: object, ctx: _Context) -> tuple[Any, dict[str, Any]]:
    from hybrid_force.geometry.paths import Circle, Helix

    kind, values = _typed_table(ctx, "trajectory", table, _TRAJECTORY)
    path: DesiredPath
    try:
        if kind == "helix":
            path = Helix(
                values["center"],
                values["radius"],
                axis=values.get("axis", [0.0, 0.0, 1.0]),
                omega=values["omega"],
                rise=values["rise"],
                phase=values.get("phase", 0.0),
            )
        else:
            path = Circle(
                values["center"],
                values["radius"],
                values["normal"],
                values["omega"],
                phase=values.get("phase", 0.0),
            )
    except BadInputError as exc:
        raise _wrap(ctx, "trajectory", values, exc) from None
    return path, {"type": kind, **values}


def _controller_model(
    control_values: Mapping[str, Any], robot: Any, file: Path, ctx: _Context
) -> Any:
    """``control.model``: the controller's own model of the arm (a name, or a model path
    relative to the scenario file), with the plant's tip and joints; None when not given."""
    from hybrid_force.control.controller import check_same_joints
    from hybrid_force.model.robot import load_robot

    if "model" not in control_values:
        return None
    model: str = control_values["model"]
    target, _ = _model_target(model, "control.model", file, ctx)
    try:
        own = load_robot(target)
        check_same_joints(robot, own)
        if own.tip != robot.tip:  # the same arm: the plant's tip frame
            own = load_robot(target, tip=robot.tip)
    except BadInputError as exc:
        raise ctx.error("control.model", model, " ".join(str(exc).split())) from None
    return own


def _sensor_settings(table: object, ctx: _Context) -> Any:
    from hybrid_force.sim.sensors import SensorSettings

    values = _check_table(ctx, "sensor", table, _SENSOR)
    try:
        return SensorSettings(**values)
    except BadInputError as exc:
        raise _wrap(ctx, "sensor", values, exc) from None


def _contact_settings(table: object, sim: Any, ctx: _Context) -> Any:
    from hybrid_force.sim.contact import ContactSettings

    values = _check_table(ctx, "contact", table, _CONTACT)
    try:
        contact = ContactSettings(**values)
    except BadInputError as exc:
        raise _wrap(ctx, "contact", values, exc) from None
    if not contact.ideal:  # the rules across tables, named by the [sim] key they are about
        from hybrid_force.sim.settings import Scenario

        try:
            Scenario._check_contact_settings(contact, sim)
        except BadInputError as exc:
            raise ctx.error(str(exc.key), exc.value, " ".join(str(exc).split())) from None
    return contact


def _check_contact_step(
    robot: Any,
    surfaces: list[Any],
    configurations: list[np.ndarray],
    control: Any,
    sim: Any,
    contact: Any,
    ctx: _Context,
) -> None:
    """Refuse a sim.dt too long for the contact model anywhere on the desired joint path."""
    from hybrid_force.sim.contact import largest_stable_dt, step_text

    f0 = float(np.max(control.f_d_for(len(surfaces))))
    dt_max = largest_stable_dt(contact, robot, surfaces, configurations, f0)
    if sim.dt > dt_max:
        raise ctx.error(
            "sim.dt",
            sim.dt,
            f"is too long for the [contact] model: the largest stable step along the path is "
            f"{step_text(dt_max)} s (docs/contact.md, time step)",
        )


def _check_control_rate(
    control: Any, sim: Any, control_values: Mapping[str, Any], ctx: _Context
) -> None:
    from hybrid_force.sim.loop import control_steps

    try:
        control_steps(control, sim)
    except BadInputError as exc:
        raise ctx.error("control.rate", control_values.get("rate"), str(exc)) from None


def _sim_settings(values: Mapping[str, Any], ctx: _Context) -> Any:
    from hybrid_force.sim.dynamics import Baumgarte
    from hybrid_force.sim.loop import SimSettings

    for key in ("baumgarte_alpha", "baumgarte_beta", "settle_time"):
        if key in values and values[key] < 0:
            raise ctx.error(f"sim.{key}", values[key], "must be >= 0")
    for key in ("duration", "dt", "model_mass_factor"):
        if key in values and values[key] <= 0:
            raise ctx.error(f"sim.{key}", values[key], "must be > 0")
    defaults = Baumgarte()
    kwargs: dict[str, Any] = {
        k: values[k]
        for k in (
            "duration",
            "dt",
            "integrator",
            "settle_time",
            "unilateral",
            "normalization",
            "seed",
            "torque_limits",
            "joint_limits",
        )
        if k in values
    }
    kwargs["baumgarte"] = Baumgarte(
        alpha=values.get("baumgarte_alpha", defaults.alpha),
        beta=values.get("baumgarte_beta", defaults.beta),
    )
    try:
        return SimSettings(**kwargs)
    except BadInputError as exc:
        raise _wrap(ctx, "sim", values, exc) from None


def _control_settings(
    values: Mapping[str, Any],
    sim_values: Mapping[str, Any],
    robot: Any,
    k: int,
    ctx: _Context,
) -> Any:
    from hybrid_force.control.laws.arimoto import make_gains
    from hybrid_force.control.supervisor import ControlSettings

    defaults = ControlSettings()
    kwargs = dict(values)
    kwargs.pop("model", None)  # the controller's own model: loaded by _controller_model
    n = robot.nv
    if "Kd" in kwargs:
        try:
            make_gains(
                kwargs["Kd"],
                kwargs.get("Lambda", defaults.Lambda),
                kwargs.get("beta", defaults.beta),
                kwargs.get("gamma", defaults.gamma),
                n,
            )
        except BadInputError as exc:
            raise _wrap(ctx, "control", values, exc) from None
        kwargs["Kd"] = np.asarray(kwargs["Kd"], dtype=float)
    if "f_d" in kwargs:
        f_d = kwargs["f_d"]
        if isinstance(f_d, list):
            if len(f_d) != k:
                raise ctx.error(
                    "control.f_d", f_d, f"must be a number or {k} numbers (one per surface)"
                )
            kwargs["f_d"] = tuple(f_d)
    for key in ("Lambda", "gamma", "clik_gain", "max_dist", "contact_tol", "kd_rate"):
        if key in kwargs and kwargs[key] <= 0:
            raise ctx.error(f"control.{key}", kwargs[key], "must be > 0")
    if "beta" in kwargs and kwargs["beta"] < 0:
        raise ctx.error("control.beta", kwargs["beta"], "must be >= 0")
    if "model_mass_factor" in sim_values:
        kwargs["mass_factor"] = sim_values["model_mass_factor"]
    try:
        return ControlSettings(**kwargs)
    except BadInputError as exc:
        merged = dict(values)
        if "model_mass_factor" in sim_values and "mass_factor" in str(exc):
            raise ctx.error(
                "sim.model_mass_factor", sim_values["model_mass_factor"], str(exc)
            ) from None
        raise _wrap(ctx, "control", merged, exc) from None


def _check_path_on_surfaces(
    path: Any,
    traj: Mapping[str, Any],
    surfaces: list[Any],
    tables: list[tuple[str, dict]],
    duration: float,
    ctx: _Context,
) -> None:
    from hybrid_force.geometry.paths import check_on_surface

    for surface, (name, table) in zip(surfaces, tables, strict=True):
        report = check_on_surface(path, surface, 0.0, duration)
        if report.worst_distance > ON_SURFACE_TOL:
            shown = ", ".join(f"trajectory.{k} = {_fmt(v)}" for k, v in traj.items())
            where = ", ".join(f"{k} = {_fmt(v)}" for k, v in table.items())
            p = [round(float(x), 6) for x in report.point_of_worst]
            raise ScenarioError(
                f"{ctx.file}: {shown}: the trajectory is not on [{name}] ({where}): "
                f"{report.worst_distance:.3g} m away at t = {report.time_of_worst:.4g} s "
                f"(p_d = {p}); it must stay within {ON_SURFACE_TOL:g} m over "
                f"[0, sim.duration = {duration:g} s]"
            )


def _initial(table: object, robot: Any, ctx: _Context) -> tuple[Any, Any, str, object]:
    from hybrid_force.control.clik import inverse_kinematics

    values = _check_table(ctx, "initial", table, _INITIAL)
    raw = table if isinstance(table, dict) else {}
    if "tip" in values and "q" in values:
        raise ctx.table_error(
            "initial.tip, initial.q", "give either the start tip position or the joints q, not both"
        )
    if "tip" not in values and "q" not in values:
        raise ctx.table_error(
            "initial.tip", "missing required key: give initial.tip = [x, y, z] or initial.q"
        )
    if "seed" in values and "tip" not in values:
        raise ctx.error("initial.seed", raw["seed"], "a seed is only used with initial.tip")
    nq, nv = robot.nq, robot.nv
    for key, size in (("seed", nq), ("q", nq), ("v", nv)):
        if key in values and len(values[key]) != size:
            raise ctx.error(
                f"initial.{key}",
                raw[key],
                f"must have {size} numbers for robot '{robot.name}', got {len(values[key])}",
            )
    v0 = np.array(values["v"]) if "v" in values else None
    if "q" in values:
        return np.array(values["q"]), v0, "initial.q", raw["q"]
    seed = np.array(values["seed"]) if "seed" in values else None
    try:
        q0 = inverse_kinematics(robot, np.array(values["tip"]), seed=seed)
    except ReachError as exc:
        extra = f" (initial.seed = {_fmt(raw['seed'])})" if "seed" in values else ""
        raise ctx.error(
            "initial.tip", raw["tip"], f"start out of reach{extra}: {' '.join(str(exc).split())}"
        ) from None
    return q0, v0, "initial.tip", raw["tip"]


def _check_start(
    robot: Any,
    q0: Any,
    surfaces: list[Any],
    control: Any,
    key: str,
    value: object,
    ctx: _Context,
) -> None:
    p = robot.tip_position(q0)
    d = np.array([float(s.distance(p)) for s in surfaces])
    where = f"tip at {[round(float(x), 6) for x in p]}"
    if not control.supervisor:
        worst = float(np.abs(d).max())
        if worst > control.contact_tol:
            raise ctx.error(
                key,
                value,
                f"the run starts in contact (control.supervisor = false) but the start is "
                f"{worst:.3g} m from the surface ({where}); it must be within control.contact_tol "
                f"= {control.contact_tol:g} m",
            )
    elif float(d.min()) < -control.contact_tol:
        raise ctx.error(
            key,
            value,
            f"the start is {-float(d.min()):.3g} m behind the surface, inside the solid "
            f"({where}); start on the free side",
        )


def _check_controller(
    robot: Any,
    surfaces: list[Any],
    path: Any,
    q0: Any,
    control: Any,
    sim: Any,
    control_values: Mapping[str, Any],
    ctx: _Context,
) -> None:
    """Build the controller once: checks q_d(0) in reach and dt·λ_max(M⁻¹K_d)."""
    from hybrid_force.control.constraint import Constraint
    from hybrid_force.control.supervisor import ReferenceController
    from hybrid_force.sim.loop import control_steps

    try:
        constraint = Constraint(surfaces, normalization=sim.normalization)
        # the numpy reference: the same checks without loading the compiled kernels (about
        # 1 s), which a sweep's parent, that never simulates, does not need
        period = control_steps(control, sim) * sim.dt  # the law runs at the control rate
        ReferenceController(robot, constraint, path, q0, control, dt=period)
    except ReachError as exc:
        raise ctx.error(
            "trajectory.center",
            path.to_dict().get("center"),
            f"the start of the trajectory is out of reach from the start configuration: "
            f"{' '.join(str(exc).split())}",
        ) from None
    except BadInputError as exc:
        message = " ".join(str(exc).split())
        if "dt" in message and "Kd" in message:
            value = control_values.get(
                "Kd", f"default kd_rate · M(q0), kd_rate = {control.kd_rate}"
            )
            period = control_steps(control, sim) * sim.dt
            where = f"sim.dt = {sim.dt:g} s" + (
                f", control period {period:g} s" if period != sim.dt else ""
            )
            raise ctx.error("control.Kd", value, f"{message} ({where})") from None
        raise _wrap(ctx, "control", control_values, exc) from None


def _check_path_followable(
    robot: Any, path: Any, traj: Mapping[str, Any], q0: Any, duration: float, ctx: _Context
) -> list[np.ndarray]:
    """Follow p_d(t) by inverse kinematics over [0, duration]: out of reach or singular → error.

    The run's desired joint path (CLIK, eq. 27) starts at the inverse kinematics of p_d(0)
    seeded with the start q0 and moves continuously; here each sample is solved from the
    previous one (same branch), every :data:`PATH_CHECK_STEP` s (at most
    :data:`PATH_CHECK_SAMPLES` samples), and J must be as well conditioned as the CLIK needs
    (``hybrid_force.control.clik``). A singular instant between two samples can still stop the run;
    the run then keeps its partial result. Returns the configurations found (one per sample).
    """
    from hybrid_force.control.clik import _COND_MAX, ClikSettings, inverse_kinematics

    n = int(min(PATH_CHECK_SAMPLES, max(2, math.ceil(duration / PATH_CHECK_STEP) + 1)))
    damping = ClikSettings().damping if robot.nv > 3 else 0.0
    shown = ", ".join(f"trajectory.{k} = {_fmt(v)}" for k, v in traj.items())
    q = q0
    found: list[np.ndarray] = []
    for t in np.linspace(0.0, duration, n):
        target = path.position(float(t))
        try:
            q = inverse_kinematics(robot, target, seed=q, tol=1e-9, max_iter=50)
        except ReachError:
            p = [round(float(x), 6) for x in target]
            raise ScenarioError(
                f"{ctx.file}: {shown}: the desired path is out of reach at t = {t:.4g} s "
                f"(p_d = {p}), followed from the start; it must be reachable over "
                f"[0, sim.duration = {duration:g} s]"
            ) from None
        # the CLIK's test: cond(J Jᵀ + λ² I) < _COND_MAX, λ its damping (0 for three joints)
        sv = np.linalg.svd(robot.jacobian(q), compute_uv=False)
        if not (sv[0] ** 2 + damping**2) < _COND_MAX * (sv[-1] ** 2 + damping**2):
            p = [round(float(x), 6) for x in target]
            s_text = ", ".join(f"{x:.3g}" for x in sv)
            raise ScenarioError(
                f"{ctx.file}: {shown}: the desired path passes a singular configuration at "
                f"t = {t:.4g} s (p_d = {p}, q_d = {np.round(q, 6).tolist()}, singular values "
                f"of J: {s_text}); the controller cannot follow it"
            )
        found.append(q)
    return found


def _check_sampled_force_loop(
    robot: Any,
    surfaces: list[Any],
    configurations: list[np.ndarray],
    control: Any,
    sim: Any,
    sensor: Any,
    control_values: Mapping[str, Any],
    ctx: _Context,
) -> None:
    """A sampled controller's β below the stability bound of its force loop (force_loop.py).

    Only for sampled runs (non-ideal sensing or a control rate below 1/sim.dt): with ideal
    sensing at the plant's rate the loop is resolved exactly and any β ≥ 0 is fine. W is taken
    at its smallest over the desired path's configurations.
    """
    from hybrid_force.control.force_loop import beta_bound, inverse_effective_mass
    from hybrid_force.sim.loop import control_steps

    steps = control_steps(control, sim)
    if steps == 1 and sensor.ideal:
        return
    period = steps * sim.dt
    cutoff, delay = sensor.force_cutoff, sensor.force_delay
    alpha = 1.0 - math.exp(-2.0 * math.pi * cutoff * period) if cutoff else 1.0
    w_min = inverse_effective_mass(robot, surfaces, configurations, sim.normalization)
    bound = beta_bound(w_min, control.mass_factor, alpha, delay)
    if not control.beta < bound:
        raise ctx.error(
            "control.beta",
            control_values.get("beta", control.beta),
            f"the sampled force loop (control period {period:g} s, sensor.force_delay = "
            f"{delay}, sensor.force_cutoff = {cutoff:g} Hz) oscillates and grows for "
            f"beta >= {bound:.4g}: beta · mass_factor / (A M⁻¹ Aᵀ) must stay below "
            f"{bound * control.mass_factor / w_min:.4g}, with A M⁻¹ Aᵀ >= {w_min:.4g} along "
            "the path (docs/scenarios.md, [sensor])",
        )

"""Scenario files: one TOML file describes one run (robot, surfaces, path, start, gains, sim).

:func:`load_scenario` reads a file, applies ``--set``-style overrides, validates every table
and key, and returns the :class:`hybrid_force.sim.settings.Scenario` that
:func:`hybrid_force.sim.loop.simulate` runs. The format is documented in docs/scenarios.md.

Validation is done up front so a bad file fails in milliseconds, not after a long run. Every
problem raises :class:`~hybrid_force.errors.ScenarioError` whose message names the file, the
``table.key`` and the offending value, e.g.::

    scenarios/x.toml: surface.radius = "0.4": must be a number [m], got a string

Checked: TOML syntax (with tomllib's line and column), unknown tables and keys (with a
did-you-mean), missing required keys, types and shapes, parameter ranges (by the constructors
of the surfaces, paths and settings), the desired path lying on every surface over
[0, sim.duration] (within 1e-6 m), the start in reach (inverse kinematics), the start on the
surface when the run starts in contact (``control.supervisor = false``), the gains, and with
``[tool] orientation = "normal"`` the arm's joint count and the tool pose followable without a
singular configuration.

No Python code or expression is ever evaluated: values are plain TOML data, and a string
where a number is expected is an error, whatever it contains.

This module reads the file and runs the steps in order; the steps live beside it: the keys
and messages every table shares in ``_tables``, the settings of each table in ``_builders``,
the rules across tables that run the model in :mod:`hybrid_force.sim.prerun`.
"""

from __future__ import annotations

import copy
import json
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hybrid_force.errors import BadInputError, ScenarioError
from hybrid_force.geometry.on_surface import ON_SURFACE_TOL, check_path_on_surfaces
from hybrid_force.model.scenario_robot import load_arm, load_controller_model
from hybrid_force.scenario._builders import (
    _control_settings,
    _initial,
    _robot_table,
    _surfaces,
    _tool_settings,
    _trajectory,
)
from hybrid_force.scenario._tables import (
    _TABLES,
    _TOP,
    _check_table,
    _Context,
    _fmt,
    _suggest,
    check_nesting,
    control_keys,
    read_settings,
    sim_keys,
)
from hybrid_force.scenario.acting_keys import _check_acting, _drop_never_acting
from hybrid_force.scenario.overrides import _apply_overrides
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.prerun import (
    _check_contact_step,
    _check_controller,
    _check_law_loops,
    _check_path_followable,
    _check_pose_followable,
)
from hybrid_force.sim.removal import RemovalSettings
from hybrid_force.sim.sensors import SensorSettings
from hybrid_force.sim.settings import Scenario, SimSettings
from hybrid_force.sim.start import start_at_tip

__all__ = ["MAX_FILE_BYTES", "load_scenario", "read_scenario_document", "scenario_from_document"]

MAX_FILE_BYTES = 1 << 20
"""Largest scenario file read [bytes]: a scenario is a page of text, never megabytes."""


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
    doc = _parse_toml(text, ctx.file)
    check_nesting(doc, ctx)  # dotted table headers nest without any recursion in tomllib
    return doc


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
) -> Any:  # -> hybrid_force.sim.settings.Scenario
    """Read, override, validate a scenario file and return a ``Scenario`` ready to simulate.

    Args:
        path: the TOML file (format: docs/scenarios.md).
        overrides: ``{"table.key": value}`` (e.g. from
            :func:`~hybrid_force.scenario.overrides.parse_override`), applied to the file's data
            before validation; they replace or add keys.

    Returns:
        :class:`hybrid_force.sim.settings.Scenario` with ``source`` = the file's data with the
        overrides applied (JSON-able).

    Raises:
        ScenarioError: any problem with the file; the message names the file, the
            ``table.key`` and the value.
    """
    return _build(read_scenario_document(path, overrides), Path(path), _Context(str(path)))


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
) -> Any:  # -> hybrid_force.sim.settings.Scenario
    """Validate scenario data (as :func:`read_scenario_document` returns) into a Scenario.

    Args:
        doc: the scenario's tables (a deep copy is taken; it is not modified).
        origin: how error messages name the scenario (a file name).
        base_dir: folder against which a relative ``robot.model`` path resolves.

    Raises:
        ScenarioError: as :func:`load_scenario`, naming ``origin``.
    """
    ctx = _Context(origin)
    check_nesting(doc, ctx)  # before deepcopy, which recurses per level
    return _build(copy.deepcopy(dict(doc)), Path(base_dir) / Path(origin).name, ctx)


def _build(doc: dict[str, Any], file: Path, ctx: _Context) -> Any:
    check_nesting(doc, ctx)  # overrides may nest too
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

    robot = load_arm(_robot_table(doc["robot"], file, ctx), ctx, doc["initial"])
    surfaces, surface_tables = _surfaces(doc, ctx)
    path, traj = _trajectory(doc["trajectory"], surfaces, ctx)
    control_values = _check_table(ctx, "control", doc.get("control", {}), control_keys())
    sim_values = _check_table(ctx, "sim", doc.get("sim", {}), sim_keys())
    _check_acting(doc, ctx)  # a key with no effect here: refused (or warned about and dropped)
    sim = read_settings(ctx, "sim", SimSettings, None, sim_values)
    control = _control_settings(control_values, sim_values, robot, len(surfaces), ctx)
    _drop_never_acting(doc, ctx)
    sensor = read_settings(ctx, "sensor", SensorSettings, doc.get("sensor", {}))
    contact = read_settings(ctx, "contact", ContactSettings, doc.get("contact", {}))
    trust = isinstance(doc["robot"], dict) and doc["robot"].get("xacro_trust") is True
    controller_model = load_controller_model(control_values, robot, file, ctx, trust)
    tool = _tool_settings(doc.get("tool", {}), robot, ctx)
    removal = (
        read_settings(ctx, "removal", RemovalSettings, doc["removal"]) if "removal" in doc else None
    )
    if removal is not None and tool.pad is None:  # (a pad without [removal]: _check_acting)
        raise ctx.table_error(
            "removal", "Preston's removal needs the tool's contact pad: add a [tool.pad] table "
            '(type = "hertz" with radius and modulus, or type = "flat" with radius)',
        )  # fmt: skip
    if control.supervisor:  # a run that starts in contact: checked by Scenario
        try:
            check_path_on_surfaces(path, surfaces, sim.duration)
        except BadInputError as exc:
            raise _refusal(exc, doc, traj, surface_tables, None, control, sim, ctx) from None
    q0, v0, start_key, start_value = _initial(doc["initial"], robot, ctx)
    if start_key == "initial.tip":
        q0 = start_at_tip(robot, tool, surfaces, path, q0, doc["initial"], ctx)
    try:  # the start, v0, the rate, the stacked rows, the path of a run in contact: by Scenario
        scenario = Scenario(
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
            tool=tool,
            removal=removal,
        )
    except BadInputError as exc:
        start = (robot, q0, start_key, start_value)
        raise _refusal(exc, doc, traj, surface_tables, start, control, sim, ctx) from None
    own = controller_model if controller_model is not None else robot
    _check_controller(own, surfaces, path, q0, control, sim, control_values, ctx, tool)
    if tool.controlled:
        configurations = _check_pose_followable(robot, surfaces, path, tool, q0, sim.duration, ctx)
    else:
        configurations = _check_path_followable(robot, path, traj, q0, sim.duration, ctx)
    _check_law_loops(
        robot, surfaces, configurations, q0, control, sim, sensor, controller_model,
        control_values.get("model"), ctx,
    )  # fmt: skip
    _check_contact_step(robot, surfaces, [q0, *configurations], control, sim, contact, ctx)
    return scenario


def _refusal(
    exc: BadInputError,
    doc: Mapping[str, Any],
    traj: Mapping[str, Any],
    tables: list[tuple[str, dict[str, Any]]],
    start: tuple[Any, Any, str, object] | None,
    control: Any,
    sim: Any,
    ctx: _Context,
) -> ScenarioError:
    """Scenario's refusal of the path, the start or the stacked surfaces (its ``key`` and
    ``value``) as the file's: naming the file, the keys and their values. ``start``: (the
    arm, q0, the start's key and its value as written). Its refusals of a file's key
    (``control.rate``, the ``[sim]`` keys a contact model needs) and of v0 name that key."""
    key, value = exc.key, exc.value
    if key == "Scenario.v0":
        problem = str(exc).removeprefix("Scenario.v0: ")
        return ctx.error("initial.v", doc["initial"]["v"], problem)
    if isinstance(key, str) and key.split(".")[0] in ("control", "sim"):
        return ctx.error(key, value, " ".join(str(exc).split()))
    if key == "Scenario.path" and isinstance(value, tuple):
        i, report = value
        name, table = tables[i]
        shown = ", ".join(f"trajectory.{k} = {_fmt(v)}" for k, v in traj.items())
        where = ", ".join(f"{k} = {_fmt(v)}" for k, v in table.items())
        if report is None:  # e.g. Φ(p_d) not finite
            problem = " ".join(str(exc).split()).split("): ", 1)[-1]
            return ScenarioError(
                f"{ctx.file}: {shown}: the trajectory cannot be checked against [{name}] "
                f"({where}): {problem}"
            )
        p = [round(float(x), 6) for x in report.point_of_worst]
        return ScenarioError(
            f"{ctx.file}: {shown}: the trajectory is not on [{name}] ({where}): "
            f"{report.worst_distance:.3g} m away at t = {report.time_of_worst:.4g} s "
            f"(p_d = {p}); it must stay within {ON_SURFACE_TOL:g} m over "
            f"[0, sim.duration = {sim.duration:g} s]"
        )
    if key == "Scenario.q0" and isinstance(value, tuple) and start is not None:
        robot, q0, start_key, start_value = start
        d = float(value[1])
        where = f"tip at {[round(float(x), 6) for x in robot.tip_position(q0)]}"
        if control.supervisor:
            problem = (
                f"the start is {-d:.3g} m behind the surface, inside the solid ({where}); "
                "start on the free side"
            )
        else:
            problem = (
                "the run starts in contact (control.supervisor = false) but the start is "
                f"{abs(d):.3g} m from the surface ({where}); it must be within "
                f"control.contact_tol = {control.contact_tol:g} m"
            )
        return ctx.error(start_key, start_value, problem)
    if key == "Scenario.surfaces" and isinstance(value, tuple):
        names = ", ".join(tables[i][0] for i in value)
        detail = " ".join(str(exc).split()).split("at q0 ", 1)[-1]
        return ctx.table_error(
            names,
            "the constraint rows n̂ᵀJ of these stacked surfaces are linearly dependent at the "
            f"start {detail}",
        )
    return ScenarioError(f"{ctx.file}: {' '.join(str(exc).split())}")

"""Scenario files (docs/scenarios.md): one TOML file, plain data never evaluated, checked up
front into the :class:`~hybrid_force.sim.settings.Scenario` of one run; every problem a
ScenarioError naming the file, the ``table.key`` and the value as written. Each table is read
by its declarations (``_tables``, built by ``_builders``), the rules across tables checked by
``Scenario``, those that run the model by :mod:`hybrid_force.sim.prerun`."""

from __future__ import annotations

import copy
import json
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hybrid_force._file_errors import _Context, _fmt
from hybrid_force.control.laws.base import law_names
from hybrid_force.errors import BadInputError, ScenarioError
from hybrid_force.geometry.offset import tool_surfaces
from hybrid_force.geometry.on_surface import ON_SURFACE_TOL, check_path_on_surfaces
from hybrid_force.model.scenario_robot import load_arm, load_controller_model
from hybrid_force.scenario import _builders as build
from hybrid_force.scenario._tables import (
    SETTINGS,
    TABLES,
    TOP,
    check_nesting,
    law_keys,
    settings_tables,
    type_keys,
)
from hybrid_force.scenario.overrides import _apply_overrides
from hybrid_force.settings_reader import check_acting, check_table, read_settings, suggest
from hybrid_force.sim import prerun
from hybrid_force.sim.removal import RemovalSettings
from hybrid_force.sim.settings import Scenario
from hybrid_force.sim.start import start_at_tip

__all__ = ["MAX_FILE_BYTES", "load_scenario", "read_scenario_document", "scenario_from_document"]

MAX_FILE_BYTES = 1 << 20
"""Largest scenario file read [bytes]: a scenario is a page of text, never megabytes."""


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
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{ctx.file}: TOML syntax error: {exc}") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise ScenarioError(
            f"{ctx.file}: arrays or tables nested too deeply (hundreds of levels); "
            "a scenario needs at most three"
        ) from None
    check_nesting(doc, ctx)  # dotted table headers nest without any recursion in tomllib
    return doc


def load_scenario(
    path: str | Path, overrides: Mapping[str, object] | None = None
) -> Any:  # Scenario (Any: a sweep's check calls it for its refusals only)
    """The ``Scenario`` of TOML file ``path``, ready to simulate, with ``overrides``
    ``{"table.key": value}`` set before validation; its ``source`` is that data (JSON-able)."""
    return _build(read_scenario_document(path, overrides), Path(path), _Context(str(path)))


def read_scenario_document(
    path: str | Path, overrides: Mapping[str, object] | None = None
) -> dict[str, Any]:
    """The TOML data of a scenario file with the overrides set, not yet validated: what
    :func:`scenario_from_document` takes (in a sweep's workers, which may not see the file)."""
    ctx = _Context(str(path))
    doc = _read(Path(path), ctx)
    if overrides:
        _apply_overrides(doc, overrides, ctx)
    return doc


def scenario_from_document(
    doc: Mapping[str, Any], *, origin: str = "<scenario>", base_dir: str | Path = "."
) -> Scenario:
    """The Scenario of scenario data ``doc`` (copied), named ``origin`` in the messages, a
    relative ``robot.model`` resolved against ``base_dir``."""
    ctx = _Context(origin)
    check_nesting(doc, ctx)  # before deepcopy, which recurses per level
    return _build(copy.deepcopy(dict(doc)), Path(base_dir) / Path(origin).name, ctx)


def _build(doc: dict[str, Any], file: Path, ctx: _Context) -> Scenario:
    check_nesting(doc, ctx)  # overrides may nest too
    for key, value in doc.items():
        if key not in TOP and key not in TABLES:
            raise ctx.error(
                key,
                value,
                f"unknown top-level key or table{suggest(key, [*TOP, *TABLES])}; valid: "
                f"{', '.join([*TOP, *TABLES])}",
            )
    top = check_table(ctx, "", {k: v for k, v in doc.items() if k in TOP}, TOP)
    for table in ("robot", "trajectory", "initial"):
        if table not in doc:
            raise ctx.table_error(f"[{table}]", "missing required table")

    robot = load_arm(build._robot_table(doc["robot"], file, ctx), ctx, doc["initial"])
    parts, surface_tables = build._surfaces(doc, ctx, file.parent)
    # the path and every check below are the tool centre's: on the parts' offsets by
    # tool.radius (the parts themselves for a point tool); the Scenario keeps the parts
    radius = doc["tool"].get("radius", 0.0) if isinstance(doc.get("tool"), dict) else 0.0
    try:  # a ball's warning (a hollow tighter than it) is the Scenario's
        surfaces = list(tool_surfaces(parts, radius, warn=False))
    except BadInputError as exc:
        raise ctx.error("tool.radius", radius, " ".join(str(exc).split())) from None
    path, traj = build._trajectory(doc["trajectory"], surfaces, ctx)
    keys = {**settings_tables(), "trajectory": type_keys("trajectory")[traj["type"]]}
    values = {t: check_table(ctx, t, doc.get(t, {}), keys[t]) for t in ("control", *SETTINGS)}
    for law in (law for law in law_names() if law in values["control"]):
        keys[f"control.{law}"] = law_keys(law)
        table = values["control"][law]
        values[f"control.{law}"] = check_table(ctx, f"control.{law}", table, keys[f"control.{law}"])
    for table_name, given in surface_tables:  # [surface] or each [[surfaces]] table
        keys[table_name] = type_keys("surface")[given["type"]]
        values[table_name] = {k: v for k, v in given.items() if k != "type"}
    check_acting(ctx, doc, {**values, "trajectory": traj}, keys)
    control = build._control_settings(values, doc.get("control", {}), ctx)
    sim, sensor, contact, tool = (
        read_settings(ctx, t, cls, None, values[t]) for t, cls in SETTINGS.items()
    )
    removal = None  # [removal] is optional (docs/removal.md)
    if "removal" in doc:
        removal = read_settings(ctx, "removal", RemovalSettings, doc["removal"])
    trust = isinstance(doc["robot"], dict) and doc["robot"].get("xacro_trust") is True
    controller_model = load_controller_model(values["control"], robot, file, ctx, trust)
    if control.supervisor:  # a run that starts in contact: checked by Scenario
        try:
            check_path_on_surfaces(path, surfaces, sim.duration)
        except BadInputError as exc:
            raise _refusal(exc, doc, traj, surface_tables, None, control, sim, ctx) from None
    q0, v0, start_key, start_value = build._initial(doc["initial"], robot, ctx)
    if start_key == "initial.tip":
        q0 = start_at_tip(robot, tool, surfaces, path, q0, doc["initial"], ctx)
    try:  # every rule across the tables that needs no run of the model: by Scenario
        scenario = Scenario(
            robot=robot,
            surfaces=parts,
            path=path,
            q0=q0,
            v0=v0,
            control=control,
            sim=sim,
            name=top["name"],
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
    prerun._check_controller(own, surfaces, path, q0, control, sim, values["control"], ctx, tool)
    if tool.controlled:
        configurations = prerun._check_pose_followable(
            robot, surfaces, path, tool, q0, sim.duration, ctx
        )
    else:
        configurations = prerun._check_path_followable(robot, path, traj, q0, sim.duration, ctx)
    prerun._check_law_loops(
        robot, surfaces, configurations, q0, control, sim, sensor, controller_model,
        values["control"].get("model"), ctx,
    )  # fmt: skip
    prerun._check_contact_step(robot, surfaces, [q0, *configurations], control, sim, contact, ctx)
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
    """Scenario's refusal ``exc`` as the file's, naming the keys and their values as written.
    ``start``: (the arm, q0, the start's key, its value as written)."""
    key, value = exc.key, exc.value
    message = " ".join(str(exc).split())
    if key == "Scenario.v0":
        return ctx.error("initial.v", doc["initial"]["v"], message.removeprefix("Scenario.v0: "))
    if isinstance(key, str) and key.split(".")[0] in (*TOP, *TABLES):
        head, _, last = key.rpartition(".")
        written = doc.get(head, {}).get(last, value) if head else doc.get(key, value)
        return ctx.error(key, written, message.removeprefix(f"Scenario.{key} "))
    if key == "Scenario.path" and isinstance(value, tuple):
        i, report = value
        name, table = tables[i]
        shown = ", ".join(f"trajectory.{k} = {_fmt(v)}" for k, v in traj.items())
        where = ", ".join(f"{k} = {_fmt(v)}" for k, v in table.items())
        if report is None:  # e.g. Φ(p_d) not finite
            problem = message.split("): ", 1)[-1]
            return ScenarioError(
                f"{ctx.file}: {shown}: the trajectory cannot be checked against [{name}] "
                f"({where}): {problem}"
            )
        p = [round(float(x), 6) for x in report.point_of_worst]
        radius = doc["tool"].get("radius", 0) if isinstance(doc.get("tool"), dict) else 0
        ball = radius and (
            f" (with tool.radius = {radius} m the path is the tool centre's: on the surface "
            f"{radius} m off [{name}] along its normal)"
        )
        return ScenarioError(
            f"{ctx.file}: {shown}: the trajectory is not on [{name}] ({where}): "
            f"{report.worst_distance:.3g} m away at t = {report.time_of_worst:.4g} s "
            f"(p_d = {p}); it must stay within {ON_SURFACE_TOL:g} m over "
            f"[0, sim.duration = {sim.duration:g} s]{ball or ''}"
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
        detail = message.split("at q0 ", 1)[-1]
        return ctx.table_error(
            names,
            "the constraint rows n̂ᵀJ of these stacked surfaces are linearly dependent at the "
            f"start {detail}",
        )
    return ScenarioError(f"{ctx.file}: {message}")

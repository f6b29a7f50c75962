"""The settings each table of a scenario file builds, one table at a time: the arm of
``[robot]``, the surfaces, the desired path, the start, and the control, sensor, contact and
sim settings; each constructor's refusal named by its ``table.key``.

The rules across tables, which need the model, are :mod:`hybrid_force.sim.prerun`.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hybrid_force.control.laws.arimoto import check_damping_gain
from hybrid_force.control.laws.base import law_names
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.control.tool import ToolSettings
from hybrid_force.errors import BadInputError, RunWarning
from hybrid_force.geometry.paths import path_parameters, path_types
from hybrid_force.geometry.surface_base import surface_types
from hybrid_force.geometry.surface_path import SurfacePath
from hybrid_force.model.scenario_robot import RobotTable, per_joint, robot_table
from hybrid_force.scenario._tables import (
    _INITIAL,
    _ROBOT,
    _check_table,
    _Context,
    _fmt,
    _typed_table,
    _wrap,
)
from hybrid_force.schema import keys_of
from hybrid_force.sim.removal import PAD_TYPES


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


def _robot_table(table: object, file: Path, ctx: _Context) -> RobotTable:
    raw = table if isinstance(table, dict) else {}
    return robot_table(_check_table(ctx, "robot", table, _ROBOT), raw, file, ctx)


def _surfaces(doc: Mapping[str, Any], ctx: _Context) -> tuple[list[Any], list[tuple[str, dict]]]:
    """The surfaces of [surface] or [[surfaces]], each built from its registered type's
    declared parameters (:func:`~hybrid_force.geometry.surface_base.surface_types`)."""

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
        types = surface_types()
        schema = {kind: keys_of(cls) for kind, cls in types.items()}
        kind, values = _typed_table(ctx, name, table, schema)
        try:
            s = types[kind](**values)
        except BadInputError as exc:
            raise _wrap(ctx, name, values, exc) from None
        surfaces.append(s)
        checked.append((name, {"type": kind, **values}))
    return surfaces, checked


def _trajectory(table: object, surfaces: list[Any], ctx: _Context) -> tuple[Any, dict[str, Any]]:
    """[trajectory]: its registered path type built from its declared parameters
    (:func:`~hybrid_force.geometry.paths.path_types`); a path on a surface by
    :func:`_surface_path`."""

    types = path_types()
    schema = {kind: keys_of(path_parameters(cls)) for kind, cls in types.items()}
    kind, values = _typed_table(ctx, "trajectory", table, schema)
    cls = types[kind]
    if issubclass(cls, SurfacePath):
        raw = table if isinstance(table, dict) else {}
        return _surface_path(cls, values, raw, surfaces, ctx), {"type": kind, **values}
    try:
        return cls(**values), {"type": kind, **values}
    except BadInputError as exc:
        raise _wrap(ctx, "trajectory", values, exc) from None


def _surface_path(
    cls: Any, values: dict[str, Any], raw: Mapping[str, Any], surfaces: list[Any], ctx: _Context
) -> Any:
    """A waypoints or raster path on surface ``trajectory.surface`` (default 0); its refusals
    name the key and the value as written (``raw``), its PathWarnings the file and the key."""

    index = values.get("surface", 0)
    params = {k: v for k, v in values.items() if k != "surface"}
    if not 0 <= index < len(surfaces):
        raise ctx.error(
            "trajectory.surface",
            index,
            f"must be the index of a surface, 0 to {len(surfaces) - 1} (the scenario has "
            f"{len(surfaces)})",
        )
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RunWarning)
            path = cls(surfaces[index], **params)
    except BadInputError as exc:
        if exc.key in params:
            message = " ".join(str(exc).split())
            raise ctx.error(f"trajectory.{exc.key}", raw.get(exc.key), message) from None
        raise _wrap(ctx, "trajectory", params, exc) from None
    for w in caught:
        if issubclass(w.category, RunWarning):
            message = f"{ctx.file}: trajectory.points = {_fmt(raw.get('points'))}: {w.message}"
            warnings.warn(RunWarning(message), stacklevel=2)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return path


def _control_settings(
    values: Mapping[str, Any],
    sim_values: Mapping[str, Any],
    robot: Any,
    k: int,
    ctx: _Context,
) -> Any:
    """[control] (with [sim]'s model_mass_factor) → ControlSettings; K_d against the arm's
    joints and f_d against the k surfaces, named by their keys."""

    merged: dict[str, Any] = {
        key: tuple(v) if key == "f_d" and isinstance(v, list) else v
        for key, v in values.items()
        if key != "model" and key not in law_names()
    }
    if "model_mass_factor" in sim_values:
        merged["mass_factor"] = sim_values["model_mass_factor"]
    merged["options"] = {law: values[law] for law in law_names() if law in values}
    if "Kd" in values:
        try:
            check_damping_gain(values["Kd"], robot.nv)
        except BadInputError as exc:
            raise _wrap(ctx, "control", values, exc) from None
    f_d = values.get("f_d")
    if isinstance(f_d, list) and len(f_d) != k:
        raise ctx.error("control.f_d", f_d, f"must be a number or {k} numbers (one per surface)")
    try:
        control = ControlSettings(**merged)
    except BadInputError as exc:
        if "mass_factor" in str(exc):
            raise ctx.error(
                "sim.model_mass_factor", sim_values.get("model_mass_factor"), str(exc)
            ) from None
        raise _wrap(ctx, "control", values, exc) from None
    return control


def _tool_settings(table: object, robot: Any, ctx: _Context) -> Any:
    """``[tool]``: the ToolSettings, refused for an arm with too few joints for its task."""

    rest = {k: v for k, v in table.items() if k != "pad"} if isinstance(table, dict) else table
    values = _check_table(ctx, "tool", rest, keys_of(ToolSettings))
    if isinstance(table, dict) and "pad" in table:  # [tool.pad]: its own typed table
        schema = {kind: keys_of(cls) for kind, cls in PAD_TYPES.items()}
        kind, pad_values = _typed_table(ctx, "tool.pad", table["pad"], schema)
        try:
            values["pad"] = PAD_TYPES[kind](**pad_values)
        except BadInputError as exc:
            raise _wrap(ctx, "tool.pad", pad_values, exc) from None
    try:
        tool = ToolSettings(**values)
        tool.check_arm(robot)
    except BadInputError as exc:
        key = str(exc.key or "tool")
        raise ctx.error(key, values.get(key.removeprefix("tool.")), str(exc)) from None
    return tool


def _initial(table: object, robot: Any, ctx: _Context) -> tuple[Any, Any, str, object]:
    """[initial] → (q0, or (the tip, the seed) for :func:`~hybrid_force.sim.start.start_at_tip`;
    v0 or None; the start's key; its value as written)."""
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
    per_joint(robot, values, raw, ctx)
    v0 = np.array(values["v"]) if "v" in values else None
    if "q" in values:
        return np.array(values["q"]), v0, "initial.q", raw["q"]
    seed = np.array(values["seed"]) if "seed" in values else None
    return (values["tip"], seed), v0, "initial.tip", raw["tip"]

"""What the tables of a scenario file build beyond a settings dataclass (the arm, surfaces,
path, control settings, start), each constructor's refusal named by its ``table.key``."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hybrid_force._file_errors import _Context, _fmt, _wrap
from hybrid_force.control.laws.base import LAWS, PAPER_GAINS, law_names, law_spec
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.errors import BadInputError, RunWarning, ScenarioError
from hybrid_force.geometry.paths import path_types
from hybrid_force.geometry.surface_base import surface_from_table, surface_types
from hybrid_force.geometry.surface_path import SurfacePath
from hybrid_force.model.scenario_robot import RobotTable, per_joint, robot_table
from hybrid_force.scenario._tables import _INITIAL, _ROBOT, type_keys
from hybrid_force.settings_reader import check_table, no_effect, typed_table


def resolve_robot_table(
    doc: Mapping[str, Any], path: str | Path, origin: str | None = None
) -> RobotTable:
    """The ``[robot]`` table of scenario data ``doc`` checked, its files found (relative to
    ``path``) and the arm not loaded: what a sweep sends to its workers."""
    ctx = _Context(str(path) if origin is None else origin)
    if "robot" not in doc:
        raise ctx.table_error("[robot]", "missing required table")
    return _robot_table(doc["robot"], Path(path), ctx)


def _robot_table(table: object, file: Path, ctx: _Context) -> RobotTable:
    raw = table if isinstance(table, dict) else {}
    return robot_table(check_table(ctx, "robot", table, _ROBOT), raw, file, ctx)


def _surface_tables(doc: Mapping[str, Any], ctx: _Context) -> list[tuple[str, Any]]:
    if "surface" in doc and "surfaces" in doc:
        raise ctx.table_error(
            "surface, surfaces", "give either one [surface] table or [[surfaces]], not both"
        )
    if "surface" in doc:
        return [("surface", doc["surface"])]
    if "surfaces" in doc:
        items = doc["surfaces"]
        if not isinstance(items, list) or not items:
            raise ctx.error("surfaces", items, "must be a non-empty array of tables [[surfaces]]")
        return [(f"surfaces.{i}", t) for i, t in enumerate(items)]
    raise ctx.table_error("[surface]", "missing required table ([surface] or [[surfaces]])")


def _surfaces(
    doc: Mapping[str, Any], ctx: _Context, folder: Path = Path(".")
) -> tuple[list[Any], list[tuple[str, dict]]]:
    """The surfaces of [surface] or [[surfaces]] and their checked tables; a file a type reads
    (a mesh part's) is relative to ``folder``. A refusal of a type built from a file names its
    own ``name.key`` in its message."""
    surfaces: list[Any] = []
    checked: list[tuple[str, dict]] = []
    for name, table in _surface_tables(doc, ctx):
        kind, values = typed_table(ctx, name, table, type_keys("surface"))
        try:
            surfaces.append(surface_from_table(surface_types()[kind], name, values, folder))
        except BadInputError as exc:
            key, message = str(exc.key or ""), " ".join(str(exc).split())
            if not key.startswith(f"{name}."):
                raise _wrap(ctx, name, values, exc) from None
            raise ScenarioError(
                f"{ctx.file}: {message}", key=key, value=exc.value, file=ctx.file
            ) from None
        checked.append((name, {"type": kind, **values}))
    return surfaces, checked


def file_surfaces(
    doc: Mapping[str, Any], path: str | Path, origin: str | None = None
) -> dict[str, tuple[dict[str, Any], Any]]:
    """The surfaces of scenario file ``path`` built from files (mesh parts): {table name: (its
    checked values, the surface)}, the ``prebuilt_surfaces`` of a process without the files."""
    ctx = _Context(str(path) if origin is None else origin)
    surfaces, checked = _surfaces(doc, ctx, Path(path).parent)
    return {
        name: ({k: v for k, v in values.items() if k != "type"}, surface)
        for (name, values), surface in zip(checked, surfaces, strict=True)
        if hasattr(type(surface), "from_table")
    }


def _trajectory(table: object, surfaces: list[Any], ctx: _Context) -> tuple[Any, dict[str, Any]]:
    """[trajectory]: its registered path type built, and its checked table."""
    kind, values = typed_table(ctx, "trajectory", table, type_keys("trajectory"))
    cls = path_types()[kind]
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
    """A path on surface ``trajectory.surface`` (default 0); its refusals name the key and
    the value as written (``raw``), its PathWarnings the file and the key."""
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
    values: Mapping[str, dict[str, Any]], raw: Mapping[str, Any], ctx: _Context
) -> ControlSettings:
    """[control] (with ``values["control.<law>"]``, [sim]'s model_mass_factor) →
    ControlSettings; a paper's gain the chosen law does not read is refused (Λ is also the
    supervisor's approach rate without ``approach_rate``)."""
    control = values["control"]
    law = control.get("law", ControlSettings.law)
    keys = dict.fromkeys([*control, *values.get(f"control.{law}", {})])
    supervised = control.get("supervisor", ControlSettings.supervisor)
    approach = supervised and "approach_rate" not in control
    for gain in (g for g in PAPER_GAINS if g in control):
        if not (law_spec(law).reads(gain, keys) or (gain == "Lambda" and approach)):
            readers = [name for name, spec in LAWS.items() if gain in spec.gains]
            replaced = sorted({str(s.gains[gain]) for s in LAWS.values() if s.gains.get(gain)})
            needs = f"control.law = one of {readers}" + (
                f", without the key that replaces it ({', '.join(replaced)})" if replaced else ""
            )
            if gain == "Lambda":
                needs += (
                    ", or the supervisor's approach (control.supervisor = true, no approach_rate)"
                )
            raise no_effect(ctx, f"control.{gain}", raw[gain], needs)
    given: dict[str, Any] = {k: v for k, v in control.items() if k != "model" and k not in LAWS}
    if isinstance(given.get("f_d"), list):
        given["f_d"] = tuple(given["f_d"])
    if "model_mass_factor" in values["sim"]:
        given["mass_factor"] = values["sim"]["model_mass_factor"]
    given["options"] = {law: values[f"control.{law}"] for law in law_names() if law in control}
    try:
        return ControlSettings(**given)
    except BadInputError as exc:
        raise _wrap(ctx, "control", control, exc) from None


def _initial(table: object, robot: Any, ctx: _Context) -> tuple[Any, Any, str, object]:
    """[initial] → (q0, or (the tip, the seed) for :func:`~hybrid_force.sim.start.start_at_tip`;
    v0 or None; the start's key; its value as written)."""
    values = check_table(ctx, "initial", table, _INITIAL)
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

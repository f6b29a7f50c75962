"""The arm of a scenario file: its ``[robot]`` table's model file (or registry name) and
package folders found against the scenario's folder, the arm loaded with the joints the
loader locks held at ``initial.q`` or ``initial.seed``, and ``control.model``, the
controller's own model of the same arm."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hybrid_force._file_errors import _Context, _fmt
from hybrid_force.errors import BadInputError, RobotError
from hybrid_force.model.loading import _is_path, load_robot, model_kind
from hybrid_force.model.robot import Robot, check_same_joints


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


def model_target(model: str, key: str, file: Path, ctx: _Context) -> tuple[str | Path, str]:
    """A model reference of a scenario: (the registry name, "name") or (the model file,
    resolved against the scenario's folder, its kind "urdf", "xacro" or "mjcf")."""

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


def robot_table(
    values: dict[str, Any], raw: Mapping[str, Any], file: Path, ctx: _Context
) -> RobotTable:
    """The ``[robot]`` table's ``values`` (checked; ``raw`` as written) with the files it names
    found: the model (:func:`model_target`), the package folders; xacro arguments only for a
    xacro model."""
    model: str = values["model"]
    target, kind = model_target(model, "robot.model", file, ctx)
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


def load_arm(resolved: RobotTable, ctx: _Context, initial: object = None) -> Robot:
    """The scenario's arm. When ``initial.q`` or ``initial.seed`` (the ``initial`` table)
    lists every joint of the model file and the loader locks some, it is loaded again with
    the locked joints held at their values there (:func:`_full_start`)."""

    values = resolved.values
    options: dict[str, Any] = {
        "tip": values.get("tip"),
        "package_dirs": resolved.package_dirs,
        "xacro_args": resolved.xacro_args or None,
        "lock_off_chain": values.get("lock_off_chain"),
        "xacro_trust": values.get("xacro_trust", False),
    }
    try:
        robot = load_robot(resolved.target, **options)
        held = _full_start(robot, initial)
        if held is not None:
            key, numbers = held
            try:
                robot = load_robot(resolved.target, **options, locked_positions=numbers)
            except RobotError as exc:
                raw = initial.get(key) if isinstance(initial, dict) else None
                raise ctx.error(f"initial.{key}", raw, " ".join(str(exc).split())) from None
    except RobotError as exc:  # a frame error has key "tip"
        key, value = (
            ("robot.tip", values.get("tip"))
            if exc.key == "tip"
            else ("robot.model", resolved.model)
        )
        raise ctx.error(key, value, " ".join(str(exc).split())) from None
    return robot


def _full_start(robot: Robot, initial: object) -> tuple[str, dict[str, float]] | None:
    """(``"q"`` or ``"seed"``, {locked joint: its value}) when that key of the ``initial``
    table lists one number per joint of the model file and the robot has locked joints;
    None otherwise (a wrong count or type is refused later, by the ``[initial]`` reader)."""
    if not robot.locked_joints or not isinstance(initial, dict):
        return None
    names = robot.file_joints
    for key in ("q", "seed"):
        values = initial.get(key)
        if (
            isinstance(values, list)
            and len(values) == len(names) != robot.nq
            and all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
        ):
            locked = robot.locked_joints
            return key, {n: float(v) for n, v in zip(names, values, strict=True) if n in locked}
    return None


def load_controller_model(
    control_values: Mapping[str, Any], robot: Robot, file: Path, ctx: _Context, trust: bool = False
) -> Robot | None:
    """``control.model``: the controller's own model of the arm (a name, or a model path
    relative to the scenario file), with the plant's tip and joints; None when not given.
    ``trust``: ``robot.xacro_trust``, which covers a xacro ``control.model`` too."""

    if "model" not in control_values:
        return None
    model: str = control_values["model"]
    target, _ = model_target(model, "control.model", file, ctx)
    try:
        own = load_robot(target, xacro_trust=trust)
        # held where the plant's are (initial.q listing every joint), when it locks them too
        held = {k: v for k, v in robot.locked_joints.items() if k in own.locked_joints}
        if held != {k: own.locked_joints[k] for k in held}:
            own = load_robot(target, locked_positions=held, xacro_trust=trust)
        check_same_joints(robot, own)
        if own.tip != robot.tip:  # the same arm: the plant's tip frame
            own = load_robot(
                target, tip=robot.tip, locked_positions=held or None, xacro_trust=trust
            )
    except BadInputError as exc:
        raise ctx.error("control.model", model, " ".join(str(exc).split())) from None
    return own


def per_joint(robot: Robot, values: dict[str, Any], raw: Mapping[str, Any], ctx: _Context) -> None:
    """``initial.seed``, ``initial.q`` and ``initial.v`` (checked ``values``, ``raw`` as
    written) one number per joint of the arm; ``seed`` and ``q`` may also list every joint of
    the model file, and then lose the locked ones (in place: :func:`load_arm` holds those)."""
    nq, nv = robot.nq, robot.nv
    names, locked = robot.file_joints, robot.locked_joints
    moving = [i for i, name in enumerate(names) if name not in locked]
    for key, size in (("seed", nq), ("q", nq), ("v", nv)):
        if key not in values or len(values[key]) == size:
            continue
        if key != "v" and locked and len(values[key]) == len(names):
            values[key] = [values[key][i] for i in moving]  # locked ones: held (load_arm)
            continue
        if key != "v" and locked:
            held = ", ".join(f"{n} (held at {v:g})" for n, v in locked.items())
            counts = (
                f"{size} numbers (its moving joints) or {len(names)} (every joint of the model "
                "file, in the file's order: the locked joints' values become their locked "
                "positions)"
            )
            why = (
                "robot.lock_off_chain locks the joints off the chain to the tip (true by "
                "default for a model file; false keeps them moving), a registry arm's entry "
                "names the ones it locks"
            )
            raise ctx.error(
                f"initial.{key}",
                raw[key],
                f"must have {counts} for robot '{robot.name}', got {len(values[key])}; "
                f"locked joints: {held}: {why}",
            )
        raise ctx.error(
            f"initial.{key}",
            raw[key],
            f"must have {size} numbers for robot '{robot.name}', got {len(values[key])}",
        )


def resolve_control_model(
    doc: Mapping[str, Any], path: str | Path, origin: str | None = None
) -> tuple[str, Path, str] | None:
    """``control.model`` when it names a model file: (the text as written, the file resolved
    against the scenario's folder as the loader resolves it, its kind); None when there is no
    ``control.model``, it names a registry arm, or it is not a text (the loader says why).

    Raises:
        ScenarioError: the file does not exist, with the loader's message.
    """
    control = doc.get("control")
    model = control.get("model") if isinstance(control, Mapping) else None
    if not isinstance(model, str):
        return None
    ctx = _Context(str(path) if origin is None else origin)
    target, kind = model_target(model, "control.model", Path(path), ctx)
    return None if kind == "name" else (model, Path(target), kind)

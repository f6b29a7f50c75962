"""The start of a run given by its tip (``initial.tip``): the inverse kinematics from
``initial.seed``, the tool along a_d(0) when it is pointed, and a start within the joint
limits (revolute angles renamed by 2π, else fixed seeds spread over the limits)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np

from hybrid_force._file_errors import _Context, _fmt
from hybrid_force.control.clik import inverse_kinematics
from hybrid_force.control.pose_clik import pose_inverse_kinematics
from hybrid_force.control.tool import ToolSettings, ToolTarget
from hybrid_force.errors import ReachError, RunWarning
from hybrid_force.sim.run_checks import joint_names, limit_slack


def start_at_tip(
    robot: Any,
    tool: Any,
    surfaces: list[Any],
    path: Any,
    solved: tuple[Any, np.ndarray | None],
    raw: Mapping[str, Any],
    ctx: _Context,
) -> np.ndarray:
    """q0 for ``initial.tip``: ``solved`` = (the tip as checked, the seed (nq,) or None),
    ``raw`` the ``[initial]`` table as written (its refusals name ``initial.tip``)."""

    tip, seed = solved
    try:
        q0 = inverse_kinematics(robot, np.array(tip), seed=seed)
    except ReachError as exc:
        extra = f" (initial.seed = {_fmt(raw['seed'])})" if "seed" in raw else ""
        raise ctx.error(
            "initial.tip", raw["tip"], f"start out of reach{extra}: {' '.join(str(exc).split())}"
        ) from None
    if tool.controlled and tool.task_size > robot.nv:  # Scenario refuses it (tool.check_arm)
        tool = ToolSettings()
    if tool.controlled:
        q0 = _tool_start(tool, robot, surfaces, path, q0, raw["tip"], ctx)
    solve = _start_solver(tool, robot, surfaces, path, raw["tip"])
    return _start_in_limits(robot, q0, solve, raw.get("seed"), "initial.tip")


def _tool_start(
    tool: Any, robot: Any, surfaces: list[Any], path: Any, q0: Any, raw: object, ctx: _Context
) -> Any:
    """The start of ``initial.tip`` with the tool along a_d(0) too (``orientation = "normal"``):
    the pose inverse kinematics from the position-only solution q0."""

    try:
        target = ToolTarget(tool, surfaces[0], path)
        tip = robot.tip_position(q0)
        return pose_inverse_kinematics(robot, target, 0.0, q0, position=tip)
    except ReachError as exc:
        raise ctx.error(
            "initial.tip",
            raw,
            "start out of reach with the tool along its desired direction (tool.orientation = "
            f'"normal"): {" ".join(str(exc).split())}',
        ) from None


_START_SEEDS = 24
"""Seeds (within the joint limits, fixed) tried when the start found from ``initial.seed``
puts a joint outside its limits."""


def _wrapped_into_limits(robot: Any, q: np.ndarray) -> np.ndarray:
    """q with each revolute joint outside its limits turned by a multiple of 2π into them
    where one fits (the same pose: only the joint's angle is renamed)."""
    out = np.array(q, dtype=float)
    outside = {int(i) for i in _outside_joints(robot, out)}
    lower, upper = robot.position_limits
    for joint in robot.model.joints[1:]:
        i = joint.idx_q
        if joint.nq != 1 or "R" not in joint.shortname().removeprefix("JointModel")[:1]:
            continue  # prismatic or a continuous (cos, sin) joint
        if i not in outside:
            continue
        k = math.ceil((lower[i] - out[i]) / (2.0 * math.pi))
        if out[i] + 2.0 * math.pi * k <= upper[i]:
            out[i] += 2.0 * math.pi * k
    return out


def _outside_limits(robot: Any, q: np.ndarray) -> list[str]:
    """The joints of q (nq,) outside their position limits (:func:`_outside_joints`), as
    'name = value (limits [lo, hi])'."""

    lower, upper = robot.position_limits
    names = joint_names(robot)
    return [
        f"{names[i]} = {q[i]:.4g} (limits [{lower[i]:.4g}, {upper[i]:.4g}])"
        for i in _outside_joints(robot, q)
    ]


def _outside_joints(robot: Any, q: np.ndarray) -> np.ndarray:
    """Indices into q (nq,) beyond their position limits by the run's rule (round-off on a
    bound is no crossing: :func:`~hybrid_force.sim.run_checks.limit_slack`)."""

    lower, upper = robot.position_limits
    return np.flatnonzero((q < lower - limit_slack(lower)) | (q > upper + limit_slack(upper)))


def _start_solver(tool: Any, robot: Any, surfaces: list[Any], path: Any, tip: object) -> Any:
    """seed (nq,) → a start with the tip at ``tip`` (and the tool along a_d(0) when pointed),
    as the loader finds it from ``initial.seed``; raises ReachError."""

    position = np.array(tip, dtype=float)
    target = ToolTarget(tool, surfaces[0], path) if tool.controlled else None

    def solve(seed: np.ndarray) -> np.ndarray:
        q = inverse_kinematics(robot, position, seed=seed)
        if target is None:
            return q
        return pose_inverse_kinematics(robot, target, 0.0, q, position=position)

    return solve


def _start_in_limits(
    robot: Any, q0: np.ndarray, solve: Any, seed: np.ndarray | None, key: str
) -> np.ndarray:
    """A start within the joint limits for ``initial.tip``.

    The inverse kinematics of the start knows no joint limits: from ``initial.seed`` (or the
    neutral configuration) it may land on a branch outside them. Then revolute angles are
    first renamed by 2π, and if a joint is still out, ``solve`` (seed (nq,) → a start q for
    the same tip, and tool direction when pointed; raises ReachError) is tried from fixed
    seeds spread over the limits; the in-limits solution nearest to the seed is kept. When
    none is found, q0 is kept with a RunWarning naming the joints (the run reports them too).
    """
    q = _wrapped_into_limits(robot, q0)
    if not _outside_limits(robot, q):
        return q
    lower, upper = robot.position_limits
    single = [j.idx_q for j in robot.model.joints[1:] if j.nq == 1]  # not (cos, sin) joints
    lo = np.where(np.isfinite(lower), lower, -math.pi)[single]
    hi = np.where(np.isfinite(upper), upper, math.pi)[single]
    rng = np.random.default_rng(0)
    ref = robot.neutral() if seed is None else np.asarray(seed, dtype=float)
    best, best_distance = None, math.inf
    for k in range(_START_SEEDS):
        candidate = robot.neutral()
        candidate[single] = 0.5 * (lo + hi) if k == 0 else rng.uniform(lo, hi)
        try:
            found = _wrapped_into_limits(robot, solve(candidate))
        except ReachError:
            continue
        distance = float(np.linalg.norm(found - ref))
        if not _outside_limits(robot, found) and distance < best_distance:
            best, best_distance = found, distance
    if best is not None:
        return best
    warnings.warn(
        RunWarning(
            f"{key}: the start found from the seed puts {', '.join(_outside_limits(robot, q))} "
            f"outside the joint limits, and none of {_START_SEEDS} other seeds gave a start "
            "within them; give initial.seed (or initial.q) on the branch you want"
        ),
        stacklevel=2,
    )
    return q

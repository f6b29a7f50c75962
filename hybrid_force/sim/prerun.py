"""The pre-run checks of a scenario file's run, by running the model before the run:
the path on every surface, the start in reach and on the right side of the surface, the
controller built once, the path followable by inverse kinematics, the sampled force loop
stable, and sim.dt short enough for the contact model.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from hybrid_force._file_errors import _Context, _fmt, _wrap
from hybrid_force.control.clik import _COND_MAX, ClikSettings, newton_ik
from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.base import LoopContext, law_loop_bounds
from hybrid_force.control.pose_clik import follow_pose
from hybrid_force.control.supervisor import check_controller
from hybrid_force.control.tool import ToolSettings, ToolTarget
from hybrid_force.errors import BadInputError, ReachError, ScenarioError
from hybrid_force.model.robot import LWA
from hybrid_force.sim.contact import largest_stable_dt, step_text
from hybrid_force.sim.settings import control_steps

PATH_CHECK_STEP = 0.02
"""Spacing [s] of the samples at which the loader follows the desired path by inverse
kinematics (at most :data:`PATH_CHECK_SAMPLES` samples over [0, sim.duration])."""
PATH_CHECK_SAMPLES = 1000


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

    f0 = float(np.max(control.f_d_for(len(surfaces))))
    dt_max = largest_stable_dt(contact, robot, surfaces, configurations, f0)
    if sim.dt > dt_max:
        raise ctx.error(
            "sim.dt",
            sim.dt,
            f"is too long for the [contact] model: the largest stable step along the path is "
            f"{step_text(dt_max)} s (docs/contact.md, time step)",
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
    tool: Any = None,
) -> None:
    """The checks of the controller's start on its own model (``robot``: ``control.model`` or
    the plant), without building it (:func:`~hybrid_force.control.supervisor.check_controller`):
    q_d(0) in reach, the gains, dt·λ_max(M_c⁻¹K_d) and the law's own checks (the controller's
    own consistency; the loops against the plant are :func:`_check_law_loops`)."""

    try:
        constraint = Constraint(surfaces, normalization=sim.normalization)
        period = control_steps(control, sim) * sim.dt  # the law runs at the control rate
        check_controller(robot, constraint, path, q0, control, period, tool or ToolSettings())
    except ReachError as exc:
        given = path.to_dict()
        start = next((k for k in ("points", "origin") if k in given), "center")
        raise ctx.error(
            f"trajectory.{start}",
            given.get(start),
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

    n = int(min(PATH_CHECK_SAMPLES, max(2, math.ceil(duration / PATH_CHECK_STEP) + 1)))
    damping = ClikSettings().damping if robot.nv > 3 else 0.0
    shown = ", ".join(f"trajectory.{k} = {_fmt(v)}" for k, v in traj.items())
    model, data = robot.model, robot.new_data()
    q = robot.check_q(q0, "q0").copy()
    found: list[np.ndarray] = []
    for t in np.linspace(0.0, duration, n):
        target = path.position(float(t))
        # what inverse_kinematics(robot, target, seed=q, tol=1e-9, max_iter=50) does, on one
        # Pinocchio data for the whole path (this check runs before every run of a sweep)
        q, err = newton_ik(robot, data, target, q, 1e-9, 50)
        if not err < 1e-9:
            p = [round(float(x), 6) for x in target]
            raise ScenarioError(
                f"{ctx.file}: {shown}: the desired path is out of reach at t = {t:.4g} s "
                f"(p_d = {p}), followed from the start; it must be reachable over "
                f"[0, sim.duration = {duration:g} s]"
            ) from None
        # the CLIK's test: cond(J Jᵀ + λ² I) < _COND_MAX, λ its damping (0 for three joints)
        pin.computeJointJacobians(model, data, q)
        J = pin.getFrameJacobian(model, data, robot.tip_id, LWA)[:3]
        sv = np.linalg.svd(J, compute_uv=False)
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


def _check_pose_followable(
    robot: Any,
    surfaces: list[Any],
    path: Any,
    tool: Any,
    q0: Any,
    duration: float,
    ctx: _Context,
) -> list[np.ndarray]:
    """:func:`_check_path_followable` for ``[tool] orientation = "normal"``: the tip position
    and the tool direction (and the roll, when held) followed by the pose inverse kinematics
    (:func:`hybrid_force.control.pose_clik.follow_pose`), the pose task Jacobian as well
    conditioned as the pose CLIK needs. Returns the configurations found."""

    n = int(min(PATH_CHECK_SAMPLES, max(2, math.ceil(duration / PATH_CHECK_STEP) + 1)))
    what = f'tool.orientation = "normal", tool.roll = "{tool.roll}"'
    target = ToolTarget(tool, surfaces[0], path)
    try:
        samples = follow_pose(
            robot, target, robot.check_q(q0, "q0"), np.linspace(0.0, duration, n),
            ClikSettings().damping,
        )  # fmt: skip
    except ReachError as exc:
        raise ctx.error(
            "tool.orientation",
            tool.orientation,
            f"{' '.join(str(exc).split())}, followed from the start ({what}); the tool pose must "
            f"be reachable over [0, sim.duration = {duration:g} s]",
        ) from None
    t, q, singular = samples[-1]
    if singular is not None:
        p = [round(float(x), 6) for x in path.position(t)]
        s_text = ", ".join(f"{x:.3g}" for x in singular)
        raise ctx.error(
            "tool.orientation",
            tool.orientation,
            f"the desired tool pose ({what}) passes a singular configuration at t = {t:.4g} s "
            f"(p_d = {p}, q_d = {np.round(q, 6).tolist()}, singular values of the pose task "
            f"Jacobian: {s_text}); the controller cannot follow it",
        )
    return [q for _, q, _ in samples]


def _check_law_loops(
    robot: Any,
    surfaces: list[Any],
    configurations: list[np.ndarray],
    q0: np.ndarray,
    control: Any,
    sim: Any,
    sensor: Any,
    controller_model: Any,
    model_value: object,
    ctx: _Context,
) -> None:
    """The running law's own pre-run stability checks, on the controller's model.

    Each law says what it needs (``LawSpec.loop_bounds``: its sampled velocity loop, and in a
    sampled run, non-ideal sensing or a control rate below 1/sim.dt, its force loop; derivations
    in each law's ``loop_bounds`` and :mod:`hybrid_force.control.force_loop`); none inherits
    another law's β bound. The controller's model is ``control.model`` (or the plant's file)
    with its masses × ``sim.model_mass_factor``; the plant's masses are the simulator's. The
    first check that fails is refused, naming its key, its value and the bound.
    """

    steps = control_steps(control, sim)
    period = steps * sim.dt
    cutoff = sensor.force_cutoff
    if control.mass_factor != 1.0:
        model_key: str | None = "sim.model_mass_factor"
        model_value = control.mass_factor
    elif controller_model is not None:
        model_key = "control.model"
    else:
        model_key, model_value = None, None
    context = LoopContext(
        plant=robot,
        model=controller_model if controller_model is not None else robot,
        mass_factor=control.mass_factor,
        surfaces=surfaces,
        normalization=sim.normalization,
        configurations=configurations,
        q0=np.asarray(q0, dtype=float),
        settings=control,
        period=period,
        sampled=steps > 1 or not sensor.ideal,
        alpha=1.0 - math.exp(-2.0 * math.pi * cutoff * period) if cutoff else 1.0,
        delay=sensor.force_delay,
        model_key=model_key,
        model_value=model_value,
    )
    for bound in law_loop_bounds(context):
        if not bound.stable:
            raise ctx.error(
                bound.key,
                bound.value,
                f"control.law = {_fmt(control.law)}: {bound.loop} (docs/laws.md, pre-run checks)",
            )

"""What a run records about itself: its meta before it starts, its Result and failure at the end.

:func:`run_meta` is the metadata known before the loop starts (scenario, robot, surfaces,
path, the controller's gains and settings, software versions). :func:`finish_result` turns the
loop's log into the :class:`~hybrid_force.result.Result` with what the run must say about itself
(limits crossed, effort saturation, the contact outcome, warnings; the checks are in
:mod:`hybrid_force.sim.run_checks`). :func:`run_failure` is the
:class:`~hybrid_force.errors.RunFailedError` that reports whatever stopped a run.
"""

from __future__ import annotations

import json
import os
import platform
import uuid
import warnings
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from hybrid_force._version import VERSION
from hybrid_force.control.laws.base import law_spec
from hybrid_force.control.supervisor import HybridController
from hybrid_force.errors import (
    HybridForceError,
    PathError,
    ReachError,
    RunFailedError,
    RunWarning,
    SurfaceError,
)
from hybrid_force.events import Event, RunStopped
from hybrid_force.geometry.paths import Path
from hybrid_force.model.robot import Robot
from hybrid_force.phases import CONTACT
from hybrid_force.result import Result
from hybrid_force.sim.control_side import ControlSide
from hybrid_force.sim.plant import Plant
from hybrid_force.sim.record import Record
from hybrid_force.sim.run_checks import (
    SampleChecks,
    contact_outcome,
    describe,
    joint_names,
    limit_events,
    limit_violations,
    run_behaviour,
    saturated_time,
)
from hybrid_force.sim.settings import Scenario

__all__ = ["failed_run", "finish_result", "merge_events", "run_failure", "run_meta"]


def _versions() -> dict:

    return {
        "hybrid_force": VERSION,
        "pinocchio": pin.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }


def _jsonable(x: object) -> object:
    return json.loads(json.dumps(x, default=lambda o: np.asarray(o).tolist()))


def _model_text(robot: Robot) -> dict[str, str]:
    """``{"model_text", "model_format"}``: the XML a model file's arm was built from (a
    xacro file's expansion) and ``"urdf"`` or ``"mjcf"``; empty for a registry arm (its name
    re-loads it) or a text that cannot be had (a hand-built Robot's missing file)."""
    if not os.path.isabs(str(robot.source)):
        return {}
    try:
        text = robot.model_xml
    except (OSError, UnicodeDecodeError, HybridForceError):
        return {}
    return {"model_text": text, "model_format": "mjcf" if robot.kind == "mjcf" else "urdf"}


def run_meta(sc: Scenario, ctrl: ControlSide, k: int, nq: int) -> dict:
    """The run's metadata known before it starts (the loop adds status, events, timing)."""
    sim, law = sc.sim, ctrl.law
    return {
        "name": sc.name,
        "run_id": uuid.uuid4().hex,
        "description": sc.description,
        "scenario": _jsonable(sc.source) if sc.source is not None else None,
        # what re-loads the arm from any folder: model (registry name or absolute path), tip,
        # package_dirs, xacro_args, lock_off_chain; and the model's text, which the replay
        # rebuilds it from (a xacro file is never expanded again)
        "robot": {**sc.robot.reference, "nq": nq, **_model_text(sc.robot)},
        "surfaces": [s.to_dict() for s in sc.surfaces],
        "path": _path_meta(sc.path),
        "controller": {
            "law": sc.control.law if law is not None else type(ctrl.user).__name__,
            "model": ctrl.model_robot.reference,
            # the running law's own gains and settings (the paper's K_d, Λ, β, γ for arimoto)
            "settings": _jsonable(law.law.info()) if law is not None else None,
        },
        "gains": None if law is None else _gains_meta(sc, law),
        "settings": _acting(
            {
                "dt": sim.dt,
                "duration": sim.duration,
                "integrator": sim.integrator,
                "settle_time": sim.settle_time,
                "baumgarte_alpha": sim.baumgarte.alpha,
                "baumgarte_beta": sim.baumgarte.beta,
                "unilateral": sim.unilateral,
                "normalization": sim.normalization,
                "control_rate": 1.0 / ctrl.period,
                "seed": sim.seed,
            },
            # the rigid contact's: a compliant force needs no stabilisation and never pulls
            ("baumgarte_alpha", "baumgarte_beta", "unilateral") if sc.contact.compliant else (),
        ),
        "sensor": sc.sensor.to_dict(),
        "contact": _acting(sc.contact.to_dict(), _contact_inert(sc)),
        "tool": sc.tool.to_dict()
        if sc.tool.controlled
        else {"orientation": "free", **({"radius": sc.tool.radius} if sc.tool.radius else {})},
        "versions": _versions(),
    }


def _contact_inert(sc: Scenario) -> tuple[str, ...]:
    """The [contact] settings that have no effect in this run (the loader's rules)."""
    inert = () if sc.contact.compliant else ("stiffness", "damping", "exponent")
    return inert + (("friction_velocity",) if sc.contact.friction == 0.0 else ())


def _acting(settings: dict, inert: tuple[str, ...]) -> dict:
    return {k: v for k, v in settings.items() if k not in inert}


def _gains_meta(sc: Scenario, law: HybridController) -> dict:
    """The controller's gains and supervisor settings that this run reads: the paper's K_d,
    Λ, β, γ only for a law that reads them (``LawSpec.gains``), the approach settings only
    with the supervisor; ``control.P``, which no configuration reads, never (issue 27)."""

    c, g = sc.control, law.gains
    spec = law_spec(c.law)
    options = c.options.get(c.law, {})
    paper = {"Kd": g.Kd.tolist(), "Lambda": g.Lambda, "beta": g.beta, "gamma": g.gamma}
    out: dict = {k: v for k, v in paper.items() if spec.reads(k, options)}
    out.update(f_d=law.f_d_contact.tolist(), clik_gain=c.clik_gain, contact_tol=c.contact_tol)
    if c.supervisor:
        out.update(max_dist=c.max_dist, approach_rate=law.approach_rate)
    out.update(mass_factor=c.mass_factor, supervisor=c.supervisor)
    return out


def _path_meta(path: Path) -> dict:
    """The path for the result's metadata: its dict, or its type and repr for a FunctionPath
    (Python callables cannot be stored; the run itself is not affected)."""
    try:
        return path.to_dict()
    except PathError:
        return {"type": "function", "repr": repr(path)}


def merge_events(a: Sequence[Event | dict], b: Sequence[Event | dict]) -> list[dict]:
    """Both lists of events as the stored dicts (:meth:`Event.to_dict`), in time order."""
    stored = [e.to_dict() if isinstance(e, Event) else e for e in [*a, *b]]
    events: list[dict] = _jsonable(stored)  # type: ignore[assignment]  # a list stays a list
    return sorted(events, key=lambda e: e["t"])


def run_failure(exc: BaseException, name: str, t: float) -> RunFailedError:
    """The RunFailedError that reports ``exc``, which stopped run ``name`` at time t [s]."""
    where = f"run '{name}' stopped at t = {t:.6g} s"
    if isinstance(exc, KeyboardInterrupt):
        signal_name = getattr(exc, "signal", "SIGINT")
        return RunFailedError(
            f"{where}: interrupted ({signal_name})", signal=signal_name, reason="interrupted"
        )
    if isinstance(exc, RunFailedError) and exc.reason == "joint limit":
        return RunFailedError(f"{where}: {exc}", reason="joint limit")
    if isinstance(exc, RunFailedError) and exc.reason == "diverged":
        return RunFailedError(f"run '{name}' failed at t = {t:.6g} s: {exc}", reason="diverged")
    if isinstance(exc, ReachError):
        failure = RunFailedError(f"{where}: the desired path cannot be followed: {exc}")
        failure.reason = "path"
        return failure
    if isinstance(exc, SurfaceError | np.linalg.LinAlgError):
        return RunFailedError(f"run '{name}' failed at t = {t:.6g} s: {exc}", reason="diverged")
    return RunFailedError(f"{where} by an unexpected error: {type(exc).__name__}: {exc}")


def failed_run(
    exc: BaseException,
    sc: Scenario,
    meta: dict,
    log: Record,
    plant: Plant,
    ctrl: ControlSide,
    checks: SampleChecks,
    t: float,
    steps: int,
    wall: float,
) -> RunFailedError:
    """The RunFailedError of run ``sc`` that ``exc`` stopped at time t [s], after ``steps``
    steps and ``wall`` s of wall time, with its partial result: the samples ``log`` holds,
    ``meta`` with ``status = "failed"``, ``reason`` and ``error`` (None when the log itself
    is unusable)."""
    failure = run_failure(exc, sc.name, t)
    meta.update(
        status="failed",
        reason=failure.reason,
        error=f"{type(exc).__name__}: {exc}",
        events=merge_events(ctrl.events, [*plant.events, RunStopped(t, failure.reason)]),
        steps_per_second=steps / wall if wall > 0 else 0.0,
        wall_time=wall,
    )
    try:
        failure.result = finish_result(
            log, log.filled, meta, plant.constraint.k, sc.robot, plant, warn=False,
            extra=checks.notes(t),
        )  # fmt: skip
    except Exception:  # the log itself is unusable: report the failure without it
        failure.result = None
    return failure


def finish_result(
    log: Record,
    n: int,
    meta: dict,
    k: int,
    robot: Robot,
    plant: Plant,
    warn: bool = True,
    task_f_d: np.ndarray | None = None,
    extra: Sequence[str] = (),
) -> Result:
    """The Result of the first n samples, with what the run must say about itself in meta.

    Adds ``limits`` (joints beyond their range, velocity or effort limit, see
    :func:`~hybrid_force.sim.run_checks.limit_violations`; the effort against the commanded
    torque), a "joint_limit" or "velocity_limit" event at each joint's first crossing,
    ``saturated_time`` ({joint: s} the plant held at an effort limit, when it enforces them),
    ``friction_energy`` and ``damping_energy`` [J] (dissipated by the contact),
    ``joint_damping_energy`` and ``joint_friction_energy`` [J] (by the joints' own damping
    and friction),
    ``contact_at_end``, ``lost_contact``, ``left_at``, ``behaviour`` (the flags of
    :func:`~hybrid_force.sim.run_checks.run_behaviour`: touched, chatter, force_settled; for a
    run that finished, with ``task_f_d`` (k,) [N] the task's desired force) and ``warnings``:
    the one channel of what the run must say about itself, one line each, in this order: the
    limits and the contact outcome, ``extra`` (the Python warnings the run raised, from
    :func:`~hybrid_force.sim.run_checks.warning_notes`), what it did at the surface; issued
    as RunWarnings with ``warn`` (a failed run reports its failure, not them).
    """
    names = joint_names(robot)
    lower, upper = robot.position_limits
    u_cmd = log.u[:n] if log.u_cmd is None else log.u_cmd[:n]
    limits = limit_violations(
        names, lower, upper, robot.effort_limits, log.t[:n], log.q[:n], u_cmd,
        robot.velocity_limits, log.v[:n],
    )  # fmt: skip
    saturated = None
    if plant.effort is not None:
        saturated = saturated_time(
            names, plant.effort, log.u[:n], u_cmd, float(meta["settings"]["dt"])
        )
    outcome = contact_outcome(plant.ever_in_contact, plant.in_contact, meta.get("events", []))
    notes = [*describe(limits, outcome, saturated), *extra]
    behaviour: dict = {}
    if warn and task_f_d is not None:
        behaviour, surface_notes = run_behaviour(
            log.t[:n], log.f[:n], np.asarray(task_f_d, dtype=float), log.phi[:n],
            log.phase[:n] == CONTACT,
        )  # fmt: skip
        notes += surface_notes
    for note in notes if warn else ():
        warnings.warn(f"run '{meta.get('name')}': {note}", RunWarning, stacklevel=3)
    events = merge_events(meta.get("events", []), limit_events(limits))
    meta.update(
        limits=limits, saturated_time=saturated or {}, warnings=notes, events=events,
        behaviour=behaviour, **outcome,
    )  # fmt: skip
    # [J] dissipated by the plant's friction and compliant damping (docs/contact.md)
    meta.update(friction_energy=plant.friction_energy, damping_energy=plant.damping_energy)
    meta.update(
        joint_damping_energy=plant.joint_damping_energy,
        joint_friction_energy=plant.joint_friction_energy,
    )
    return log.result(n, meta, k)

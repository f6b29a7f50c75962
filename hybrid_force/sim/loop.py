"""The closed loop: sense → control → plant → record → integrate, one plant step at a time.

:func:`simulate` runs a :class:`Scenario` (a plain Python description of one run, which the
TOML loader of :mod:`hybrid_force.scenario.loader` also produces) and returns a
:class:`~hybrid_force.result.Result`. One step (``sim.dt``, 1 ms by default), in the order the
loop in :func:`simulate` reads:

1. the plant's terms and constraint rows at (q, v) (:meth:`Plant.evaluate
   <hybrid_force.sim.plant.Plant.evaluate>`), which only the plant uses;
2. the controller's command: with ideal sensing at the plant's rate the law's u = u0 + B f,
   affine in the force the plant will produce (the paper's exact algebraic loop); otherwise,
   at each control tick, the law on its sensors' readings (:mod:`hybrid_force.sim.sensors`)
   and its own model, its torque held until the next tick
   (:class:`~hybrid_force.sim.control_side.ControlSide`);
3. the plant's q̈ and contact force, together, with release when the surface would pull
   (:meth:`~hybrid_force.sim.plant.Plant.accelerate`);
4. the sample, recorded (:class:`~hybrid_force.sim.record.Record`; its phase is the plant's
   contact state: "contact" only on the surface) and checked for divergence;
5. the controller's integrators and the plant's state advanced to t + dt, with projection onto
   the surface in contact and touch detection and impacts out of it
   (:meth:`~hybrid_force.sim.plant.Plant.advance`).

After the loop (or when anything stops it: divergence, Ctrl-C, SIGTERM, an exception) the
run's samples become its Result, with what it must say about itself in ``meta``: joints that
left their range or exceeded an effort limit, whether the tool ended on the surface
(:mod:`hybrid_force.sim.run_checks`), ``status`` and ``reason``
(:mod:`hybrid_force.sim.run_report`).

``SimSettings(reference=True)`` builds the same loop from the readable numpy components
(:class:`~hybrid_force.sim.plant.ReferencePlant`,
:class:`~hybrid_force.control.supervisor.ReferenceController`,
:class:`~hybrid_force.control.controller.ReferenceControllerModel`) instead of the compiled
ones; the tests compare the two.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable

import numpy as np

from hybrid_force.control.constraint import Constraint
from hybrid_force.control.controller import Controller
from hybrid_force.control.laws.base import law_log_names
from hybrid_force.errors import ControlError, RunFailedError, ScenarioError
from hybrid_force.events import RunStopped
from hybrid_force.law_log import NAMES_KEY as LAW_LOG_NAMES
from hybrid_force.phases import CONTACT
from hybrid_force.result import Result
from hybrid_force.sim.control_side import ToolLog, build_control_side
from hybrid_force.sim.plant import Plant, ReferencePlant
from hybrid_force.sim.record import Record
from hybrid_force.sim.run_checks import (
    JointLimits,
    check_contact_step,
    check_finite,
    check_log_memory,
    warning_notes,
)
from hybrid_force.sim.run_report import finish_result, merge_events, run_failure, run_meta
from hybrid_force.sim.settings import Scenario

__all__ = ["simulate"]


def simulate(
    scenario: Scenario,
    *,
    progress: Callable[[float], None] | None = None,
    controller: Controller | None = None,
) -> Result:
    """Run a scenario and return its result.

    Args:
        scenario: the run.
        progress: optional callback called with the fraction done (0..1) about 100 times.
        controller: your own controller (:class:`~hybrid_force.control.controller.Controller`:
            ``command(t, q, v, f) -> u``), instead of the scenario's law; it runs at
            ``control.rate`` on the ``[sensor]`` measurements, its torque held between ticks.
            The result then has no desired joint path (q_d is NaN) and no Lyapunov function
            (V is NaN); p_d is the scenario's path and f_d its ``control.f_d``.

    Raises:
        RunFailedError: the run started and stopped early, or ended in a state it must not
            claim as a success; ``err.result`` holds every sample computed, its meta has
            ``status = "failed"`` and ``reason``. Subclasses: RunFailedError (non-finite
            state, runaway, singular constraint), RunFailedError (started in contact with
            ``control.supervisor = false`` and ended off the surface), RunFailedError
            (KeyboardInterrupt, i.e. Ctrl-C, or SIGTERM turned into one by the CLI); reason
            "path" when the desired path became singular or unreachable, "error" for any other
            exception (its type and message are in ``meta["error"]``).
        BadInputError subclasses: bad settings, start out of reach, a log that would not fit
            in memory (before the run starts).

    Warns:
        RunWarning: a joint left its URDF range, a command exceeded an effort limit, or the
            tool left the surface and was not back at the end (also in ``meta["warnings"]``).
    """
    if not isinstance(scenario, Scenario):  # not an AttributeError from deep inside
        raise ScenarioError(
            f"simulate() takes a hybrid_force Scenario (load_scenario(...) or Scenario(...)), "
            f"got {scenario!r:.80}"
        )
    sc, sim = scenario, scenario.sim
    robot = sc.robot
    if controller is not None and not callable(getattr(controller, "command", None)):
        raise ControlError(
            f"controller must have a method command(t, q, v, f) -> u, got {controller!r}"
        )
    # Scenario has checked its fields (stacked surfaces only without the supervisor, ...)
    constraint = Constraint(sc.surfaces, normalization=sim.normalization)
    k, nq, nv, dt = constraint.k, robot.nq, robot.nv, sim.dt
    N = round(sim.duration / dt) + 1
    q = robot.check_q(sc.q0, "initial q").copy()
    v = np.zeros(nv) if sc.v0 is None else robot.check_v(sc.v0, "initial v").copy()
    reference = sim.reference
    task_f_d = sc.control.f_d_for(k)
    check_contact_step(sc, q, float(np.max(task_f_d)))
    plant = (ReferencePlant if reference else Plant)(
        robot, constraint, sim, sc.control.contact_tol, sc.contact
    )
    ctrl = build_control_side(sc, controller, q, reference)
    law = ctrl.law
    # the law's own signals (its optional log hook), recorded at every sample
    law_signals = law_log_names(law.law if law is not None else None)
    log_law_values = getattr(law.law, "log_values", None) if law is not None else None
    if not law_signals:
        log_law_values = None
    if float(plant.distance(q).max()) <= sc.control.contact_tol:
        q, v = plant.touch(q, v, 0.0)
    started_in_contact = plant.in_contact
    check_log_memory(N, Record.width(nq, nv, k) + len(law_signals), sim.duration, dt)
    saturates = plant.effort is not None
    log = Record(
        N, nq, nv, k, sim.max_velocity, sim.max_force, measured=ctrl.measured,
        commanded=saturates, law_signals=len(law_signals), tool=sc.tool.controlled,
    )  # fmt: skip
    tool = ToolLog(sc, law, ctrl.measured) if sc.tool.controlled else None
    meta = run_meta(sc, ctrl, k, nq)
    if law_signals:
        meta[LAW_LOG_NAMES] = list(law_signals)
    no_q_d, no_B = np.full(nq, np.nan), np.zeros((nv, k))
    # sim.joint_limits = "stop": position and velocity limits checked at every sample
    stop_at = JointLimits(robot) if sim.joint_limits == "stop" else None
    if stop_at is not None and not stop_at.any:
        stop_at = None
    clik = law.clik if law is not None else None
    f = np.zeros(k)  # the plant's force at the last step: what the force sensor reads
    report_every = max(1, N // 100)
    wall0 = wall1 = time.perf_counter()
    t = 0.0
    i = n_logged = 0  # n_logged: rows filled so far (kept in a failed run's partial result)
    # the Python warnings raised inside the loop (a wrong branch, numpy's): recorded with the
    # time they were raised and reported once, through the run's warnings (finish_result)
    caught_at: list[float] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            for i in range(N):
                t = i * dt
                # 1. the plant's state: its terms and constraint rows (never seen by the controller)
                terms, cons = plant.evaluate(q, v)
                # 2. sense and control: u = u0 + B f (exact loop) or a held torque (sampled)
                cmd = ctrl.command(i, t, q, v, terms, cons, f)
                # 3. the plant: q̈ and the contact force, together; release if it would pull
                ddq, f = plant.accelerate(terms, cons, cmd, t)
                # 4. record sample i (u = u0 + B f) and check the state
                distance = cons.distance if cons is not None else plant.distance(q)
                applied = plant.applied
                ok = log.record(
                    i, t, q, v,
                    clik.q if clik is not None else no_q_d,
                    # the applied torque: the command u0 + B f, or what the effort limits pass
                    cmd.u0 if applied is None else applied,
                    no_B if cmd.B is None or applied is not None else cmd.B,
                    f, terms.p,
                    # sampled: the desired point now, not the one of the last tick (held 1/rate s)
                    clik.p_d if clik is not None and not ctrl.measured else sc.path.position(t),
                    law.f_d if law is not None else task_f_d,
                    distance,
                    law.V if law is not None else np.nan,
                    # the plant's contact state: a tool off the surface is never logged in contact
                    CONTACT if plant.in_contact else ctrl.phase(distance),
                )  # fmt: skip
                if ctrl.measured:
                    log.f_meas[i] = ctrl.f_meas  # type: ignore[index]
                if saturates:  # the commanded torque, before the limits
                    log.u_cmd[i] = cmd.u0 if cmd.B is None else cmd.u0 + cmd.B @ f  # type: ignore[index]
                if log_law_values is not None:
                    log_law_values(log.law_log[i])  # type: ignore[index]
                if tool is not None:
                    log.tool_angle[i] = tool.angle(t, q)  # type: ignore[index]
                n_logged = i + 1
                if len(caught) > len(caught_at):  # a Python warning at this step: its time
                    caught_at.extend([t] * (len(caught) - len(caught_at)))
                if not ok:
                    check_finite(t, q, v, f, sim)  # raises RunFailedError with the details
                if stop_at is not None:
                    stop_at.check(t, q, v)  # raises RunFailedError
                if i == N - 1:
                    break
                if i == 1:
                    wall1 = time.perf_counter()  # steps 0 and 1 loaded (or compiled) the kernels
                # 5. the controller's integrators, then the plant's: (q, v) at t + dt
                ctrl.update(dt, f)
                q, v = plant.advance(q, v, ddq, cmd, t, dt, distance)
                if progress is not None and i % report_every == 0:
                    progress(i / N)
        except BaseException as exc:  # whatever stopped the run, keep what it computed
            wall = time.perf_counter() - wall0
            failure = run_failure(exc, sc.name, t)
            meta.update(
                status="failed",
                reason=failure.reason,
                error=f"{type(exc).__name__}: {exc}",
                events=merge_events(ctrl.events, [*plant.events, RunStopped(t, failure.reason)]),
                steps_per_second=i / wall if wall > 0 else 0.0,
                wall_time=wall,
            )
            try:
                failure.result = finish_result(
                    log, n_logged, meta, k, robot, plant, warn=False,
                    extra=warning_notes(caught, [*caught_at, *[t] * len(caught)]),
                )  # fmt: skip
            except Exception:  # the log itself is unusable: report the failure without it
                failure.result = None
            raise failure from exc
    end = time.perf_counter()
    wall = end - wall0
    # the rate of the steady loop: from step 1 on, once the compiled kernels are loaded
    steady = (
        (N - 2) / (end - wall1) if N > 3 and end > wall1 else (N - 1) / wall if wall > 0 else 0.0
    )
    meta.update(
        status="ok",
        reason=None,
        error=None,
        events=merge_events(ctrl.events, plant.events),
        steps_per_second=steady,
        wall_time=wall,
    )
    if progress is not None:
        progress(1.0)
    extra = warning_notes(caught, [*caught_at, *[t] * len(caught)])
    result = finish_result(log, N, meta, k, robot, plant, task_f_d=task_f_d, extra=extra)
    if started_in_contact and not sc.control.supervisor and result.meta["lost_contact"]:
        left = result.meta["left_at"]
        message = (
            f"run '{sc.name}' lost contact: it started on the surface without the supervisor "
            f"(control.supervisor = false), left it at t = {left:.6g} s and ended off it"
        )
        failed = result.with_meta(status="failed", reason="lost contact", error=message)
        raise RunFailedError(message, result=failed, reason="lost contact")
    return result

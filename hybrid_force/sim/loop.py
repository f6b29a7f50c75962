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
4. the sample, recorded in one call (:class:`~hybrid_force.sim.record.Record` pulls what it
   needs from the plant and the control side; its phase is the plant's contact state:
   "contact" only on the surface) and checked for divergence and joint limits
   (:class:`~hybrid_force.sim.run_checks.SampleChecks`);
5. the controller's integrators and the plant's state advanced to t + dt, with projection onto
   the surface in contact and touch detection and impacts out of it
   (:meth:`~hybrid_force.sim.plant.Plant.advance`).

After the loop (or when anything stops it: divergence, Ctrl-C, SIGTERM, an exception) the
run's samples become its Result, with what it must say about itself in ``meta``: joints that
left their range or exceeded an effort limit, whether the tool ended on the surface
(:mod:`hybrid_force.sim.run_checks`), ``status`` and ``reason``
(:mod:`hybrid_force.sim.run_report`).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable

import numpy as np

from hybrid_force.control.constraint import Constraint
from hybrid_force.control.controller import Controller
from hybrid_force.errors import ControlError, RunFailedError, ScenarioError
from hybrid_force.law_log import NAMES_KEY as LAW_LOG_NAMES
from hybrid_force.result import Result
from hybrid_force.sim.control_side import build_control_side
from hybrid_force.sim.plant import Plant
from hybrid_force.sim.record import Record
from hybrid_force.sim.run_checks import SampleChecks, check_contact_step
from hybrid_force.sim.run_report import failed_run, finish_result, merge_events, run_meta
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
    constraint = Constraint(sc.tool_surfaces, normalization=sim.normalization)
    k, nq, nv, dt = constraint.k, robot.nq, robot.nv, sim.dt
    N = round(sim.duration / dt) + 1
    q = robot.check_q(sc.q0, "initial q").copy()
    v = np.zeros(nv) if sc.v0 is None else robot.check_v(sc.v0, "initial v").copy()
    task_f_d = sc.control.f_d_for(k)
    check_contact_step(sc, q, float(np.max(task_f_d)))
    plant = Plant(robot, constraint, sim, sc.control.contact_tol, sc.contact)
    ctrl = build_control_side(sc, controller, q)
    if float(plant.distance(q).max()) <= sc.control.contact_tol:
        q, v = plant.touch(q, v, 0.0)
    started_in_contact = plant.in_contact
    log = Record(sc, plant, ctrl, N)
    meta = run_meta(sc, ctrl, k, nq)
    if log.law_signals:
        meta[LAW_LOG_NAMES] = list(log.law_signals)
    f = np.zeros(k)  # the plant's force at the last step: what the force sensor reads
    report_every = max(1, N // 100)
    # the step's methods, looked up once
    evaluate, command, accelerate = plant.evaluate, ctrl.command, plant.accelerate
    record, update, advance = log.record, ctrl.update, plant.advance
    law_command = ctrl.law_command  # ctrl.command's own callee, when it only forwards
    wall0 = wall1 = time.perf_counter()
    t, i = 0.0, 0
    # the Python warnings raised inside the loop (a wrong branch, numpy's): recorded with the
    # time they were raised and reported once, through the run's warnings (finish_result)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        checks = SampleChecks(sc, caught)
        # a sample that is ok, in a run that stops at no limit and has caught no warning, has
        # nothing to check: check() is called for the others only
        check, stops = checks.check, checks.stop_at is not None
        try:
            for i in range(N):
                t = i * dt
                # 1. the plant's state: its terms and constraint rows (never seen by the controller)
                terms, cons = evaluate(q, v)
                # 2. sense and control: u = u0 + B f (exact loop) or a held torque (sampled)
                if law_command is not None:
                    cmd = law_command(t, q, v, terms, cons)
                else:
                    cmd = command(i, t, q, v, terms, cons, f)
                # 3. the plant: q̈ and the contact force, together; release if it would pull
                ddq, f = accelerate(terms, cons, cmd, t)
                # 4. record sample i, then check it
                distance = cons.distance if cons is not None else plant.distance(q)
                ok = record(i, t, q, v, terms, cmd, f, distance)
                if not ok or stops or caught:
                    check(t, ok, q, v, f)
                if i == N - 1:
                    break
                if i == 1:
                    wall1 = time.perf_counter()  # steps 0 and 1 loaded (or compiled) the kernels
                # 5. integrate: the controller's integrators, then the plant's (q, v) at t + dt
                update(dt, f)
                q, v = advance(q, v, ddq, cmd, t, dt, distance)
                if progress is not None and i % report_every == 0:
                    progress(i / N)
        except BaseException as exc:  # whatever stopped the run, keep what it computed
            wall = time.perf_counter() - wall0
            raise failed_run(exc, sc, meta, log, plant, ctrl, checks, t, i, wall) from exc
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
    extra = checks.notes(t)
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

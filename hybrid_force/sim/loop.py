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
   and its own model, its torque held until the next tick (:class:`_ControlSide`);
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
(:mod:`hybrid_force.sim.run_checks`), ``status`` and ``reason``.

``SimSettings(reference=True)`` builds the same loop from the readable numpy components
(:class:`~hybrid_force.sim.plant.ReferencePlant`,
:class:`~hybrid_force.control.supervisor.ReferenceController`,
:class:`~hybrid_force.control.controller.ReferenceControllerModel`) instead of the compiled
ones; the tests compare the two.
"""

from __future__ import annotations

import json
import platform
import time
import uuid
import warnings
from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.controller import (
    Controller,
    ControllerModel,
    ReferenceControllerModel,
)
from hybrid_force.control.laws.arimoto import Command
from hybrid_force.control.laws.base import law_log_names
from hybrid_force.control.pose_clik import PoseJointPath
from hybrid_force.control.supervisor import HybridController, ReferenceController
from hybrid_force.control.tool import ToolAngleProbe, ToolTarget
from hybrid_force.errors import (
    ControlError,
    DivergenceError,
    JointLimitError,
    LostContactError,
    ReachError,
    RunFailedError,
    RunInterruptedError,
    RunWarning,
    SingularConfigurationError,
)
from hybrid_force.events import Event, RunStopped
from hybrid_force.geometry.paths import Path, PathParameterError
from hybrid_force.law_log import NAMES_KEY as LAW_LOG_NAMES
from hybrid_force.model.robot import Robot, RobotTerms
from hybrid_force.phases import CONTACT, FREE, NEAR
from hybrid_force.result import Result
from hybrid_force.sim.plant import Plant, ReferencePlant
from hybrid_force.sim.record import Record
from hybrid_force.sim.run_checks import (
    check_log_memory,
    contact_outcome,
    describe,
    limit_events,
    limit_slack,
    limit_violations,
    saturated_time,
)
from hybrid_force.sim.sensors import Sensors
from hybrid_force.sim.settings import Scenario, SimSettings, control_steps

__all__ = ["Scenario", "SimSettings", "control_steps", "simulate"]


def _versions() -> dict:
    from hybrid_force import __version__

    return {
        "hybrid_force": __version__,
        "pinocchio": pin.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }


def _jsonable(x: object) -> object:
    return json.loads(json.dumps(x, default=lambda o: np.asarray(o).tolist()))


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
            ``status = "failed"`` and ``reason``. Subclasses: DivergenceError (non-finite
            state, runaway, singular constraint), LostContactError (started in contact with
            ``control.supervisor = false`` and ended off the surface), RunInterruptedError
            (KeyboardInterrupt, i.e. Ctrl-C, or SIGTERM turned into one by the CLI); reason
            "path" when the desired path became singular or unreachable, "error" for any other
            exception (its type and message are in ``meta["error"]``).
        BadInputError subclasses: bad settings, start out of reach, a log that would not fit
            in memory (before the run starts).

    Warns:
        RunWarning: a joint left its URDF range, a command exceeded an effort limit, or the
            tool left the surface and was not back at the end (also in ``meta["warnings"]``).
    """
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
    _check_contact_step(sc, q, float(np.max(task_f_d)))
    plant = (ReferencePlant if reference else Plant)(
        robot, constraint, sim, sc.control.contact_tol, sc.contact
    )
    ctrl = _control_side(sc, controller, q, reference)
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
    tool = _ToolLog(sc, law, ctrl.measured) if sc.tool.controlled else None
    meta = _meta(sc, ctrl, k, nq)
    if law_signals:
        meta[LAW_LOG_NAMES] = list(law_signals)
    no_q_d, no_B = np.full(nq, np.nan), np.zeros((nv, k))
    # sim.joint_limits = "stop": position and velocity limits checked at every sample
    stop_at = _JointLimits(robot) if sim.joint_limits == "stop" else None
    if stop_at is not None and not stop_at.any:
        stop_at = None
    clik = law.clik if law is not None else None
    f = np.zeros(k)  # the plant's force at the last step: what the force sensor reads
    report_every = max(1, N // 100)
    wall0 = wall1 = time.perf_counter()
    t = 0.0
    i = n_logged = 0  # n_logged: rows filled so far (kept in a failed run's partial result)
    try:
        for i in range(N):
            t = i * dt
            # 1. the plant's state: its terms and constraint rows (the controller never sees them)
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
                # the applied torque: the command u0 + B f, or what the effort limits let through
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
            if not ok:
                _check_finite(t, q, v, f, sim)  # raises DivergenceError with the details
            if stop_at is not None:
                stop_at.check(t, q, v)  # raises JointLimitError
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
        failure = _failure(exc, sc.name, t)
        meta.update(
            status="failed",
            reason=failure.reason,
            error=f"{type(exc).__name__}: {exc}",
            events=_merge(ctrl.events, [*plant.events, RunStopped(t, failure.reason)]),
            steps_per_second=i / wall if wall > 0 else 0.0,
            wall_time=wall,
        )
        try:
            failure.result = _finish(log, n_logged, meta, k, robot, plant, warn=False)
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
        events=_merge(ctrl.events, plant.events),
        steps_per_second=steady,
        wall_time=wall,
    )
    if progress is not None:
        progress(1.0)
    result = _finish(log, N, meta, k, robot, plant)
    if started_in_contact and not sc.control.supervisor and result.meta["lost_contact"]:
        left = result.meta["left_at"]
        message = (
            f"run '{sc.name}' lost contact: it started on the surface without the supervisor "
            f"(control.supervisor = false), left it at t = {left:.6g} s and ended off it"
        )
        failed = result.with_meta(status="failed", reason="lost contact", error=message)
        raise LostContactError(message, result=failed)
    return result


class _ControlSide:
    """The controller as the loop sees it: a command per step, its integrators, its logs.

    Ideal sensing at the plant's rate (``measured`` False): the law's command is affine in the
    force the plant will produce (u = u0 + B f) and the plant resolves that loop exactly (the
    paper's runs). The law then evaluates its model at the plant's state; when that model is
    the plant's own model file, the plant's terms at that state are the same numbers and are
    passed instead of being computed twice.

    Sampled (``measured`` True: a control rate below the plant's, sensors that are not ideal,
    or a user's controller): every ``per_tick`` plant steps the controller reads its sensors,
    computes its terms from its own model at the measured state, and its torque is held
    (zero-order hold).
    """

    def __init__(
        self,
        sc: Scenario,
        law: HybridController | None,
        user: Controller | None,
        own: ControllerModel | None,
        model_robot: Robot,
        per_tick: int,
        measured: bool,
    ) -> None:
        self.law, self.user, self.own = law, user, own
        self.model_robot = model_robot  # the controller's model of the arm
        self.per_tick, self.measured = per_tick, measured
        self.period = per_tick * sc.sim.dt
        self.sensors = Sensors(sc.sensor, self.period, sc.sim.seed) if measured else None
        self.f_meas = np.zeros(len(sc.surfaces))
        self.max_dist = sc.control.max_dist
        self.nv = sc.robot.nv
        self._held: Command | None = None

    @property
    def events(self) -> list[Event]:
        return self.law.events if self.law is not None else []

    def command(
        self,
        i: int,
        t: float,
        q: np.ndarray,
        v: np.ndarray,
        terms: RobotTerms,
        cons: ConstraintTerms | None,
        f: np.ndarray,
    ) -> Command:
        """The command at plant step i (time t [s]); f (k,) [N] is the plant's last force."""
        law = self.law
        if not self.measured:
            assert law is not None
            if self.own is None:
                return law.command(t, q, v, terms, cons)
            return law.command(t, q, v, *self.own.evaluate(q, v))
        if i % self.per_tick == 0:  # a tick: sense, then control; the torque is held
            assert self.sensors is not None
            if law is not None and i:  # the law's integrators and CLIK over the period
                law.update(self.period, self.f_meas)
            q_m, v_m, self.f_meas = self.sensors.measure(q, v, f)
            if law is None:
                assert self.user is not None
                u = _user_torque(self.user, t, q_m, v_m, self.f_meas, self.nv)
            else:
                assert self.own is not None
                c = law.command(t, q_m, v_m, *self.own.evaluate(q_m, v_m))
                u = c.u0 + c.B @ self.f_meas if c.B is not None else c.u0.copy()
            self._held = Command(u, None)
        assert self._held is not None
        return self._held

    def update(self, dt: float, f: np.ndarray) -> None:
        """The exact loop's integrators over one plant step with the force f (k,) [N]."""
        if not self.measured:
            assert self.law is not None
            self.law.update(dt, f)

    def phase(self, distance: np.ndarray) -> int:
        """The phase logged off the surface: the supervisor's (free or near), or for a user's
        controller near when the tip's distances (k,) [m] are within ``control.max_dist``."""
        if self.law is not None:
            return min(self.law.phase, NEAR)
        return NEAR if float(distance.max()) <= self.max_dist else FREE


class _ToolLog:
    """The tool axis' angle from its desired direction a_d(t) at each sample (``[tool]``).

    a_d is the desired joint path's own (it is at time t) when the law runs at the plant's
    rate, else evaluated at t; the axis is the plant's, at its state q.
    """

    def __init__(self, sc: Scenario, law: HybridController | None, measured: bool) -> None:
        self.probe = ToolAngleProbe(sc.robot, sc.tool)
        clik = law.clik if law is not None else None
        self.clik = clik if isinstance(clik, PoseJointPath) and not measured else None
        self.target = ToolTarget(sc.tool, sc.surfaces[0], sc.path)

    def angle(self, t: float, q: np.ndarray) -> float:
        """[rad] at time t [s] and configuration q (nq,)."""
        a_d = self.clik.a_d if self.clik is not None else self.target.axis(t)[0]
        return self.probe.angle(q, a_d)


def _control_side(
    sc: Scenario, user: Controller | None, q: np.ndarray, reference: bool
) -> _ControlSide:
    """The controller of the run: the scenario's law on its own model, or the user's."""
    sim = sc.sim
    per_tick = control_steps(sc.control, sim)
    measured = user is not None or per_tick > 1 or not sc.sensor.ideal
    # the controller's own model: the plant's model file, or control.model (same joints)
    model_robot = sc.controller_model if sc.controller_model is not None else sc.robot
    own = None
    if measured or model_robot is not sc.robot:
        own_type = ReferenceControllerModel if reference else ControllerModel
        own = own_type(model_robot, sc.surfaces, sim.normalization)
    law = None
    if user is None:
        constraint = (
            own.constraint if own is not None else Constraint(sc.surfaces, sim.normalization)
        )
        law_type = ReferenceController if reference else HybridController
        law = law_type(
            model_robot, constraint, sc.path, q, sc.control, dt=per_tick * sim.dt, tool=sc.tool
        )
    return _ControlSide(sc, law, user, own, model_robot, per_tick, measured)


def _meta(sc: Scenario, ctrl: _ControlSide, k: int, nq: int) -> dict:
    """The run's metadata known before it starts (the loop adds status, events, timing)."""
    sim, law = sc.sim, ctrl.law
    return {
        "name": sc.name,
        "run_id": uuid.uuid4().hex,
        "description": sc.description,
        "scenario": _jsonable(sc.source) if sc.source is not None else None,
        # what re-loads the arm from any folder: model (registry name or absolute path), tip,
        # package_dirs, xacro_args, lock_off_chain
        "robot": {**sc.robot.reference, "nq": nq},
        "surfaces": [s.to_dict() for s in sc.surfaces],
        "path": _path_meta(sc.path),
        "controller": {
            "law": sc.control.law if law is not None else type(ctrl.user).__name__,
            "model": ctrl.model_robot.reference,
            # the running law's own gains and settings (the paper's K_d, Λ, β, γ for arimoto)
            "settings": _jsonable(law.law.info()) if law is not None else None,
        },
        "gains": None
        if law is None
        else {
            "Kd": law.gains.Kd.tolist(),
            "Lambda": law.gains.Lambda,
            "beta": law.gains.beta,
            "gamma": law.gains.gamma,
            "f_d": law.f_d_contact.tolist(),
            "clik_gain": sc.control.clik_gain,
            "max_dist": sc.control.max_dist,
            "contact_tol": sc.control.contact_tol,
            "P": sc.control.P,
            "approach_rate": law.approach_rate,
            "mass_factor": sc.control.mass_factor,
            "supervisor": sc.control.supervisor,
        },
        "settings": {
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
        "sensor": sc.sensor.to_dict(),
        "contact": sc.contact.to_dict(),
        "tool": sc.tool.to_dict(),
        "versions": _versions(),
    }


def _check_contact_step(sc: Scenario, q0: np.ndarray, f0: float) -> None:
    """Refuse a time step too long for the contact model (compliant stiffness, friction's
    regularisation) at the start configuration q0 (nq,); f0 [N]: the task's force."""
    from hybrid_force.errors import ContactSettingsError
    from hybrid_force.sim.contact import largest_stable_dt, step_text

    dt_max = largest_stable_dt(sc.contact, sc.robot, sc.surfaces, [q0], f0)
    if sc.sim.dt > dt_max:
        raise ContactSettingsError(
            f"sim.dt = {sc.sim.dt:g} s is too long for the contact "
            f"({_contact_text(sc.contact.to_dict())}): the largest stable step at the start "
            f"is {step_text(dt_max)} s (docs/contact.md, time step)",
            key="sim.dt",
            value=sc.sim.dt,
        )


def _contact_text(contact: dict) -> str:
    """The contact settings as the ``[contact]`` keys that matter for the time step."""
    keys: tuple[str, ...] = ()
    if contact["model"] == "compliant":
        keys = ("stiffness", "damping", "exponent")
    keys += ("friction", "friction_velocity") if contact["friction"] > 0 else ()
    return ", ".join(f"contact.{k} = {contact[k]:g}" for k in keys)


def _user_torque(
    controller: Controller, t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray, n: int
) -> np.ndarray:
    """The user controller's torque at a tick, checked: (n,) finite real numbers."""
    u = np.asarray(controller.command(t, q.copy(), v.copy(), f.copy()), dtype=float)
    if u.shape != (n,) or not np.all(np.isfinite(u)):
        raise ControlError(
            f"controller {type(controller).__name__}.command(t = {t:.6g} s, ...) returned "
            f"{u!r}; it must return {n} finite joint torques"
        )
    return u.copy()


def _failure(exc: BaseException, name: str, t: float) -> RunFailedError:
    """The RunFailedError that reports ``exc``, which stopped run ``name`` at time t [s]."""
    where = f"run '{name}' stopped at t = {t:.6g} s"
    if isinstance(exc, KeyboardInterrupt):
        signal_name = getattr(exc, "signal", "SIGINT")
        return RunInterruptedError(f"{where}: interrupted ({signal_name})", signal=signal_name)
    if isinstance(exc, JointLimitError):
        return JointLimitError(f"{where}: {exc}")
    if isinstance(exc, DivergenceError):
        return DivergenceError(f"run '{name}' failed at t = {t:.6g} s: {exc}")
    if isinstance(exc, ReachError):
        failure = RunFailedError(f"{where}: the desired path cannot be followed: {exc}")
        failure.reason = "path"
        return failure
    if isinstance(exc, SingularConfigurationError | np.linalg.LinAlgError):
        return DivergenceError(f"run '{name}' failed at t = {t:.6g} s: {exc}")
    return RunFailedError(f"{where} by an unexpected error: {type(exc).__name__}: {exc}")


def _finish(
    log: Record, n: int, meta: dict, k: int, robot: Robot, plant: Plant, warn: bool = True
) -> Result:
    """The Result of the first n samples, with what the run must say about itself in meta.

    Adds ``limits`` (joints beyond their range, velocity or effort limit, see
    :func:`~hybrid_force.sim.run_checks.limit_violations`; the effort against the commanded
    torque), a "joint_limit" or "velocity_limit" event at each joint's first crossing,
    ``saturated_time`` ({joint: s} held at an effort limit, when the plant enforces them),
    ``friction_energy`` and ``damping_energy`` [J] (dissipated by the contact),
    ``contact_at_end``, ``lost_contact``, ``left_at`` and ``warnings`` (one line each, also
    issued as Python warnings with ``warn``: a failed run reports its failure, not them).
    """
    names = _joint_names(robot)
    lower, upper = robot.position_limits
    u_cmd = log.u[:n] if log.u_cmd is None else log.u_cmd[:n]
    limits = limit_violations(
        names, lower, upper, robot.effort_limits, log.t[:n], log.q[:n], u_cmd,
        robot.velocity_limits, log.v[:n],
    )  # fmt: skip
    saturated = None
    if plant.effort is not None:
        saturated = saturated_time(names, plant.effort, u_cmd, float(meta["settings"]["dt"]))
    outcome = contact_outcome(plant.ever_in_contact, plant.in_contact, meta.get("events", []))
    notes = describe(limits, outcome, saturated)
    for note in notes if warn else ():
        warnings.warn(f"run '{meta.get('name')}': {note}", RunWarning, stacklevel=3)
    events = _merge(meta.get("events", []), limit_events(limits))
    meta.update(
        limits=limits, saturated_time=saturated or {}, warnings=notes, events=events, **outcome
    )
    # [J] dissipated by the plant's friction and compliant damping (docs/contact.md)
    meta.update(friction_energy=plant.friction_energy, damping_energy=plant.damping_energy)
    return log.result(n, meta, k)


class _JointLimits:
    """The position and velocity limits a run with ``sim.joint_limits = "stop"`` stops at."""

    def __init__(self, robot: Robot) -> None:
        # the slack of run_checks.limit_violations: round-off on a bound is no crossing
        lower, upper = robot.position_limits
        self.lower, self.upper = lower - limit_slack(lower), upper + limit_slack(upper)
        velocity = robot.velocity_limits
        self.velocity = velocity + limit_slack(velocity, relative=True)
        self.names = _joint_names(robot)
        self.any = bool(np.isfinite(lower).any() or np.isfinite(upper).any())
        self.any |= bool(np.isfinite(velocity).any())

    def check(self, t: float, q: np.ndarray, v: np.ndarray) -> None:
        """Raise JointLimitError naming the first joint beyond a limit at time t [s]."""
        if (
            np.all(q >= self.lower)
            and np.all(q <= self.upper)
            and np.all(np.abs(v) <= self.velocity)
        ):
            return
        for j, name in enumerate(self.names):
            if not self.lower[j] <= q[j] <= self.upper[j]:
                raise JointLimitError(
                    f"joint {name} left its range [{self.lower[j]:.6g}, {self.upper[j]:.6g}] at "
                    f't = {t:.6g} s (q = {q[j]:.6g}; sim.joint_limits = "stop")'
                )
            if j < v.shape[0] and not abs(v[j]) <= self.velocity[j]:
                raise JointLimitError(
                    f"joint {name} exceeded its velocity limit {self.velocity[j]:.6g} at "
                    f't = {t:.6g} s (v = {v[j]:.6g}; sim.joint_limits = "stop")'
                )


def _joint_names(robot: Robot) -> list[str]:
    """Names of the joints, one per column of q (nq = nv for every arm the loader builds)."""
    model = robot.model
    names = [""] * robot.nq
    for j in range(1, model.njoints):
        joint = model.joints[j]
        for c in range(joint.nq):
            names[joint.idx_q + c] = model.names[j] if joint.nq == 1 else f"{model.names[j]}[{c}]"
    return names


def _path_meta(path: Path) -> dict:
    """The path for the result's metadata: its dict, or its type and repr for a FunctionPath
    (Python callables cannot be stored; the run itself is not affected)."""
    try:
        return path.to_dict()
    except PathParameterError:
        return {"type": "function", "repr": repr(path)}


def _merge(a: Sequence[Event | dict], b: Sequence[Event | dict]) -> list[dict]:
    """Both lists of events as the stored dicts (:meth:`Event.to_dict`), in time order."""
    stored = [e.to_dict() if isinstance(e, Event) else e for e in [*a, *b]]
    events: list[dict] = _jsonable(stored)  # type: ignore[assignment]  # a list stays a list
    return sorted(events, key=lambda e: e["t"])


def _check_finite(t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray, sim: SimSettings) -> None:
    vmax = float(np.abs(v).max())
    fmax = float(np.abs(f).max()) if f.size else 0.0
    if vmax <= sim.max_velocity and fmax <= sim.max_force and np.isfinite(q @ q):
        return
    if not (np.isfinite(vmax) and np.isfinite(fmax) and np.all(np.isfinite(q))):
        raise DivergenceError(
            f"non-finite state at t = {t:.6g} s: q = {q.tolist()}, v = {v.tolist()}"
        )
    if vmax > sim.max_velocity:
        raise DivergenceError(
            f"runaway at t = {t:.6g} s: |q̇| = {vmax:.3g} > {sim.max_velocity:.3g} "
            f"(q = {np.round(q, 6).tolist()}, v = {np.round(v, 6).tolist()})"
        )
    raise DivergenceError(
        f"runaway at t = {t:.6g} s: |f| = {fmax:.3g} N > {sim.max_force:.3g} N "
        f"(q = {np.round(q, 6).tolist()})"
    )

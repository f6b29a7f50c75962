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
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pinocchio as pin

from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.controller import (
    Controller,
    ControllerModel,
    ReferenceControllerModel,
    check_same_joints,
)
from hybrid_force.control.laws.arimoto import Command
from hybrid_force.control.supervisor import ControlSettings, HybridController, ReferenceController
from hybrid_force.errors import (
    ControlError,
    DivergenceError,
    LostContactError,
    ReachError,
    RunFailedError,
    RunInterruptedError,
    RunWarning,
    SensorError,
    SingularConfigurationError,
)
from hybrid_force.geometry.paths import Path, PathParameterError
from hybrid_force.geometry.surfaces import Surface
from hybrid_force.model.robot import Robot, RobotTerms
from hybrid_force.phases import CONTACT, FREE, NEAR
from hybrid_force.result import Result
from hybrid_force.sim.dynamics import Baumgarte
from hybrid_force.sim.plant import Plant, ReferencePlant
from hybrid_force.sim.record import Record
from hybrid_force.sim.run_checks import (
    check_log_memory,
    contact_outcome,
    describe,
    limit_violations,
)
from hybrid_force.sim.sensors import Sensors, SensorSettings

__all__ = ["Scenario", "SimSettings", "simulate"]

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
Integrator = Literal["euler", "rk4"]


@dataclass(frozen=True)
class SimSettings:
    """Settings of the simulation.

    Attributes:
        duration: simulated time [s].
        dt: time step [s] (1 ms by default).
        integrator: "euler" (semi-implicit) or "rk4" (command held over the step).
        baumgarte: stabilisation gains (section 6.2).
        unilateral: release the contact when the surface would have to pull (f < 0).
        release_tol: f below −release_tol [N] releases.
        max_velocity: |q̇_i| beyond this [rad/s or m/s] is a runaway.
        max_force: |f| beyond this [N] is a runaway.
        settle_time: metrics "after settling" start here [s].
        normalization: constraint row scaling, "tip" (f in N) or "joint" (the paper's J_Φn).
        reference: use the straightforward step instead of the fast one: every robot term
            from its own Pinocchio call, the general k-row constraint algebra, the numpy laws
            and CLIK, and a dense numpy solve of the KKT system instead of
            pin.forwardDynamics; no compiled kernel but the recorder's (the sample row is
            written the same way in both). About 10× slower; for tests.
        seed: seed of the sensors' noise (an integer ≥ 0): a run with noisy sensors is
            reproducible from it.
    """

    duration: float = 20.0
    dt: float = 1e-3
    integrator: Integrator = "euler"
    baumgarte: Baumgarte = field(default_factory=Baumgarte)
    unilateral: bool = True
    release_tol: float = 1e-9
    max_velocity: float = 1e3
    max_force: float = 1e7
    settle_time: float = 5.0
    normalization: Literal["tip", "joint"] = "tip"
    reference: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        """Check every field; numbers are stored as floats, flags as bools.

        Raises SimSettingsError (a BadInputError) naming the field as the scenario file's
        ``[sim]`` key spells it (``sim.dt``) with the value and what is valid.
        """
        from hybrid_force import _checks as checks
        from hybrid_force.errors import SimSettingsError

        for name, strict, unit in (
            ("duration", True, "s"),
            ("dt", True, "s"),
            ("release_tol", True, "N"),
            ("max_velocity", True, "rad/s or m/s"),
            ("max_force", True, "N"),
            ("settle_time", False, "s"),
        ):
            what = f"sim.{name}"
            value = getattr(self, name)
            value = checks.number(
                value, what, SimSettingsError, minimum=0, strict=strict, unit=unit
            )
            object.__setattr__(self, name, value)
        if self.dt > self.duration:
            raise SimSettingsError(
                f"sim.dt = {self.dt} s is larger than sim.duration = {self.duration} s"
            )
        if self.duration / self.dt > 5e7:
            raise SimSettingsError(
                f"sim.duration / sim.dt = {self.duration / self.dt:.3g} steps is absurd (max 5e7)"
            )
        for name, choices in (
            ("integrator", ("euler", "rk4")),
            ("normalization", ("tip", "joint")),
        ):
            checks.one_of(getattr(self, name), f"sim.{name}", SimSettingsError, choices)
        for name in ("unilateral", "reference"):
            value = checks.flag(getattr(self, name), f"sim.{name}", SimSettingsError)
            object.__setattr__(self, name, value)
        seed = checks.integer(self.seed, "sim.seed", SimSettingsError, minimum=0)
        object.__setattr__(self, "seed", seed)
        if not isinstance(self.baumgarte, Baumgarte):
            raise SimSettingsError(
                "sim.baumgarte (SimSettings.baumgarte) must be a hybrid_force.Baumgarte, "
                f"e.g. Baumgarte(alpha=50.0, beta=50.0), got {checks.shown(self.baumgarte)}"
            )


@dataclass(frozen=True)
class Scenario:
    """One run, described in Python (the TOML loader builds the same object).

    Attributes:
        robot: the plant, a :class:`~hybrid_force.Robot` (the controller's model is the
            same arm, masses × mass_factor).
        surfaces: a non-empty sequence of :class:`~hybrid_force.Surface` touched by
            the tip (stored as a tuple).
        path: desired task-space path, a :class:`~hybrid_force.Path` (on the surface).
        q0: (nq,) start configuration. v0: None or (nv,) start velocity (None: 0). Both are
            stored as new read-only float64 arrays.
        control: controller settings. sim: simulation settings.
        sensor: what the controller measures (default: ideal sensing, the plant's state).
        controller_model: the controller's own model of the arm (``control.model``): another
            :class:`~hybrid_force.model.robot.Robot` with the plant's joints (a heavier link, say);
            None: the plant's own model. ``control.mass_factor`` applies on top of it.
        name: a short name (used for output folders): letters, digits, '_', '-', '.', not
            starting with '.' or '-', at most ``NAME_MAX_LENGTH`` = 100 characters (the
            scenario file's rule, ``NAME_PATTERN``, matched in full). description: free text.
        source: the scenario as loaded from a file (JSON-able dict), stored in the result.

    Checked on construction, like a scenario file by its loader (ScenarioValueError, or the
    GainError of a K_d or f_d that does not fit the arm or the surfaces, naming the field):

    * the types and shapes above, finite q0 and v0; K_d's size against the arm's joints and
      f_d's count against the surfaces;
    * a run that starts in contact (``control.supervisor`` False): the desired path within
      ``ON_SURFACE_TOL`` (1e-6 m) of every surface over [0, sim.duration] (sampled by
      :func:`~hybrid_force.geometry.paths.check_on_surface`) and the start tip p(q0) within
      ``control.contact_tol`` of every surface;
    * with the supervisor: a start inside the solid (distance < −contact_tol) is refused, and
      so are stacked surfaces (k > 1), whose approach would touch a subset first;
    * the control rate (``control.rate``) a whole number of plant steps, not faster than them.
    """

    NAME_PATTERN = r"[A-Za-z0-9_][A-Za-z0-9_.\-]*"
    NAME_MAX_LENGTH = 100

    robot: Robot
    surfaces: Sequence[Surface]
    path: Path
    q0: np.ndarray
    v0: np.ndarray | None = None
    control: ControlSettings = field(default_factory=ControlSettings)
    sim: SimSettings = field(default_factory=SimSettings)
    name: str = "run"
    description: str = ""
    source: dict | None = None
    sensor: SensorSettings = field(default_factory=SensorSettings)
    controller_model: Robot | None = None

    def __post_init__(self) -> None:
        """Validate the fields (see the class docstring); q0, v0, surfaces are stored anew."""
        import re
        from collections.abc import Mapping

        from hybrid_force import _checks as checks
        from hybrid_force.control.laws.arimoto import check_damping_gain
        from hybrid_force.errors import ScenarioValueError as Bad

        set_ = object.__setattr__
        robot = self.robot
        if not isinstance(robot, Robot):
            raise Bad(
                "Scenario.robot must be a hybrid_force.model.robot.Robot (e.g. load_robot('rtr')), "
                f"got {checks.shown(robot)}"
            )
        surfaces = self.surfaces
        if isinstance(surfaces, Surface):
            raise Bad(f"Scenario.surfaces must be a sequence of surfaces: wrap it, [{surfaces!r}]")
        if not isinstance(surfaces, Sequence) or isinstance(surfaces, str | bytes) or not surfaces:
            raise Bad(
                "Scenario.surfaces must be a non-empty sequence (list, tuple) of "
                f"hybrid_force.geometry.surfaces.Surface, got {checks.shown(surfaces)}"
            )
        for i, surface in enumerate(surfaces):
            if not isinstance(surface, Surface):
                raise Bad(
                    f"Scenario.surfaces[{i}] must be a hybrid_force.Surface (Cylinder, "
                    f"Sphere, Plane, FunctionSurface), got {checks.shown(surface)}"
                )
        set_(self, "surfaces", tuple(surfaces))
        if not isinstance(self.path, Path):
            raise Bad(
                "Scenario.path must be a hybrid_force.Path (Helix, Circle, FunctionPath), "
                f"got {checks.shown(self.path)}"
            )
        for key, size, optional in (("q0", robot.nq, False), ("v0", robot.nv, True)):
            value = getattr(self, key)
            if optional and value is None:
                continue
            valid = f"{size} finite real numbers (robot '{robot.name}' has {size})"
            array = checks.array(value, f"Scenario.{key}", Bad, valid=valid)
            if array.shape != (size,):
                raise Bad(f"Scenario.{key} must be {valid}, got shape {array.shape}")
            array.setflags(write=False)
            set_(self, key, array)
        for key, kind in (("control", ControlSettings), ("sim", SimSettings)):
            value = getattr(self, key)
            if not isinstance(value, kind):
                raise Bad(f"Scenario.{key} must be a {kind.__name__}, got {checks.shown(value)}")
        name = self.name
        if not isinstance(name, str) or not (
            re.fullmatch(self.NAME_PATTERN, name) and len(name) <= self.NAME_MAX_LENGTH
        ):
            raise Bad(
                f"Scenario.name must be a simple name of 1 to {self.NAME_MAX_LENGTH} letters, "
                "digits, '_', '-', '.' (not starting with '.' or '-'): it names the output folder "
                f"runs/<name>/; got {checks.shown(name)}"
            )
        if not isinstance(self.description, str):
            raise Bad(f"Scenario.description must be a str, got {checks.shown(self.description)}")
        if self.source is not None and not isinstance(self.source, Mapping):
            raise Bad(
                "Scenario.source must be None or the scenario file's data (a dict), "
                f"got {checks.shown(self.source)}"
            )
        control = self.control
        if control.Kd is not None:
            check_damping_gain(control.Kd, robot.nv)
        control.f_d_for(len(self.surfaces))
        if not isinstance(self.sensor, SensorSettings):
            raise Bad(
                "Scenario.sensor must be a hybrid_force.sim.sensors.SensorSettings, "
                f"got {checks.shown(self.sensor)}"
            )
        control_steps(control, self.sim)
        if self.controller_model is not None:
            if not isinstance(self.controller_model, Robot):
                raise Bad(
                    "Scenario.controller_model must be None or a hybrid_force.model.robot.Robot, "
                    f"got {checks.shown(self.controller_model)}"
                )
            check_same_joints(robot, self.controller_model)
        self._check_start_and_path()

    def _check_start_and_path(self) -> None:
        """The contact conditions of the start (class docstring), as the scenario loader's."""
        from hybrid_force.errors import ScenarioValueError as Bad
        from hybrid_force.geometry.paths import ON_SURFACE_TOL, check_on_surface

        control, surfaces, k = self.control, self.surfaces, len(self.surfaces)
        if k > 1 and control.supervisor:
            raise Bad(
                f"Scenario.surfaces: {k} stacked surfaces are supported only for a run that starts "
                "in contact with all of them (control.supervisor = false, ControlSettings("
                "supervisor=False)): contact with a subset of the surfaces, as an approach would "
                "make, is not implemented"
            )
        p = self.robot.tip_position(self.q0)
        tip = f"the tip p(q0) = {np.round(p, 6).tolist()} m"
        distances = [float(s.distance(p)) for s in surfaces]
        if control.supervisor:
            i = int(np.argmin(distances))
            if distances[i] < -control.contact_tol:
                raise Bad(
                    f"Scenario.q0: {tip} is {-distances[i]:.3g} m behind surfaces[{i}] "
                    f"({surfaces[i]!r}), inside the solid; start on the free side (distance "
                    f">= -control.contact_tol = {-control.contact_tol:g} m)"
                )
            return
        duration = self.sim.duration
        for i, surface in enumerate(surfaces):
            report = check_on_surface(self.path, surface, 0.0, duration)
            if report.worst_distance > ON_SURFACE_TOL:
                raise Bad(
                    f"Scenario.path is not on surfaces[{i}] ({surface!r}): "
                    f"{report.worst_distance:.3g} m away at t = {report.time_of_worst:.4g} s "
                    f"(p_d = {np.round(report.point_of_worst, 6).tolist()}); a run that starts in "
                    "contact (control.supervisor = False) needs the desired path within "
                    f"ON_SURFACE_TOL = {ON_SURFACE_TOL:g} m of every surface over "
                    f"[0, sim.duration = {duration:g} s]"
                )
        for i, d in enumerate(distances):
            if abs(d) > control.contact_tol:
                raise Bad(
                    f"Scenario.q0: the run starts in contact (control.supervisor = False) but "
                    f"{tip} is {d:.3g} m from surfaces[{i}] ({surfaces[i]!r}); it must be within "
                    f"control.contact_tol = {control.contact_tol:g} m of every surface"
                )


def control_steps(control: ControlSettings, sim: SimSettings) -> int:
    """Plant steps per control tick: 1/(rate·dt), which must be a whole number ≥ 1.

    Raises:
        SensorError: naming control.rate and sim.dt, with the nearest rates that fit.
    """
    if control.rate is None:
        return 1
    ratio = 1.0 / (control.rate * sim.dt)
    steps = round(ratio)
    if steps < 1 or abs(ratio - steps) > 1e-9 * ratio:
        fits = sorted({1.0 / (n * sim.dt) for n in (max(int(ratio), 1), int(ratio) + 1)})
        raise SensorError(
            f"control.rate = {control.rate:g} Hz is not a whole number of plant steps of "
            f"sim.dt = {sim.dt:g} s (1 / (rate · dt) = {ratio:.6g}); the controller ticks every "
            f"n plant steps: rates that fit nearby: {', '.join(f'{r:g} Hz' for r in fits)}"
            + ("; it cannot be faster than the plant" if ratio < 1 else "")
        )
    return steps


def _versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    try:
        own = version("hybrid_force")
    except PackageNotFoundError:
        own = "0+unknown"
    return {
        "hybrid_force": own,
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
    plant = (ReferencePlant if reference else Plant)(
        robot, constraint, sim.baumgarte, sim.integrator, sim.unilateral, sim.release_tol,
        sc.control.contact_tol,
    )  # fmt: skip
    ctrl = _control_side(sc, controller, q, reference)
    law = ctrl.law
    if float(plant.distance(q).max()) <= sc.control.contact_tol:
        q, v = plant.touch(q, v, 0.0)
    started_in_contact = plant.in_contact
    check_log_memory(N, Record.width(nq, nv, k), sim.duration, dt)
    log = Record(N, nq, nv, k, sim.max_velocity, sim.max_force, measured=ctrl.measured)
    meta = _meta(sc, ctrl, k, nq)
    no_q_d, no_B = np.full(nq, np.nan), np.zeros((nv, k))
    task_f_d = sc.control.f_d_for(k)
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
            ok = log.record(
                i, t, q, v,
                clik.q if clik is not None else no_q_d,
                cmd.u0, no_B if cmd.B is None else cmd.B, f, terms.p,
                # sampled: the desired point now, not the one of the last tick (held 1/rate s)
                clik.p_d if clik is not None and not ctrl.measured else sc.path.position(t),
                law.f_d if law is not None else task_f_d,
                distance,
                law.V if law is not None else np.nan,
                # the plant's contact state: a tool off the surface is never logged in contact
                CONTACT if plant.in_contact else ctrl.phase(cons, plant, q),
            )  # fmt: skip
            if ctrl.measured:
                log.f_meas[i] = ctrl.f_meas  # type: ignore[index]
            n_logged = i + 1
            if not ok:
                _check_finite(t, q, v, f, sim)  # raises DivergenceError with the details
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
            events=_merge(ctrl.events, [*plant.events, {"t": t, "kind": failure.reason}]),
            steps_per_second=i / wall if wall > 0 else 0.0,
            wall_time=wall,
        )
        try:
            failure.result = _finish(log, n_logged, meta, k, robot, plant)
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
        per_tick: int,
        measured: bool,
    ) -> None:
        self.law, self.user, self.own = law, user, own
        self.per_tick, self.measured = per_tick, measured
        self.period = per_tick * sc.sim.dt
        self.sensors = Sensors(sc.sensor, self.period, sc.sim.seed) if measured else None
        self.f_meas = np.zeros(len(sc.surfaces))
        self.max_dist = sc.control.max_dist
        self.nv = sc.robot.nv
        self._held: Command | None = None

    @property
    def events(self) -> list[dict]:
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

    def phase(self, cons: ConstraintTerms | None, plant: Plant, q: np.ndarray) -> int:
        """The phase logged off the surface: the supervisor's (free or near), or for a user's
        controller near within ``control.max_dist`` [m]."""
        if self.law is not None:
            return min(self.law.phase, NEAR)
        distance = cons.distance if cons is not None else plant.distance(q)
        return NEAR if float(distance.max()) <= self.max_dist else FREE


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
        law = law_type(model_robot, constraint, sc.path, q, sc.control, dt=per_tick * sim.dt)
    return _ControlSide(sc, law, user, own, per_tick, measured)


def _meta(sc: Scenario, ctrl: _ControlSide, k: int, nq: int) -> dict:
    """The run's metadata known before it starts (the loop adds status, events, timing)."""
    sim, law = sc.sim, ctrl.law
    model_robot = sc.controller_model if sc.controller_model is not None else sc.robot
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
            "law": "arimoto" if law is not None else type(ctrl.user).__name__,
            "model": model_robot.reference,
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
        "versions": _versions(),
    }


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
    if isinstance(exc, DivergenceError):
        return DivergenceError(f"run '{name}' failed at t = {t:.6g} s: {exc}")
    if isinstance(exc, ReachError):
        failure = RunFailedError(f"{where}: the desired path cannot be followed: {exc}")
        failure.reason = "path"
        return failure
    if isinstance(exc, SingularConfigurationError | np.linalg.LinAlgError):
        return DivergenceError(f"run '{name}' failed at t = {t:.6g} s: {exc}")
    return RunFailedError(f"{where} by an unexpected error: {type(exc).__name__}: {exc}")


def _finish(log: Record, n: int, meta: dict, k: int, robot: Robot, plant: Plant) -> Result:
    """The Result of the first n samples, with what the run must say about itself in meta.

    Adds ``limits`` (joints beyond their range or effort limit, see
    :func:`~hybrid_force.sim.run_checks.limit_violations`), ``contact_at_end``, ``lost_contact``,
    ``left_at`` and ``warnings`` (one line each, also issued as Python warnings).
    """
    lower, upper = robot.position_limits
    limits = limit_violations(
        _joint_names(robot), lower, upper, robot.effort_limits,
        log.t[:n], log.q[:n], log.u[:n],
    )  # fmt: skip
    outcome = contact_outcome(plant.ever_in_contact, plant.in_contact, meta.get("events", []))
    notes = describe(limits, outcome)
    for note in notes:
        warnings.warn(f"run '{meta.get('name')}': {note}", RunWarning, stacklevel=3)
    meta.update(limits=limits, warnings=notes, **outcome)
    return log.result(n, meta, k)


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


def _merge(a: list[dict], b: list[dict]) -> list[dict]:
    events: list[dict] = _jsonable(a + b)  # type: ignore[assignment]  # a list stays a list
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

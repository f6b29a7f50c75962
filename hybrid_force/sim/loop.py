"""The closed loop: controller + constrained dynamics + contact events + integration.

:func:`simulate` runs a :class:`Scenario` (a plain Python description of one run, which the
TOML loader of :mod:`hybrid_force.scenario.loader` also produces) and returns a
:class:`~hybrid_force.result.Result`.

One step (dt, 1 ms by default):

1. the plant's terms at (q, v), once (:meth:`Robot.terms`), and the constraint terms;
2. the controller's command u = u0 + B f (the simulator does not know which law made it);
3. in contact, the constrained dynamics resolve q̈ and f together
   (:class:`~hybrid_force.sim.dynamics.ConstrainedDynamics`); if the surface would have to
   pull (f < 0) the contact is released (unilateral surface) and the step is free;
4. the sample is recorded (its phase is the plant's contact state: "contact" only on the
   surface); the controller advances its integrators with f; the plant is
   integrated by semi-implicit Euler with ``pinocchio.integrate`` (q + v dt directly for arms
   whose joints are all bounded revolute or prismatic), or RK4 with the command held over the
   step;
5. in contact, post-stabilisation: one Gauss–Newton step puts the tip back on the surface and
   the velocity is projected onto the tangent space (removes the O(dt²) drift that the
   Baumgarte terms alone would leave, so the distance stays at round-off);
6. out of contact, a crossing of the surface between two steps (d changing sign) is detected,
   the tip is placed on the surface at the crossing, and a plastic impact (A q̇⁺ = 0) is
   applied: the tool never passes through the surface.

After the loop (or when anything stops it: divergence, Ctrl-C, SIGTERM, an exception) the
run's samples become its Result, with what it must say about itself in ``meta``: joints that
left their range or exceeded an effort limit, whether the tool ended on the surface
(:mod:`hybrid_force.sim.run_checks`), ``status`` and ``reason``.

Two implementations of the step: the default calls compiled kernels between the Pinocchio
calls (:mod:`hybrid_force._kernels`); ``SimSettings(reference=True)`` runs the readable numpy
code they mirror (one public method per robot term, the general constraint algebra, the numpy
laws and CLIK, a dense KKT solve). The tests compare the two.
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

from hybrid_force._lazy import LazyKernels
from hybrid_force.control.constraint import _GRAD_TOL, Constraint, ConstraintTerms
from hybrid_force.control.controller import Controller, ControllerModel, check_same_joints
from hybrid_force.control.laws.arimoto import Command
from hybrid_force.control.supervisor import ControlSettings, HybridController
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
from hybrid_force.model.robot import reference_terms as _reference_terms
from hybrid_force.phases import CONTACT, FREE, NEAR
from hybrid_force.result import Result
from hybrid_force.sim.dynamics import (
    Baumgarte,
    ConstrainedDynamics,
    constrained_acceleration,
    free_acceleration,
    kkt_reference,
    plastic_impact,
)
from hybrid_force.sim.run_checks import (
    check_log_memory,
    contact_outcome,
    describe,
    limit_violations,
)
from hybrid_force.sim.sensors import Sensors, SensorSettings

_K = LazyKernels("hybrid_force.sim._kernels")

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


class _Log:
    """The run's samples, preallocated as one (N, width) table; one compiled call per row.

    The fields (t, q, v, q_d, u, p, p_d, f, f_d, phi, V, phase) are column views of the table,
    in that order (:func:`hybrid_force._kernels.record_row` writes a row in the same order).
    """

    @staticmethod
    def widths(nq: int, nv: int, k: int) -> tuple[int, ...]:
        """Columns of each field, in table order."""
        return (1, nq, nv, nq, nv, 3, 3, k, k, k, 1, 1)

    @classmethod
    def width(cls, nq: int, nv: int, k: int) -> int:
        """Float64 numbers per sample."""
        return sum(cls.widths(nq, nv, k))

    def __init__(
        self,
        N: int,
        nq: int,
        nv: int,
        k: int,
        max_velocity: float,
        max_force: float,
        *,
        measured: bool = False,
    ) -> None:
        self.max_velocity, self.max_force = max_velocity, max_force
        # the measured force (N, k), when it is not the plant's force (sampled sensing)
        self.f_meas: np.ndarray | None = np.zeros((N, k)) if measured else None
        widths = self.widths(nq, nv, k)
        self.table = np.zeros((N, sum(widths)))
        views = []
        start = 0
        for w in widths:
            views.append(self.table[:, start : start + w])
            start += w
        (t, self.q, self.v, self.q_d, self.u, self.p, self.p_d, self.f, self.f_d, self.phi, V,
         phase) = views  # fmt: skip
        self.t, self.V, self.phase = t[:, 0], V[:, 0], phase[:, 0]

    def record(
        self,
        i: int,
        t: float,
        q: np.ndarray,
        v: np.ndarray,
        q_d: np.ndarray,
        u0: np.ndarray,
        B: np.ndarray,
        f: np.ndarray,
        p: np.ndarray,
        p_d: np.ndarray,
        f_d: np.ndarray,
        phi: np.ndarray,
        V: float,
        phase: int,
    ) -> bool:
        """Write sample i, with the command u = u0 + B f (B: (n, k), zeros when u ignores f).

        Returns True when q, v, f are finite, |v_i| ≤ max_velocity and |f_m| ≤ max_force
        (otherwise :func:`_check_finite` says which and raises).
        """
        return _K.record_row(
            self.table, i, t, q, v, q_d, u0, B, f, p, p_d, f_d, phi, V, phase,
            self.max_velocity, self.max_force,
        )  # fmt: skip

    def result(self, n: int, meta: dict, k: int) -> Result:
        def own(a: np.ndarray) -> np.ndarray:
            return np.ascontiguousarray(a[:n])

        def col(a: np.ndarray) -> np.ndarray:
            return own(a[:, 0] if k == 1 else a)

        return Result(
            t=own(self.t),
            q=own(self.q),
            v=own(self.v),
            q_d=own(self.q_d),
            u=own(self.u),
            p=own(self.p),
            p_d=own(self.p_d),
            f=col(self.f),
            f_d=col(self.f_d),
            phi=col(self.phi),
            V=own(self.V),
            phase=self.phase[:n].astype(np.int64),
            meta=meta,
            f_meas=None if self.f_meas is None else col(self.f_meas),
        )


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


class _Plant:
    """Geometry helpers of the plant: distances, projection onto the surfaces."""

    def __init__(self, robot: Robot, constraint: Constraint) -> None:
        self.robot = robot
        self.constraint = constraint
        self.data = robot.new_data()
        n = robot.nv
        # two (q, v) pairs for contact_step: its output is never its input
        self._pairs = ((np.zeros(n), np.zeros(n)), (np.zeros(n), np.zeros(n)))
        self._tmp = (np.zeros(n), np.zeros(n))
        # a view of the tip translation in self.data (updated in place by updateFramePlacement)
        self._tip = self.data.oMf[robot.tip_id].translation
        self._grad = np.zeros(3)  # scratch ∇Φ of contact_step

    def tip(self, q: np.ndarray) -> np.ndarray:
        pin.forwardKinematics(self.robot.model, self.data, q)
        return pin.updateFramePlacement(self.robot.model, self.data, self.robot.tip_id).translation

    def distance(self, q: np.ndarray) -> np.ndarray:
        return self.constraint.distance(self.tip(q))

    def _rows(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows n̂ᵀJ (k, n) and first-order distances Φ / ‖∇Φ‖ (k,) at q."""
        model, data, fid = self.robot.model, self.data, self.robot.tip_id
        pin.computeJointJacobians(model, data, q)
        p = pin.updateFramePlacement(model, data, fid).translation
        return self.constraint.normal_rows(p, pin.getFrameJacobian(model, data, fid, _LWA)[:3])

    def project(self, q: np.ndarray, v: np.ndarray, iterations: int = 1) -> tuple:
        """Gauss–Newton steps putting the tip on the surfaces, then v onto the tangent space.

        The velocity is projected with the rows of the last iteration's start point (the
        difference is of the order of the position correction, ~1e-9 m here).
        """
        model = self.robot.model
        for _ in range(iterations):
            A, d = self._rows(q)
            gram = A @ A.T
            A_pinv = A.T / gram[0, 0] if A.shape[0] == 1 else A.T @ np.linalg.inv(gram)
            q = pin.integrate(model, q, -(A_pinv @ d))
        v = v - A_pinv @ (A @ v)
        return q, v

    def contact_step(
        self, q: np.ndarray, v: np.ndarray, ddq: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Semi-implicit Euler then :meth:`project`, for one surface and a Euclidean arm.

        The same arithmetic as ``v + ddq dt``, ``pin.integrate`` and :meth:`project` in two
        compiled calls (:func:`hybrid_force._kernels.euler_step`, ``project_one``). Returns
        arrays owned by the plant, never q or v themselves; the next call may reuse them.
        """
        K = _K
        model, data, fid = self.robot.model, self.data, self.robot.tip_id
        q_tmp, v_tmp = self._tmp
        K.euler_step(q, v, ddq, dt, v_tmp, q_tmp)
        pin.computeJointJacobians(model, data, q_tmp)
        pin.updateFramePlacement(model, data, fid)
        surface = self.constraint.surfaces[0]
        desc, grad, phi = surface._descriptor, self._grad, 0.0
        if desc.shape[0] == 0:  # no closed form: evaluate in Python
            phi, grad, _ = surface.evaluate(self._tip)
        q_out, v_out = self._pairs[0] if q is not self._pairs[0][0] else self._pairs[1]
        J6 = pin.getFrameJacobian(model, data, fid, _LWA)
        gn = K.project_one(desc, self._tip, grad, phi, J6, q_tmp, v_tmp, q_out, v_out)
        if not gn >= _GRAD_TOL:
            self._rows(q_tmp)  # raises the precise SingularConfigurationError
        return q_out, v_out


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
    # Scenario has checked its fields (stacked surfaces only without the supervisor, ...)
    constraint = Constraint(sc.surfaces, normalization=sim.normalization)
    model, data = robot.model, robot.new_data()
    k, nq, nv = constraint.k, robot.nq, robot.nv
    dt = sim.dt
    N = round(sim.duration / dt) + 1
    q = robot.check_q(sc.q0, "initial q").copy()
    v = np.zeros(nv) if sc.v0 is None else robot.check_v(sc.v0, "initial v").copy()
    plant = _Plant(robot, constraint)
    fast = not sim.reference
    # Ideal sensing at the plant's rate: the controller's command is affine in the force it
    # produces (u = u0 + B f) and the plant resolves that loop exactly (the paper's runs).
    # Otherwise it is sampled: every `per_tick` plant steps the controller reads its sensors,
    # computes its terms from its own model at the measured state, and its torque is held.
    per_tick = control_steps(sc.control, sim)
    if controller is not None and not callable(getattr(controller, "command", None)):
        raise ControlError(
            f"controller must have a method command(t, q, v, f) -> u, got {controller!r}"
        )
    sampled = controller is not None or per_tick > 1 or not sc.sensor.ideal
    period = per_tick * dt
    # the controller's own model: the plant's model file, or control.model (same joints)
    model_robot = sc.controller_model if sc.controller_model is not None else robot
    own = (
        ControllerModel(model_robot, sc.surfaces, sim.normalization, fast)
        if sampled or model_robot is not robot
        else None
    )
    law = (
        HybridController(
            model_robot,
            own.constraint if own is not None else constraint,
            sc.path,
            q,
            sc.control,
            dt=period,
            fast=fast,
        )
        if controller is None
        else None
    )
    sensors = Sensors(sc.sensor, period, sim.seed) if sampled else None
    task_f_d = sc.control.f_d_for(k)
    no_q_d = np.full(nq, np.nan)
    terms_buf = RobotTerms.zeros(nv)
    no_B = np.zeros((nv, k))
    solver = ConstrainedDynamics(model, data, k)
    clik = law.clik if law is not None else None
    unilateral, release_tol = sim.unilateral, sim.release_tol
    gamma_buf = np.zeros(k)
    cons_buf = ConstraintTerms.zeros(k, nv)
    # the compiled Euler + projection step of the plant (one surface, q ⊕ dq = q + dq)
    fast_contact = fast and k == 1 and robot.euclidean and sim.integrator == "euler"
    events: list[dict] = []
    in_contact = False
    if float(plant.distance(q).max()) <= sc.control.contact_tol:
        q, v, in_contact = _touch(plant, q, v, 0.0, events)
    started_in_contact = ever_in_contact = in_contact
    check_log_memory(N, _Log.width(nq, nv, k), sim.duration, dt)
    log = _Log(N, nq, nv, k, sim.max_velocity, sim.max_force, measured=sampled)
    f_meas_log = log.f_meas
    baum = sim.baumgarte
    zeros_k = np.zeros(k)
    f_last = zeros_k  # the plant's force at the last step: what the force sensor reads
    f_meas = zeros_k
    cmd: Command | None = None
    meta = {
        "name": sc.name,
        "run_id": uuid.uuid4().hex,
        "description": sc.description,
        "scenario": _jsonable(sc.source) if sc.source is not None else None,
        # what re-loads the arm from any folder: model (registry name or absolute path), tip,
        # package_dirs, xacro_args, lock_off_chain
        "robot": {**robot.reference, "nq": nq},
        "surfaces": [s.to_dict() for s in sc.surfaces],
        "path": _path_meta(sc.path),
        "controller": {
            "law": "arimoto" if law is not None else type(controller).__name__,
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
            "dt": dt,
            "duration": sim.duration,
            "integrator": sim.integrator,
            "settle_time": sim.settle_time,
            "baumgarte_alpha": baum.alpha,
            "baumgarte_beta": baum.beta,
            "unilateral": sim.unilateral,
            "normalization": sim.normalization,
            "control_rate": 1.0 / period,
            "seed": sim.seed,
        },
        "sensor": sc.sensor.to_dict(),
        "versions": _versions(),
    }

    def law_events() -> list[dict]:
        return law.events if law is not None else []

    report_every = max(1, N // 100)
    wall0 = wall1 = time.perf_counter()
    t = 0.0
    i = 0
    n_logged = 0  # rows of the log filled so far (kept in a failed run's partial result)
    try:
        for i in range(N):
            t = i * dt
            if fast:
                terms = robot.terms(q, v, data, out=terms_buf)
            else:
                terms = _reference_terms(robot, q, v)
            try:
                cons = constraint.evaluate(terms, v, fast=fast, out=cons_buf)
            except SingularConfigurationError:
                if in_contact:
                    raise
                cons = None
            if not sampled:  # the exact loop: u = u0 + B f, resolved with the plant below
                assert law is not None
                if own is None:
                    cmd = law.command(t, q, v, terms, cons)
                else:  # the controller's own model, at the exact state
                    cmd = law.command(t, q, v, *own.evaluate(q, v))
            elif i % per_tick == 0:  # a tick: sense, then control; the torque is held
                assert sensors is not None
                if law is not None and i:  # the law's integrators and CLIK over the period
                    law.update(period, f_meas)
                q_m, v_m, f_meas = sensors.measure(q, v, f_last)
                if law is None:
                    assert controller is not None
                    cmd = Command(_user_torque(controller, t, q_m, v_m, f_meas, nv), None)
                else:
                    assert own is not None
                    c = law.command(t, q_m, v_m, *own.evaluate(q_m, v_m))
                    cmd = Command(c.u0 + c.B @ f_meas if c.B is not None else c.u0.copy(), None)
            assert cmd is not None
            f = zeros_k
            if in_contact:
                assert cons is not None  # in contact, evaluate() raised instead of failing
                if fast:
                    gamma = baum.gamma_into(cons.drift, cons.rate, cons.phi, cons.scale, gamma_buf)
                else:
                    gamma = baum.gamma(cons.drift, cons.rate, cons.phi / cons.scale)
                if fast:
                    ddq, f = solver.solve(terms.nle, cmd.u0, cmd.B, cons.A, gamma)
                else:
                    ddq, f = kkt_reference(terms.M, terms.nle, cmd.u0, cmd.B, cons.A, gamma)
                if unilateral and float(f[0] if k == 1 else f.min()) < -release_tol:
                    events.append({"t": t, "kind": "release", "force": float(f.min())})
                    in_contact = False
                    f = zeros_k
                    ddq = free_acceleration(terms.M, terms.nle, cmd.u0)
            else:
                ddq = free_acceleration(terms.M, terms.nle, cmd.u0)
            # --- log sample i (with u = u0 + B f) and check the state
            ok = log.record(
                i,
                t,
                q,
                v,
                clik.q if clik is not None else no_q_d,
                cmd.u0,
                no_B if cmd.B is None else cmd.B,
                f,
                terms.p,
                # sampled: the desired point now, not the one of the last tick (held 1/rate s)
                clik.p_d if clik is not None and not sampled else sc.path.position(t),
                law.f_d if law is not None else task_f_d,
                cons.distance if cons is not None else plant.distance(q),
                law.V if law is not None else np.nan,
                # the real contact state: the supervisor's phase says which law runs, and a
                # tool off the surface is never logged as in contact
                CONTACT
                if in_contact
                else min(law.phase, NEAR)
                if law is not None
                else _free_phase(cons, plant, q, sc.control.max_dist),
            )
            if f_meas_log is not None:
                f_meas_log[i] = f_meas
            f_last = f
            n_logged = i + 1
            if not ok:
                _check_finite(t, q, v, f, sim)  # raises DivergenceError with the details
            if i == N - 1:
                break
            if i == 1:
                wall1 = time.perf_counter()  # steps 0 and 1 loaded (or compiled) the kernels
            if not sampled:
                assert law is not None
                law.update(dt, f)
            if in_contact and fast_contact:
                q, v = plant.contact_step(q, v, ddq, dt)
                if progress is not None and i % report_every == 0:
                    progress(i / N)
                continue
            if sim.integrator == "euler":
                v = v + ddq * dt
                q_new = pin.integrate(model, q, v * dt)
            else:
                q_new, v = _rk4(robot, data, constraint, baum, cmd, q, v, ddq, dt, in_contact)
            if in_contact:
                q, v = plant.project(q_new, v)
            else:
                d_new = float(plant.distance(q_new).max())
                if d_new < 0.0 or (
                    d_new <= sc.control.contact_tol and d_new <= float(log.phi[i].max())
                ):
                    # crossed the surface, or within the tolerance and still closing in
                    q_new = _crossing(model, q, q_new, float(log.phi[i].max()), d_new)
                    q_new, v, in_contact = _touch(plant, q_new, v, t + dt, events)
                    ever_in_contact = True
                q = q_new
            if progress is not None and i % report_every == 0:
                progress(i / N)
    except BaseException as exc:  # whatever stopped the run, keep what it computed
        wall = time.perf_counter() - wall0
        failure = _failure(exc, sc.name, t)
        meta.update(
            status="failed",
            reason=failure.reason,
            error=f"{type(exc).__name__}: {exc}",
            events=_merge(law_events(), [*events, {"t": t, "kind": failure.reason}]),
            steps_per_second=i / wall if wall > 0 else 0.0,
            wall_time=wall,
        )
        try:
            failure.result = _finish(log, n_logged, meta, k, robot, ever_in_contact, in_contact)
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
        events=_merge(law_events(), events),
        steps_per_second=steady,
        wall_time=wall,
    )
    if progress is not None:
        progress(1.0)
    result = _finish(log, N, meta, k, robot, ever_in_contact, in_contact)
    if started_in_contact and not sc.control.supervisor and result.meta["lost_contact"]:
        left = result.meta["left_at"]
        message = (
            f"run '{sc.name}' lost contact: it started on the surface without the supervisor "
            f"(control.supervisor = false), left it at t = {left:.6g} s and ended off it"
        )
        failed = result.with_meta(status="failed", reason="lost contact", error=message)
        raise LostContactError(message, result=failed)
    return result


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


def _free_phase(cons: ConstraintTerms | None, plant: _Plant, q: np.ndarray, max_dist: float) -> int:
    """Off the surface, for a run without the paper's supervisor: near within max_dist [m]."""
    distance = cons.distance if cons is not None else plant.distance(q)
    return NEAR if float(distance.max()) <= max_dist else FREE


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


def _finish(
    log: _Log,
    n: int,
    meta: dict,
    k: int,
    robot: Robot,
    ever_in_contact: bool,
    in_contact: bool,
) -> Result:
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
    outcome = contact_outcome(ever_in_contact, in_contact, meta.get("events", []))
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


def _crossing(model: pin.Model, q0: np.ndarray, q1: np.ndarray, d0: float, d1: float) -> np.ndarray:
    """Configuration where the distance crosses 0 between q0 (d0 > 0) and q1 (d1 ≤ 0), linearly."""
    if d1 >= 0 or d0 <= d1:
        return q1
    tau = d0 / (d0 - d1)
    return pin.interpolate(model, q0, q1, tau)


def _touch(plant: _Plant, q: np.ndarray, v: np.ndarray, t: float, events: list[dict]) -> tuple:
    """Place the tip on the surface and apply a plastic impact if it moves into it."""
    q, _ = plant.project(q, np.zeros_like(v), iterations=3)
    A, _ = plant._rows(q)
    speed = A @ v
    if float(speed.min()) < 0.0:
        data = plant.robot.new_data()
        v_after, impulse = plastic_impact(plant.robot.model, data, q, v, A)
        events.append(
            {
                "t": t,
                "kind": "impact",
                "impulse": float(np.abs(impulse).sum()),
                "speed": float(-speed.min()),
            }
        )
        v = v_after
    return q, v, True


def _rk4(
    robot: Robot,
    data: pin.Data,
    constraint: Constraint,
    baum: Baumgarte,
    cmd: Command,
    q: np.ndarray,
    v: np.ndarray,
    a1: np.ndarray,
    dt: float,
    in_contact: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """One RK4 step of the plant with the command (u0, B) held over the step.

    a1: (n,) the acceleration already solved at (q, v); the stages reuse ``data``.
    Returns (q, v) at t + dt.
    """
    model = robot.model

    def acc(qs: np.ndarray, vs: np.ndarray) -> np.ndarray:
        terms = robot.terms(qs, vs, data)
        if not in_contact:
            return free_acceleration(terms.M, terms.nle, cmd.u0)
        cons = constraint.evaluate(terms, vs)
        gamma = baum.gamma(cons.drift, cons.rate, cons.phi / cons.scale)
        ddq, _ = constrained_acceleration(model, data, terms.nle, cmd.u0, cmd.B, cons.A, gamma)
        return ddq

    k1v, k1a = v, a1
    q2 = pin.integrate(model, q, k1v * (dt / 2))
    k2v = v + k1a * (dt / 2)
    k2a = acc(q2, k2v)
    q3 = pin.integrate(model, q, k2v * (dt / 2))
    k3v = v + k2a * (dt / 2)
    k3a = acc(q3, k3v)
    q4 = pin.integrate(model, q, k3v * dt)
    k4v = v + k3a * dt
    k4a = acc(q4, k4v)
    q_new = pin.integrate(model, q, (k1v + 2 * k2v + 2 * k3v + k4v) * (dt / 6))
    v_new = v + (k1a + 2 * k2a + 2 * k3a + k4a) * (dt / 6)
    return q_new, v_new

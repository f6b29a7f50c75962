"""What a run is: its simulation settings and its description (arm, surfaces, path, start,
controller and sensor settings), each checked when it is built."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from hybrid_force import _checks as checks
from hybrid_force.control.constraint import Constraint, dependent_rows
from hybrid_force.control.controller import check_same_joints
from hybrid_force.control.laws.arimoto import check_damping_gain
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.control.tool import ToolSettings
from hybrid_force.errors import ScenarioError
from hybrid_force.errors import ScenarioError as Bad
from hybrid_force.geometry.on_surface import ON_SURFACE_TOL, check_on_surface
from hybrid_force.geometry.paths import Path
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.metrics import DEFAULT_SETTLE_TIME
from hybrid_force.model.robot import Robot
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.dynamics import Baumgarte
from hybrid_force.sim.sensors import SensorSettings

__all__ = ["Integrator", "Scenario", "SimSettings", "control_steps"]

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
        torque_limits: saturate the applied torque at the model's effort limits, where it
            declares them (:attr:`Robot.effort_limits <hybrid_force.Robot.effort_limits>`);
            False: apply the command as is (a demand beyond a limit is still reported).
        joint_limits: "report" (a joint beyond its position or velocity limit is an event and
            a warning) or "stop" (the run stops there, failed with reason "joint limit").
        joint_friction_velocity: regularisation velocity ε [rad/s or m/s] > 0 of the joints'
            Coulomb friction (the model's ``friction``, URDF ``<dynamics friction>``):
            τ = −τ_c q̇/√(q̇² + ε²), the tip friction's law
            (:func:`~hybrid_force.sim.contact.joint_dissipation`).
    """

    duration: float = 20.0
    dt: float = 1e-3
    integrator: Integrator = "euler"
    baumgarte: Baumgarte = field(default_factory=Baumgarte)
    unilateral: bool = True
    release_tol: float = 1e-9
    max_velocity: float = 1e3
    max_force: float = 1e7
    settle_time: float = DEFAULT_SETTLE_TIME
    normalization: Literal["tip", "joint"] = "tip"
    reference: bool = False
    seed: int = 0
    torque_limits: bool = True
    joint_limits: Literal["report", "stop"] = "report"
    joint_friction_velocity: float = 1e-3

    def __post_init__(self) -> None:
        """Check every field; numbers are stored as floats, flags as bools.

        Raises ScenarioError (a BadInputError) naming the field as the scenario file's
        ``[sim]`` key spells it (``sim.dt``) with the value and what is valid.
        """

        for name, strict, unit in (
            ("duration", True, "s"),
            ("dt", True, "s"),
            ("release_tol", True, "N"),
            ("max_velocity", True, "rad/s or m/s"),
            ("max_force", True, "N"),
            ("settle_time", False, "s"),
            ("joint_friction_velocity", True, "rad/s or m/s"),
        ):
            what = f"sim.{name}"
            value = getattr(self, name)
            value = checks.number(value, what, ScenarioError, minimum=0, strict=strict, unit=unit)
            object.__setattr__(self, name, value)
        if self.dt > self.duration:
            raise ScenarioError(
                f"sim.dt = {self.dt} s is larger than sim.duration = {self.duration} s"
            )
        if self.duration / self.dt > 5e7:
            raise ScenarioError(
                f"sim.duration / sim.dt = {self.duration / self.dt:.3g} steps is absurd (max 5e7)"
            )
        for name, choices in (
            ("integrator", ("euler", "rk4")),
            ("normalization", ("tip", "joint")),
            ("joint_limits", ("report", "stop")),
        ):
            checks.one_of(getattr(self, name), f"sim.{name}", ScenarioError, choices)
        for name in ("unilateral", "reference", "torque_limits"):
            value = checks.flag(getattr(self, name), f"sim.{name}", ScenarioError)
            object.__setattr__(self, name, value)
        seed = checks.integer(self.seed, "sim.seed", ScenarioError, minimum=0)
        object.__setattr__(self, "seed", seed)
        if not isinstance(self.baumgarte, Baumgarte):
            raise ScenarioError(
                "sim.baumgarte (SimSettings.baumgarte) must be a "
                "hybrid_force.sim.dynamics.Baumgarte, e.g. "
                f" Baumgarte(alpha=50.0, beta=50.0), got {checks.shown(self.baumgarte)}"
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
        contact: how the surface pushes back (the ``[contact]`` table): rigid (default) or
            compliant, with or without friction
            (:class:`~hybrid_force.sim.contact.ContactSettings`).
        controller_model: the controller's own model of the arm (``control.model``): another
            :class:`~hybrid_force.model.robot.Robot` with the plant's joints (a heavier link, say);
            None: the plant's own model. ``control.mass_factor`` applies on top of it.
        tool: which way the tool points (the ``[tool]`` table,
            :class:`~hybrid_force.control.tool.ToolSettings`; default: free, the paper's
            position-only CLIK). An arm with fewer joints than the tool task has rows is refused
            (ControlError naming ``tool.orientation`` or ``tool.roll``).
        name: a short name (used for output folders): letters, digits, '_', '-', '.', not
            starting with '.' or '-', at most ``NAME_MAX_LENGTH`` = 100 characters (the
            scenario file's rule, ``NAME_PATTERN``, matched in full). description: free text.
        source: the scenario as loaded from a file (JSON-able dict), stored in the result.

    Checked on construction, like a scenario file by its loader (ScenarioError, or the
    ControlError of a K_d or f_d that does not fit the arm or the surfaces, naming the field):

    * the types and shapes above, finite q0 and v0, every |v0_i| below ``sim.max_velocity``
      (the run would stop as a runaway at once); K_d's size against the arm's joints and
      f_d's count against the surfaces;
    * a run that starts in contact (``control.supervisor`` False): the desired path within
      ``ON_SURFACE_TOL`` (1e-6 m) of every surface over [0, sim.duration] (sampled by
      :func:`~hybrid_force.geometry.on_surface.check_on_surface`) and the start tip p(q0) within
      ``control.contact_tol`` of every surface;
    * with the supervisor: a start inside the solid (distance < −contact_tol) is refused, and
      so are stacked surfaces (k > 1), whose approach would touch a subset first; without it,
      stacked surfaces whose constraint rows n̂ᵀJ are dependent at q0 (two parallel planes);
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
    contact: ContactSettings = field(default_factory=ContactSettings)
    tool: ToolSettings = field(default_factory=ToolSettings)

    def __post_init__(self) -> None:
        """Validate the fields (see the class docstring); q0, v0, surfaces are stored anew."""

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
                f"hybrid_force.geometry.surface_base.Surface, got {checks.shown(surfaces)}"
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
            if key == "v0" and isinstance(self.sim, SimSettings) and array.size:
                fastest = float(np.abs(array).max())
                if fastest > self.sim.max_velocity:  # the first step would be a runaway
                    raise Bad(
                        f"Scenario.v0: |v| = {fastest:.6g} is beyond sim.max_velocity = "
                        f"{self.sim.max_velocity:g} rad/s or m/s, where a run stops as a runaway"
                    )
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
        self._check_contact()
        if self.controller_model is not None:
            if not isinstance(self.controller_model, Robot):
                raise Bad(
                    "Scenario.controller_model must be None or a hybrid_force.model.robot.Robot, "
                    f"got {checks.shown(self.controller_model)}"
                )
            check_same_joints(robot, self.controller_model)
        if not isinstance(self.tool, ToolSettings):
            raise Bad(
                "Scenario.tool must be a hybrid_force.control.tool.ToolSettings, "
                f"got {checks.shown(self.tool)}"
            )
        self.tool.check_arm(robot)
        self._check_start_and_path()

    def _check_contact(self) -> None:
        """The contact settings against the simulation's: a compliant or frictional contact
        needs the explicit Euler step (its forces are evaluated once per step) and forces in
        newtons (``sim.normalization = "tip"``)."""

        contact = self.contact
        if not isinstance(contact, ContactSettings):
            raise ScenarioError(
                "Scenario.contact must be a hybrid_force.sim.contact.ContactSettings, "
                f"got {checks.shown(contact)}"
            )
        self._check_contact_settings(contact, self.sim)

    @staticmethod
    def _check_contact_settings(contact: ContactSettings, sim: SimSettings) -> None:
        """Raise ScenarioError (key: the ``[sim]`` key) where they do not fit."""

        if contact.ideal:
            return
        what = f'contact.model = "{contact.model}", contact.friction = {contact.friction:g}'
        if sim.integrator != "euler":
            raise ScenarioError(
                f'{what} needs sim.integrator = "euler" (the contact forces are evaluated once '
                f'per step), got "{sim.integrator}"',
                key="sim.integrator",
                value=sim.integrator,
            )
        if sim.normalization != "tip":
            raise ScenarioError(
                f'{what} needs sim.normalization = "tip" (forces in newtons), '
                f'got "{sim.normalization}"',
                key="sim.normalization",
                value=sim.normalization,
            )

    def _check_start_and_path(self) -> None:
        """The contact conditions of the start (class docstring), as the scenario loader's."""

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
        if k > 1:  # dependent rows: A M⁻¹ Aᵀ singular, the first step would fail in numpy
            rows, _ = Constraint(list(surfaces)).normal_rows(p, self.robot.jacobian(self.q0))
            found = dependent_rows(rows)
            if found is not None:
                names = ", ".join(f"surfaces[{i}]" for i in found[0])
                raise Bad(
                    f"Scenario.surfaces: the constraint rows n̂ᵀJ of {names} are linearly "
                    f"dependent at q0 (singular values "
                    f"{', '.join(f'{x:.3g}' for x in found[1])}): their contact forces are not "
                    "determined"
                )


def control_steps(control: ControlSettings, sim: SimSettings) -> int:
    """Plant steps per control tick: 1/(rate·dt), which must be a whole number ≥ 1.

    Raises:
        ScenarioError: naming control.rate and sim.dt, with the nearest rates that fit.
    """
    if control.rate is None:
        return 1
    steps = _whole_steps(control.rate, sim.dt)
    if steps is None:
        ratio = _ratio(control.rate, sim.dt)
        if ratio > 1e15:  # a rate so low that no nearby whole number is a different float
            raise ScenarioError(
                f"control.rate = {control.rate:g} Hz is not a whole number of plant steps of "
                f"sim.dt = {sim.dt:g} s: 1 / (rate · dt) = {ratio:.6g} is far beyond any run"
            )
        fits = sorted({1.0 / (n * sim.dt) for n in (max(int(ratio), 1), int(ratio) + 1)})
        # printed so that the text copied into control.rate is accepted (1000/3 Hz: 333.3333...)
        shown = [checks.suggested(r, lambda x: _whole_steps(x, sim.dt) is not None) for r in fits]
        raise ScenarioError(
            f"control.rate = {control.rate:g} Hz is not a whole number of plant steps of "
            f"sim.dt = {sim.dt:g} s (1 / (rate · dt) = {ratio:.6g}); the controller ticks every "
            f"n plant steps: rates that fit nearby: {', '.join(f'{r} Hz' for r in shown)}"
            + ("; it cannot be faster than the plant" if ratio < 1 else "")
        )
    return steps


def _ratio(rate: float, dt: float) -> float:
    """1/(rate·dt), inf where the product underflows or the quotient overflows."""
    product = rate * dt
    return 1.0 / product if product > 1e-300 else math.inf


def _whole_steps(rate: float, dt: float) -> int | None:
    """1/(rate·dt) as a whole number ≥ 1 of plant steps (to 1e-9 relative), or None."""
    ratio = _ratio(rate, dt)
    if not ratio <= 1e15:
        return None
    steps = round(ratio)
    return None if steps < 1 or abs(ratio - steps) > 1e-9 * ratio else steps

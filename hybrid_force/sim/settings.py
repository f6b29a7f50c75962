"""What a run is: its simulation settings and its description (arm, surfaces, path, start,
controller and sensor settings), each checked when it is built."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import ClassVar, Literal

import numpy as np

from hybrid_force import _checks as checks
from hybrid_force.control.constraint import Constraint, dependent_rows
from hybrid_force.control.laws.arimoto import check_damping_gain
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.control.tool import ToolSettings
from hybrid_force.errors import ControlError, ScenarioError
from hybrid_force.geometry.offset import tool_surfaces as offset_surfaces
from hybrid_force.geometry.on_surface import (
    check_path_on_surfaces,
    path_samples,
    warn_untrusted_path,
)
from hybrid_force.geometry.paths import Path
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.metrics import DEFAULT_SETTLE_TIME
from hybrid_force.model.robot import Robot, check_same_joints
from hybrid_force.schema import check_fields, param
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.dynamics import Baumgarte
from hybrid_force.sim.removal import RemovalSettings
from hybrid_force.sim.removal_run import check_removal
from hybrid_force.sim.sensors import SensorSettings

__all__ = ["Integrator", "Scenario", "SimSettings", "control_steps"]

Integrator = Literal["euler", "rk4"]


@dataclass(frozen=True)
class SimSettings:
    """Settings of the simulation (``[sim]``): each field's unit, range and meaning its param."""

    duration: float = param(20.0, unit="s", minimum=0.0, strict=True, doc="simulated time")
    dt: float = param(1e-3, unit="s", minimum=0.0, strict=True, doc="time step")
    integrator: Integrator = param(
        "euler", doc="euler (semi-implicit) or rk4 (command held over the step)"
    )
    baumgarte: Baumgarte = param(
        default_factory=Baumgarte, acts_when=("contact.model", "rigid"), doc="stabilisation gains"
    )
    unilateral: bool = param(
        True,
        acts_when=("contact.model", "rigid"),
        doc="release the contact where the surface would pull",
    )
    release_tol: float = param(
        1e-9, unit="N", minimum=0.0, strict=True, toml=False, doc="f below −release_tol releases"
    )
    max_velocity: float = param(
        1e3, unit="rad/s or m/s", minimum=0.0, strict=True, toml=False, doc="runaway speed"
    )
    max_force: float = param(
        1e7, unit="N", minimum=0.0, strict=True, toml=False, doc="runaway force"
    )
    settle_time: float = param(
        DEFAULT_SETTLE_TIME, unit="s", minimum=0.0, doc="metrics after settling start here"
    )
    normalization: Literal["tip", "joint"] = param(
        "tip", doc="constraint row scaling: tip (f in N) or joint (the paper's J_Φn)"
    )
    seed: int = param(0, minimum=0, doc="seed of the sensors' noise")
    torque_limits: bool = param(True, doc="saturate the torque at the model's effort limits")
    joint_limits: Literal["report", "stop"] = param(
        "report", doc="a joint beyond its limits: report (an event) or stop the run"
    )
    joint_friction_velocity: float = param(
        1e-3, unit="rad/s or m/s", minimum=0.0, strict=True,
        doc="regularisation velocity of the joints' Coulomb friction",
    )  # fmt: skip

    def __post_init__(self) -> None:
        """Check every field (numbers stored as floats), naming its key (``sim.dt``)."""
        check_fields(self, ScenarioError, "sim.")
        if self.dt > self.duration:
            raise ScenarioError(
                f"sim.dt = {self.dt} s is larger than sim.duration = {self.duration} s"
            )
        if self.duration / self.dt > 5e7:
            raise ScenarioError(
                f"sim.duration / sim.dt = {self.duration / self.dt:.3g} steps is absurd (max 5e7)"
            )
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
        robot: the plant. surfaces: a non-empty sequence of Surface touched by the tip (stored
            as a tuple); with ``tool.radius`` > 0 the part's, whose offsets
            (:attr:`tool_surfaces`) the plant, the controller and the path follow.
        path: desired task-space path (on the surface). q0: (nq,) start configuration [rad or
            m]; v0: None (0) or (nv,) start velocity; both stored as new read-only arrays.
        control, sim, sensor, contact, tool: the settings of their tables (defaults: ideal
            sensing, rigid frictionless contact, a free tool). removal: None or ``[removal]``,
            with ``tool.pad`` and only with it. controller_model: None (the plant's) or the
            controller's own model of the arm, with the plant's joints (``control.model``).
        name: the output folder runs/<name>/ (``NAME_PATTERN``, ``NAME_MAX_LENGTH``);
            description: free text; source: the scenario file's data (JSON-able), if any.

    Checked on construction, the one check for a file's run and one built by hand
    (ScenarioError, or ControlError naming the field): the types and shapes above, finite
    q0 and v0 with |v0| ≤ ``sim.max_velocity``, K_d, f_d and the tool task against the arm
    and the surfaces; a run that starts in contact (no supervisor): the path within
    ``ON_SURFACE_TOL`` of every surface over [0, sim.duration], the start tip within
    ``control.contact_tol`` of each, stacked surfaces with independent rows n̂ᵀJ at q0; with
    the supervisor: one surface, the start not inside the solid; a compliant or frictional
    contact with the Euler step and forces in newtons; ``control.rate`` a whole number of
    plant steps.
    """

    NAME_PATTERN = r"[A-Za-z0-9_][A-Za-z0-9_.\-]*"
    NAME_MAX_LENGTH = 100
    _TYPES: ClassVar = (
        ("robot", Robot, "a hybrid_force.model.robot.Robot (e.g. load_robot('rtr'))"),
        ("path", Path, "a hybrid_force.Path (Helix, Circle, FunctionPath)"),
        ("control", ControlSettings, "a ControlSettings"),
        ("sim", SimSettings, "a SimSettings"),
        ("sensor", SensorSettings, "a hybrid_force.sim.sensors.SensorSettings"),
        ("contact", ContactSettings, "a hybrid_force.sim.contact.ContactSettings"),
        ("controller_model", (Robot, type(None)), "None or a hybrid_force.model.robot.Robot"),
        ("tool", ToolSettings, "a hybrid_force.control.tool.ToolSettings"),
        ("description", str, "a str"),
        ("source", (Mapping, type(None)), "None or the scenario file's data (a dict)"),
    )  # the type of each field (the first check: the others read them)

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
    removal: RemovalSettings | None = None

    def __post_init__(self) -> None:
        """Validate the fields (see the class docstring); q0, v0, surfaces are stored anew."""
        for key, kind, what in self._TYPES:
            if not isinstance(value := getattr(self, key), kind):
                raise ScenarioError(f"Scenario.{key} must be {what}, got {checks.shown(value)}")
        robot, surfaces, control = self.robot, self.surfaces, self.control
        if isinstance(surfaces, Surface):
            raise ScenarioError(
                f"Scenario.surfaces must be a sequence of surfaces: wrap it, [{surfaces!r}]"
            )
        if not isinstance(surfaces, Sequence) or isinstance(surfaces, str | bytes) or not surfaces:
            raise ScenarioError(
                "Scenario.surfaces must be a non-empty sequence (list, tuple) of "
                f"hybrid_force.geometry.surface_base.Surface, got {checks.shown(surfaces)}"
            )
        for i, surface in enumerate(surfaces):
            if not isinstance(surface, Surface):
                raise ScenarioError(
                    f"Scenario.surfaces[{i}] must be a hybrid_force.Surface (Cylinder, "
                    f"Sphere, Plane, FunctionSurface), got {checks.shown(surface)}"
                )
        object.__setattr__(self, "surfaces", tuple(surfaces))
        # the offsets the tool centre follows exist (else SurfaceError naming tool.radius)
        offset_surfaces(self.surfaces, self.tool.radius, warn=False)
        for key, size in (("q0", robot.nq), ("v0", robot.nv)):
            if getattr(self, key) is None and key == "v0":
                continue
            valid = f"{size} finite real numbers (robot '{robot.name}' has {size})"
            array = checks.array(getattr(self, key), f"Scenario.{key}", ScenarioError, valid=valid)
            if array.shape != (size,):
                raise ScenarioError(f"Scenario.{key} must be {valid}, got shape {array.shape}")
            fastest = float(np.abs(array).max()) if key == "v0" and array.size else 0.0
            if fastest > self.sim.max_velocity:  # the first step would be a runaway
                raise ScenarioError(
                    f"Scenario.v0: |v| = {fastest:.6g} is beyond sim.max_velocity = "
                    f"{self.sim.max_velocity:g} rad/s or m/s, where a run stops as a runaway",
                    key="Scenario.v0",
                    value=fastest,
                )
            array.setflags(write=False)
            object.__setattr__(self, key, array)
        name = self.name
        if not isinstance(name, str) or not (
            re.fullmatch(self.NAME_PATTERN, name) and len(name) <= self.NAME_MAX_LENGTH
        ):
            raise ScenarioError(
                f"Scenario.name must be a simple name of 1 to {self.NAME_MAX_LENGTH} letters, "
                "digits, '_', '-', '.' (not starting with '.' or '-'): it names the output folder "
                f"runs/<name>/; got {checks.shown(name)}",
                key="name",
                value=name,
            )
        for key, check in (
            ("Kd", lambda: control.Kd is None or check_damping_gain(control.Kd, robot.nv)),
            ("f_d", lambda: control.f_d_for(len(surfaces))),
        ):  # the settings against the arm and the surfaces, named by their [control] keys
            try:
                check()
            except ControlError as exc:
                value = getattr(control, key)
                raise ControlError(str(exc), key=f"control.{key}", value=value) from None
        self._check_contact()
        control_steps(control, self.sim)
        if self.controller_model is not None:
            check_same_joints(robot, self.controller_model)
        self.tool.check_arm(robot)
        check_removal(self)  # with tool.pad, each only with the other; a grid it can lay
        self._check_start_and_path()
        # warnings: a hollow tighter than the ball (with the path's nearest approach to it);
        # a path near a mesh part's open edge, where Φ is not the part's
        # (sampled only for a ball or an open part: a command's fixed cost)
        if self.tool.radius > 0.0 or any(getattr(s, "untrusted_width", 0) for s in self.surfaces):
            along = path_samples(self.path, self.sim.duration)
            offset_surfaces(self.surfaces, self.tool.radius, along=along)
            warn_untrusted_path(along, self.surfaces, self.tool.radius)

    @property
    def tool_surfaces(self) -> tuple[Surface, ...]:
        """The surfaces the tool centre follows (plant, controller): ``surfaces`` offset by
        ``tool.radius``; a property so that ``Scenario(**other.__dict__)`` still copies."""
        return offset_surfaces(self.surfaces, self.tool.radius, warn=False)

    def _check_contact(self) -> None:
        """A compliant or frictional contact needs the Euler step and forces in newtons."""
        contact, sim = self.contact, self.sim
        what = f'contact.model = "{contact.model}", contact.friction = {contact.friction:g}'
        once = "the contact forces are evaluated once per step"
        for key, value, needed, why in (
            ("integrator", sim.integrator, "euler", once),
            ("normalization", sim.normalization, "tip", "forces in newtons"),
        ):
            if not contact.ideal and value != needed:
                raise ScenarioError(
                    f'{what} needs sim.{key} = "{needed}" ({why}), got "{value}"',
                    key=f"sim.{key}",
                    value=value,
                )

    def _check_start_and_path(self) -> None:
        """The start and the path (class docstring); ``value`` for the loader: (surface
        index, OnSurfaceReport or None), (surface index, distance [m]) or the row indices."""
        control, surfaces = self.control, self.tool_surfaces
        k = len(surfaces)
        if k > 1 and control.supervisor:
            raise ScenarioError(
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
                raise ScenarioError(
                    f"Scenario.q0: {tip} is {-distances[i]:.3g} m behind surfaces[{i}] "
                    f"({surfaces[i]!r}), inside the solid; start on the free side (distance "
                    f">= -control.contact_tol = {-control.contact_tol:g} m)",
                    key="Scenario.q0",
                    value=(i, distances[i]),
                )
            return
        check_path_on_surfaces(self.path, surfaces, self.sim.duration)
        i = int(np.argmax(np.abs(distances)))
        if abs(distances[i]) > control.contact_tol:
            raise ScenarioError(
                f"Scenario.q0: the run starts in contact (control.supervisor = False) but "
                f"{tip} is {distances[i]:.3g} m from surfaces[{i}] ({surfaces[i]!r}); it must be "
                f"within control.contact_tol = {control.contact_tol:g} m of every surface",
                key="Scenario.q0",
                value=(i, distances[i]),
            )
        if k > 1:  # dependent rows: A M⁻¹ Aᵀ singular, the first step would fail in numpy
            rows, _ = Constraint(list(surfaces)).normal_rows(p, self.robot.jacobian(self.q0))
            found = dependent_rows(rows)
            if found is not None:
                names = ", ".join(f"surfaces[{i}]" for i in found[0])
                raise ScenarioError(
                    f"Scenario.surfaces: the constraint rows n̂ᵀJ of {names} are linearly "
                    f"dependent at q0 (singular values "
                    f"{', '.join(f'{x:.3g}' for x in found[1])}; {k} rows for "
                    f"{self.robot.nv} joints): their contact forces are not determined; stack "
                    "surfaces whose normals, seen through the arm's Jacobian, are independent",
                    key="Scenario.surfaces",
                    value=tuple(found[0]),
                )


def control_steps(control: ControlSettings, sim: SimSettings) -> int:
    """Plant steps per control tick: 1/(rate·dt), which must be a whole number ≥ 1
    (ScenarioError, key ``"control.rate"``, naming sim.dt and the nearest rates that fit)."""
    if control.rate is None:
        return 1
    steps = _whole_steps(control.rate, sim.dt)
    if steps is None:
        ratio = _ratio(control.rate, sim.dt)
        if ratio > 1e15:  # a rate so low that no nearby whole number is a different float
            raise ScenarioError(
                f"control.rate = {control.rate:g} Hz is not a whole number of plant steps of "
                f"sim.dt = {sim.dt:g} s: 1 / (rate · dt) = {ratio:.6g} is far beyond any run",
                key="control.rate",
                value=control.rate,
            )
        fits = sorted({1.0 / (n * sim.dt) for n in (max(int(ratio), 1), int(ratio) + 1)})
        # printed so that the text copied into control.rate is accepted (1000/3 Hz: 333.3333...)
        shown = [checks.suggested(r, lambda x: _whole_steps(x, sim.dt) is not None) for r in fits]
        raise ScenarioError(
            f"control.rate = {control.rate:g} Hz is not a whole number of plant steps of "
            f"sim.dt = {sim.dt:g} s (1 / (rate · dt) = {ratio:.6g}); the controller ticks every "
            f"n plant steps: rates that fit nearby: {', '.join(f'{r} Hz' for r in shown)}"
            + ("; it cannot be faster than the plant" if ratio < 1 else ""),
            key="control.rate",
            value=control.rate,
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

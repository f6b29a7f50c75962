"""The controller as the loop sees it: its command at each plant step, its integrators, its log.

:func:`build_control_side` builds the run's controller from a
:class:`~hybrid_force.sim.settings.Scenario`: the scenario's law on its own model of the arm,
or a user's :class:`~hybrid_force.control.controller.Controller`. A :class:`ControlSide` hands
:func:`~hybrid_force.sim.loop.simulate` the command of each step: :class:`ExactControl`
(u = u0 + B f, the plant resolves the loop) or :class:`SampledControl` (sensors, the control
rate, the torque held); :class:`ToolLog` measures the tool axis' angle from its desired
direction for runs with a ``[tool]`` table.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.controller import Controller, ControllerModel
from hybrid_force.control.laws.base import Command
from hybrid_force.control.pose_clik import PoseJointPath
from hybrid_force.control.supervisor import HybridController
from hybrid_force.control.tool import ToolAngleProbe, ToolTarget
from hybrid_force.errors import ControlError
from hybrid_force.events import Event
from hybrid_force.model.robot import Robot, RobotTerms
from hybrid_force.phases import FREE, NEAR
from hybrid_force.sim.sensors import Sensors
from hybrid_force.sim.settings import Scenario, control_steps

__all__ = ["ControlSide", "ExactControl", "SampledControl", "ToolLog", "build_control_side"]


class ControlSide:
    """The controller as the loop sees it: a command per step, its integrators, its logs
    (:class:`ExactControl` or :class:`SampledControl`, chosen once by
    :func:`build_control_side`).

    Attributes:
        law: the scenario's law in its supervisor, or None (a user's controller).
        user: the user's controller, or None.
        model_robot: the controller's model of the arm.
        period: the control period [s]. measured: the controller reads sensors (sampled).
        f_meas: (k,) the force the controller read last [N] (0 when exact).
    """

    measured = False

    def __init__(
        self,
        sc: Scenario,
        law: HybridController | None,
        user: Controller | None,
        own: ControllerModel | None,
        model_robot: Robot,
        period: float,
    ) -> None:
        self.law, self.user, self.own = law, user, own
        self.model_robot = model_robot
        self.period = period
        self.f_meas = np.zeros(len(sc.tool_surfaces))
        self.max_dist = sc.control.max_dist
        #: update(dt, f): the integrators over one plant step of dt [s] with the force f (k,)
        #: [N]; exact: the supervisor's own method (one Python call per step, not two);
        #: sampled: nothing, a sampled controller advances its own at its ticks
        self.update: Callable[[float, np.ndarray], None] = (
            law.update if law is not None and not self.measured else _no_update
        )
        #: the supervisor's own command(t, q, v, terms, cons) when :meth:`command` would only
        #: pass the plant's terms on to it (exact, on the plant's own model: one Python call
        #: per step, not two), else None
        self.law_command: Callable[..., Command] | None = (
            law.command if law is not None and not self.measured and own is None else None
        )

    @property
    def events(self) -> list[Event]:
        """The supervisor's events (none for a user's controller)."""
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
        """The command at plant step i (time t [s]) at the plant's state (q, v) with its terms
        and rows there; f (k,) [N] is the plant's last force.

        Exact (:class:`ExactControl`): the law evaluates its model at the plant's state; when
        that model is the plant's own model file (``own`` None), the plant's terms at that
        state are the same numbers and are passed instead of being computed twice. Sampled:
        :meth:`_tick`'s held torque."""
        if self.measured:
            return self._tick(i, t, q, v, f)
        assert self.law is not None
        if self.own is None:
            return self.law.command(t, q, v, terms, cons)
        return self.law.command(t, q, v, *self.own.evaluate(q, v))

    def _tick(self, i: int, t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray) -> Command:
        """A measured controller's command at plant step i (:class:`SampledControl`)."""
        raise NotImplementedError

    def phase(self, distance: np.ndarray) -> int:
        """The phase logged off the surface: the supervisor's (free or near), or for a user's
        controller near when the tip's distances (k,) [m] are within ``control.max_dist``."""
        if self.law is not None:
            return min(self.law.phase, NEAR)
        return NEAR if float(distance.max()) <= self.max_dist else FREE


class ExactControl(ControlSide):
    """Ideal sensing at the plant's rate: the law's command is affine in the force the plant
    will produce (u = u0 + B f) and the plant resolves that loop exactly (the paper's runs;
    :meth:`ControlSide.command`); its ``update`` is the supervisor's integrators' (eq. 3, the
    law's own states, the CLIK)."""

    law: HybridController


class SampledControl(ControlSide):
    """A control rate below the plant's, sensors that are not ideal, or a user's controller:
    every ``per_tick`` plant steps the controller reads its sensors, computes its terms from
    its own model at the measured state, and its torque is held (zero-order hold)."""

    measured = True
    own: ControllerModel

    def __init__(
        self,
        sc: Scenario,
        law: HybridController | None,
        user: Controller | None,
        own: ControllerModel,
        model_robot: Robot,
        per_tick: int,
    ) -> None:
        super().__init__(sc, law, user, own, model_robot, per_tick * sc.sim.dt)
        self.per_tick = per_tick
        self.sensors = Sensors(sc.sensor, self.period, sc.sim.seed)
        self.nv = sc.robot.nv
        self._held: Command | None = None

    def _tick(self, i: int, t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray) -> Command:
        if i % self.per_tick == 0:  # a tick: sense, then control; the torque is held
            law = self.law
            if law is not None and i:  # the law's integrators and CLIK over the period
                law.update(self.period, self.f_meas)
            q_m, v_m, self.f_meas = self.sensors.measure(q, v, f)
            if law is None:
                assert self.user is not None
                u = _user_torque(self.user, t, q_m, v_m, self.f_meas, self.nv)
            else:
                c = law.command(t, q_m, v_m, *self.own.evaluate(q_m, v_m))
                u = c.u0 + c.B @ self.f_meas if c.B is not None else c.u0.copy()
            self._held = Command(u, None)
        assert self._held is not None
        return self._held


class ToolLog:
    """The tool axis' angle from its desired direction a_d(t) at each sample (``[tool]``).

    a_d is the desired joint path's own (it is at time t) when the law runs at the plant's
    rate, else evaluated at t; the axis is the plant's, at its state q.
    """

    def __init__(self, sc: Scenario, law: HybridController | None, measured: bool) -> None:
        self.probe = ToolAngleProbe(sc.robot, sc.tool)
        clik = law.clik if law is not None else None
        self.clik = clik if isinstance(clik, PoseJointPath) and not measured else None
        self.target = ToolTarget(sc.tool, sc.tool_surfaces[0], sc.path)

    def angle(self, t: float, q: np.ndarray) -> float:
        """[rad] at time t [s] and configuration q (nq,)."""
        a_d = self.clik.a_d if self.clik is not None else self.target.axis(t)[0]
        return self.probe.angle(q, a_d)


def build_control_side(sc: Scenario, user: Controller | None, q: np.ndarray) -> ControlSide:
    """The controller of the run: the scenario's law on its own model, or the user's; exact
    (:class:`ExactControl`) with ideal sensing at the plant's rate, else sampled."""
    sim = sc.sim
    per_tick = control_steps(sc.control, sim)
    measured = user is not None or per_tick > 1 or not sc.sensor.ideal
    # the controller's own model: the plant's model file, or control.model (same joints)
    model_robot = sc.controller_model if sc.controller_model is not None else sc.robot
    own = None
    if measured or model_robot is not sc.robot:
        own = ControllerModel(model_robot, sc.tool_surfaces, sim.normalization)
    law = None
    if user is None:
        constraint = (
            own.constraint if own is not None else Constraint(sc.tool_surfaces, sim.normalization)
        )
        law = HybridController(
            model_robot, constraint, sc.path, q, sc.control, dt=per_tick * sim.dt, tool=sc.tool
        )
    if not measured:
        assert law is not None
        return ExactControl(sc, law, None, own, model_robot, sim.dt)
    assert own is not None
    return SampledControl(sc, law, user, own, model_robot, per_tick)


def _no_update(dt: float, f: np.ndarray) -> None:
    """The update of a sampled control side at a plant step: nothing (see ControlSide)."""


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

"""The phase supervisor (section 6.4): free space → near → contact, around the two laws.

:class:`HybridController` is the complete controller the simulator runs. It owns the
controller-side integrators (the desired joint path q_d of eq. 27, the momenta F = ∫f and
F_d = ∫f_d of eq. 3) and advances them in :meth:`HybridController.update`, in step with the
plant; it never integrates the arm's dynamics.

Phases, by the metric distance d of the tip to the surface (the largest d over stacked
surfaces):

* free (0), d > max_dist: free-space law (eq. 29–30) tracking q_d.
* near (1), contact_tol < d ≤ max_dist: the hybrid law (eq. 11) with f_d = max(P·f, 0)
  (eq. 31). **Interpretation.** f in eq. 31 is the *measured* contact force, which is 0
  before contact, so f_d = 0 and F = F_d = 0 there. The paper's Fig. 4a shows a non-zero f_d
  before contact, which is only possible with a *virtual* force: their Simulink computed the
  Lagrange multiplier of section 6.2 off the surface too (with the Baumgarte terms), a
  quantity no sensor measures. With f_d = 0 the projection Q removes every normal component
  of q̇_r, so the tool would hover where it entered the near zone. We therefore add an
  explicit approach term to the nominal reference, q̇_r += −λ_a A⁺ φ (φ the scaled distance,
  λ_a the approach rate, default Λ): the tip closes in on the surface exponentially and
  touches it at a normal speed of about λ_a·contact_tol (≈ 1e-4 m/s), i.e. it "slows down to
  avoid sudden collision" as the paper asks. This is a documented departure from eq. 4.
* contact (2), d ≤ contact_tol: the hybrid law with the constant f_d. F and F_d restart from
  0 at the contact instant, after the impact (the impulse is not counted in F), and at every
  other phase change (a stale e_F would keep pushing through γ e_F after a release).

Model mismatch: the controller's model is the plant's with every link mass and inertia
multiplied by ``mass_factor`` (M, C, g scale by it; kinematics are exact).
"""

from __future__ import annotations

import math
import numbers
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from hybrid_force import _checks as checks
from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.control.clik import (
    ClikSettings,
    DesiredJointPath,
    inverse_kinematics,
)
from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.laws.arimoto import check_damping_gain, default_damping_gain, make_gains
from hybrid_force.control.laws.base import (
    Command,
    ControlTrace,
    Desired,
    Gains,
    Law,
    LawContext,
    LawInput,
    check_law,
    check_options,
    law_spec,
)
from hybrid_force.control.pose_clik import (
    PoseJointPath,
    pose_inverse_kinematics,
)
from hybrid_force.control.tool import ToolSettings, ToolTarget
from hybrid_force.errors import ControlError, RunWarning
from hybrid_force.events import Branch, Event, PhaseChange
from hybrid_force.geometry.paths import Path
from hybrid_force.model.robot import Robot, RobotTerms
from hybrid_force.phases import CONTACT, FREE, NEAR, Phase
from hybrid_force.schema import check_fields, param

_K = LazyKernels("hybrid_force.control._kernels")

__all__ = [
    "ControlSettings",
    "ControllerStart",
    "HybridController",
    "check_controller",
]

_BRANCH_PERIOD = 0.01  # [s] the wrong-branch check runs at most this often (seconds-long test)


@dataclass(frozen=True)
class ControlSettings:
    """Settings of the controller (defaults documented in the README).

    Attributes:
        Kd: K_d as scalar, (n,) or (n, n); None → ``kd_rate`` · M(q0) (scales with the arm).
        kd_rate: κ [1/s] of the default K_d = κ M(q0).
        Lambda: Λ [1/s] (eq. 4, 29).
        beta: β (eq. 4) [(m/s)/(N·s)].
        gamma: γ [1/s] force gain (eq. 11).
        f_d: desired contact force [N] (section 6.3: 10 N); a float or one per surface, each
            ≥ 0 (every surface is unilateral: it pushes, never pulls).
        clik_gain: γ of the CLIK (eq. 27), paper: 7.
        max_dist: near-phase distance [m] (paper: 0.05).
        contact_tol: contact distance [m] (paper: 1e-5).
        P: proportionality factor of eq. 31, in (0, 1) (paper: 0.5).
        approach_rate: λ_a [1/s] of the near-phase approach term (None → Λ).
        supervisor: True: phases by distance (section 6.4); False: always the hybrid law
            (section 6.3, the arm starts and stays on the surface).
        mass_factor: controller's link masses / plant's (model mismatch), default 1.
        branch_check_time: in contact for longer than this [s] with a task error above
            ``branch_error`` that no longer decreases → "branch" event and a warning.
        branch_error: [m].
        law: the control law, a name of :data:`hybrid_force.control.laws.base.LAWS`
            (``"arimoto"``, the paper's, by default); every law runs inside this supervisor.
        options: each law's own settings, ``{law: {key: value}}`` (the scenario's
            ``[control.<law>]`` tables), checked against the law's keys; only the running
            law's table is used.
        rate: the control rate [Hz]: the controller reads its sensors and computes a new
            torque every 1/rate s and the torque is held in between (zero-order hold); None:
            every plant step (1/sim.dt). Must be a whole number of plant steps (checked with
            sim.dt by ``Scenario`` and :func:`hybrid_force.sim.loop.simulate`).

    Every number must be a finite real number (not a bool, not a string) within the range
    above, ``supervisor`` a bool: anything else raises :class:`ControlError` (a number) or
    :class:`ControlError` naming the field. Numbers are stored as floats, K_d as a float or a
    read-only float array, f_d as a float or a tuple of floats.
    """

    Kd: float | np.ndarray | None = param(None, doc="K_d: a number, (n,) or (n, n)")
    kd_rate: float = param(
        100.0, unit="1/s", minimum=0.0, strict=True, doc="κ of the default K_d = κ M(q0)"
    )
    Lambda: float = param(10.0, unit="1/s", minimum=0.0, strict=True, doc="Λ (eq. 4, 29)")
    beta: float = param(0.01, unit="(m/s)/(N·s)", minimum=0.0, doc="β (eq. 4)")
    gamma: float = param(20.0, unit="1/s", minimum=0.0, strict=True, doc="γ (eq. 11)")
    f_d: float | tuple[float, ...] = param(
        10.0, unit="N", doc="desired contact force: one, or one per surface (each >= 0)"
    )
    clik_gain: float = param(7.0, unit="1/s", minimum=0.0, strict=True, doc="CLIK γ (eq. 27)")
    max_dist: float = param(
        0.05, unit="m", minimum=0.0, strict=True, acts_when=("supervisor", True),
        doc="near-phase distance",
    )  # fmt: skip
    contact_tol: float = param(1e-5, unit="m", minimum=0.0, strict=True, doc="contact distance")
    P: float = param(
        0.5, minimum=0.0, maximum=1.0, strict=True, doc="proportionality factor of eq. 31",
        inert="eq. 31's f_d = P·f is 0 before contact, where the measured force is 0: the near "
        "phase uses the approach term instead (docs/scenarios.md, [control])",
    )  # fmt: skip
    approach_rate: float | None = param(
        None, unit="1/s", minimum=0.0, strict=True, acts_when=("supervisor", True),
        doc="λ_a of the approach (none: Λ)",
    )  # fmt: skip
    supervisor: bool = param(True, doc="phases by distance (false: always the hybrid law)")
    mass_factor: float = param(
        1.0, minimum=0.0, strict=True, toml=False, doc="controller's link masses / plant's"
    )
    branch_check_time: float = param(
        1.0, unit="s", minimum=0.0, toml=False, doc="time before a stalled error is a branch"
    )
    branch_error: float = param(
        1e-2, unit="m", minimum=0.0, strict=True, toml=False, doc="task error of a branch"
    )
    rate: float | None = param(
        None, unit="Hz", minimum=0.0, strict=True, doc="control rate (none: every plant step)"
    )
    law: str = param("arimoto", doc="the control law (a registered law name)")
    options: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        """Check every field (types, signs, finiteness) and store numbers as floats.

        K_d is checked for its own shape and definiteness; its size against the arm's joint
        count, and the number of f_d values against the number of surfaces, are checked when
        the arm and the surfaces are known (``Scenario``, :class:`HybridController`).
        """
        set_ = object.__setattr__
        if self.Kd is not None:
            set_(self, "Kd", check_damping_gain(self.Kd))
        supervisor = checks.flag(self.supervisor, "ControlSettings.supervisor", ControlError)
        set_(self, "supervisor", supervisor)
        law_spec(self.law)
        check_fields(self, ControlError, "ControlSettings.")
        if not self.max_dist > self.contact_tol:
            raise ControlError(
                f"need max_dist > contact_tol > 0, got max_dist={self.max_dist!r}, "
                f"contact_tol={self.contact_tol!r}"
            )
        set_(self, "options", check_options(self.options))
        set_(self, "f_d", _desired_force(self.f_d))

    def f_d_for(self, k: int) -> np.ndarray:
        """The desired contact force of each of ``k`` surfaces: (k,) [N], a new array.

        Raises ControlError if f_d has neither 1 nor k values.
        """
        f_d = np.atleast_1d(np.asarray(self.f_d, dtype=float))
        if f_d.shape not in ((1,), (k,)):
            raise ControlError(
                f"ControlSettings.f_d must be one number or {k} numbers (one per surface), got "
                f"{len(f_d)} values: {self.f_d!r}"
            )
        return np.broadcast_to(f_d, (k,)).copy()


def _desired_force(f_d: object) -> float | tuple[float, ...]:
    """f_d as a float or a tuple of floats, each ≥ 0 [N]: every surface here is unilateral."""
    what = "ControlSettings.f_d"
    valid = "a finite real number >= 0 [N] or a sequence of them (one per surface)"
    if isinstance(f_d, numbers.Real) and not isinstance(f_d, bool | np.bool_):
        values = np.array([checks.number(f_d, what, ControlError, unit="N")])
    else:
        values = checks.array(f_d, what, ControlError, valid=valid)
        if values.ndim != 1 or values.size == 0:
            raise ControlError(f"{what} must be {valid}, got {checks.shown(f_d)}")
    if np.any(values < 0):
        raise ControlError(
            f"{what} = {checks.shown(f_d)}: a surface can only push, so f_d must be >= 0 N "
            "(0 is allowed: touch without pressing); a negative desired force would ask the "
            "surface to pull"
        )
    if isinstance(f_d, numbers.Real):
        return float(values[0])
    return tuple(float(x) for x in values)


@dataclass(frozen=True)
class ControllerStart:
    """What :func:`check_controller` found at the start of a run.

    Attributes:
        q0: (nq,) the checked start configuration.
        qd0: (nq,) q_d(0) by inverse kinematics from q0 (the same branch).
        target: the tool's desired direction (``[tool] orientation = "normal"``), else None.
        M0: (n, n) the controller's M(q0) × mass_factor. gains: K_d, Λ, β, γ.
        stiffness: λ_max(M0⁻¹ K_d) [1/s²·s = 1/s per unit dt]. f_d: (k,) desired force [N].
        context: what the law is built from.
    """

    q0: np.ndarray
    qd0: np.ndarray
    target: ToolTarget | None
    M0: np.ndarray
    gains: Gains
    stiffness: float
    f_d: np.ndarray
    context: LawContext


def check_controller(
    robot: Robot,
    constraint: Constraint,
    path: Path,
    q0: np.ndarray,
    settings: ControlSettings,
    dt: float,
    tool: ToolSettings,
    t0: float = 0.0,
) -> ControllerStart:
    """The checks of a controller's start, without building it (what
    :class:`HybridController` runs first, and the scenario loader runs alone).

    q_d(0) in reach from q0 (the tool pose too with ``[tool]``), the gains (eq. 4, 11, 29),
    dt·λ_max(M⁻¹K_d) at q0 for a law that reads K_d, f_d against the surfaces, and the law's
    own checks (:attr:`~hybrid_force.control.laws.base.LawSpec.check`).

    Args:
        robot: the controller's model of the arm. constraint: the surfaces. path: p_d(t).
        q0: (nq,) the start configuration. settings: the control settings.
        dt: the control period [s]. tool: the ``[tool]`` settings. t0: start time [s].

    Raises:
        ReachError: q_d(0) out of reach. ControlError, ControlError: a gain or a law's setting.
    """
    s, n = settings, robot.nv
    q0 = robot.check_q(q0, "q0")
    target = None
    if tool.controlled:
        tool.check_arm(robot)
        target = ToolTarget(tool, constraint.surfaces[0], path)
        qd0 = pose_inverse_kinematics(robot, target, t0, q0)
    else:
        qd0 = inverse_kinematics(robot, path.position(t0), seed=q0)
    M0 = robot.mass_matrix(q0) * s.mass_factor
    Kd = default_damping_gain(M0, s.kd_rate) if s.Kd is None else s.Kd
    gains = make_gains(Kd, s.Lambda, s.beta, s.gamma, n)
    stiffness = float(np.linalg.eigvals(np.linalg.solve(M0, gains.Kd)).real.max())
    spec = law_spec(s.law)
    # only a law that reads K_d is held to it (each law checks its own gains: loop_bounds)
    if "Kd" in spec.gains and stiffness * dt > 0.5:
        raise ControlError(
            f"dt·λ_max(M⁻¹K_d) = {stiffness * dt:.3g} at q0 is too large for explicit "
            f"integration (must stay well below 2; limit here 0.5): lower Kd or dt = {dt}"
        )
    f_d = s.f_d_for(constraint.k)
    context = LawContext(robot, constraint, s, gains, M0, q0, dt)
    check_law(context)
    return ControllerStart(q0, qd0, target, M0, gains, stiffness, f_d, context)


@dataclass
class _Integrators:
    F: np.ndarray
    F_d: np.ndarray
    f_d: np.ndarray
    best_error: float = np.inf
    best_error_time: float = 0.0
    branch_reported: bool = False
    events: list[Event] = field(default_factory=list)


class HybridController:
    """The paper's controller: CLIK + free-space law + hybrid law + phase supervisor.

    Args:
        robot: the arm (kinematics; the dynamics terms come from the simulator's pass).
        constraint: the surfaces.
        path: desired task-space path p_d(t) (on the surface).
        q0: (nq,) start configuration; q_d(0) is found by inverse kinematics from it, so it
            lies on the same branch.
        settings: see :class:`ControlSettings`.
        dt: time step [s] (used to check dt·λ_max(M⁻¹K_d)).
        t0: start time [s].
        tool: the ``[tool]`` settings; with ``orientation = "normal"`` the desired joint path
            also points the tool into the first surface
            (:class:`~hybrid_force.control.pose_clik.PoseJointPath`, compiled); the laws are
            unchanged: the orientation enters through q_d only.

    The CLIK and the laws run compiled, writing into preallocated arrays
    (:class:`~hybrid_force.control.clik.DesiredJointPath`,
    :class:`~hybrid_force.control.laws.arimoto.LawWorkspace`).
    """

    _joint_path: type[DesiredJointPath] = DesiredJointPath
    _pose_path: type[PoseJointPath] = PoseJointPath

    def __init__(
        self,
        robot: Robot,
        constraint: Constraint,
        path: Path,
        q0: np.ndarray,
        settings: ControlSettings | None = None,
        dt: float = 1e-3,
        t0: float = 0.0,
        tool: ToolSettings | None = None,
    ) -> None:
        self.robot = robot
        self.constraint = constraint
        self.path = path
        self.settings = s = settings or ControlSettings()
        self.tool = tool = tool or ToolSettings()
        k, n = constraint.k, robot.nv
        start = check_controller(robot, constraint, path, q0, s, dt, tool, t0)
        self.clik: DesiredJointPath | PoseJointPath
        clik = ClikSettings(gamma=s.clik_gain)
        if start.target is not None:
            self.clik = self._pose_path(robot, path, start.target, start.qd0, clik, t0=t0)
        else:
            self.clik = self._joint_path(robot, path, start.qd0, clik, t0=t0)
        self.gains: Gains = start.gains
        self.stiffness = start.stiffness
        # e_q, e_F, the contact's f_d and the momenta F, F_d as views of one flat array,
        # which the steady contact step hands to the law as one argument (LawInput.steady)
        # and the momenta's update takes whole (_kernels.steady_parts, accumulate_steady)
        self._steady_pack = pack = np.zeros(n + 4 * k)
        self._accumulate_steady: Callable[..., None] | None = None  # (_accumulate)
        self.f_d_contact = pack[n + k : n + 2 * k]
        self.f_d_contact[:] = start.f_d
        self.approach_rate = s.Lambda if s.approach_rate is None else s.approach_rate
        self._int = _Integrators(
            F=pack[n + 2 * k : n + 3 * k], F_d=pack[n + 3 * k :], f_d=np.zeros(k)
        )
        self.phase = FREE
        self.V = 0.0  # V of the last step [J] (section 5.1)
        self._first = True
        self._zeros_k = np.zeros(k)
        self._e_q = self._steady_pack[:n]
        self._e_F = self._steady_pack[n : n + k]
        self._law: Law = law_spec(s.law).factory(start.context)  # checked by check_controller
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._scaled = RobotTerms.zeros(n)
        # per-step tests, decided once
        self._supervised = s.supervisor
        self._exact_model = s.mass_factor == 1.0
        self._subtract = robot.euclidean  # e_q = q − q_d (else pin.difference)
        # always in contact (no supervisor), the plant's terms as they are and e_q = q − q_d:
        # after the first call, every step is :meth:`_contact_command`
        self._steady_contact = not s.supervisor and self._exact_model and self._subtract
        self._steady = False
        # the law whose hybrid_at (e_q formed in its own call) _contact_command calls
        self._at_law: object = None
        self._hybrid_at: Callable[[LawInput, np.ndarray], Command] | None = None
        self._next_branch_check = -np.inf
        self._desired = self._sample_desired()
        # the law's input, its fields set at every step
        self._input = LawInput(self._scaled, self._e_q, self._e_q, self._desired)

    # ------------------------------------------------------------------ helpers
    @property
    def events(self) -> list[Event]:
        """Phase changes and a wrong branch (:mod:`hybrid_force.events`), in time order."""
        return self._int.events

    @property
    def desired(self) -> Desired:
        """q_d, q̇_d, q̈_d now (arrays that the next step may overwrite)."""
        c, d = self.clik, self._desired
        if d.q is not c.q or d.qd is not c.qd or d.qdd is not c.qdd or d.p is not c.p_d:
            self._desired = d = self._sample_desired()  # new arrays (a new sample)
        return d

    def _sample_desired(self) -> Desired:
        c = self.clik
        return Desired(
            q=c.q, qd=c.qd, qdd=c.qdd, p=c.p_d, pd=c.pdot_d, pdd=c.pddot_d,
            pack=getattr(c, "desired_pack", None),
        )  # fmt: skip

    @property
    def law(self) -> Law:
        """The control law this supervisor runs (``settings.law``)."""
        return self._law

    @property
    def trace(self) -> ControlTrace | None:
        """What the law computed at the last step (None before the first step)."""
        return None if self._last is None else self._law.trace(*self._last)

    @property
    def f_d(self) -> np.ndarray:
        """(k,) desired force of the current step [N]."""
        return self._int.f_d

    def _phase_of(self, distance: np.ndarray) -> int:
        d = float(distance.max())
        if not self.settings.supervisor or d <= self.settings.contact_tol:
            return CONTACT
        return NEAR if d <= self.settings.max_dist else FREE

    def _model_terms(self, terms: RobotTerms) -> RobotTerms:
        """The controller's model: the plant's terms with M, C, g, nle × mass_factor."""
        m = self.settings.mass_factor
        if m == 1.0:
            return terms
        out = self._scaled
        for name in ("M", "C", "g", "nle"):
            np.multiply(getattr(terms, name), m, out=getattr(out, name))
        for name in ("p", "J", "Jdot", "Jdot_v", "pdot"):
            getattr(out, name)[...] = getattr(terms, name)
        return out

    # ------------------------------------------------------------------ one step
    def command(
        self,
        t: float,
        q: np.ndarray,
        v: np.ndarray,
        terms: RobotTerms,
        cons: ConstraintTerms | None,
    ) -> Command:
        """The command for the state (q, v) at time t.

        Args:
            terms: the plant's robot terms at (q, v) (the controller scales its dynamics by
                ``mass_factor``).
            cons: constraint terms at (q, v), or None when they are undefined (free phase
                far from the surface, e.g. the tip on the cylinder's axis).
        """
        if self._steady and cons is not None:
            return self._contact_command(t, q, v, terms, cons)
        if cons is None:
            if self.settings.supervisor is False:
                raise ControlError(f"constraint undefined at t = {t:.6g} s, q = {q.tolist()}")
            phase = FREE
        elif not self._supervised:
            phase = CONTACT
        else:
            phase = self._phase_of(cons.distance)
        st = self._int
        if phase != self.phase or self._first:
            if not self._first or phase != FREE:
                st.events.append(PhaseChange(float(t), Phase(phase)))
            # F and F_d restart at every phase change: they only mean something in contact,
            # and a stale e_F would keep pushing (γ e_F) after a release.
            st.F[:] = 0.0
            st.F_d[:] = 0.0
            self._e_F[:] = 0.0
            if phase == CONTACT:
                st.best_error, st.best_error_time = np.inf, t
            self.phase = phase
            self._first = False
        model = terms if self._exact_model else self._model_terms(terms)
        desired = self.desired
        if self._subtract:
            e_q = np.subtract(q, desired.q, out=self._e_q)
        else:
            e_q = pin.difference(self.robot.model, desired.q, q)
        law, inp = self._law, self._input
        inp.robot, inp.v, inp.e_q, inp.desired = model, v, e_q, desired
        if phase == FREE:
            st.f_d = self._zeros_k
            self._last = (e_q, self._zeros_k, st.f_d)
            inp.cons, inp.e_F, inp.f_d, inp.approach = None, self._zeros_k, st.f_d, None
            command = law.free_space(inp)
            self.V = law.V
            return command
        assert cons is not None  # only the free phase runs without constraint terms
        if phase == NEAR:
            # eq. 31 with the measured force, which is 0 before contact (see module docstring).
            st.f_d = self._zeros_k
            approach = -self.approach_rate * cons.distance
        else:
            st.f_d = self.f_d_contact
            approach = None
            if t >= self._next_branch_check:
                self._next_branch_check = t + _BRANCH_PERIOD
                self._check_branch(t, terms, cons, e_q)
        e_F = self._e_F  # F − F_d, kept up to date by update()
        self._last = (e_q, e_F, st.f_d)
        inp.cons, inp.e_F, inp.f_d, inp.approach = cons, e_F, st.f_d, approach
        command = law.hybrid(inp)
        self.V = law.V
        # from now on the contact phase's inputs above stay as they are (same arrays), views
        # of the steady pack the law may take whole (Law.hybrid_at)
        self._steady = self._steady_contact
        if self._steady and inp.e_F is self._e_F and inp.f_d is self.f_d_contact:
            inp.steady = self._steady_pack
        return command

    def _contact_command(
        self, t: float, q: np.ndarray, v: np.ndarray, terms: RobotTerms, cons: ConstraintTerms
    ) -> Command:
        """:meth:`command` of a run always in contact (no supervisor), once its first call
        has set the law's input: the law with e_q = q − q_d (``Law.hybrid_at``), the branch
        check; the phase, f_d, e_F's array and the approach term (none) are those of the
        first call."""
        inp = self._input
        inp.robot, inp.v, inp.desired, inp.cons = terms, v, self.desired, cons
        law = self._law
        if law is not self._at_law:  # (a law set after __init__, e.g. by a test's oracle)
            # a law without Law.hybrid_at (any object with the methods the supervisor calls)
            self._at_law, self._hybrid_at = law, getattr(law, "hybrid_at", None)
        if self._hybrid_at is not None:
            command = self._hybrid_at(inp, q)  # e_q = q − q_d into inp.e_q, then the law
        else:
            np.subtract(q, inp.desired.q, out=self._e_q)
            command = law.hybrid(inp)
        self.V = law.V
        # (after the law, which does not read what the check records: e_q is formed there)
        if t >= self._next_branch_check:
            self._next_branch_check = t + _BRANCH_PERIOD
            self._check_branch(t, terms, cons, self._e_q)
        return command

    def _check_branch(
        self, t: float, terms: RobotTerms, cons: ConstraintTerms, e_q: np.ndarray
    ) -> None:
        """Flag a task error that persists and lies along the constraint normal in joint space.

        Q removes the part (I − Q) e_q = A⁺A e_q of the joint error, so if that part carries
        most of e_q (‖A⁺A e_q‖ > 0.9 ‖e_q‖) while the tip error stays above ``branch_error``
        for ``branch_check_time``, no gain can correct it: the arm is on another IK branch.
        A steady offset from model error lies along the surface (Q e_q) and is not flagged.
        Runs at most every 10 ms of simulated time (``_BRANCH_PERIOD``): the test spans seconds.
        """
        st, s = self._int, self.settings
        err = math.dist(terms.p.tolist(), self.clik.p_d.tolist())  # clik is at time t
        if err < 0.5 * st.best_error:
            st.best_error, st.best_error_time = err, t
        if (
            not st.branch_reported
            and err > s.branch_error
            and t - st.best_error_time > s.branch_check_time
        ):
            normal_part = cons.A_pinv @ (cons.A @ e_q)
            share = float(normal_part @ normal_part) / max(float(e_q @ e_q), 1e-300)
            if share <= 0.81:
                return
            st.branch_reported = True
            msg = (
                f"at t = {t:.4g} s the task-space error |p − p_d| = {err:.3g} m had not halved "
                f"since t = {st.best_error_time:.4g} s in the supervisor's contact phase (tip "
                f"within control.contact_tol of the surface), and {100 * math.sqrt(share):.0f} % "
                "of the joint error lies along the constraint normal, which the projection Q "
                "removes: the arm is probably on another inverse-kinematics branch than q_d and "
                "the hybrid law cannot bring it back (change the start configuration or the gains)"
            )
            st.events.append(Branch(float(t), err))
            warnings.warn(RunWarning(msg), stacklevel=2)

    def update(self, dt: float, f: np.ndarray) -> None:
        """Advance the controller's integrators over one step with the force f (k,) [N]."""
        if self.phase == CONTACT:
            self._accumulate(f, dt)
        self._law.update(dt, f)
        self.clik.advance(dt)

    def _accumulate(self, f: np.ndarray, dt: float) -> None:
        """F += f dt, F_d += f_d dt, e_F = F − F_d (eq. 3), in one compiled call."""
        st = self._int
        if st.f_d is self.f_d_contact:  # all four in the steady pack: one argument
            kernel = self._accumulate_steady
            if kernel is None:  # bound at the first call (entry): the force's (k,) array
                kernel = self._accumulate_steady = entry(
                    _K.accumulate_steady, self._steady_pack, f, float(dt)
                )
            kernel(self._steady_pack, f, dt)
        else:
            _K.accumulate(st.F, f, st.F_d, st.f_d, dt, self._e_F)

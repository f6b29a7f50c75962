"""What a control law is to the supervisor, and the registry of the laws a scenario can name.

A law is the part of the controller that turns one step's errors into joint torques. The
supervisor (:class:`~hybrid_force.control.supervisor.HybridController`) owns what every law
shares: the desired joint path of the CLIK (eq. 27) with its task-space samples, the phases
(section 6.4), the momenta F = ∫f, F_d = ∫f_d and e_F = F − F_d (eq. 3). It calls

* :meth:`Law.free_space` away from the surface, and
* :meth:`Law.hybrid` near it (f_d = 0 and an approach velocity) and in contact (f_d),

and after each step :meth:`Law.update` with the force the controller measured, so a law can
advance its own states (parameter estimates, an admittance reference). A command is affine
in the contact force the plant will produce, u = u0 + B f (:class:`Command`): a law that feeds
the measured force straight through says so in B, and with ideal sensing at the plant's rate
the simulator resolves u and f together, exactly; sampled, the law's B meets the last reading.

A law is built by its registry entry's factory from a :class:`LawContext`: the controller's own
model, the surfaces' constraint, the control settings (with this law's ``[control.<law>]``
table as ``options``) and the paper's gains with K_d = κ M(q0), which scale with the arm; a law
derives its default gains the same way so that one scenario file serves every law.
"""

from __future__ import annotations

import importlib
import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from hybrid_force.control.constraint import Constraint
from hybrid_force.errors import ControlError, did_you_mean

if TYPE_CHECKING:  # annotations only: the registry is read without importing any law
    from collections.abc import Sequence

    from hybrid_force.control.constraint import Constraint, ConstraintTerms
    from hybrid_force.control.laws.arimoto import Command, ControlTrace, Desired, Gains
    from hybrid_force.control.supervisor import ControlSettings
    from hybrid_force.geometry.surface_base import Surface
    from hybrid_force.model.robot import Robot, RobotTerms

__all__ = [
    "LAWS",
    "Law",
    "LawContext",
    "LawSpec",
    "LoopBound",
    "LoopContext",
    "Option",
    "build_law",
    "check_options",
    "law_log_names",
    "law_loop_bounds",
    "law_names",
    "law_spec",
]


class Law(Protocol):
    """A control law as the supervisor runs it (see the module docstring).

    Optional hook, for signals of the law's own that a run should record at every sample (its
    parameter estimates, say): ``log_names() -> tuple[str, ...]`` (m names, fixed when the law
    is built) and ``log_values(out)``, which writes the m current values into ``out`` (m,).
    The simulator stores them as ``Result.law_log`` (N, m) (:mod:`hybrid_force.law_log`); a
    law without the hook logs nothing (:func:`law_log_names`).

    Attributes:
        V: the law's Lyapunov function (or NaN when it has none) at the last call [J].
    """

    V: float

    def free_space(
        self, robot: RobotTerms, v: np.ndarray, e_q: np.ndarray, desired: Desired
    ) -> Command:
        """Torques away from the surface: track q_d (or p_d).

        Args:
            robot: the controller's model terms at the measured (q, v).
            v: (n,) joint velocity [rad/s or m/s]. e_q: (n,) q − q_d.
            desired: q_d, q̇_d, q̈_d (n,) and p_d, ṗ_d, p̈_d (3,) [m, m/s, m/s²] now.
        """
        ...

    def hybrid(
        self,
        robot: RobotTerms,
        cons: ConstraintTerms,
        v: np.ndarray,
        e_q: np.ndarray,
        desired: Desired,
        e_F: np.ndarray,
        f_d: np.ndarray,
        approach: np.ndarray | None,
    ) -> Command:
        """Torques near and on the surface: track the path along it and f_d across it.

        Args:
            cons: the constraint rows at (q, v) (A (k, n), its normal, distance, Q, …).
            e_F: (k,) momentum error F − F_d [N·s] (eq. 3); 0 outside contact.
            f_d: (k,) desired force [N]; 0 in the near phase.
            approach: (k,) normal reference velocity [m/s per row scaling] of the near phase,
                which brings the tool onto the surface slowly; None in contact.
        """
        ...

    def update(self, dt: float, f: np.ndarray) -> None:
        """Advance the law's own states over dt [s] with the measured force f (k,) [N]."""
        ...

    def trace(self, e_q: np.ndarray, e_F: np.ndarray, f_d: np.ndarray) -> ControlTrace | None:
        """What the last call computed, for logs and tests (None if the law keeps none)."""
        ...

    def info(self) -> dict[str, Any]:
        """The law's gains and settings as JSON-able data (stored in the result's meta)."""
        ...


@dataclass(frozen=True)
class LawContext:
    """Everything a law's factory may use.

    Attributes:
        robot: the controller's model of the arm (kinematics; its dynamics scaled by
            ``settings.mass_factor`` in the terms the law receives).
        constraint: the controller's constraint rows of the surfaces.
        settings: the control settings; ``settings.options.get(name, {})`` is this law's table.
        gains: the paper's gains (K_d (n, n) = κ M(q0) by default, Λ, β, γ).
        M0: (n, n) the controller's mass matrix at the start [kg·m² …].
        q0: (nq,) the start configuration.
        dt: the control period [s].
        reference: True: build the readable numpy form (no compiled kernels).
    """

    robot: Robot
    constraint: Constraint
    settings: ControlSettings
    gains: Gains
    M0: np.ndarray
    q0: np.ndarray
    dt: float
    reference: bool = False

    @property
    def options(self) -> Mapping[str, Any]:
        """This law's ``[control.<law>]`` table (checked values; empty when absent)."""
        return self.settings.options.get(self.settings.law, {})


@dataclass(frozen=True)
class Option:
    """One key of a law's ``[control.<law>]`` table.

    Attributes:
        doc: what it is, with its unit and default (shown by ``hybrid-force laws --options``).
        kind: "number" (a finite real number), "choice" (one of ``choices``) or "bool".
        minimum: the smallest number allowed (numbers only); ``strict``: excluded.
    """

    doc: str
    kind: str = "number"
    choices: tuple[str, ...] = ()
    minimum: float | None = 0.0
    strict: bool = True


@dataclass(frozen=True)
class LawSpec:
    """A registry entry: the law's name, one line about it and where its factory lives.

    Attributes:
        summary: one line for ``hybrid-force laws`` (with its source).
        factory: ``"module:function"``, imported only when the law is built.
        options: the keys of its ``[control.<law>]`` table.
        gains: the ``[control]`` gains the law reads (of Kd, kd_rate, Lambda, beta, gamma),
            each with the key of its own table that replaces it when given (None: none does);
            a gain not listed has no effect with this law (the loader refuses it, a run's meta
            does not record it).
        loop_bounds: ``"module:function"`` of the law's pre-run stability checks
            (``function(LoopContext) -> list[LoopBound]``); None: the law has none.
    """

    name: str
    summary: str
    factory: str
    options: Mapping[str, Option] = field(default_factory=dict)
    gains: Mapping[str, str | None] = field(default_factory=dict)
    loop_bounds: str | None = None

    def load(self) -> Callable[[LawContext], Law]:
        """The factory function (imports its module)."""
        module, _, function = self.factory.partition(":")
        return getattr(importlib.import_module(module), function)

    def reads(self, gain: str, options: Mapping[str, Any]) -> bool:
        """True when the law reads ``control.<gain>`` with its table ``options`` (the gain is
        listed in :attr:`gains` and the key of the table that replaces it is not given)."""
        if gain not in self.gains:
            return False
        replaced_by = self.gains[gain]
        return replaced_by is None or replaced_by not in options


def below(limit: float) -> str:
    """``limit`` > 0 shown to 4 significant digits rounded down: a value copied from a
    message ("must stay below 0.1234") is then inside the bound it names."""
    if not (math.isfinite(limit) and limit > 0):
        return f"{limit:.4g}"
    scale = 10.0 ** (math.floor(math.log10(limit)) - 3)
    shown = math.floor(limit / scale) * scale
    while shown >= limit:
        shown -= scale
    return f"{shown:.4g}"


@dataclass(frozen=True)
class LoopBound:
    """One pre-run stability check of a law: a loop number that must stay below a limit.

    Attributes:
        key: the scenario key the check names (``control.beta``, ``sim.model_mass_factor``).
        value: that key's value as set (or its default, said in words).
        number: the loop's number in this run (a gain, or T·λ_max of a velocity loop).
        limit: the loop is stable iff ``number < limit``.
        loop: what the loop is and how the number and the limit follow (one line).
    """

    key: str
    value: object
    number: float
    limit: float
    loop: str

    @property
    def stable(self) -> bool:
        """number < limit."""
        return bool(self.number < self.limit)


@dataclass(frozen=True)
class LoopContext:
    """What a law's pre-run checks (``LawSpec.loop_bounds``) may use: the plant, the
    CONTROLLER's model of it, the configurations the run will pass and how it samples.

    Attributes:
        plant: the arm the simulator integrates.
        model: the controller's model of the arm (``control.model``, else the plant's file).
        mass_factor: ``sim.model_mass_factor`` (M, C, g of ``model`` × it).
        surfaces: the surfaces. normalization: ``sim.normalization`` ("tip" or "joint").
        configurations: q (nq,) samples of the desired path (and the start).
        q0: the start configuration. settings: the control settings.
        period: the control period T [s]. sampled: the controller reads a measured force
            (a control rate below the plant's, or sensors that are not ideal); False: the
            force loop is resolved exactly.
        alpha: the force filter's α in (0, 1] (1: none). delay: ``sensor.force_delay``.
        model_key, model_value: the key that makes the controller's model differ from the
            plant (``sim.model_mass_factor``, ``control.model``) and its value; None when it
            does not.
    """

    plant: Robot
    model: Robot
    mass_factor: float
    surfaces: Sequence[Surface]
    normalization: str
    configurations: Sequence[np.ndarray]
    q0: np.ndarray
    settings: ControlSettings
    period: float
    sampled: bool
    alpha: float = 1.0
    delay: int = 0
    model_key: str | None = None
    model_value: object = None

    def plant_mass(self, q: np.ndarray) -> np.ndarray:
        """(n, n) the plant's M(q)."""
        return self.plant.mass_matrix(q)

    def model_mass(self, q: np.ndarray) -> np.ndarray:
        """(n, n) the controller's M_c(q) = mass_factor × its model's M(q)."""
        return self.mass_factor * self.model.mass_matrix(q)

    def rows(self, q: np.ndarray, robot: Robot | None = None) -> np.ndarray:
        """(k, n) the constraint rows A at q of ``robot`` (default the plant), scaled as
        ``sim.normalization`` says."""

        arm = self.plant if robot is None else robot
        A, _ = Constraint(list(self.surfaces)).normal_rows(arm.tip_position(q), arm.jacobian(q))
        if self.normalization == "joint":
            A = A / np.linalg.norm(A, axis=1, keepdims=True)
        return A

    def options_of(self, law: str) -> Mapping[str, Any]:
        """The law's ``[control.<law>]`` table (empty when absent)."""
        return self.settings.options.get(law, {})

    def named(self, key: str, value: object) -> tuple[str, object]:
        """(key, value) for a check on the controller's model: the model's key when the
        controller's model differs from the plant, else the law's own ``key``."""
        if self.model_key is not None:
            return self.model_key, self.model_value
        return key, value

    @property
    def where(self) -> str:
        """The run's sampling, in words, for the messages."""
        text = f"control period T = {self.period:g} s"
        if self.sampled:
            text += f", force read one period late, sensor.force_delay = {self.delay}"
            if self.alpha < 1.0:
                text += f", filter α = {self.alpha:.3g}"
        if self.model_key is not None:
            text += f", the controller's model {self.model_key} = {self.model_value!r}"
        return text


def law_loop_bounds(context: LoopContext) -> list[LoopBound]:
    """The running law's pre-run checks (its ``LawSpec.loop_bounds``; none by default)."""
    spec = law_spec(context.settings.law)
    if spec.loop_bounds is None:
        return []
    module, _, function = spec.loop_bounds.partition(":")
    checks: Callable[[LoopContext], list[LoopBound]] = getattr(
        importlib.import_module(module), function
    )
    return checks(context)


_PAPER_GAINS: Mapping[str, str | None] = {
    "Kd": None, "kd_rate": "Kd", "Lambda": None, "beta": None, "gamma": None,
}  # fmt: skip
"""The paper's gains as its laws read them: K_d (or kd_rate · M(q0) when Kd is not given),
Λ, β, γ."""

# Each law adds its entry here; the modules are imported only when a law is built.
LAWS: dict[str, LawSpec] = {
    spec.name: spec
    for spec in (
        LawSpec(
            "arimoto",
            "the paper's modified Arimoto hybrid law with its phase supervisor (eq. 4, 11, 29-31)",
            "hybrid_force.control.laws.arimoto:build",
            gains=_PAPER_GAINS,
            loop_bounds="hybrid_force.control.laws.arimoto:loop_bounds",
        ),
        LawSpec(
            "arimoto_adaptive",
            "the paper's law with Slotine-Li adaptation of its model terms (Slotine & Li, IJRR "
            "6(3) 1987; paper section 7)",
            "hybrid_force.control.laws.arimoto_adaptive:build",
            {
                "adaptation_rate": Option(
                    "ρ [1/s] of the default Γ_ii = ρ / E[Y_iᵀ K_d⁻¹ Y_i]: the rate at which one "
                    "parameter's error alone decays, for any arm (default 5)"
                ),
            },
            gains=_PAPER_GAINS,
            loop_bounds="hybrid_force.control.laws.arimoto:loop_bounds",
        ),
        LawSpec(
            "raibert_craig",
            "task-space selection-matrix hybrid control with a PI force loop (Raibert & Craig "
            "1981; corrected form: Fisher & Mujtaba 1992)",
            "hybrid_force.control.laws.raibert_craig:build",
            {
                "form": Option(
                    '"corrected" (default: the position servo exerts no force along the '
                    'normals, Fisher & Mujtaba 1992) or "original" (J⁻¹ S, Raibert & Craig 1981)',
                    kind="choice",
                    choices=("corrected", "original"),
                ),
                "feedforward": Option(
                    '"model" (default: M q̈_ff + C q̇ + g of the controller\'s model) or '
                    '"gravity" (g only, as in 1981)',
                    kind="choice",
                    choices=("model", "gravity"),
                ),
                "decouple": Option(
                    "true (default): project the position feedback so that, by the model, it "
                    "cannot change the contact force; false: the published forms",
                    kind="bool",
                ),
                "position_rate": Option("ω_p [1/s], slow pole of the position error (Λ)"),
                "damping_rate": Option("ω_d [1/s], fast pole of the position error (kd_rate)"),
                "kp": Option("k_p [-], proportional force gain (0.5)", strict=False),
                "ki": Option("k_i [1/s], integral force gain ((1 + k_p) γ)"),
            },
            gains={"Lambda": "position_rate", "kd_rate": "damping_rate", "gamma": "ki"},
            loop_bounds="hybrid_force.control.laws.raibert_craig:loop_bounds",
        ),
        LawSpec(
            "osc_hybrid",
            "operational-space hybrid motion/force control, dynamically consistent, with a "
            "null-space posture (Khatib 1987, IEEE J. Robot. Autom. 3(1))",
            "hybrid_force.control.laws.osc_hybrid:build",
            {
                "omega": Option("task-space bandwidth ω [rad/s]: K_p = ω², K_v = 2ζω (default 20)"),
                "zeta": Option("damping ratio ζ of the task-space error (default 1: critical)"),
                "normal_damping": Option(
                    "K_n [1/s]: damping of the normal speed in contact, rate of the approach "
                    "speed in the near phase (default K_v = 2ζω)"
                ),
                "force_p": Option(
                    "k_P [-]: proportional force gain on f − f_d (default 0; keep it < 1 at a "
                    "control rate)",
                    minimum=0.0,
                    strict=False,
                ),
                "force_i": Option(
                    "k_I [1/s]: integral force gain on e_F = ∫(f − f_d) dt (default 20)"
                ),
                "null_omega": Option(
                    "null-space posture bandwidth ω_n [rad/s]: k_n = ω_n², d_n = 2ω_n (default 10)"
                ),
            },
            loop_bounds="hybrid_force.control.laws.osc_hybrid:loop_bounds",
        ),
        LawSpec(
            "impedance",
            "Cartesian impedance, K = ω²Λ(q) (Hogan 1985), with force tracking along the "
            "normal (Seraji & Colbaugh 1997)",
            "hybrid_force.control.laws.impedance:build",
            {
                "omega": Option("natural frequency ω of K = ω²Λ(q), D = 2ζωΛ(q) [1/s] (30)"),
                "zeta": Option("damping ratio ζ of D = 2ζωΛ(q) (1: critical)"),
                "force_tracking": Option(
                    "true: the reference's depth adapts until f = f_d (φ̇ = κ_f (f_d − f)); "
                    "false: plain impedance at the model's depth f_d/k_n (true)",
                    kind="bool",
                ),
                "force_rate": Option("κ_f, rate of the force-tracking admittance [1/s] (10)"),
                "feedforward": Option(
                    "true: add M q̈_d + C q̇_d of the desired joint path (true)", kind="bool"
                ),
            },
            loop_bounds="hybrid_force.control.laws.impedance:loop_bounds",
        ),
    )
}


def law_log_names(law: object) -> tuple[str, ...]:
    """The names of the signals ``law`` logs at every sample: its ``log_names()`` when it has
    the optional hook of :class:`Law` (with ``log_values``), else none."""
    if not (
        callable(getattr(law, "log_names", None)) and callable(getattr(law, "log_values", None))
    ):
        return ()
    return tuple(str(name) for name in law.log_names())  # type: ignore[attr-defined]


def law_names() -> tuple[str, ...]:
    """The names a scenario's ``control.law`` may take, in registry order."""
    return tuple(LAWS)


def law_spec(name: object) -> LawSpec:
    """The registry entry of ``name`` (ControlError naming ``control.law`` and the valid names)."""
    if not isinstance(name, str) or name not in LAWS:
        hint = did_you_mean(name, LAWS) if isinstance(name, str) else ""
        raise ControlError(
            f"control.law = {name!r} is not a known law{hint}; valid: {', '.join(LAWS)}",
            key="control.law",
            value=name,
        )
    return LAWS[name]


def check_options(options: object) -> dict[str, dict[str, Any]]:
    """Check ``{law: {key: value}}`` against each law's :class:`Option` keys.

    Returns:
        A new dict of new dicts, numbers as floats.

    Raises:
        ControlError: an unknown law or key (naming ``control.<law>.<key>`` and the valid
            ones), or ControlError: a value of the wrong kind or out of range.
    """
    if not isinstance(options, Mapping):
        raise ControlError(
            f"ControlSettings.options must be a mapping {{law: {{key: value}}}}, got {options!r}",
            key="control",
            value=options,
        )
    out: dict[str, dict[str, Any]] = {}
    for law, table in options.items():
        spec = law_spec(law)
        if not isinstance(table, Mapping):
            raise ControlError(
                f"control.{law} must be a table of the law's settings, got {table!r}",
                key=f"control.{law}",
                value=table,
            )
        checked: dict[str, Any] = {}
        for key, value in table.items():
            where = f"control.{law}.{key}"
            if key not in spec.options:
                valid = ", ".join(spec.options) or "(none: this law has no settings of its own)"
                raise ControlError(
                    f"{where} is not a setting of law {law!r}{did_you_mean(str(key), spec.options)}"
                    f"; valid: {valid}",
                    key=where,
                    value=value,
                )
            checked[key] = _check_option(where, value, spec.options[key])
        out[law] = checked
    return out


def _check_option(where: str, value: object, option: Option) -> object:
    if option.kind == "bool":
        if not isinstance(value, bool):
            raise ControlError(
                f"{where} must be true or false, got {value!r}", key=where, value=value
            )
        return value
    if option.kind == "choice":
        if not isinstance(value, str) or value not in option.choices:
            hint = did_you_mean(value, option.choices) if isinstance(value, str) else ""
            raise ControlError(
                f"{where} = {value!r} is not valid{hint}; valid: {', '.join(option.choices)}",
                key=where,
                value=value,
            )
        return value
    if not isinstance(value, numbers.Real) or isinstance(value, bool) or not math.isfinite(value):
        raise ControlError(
            f"{where} must be a finite real number, got {value!r}", key=where, value=value
        )
    number = float(value)
    low = option.minimum
    if low is not None and (number < low or (option.strict and number == low)):
        relation = ">" if option.strict else ">="
        raise ControlError(
            f"{where} = {number!r} must be {relation} {low:g}", key=where, value=value
        )
    return number


def build_law(context: LawContext) -> Law:
    """Build the law named by ``context.settings.law`` (ControlError if it is unknown)."""
    return law_spec(context.settings.law).load()(context)

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

Each call receives one :class:`LawInput`; :class:`Law` declares the optional parts (update,
trace, info, the logged signals) once, with their defaults.

A law registers itself in its own module (:func:`register`, a :class:`LawSpec` into
:data:`LAWS`). Its entry's factory builds it from a :class:`LawContext`: the controller's own
model, the surfaces' constraint, the control settings (with this law's ``[control.<law>]``
table as ``options``) and the paper's gains with K_d = κ M(q0), which scale with the arm; a law
derives its default gains the same way so that one scenario file serves every law. Its table
is a frozen dataclass of :func:`hybrid_force.schema.param` fields (:class:`LawOptions`), from
which :func:`check_options`, ``hybrid-force laws --options`` and the law's defaults all derive.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from hybrid_force._jit import entry
from hybrid_force.control.constraint import Constraint
from hybrid_force.errors import ControlError, did_you_mean
from hybrid_force.schema import check_fields, specs

if TYPE_CHECKING:  # annotations only (the laws' modules import this one)
    from collections.abc import Sequence

    from hybrid_force.control.constraint import ConstraintTerms
    from hybrid_force.geometry.surface_base import Surface
    from hybrid_force.model.robot import Robot, RobotTerms

__all__ = [
    "LAWS",
    "PAPER_GAINS",
    "Command",
    "ControlTrace",
    "Desired",
    "Gains",
    "Law",
    "LawContext",
    "LawInput",
    "LawOptions",
    "LawSettings",
    "LawSpec",
    "LoopBound",
    "LoopContext",
    "below",
    "build_law",
    "check_law",
    "check_log_source",
    "check_options",
    "law_log_names",
    "law_loop_bounds",
    "law_names",
    "law_spec",
    "register",
    "velocity_loop_bound",
]


@dataclass(frozen=True)
class Gains:
    """Gains of the paper's laws.

    Attributes:
        Kd: (n, n) symmetric positive definite damping gain K_d [N·m·s/rad …] (eq. 11, 30).
        Lambda: Λ > 0 [1/s] position-error gain (eq. 4, 29).
        beta: β ≥ 0 [(m/s)/(N·s) for the "tip" scaling] momentum-error gain (eq. 4).
        gamma: γ > 0 [1/s] force gain (eq. 11).
    """

    Kd: np.ndarray
    Lambda: float
    beta: float
    gamma: float


@dataclass(frozen=True)
class Desired:
    """Desired motion at one instant: q_d, q̇_d, q̈_d, each (n,) [rad or m, /s, /s²], and the
    task-space path it follows, p_d, ṗ_d, p̈_d, each (3,) [m, m/s, m/s²] (None when not given).

    ``pack``: when q, qd, qdd, p, pd, pdd are views of one flat array (a CLIK's, laid out as
    ``control._kernels.desired_parts``), that array, so a compiled law takes one argument
    for six (:meth:`Law.hybrid_at`); None otherwise.
    """

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    p: np.ndarray | None = None
    pd: np.ndarray | None = None
    pdd: np.ndarray | None = None
    pack: np.ndarray | None = None


@dataclass(frozen=True)
class Command:
    """Joint command u = u0 + B f (u0: (n,) [N or N·m]; B: (n, k) or None when u ignores f).

    Made C-contiguous, writeable float64 here (the same arrays when they are, as a law's
    buffers are): the plant's and the record's kernels are bound for those types
    (:func:`hybrid_force._jit.entry`), so any law's command reaches them so.

    Raises:
        ControlError: u0 is not one-dimensional or B not two-dimensional.
    """

    u0: np.ndarray
    B: np.ndarray | None

    def __post_init__(self) -> None:
        u0 = np.require(self.u0, dtype=float, requirements=("C", "W"))
        if u0.ndim != 1:
            raise ControlError(f"a command's u0 must be an (n,) array, got shape {u0.shape}")
        object.__setattr__(self, "u0", u0)
        if self.B is not None:
            B = np.require(self.B, dtype=float, requirements=("C", "W"))
            if B.ndim != 2:
                raise ControlError(f"a command's B must be an (n, k) array, got shape {B.shape}")
            object.__setattr__(self, "B", B)


@dataclass(frozen=True)
class ControlTrace:
    """What a law computed at one step (for logging and tests).

    e_q (n,), s (n,), s0 (n,), s1 (n,), e_F (k,) [N·s], qdot_r (n,), qddot_r0 (n,) = q̈_r at f = 0,
    qddot_r_f (n, k) with q̈_r = qddot_r0 + qddot_r_f f, V [J] (section 5.1), f_d (k,) [N].
    """

    e_q: np.ndarray
    s: np.ndarray
    s0: np.ndarray
    s1: np.ndarray
    e_F: np.ndarray
    qdot_r: np.ndarray
    qddot_r0: np.ndarray
    qddot_r_f: np.ndarray | None
    V: float
    f_d: np.ndarray


class LawSettings(Protocol):
    """What a law reads of the control settings
    (:class:`~hybrid_force.control.supervisor.ControlSettings` has these fields)."""

    @property
    def law(self) -> str: ...
    @property
    def options(self) -> Mapping[str, Mapping[str, Any]]: ...
    @property
    def Lambda(self) -> float: ...
    @property
    def beta(self) -> float: ...
    @property
    def gamma(self) -> float: ...
    @property
    def approach_rate(self) -> float | None: ...
    @property
    def Kd(self) -> float | np.ndarray | None: ...
    @property
    def kd_rate(self) -> float: ...
    @property
    def mass_factor(self) -> float: ...


@dataclass
class LawInput:
    """One step's input to a law, filled by the supervisor (the same object every step: its
    arrays are the supervisor's and the next step may overwrite them).

    Attributes:
        robot: the controller's model terms at the measured (q, v) (M, C, g scaled by
            ``control.mass_factor``).
        v: (n,) joint velocity [rad/s or m/s]. e_q: (n,) q − q_d [rad or m].
        desired: q_d, q̇_d, q̈_d (n,) and p_d, ṗ_d, p̈_d (3,) [m, m/s, m/s²] now.
        cons: the constraint rows at (q, v) (A (k, n), its normal, distance, Q, …): set near
            and on the surface (:meth:`Law.hybrid`); None in free space.
        e_F: (k,) momentum error F − F_d [N·s] (eq. 3); 0 outside contact.
        f_d: (k,) desired force [N]; 0 in the near phase.
        approach: (k,) normal reference velocity [m/s per row scaling] of the near phase,
            which brings the tool onto the surface slowly; None in contact.
        steady: (n + 4k,) in the supervisor's steady contact step (:meth:`Law.hybrid_at`),
            the flat array whose views e_q, e_F and f_d are, then the supervisor's momenta F,
            F_d (``control._kernels.steady_parts``),
            so a compiled law takes one argument for three; None otherwise.
    """

    robot: RobotTerms
    v: np.ndarray
    e_q: np.ndarray
    desired: Desired
    cons: ConstraintTerms | None = None
    e_F: np.ndarray = field(default_factory=lambda: np.zeros(0))
    f_d: np.ndarray = field(default_factory=lambda: np.zeros(0))
    approach: np.ndarray | None = None
    steady: np.ndarray | None = None

    @property
    def rows(self) -> ConstraintTerms:
        """:attr:`cons`, which :meth:`Law.hybrid` is always given."""
        assert self.cons is not None, "the hybrid law runs with the constraint rows"
        return self.cons


class Carver:
    """Consecutive views of one flat buffer from ``start`` on: a law's own arrays, which its
    steady contact kernel takes as one argument (Numba's call costs about 0.1 µs per array);
    the kernel slices the buffer in the same order."""

    def __init__(self, buffer: np.ndarray, start: int) -> None:
        self.buffer, self.offset = buffer, start

    def take(self, *shape: int) -> np.ndarray:
        """The next view, of ``shape``."""
        size = math.prod(shape)
        view = self.buffer[self.offset : self.offset + size].reshape(shape)
        self.offset += size
        return view

    def done(self) -> None:
        """Check that the views fill the buffer (its size and the kernel's layout agree)."""
        if self.offset != self.buffer.shape[0]:
            raise AssertionError(f"views end at {self.offset} of {self.buffer.shape[0]}")


class Law:
    """A control law as the supervisor runs it (see the module docstring): a law defines
    :meth:`free_space` and :meth:`hybrid`; the other parts have their defaults here.

    Attributes:
        V: the law's Lyapunov function (or NaN when it has none) at the last call [J].
    """

    V: float = math.nan
    #: the steady contact kernel of :meth:`hybrid_at`, bound at its first call for its
    #: arguments' types (:func:`hybrid_force._jit.entry`); None until then
    _steady_kernel: Callable[..., Any] | None = None

    def _entry(
        self, key: object, kernel: Callable[..., Any], args: tuple[Any, ...]
    ) -> Callable[..., Any]:
        """``kernel`` bound for the types of ``args`` (:func:`hybrid_force._jit.entry`) the
        first time ``key`` is asked for, then the same: one key per call site and phase (the
        phases' arrays may differ in layout: a pass's own array seen as (1, n, p) is
        Fortran-ordered, free space's (0, n, p) buffer is not)."""
        entries: dict[object, Callable[..., Any]] | None = self.__dict__.get("_entries")
        if entries is None:
            entries = self.__dict__["_entries"] = {}
        bound = entries.get(key)
        if bound is None:
            bound = entries[key] = entry(kernel, *args)
        return bound

    def free_space(self, inp: LawInput) -> Command:
        """Torques away from the surface: track q_d (or p_d); ``inp.cons`` is None."""
        raise NotImplementedError

    def hybrid(self, inp: LawInput) -> Command:
        """Torques near and on the surface: track the path along it and f_d across it."""
        raise NotImplementedError

    def hybrid_at(self, inp: LawInput, q: np.ndarray) -> Command:
        """:meth:`hybrid` at the measured q (nq,) of a Euclidean arm, with inp.e_q (n,) the
        array to write e_q = q − q_d (= inp.desired.q) into first (the supervisor's contact
        step: inp.approach is None, and inp.steady and inp.desired.pack are set when the
        arrays are views of them). A law may form e_q inside its own compiled call, on those
        packs; by default numpy does."""
        np.subtract(q, inp.desired.q, out=inp.e_q)
        return self.hybrid(inp)

    def update(self, dt: float, f: np.ndarray) -> None:
        """Advance the law's own states over dt [s] with the measured force f (k,) [N]
        (nothing to advance by default: the force integral e_F is the supervisor's)."""

    def trace(self, e_q: np.ndarray, e_F: np.ndarray, f_d: np.ndarray) -> ControlTrace | None:
        """What the last call computed, for logs and tests (None: the law keeps none)."""
        return None

    def info(self) -> dict[str, Any]:
        """The law's gains and settings as JSON-able data (stored in the result's meta)."""
        return {}

    def log_names(self) -> tuple[str, ...]:
        """The m signals of the law's own that a run records at every sample (its parameter
        estimates, say), fixed when the law is built; stored as ``Result.law_log`` (N, m)
        (:mod:`hybrid_force.law_log`). None by default."""
        return ()

    def log_source(self) -> tuple[np.ndarray, np.ndarray]:
        """Where a run reads the m signals of :meth:`log_names` at every sample: (values (p,)
        float64, index (m,) int64), signal j being ``values[index[j]]`` when the sample is
        taken. ``values`` is the law's own array, which it updates in place and never
        replaces: the run's record keeps it and gathers from it in its compiled row, without
        a call to the law per sample (:func:`check_log_source`). Nothing by default."""
        return np.zeros(0), np.zeros(0, dtype=np.int64)


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
    """

    robot: Robot
    constraint: Constraint
    settings: LawSettings
    gains: Gains
    M0: np.ndarray
    q0: np.ndarray
    dt: float

    @property
    def options(self) -> Mapping[str, Any]:
        """This law's ``[control.<law>]`` table (checked values; empty when absent)."""
        return self.settings.options.get(self.settings.law, {})


@dataclass(frozen=True)
class LawSpec:
    """A registry entry: the law's name, one line about it, its factory and its settings.

    Attributes:
        summary: one line for ``hybrid-force laws`` (with its source).
        factory: builds the law from a :class:`LawContext`.
        options: the frozen dataclass of its ``[control.<law>]`` table, one
            :func:`hybrid_force.schema.param` field per key (unit, range, choices, doc and
            default written there once); None: the law has no settings of its own.
        gains: the ``[control]`` gains the law reads (of Kd, kd_rate, Lambda, beta, gamma),
            each with the key of its own table that replaces it when given (None: none does);
            a gain not listed has no effect with this law (the loader refuses it, a run's meta
            does not record it).
        loop_bounds: the law's pre-run stability checks (``LoopContext -> list[LoopBound]``);
            None: the law has none.
        check: the checks the factory needs passed (ControlError, ControlError naming the key),
            run by :func:`check_law` before the factory and by the scenario loader alone;
            None: the law has none.
    """

    name: str
    summary: str
    factory: Callable[[LawContext], Law]
    options: type | None = None
    gains: Mapping[str, str | None] = field(default_factory=dict)
    loop_bounds: Callable[[LoopContext], list[LoopBound]] | None = None
    check: Callable[[LawContext], object] | None = None

    def reads(self, gain: str, options: Mapping[str, Any]) -> bool:
        """True when the law reads ``control.<gain>`` with its table ``options`` (the gain is
        listed in :attr:`gains` and the key of the table that replaces it is not given)."""
        if gain not in self.gains:
            return False
        replaced_by = self.gains[gain]
        return replaced_by is None or replaced_by not in options

    def describe(self) -> list[tuple[str, str]]:
        """(key, its doc with unit and default) for ``hybrid-force laws --options``."""
        if self.options is None:
            return []
        out = []
        for f, spec in specs(self.options):
            unit = f" [{spec.unit}]" if spec.unit else ""
            if spec.choices:
                unit = f" ({' or '.join(_shown(c) for c in spec.choices)})"
            default = "" if f.default is None else f"; default {_shown(f.default)}"
            out.append((f.name, f"{spec.doc}{unit}{default}"))
        return out


def _shown(value: object) -> str:
    """A default as a scenario file writes it (true/false, "text", 20)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    return f"{value:g}" if isinstance(value, float) else str(value)


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


def velocity_loop_bound(
    key: str, value: object, number: float, gain: str, where: str, defined: str = ""
) -> LoopBound:
    """The bound of a law's sampled velocity loop q̇ ← (I − T M⁻¹ G) q̇ (M the plant's, G the
    law's damping from the controller's model M_c): stable iff T·λ_max(M⁻¹ G) < 2
    (:func:`~hybrid_force.control.force_loop.velocity_loop_number`, ``number`` along the path).

    ``gain`` is G as the message writes it after M⁻¹ (" G", "(K_d + Λ M_c)"), ``defined`` what
    it is (", G = 2ζω (Jᵀ Λ_c J + M_c N)") and ``where`` :attr:`LoopContext.where`.
    """
    return LoopBound(
        key,
        value,
        number,
        2.0,
        f"the sampled velocity loop q̇ ← (I − T M⁻¹{gain}) q̇{defined} (M the plant's, M_c the "
        f"controller's; {where}) diverges unless T·λ_max(M⁻¹{gain}) < 2; here it reaches "
        f"{number:.4g} along the path",
    )


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
    settings: LawSettings
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
    checks = law_spec(context.settings.law).loop_bounds
    return [] if checks is None else checks(context)


PAPER_GAINS: Mapping[str, str | None] = {
    "Kd": None, "kd_rate": "Kd", "Lambda": None, "beta": None, "gamma": None,
}  # fmt: skip
"""The paper's gains as its laws read them: K_d (or kd_rate · M(q0) when Kd is not given),
Λ, β, γ."""

LAWS: dict[str, LawSpec] = {}
"""The registry, filled by :func:`register` in each law's module (the package
:mod:`hybrid_force.control.laws` imports every one of its law modules)."""


def register(spec: LawSpec) -> LawSpec:
    """Add a law to :data:`LAWS` (a law's module calls it once, where the law is defined)."""
    if spec.name in LAWS:
        raise ValueError(f"law {spec.name!r} is registered twice")
    LAWS[spec.name] = spec
    return spec


def law_log_names(law: object) -> tuple[str, ...]:
    """The names of the signals ``law`` logs at every sample: its ``log_names()`` when it has
    the optional hook of :class:`Law` (with ``log_source``), else none."""
    if not (
        callable(getattr(law, "log_names", None)) and callable(getattr(law, "log_source", None))
    ):
        return ()
    return tuple(str(name) for name in law.log_names())  # type: ignore[attr-defined]


def check_log_source(law: object, m: int) -> tuple[np.ndarray, np.ndarray]:
    """``law.log_source()`` (:meth:`Law.log_source`) checked for its m signals: the law's own
    values array as it is (a copy would log frozen values) and its index as int64.

    Raises:
        ControlError: values is not a 1-D C-contiguous float64 array, or the index is not m
            integers within it.
    """
    name = type(law).__name__
    values, index = law.log_source()  # type: ignore[attr-defined]
    if not (
        isinstance(values, np.ndarray)
        and values.dtype == np.float64
        and values.ndim == 1
        and values.flags.c_contiguous
    ):
        raise ControlError(
            f"{name}.log_source() must give its own 1-D C-contiguous float64 array of values "
            f"(updated in place), got {type(values).__name__} "
            f"{getattr(values, 'dtype', '')}{getattr(values, 'shape', '')}",
            key="log_source.values", value=values,
        )  # fmt: skip
    idx = np.asarray(index)
    if idx.shape != (m,) or (m and idx.dtype.kind not in "iu"):
        raise ControlError(
            f"{name}.log_source() must give an index of {m} integers (one per name of "
            f"log_names()), got {idx.dtype}{idx.shape}",
            key="log_source.index", value=index,
        )  # fmt: skip
    if m and (int(idx.min()) < 0 or int(idx.max()) >= values.size):
        raise ControlError(
            f"{name}.log_source()'s index must lie in 0..{values.size - 1} (its values' "
            f"length), got {idx.min()}..{idx.max()}",
            key="log_source.index", value=index,
        )  # fmt: skip
    return values, np.ascontiguousarray(idx, dtype=np.int64)


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
    """Check ``{law: {key: value}}`` against each law's settings dataclass
    (:attr:`LawSpec.options`), key by key in the table's order.

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
        fields = {} if spec.options is None else {f.name for f, _ in specs(spec.options)}
        for key, value in table.items():
            if key not in fields:
                where = f"control.{law}.{key}"
                valid = ", ".join(fields) or "(none: this law has no settings of its own)"
                raise ControlError(
                    f"{where} is not a setting of law {law!r}{did_you_mean(str(key), fields)}"
                    f"; valid: {valid}",
                    key=where,
                    value=value,
                )
        checked = spec.options(**table) if spec.options is not None else None
        out[law] = {key: getattr(checked, key) for key in table}
    return out


@dataclass(frozen=True)
class LawOptions:
    """Base of a law's settings dataclass (:attr:`LawSpec.options`): every field is checked
    by its declaration (:func:`~hybrid_force.schema.check_fields`), numbers stored as floats;
    a field whose default is None (derived from another setting) may stay None.

    Attributes:
        law: (class) the law's name, for the messages (``control.<law>.<key>``).
    """

    law: ClassVar[str] = ""

    def __post_init__(self) -> None:
        """Check each field (ControlError naming ``control.<law>.<key>``)."""
        check_fields(self, ControlError, f"control.{self.law}.")


def check_law(context: LawContext) -> None:
    """The checks of the law named by ``context.settings.law`` (its :attr:`LawSpec.check`),
    without building it (ControlError if the law is unknown)."""
    check = law_spec(context.settings.law).check
    if check is not None:
        check(context)


def build_law(context: LawContext) -> Law:
    """Build the law named by ``context.settings.law``, its checks passed first (ControlError
    if it is unknown)."""
    check_law(context)
    return law_spec(context.settings.law).factory(context)

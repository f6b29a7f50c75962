"""The paper's modified Arimoto law with its model part adapted online (Slotine & Li 1987).

The paper ends (section 7) noting that its law "can be easily transformed to adaptive case by
using classical adaptive algorithm in position part". This is that law: the model terms
M q̈_r + C q̇_r + g of eq. 11 become Y(q, q̇, q̇_r, q̈_r) θ̂, linear in the estimated inertial
parameters θ̂ (:mod:`hybrid_force.model.regressor`), and θ̂ follows the gradient law of
J.-J. E. Slotine and W. Li, "On the adaptive control of robot manipulators", IJRR 6(3), 1987:

    q̇_r = Q x + β A⁺ e_F,   x = q̇_d − Λ e_q                              (eq. 4)
    q̈_r = Q̇ x + Q ẋ + β Ȧ⁺ e_F + β A⁺ (f − f_d),   s = q̇ − q̇_r             (eq. 8)
    u    = Y θ̂ − K_d s − Aᵀ (f_d − γ e_F)                                 (eq. 11, adapted)
         = [Y₀ θ̂ − K_d s − Aᵀ(f_d − γ e_F)] + (β M̂ A⁺) f  =  u0 + B f
    θ̂̇   = −Γ Yᵀ s                                                          (Slotine–Li)

with Y₀ = Y(q, q̇, q̇_r, q̈_r at f = 0) and M̂ = M(q; θ̂) the mass matrix of the estimates, so the
algebraic loop in f is kept exactly as in the paper's law (:mod:`~.arimoto`). Away from the surface
the free-space law (eq. 29–30) is adapted the same way (Q = I, no force terms).

Closed loop (rigid contact, A q̇ = 0): with θ̃ = θ̂ − θ and Y θ = M q̈_r + C q̇_r + g,
M ṡ + C s + K_d s = Y θ̃ + Aᵀ(ė_F + γ e_F). With

    V = ½ sᵀ M s + ½ β e_Fᵀ e_F + ½ θ̃ᵀ Γ⁻¹ θ̃,

Ṁ − 2C skew and A s = −β e_F give V̇ = −sᵀK_d s − βγ|e_F|² + θ̃ᵀ(Yᵀ s + Γ⁻¹ θ̂̇), and the
adaptation cancels the last term: V̇ = −sᵀK_d s − βγ|e_F|² ≤ 0 for a constant Γ (and less with
the schedule below), so s, e_F → 0 (Barbalat) and the estimates stay bounded, whatever the
initial model error. The estimates need not converge to the plant's values (only the
combinations the path excites do).

Which parameters adapt: those the joint torques depend on (the visible columns of Y,
:func:`~hybrid_force.model.regressor.visible_columns`); the others keep the model's value (no
measurement can tell them). θ̂(0) is the controller's model, the plant's parameters ×
``control.mass_factor`` (``sim.model_mass_factor``). The masses are kept ≥ 1 % of the model's:
with Γ diagonal, clipping one coordinate is the projection onto {m ≥ m_min} in the Γ⁻¹ metric
of V, so it never increases V's parameter term while the plant's mass is above the floor.
Physical consistency of the inertias (pseudo-inertia ⪰ 0) is not enforced.

Default gain (scales with the arm): Γ₀,ii = ρ / E[Y_iᵀ K_d⁻¹ Y_i], the expectation over the
regressor at random states near q0 with unit velocities and accelerations
(:func:`~hybrid_force.model.regressor.sample_regressors`). Why: with s quasi-static
(s ≈ K_d⁻¹ Y θ̃, valid while adaptation is slower than K_d's rate κ), θ̃_i alone decays as
θ̃̇_i = −Γ_ii Y_iᵀ K_d⁻¹ Y_i θ̃_i, i.e. at the rate ρ [1/s] (``[control.arimoto_adaptive]
adaptation_rate``), for every arm and every parameter unit.

Gain schedule: Γ(t) = σ(t) Γ₀. Γ₀ is normalised for unit velocities and accelerations; a large
tracking error drives the reference far beyond them. At the start of section 6.3 (3 m below the
helix, Λ = 10 1/s) q̇_r ≈ 30 m/s and the accelerations reach ~10³ m/s², so ‖Y‖² is ~10⁵ times
the reference's and Γ₀ would adapt ~10⁵ times faster than ρ: the explicit update diverges
early in the transient, and even in continuous time V lets the transient's ~18 kJ of ½sᵀMs move
the estimates by up to √(2 Γ₀ V) ~ 10³ kg. Hence σ(t) = min(1, Z_ref / min_{τ≤t} Z(τ)), with
Z = ½ wᵀ M w the energy of the error-driven part of the reference, w = q̇_r − q̇_d, and
Z_ref = ½ tr M(q0) / Λ²
(w of 1/Λ per joint: error-driven accelerations Λ w of unit size, what Γ₀ is normalised for).
‖Y‖² grows like Z in such a transient, so σ keeps the adaptation's rate near ρ; and σ never
decreases, so Γ(t)⁻¹ never increases and V below (with Γ(t)) stays non-increasing:
½ θ̃ᵀ (dΓ⁻¹/dt) θ̃ ≤ 0 only adds to V̇. A task that starts on its path has σ = 1 throughout.

V reported (:attr:`AdaptiveArimotoWorkspace.V`): ½ sᵀ M̂ s + ½ β e_Fᵀ e_F, the part the controller
can evaluate; the parameter term needs the plant's θ (the tests add it).

:class:`AdaptiveArimotoWorkspace` calls Pinocchio between compiled kernels
(:mod:`hybrid_force.control.laws._arimoto_adaptive_kernels`: Y from two regressor passes
instead of three, ½ sᵀ M̂ s from the kinetic energy regressor, into preallocated buffers);
``tests/test_arimoto_adaptive_kernel.py`` holds it to the readable numpy law of
``tests/oracles/laws.py``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pinocchio as pin

from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.control.constraint import ConstraintTerms
from hybrid_force.control.laws import base
from hybrid_force.control.laws.arimoto import free_space_rows, loop_bounds
from hybrid_force.model.regressor import (
    PARAMETER_LABELS,
    SlotineLiRegressor,
    dynamic_parameters,
    parameter_names,
    sample_regressors,
    visible_columns,
)
from hybrid_force.model.robot import Robot
from hybrid_force.schema import param

_K = LazyKernels("hybrid_force.control.laws._arimoto_adaptive_kernels")

__all__ = [
    "DEFAULT_ADAPTATION_RATE",
    "MASS_FLOOR",
    "Adaptation",
    "AdaptiveArimotoOptions",
    "AdaptiveArimotoWorkspace",
    "build",
    "make_adaptation",
]

#: ρ [1/s] of the default Γ (module docstring).
DEFAULT_ADAPTATION_RATE = 5.0
#: Smallest estimated mass, as a fraction of the model's.
MASS_FLOOR = 0.01
_MASS = PARAMETER_LABELS.index("m")
_SIGMA = 5  # σ's place in the compiled law's parameters (_arimoto_adaptive_kernels.SIGMA)


_AdaptiveRows = tuple[
    ConstraintTerms, np.ndarray, np.ndarray, np.ndarray,
    tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
]  # fmt: skip
"""What one call of the law reads besides its input: the constraint terms, e_F, f_d, the
approach speeds (k,), and the buffers it writes (matrices (2, n, k), Y_A (k, n, p), B (n, k),
gradients (1 + k, p)); k = 0 in free space."""


@dataclass(frozen=True)
class Adaptation:
    """What the adaptation starts from, fixed when the law is built.

    Attributes:
        theta0: (p,) θ̂(0): the controller's model's parameters [kg, kg·m, kg·m²].
        adapted: (p,) bool, the parameters that adapt (the visible ones).
        Gamma: (p,) the diagonal of Γ₀ [parameter unit² / J], 0 where not adapted.
        floor: (p,) each estimate's lower bound (the masses' floor, −inf elsewhere).
        names: (p,) ``"<link>.<label>"``.
        rate: ρ [1/s] of Γ₀.
        energy: Z_ref [J] of the gain schedule, ½ tr M(q0) / Λ².
    """

    theta0: np.ndarray
    adapted: np.ndarray
    Gamma: np.ndarray
    floor: np.ndarray
    names: tuple[str, ...]
    rate: float
    energy: float


def make_adaptation(
    robot: Robot, q0: np.ndarray, M0: np.ndarray, gains: base.Gains, mass_factor: float, rate: float
) -> Adaptation:
    """The adaptation of ``robot`` (the controller's model) started at q0 (module docstring).

    Args:
        robot: the controller's model of the arm; θ̂(0) = its parameters × mass_factor.
        q0: (nq,) the start configuration. M0: (n, n) the controller's M(q0).
        gains: the law's gains (K_d and Λ set Γ₀ and Z_ref).
        rate: ρ [1/s]: each parameter's own decay rate, Γ₀,ii = ρ / E[Y_iᵀ K_d⁻¹ Y_i].
    """
    regressor = SlotineLiRegressor(robot.model)
    theta0 = dynamic_parameters(robot.model) * mass_factor
    samples = sample_regressors(regressor, q0)
    adapted = visible_columns(samples)
    # E[Y_iᵀ K_d⁻¹ Y_i], the diagonal of E[Yᵀ K_d⁻¹ Y]
    weight = np.einsum("snp,nm,smp->p", samples, np.linalg.inv(gains.Kd), samples) / len(samples)
    Gamma = np.zeros_like(theta0)
    Gamma[adapted] = rate / weight[adapted]
    floor = np.full_like(theta0, -np.inf)
    masses = np.arange(_MASS, theta0.size, len(PARAMETER_LABELS))
    floor[masses] = np.where(adapted[masses], MASS_FLOOR * theta0[masses], -np.inf)
    return Adaptation(
        theta0=theta0,
        adapted=adapted,
        Gamma=Gamma,
        floor=floor,
        names=parameter_names(robot.model),
        rate=rate,
        energy=0.5 * float(np.trace(M0)) / gains.Lambda**2,
    )


@dataclass(frozen=True)
class AdaptiveArimotoOptions(base.LawOptions):
    """The ``[control.arimoto_adaptive]`` table."""

    law: ClassVar[str] = "arimoto_adaptive"

    adaptation_rate: float = param(
        DEFAULT_ADAPTATION_RATE, unit="1/s", minimum=0.0, strict=True,
        doc="ρ of the default Γ_ii = ρ / E[Y_iᵀ K_d⁻¹ Y_i]: the rate at which one parameter's "
        "error alone decays, for any arm",
    )  # fmt: skip


class AdaptiveArimotoWorkspace(base.Law):
    """The adaptive law as the supervisor runs it compiled: per step the four Pinocchio passes
    the law needs (three in free space) between two compiled calls, and one compiled update,
    all writing into arrays preallocated here.

    Per call: :func:`~._arimoto_adaptive_kernels.reference_velocities` (the paper's reference:
    q̇_r, q̈_r0, s, s0, s1, and the passes' inputs); Pinocchio's joint-torque regressor twice for
    Y (the two-pass polarisation of that module's docstring, not the oracle's three), once
    per constraint row for Y_M(q, A⁺_j), and its kinetic energy regressor at s for ½ sᵀ M̂ s;
    then :func:`~._arimoto_adaptive_kernels.adaptive_command` (Y θ̂ − K_d s − force, β M̂ A⁺,
    Yᵀ s, the schedule, V). :meth:`update` is
    :func:`~._arimoto_adaptive_kernels.adaptive_update`. The command returned and
    the buffers are overwritten at every call: copy to keep.

    Args:
        robot: the controller's model of the arm (its kinematics and parameter layout).
        k: the number of constraint rows.
        gains: K_d, Λ, β, γ of the paper's law.
        adaptation: θ̂(0), Γ and which parameters adapt (:func:`make_adaptation`).

    Attributes:
        theta: (p,) θ̂ (updated in place by :meth:`update`).
        sigma: σ of the gain schedule at the last call. V: [J] at the last call.
        u0: (n,), B: (n, k) of the last command. in_contact_law: True after :meth:`hybrid`.
    """

    # the kernels of hybrid_at (after the passes) and update, each bound at its first call
    # (hybrid_force._jit.entry; hybrid_at's first: Law._steady_kernel)
    _command_steady: Callable[..., float] | None = None
    _update_steady: Callable[..., None] | None = None

    def __init__(self, robot: Robot, k: int, gains: base.Gains, adaptation: Adaptation) -> None:
        self.gains = gains
        self.adaptation = adaptation
        self.regressor = regressor = SlotineLiRegressor(robot.model)
        self.V = 0.0
        self._model = robot.model
        self._euclidean = robot.euclidean
        self._adapted = np.flatnonzero(adaptation.adapted)
        n, p = robot.nv, regressor.size
        # the law's own arrays as views of one flat buffer (_arimoto_adaptive_kernels.
        # workspace_parts), which the steady contact step's kernels take as one argument:
        # the parameters (the kernels' layout LAMBDA … Z_MIN: Λ, β, γ, 1.0 when q = q_d + e_q,
        # Z_ref, then the schedule's σ and min Z, σ = 0 before the first call); the vectors
        # u0, s, s0, s1, q̇_r, q̈_r0, (q̇ + q̇_r)/2, s/2; the matrices β M A⁺ of the model
        # (unused) and q̈_r,f; B; the gradients Yᵀ s, then β Y_M(q, A⁺_j)ᵀ s; θ̂, Γ₀, floor;
        # K_d; zeros (k,); the passes' q
        self._ws = ws = np.zeros(_K.workspace_size(n, robot.nq, k, p))
        ws[0], ws[1], ws[2] = k, p, robot.nq
        (
            self._params, self._vectors, self._matrices, self.B, self._gradients, self.theta,
            self._Gamma, self._floor, Kd, self._zeros_k, self._q,
        ) = _K.workspace_parts(ws, n)  # fmt: skip
        self._params[:] = [
            gains.Lambda, gains.beta, gains.gamma, float(robot.euclidean), adaptation.energy,
            0.0, np.inf,
        ]  # fmt: skip
        self.theta[:] = adaptation.theta0
        self._Gamma[:], self._floor[:], Kd[:] = adaptation.Gamma, adaptation.floor, gains.Kd
        self._n = n
        self.u0 = self._vectors[0]
        self._s, self._qddot_r0 = self._vectors[1], self._vectors[5]
        self._free_matrices = np.zeros((2, n, 0))
        self._free_B = np.zeros((n, 0))
        self._Y_A = np.zeros((k, n, p))
        self._free_Y_A = np.zeros((0, n, p))
        self._free_gradients = np.zeros((1, p))
        self._no_force = np.zeros(0)
        # the buffers each law writes (matrices, Y_A, B, gradients), and the free-space law's
        # inputs besides its LawInput (_AdaptiveRows)
        self._hybrid_buffers = (self._matrices, self._Y_A, self.B, self._gradients)
        self._free_rows: _AdaptiveRows = (
            free_space_rows(n), self._no_force, self._no_force, self._no_force,
            (self._free_matrices, self._free_Y_A, self._free_B, self._free_gradients),
        )  # fmt: skip
        self._hybrid = base.Command(u0=self.u0, B=self.B if gains.beta > 0 else None)
        self._free = base.Command(u0=self.u0, B=None)
        self.in_contact_law = False
        self._called = False
        # one Data for all the passes (the model with gravity and its copy without have the
        # same structure; each pass sets what it reads): less memory touched per step
        self._pin_args = (
            regressor.model, regressor.data, regressor.model0, pin.computeJointTorqueRegressor,
            regressor.zeros, self._vectors[6], self._vectors[7], self._qddot_r0, self._s,
            gains.beta > 0,
        )  # fmt: skip

    @property
    def sigma(self) -> float:
        """σ of the gain schedule Γ = σ Γ₀ at the last call (non-decreasing, ≤ 1)."""
        return float(self._params[_SIGMA])

    def free_space(self, inp: base.LawInput) -> base.Command:
        """Eq. 29–30 adapted: u = Y(q, q̇, q̇_r, q̈_r) θ̂ − K_d s, q̇_r = q̇_d − Λ e_q."""
        self.V = self._run(inp, *self._free_rows)
        self.in_contact_law = False
        return self._free

    def hybrid(self, inp: base.LawInput) -> base.Command:
        """Eq. 4, 8, 11 adapted (module docstring): q̇_r, q̈_r (at f = 0) and s are the paper's
        law's own."""
        approach = self._zeros_k if inp.approach is None else inp.approach
        self.V = self._run(inp, inp.rows, inp.e_F, inp.f_d, approach, self._hybrid_buffers)
        self.in_contact_law = True
        return self._hybrid

    def hybrid_at(self, inp: base.LawInput, q: np.ndarray) -> base.Command:
        """:meth:`hybrid` at the measured q of a Euclidean arm (:meth:`Law.hybrid_at`): on
        the supervisor's, the CLIK's, the terms' and this law's packs, the two compiled calls
        take 6 and 9 arguments instead of 16 and 15 (the same operations)."""
        steady, pack, cons = inp.steady, inp.desired.pack, inp.rows
        r_packs, flat = inp.robot._packs, cons._flat
        if steady is None or pack is None or r_packs is None or flat is None:
            return super().hybrid_at(inp, q)
        ws, v = self._ws, inp.v
        # the three steady kernels, each bound at its first call for its arguments' types
        # (hybrid_force._jit.entry): the packs, the state, the passes' results
        reference = self._steady_kernel
        if reference is None:
            reference = self._steady_kernel = entry(
                _K.reference_steady, q, v, flat, pack, steady, ws
            )
        reference(q, v, flat, pack, steady, ws)
        model, data, model0, regress, zeros, w_plus, w_minus, qddot_r0, s, beta = self._pin_args
        q = self._q
        Y_plus = regress(model, data, q, w_plus, qddot_r0)
        Y_minus = regress(model0, data, q, w_minus, zeros)
        Y_A = self._Y_A
        if beta:
            if Y_A.shape[0] == 1:  # the pass's own array, seen as (1, n, p): no copy
                Y_A = regress(model0, data, q, zeros, cons.A_pinv[:, 0])[None]
            else:
                Ap = cons.A_pinv
                for j in range(Y_A.shape[0]):
                    Y_A[j] = regress(model0, data, q, zeros, Ap[:, j])
        kinetic = pin.computeKineticEnergyRegressor(model0, data, q, s)
        self._called = self.in_contact_law = True
        mats = r_packs[0]
        command = self._command_steady
        if command is None:
            command = self._command_steady = entry(
                _K.command_steady, Y_plus, Y_minus, Y_A, kinetic, mats, flat, pack, steady, ws
            )
        self.V = command(Y_plus, Y_minus, Y_A, kinetic, mats, flat, pack, steady, ws)
        return self._hybrid

    def _run(
        self,
        inp: base.LawInput,
        cons: ConstraintTerms,
        e_F: np.ndarray,
        f_d: np.ndarray,
        approach: np.ndarray,
        buffers: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    ) -> float:
        """One call of the law with the inputs and buffers of :data:`_AdaptiveRows`, returning V
        (k = 0: :meth:`free_space`)."""
        matrices, Y_A, B, gradients = buffers
        desired, e_q, q = inp.desired, inp.e_q, self._q
        if not self._euclidean:
            q[:] = pin.integrate(self._model, desired.q, e_q)
        vectors, params = self._vectors, self._params
        args = (
            cons.Q, cons.Qdot, cons.A_pinv, cons.A_pinv_dot, inp.v, e_q, desired.q, desired.qd,
            desired.qdd, e_F, f_d, approach, params, vectors, matrices, q,
        )  # fmt: skip
        free = buffers is not self._hybrid_buffers  # one entry per law (their layouts differ)
        self._entry((free, "reference"), _K.reference_velocities, args)(*args)
        model, data, model0, regress, zeros, w_plus, w_minus, qddot_r0, s, beta = self._pin_args
        Y_plus = regress(model, data, q, w_plus, qddot_r0)
        Y_minus = regress(model0, data, q, w_minus, zeros)
        if beta:
            k = Y_A.shape[0]
            if k == 1:  # the pass's own array, seen as (1, n, p): no copy
                Y_A = regress(model0, data, q, zeros, cons.A_pinv[:, 0])[None]
            else:
                Ap = cons.A_pinv
                for j in range(k):
                    Y_A[j] = regress(model0, data, q, zeros, Ap[:, j])
        kinetic = pin.computeKineticEnergyRegressor(model0, data, q, s)
        self._called = True
        c_args = (
            Y_plus, Y_minus, Y_A, kinetic, self.theta, self.gains.Kd, inp.robot.M, cons.A,
            desired.qd, e_F, f_d, params, vectors, B, gradients,
        )  # fmt: skip
        command: float = self._entry((free, "command"), _K.adaptive_command, c_args)(*c_args)
        return command

    def update(self, dt: float, f: np.ndarray) -> None:
        """θ̂ += dt · (−σ Γ₀ Yᵀ s) at the force f (k,) [N] met, then the masses' floor, as
        after the projection of the module docstring (f is not used after the free-space
        law)."""
        if not self._called:
            return
        if self.in_contact_law:  # the gradients in the law's buffer: one argument
            update = self._update_steady
            if update is None:
                update = self._update_steady = entry(
                    _K.update_steady, self._ws, self._n, f, float(dt)
                )
            update(self._ws, self._n, f, dt)
        else:
            args = (
                self._free_gradients, self._no_force, float(dt), self._params, self._Gamma,
                self._floor, self.theta,
            )  # fmt: skip
            self._entry("update", _K.adaptive_update, args)(*args)

    def trace(self, e_q: np.ndarray, e_F: np.ndarray, f_d: np.ndarray) -> base.ControlTrace:
        """The :class:`ControlTrace` of the last call (copies of the buffers), V = ½ sᵀ M̂ s
        + ½ β e_Fᵀ e_F without the parameter term."""
        contact = self.in_contact_law
        _, s, s0, s1, qdot_r, qddot_r0 = self._vectors[:6]
        return base.ControlTrace(
            e_q=e_q.copy(),
            s=s.copy(),
            s0=s0.copy(),
            s1=s1.copy(),
            e_F=e_F.copy() if contact else np.zeros(0),
            qdot_r=qdot_r.copy(),
            qddot_r0=qddot_r0.copy(),
            qddot_r_f=self._matrices[1].copy() if contact else None,
            V=self.V,
            f_d=f_d.copy() if contact else np.zeros(0),
        )

    def info(self) -> dict[str, object]:
        """K_d, Λ, β, γ, ρ, Z_ref and the adapted parameters with their θ̂(0) and Γ₀,ii."""
        g, a, i = self.gains, self.adaptation, self._adapted
        return {
            "Kd": g.Kd.tolist(),
            "Lambda": g.Lambda,
            "beta": g.beta,
            "gamma": g.gamma,
            "adaptation_rate": a.rate,
            "schedule_energy": a.energy,
            "adapted": [a.names[j] for j in i],
            "theta0": a.theta0[i].tolist(),
            "Gamma0": a.Gamma[i].tolist(),
        }

    def log_names(self) -> tuple[str, ...]:
        """The estimates this law logs at every sample: the adapted parameters' names."""
        return tuple(self.adaptation.names[j] for j in self._adapted)

    def log_source(self) -> tuple[np.ndarray, np.ndarray]:
        """The adapted estimates: θ̂ (p,) [kg, kg·m, kg·m²], updated in place by
        :meth:`update`, at the adapted columns (m,)."""
        return self.theta, self._adapted


def build(context: base.LawContext) -> AdaptiveArimotoWorkspace:
    """The registry's factory of ``control.law = "arimoto_adaptive"``."""
    rate = AdaptiveArimotoOptions(**context.options).adaptation_rate
    adaptation = make_adaptation(
        context.robot, context.q0, context.M0, context.gains, context.settings.mass_factor, rate
    )
    return AdaptiveArimotoWorkspace(context.robot, context.constraint.k, context.gains, adaptation)


base.register(
    base.LawSpec(
        "arimoto_adaptive",
        "the paper's law with Slotine-Li adaptation of its model terms (Slotine & Li, IJRR "
        "6(3) 1987; paper section 7)",
        build,
        AdaptiveArimotoOptions,
        gains=base.PAPER_GAINS,
        loop_bounds=loop_bounds,
    )
)

"""Operational-space hybrid motion/force control (Khatib 1987) as a plug-in law.

Source: O. Khatib, "A unified approach for motion and force control of robot manipulators:
the operational space formulation", IEEE J. Robotics and Automation 3(1), 43–53, 1987,
cited below by the subject of its sections: [EoM] the end-effector equations of motion,
[R] redundant manipulators, [U] the unified motion and force control.

The task is the tip position p (3,) [m] with the world-aligned Jacobian J (3, n); M, C, g are
the controller's model (:class:`~hybrid_force.model.robot.RobotTerms`). Operational space:

    Λ  = (J M⁻¹ Jᵀ)⁻¹        (3, 3) [kg]  task-space inertia                       [EoM, R]
    J̄  = M⁻¹ Jᵀ Λ            (n, 3)       dynamically consistent inverse: J J̄ = I   [R]
    N  = I − J̄ J             (n, n)       null space: J M⁻¹ Nᵀ τ₀ = 0 for every τ₀  [R]
    μ + p = J̄ᵀ(C q̇ + g) − Λ J̇ q̇           task Coriolis/centrifugal and gravity     [EoM, R]

N = 0 when n = 3 (the RTR): J is square and the null space empty. The command is [R, U]

    τ = Jᵀ F + C q̇ + g + Nᵀ τ₀,       F = Λ (a − J̇ q̇) + W φ                       (1)

which is Khatib's Jᵀ(Λ a + W φ + μ + p) + Nᵀ Γ₀ with Γ₀ = τ₀ + C q̇ + g: the null-space
part of the model's forces is compensated too (Jᵀ J̄ᵀ = I − Nᵀ), so the posture torque τ₀
below sees the arm without its Coriolis and gravity. With the exact model the plant
M q̈ + C q̇ + g = τ + Aᵀ f (A = Wᵀ J, k contact rows) gives, since J M⁻¹ Nᵀ = 0,

    p̈ = J q̈ + J̇ q̇ = a + Λ⁻¹ W (φ + f).                                             (2)

Selection [U]: the contact rows are A_i = w_iᵀ J with w_i = ∇Φ_i / s_i (the "tip" scaling:
w = n̂, the unit normal), W = [w_1 … w_k] (3, k); Khatib's selection matrices become the
projections Ω̃ = W (WᵀW)⁻¹ Wᵀ onto the normals (force) and Ω = I − Ω̃ (motion along the
surface). With e = p − p_d, ė = ṗ − ṗ_d and K_p = ω², K_v = 2ζω [U]:

    free space:  a = a_m = p̈_d − K_v ė − K_p e,     φ = 0                           (3)
    near, contact: a = Ω a_m + W (WᵀW)⁻¹ (c + x)                                     (4)

where ν = A q̇ (k,) [m/s] is the normal speed, c = Wᵀ J̇ q̇ − drift = −q̇ᵀJᵀ∇²ΦJq̇ / s the
normal acceleration that keeps it constant on the curved surface (the constraint's own
A q̈ + drift = Φ̈ / s), so that Wᵀ a = c + x means Φ̈ / s = x, and

    near:    x = K_n (ν_a − ν) − λ_a ν   (ν_a = −λ_a d the supervisor's approach speed,
                                           −λ_a ν its derivative: d̈ + (λ_a + K_n) ḋ + λ_a K_n d = 0,
                                           so the tip touches at ḋ ≈ −min(λ_a, K_n) d)
    contact: x = −K_n ν                  (the Λ-weighted damping of the normal speed [U])

and the force part [U] (Khatib's Ω̃ F_d + Λ Ω̃ F*_f with the PI F*_f written on the force
itself, so its gains are a number and a rate for every arm):

    φ = −f_d + k_I e_F + k_P (f − f_d),   e_F = ∫(f − f_d) dt (the supervisor's).     (5)

The term k_P f is the command's dependence on the force measured now: u = u0 + B f with
B = k_P Aᵀ (n, k) (None when k_P = 0). Null-space posture [R], toward the CLIK's joint path
q_d, which already lies on the task path:

    τ₀ = M (q̈_d − k_n e_q − d_n ė_q),   Nᵀ τ₀ = M N (q̈_d − k_n e_q − d_n ė_q)        (6)

(Nᵀ M = M N; the q̈_d feedforward and ė_q = q̇ − q̇_d instead of q̇ because q_d moves).

Closed loop with the exact model. Free space, from (2, 3): ë + K_v ė + K_p e = 0. On a rigid
surface Wᵀ p̈ = c − Baumgarte terms, and WᵀΩ = 0, so (2, 4, 5) give, with Σ = WᵀΛ⁻¹W,

    (1 + k_P)(f − f_d) = −k_I e_F + Σ⁻¹ K_n ν,   Ω p̈ = Ω a_m + ΩΛ⁻¹W Σ⁻¹ K_n ν,

i.e. e_F → 0 at the rate k_I / (1 + k_P) and the motion along the surface decoupled from the
force (ν = 0 on the surface). On a compliant surface of stiffness k_s the normal loop is
Λ_n s³ + Λ_n K_n s² + (1 + k_P) k_s s + k_I k_s (Λ_n = Σ⁻¹): stable iff K_n (1 + k_P) > k_I.
Sampled at a control rate T on a rigid surface, the reading of the last tick enters through
k_P: the tick-to-tick map of (f − f_d, e_F) has determinant −k_P, so k_P < 1 there
(default 0); with k_P = 0 force noise σ leaves |f − f_d| of RMS σ √(k_I T / (2 − k_I T)).

What it cannot do: it needs a tip Jacobian of full row rank (3 ≤ n and away from a singular
configuration, else SurfaceError); it has no Lyapunov function in joules
(``V`` is NaN): the decoupling of (2) is exact only with the exact model.

Runs compiled: :class:`OscHybridWorkspace`, one Numba call per step
(:mod:`hybrid_force.control.laws._osc_hybrid_kernels`) into preallocated arrays. The numpy
function :func:`task_space` (Λ and J̄, for the pre-run checks) and the numpy law of
``tests/oracles/laws.py`` are its readable forms, which the tests hold the kernel to.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.control import force_loop
from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws import base
from hybrid_force.errors import ControlError, SurfaceError
from hybrid_force.model.robot import RobotTerms
from hybrid_force.schema import param

_K = LazyKernels("hybrid_force.control.laws._osc_hybrid_kernels")

__all__ = [
    "OscGains",
    "OscHybridWorkspace",
    "OscOptions",
    "OscTrace",
    "TaskSpace",
    "build",
    "check",
    "force_gain_bounds",
    "loop_bounds",
    "osc_gains",
    "task_space",
]

_NAME = "osc_hybrid"
_COND_MAX = 1e12  # cond(J M⁻¹ Jᵀ) above this: the tip Jacobian is (nearly) rank deficient


@dataclass(frozen=True)
class OscGains:
    """Gains of the operational-space law (module docstring, eq. 3–6).

    Attributes:
        kp: K_p = ω² [1/s²]. kv: K_v = 2ζω [1/s]. kn: K_n [1/s] normal-speed gain.
        force_p: k_P [-]. force_i: k_I [1/s].
        null_kp: k_n = ω_n² [1/s²]. null_kd: d_n = 2ω_n [1/s].
        approach_rate: λ_a [1/s] of the supervisor's approach speed ν_a = −λ_a d.
    """

    kp: float
    kv: float
    kn: float
    force_p: float
    force_i: float
    null_kp: float
    null_kd: float
    approach_rate: float


@dataclass(frozen=True)
class OscOptions(base.LawOptions):
    """The ``[control.osc_hybrid]`` table. Its defaults are rates, which the law multiplies by
    Λ (or M), so they serve every arm."""

    law: ClassVar[str] = "osc_hybrid"

    omega: float = param(
        20.0, unit="rad/s", minimum=0.0, strict=True,
        doc="task-space bandwidth ω: K_p = ω², K_v = 2ζω",
    )  # fmt: skip
    zeta: float = param(
        1.0, minimum=0.0, strict=True, doc="damping ratio ζ of the task-space error (1: critical)"
    )
    normal_damping: float | None = param(
        None, unit="1/s", minimum=0.0, strict=True,
        doc="K_n: damping of the normal speed in contact, rate of the approach speed in the "
        "near phase (K_v = 2ζω when not given)",
    )  # fmt: skip
    force_p: float = param(
        0.0, minimum=0.0,
        doc="k_P: proportional force gain on f − f_d (keep it < 1 at a control rate)",
    )  # fmt: skip
    force_i: float = param(
        20.0, unit="1/s", minimum=0.0, strict=True,
        doc="k_I: integral force gain on e_F = ∫(f − f_d) dt",
    )  # fmt: skip
    null_omega: float = param(
        10.0, unit="rad/s", minimum=0.0, strict=True,
        doc="null-space posture bandwidth ω_n: k_n = ω_n², d_n = 2ω_n",
    )  # fmt: skip


def osc_gains(options: OscOptions, approach_rate: float) -> OscGains:
    """The gains of the law's settings (module docstring, eq. 3–6).

    Args:
        options: the ``[control.osc_hybrid]`` table.
        approach_rate: λ_a [1/s], the supervisor's.
    """
    omega, kv, null_omega = options.omega, 2.0 * options.zeta * options.omega, options.null_omega
    return OscGains(
        kp=omega * omega,
        kv=kv,
        kn=kv if options.normal_damping is None else options.normal_damping,
        force_p=options.force_p,
        force_i=options.force_i,
        null_kp=null_omega * null_omega,
        null_kd=2.0 * null_omega,
        approach_rate=float(approach_rate),
    )


@dataclass(frozen=True)
class TaskSpace:
    """The operational-space model at one state (module docstring, [EoM, R]).

    Attributes:
        Lambda: (3, 3) Λ = (J M⁻¹ Jᵀ)⁻¹ [kg].
        Jbar: (n, 3) J̄ = M⁻¹ Jᵀ Λ.
        J: (3, n) the tip Jacobian they were computed from.
    """

    Lambda: np.ndarray
    Jbar: np.ndarray
    J: np.ndarray

    @property
    def N(self) -> np.ndarray:
        """(n, n) the null-space projector I − J̄ J (exactly 0 when n = 3), a new array."""
        n = self.J.shape[1]
        return np.zeros((n, n)) if n == 3 else np.eye(n) - self.Jbar @ self.J

    def null(self, y: np.ndarray) -> np.ndarray:
        """N y = y − J̄ (J y) for y (n,), without forming N (0 when n = 3)."""
        if self.J.shape[1] == 3:
            return np.zeros(3)
        return y - self.Jbar @ (self.J @ y)


def task_space(M: np.ndarray, J: np.ndarray) -> TaskSpace:
    """Λ and J̄ of the mass matrix M (n, n) and the tip Jacobian J (3, n).

    Raises:
        SurfaceError: J M⁻¹ Jᵀ is (nearly) singular (the tip cannot move in
            some direction): Λ is undefined there.
    """
    Minv_Jt = np.linalg.solve(M, J.T)  # (n, 3)
    inv_Lambda = J @ Minv_Jt
    try:
        Lambda = np.linalg.inv(inv_Lambda)
        # ‖S‖_F ‖S⁻¹‖_F bounds cond₂(S) within a factor 3 for 3×3 matrices
        cond = float(np.linalg.norm(inv_Lambda) * np.linalg.norm(Lambda))
    except np.linalg.LinAlgError:  # exactly singular
        cond = math.inf
    if not cond < _COND_MAX:
        raise _singular(cond)
    return TaskSpace(Lambda=Lambda, Jbar=Minv_Jt @ Lambda, J=J)


def _singular(cond: float) -> SurfaceError:
    """The error of a (nearly) singular J M⁻¹ Jᵀ, whose cond estimate is ``cond``."""
    return SurfaceError(
        f"law {_NAME!r}: the task-space inertia (J M⁻¹ Jᵀ)⁻¹ is undefined: cond(J M⁻¹ Jᵀ) "
        f"≈ {cond:.3g} (the tip Jacobian is rank deficient: a singular configuration, or "
        "fewer than 3 joints move the tip)",
        key="control.law",
        value=_NAME,
    )


@dataclass(frozen=True)
class OscTrace:
    """What the law computed at one step (for tests and logs).

    Attributes:
        a: (3,) commanded task acceleration a of eq. 3–4 [m/s²].
        F0: (3,) task force F of eq. 1 at f = 0 [N].
        phi: (k,) force part φ at f = 0 [N] (empty in free space).
        null_torque: (n,) Nᵀ τ₀ [N·m or N].
        task: the :class:`TaskSpace` terms used.
    """

    a: np.ndarray
    F0: np.ndarray
    phi: np.ndarray
    null_torque: np.ndarray
    task: TaskSpace


def _check_desired(desired: base.Desired) -> None:
    """Refuse a Desired without the task-space path (ControlError)."""
    if desired.p is None or desired.pd is None or desired.pdd is None:
        raise ControlError(
            f"law {_NAME!r} needs the task-space path p_d, ṗ_d, p̈_d in Desired",
            key="control.law",
            value=_NAME,
        )


# the modes of the kernel (hybrid_force.control.laws._osc_hybrid_kernels: the same values)
_FREE_SPACE, _NEAR, _CONTACT = 0, 1, 2


_KernelRows = tuple[
    np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray
]  # fmt: skip
"""What one kernel call reads of the constraint and the force loop, in its order: the rows'
scale, rate A q̇ and drift (k,), A (k, n), e_F, f_d and the approach speeds (k,); zeros in
free space (the kernel reads none of them there)."""


class OscHybridWorkspace(base.Law):
    """The law (module docstring, eq. 1, 3–6) as one compiled call per step, writing into
    arrays preallocated here (hot path).

    :func:`hybrid_force.control.laws._osc_hybrid_kernels.osc_hybrid` computes Λ, J̄ and Nᵀτ₀
    by small dense factorisations and the directions W from the surfaces' closed forms,
    without allocating. Where J M⁻¹ Jᵀ is (nearly) singular, cond(J M⁻¹ Jᵀ) ≥ 1e12, it raises
    SurfaceError; where M or WᵀW is exactly singular, numpy's LinAlgError. The
    command returned and the arrays below are overwritten at every call: copy to keep.

    Args:
        gains: see :class:`OscGains`.
        constraint: the controller's surfaces (for the directions W of the rows).
        n: the number of joints (≥ 3).

    Attributes:
        V: NaN (no Lyapunov function in joules: see the module docstring).
        u0, null_torque: (n,) the command at f = 0 and Nᵀτ₀. a, F0: (3,) as in
            :class:`OscTrace`. Lambda (3, 3), Jbar (n, 3): the last :class:`TaskSpace`.
        W: (3, k) directions of the rows. phi: (k,). B: (n, k) k_P Aᵀ (contact, k_P > 0).
    """

    def __init__(self, gains: OscGains, constraint: Constraint, n: int) -> None:
        self.gains = gains
        self.constraint = constraint
        self.V = math.nan
        k = constraint.k
        descs = [surface._descriptor for surface in constraint.surfaces]
        width = max([10, *(d.shape[0] for d in descs)])
        # the law's own arrays as views of one flat buffer, which the steady contact step's
        # kernel takes whole (_osc_hybrid_kernels.osc_steady, its layout)
        self._ws = ws = np.zeros(_K.workspace_size(n, k, width))
        ws[:3] = [k, n, width]
        carver = base.Carver(ws, 3)
        take = carver.take
        self._descs = take(k, width)
        self._grads = take(3, k)
        self._gains = take(8)
        self._gains[:] = [
            gains.kp, gains.kv, gains.kn, gains.force_p, gains.force_i, gains.null_kp,
            gains.null_kd, gains.approach_rate,
        ]  # fmt: skip
        for i, d in enumerate(descs):
            if d.shape[0] == 0:  # no closed form: ∇Φ from Python, in _grads
                self._descs[i, 0] = -1.0
            else:
                self._descs[i, : d.shape[0]] = d
        self._python_surfaces = tuple(
            (i, s) for i, s in enumerate(constraint.surfaces) if s._descriptor.shape[0] == 0
        )
        self._work = take(n, n)
        self._vectors = take(2, n)
        self.u0, self.null_torque = self._vectors
        self._task = take(2, 3)
        self.a, self.F0 = self._task
        self.Lambda = take(3, 3)
        self.Jbar = take(n, 3)
        self.W = take(3, k)
        self.phi = take(k)
        self.B = take(n, k)
        self._zeros_k = take(k)
        carver.done()
        z = self._zeros_k
        self._free_rows: _KernelRows = (z, z, z, np.zeros((k, n)), z, z, z)
        self._free = base.Command(u0=self.u0, B=None)
        self._near = base.Command(u0=self.u0, B=None)
        self._contact = base.Command(u0=self.u0, B=self.B if gains.force_p > 0 else None)
        self._mode: int | None = None  # of the last call (None before the first)
        self._J: np.ndarray | None = None  # the J of the last call

    def free_space(self, inp: base.LawInput) -> base.Command:
        """Full-task motion control (eq. 3) with the null-space posture (eq. 6)."""
        self._run(inp, self._free_rows, _FREE_SPACE)
        return self._free

    def hybrid(self, inp: base.LawInput) -> base.Command:
        """Motion along the surface, force (contact) or approach speed (near) across it
        (eq. 4–6)."""
        cons, robot = inp.rows, inp.robot
        if inp.approach is None:
            mode, command, approach = _CONTACT, self._contact, self._zeros_k
        else:
            mode, command, approach = _NEAR, self._near, inp.approach
        if self._python_surfaces:
            for i, surface in self._python_surfaces:
                self._grads[:, i] = surface.evaluate(robot.p)[1]
        rows = (cons.scale, cons.rate, cons.drift, cons.A, inp.e_F, inp.f_d, approach)
        self._run(inp, rows, mode)
        return command

    def hybrid_at(self, inp: base.LawInput, q: np.ndarray) -> base.Command:
        """:meth:`hybrid` in contact at the measured q of a Euclidean arm (:meth:`Law.hybrid_at`):
        on the supervisor's, the CLIK's, the terms' and this law's packs, one compiled call of
        10 arguments instead of 30 (the same operations)."""
        steady, pack, cons, robot = inp.steady, inp.desired.pack, inp.rows, inp.robot
        r_packs, flat = robot._packs, cons._flat
        if steady is None or pack is None or r_packs is None or flat is None:
            return super().hybrid_at(inp, q)
        for i, surface in self._python_surfaces:
            self._grads[:, i] = surface.evaluate(robot.p)[1]
        mats, vecs, jac, tip = r_packs
        self._mode, self._J = _CONTACT, robot.J
        kernel = self._steady_kernel
        if kernel is None:
            kernel = self._steady_kernel = entry(
                _K.osc_steady, q, inp.v, mats, vecs, jac, tip, flat, pack, steady, self._ws
            )
        cond = kernel(q, inp.v, mats, vecs, jac, tip, flat, pack, steady, self._ws)
        if not 0.0 <= cond < _COND_MAX:
            self._refuse(cond, robot)
        return self._contact

    def _refuse(self, cond: float, robot: RobotTerms) -> None:
        """Raise for the kernel's cond (< 0: exactly singular; else beyond the bound)."""
        if cond < 0.0:  # M or WᵀW exactly singular: numpy's solve would refuse it
            raise np.linalg.LinAlgError("Singular matrix")
        task_space(robot.M, robot.J)  # the error names cond as task_space estimates it (numpy)
        raise _singular(cond)

    def _run(self, inp: base.LawInput, rows: _KernelRows, mode: int) -> None:
        """One kernel call; raises where it cannot finish (see the class docstring)."""
        scale, rate, drift, A, e_F, f_d, approach = rows
        robot, desired, v, e_q = inp.robot, inp.desired, inp.v, inp.e_q
        p_d, pd_d, pdd_d = desired.p, desired.pd, desired.pdd
        if p_d is None or pd_d is None or pdd_d is None:
            _check_desired(desired)
        packs = robot._packs
        if packs is None:
            packs = robot.packed()._packs
        mats, vecs, jac, tip = packs  # type: ignore[misc]
        self._mode = mode
        self._J = robot.J
        args = (
            mats, vecs, jac, tip, v, e_q, desired.qd, desired.qdd, p_d, pd_d, pdd_d,
            self._descs, self._grads, scale, rate, drift, A, e_F, f_d, approach, mode,
            self._gains, self._work, self._vectors, self._task, self.Lambda, self.Jbar, self.W,
            self.phi, self.B,
        )  # fmt: skip
        cond = self._entry(mode, _K.osc_hybrid, args)(*args)  # one per phase
        if cond < 0.0:  # M or WᵀW exactly singular: numpy's solve would refuse it
            raise np.linalg.LinAlgError("Singular matrix")
        if not cond < _COND_MAX:  # the error names cond as task_space estimates it (numpy)
            task_space(robot.M, robot.J)
            raise _singular(cond)

    @property
    def last(self) -> OscTrace | None:
        """The :class:`OscTrace` of the last call (copies of the buffers; None before the
        first call). Its ``task.J`` is a copy of the J the call read (robot terms are
        overwritten by the next step: read this before)."""
        if self._mode is None or self._J is None:
            return None
        free = self._mode == _FREE_SPACE
        return OscTrace(
            a=self.a.copy(),
            F0=self.F0.copy(),
            phi=np.zeros(0) if free else self.phi.copy(),
            null_torque=self.null_torque.copy(),
            task=TaskSpace(Lambda=self.Lambda.copy(), Jbar=self.Jbar.copy(), J=self._J.copy()),
        )

    def info(self) -> dict[str, Any]:
        """The gains as JSON-able data."""
        return {"law": _NAME, **vars(self.gains)}


def check(context: base.LawContext) -> None:
    """The registry's check of ``control.law = "osc_hybrid"``.

    Raises:
        ControlError: the arm has fewer than 3 joints (a 3-D tip task needs n ≥ 3).
    """
    n = context.robot.nv
    if n < 3:
        raise ControlError(
            f"law {_NAME!r} controls the 3-D tip position and needs at least 3 joints; "
            f"the arm has {n}",
            key="control.law",
            value=_NAME,
        )


def build(context: base.LawContext) -> OscHybridWorkspace:
    """The registry's factory of ``control.law = "osc_hybrid"`` (:func:`check` passed)."""
    n = context.robot.nv
    s = context.settings
    approach_rate = s.Lambda if s.approach_rate is None else s.approach_rate
    gains = osc_gains(OscOptions(**context.options), approach_rate)
    return OscHybridWorkspace(gains, context.constraint, n)


def force_gain_bounds(
    context: base.LoopContext, law: str, p_key: str, p_gain: float, i_key: str, i_gain: float
) -> list[base.LoopBound]:
    """The sampled force loop of a law whose torque holds Aᵀ(k_P f̃ + k_I e_F) (this law's
    eq. 5, Raibert–Craig's eq. 1): B = k_P A_cᵀ (A_c the controller's rows), so by
    :mod:`hybrid_force.control.force_loop` f_k = c − a f̃_k − b E_k with a = k_P ρ and
    b = k_I ρ, ρ = ρ(W⁻¹ A M⁻¹ A_cᵀ) (= 1 when the controller's rows are the plant's: a
    force term is applied as a force, whatever the controller's masses). Stable iff
    k_P ρ < a*(k_I ρ T, α, d) (:func:`~hybrid_force.control.force_loop.max_stable_loop_gain`;
    1 + k_I T/2 without filter and delay); with k_P = 0 the integral alone needs
    k_I ρ T below :func:`~hybrid_force.control.force_loop.largest_integral_step` (1).
    Empty unless the run is sampled."""
    if not context.sampled:
        return []
    qs = [context.q0, *context.configurations]
    rho = max(
        force_loop.force_feedthrough(
            context.plant_mass(q), context.rows(q), context.rows(q, context.model).T
        )
        for q in qs
    )
    T = context.period
    i_limit = force_loop.largest_integral_step(context.alpha, context.delay) / (rho * T)
    if not i_gain < i_limit:
        return [
            base.LoopBound(
                f"control.{law}.{i_key}",
                i_gain,
                i_gain,
                i_limit,
                f"the sampled force integral E_k = E_(k−1) + T f̃_(k−1) ({context.where}) "
                f"oscillates and grows for {i_key}·ρ·T >= "
                f"{force_loop.largest_integral_step(context.alpha, context.delay):.4g}: "
                f"{i_key} must stay below {base.below(i_limit)} 1/s "
                f"(ρ = ρ(W⁻¹ A M⁻¹ A_cᵀ) = {rho:.4g})",
            )
        ]
    p_limit = force_loop.max_stable_loop_gain(i_gain * rho * T, context.alpha, context.delay) / rho
    return [
        base.LoopBound(
            f"control.{law}.{p_key}",
            p_gain,
            p_gain,
            p_limit,
            f"the sampled force loop f_k = c − {p_key}·ρ f̃_k − {i_key}·ρ E_k ({context.where}) "
            f"oscillates and grows, and the tool bounces off the surface, unless {p_key} < "
            f"{base.below(p_limit)} (ρ = ρ(W⁻¹ A M⁻¹ A_cᵀ) = {rho:.4g} along the path, {i_key} = "
            f"{i_gain:g}; docs/laws.md)",
        )
    ]


def loop_bounds(context: base.LoopContext) -> list[base.LoopBound]:
    """The law's pre-run checks: the velocity loop and, sampled, the force loop.

    **Velocity loop.** From eq. 1, 3, 4, 6 the torque holds −Jᵀ Λ_c (K_v Ω + K_n Ω̃) J q̇
    − M_c N_c d_n q̇ (Λ_c, N_c of the CONTROLLER's M_c): with the plant's M, sampled at T,
    q̇_{k+1} = (I − T M⁻¹ G) q̇_k + … with G ≼ max(K_v, K_n) Jᵀ Λ_c J + d_n M_c N_c, stable iff
    T λ_max(M⁻¹ G) < 2 (:func:`~hybrid_force.control.force_loop.velocity_loop_number`); for
    M_c = m M that is T m max(K_v, K_n, d_n) < 2.

    **Force loop**: :func:`force_gain_bounds` with k_P = ``force_p``, k_I = ``force_i``.
    The law reads none of the paper's K_d, β, γ: no check of theirs applies.
    """
    options = OscOptions(**context.options_of(_NAME))
    gains = osc_gains(options, 0.0)
    qs = [context.q0, *context.configurations]
    rate = max(gains.kv, gains.kn)
    number = 0.0
    for q in qs:
        M_c = context.model_mass(q)
        task = task_space(M_c, context.model.jacobian(q))
        G = rate * task.J.T @ task.Lambda @ task.J + gains.null_kd * (M_c @ task.N)
        number = max(
            number,
            force_loop.velocity_loop_number(context.plant_mass(q), 0.5 * (G + G.T), context.period),
        )
    key, value = context.named(f"control.{_NAME}.omega", options.omega)
    gain = ", G = max(K_v, K_n) Jᵀ Λ_c J + d_n M_c N"
    bounds = [base.velocity_loop_bound(key, value, number, " G", context.where, gain)]
    return bounds + force_gain_bounds(
        context, _NAME, "force_p", gains.force_p, "force_i", gains.force_i
    )


base.register(
    base.LawSpec(
        _NAME,
        "operational-space hybrid motion/force control, dynamically consistent, with a "
        "null-space posture (Khatib 1987, IEEE J. Robot. Autom. 3(1))",
        build,
        OscOptions,
        loop_bounds=loop_bounds,
        check=check,
    )
)

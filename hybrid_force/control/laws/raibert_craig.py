"""Raibert & Craig's hybrid position/force control, as published and as corrected.

Raibert and Craig (1981, "Hybrid position/force control of manipulators", ASME J. Dyn. Sys.
Meas. Control 103(2)) split the task space with a selection matrix: position is servoed
along the surface, force across it. With the unit normals N = [n̂₁ … n̂_k] (3, k) of the k
surfaces at the tip (n̂ = ∇Φ/‖∇Φ‖),

    S = I − N (NᵀN)⁻¹ Nᵀ          (3, 3): S² = S = Sᵀ, S N = 0, rank 3 − k

and, with e = p_d − p, ė = ṗ_d − ṗ [m, m/s] and e_F = ∫(f − f_d) dt the supervisor's
momentum error (so ∫(f_d − f) dt = −e_F), the law in contact is

    u = u_ff + P u_pos + u_force
    u_force = −Aᵀ [f_d + k_p (f_d − f) − k_i e_F] − Jᵀ N D_n Nᵀ ṗ                        (1)

A = n̂ᵀJ are the constraint's rows (the "tip" scaling: f in newtons; the plant applies
Aᵀ f, so −Aᵀ f_cmd presses with f_cmd). The normal damper D_n = (ω_p + ω_d)(Nᵀ J M⁻¹ Jᵀ N)⁻¹
(the tip's inertia along the normals, from the model) is ours: it does nothing on a rigid
surface (Nᵀṗ = 0 in contact) and damps the contact spring of a compliant one. The position
part u_pos is where the two forms differ:

* ``original`` — the selected error is mapped to the joints by the inverse Jacobian (J⁻¹ for a
  square J, the pseudo-inverse J⁺ = Jᵀ(JJᵀ)⁻¹ for n > 3) and servoed by constant joint gains:

      u_pos = K_P J⁺ S e + K_D J⁺ S ė,     K_P = ω_p ω_d M(q₀),  K_D = (ω_p + ω_d) M(q₀)   (2)

* ``corrected`` — Fisher and Mujtaba (1992, "Hybrid position/force control: a correct
  formulation", IJRR 11(4)) show that the joint error J⁻¹ S e is the wrong one: the torque
  K_P J⁻¹ S e = Jᵀ (J⁻ᵀ K_P J⁻¹) S e is the tip wrench (J⁻ᵀK_PJ⁻¹) S e, whose component along
  n̂ is not zero, so the position servo pushes along the force-controlled direction. Their
  joint error (SJ)⁺ S e lies in the row space of SJ, so a scalar joint gain gives the torque
  k (SJ)⁺ S e = Jᵀ S [k (SJJᵀS)⁺] S e: a wrench S(·) with no normal component, from a
  symmetric stiffness. We keep that structure, u_pos = Jᵀ S w, with task-space gains scaled
  by the arm's Cartesian inertia Λ₀ = (J M⁻¹ Jᵀ)⁻¹ at q₀ (so that one scenario serves every
  arm, as K_d = κ M(q₀) does):

      u_pos = Jᵀ S (K_x S e + D_x S ė),    K_x = ω_p ω_d Λ₀,  D_x = (ω_p + ω_d) Λ₀          (3)

  Its stiffness Jᵀ S K_x S J and damping Jᵀ S D_x S J are symmetric positive semi-definite:
  the position loop is a spring and a damper, it can only store or dissipate energy.

Why it matters (An and Hollerbach 1989, "The role of dynamic models in Cartesian force control
of manipulators", IJRR 8(4): kinematic instability of the original for revolute arms). At q₀
the original's K_P J⁻¹ = ω_p ω_d Jᵀ Λ₀, the dynamically decoupled law; away from q₀ its
K_P J⁺ S J and K_D J⁺ S J are not symmetric. On a rigid surface the constrained motion only
feels their tangent blocks Eᵀ J⁻ᵀ K J⁻¹ E (E a tangent basis), which are symmetric: both forms
are stable there. On a compliant surface the tool vibrates on the contact spring, the joints
moving along φ = M⁻¹Aᵀ with a tip velocity Λ⁻¹n̂ that has a tangential part; the original's
damper answers it with a power φᵀ K_D J⁺ S J φ of no fixed sign, and where it is negative it
feeds the vibration, at a rate that does not fall as the surface stiffens; the corrected
damper can only drain it (:mod:`hybrid_force.studies.hybrid_stability`).

The projection P (``decouple = true``, default; false: P = I, the published forms). FM's
wrench S w exerts no static force along n̂, but it still accelerates the tip along n̂ through
the arm's inertia (n̂ᵀΛ⁻¹S w ≠ 0 unless n̂ is an eigenvector of Λ): on a rigid surface the
contact force answers that acceleration. A large tangential correction thus pulls the tool
off: at the start of scenarios/paper_contact.toml (3 m below the path) the corrected form
without P would need −35 kN of the surface and flies off. P = I − Aᵀ(A M⁻¹ Aᵀ)⁻¹ A M⁻¹ (the
model's) removes from the position feedback what would change the contact force
(A M⁻¹ P = 0); on tangent motions (A q̇ = 0) q̇ᵀ P u = q̇ᵀ u, so the tangent behaviour and its
passivity are unchanged, and the feedback no longer does work on the contact vibration (the
mode then decays at (ω_p + ω_d)/2 − λ_f/2 from D_n and the integral). Default: form
``corrected`` with P, because P is exact only with an exact model, and the corrected feedback
is passive without it: with a 5 kg tool the model lacks, the contact mode of the original with P
decays at only 7 /s 1.8 m out on the study's steep plane, the corrected's at 24 /s
(benchmarks/study_raibert_craig.py).

Feed-forward (``feedforward = "model"``, default): u_ff = M q̈_ff + C q̇ + g from the
controller's model, with the resolved acceleration q̈_ff = J⁺(p̈_d − J̇q̇) + (I − J⁺J) q̈_d;
``"gravity"``: u_ff = g only, as in 1981. The redundant directions of an arm with n > 3 are
held on the supervisor's joint path q_d by (I − J⁺J)(−K_P e_q − K_D (q̇ − q̇_d)) (part of
u_pos for P), which exerts no force at the tip.

Force loop. On a rigid surface the contact force answers the command at once:
f = f_cmd + d, where d [N] collects what the rest of u does along n̂. With (1),
(1 + k_p)(f − f_d) = d − k_i e_F and ė_F = f − f_d, so

    ė_F = −λ_f e_F + d / (1 + k_p),    λ_f = k_i / (1 + k_p)                               (4)

a first-order decay at λ_f; a constant d leaves no force error. Because f enters u directly
(k_p), the command is u = u0 + B f with B = k_p Aᵀ (n, k), solved exactly with f by the
simulator. Defaults: ω_p = Λ and ω_d = κ (control.Lambda, control.kd_rate: the paper's
poles of the position error), k_p = 0.5 and k_i = (1 + k_p) γ, so that λ_f = γ
(control.gamma). k_p < 1 because a sampled controller reads a force one tick old while a
rigid contact answers at once: the tick-to-tick map of the force is f ← −k_p f + …, which
contracts only for k_p < 1.

Phases (see :mod:`hybrid_force.control.supervisor`). Free space: S = I, where the two forms
coincide; to first order J⁺(p_d − p) = q_d − q, and the law servoes the supervisor's joint
path q_d (the inverse-kinematic image of p_d) itself, u = u_ff − K_P e_q − K_D (q̇ − q̇_d) with
q̈_ff = q̈_d, so that a large start error is closed joint by joint as the paper's free-space law
does, not along a straight task-space line that the changing inertia would bend. Near the
surface: u_ff + u_pos along it (eq. 2 or 3), and across it a torque Aᵀ w that sets, by the
model, the rows' rate r = A q̇ (= ḋ for the "tip" scaling) to ṙ = −λ_a r + ω_d (v_a − r),
v_a = −λ_a d the supervisor's approach velocity: d̈ + (λ_a + ω_d) ḋ + λ_a ω_d d = 0, and the
tool lands at ḋ ≈ −λ_a·contact_tol.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.control import force_loop
from hybrid_force.control.laws import base
from hybrid_force.control.laws.osc_hybrid import force_gain_bounds
from hybrid_force.errors import ControlError
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.schema import param

__all__ = [
    "FORMS",
    "RaibertCraigGains",
    "RaibertCraigOptions",
    "RaibertCraigWorkspace",
    "build",
    "cartesian_inertia",
    "loop_bounds",
    "make_gains",
    "pseudo_inverse",
    "selection_matrix",
]

FORMS = ("corrected", "original")
FEEDFORWARDS = ("model", "gravity")
_NAME = "raibert_craig"
_K = LazyKernels("hybrid_force.control.laws._raibert_craig_kernels")
_SINGULAR = 1e12  # cond(J M⁻¹ Jᵀ) at q₀ above this: the Cartesian inertia is undefined


def pseudo_inverse(J: np.ndarray) -> np.ndarray:
    """J⁺ = Jᵀ (J Jᵀ)⁻¹ (n, 3) of a full-rank J (3, n), n ≥ 3 (J⁻¹ for n = 3); at a singularity,
    where J Jᵀ cannot be inverted, the SVD's pseudo-inverse."""
    try:
        return J.T @ np.linalg.inv(J @ J.T)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(J)


def selection_matrix(normals: np.ndarray) -> np.ndarray:
    """S = I − N (NᵀN)⁻¹ Nᵀ: the projection onto the directions not along any normal.

    Args:
        normals: (3, k) the surfaces' unit normals at the tip, as columns (k ≥ 1, independent).

    Returns:
        (3, 3) symmetric, S² = S, S N = 0, rank 3 − k.
    """
    N = normals
    if N.shape[1] == 1:
        return np.eye(3) - N @ N.T
    return np.eye(3) - N @ np.linalg.solve(N.T @ N, N.T)


def cartesian_inertia(M: np.ndarray, J: np.ndarray) -> np.ndarray:
    """Λ = (J M⁻¹ Jᵀ)⁻¹ (3, 3) [kg]: the tip's inertia for a force at it.

    Raises:
        ControlError: J M⁻¹ Jᵀ is singular (the arm cannot move its tip along some direction).
    """
    W = J @ np.linalg.solve(M, J.T)
    cond = np.linalg.cond(W)
    if not math.isfinite(cond) or cond > _SINGULAR:
        raise ControlError(
            f"raibert_craig: the tip's Cartesian inertia (J M⁻¹ Jᵀ)⁻¹ is undefined at the start "
            f"configuration (cond = {cond:.3g}): the arm is at a singularity; start elsewhere",
            key="initial",
            value=cond,
        )
    return np.linalg.inv(0.5 * (W + W.T))


@dataclass(frozen=True)
class RaibertCraigGains:
    """Gains of the law (module docstring, eq. 1–3).

    Attributes:
        form: "corrected" (Fisher–Mujtaba) or "original" (Raibert–Craig).
        feedforward: "model" (M q̈_ff + C q̇ + g) or "gravity" (g).
        position_rate, damping_rate: ω_p, ω_d [1/s], the poles of the position error.
        Kq, Dq: (n, n) joint gains ω_p ω_d M(q₀), (ω_p + ω_d) M(q₀) of the original form and
            of the redundant directions [N·m/rad, N·m·s/rad …].
        Kx, Dx: (3, 3) task gains ω_p ω_d Λ₀, (ω_p + ω_d) Λ₀ of the corrected form [N/m, N·s/m].
        kp: proportional force gain k_p ≥ 0 [-]. ki: integral force gain k_i > 0 [1/s].
    """

    form: str
    feedforward: str
    position_rate: float
    damping_rate: float
    Kq: np.ndarray
    Dq: np.ndarray
    Kx: np.ndarray
    Dx: np.ndarray
    kp: float
    ki: float
    decouple: bool = True

    @property
    def force_rate(self) -> float:
        """λ_f = k_i / (1 + k_p) [1/s]: the decay rate of e_F on a rigid surface (eq. 4)."""
        return self.ki / (1.0 + self.kp)


@dataclass(frozen=True)
class RaibertCraigOptions(base.LawOptions):
    """The ``[control.raibert_craig]`` table (defaults in the module docstring)."""

    law: ClassVar[str] = _NAME

    form: str = param(
        "corrected", choices=FORMS,
        doc="the position servo: corrected, no force along the normals (Fisher & Mujtaba "
        "1992), or original, J⁻¹ S (Raibert & Craig 1981)",
    )  # fmt: skip
    feedforward: str = param(
        "model", choices=FEEDFORWARDS,
        doc="model: M q̈_ff + C q̇ + g of the controller's model, or gravity: g only, as in 1981",
    )  # fmt: skip
    decouple: bool = param(
        True,
        doc="true: project the position feedback so that, by the model, it cannot change the "
        "contact force; false: the published forms",
    )
    position_rate: float | None = param(
        None, unit="1/s", minimum=0.0, strict=True,
        doc="ω_p, slow pole of the position error (control.Lambda when not given)",
    )  # fmt: skip
    damping_rate: float | None = param(
        None, unit="1/s", minimum=0.0, strict=True,
        doc="ω_d, fast pole of the position error (control.kd_rate when not given)",
    )  # fmt: skip
    kp: float = param(0.5, minimum=0.0, doc="k_p, proportional force gain")
    ki: float | None = param(
        None, unit="1/s", minimum=0.0, strict=True,
        doc="k_i, integral force gain ((1 + k_p) γ when not given)",
    )  # fmt: skip

    def rates(
        self, Lambda: float, kd_rate: float, gamma: float
    ) -> tuple[float, float, float, float]:
        """(ω_p, ω_d, k_p, k_i): the values given, else ω_p = Λ, ω_d = κ (``kd_rate``) and
        k_i = (1 + k_p) γ, of the ``[control]`` settings."""
        wp = Lambda if self.position_rate is None else self.position_rate
        wd = kd_rate if self.damping_rate is None else self.damping_rate
        ki = (1.0 + self.kp) * gamma if self.ki is None else self.ki
        return wp, wd, self.kp, ki


def make_gains(context: base.LawContext) -> RaibertCraigGains:
    """The gains from the ``[control.raibert_craig]`` table and the arm at q₀
    (:meth:`RaibertCraigOptions.rates`)."""
    opts = RaibertCraigOptions(**context.options)
    wp, wd, kp, ki = opts.rates(
        context.settings.Lambda, context.settings.kd_rate, context.settings.gamma
    )
    M0 = 0.5 * (context.M0 + context.M0.T)
    J0 = context.robot.jacobian(context.q0)
    Lambda0 = cartesian_inertia(M0, J0)
    return RaibertCraigGains(
        form=opts.form,
        feedforward=opts.feedforward,
        position_rate=wp,
        damping_rate=wd,
        Kq=wp * wd * M0,
        Dq=(wp + wd) * M0,
        Kx=wp * wd * Lambda0,
        Dx=(wp + wd) * Lambda0,
        kp=kp,
        ki=ki,
        decouple=opts.decouple,
    )


class RaibertCraigWorkspace(base.Law):
    """The law of the module docstring (both forms) as one compiled call per step
    (:mod:`hybrid_force.control.laws._raibert_craig_kernels`), writing into arrays preallocated
    here (hot path), with no numpy call and no new array returned. The command returned and
    :attr:`last_u_pos` are overwritten at every call: copy to keep. Where M, A M⁻¹ Aᵀ, NᵀN
    or Nᵀ J M⁻¹ Jᵀ N is exactly singular it raises numpy's LinAlgError.

    Args:
        gains: see :class:`RaibertCraigGains`.
        surfaces: the controller's surfaces (their normals at the tip give S).
        approach_rate: λ_a [1/s] of the supervisor's approach velocity v_a = −λ_a d.

    Attributes:
        V: NaN (the law has no Lyapunov function).
        last_u_pos: (n,) the position part u_pos of the last call [N·m …], for tests.
    """

    def __init__(
        self, gains: RaibertCraigGains, surfaces: tuple[Surface, ...], approach_rate: float
    ) -> None:
        self.gains = gains
        self.surfaces = surfaces
        self.approach_rate = approach_rate
        self.original = gains.form == "original"
        self.model_feedforward = gains.feedforward == "model"
        n, k = gains.Kq.shape[0], len(surfaces)
        descriptors = [np.asarray(s._descriptor, dtype=float) for s in surfaces]
        # ∇Φ in Python when a surface has no closed form (FunctionSurface, meshes)
        self._python_gradients = any(d.shape[0] == 0 for d in descriptors)
        width = max(10, *(d.shape[0] for d in descriptors))
        # the law's own arrays as views of one flat buffer, which the steady contact step's
        # kernel takes whole (_raibert_craig_kernels.hybrid_steady, its layout)
        self._ws = ws = np.zeros(_K.workspace_size(n, k, width))
        ws[:3] = [k, n, width]
        carver = base.Carver(ws, 3)
        take = carver.take
        self._descs = take(k, width)
        for i, d in enumerate(descriptors):
            self._descs[i, : d.shape[0]] = d
        self._grads = take(k, 3)
        self._joint_gains = take(2, n, n)
        self._joint_gains[:] = [gains.Kq, gains.Dq]
        self._task_gains = take(2, 3, 3)
        self._task_gains[:] = [gains.Kx, gains.Dx]
        self._params = take(5)
        self._params[:] = [
            gains.position_rate, gains.damping_rate, gains.kp, gains.ki, approach_rate
        ]  # fmt: skip
        flags = [self.original, self.model_feedforward, gains.decouple, self._python_gradients]
        take(4)[:] = flags  # (hybrid_steady's copy; the other calls take the int array)
        self._flags = np.array(flags, dtype=np.int64)
        self._vectors = take(2, n)
        self._u0, self._u_pos = self._vectors
        self.last_u_pos = self._u_pos
        self._B = take(n, k)
        self._zeros_k = take(k)
        carver.done()
        self._plain = base.Command(u0=self._u0, B=None)
        self._contact = base.Command(u0=self._u0, B=self._B if gains.kp > 0 else None)

    V = math.nan

    def free_space(self, inp: base.LawInput) -> base.Command:
        """S = I: both forms servo every axis, J⁺(p_d − p) ≈ q_d − q; the joint path q_d
        itself is servoed (module docstring), u = u_ff − K_P e_q − K_D (q̇ − q̇_d)."""
        robot, desired = inp.robot, inp.desired
        packs = robot._packs if robot._packs is not None else robot.packed()._packs
        assert packs is not None
        args = (
            packs[0], packs[1], self._joint_gains, inp.v, inp.e_q, desired.qd, desired.qdd,
            self.model_feedforward, self._vectors,
        )  # fmt: skip
        self._entry("free", _K.free_space, args)(*args)
        return self._plain

    def hybrid_at(self, inp: base.LawInput, q: np.ndarray) -> base.Command:
        """:meth:`hybrid` in contact at the measured q of a Euclidean arm (:meth:`Law.hybrid_at`):
        on the supervisor's, the CLIK's, the terms' and this law's packs, one compiled call of
        10 arguments instead of 26 (the same operations)."""
        steady, pack, cons, robot = inp.steady, inp.desired.pack, inp.rows, inp.robot
        r_packs, flat = robot._packs, cons._flat
        if steady is None or pack is None or r_packs is None or flat is None:
            return super().hybrid_at(inp, q)
        mats, vecs, jac, tip = r_packs
        if self._python_gradients:
            for i, surface in enumerate(self.surfaces):
                self._grads[i] = surface.evaluate(tip[0])[1]
        kernel = self._steady_kernel
        if kernel is None:
            kernel = self._steady_kernel = entry(
                _K.hybrid_steady, q, inp.v, mats, vecs, jac, tip, flat, pack, steady, self._ws
            )
        if kernel(q, inp.v, mats, vecs, jac, tip, flat, pack, steady, self._ws) != 0:
            raise np.linalg.LinAlgError("Singular matrix")  # an exactly singular solve
        return self._contact

    def hybrid(self, inp: base.LawInput) -> base.Command:
        """Near (approach given): position along the surface, v_a across it. Contact: eq. 1–3."""
        robot, cons, desired, approach = inp.robot, inp.rows, inp.desired, inp.approach
        assert desired.p is not None and desired.pd is not None and desired.pdd is not None
        packs = robot._packs if robot._packs is not None else robot.packed()._packs
        assert packs is not None
        mats, vecs, jac, tip = packs
        if self._python_gradients:
            for i, surface in enumerate(self.surfaces):
                self._grads[i] = surface.evaluate(tip[0])[1]
        near = approach is not None
        args = (
            mats, vecs, jac, tip, cons.A, cons.Adot, cons.rate, inp.v, inp.e_q, desired.qd,
            desired.qdd, desired.p, desired.pd, desired.pdd, inp.e_F, inp.f_d,
            self._zeros_k if approach is None else approach, near, self._descs, self._grads,
            self._joint_gains, self._task_gains, self._params, self._flags, self._vectors,
            self._B,
        )  # fmt: skip
        status = self._entry(near, _K.hybrid, args)(*args)  # one for near, one for contact
        if status != 0:  # an exactly singular solve: numpy's error
            raise np.linalg.LinAlgError("Singular matrix")
        return self._plain if near else self._contact

    def info(self) -> dict[str, Any]:
        """The form, the feed-forward and the gains as JSON-able data."""
        g = self.gains
        return {
            "form": g.form,
            "feedforward": g.feedforward,
            "position_rate": g.position_rate,
            "damping_rate": g.damping_rate,
            "kp": g.kp,
            "ki": g.ki,
            "force_rate": g.force_rate,
            "Kx": g.Kx.tolist(),
            "Kq": g.Kq.tolist(),
        }


def build(context: base.LawContext) -> RaibertCraigWorkspace:
    """The registry's factory of ``control.law = "raibert_craig"``."""
    s = context.settings
    approach_rate = s.Lambda if s.approach_rate is None else s.approach_rate
    return RaibertCraigWorkspace(make_gains(context), context.constraint.surfaces, approach_rate)


def loop_bounds(context: base.LoopContext) -> list[base.LoopBound]:
    """The law's pre-run checks: the velocity loop and, sampled, the force loop.

    **Velocity loop.** In free space u = u_ff − K_P e_q − K_D (q̇ − q̇_d) with
    K_D = (ω_p + ω_d) M_c(q₀) from the CONTROLLER's model: with the plant's M, sampled at T,
    q̇_{k+1} = (I − T M⁻¹ K_D) q̇_k + …, stable iff T λ_max(M⁻¹ K_D) < 2
    (:func:`~hybrid_force.control.force_loop.velocity_loop_number`), i.e.
    T m (ω_p + ω_d) < 2 for M_c = m M. (Along the surface the corrected form's D_x = (ω_p +
    ω_d) Λ₀ gives the same number.)

    **Force loop** (eq. 1: u ∋ Aᵀ(k_p f̃ + k_i e_F), B = k_p Aᵀ):
    :func:`~hybrid_force.control.laws.osc_hybrid.force_gain_bounds` with k_P = ``kp``,
    k_I = ``ki``; the model's masses do not enter (ρ = 1 with the plant's rows), so the
    bound is k_p < 1 + k_i T/2 without filter and delay: the docstring's tick-to-tick map
    f ← −k_p f + … with the integral's half-step. The law reads none of β and K_d.
    """
    opts = RaibertCraigOptions(**context.options_of(_NAME))
    wp, wd, kp, ki = opts.rates(
        context.settings.Lambda, context.settings.kd_rate, context.settings.gamma
    )
    M0 = context.model_mass(context.q0)
    Dq = (wp + wd) * 0.5 * (M0 + M0.T)
    qs = [context.q0, *context.configurations]
    number = max(
        force_loop.velocity_loop_number(context.plant_mass(q), Dq, context.period) for q in qs
    )
    given = opts.damping_rate is not None
    key, value = context.named(f"control.{_NAME}.damping_rate" if given else "control.kd_rate", wd)
    gain = ", K_D = (ω_p + ω_d) M_c(q₀)"
    bounds = [base.velocity_loop_bound(key, value, number, " K_D", context.where, gain)]
    return bounds + force_gain_bounds(context, _NAME, "kp", kp, "ki", ki)


base.register(
    base.LawSpec(
        _NAME,
        "task-space selection-matrix hybrid control with a PI force loop (Raibert & Craig "
        "1981; corrected form: Fisher & Mujtaba 1992)",
        build,
        RaibertCraigOptions,
        gains={"Lambda": "position_rate", "kd_rate": "damping_rate", "gamma": "ki"},
        loop_bounds=loop_bounds,
        check=make_gains,  # the Cartesian inertia at q0 (ControlError at a singularity)
    )
)

"""Cartesian impedance control with force tracking along the surface normal (issue 16 item 5).

The tip is made to behave as a mass–spring–damper about a reference point p_r (Hogan 1985,
"Impedance control: an approach to manipulation", ASME J. Dyn. Syst. Meas. Control 107):

    τ = M q̈_d + C(q, q̇) q̇_d + g + Jᵀ [K (p_r − p) + D (ṗ_r − ṗ)] + (I − Jᵀ J̄ᵀ) τ₀       (1)

* **Stiffness and damping**, (3, 3) symmetric positive definite: K = ω² Λ(q), D = 2ζω Λ(q),
  with Λ = (J M⁻¹ Jᵀ)⁻¹ the Cartesian inertia of the controller's model at the current
  configuration. With the exact model every direction of the tip then has the natural
  frequency ω and damping ratio ζ (ë + 2ζω ė + ω² e = Λ⁻¹ f_ext), for every arm and
  everywhere on its path, so the defaults scale with the arm as K_d = κ M(q0) does, and the
  explicit step's bound dt·ω is known in advance. Λ(q0) would not do: the RTR turns about its
  base axis and Λ turns with it in world axes, so a world-fixed K = ω² Λ(q0) soon faces
  Λ(q) an order of magnitude lighter or heavier in some direction (section 6.4 starts near
  the axis, where the tangential inertia is largest). The price: K(q) is not the stiffness of
  one conservative spring, so no Lyapunov function is claimed (V is NaN).
* **Feed-forward** M q̈_d + C(q, q̇) q̇_d + g of the CLIK's joint path (the "PD+" of Paden and
  Panja 1988): without it (``feedforward = false``) the tip lags the path by about p̈_d/ω²
  along the surface (4.3e-4 m on a point mass's circle of 0.1 m at 2 rad/s, see
  tests/test_law_impedance.py) and the path's normal load goes into the contact force,
  which only force tracking takes back. With it, q ≡ q_d solves the closed loop exactly.
* **Null space** (redundant arms, n > 3): τ₀ = −M (ω² e_q + 2ζω ė_q) toward the CLIK's q_d,
  through I − Jᵀ J̄ᵀ with J̄ = M⁻¹ Jᵀ Λ (Khatib's dynamically consistent inverse): it adds no
  force at the tip (J M⁻¹ (I − Jᵀ J̄ᵀ) = 0) and is zero for a 3-joint arm.

The reference per phase of the supervisor (n̂ the unit normal of the surface at the tip):

* free: p_r = p_d, ṗ_r = ṗ_d.
* near: the reference keeps the tool's own height above the surface and descends at the
  supervisor's approach speed a = −λ_a d: p_r = p_d + n̂n̂ᵀ(p − p_d), ṗ_r = (I − n̂n̂ᵀ) ṗ_d + n̂ a,
  p̈_r = n̂ ȧ (fed forward as Λ p̈_r). As K, D and Λ are proportional, the normal motion is
  decoupled: d̈ = ȧ + 2ζω (a − ḋ), i.e. (s + λ_a)(s + 2ζω) d = 0. The tool closes in at λ_a
  (for any ω, ζ: both roots are real) and touches at about λ_a·contact_tol, as the paper's law
  does. Without ȧ the roots of s² + 2ζω s + 2ζωλ_a are complex when ζω < 2λ_a, and the tool
  would overshoot into the surface.
* contact: the reference is pushed into the surface by a depth δ,

      p_r = p_d − δ u,     u = K⁻¹n̂ / (n̂ᵀK⁻¹n̂),     ṗ_r = ṗ_d,                            (2)

  so that K (p_r − p_d) = −k_n δ n̂ with the normal stiffness k_n = 1/(n̂ᵀK⁻¹n̂) = ω² m_n,
  m_n = 1/(A M⁻¹ Aᵀ) the arm's mass along the normal. u has n̂ᵀu = 1 (δ is the depth along
  n̂) and leans off n̂ where K is anisotropic, so that the spring pushes along n̂ only: pushed
  straight along n̂, it would also drag the tool along the surface by (I − n̂n̂ᵀ)K⁻¹n̂ f. The
  offset is kept as the force it asks for, φ = k_n δ [N], so (1) holds −Aᵀ φ and stays right
  where k_n changes along the path. ṗ_r = ṗ_d: the depth is a slow preload; its own rate
  (the measured force, the turning normal) is not fed to the damping.

**Steady force on a rigid surface.** With the exact model, q ≡ q_d turns the plant
M q̈ + C q̇ + g = τ + Aᵀ f into Aᵀ (f − φ) = 0: f = φ, with no position error. A torque w the
command falls short of what the plant needs (w = (1 − m)(M q̈ + C q̇ + g) for a model m times
the plant's mass; friction) adds the surface's share of it, (A M⁻¹ w)/(A M⁻¹ Aᵀ) (with k
rows W⁻¹ A M⁻¹ w, W = A M⁻¹ Aᵀ); what is left, along the surface, is a position error
Λ⁻¹w/ω² (no integral acts on position).

* **Plain impedance** (``force_tracking = false``): φ = f_d, the depth δ₀ = f_d/k_n the
  model predicts. Its force is k_n × (the reference's penetration of the *real* surface):
  f_d only if the surface is rigid and where the model puts it, f_d + (A M⁻¹ w)/(A M⁻¹ Aᵀ)
  with an unmodelled w, and f_d k_e/(k_e + k_n) on a surface of stiffness k_e (the tool sinks
  f/k_e and the impedance spring relaxes by as much: two springs in series).
* **Force tracking** (default; Seraji and Colbaugh 1997, "Force tracking in impedance
  control", IJRR 16(1)): the depth follows the admittance b δ̇ = f_d − f with b = k_n/κ_f,
  i.e. φ̇ = κ_f (f_d − f) from φ = f_d at each touch.
  Its only rest is f = f_d, whatever the surface's stiffness, position or the model's error;
  it rests at φ = f_d − (A M⁻¹ w)/(A M⁻¹ Aᵀ), on a compliant surface at δ = f_d/k_n + f_d/k_e.
  On a rigid surface f ≈ φ at once, so the force error decays at κ_f; on a compliant one at
  the slow root of m_n s³ + 2ζω m_n s² + (k_n + k_e) s + κ_f k_e, about κ_f k_e/(k_e + k_n)
  when κ_f ≪ ω.

With k stacked surfaces n̂ φ becomes Σ ∇Φ_i/s_i φ_i (the rows A = N̂ᵀJ, any row scaling), the
depths δ = (A M⁻¹ Aᵀ) φ / ω² (k,), and f, f_d, φ are in the rows' units (newtons for "tip").
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.control import force_loop
from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.laws import base
from hybrid_force.control.laws.osc_hybrid import task_space
from hybrid_force.errors import ControlError, SurfaceError
from hybrid_force.model.robot import RobotTerms
from hybrid_force.schema import param

_K = LazyKernels("hybrid_force.control.laws._impedance_kernels")

__all__ = [
    "DEFAULTS",
    "ImpedanceGains",
    "ImpedanceWorkspace",
    "build",
    "check",
    "loop_bounds",
]

_MAX_RATE_STEP = 0.5  # ω·dt and κ_f·dt must stay below this (explicit step, sampled control)


@dataclass(frozen=True)
class ImpedanceGains(base.LawOptions):
    """Settings of the impedance law (the ``[control.impedance]`` table).

    Raises:
        ControlError: a value the ``[control.impedance]`` table would refuse (a ControlError
            for a rate ≤ 0, a ControlError for a flag that is not a bool), naming
            ``control.impedance.<key>``.
    """

    law: ClassVar[str] = "impedance"

    omega: float = param(
        30.0, unit="1/s", minimum=0.0, strict=True,
        doc="natural frequency ω of K = ω²Λ(q), D = 2ζωΛ(q) (and of the null-space posture)",
    )  # fmt: skip
    zeta: float = param(
        1.0, minimum=0.0, strict=True, doc="damping ratio ζ of D = 2ζωΛ(q) (1: critical)"
    )
    force_tracking: bool = param(
        True,
        doc="true: the reference's depth adapts until f = f_d (φ̇ = κ_f (f_d − f)); false: "
        "plain impedance at the model's depth f_d/k_n",
    )
    force_rate: float = param(
        10.0, unit="1/s", minimum=0.0, strict=True, acts_when=("force_tracking", True),
        doc="κ_f, rate of the force-tracking admittance",
    )  # fmt: skip
    feedforward: bool = param(
        True, doc="true: add M q̈_d + C q̇_d of the desired joint path (g is always added)"
    )


#: The default ``[control.impedance]`` settings, as :meth:`ImpedanceWorkspace.info` gives them.
DEFAULTS: dict[str, Any] = dataclasses.asdict(ImpedanceGains())


def _singular(robot: RobotTerms) -> SurfaceError:
    """The error of a configuration where J M⁻¹ Jᵀ (or M) is singular."""
    return SurfaceError(
        f"the tip at {robot.p.tolist()} cannot move in every direction (J M⁻¹ Jᵀ is "
        "singular): the Cartesian impedance is undefined there"
    )


class ImpedanceWorkspace(base.Law):
    """The impedance law (module docstring) as one compiled call per step, into arrays
    preallocated here (:func:`hybrid_force.control.laws._impedance_kernels.impedance`: the
    Cholesky factorisation of M and the small solves written out); a
    SurfaceError where J M⁻¹ Jᵀ or M is singular. The command returned,
    ``stiffness``, ``damping`` and ``offset`` are overwritten at every call: copy to keep.

    Args:
        gains: the settings. constraint: the controller's surfaces (for their normals).
        k: the number of surfaces.

    Attributes:
        V: NaN (no Lyapunov function is claimed, see the module docstring).
        preload: (k,) φ = k_n δ [N], the force the reference's depth asks for (contact).
        offset: (k,) δ [m for "tip" rows], the reference's depth below p_d at the last call.
        stiffness, damping: (3, 3) K and D at the last call [N/m, N·s/m].
    """

    def __init__(self, gains: ImpedanceGains, constraint: Constraint, k: int) -> None:
        self.gains = gains
        self.constraint = constraint
        self.preload = np.zeros(k)
        self.offset = np.zeros(k)
        self._f_d = np.zeros(k)
        self._in_contact = False  # the last call was the contact law
        self._gains = np.zeros((3, 3, 3))  # [Λ, K, D]
        self.stiffness, self.damping = self._gains[1], self._gains[2]
        self._normals = np.zeros((3, k))
        self._along = np.zeros((k, 3))
        self._no_rows: np.ndarray | None = None  # (0, n), made at the first call
        self._none = np.zeros(0)
        self._u: np.ndarray | None = None
        self._command: base.Command | None = None
        self._work: np.ndarray | None = None
        self._ws: np.ndarray | None = None  # the steady step's buffer (_make_steady)

    V = math.nan

    def free_space(self, inp: base.LawInput) -> base.Command:
        """Eq. (1) with p_r = p_d, ṗ_r = ṗ_d (module docstring)."""
        self._in_contact = False
        return self._run(inp, None, _FREE)

    def hybrid(self, inp: base.LawInput) -> base.Command:
        """Eq. (1) near the surface (approach given) and in contact (eq. 2); e_F is unused."""
        cons, f_d = inp.rows, inp.f_d
        if inp.approach is not None:
            self._in_contact = False
            normals = self._normals
            for i, surface in enumerate(self.constraint.surfaces):
                normals[:, i] = surface.normal(inp.robot.p)
            given = normals.shape[1] > 1
            if given:  # the kernel computes a single column's pseudo-inverse itself
                self._along[...] = np.linalg.pinv(normals)
            return self._run(inp, cons, _NEAR, inp.approach, given)
        self._touch(f_d)
        return self._run(inp, cons, _CONTACT)

    def hybrid_at(self, inp: base.LawInput, q: np.ndarray) -> base.Command:
        """:meth:`hybrid` in contact at the measured q of a Euclidean arm (:meth:`Law.hybrid_at`):
        on the supervisor's, the CLIK's, the terms' and this law's packs, one compiled call of
        10 arguments instead of 25 (the same operations)."""
        steady, pack, cons = inp.steady, inp.desired.pack, inp.rows
        r_packs, flat, ws = inp.robot._packs, cons._flat, self._ws
        if steady is None or pack is None or r_packs is None or flat is None or ws is None:
            if ws is None and self._command is not None and inp.approach is None:
                self._make_steady(r_packs is not None and flat is not None)
            return super().hybrid_at(inp, q)
        self._touch(inp.f_d)
        mats, vecs, jac, tip = r_packs
        kernel = self._steady_kernel
        if kernel is None:
            kernel = self._steady_kernel = entry(
                _K.impedance_steady, q, inp.v, mats, vecs, jac, tip, flat, pack, steady, ws
            )
        if kernel(q, inp.v, mats, vecs, jac, tip, flat, pack, steady, ws) != 0:
            raise _singular(inp.robot)
        assert self._command is not None  # (made with the buffers)
        return self._command

    def _make_steady(self, packed: bool) -> None:
        """Move the law's arrays into one flat buffer (their values kept; the next calls, on
        either path, use the views), which the steady kernel takes whole
        (``_impedance_kernels.impedance_steady``); packed: the inputs come with their packs."""
        if not packed:
            return
        assert self._u is not None and self._work is not None
        n, k, g = self._u.shape[0], self.preload.shape[0], self.gains
        ws = np.zeros(_K.workspace_size(n, k))
        ws[:5] = [k, n, g.omega, g.zeta, float(g.feedforward)]
        carver = base.Carver(ws, 5)
        parts: list[Any] = []  # (views of the shapes of the arrays they replace)
        for a in (self.preload, self.offset, self._gains, self._u, self._work, self._normals,
                  self._along):  # fmt: skip
            view = carver.take(*a.shape)
            view[...] = a
            parts.append(view)
        carver.done()
        (self.preload, self.offset, self._gains, self._u, self._work, self._normals,
         self._along) = parts  # fmt: skip
        self.stiffness, self.damping = self._gains[1], self._gains[2]
        self._command = base.Command(self._u, None)
        self._ws = ws

    def _touch(self, f_d: np.ndarray) -> None:
        """In contact with f_d (k,) [N]: φ starts from the model's depth, φ = f_d, at a touch
        (and stays there without force tracking)."""
        if not self._in_contact:
            self.preload[:] = f_d
            self._in_contact = True
        if not self.gains.force_tracking:
            self.preload[:] = f_d
        self._f_d = f_d

    def _run(
        self,
        inp: base.LawInput,
        cons: ConstraintTerms | None,
        mode: int,
        approach: np.ndarray | None = None,
        along_given: bool = False,
    ) -> base.Command:
        robot, desired = inp.robot, inp.desired
        packs = robot.packed()._packs
        assert packs is not None  # packed() always returns terms with their packs
        mats, vecs, jac, tip = packs
        if self._u is None or self._u.shape[0] != mats.shape[1]:
            n, k = mats.shape[1], self.preload.shape[0]
            self._u = np.zeros(n)
            self._command = base.Command(self._u, None)
            self._work = np.zeros((n, n + 3 + k))
            self._no_rows = np.zeros((0, n))
        assert self._command is not None and self._work is not None
        p_d, pd_d = _task(desired)
        g = self.gains
        A = self._no_rows if cons is None else cons.A
        assert A is not None
        none = self._none
        args = (
            mats, vecs, jac, tip, inp.v, inp.e_q, desired.qd, desired.qdd, p_d, pd_d, A,
            self._normals, self._along, none if approach is None else approach,
            none if cons is None else cons.distance, self.preload, mode, along_given,
            g.omega, g.zeta, g.feedforward, self._u, self._gains, self.offset, self._work,
        )  # fmt: skip
        status = self._entry((mode, along_given), _K.impedance, args)(*args)  # per phase
        if status != 0:
            raise _singular(robot)
        return self._command

    def update(self, dt: float, f: np.ndarray) -> None:
        """Force tracking in contact: φ += dt κ_f (f_d − f).

        φ may turn negative (the reference then sits off the surface, on the free side): that
        is how the law takes back a push the model does not know of (a gravity over-estimate).
        """
        if self._in_contact and self.gains.force_tracking:
            args = (self.preload, self._f_d, f, float(dt * self.gains.force_rate))
            self._entry("preload", _K.advance_preload, args)(*args)

    def info(self) -> dict[str, Any]:
        """The settings as JSON-able data."""
        return dataclasses.asdict(self.gains)


_FREE, _NEAR, _CONTACT = 0, 1, 2  # the kernel's modes (_impedance_kernels.FREE, NEAR, CONTACT)


def _task(desired: base.Desired) -> tuple[np.ndarray, np.ndarray]:
    """p_d, ṗ_d (3,) of the desired sample (the supervisor always gives them)."""
    assert desired.p is not None and desired.pd is not None
    return desired.p, desired.pd


def check(context: base.LawContext) -> None:
    """The registry's check of ``control.law = "impedance"``.

    Raises:
        ControlError: ω·dt or κ_f·dt ≥ 0.5 (the explicit step or the sampled admittance would
            not follow the continuous law), naming ``control.impedance.<key>``.
    """
    gains = ImpedanceGains(**context.options)
    for key, rate in (("omega", gains.omega), ("force_rate", gains.force_rate)):
        if rate * context.dt >= _MAX_RATE_STEP:
            raise ControlError(
                f"control.impedance.{key} = {rate:g} 1/s is too fast for the control period "
                f"{context.dt:g} s: {key}·dt = {rate * context.dt:.3g} must stay below "
                f"{_MAX_RATE_STEP}",
                key=f"control.impedance.{key}",
                value=rate,
            )


def build(context: base.LawContext) -> ImpedanceWorkspace:
    """The registry's factory of ``control.law = "impedance"`` (:func:`check` passed)."""
    gains = ImpedanceGains(**context.options)
    return ImpedanceWorkspace(gains, context.constraint, context.constraint.k)


def loop_bounds(context: base.LoopContext) -> list[base.LoopBound]:
    """The law's pre-run checks: the velocity loop and, sampled, the admittance's force loop.

    **Velocity loop.** Eq. 1 holds −Jᵀ D J q̇ − Nᵀ M_c 2ζω q̇ with D = 2ζω Λ_c (Λ_c, N of the
    CONTROLLER's M_c): with the plant's M, sampled at T, q̇_{k+1} = (I − T M⁻¹ G) q̇_k + …,
    G = 2ζω (Jᵀ Λ_c J + M_c N), stable iff T λ_max(M⁻¹ G) < 2 (2ζω m T for M_c = m M).

    **Force loop** (``force_tracking``): the preload φ_k = φ_(k−1) + T κ_f (f_d − f̃_(k−1))
    enters as −Aᵀ φ, a force (ρ = ρ(W⁻¹ A M⁻¹ A_cᵀ) = 1 with the plant's rows): the
    recursion of :mod:`hybrid_force.control.force_loop` with a = 0 and b = κ_f ρ, stable iff
    κ_f ρ T < :func:`~hybrid_force.control.force_loop.largest_integral_step` (1 without
    filter and delay). The law reads none of the paper's K_d, β, γ.
    """
    gains = ImpedanceGains(**context.options_of("impedance"))
    rate = 2.0 * gains.zeta * gains.omega
    qs = [context.q0, *context.configurations]
    number = 0.0
    for q in qs:
        M_c = context.model_mass(q)
        task = task_space(M_c, context.model.jacobian(q))
        G = rate * (task.J.T @ task.Lambda @ task.J + M_c @ task.N)
        number = max(
            number,
            force_loop.velocity_loop_number(context.plant_mass(q), 0.5 * (G + G.T), context.period),
        )
    key, value = context.named("control.impedance.omega", gains.omega)
    gain = ", G = 2ζω (Jᵀ Λ_c J + M_c N)"
    bounds = [base.velocity_loop_bound(key, value, number, " G", context.where, gain)]
    if context.sampled and gains.force_tracking:
        rho = max(
            force_loop.force_feedthrough(
                context.plant_mass(q), context.rows(q), context.rows(q, context.model).T
            )
            for q in qs
        )
        step = force_loop.largest_integral_step(context.alpha, context.delay)
        limit = step / (rho * context.period)
        bounds.append(
            base.LoopBound(
                "control.impedance.force_rate",
                gains.force_rate,
                gains.force_rate,
                limit,
                f"the sampled admittance φ_k = φ_(k−1) + T κ_f (f_d − f̃_(k−1)) ({context.where}) "
                f"oscillates and grows unless κ_f·ρ·T < {step:.4g}: force_rate must stay below "
                f"{base.below(limit)} 1/s (ρ = ρ(W⁻¹ A M⁻¹ A_cᵀ) = {rho:.4g})",
            )
        )
    return bounds


base.register(
    base.LawSpec(
        "impedance",
        "Cartesian impedance, K = ω²Λ(q) (Hogan 1985), with force tracking along the "
        "normal (Seraji & Colbaugh 1997)",
        build,
        ImpedanceGains,
        loop_bounds=loop_bounds,
        check=check,
    )
)

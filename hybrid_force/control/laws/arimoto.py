"""The paper's control laws: free-space law (eq. 29–30) and modified Arimoto law (eq. 4, 11).

Both are plain functions of one step's quantities; they integrate nothing. A command is
affine in the contact force f that the dynamics will produce from it:

    u = u0 + B f,       u0: (n,), B: (n, k)

because the hybrid law's q̈_r contains ė_F = f − f_d (the algebraic loop of issue 4). The
simulator resolves u and f together, exactly (see :mod:`hybrid_force.sim.dynamics`).

Derivation of the loop (generalised to k rows A with A⁺ = Aᵀ(AAᵀ)⁻¹, see
:mod:`hybrid_force.control.constraint`; with the paper's unit row J_Φn, A⁺ = J_Φnᵀ):

    x      = q̇_d − Λ e_q,                  ẋ = q̈_d − Λ (q̇ − q̇_d)
    q̇_r   = Q x + β A⁺ e_F                                           (eq. 4)
    q̈_r   = Q̇ x + Q ẋ + β Ȧ⁺ e_F + β A⁺ (f − f_d)                    (d/dt of eq. 4)
    u      = M q̈_r + C q̇_r + g − K_d s − Aᵀ (f_d − γ e_F)              (eq. 11)
           = [M (q̈_r − β A⁺ f) + C q̇_r + g − K_d s − Aᵀ(f_d − γ e_F)] + (β M A⁺) f
           =              u0                                          +    B   f

Closed loop (eq. 13): M ṡ + C s + K_d s = Aᵀ (ė_F + γ e_F); with V = ½ sᵀMs + ½ β e_Fᵀe_F
one finds V̇ = −sᵀK_d s − βγ e_Fᵀe_F (eq. 16) for any row scaling, because A s₁ = −β e_F.
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_force import _checks as checks
from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.control import force_loop
from hybrid_force.control.constraint import ConstraintTerms
from hybrid_force.control.laws import base
from hybrid_force.errors import ControlError

_K = LazyKernels("hybrid_force.control._kernels")

__all__ = [
    "LawWorkspace",
    "build",
    "check_damping_gain",
    "damping_matrix",
    "default_damping_gain",
    "loop_bounds",
    "make_gains",
]


def default_damping_gain(M0: np.ndarray, rate: float = 20.0) -> np.ndarray:
    """Default K_d = rate · M(q0): scales with the arm's own inertia.

    With K_d = κ M(q0), M⁻¹K_d = κ I at the start configuration, so the sliding variable
    decays at about κ [1/s] for any arm (a 20 kg RTR link and a Panda wrist alike) and the
    explicit-integration bound dt·λ_max(M⁻¹K_d) ≈ κ dt is known in advance.

    Args:
        M0: (n, n) mass matrix at the start configuration.
        rate: κ [1/s].
    """
    return rate * 0.5 * (M0 + M0.T)


_MAX_JOINTS = 10_000  # make_gains refuses n beyond this (an n×n K_d would not fit in memory)
_KD_VALID = "a number > 0, a vector of n numbers > 0 or an n×n symmetric positive definite matrix"


def check_damping_gain(Kd: object, n: int | None = None) -> float | np.ndarray:
    """Validate the damping gain K_d > 0 of eq. 11 and 30 (paper: K_d = K_dᵀ > 0).

    Args:
        Kd: a real number (K_d = Kd·I), a vector of n real numbers (the diagonal) or an (n, n)
            symmetric matrix [N·m·s/rad for a revolute joint, N·s/m for a prismatic one]; its
            eigenvalues must all be > 0.
        n: the number of joints, when known (then the size must be n).

    Returns:
        Kd as a float, or as a new read-only float64 array of shape (n,) or (n, n).

    Raises:
        ControlError: wrong type or shape, non-finite entries, not symmetric, not positive
            definite; the message names ``Kd``.
    """
    K = checks.array(Kd, "Kd", ControlError, valid=_KD_VALID)
    if n is not None and K.shape not in ((), (n,), (n, n)):
        raise ControlError(
            f"Kd must be a scalar, a vector of {n} or an {n}x{n} matrix, got shape {K.shape}"
        )
    if K.ndim > 2 or K.size == 0 or (K.ndim == 2 and K.shape[0] != K.shape[1]):
        raise ControlError(f"Kd must be {_KD_VALID}, got shape {K.shape}: {checks.shown(Kd)}")
    M = K * np.eye(1) if K.ndim == 0 else (np.diag(K) if K.ndim == 1 else K)
    if not np.allclose(M, M.T, rtol=1e-12, atol=1e-12 * float(np.abs(M).max() + 1)):
        raise ControlError(f"Kd must be symmetric (paper eq. 11: K_d = K_dᵀ > 0), got {M.tolist()}")
    eig_min = float(np.linalg.eigvalsh(M).min())
    if eig_min <= 0:
        raise ControlError(
            f"Kd must be positive definite; its smallest eigenvalue is {eig_min:.6g}"
        )
    if K.ndim == 0:
        return float(K)
    K.setflags(write=False)
    return K


def make_gains(
    Kd: object,
    Lambda: float,
    beta: float,
    gamma: float,
    n: int,
) -> base.Gains:
    """Validate the gains against the paper's assumptions and return :class:`Gains`.

    Args:
        Kd: a scalar (K_d = Kd·I), a vector (diagonal) of length n, or an (n, n) matrix
            (see :func:`check_damping_gain`).
        Lambda: Λ > 0 [1/s]. beta: β ≥ 0 [(m/s)/(N·s)]. gamma: γ > 0 [1/s].
        n: the number of joints (an integer in [1, 10000]).

    Raises:
        ControlError: K_d not symmetric positive definite, Λ ≤ 0, β < 0, γ ≤ 0, non-finite values,
            or a value that is not a real number (a bool, a string, 10**400); the message
            names the gain.
    """
    n = checks.integer(
        n, "make_gains: n (the number of joints)", ControlError, minimum=1, maximum=_MAX_JOINTS
    )
    K = check_damping_gain(Kd, n)
    K = np.array(K * np.eye(n) if isinstance(K, float) else (np.diag(K) if K.ndim == 1 else K))
    lam = checks.number(Lambda, "Lambda (paper eq. 4, 29)", ControlError, minimum=0, strict=True)
    b = checks.number(beta, "beta (paper eq. 4)", ControlError, minimum=0)
    g = checks.number(gamma, "gamma (paper eq. 11)", ControlError, minimum=0, strict=True)
    return base.Gains(Kd=K, Lambda=lam, beta=b, gamma=g)


KernelRows = tuple[ConstraintTerms, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""What one call of the paper's law reads besides its input, in the kernel's order: the
constraint terms, e_F, f_d, the approach speeds (k,) and the matrices it writes (2, n, k) (B,
q̈_r,f); k = 0 in free space (:func:`free_space_rows`)."""


def free_space_rows(n: int) -> ConstraintTerms:
    """The constraint terms of the free-space law, the hybrid law with no rows: Q = I (n, n),
    Q̇ = 0 (eq. 29–30 are eq. 4, 8 with k = 0)."""
    rows = ConstraintTerms.zeros(0, n)
    rows.Q[:] = np.eye(n)
    return rows


class LawWorkspace(base.Law):
    """The paper's laws (module docstring: eq. 4, 8, 11 near and on the surface, eq. 29–30
    away from it) as one compiled call each, writing into arrays preallocated here (hot path).

    :func:`hybrid_force.control._kernels.arimoto` computes both (the free-space law is the
    same kernel with Q = I, Q̇ = 0 and no constraint rows) without allocating; the law has no
    states of its own (the only integrals are the supervisor's F and F_d). The command
    returned and the arrays below are overwritten at every call: copy to keep.

    Attributes:
        u0, s, s0, s1, qdot_r, qddot_r0: (n,) as in :class:`ControlTrace`.
        B, qddot_r_f: (n, k) of the hybrid law. V: [J] of the last call.
        in_contact_law: True when the last call was the hybrid law.
    """

    def __init__(self, n: int, k: int, gains: base.Gains) -> None:
        self.gains = gains
        # the law's own arrays as views of one flat buffer (_kernels.arimoto_parts), so the
        # steady contact kernel takes one argument for five; the outputs are rows of two
        self._ws = np.zeros(_K.arimoto_workspace_size(n, k))
        self._ws[0] = k
        o = 1
        Kd = self._ws[o : o + n * n].reshape(n, n)
        Kd[:] = gains.Kd
        o += n * n
        self._gain_values = self._ws[o : o + 3]  # Λ, β, γ
        self._gain_values[:] = [gains.Lambda, gains.beta, gains.gamma]
        o += 3
        self._vectors = self._ws[o : o + 6 * n].reshape(6, n)
        o += 6 * n
        self._matrices = self._ws[o : o + 2 * n * k].reshape(2, n, k)
        self._zeros_k = self._ws[o + 2 * n * k :]
        self._free_matrices = np.zeros((2, n, 0))
        self.u0, self.s, self.s0, self.s1, self.qdot_r, self.qddot_r0 = self._vectors
        self.B, self.qddot_r_f = self._matrices
        self.V = 0.0
        self.in_contact_law = False
        none = np.zeros(0)
        self._free_rows: KernelRows = (free_space_rows(n), none, none, none, self._free_matrices)
        self._hybrid = base.Command(u0=self.u0, B=self.B if gains.beta > 0 else None)
        self._free = base.Command(u0=self.u0, B=None)

    def hybrid(self, inp: base.LawInput) -> base.Command:
        """Eq. 4, 8, 11 with the loop in f kept explicit (module docstring), plus A⁺·approach
        in q̇_r (and Ȧ⁺·approach in q̈_r) in the near phase."""
        approach = self._zeros_k if inp.approach is None else inp.approach
        self._run(inp, inp.rows, inp.e_F, inp.f_d, approach, self._matrices)
        self.in_contact_law = True
        return self._hybrid

    def hybrid_at(self, inp: base.LawInput, q: np.ndarray) -> base.Command:
        """:meth:`hybrid` with e_q = q − q_d formed inside the same compiled call (the
        supervisor's contact step; terms with packs, else as :meth:`Law.hybrid_at`)."""
        cons = inp.rows
        r_packs, flat = inp.robot._packs, cons._flat
        if r_packs is None or flat is None:
            return super().hybrid_at(inp, q)
        desired = inp.desired
        steady, pack = inp.steady, desired.pack
        if steady is not None and pack is not None and inp.approach is None:
            args = (q, inp.v, r_packs[0], r_packs[1], flat, pack, steady, self._ws)
            kernel = self._steady_kernel
            if kernel is None:
                kernel = self._steady_kernel = entry(_K.arimoto_steady, *args)
            self.V = kernel(*args)
            self.in_contact_law = True
            return self._hybrid
        approach = self._zeros_k if inp.approach is None else inp.approach
        self.V = _K.arimoto_contact(
            q, desired.q, r_packs[0], r_packs[1], self.gains.Kd, flat, inp.v, inp.e_q,
            desired.qd, desired.qdd, inp.e_F, inp.f_d, approach, self._gain_values,
            self._vectors, self._matrices,
        )  # fmt: skip
        self.in_contact_law = True
        return self._hybrid

    def free_space(self, inp: base.LawInput) -> base.Command:
        """Eq. 29–30: q̇_r = q̇_d − Λ e_q, s = q̇ − q̇_r, u = M q̈_r + C q̇_r + g − K_d s."""
        self._run(inp, *self._free_rows)
        self.in_contact_law = False
        return self._free

    def info(self) -> dict[str, object]:
        """K_d, Λ, β, γ as JSON-able data."""
        g = self.gains
        return {"Kd": g.Kd.tolist(), "Lambda": g.Lambda, "beta": g.beta, "gamma": g.gamma}

    def _run(
        self,
        inp: base.LawInput,
        cons: ConstraintTerms,
        e_F: np.ndarray,
        f_d: np.ndarray,
        approach: np.ndarray,
        matrices: np.ndarray,
    ) -> None:
        """One call of the kernel with the rows of :data:`KernelRows` (k = 0: free space):
        on the robot terms' packs and the constraint terms' flat array when they have them
        (``RobotTerms.zeros``, ``ConstraintTerms.zeros``: fewer arguments), else on their
        fields."""
        robot, desired = inp.robot, inp.desired
        r_packs, flat = robot._packs, cons._flat
        if r_packs is not None and flat is not None:
            args = (
                r_packs[0], r_packs[1], self.gains.Kd, flat, inp.v, inp.e_q, desired.qd,
                desired.qdd, e_F, f_d, approach, self._gain_values, self._vectors, matrices,
            )  # fmt: skip
            free = matrices is self._free_matrices  # one entry per law
            self.V = self._entry(free, _K.arimoto_packed, args)(*args)
            return
        g = self.gains
        self.V = _K.arimoto(
            robot.M, robot.C, robot.g, g.Kd, cons.Q, cons.Qdot, cons.A_pinv, cons.A_pinv_dot,
            cons.A, inp.v, inp.e_q, desired.qd, desired.qdd, e_F, f_d, approach, g.Lambda,
            g.beta, g.gamma, self._vectors, matrices,
        )  # fmt: skip

    def trace(self, e_q: np.ndarray, e_F: np.ndarray, f_d: np.ndarray) -> base.ControlTrace:
        """A :class:`ControlTrace` of the last call (copies of the buffers)."""
        return base.ControlTrace(
            e_q=e_q.copy(),
            s=self.s.copy(),
            s0=self.s0.copy(),
            s1=self.s1.copy(),
            e_F=e_F.copy() if self.in_contact_law else np.zeros(0),
            qdot_r=self.qdot_r.copy(),
            qddot_r0=self.qddot_r0.copy(),
            qddot_r_f=self.qddot_r_f.copy() if self.in_contact_law else None,
            V=self.V,
            f_d=f_d.copy() if self.in_contact_law else np.zeros(0),
        )


def build(context: base.LawContext) -> LawWorkspace:
    """The registry's factory of ``control.law = "arimoto"`` (the paper's gains, no options)."""
    return LawWorkspace(context.robot.nv, context.constraint.k, context.gains)


def damping_matrix(Kd: object, kd_rate: float, M0: np.ndarray) -> np.ndarray:
    """(n, n) K_d as the supervisor builds it: ``control.Kd`` (a number, a diagonal or a
    matrix), else ``kd_rate`` · M_c(q0) (the controller's M at the start)."""
    n = M0.shape[0]
    if Kd is None:
        return default_damping_gain(M0, kd_rate)
    K = np.asarray(Kd, dtype=float)
    return K * np.eye(n) if K.ndim == 0 else (np.diag(K) if K.ndim == 1 else K)


def loop_bounds(context: base.LoopContext) -> list[base.LoopBound]:
    """The paper's laws' pre-run checks (``arimoto`` and ``arimoto_adaptive``): the velocity
    loop, and in a sampled run the force loop through β.

    **Velocity loop.** In free space (eq. 29–30) q̈_r = q̈_d − Λ(q̇ − q̇_d) and s = q̇ − q̇_r,
    so the torque u = M_c q̈_r + C q̇_r + g − K_d s holds −(K_d + Λ M_c) q̇ (M_c the
    CONTROLLER's mass matrix, K_d = κ M_c(q0) by default): with the plant's M the sampled loop
    is q̇_{k+1} = (I − T M⁻¹(K_d + Λ M_c)) q̇_k + …, stable iff T λ_max(M⁻¹(K_d + Λ M_c)) < 2
    (:func:`~hybrid_force.control.force_loop.velocity_loop_number`). With an exact model
    and the default K_d that number is (κ + Λ) T; a model 25 times the plant's makes it
    25 (κ + Λ) T = 2.75 at the paper's T = 1 ms, which the supervisor's own test
    T λ_max(M_c⁻¹ K_d) = κ T cannot see.

    **Force loop** (sampled runs only; :mod:`hybrid_force.control.force_loop`). B = β M_c A⁺
    gives f_k = c − a f̃_k with a = β ρ(W⁻¹ A M⁻¹ M_c A⁺) (= β m / W for M_c = m M), stable
    iff a < a*(α, d): β < a* / max_q ρ(W⁻¹ A M⁻¹ M_c A⁺) over the path. (The integral terms
    γ e_F and K_d β A⁺ e_F are left out: they raise the bound by O(bT), so the check is on the
    safe side.)

    **Force integral.** e_F = ∫(f − f_d) dt is advanced explicitly (the supervisor's, with the
    force of the step, or the reading of the tick before when sampled), and f answers it
    through −Aᵀ γ e_F and −K_d s ∋ K_d β A⁺ e_F: f ∋ −b e_F with b = γ ρ(W⁻¹ A M⁻¹ A_cᵀ) +
    β ρ(W⁻¹ A M⁻¹ K_d A⁺). With the exact loop (1 + a) f = c − b E_k, so E_(k+1) =
    (1 − bT/(1 + a)) E_k + …: stable iff bT < 2 (1 + a);
    sampled, bT below :func:`~hybrid_force.control.force_loop.largest_integral_step` (the
    proportional part left out: on the safe side).
    """
    s, T = context.settings, context.period
    qs = [context.q0, *context.configurations]
    Kd = damping_matrix(s.Kd, s.kd_rate, context.model_mass(context.q0))
    kd_part = lambda_part = number = 0.0
    for q in qs:
        M, M_c = context.plant_mass(q), context.model_mass(q)
        number = max(number, force_loop.velocity_loop_number(M, Kd + s.Lambda * M_c, T))
        kd_part = max(kd_part, force_loop.velocity_loop_number(M, Kd, T))
        lambda_part = max(lambda_part, force_loop.velocity_loop_number(M, s.Lambda * M_c, T))
    if lambda_part > kd_part:  # Λ M_c carries most of the loop
        key, value = context.named("control.Lambda", s.Lambda)
    elif s.Kd is None:
        key, value = context.named("control.kd_rate", s.kd_rate)
    else:
        key, value = context.named("control.Kd", np.asarray(s.Kd).tolist())
    bounds = [base.velocity_loop_bound(key, value, number, "(K_d + Λ M_c)", context.where)]
    # the force integral: f ∋ −b e_F, b = γ ρ(W⁻¹ A M⁻¹ Aᵀ) + β ρ(W⁻¹ A M⁻¹ K_d A⁺), and the
    # proportional a = β ρ(W⁻¹ A M⁻¹ M_c A⁺) per unit β
    b, per_beta, least_per_beta = 0.0, 0.0, math.inf
    for q in qs:
        M, A, A_c = context.plant_mass(q), context.rows(q), context.rows(q, context.model)
        A_pinv = np.linalg.pinv(A_c)
        b = max(
            b,
            s.gamma * force_loop.force_feedthrough(M, A, A_c.T)
            + s.beta * force_loop.force_feedthrough(M, A, Kd @ A_pinv),
        )
        a_q = force_loop.force_feedthrough(M, A, context.model_mass(q) @ A_pinv)
        per_beta, least_per_beta = max(per_beta, a_q), min(least_per_beta, a_q)
    # the proportional loop is checked first: a β too large also inflates b (its K_d β A⁺
    # part), and the integral's message would then blame γ for it
    if context.sampled and s.beta > 0:
        a_star = force_loop.max_stable_gain(context.alpha, context.delay)
        bound = a_star / per_beta
        bounds.append(
            base.LoopBound(
                "control.beta",
                s.beta,
                s.beta,
                bound,
                "the sampled force loop f_k = c − a f̃_k, a = β·ρ(W⁻¹ A M⁻¹ M_c A⁺) "
                f"({context.where}) oscillates and grows for a >= {a_star:.4g}: "
                f"beta must stay below {base.below(bound)} (any beta below is stable, e.g. "
                f"{base.below(0.99 * bound)}) (ρ(W⁻¹ A M⁻¹ M_c A⁺) up to {per_beta:.4g} along the "
                "path; docs/scenarios.md, [sensor])",
            )
        )
    if context.sampled:
        step = force_loop.largest_integral_step(context.alpha, context.delay)
    else:  # exact: (1 + a) f = c − b E, E_(k+1) = (1 − bT/(1 + a)) E_k
        step = 2.0 * (1.0 + s.beta * least_per_beta)
    bounds.append(
        base.LoopBound(
            "control.gamma",
            s.gamma,
            b * T,
            step,
            f"the force integral E_(k+1) = E_k + T (f − f_d) with f ∋ −b E, b = γ ρ(W⁻¹ A M⁻¹ Aᵀ) "
            f"+ β ρ(W⁻¹ A M⁻¹ K_d A⁺) = {b:.4g} 1/s ({context.where}) oscillates and grows "
            f"unless b·T < {step:.4g}; here b·T = {b * T:.4g}: gamma must stay below about "
            f"{base.below(s.gamma * step / (b * T))} 1/s",
        )
    )
    return bounds


base.register(
    base.LawSpec(
        "arimoto",
        "the paper's modified Arimoto hybrid law with its phase supervisor (eq. 4, 11, 29-31)",
        build,
        gains=base.PAPER_GAINS,
        loop_bounds=loop_bounds,
    )
)

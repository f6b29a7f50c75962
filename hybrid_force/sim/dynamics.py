"""Constrained forward dynamics of the arm: q̈ and the contact force f (section 6.2, eq. 2, 28).

In contact the arm obeys (eq. 2, with the k scaled rows A of :mod:`hybrid_force.control.constraint`)

    M q̈ + C q̇ + g = u + Aᵀ f,       A q̈ + γ = 0,

with the Mills & Goldenberg stabilisation of section 6.2 (φ̈ + 2α φ̇ + β_b² φ = 0):

    γ = drift + 2 α (A q̇) + β_b² φ,    φ = Φ / s  (the scaled constraint value).

``pin.forwardDynamics(model, data, tau, A, γ)`` solves this KKT system; its multiplier
(``data.lambda_c``) is f. f > 0: the surface pushes the tool towards the free side (the tool
presses on it). With the "tip" scaling f is the normal force at the tip in newtons.

The command may depend on f itself: u = u0 + B f (the hybrid law's algebraic loop). One
call of forwardDynamics at u = u0 gives (q̈0, f0) and leaves the factorisation
M = U D Uᵀ in ``data.U``, ``data.D``. With X = M⁻¹Aᵀ, Y = M⁻¹B, G = A X, H = A Y, the
constraint A q̈ = −γ (which q̈0 already satisfies) resolves the loop exactly:

    (G + H) f = G f0,      q̈ = q̈0 + X (f − f0) + Y f

(:func:`hybrid_force.sim._kernels.loop_resolve`; the tests compare it with a dense solve of
the same system, tests/oracles/plant.py).

Impacts: a plastic impact (restitution 0) at contact with the tool moving into the surface
sets A q̇⁺ = 0 with ``pin.impulseDynamics``; the impulse [N·s] is in the same convention as f.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.control.constraint import ConstraintTerms
from hybrid_force.errors import ScenarioError
from hybrid_force.schema import check_fields, param

_K = LazyKernels("hybrid_force.sim._kernels")

# entries of the solver's buffer before its arrays (_kernels.solver_parts)
_SOLVER_HEADER = 4

__all__ = [
    "Baumgarte",
    "ConstrainedDynamics",
    "free_acceleration",
    "plastic_impact",
]


@dataclass(frozen=True)
class Baumgarte:
    """Mills & Goldenberg stabilisation gains (section 6.2): φ̈ + 2α φ̇ + β² φ = 0.

    Attributes:
        alpha: α ≥ 0 [1/s]. beta: β ≥ 0 [1/s]. α = β is critical damping; 0 switches a term
            off. Defaults give a 20 ms time constant, far slower than dt = 1 ms and far faster
            than the motion.

    Raises ScenarioError (a BadInputError) for a gain that is not a finite real number
    ≥ 0 (a bool, a string, nan, −1), naming it as the scenario file's ``[sim]`` key
    (``baumgarte_alpha``, ``baumgarte_beta``). Gains are stored as floats.
    """

    alpha: float = param(
        50.0, unit="1/s", minimum=0.0, key="baumgarte_alpha", doc="Baumgarte α (section 6.2)"
    )
    beta: float = param(
        50.0, unit="1/s", minimum=0.0, key="baumgarte_beta", doc="Baumgarte β (section 6.2)"
    )

    def __post_init__(self) -> None:
        check_fields(self, ScenarioError, "sim.")

    def gamma(self, drift: np.ndarray, rate: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """γ (k,) for pin.forwardDynamics: drift + 2α φ̇ + β² φ."""
        return drift + 2.0 * self.alpha * rate + (self.beta * self.beta) * phi

    def gamma_into(
        self,
        drift: np.ndarray,
        rate: np.ndarray,
        value: np.ndarray,
        scale: np.ndarray,
        out: np.ndarray,
    ) -> np.ndarray:
        """:meth:`gamma` with φ = value / scale, written into out (k,) in one compiled call."""
        _K.baumgarte(drift, rate, value, scale, 2.0 * self.alpha, self.beta * self.beta, out)
        return out


def free_acceleration(M: np.ndarray, nle: np.ndarray, u: np.ndarray) -> np.ndarray:
    """q̈ = M⁻¹ (u − C q̇ − g) for an arm out of contact. M: (n, n); nle, u: (n,)."""
    return np.linalg.solve(M, u - nle)


class ConstrainedDynamics:
    """The constrained dynamics with the command u = u0 + B f, for one (model, data) pair.

    The views of ``data``'s arrays (nle, U, D) are taken once and the outputs preallocated:
    the arrays returned by :meth:`solve` are overwritten by the next call (a caller that
    keeps them across calls builds one instance per call). The multiplier ``data.lambda_c``
    is read at every call (forwardDynamics resizes it).

    The outputs :attr:`ddq` (n,), :attr:`f` (k,), the Baumgarte γ (k,) (:attr:`gamma`), the
    gains and the effort limits of :meth:`solve_checked` are views of one buffer
    (:func:`~hybrid_force.sim._kernels.solver_parts`): its two compiled calls take that
    buffer as one argument instead of six (Numba's call costs ~0.14 µs per array argument).

    Args:
        model, data: the Pinocchio model and the data that ``pin.crba`` fills each step.
        k: number of constraint rows.
        baumgarte: the gains :meth:`solve_checked` forms γ with (default: both 0).
        effort: (n,) the effort limits :meth:`solve_checked` checks [N·m or N] (default:
            none; :meth:`set_limits` changes them).
    """

    def __init__(
        self,
        model: pin.Model,
        data: pin.Data,
        k: int,
        baumgarte: Baumgarte | None = None,
        effort: np.ndarray | None = None,
    ) -> None:
        self.model, self.data = model, data
        self._nle, self._U, self._D = data.nle, data.U, data.D
        n = model.nv
        ws = np.zeros(_SOLVER_HEADER + n + 2 * k + n)
        gains = baumgarte if baumgarte is not None else Baumgarte(0.0, 0.0)
        # the same products as Baumgarte.gamma_into's, made once
        ws[:4] = (k, 0, 2.0 * gains.alpha, gains.beta * gains.beta)
        self._ws = ws
        o = _SOLVER_HEADER  # the layout of _kernels.solver_parts
        self.ddq, self.f = ws[o : o + n], ws[o + n : o + n + k]
        self.gamma = ws[o + n + k : o + n + 2 * k]
        self._effort = ws[o + n + 2 * k :]
        self.limits: np.ndarray | None = None
        self.set_limits(effort)
        self._stacked: ConstraintTerms | None = None  # the copy of k > 1 rows (_flat_of)
        # solve_checked's two kernels, bound at its first call (hybrid_force._jit.entry)
        self._kkt: Callable[..., None] | None = None
        self._loop: Callable[..., int] | None = None

    def set_limits(self, effort: np.ndarray | None) -> None:
        """The effort limits (n,) [N·m or N] :meth:`solve_checked` checks from now on (None:
        none), copied into the buffer; :attr:`limits` is the array given."""
        self.limits = effort
        self._ws[1] = 0 if effort is None else effort.shape[0]
        if effort is not None:
            self._effort[:] = effort

    def solve(
        self,
        nle: np.ndarray,
        u0: np.ndarray,
        B: np.ndarray | None,
        A: np.ndarray,
        gamma: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Solve the constrained dynamics with the command u = u0 + B f.

        Requires ``data.M`` to hold the mass matrix at the current q (``pin.crba`` was run on
        ``data``); ``data.nle`` is set here from ``nle``.

        Args:
            nle: (n,) C q̇ + g. u0: (n,). B: (n, k) or None. A: (k, n) constraint rows.
            gamma: (k,) γ with A q̈ + γ = 0.

        Returns:
            q̈ (n,) and f (k,) [N].
        """
        self._nle[:] = nle
        ddq0 = pin.forwardDynamics(self.model, self.data, u0, A, gamma)
        f0 = self.data.lambda_c
        if B is None:
            self.ddq[:] = ddq0
            self.f[:] = f0
        elif not _K.loop_resolve(self._U, self._D, A, B, ddq0, f0, self.ddq, self.f):
            raise np.linalg.LinAlgError(
                "the loop u = u0 + B f has no unique solution: A M⁻¹ (Aᵀ + B) is singular"
            )
        return self.ddq, self.f

    def solve_checked(
        self, nle: np.ndarray, u0: np.ndarray, B: np.ndarray, cons: ConstraintTerms
    ) -> bool:
        """:meth:`solve` with γ formed here and the effort limits checked, in two compiled
        calls around forwardDynamics (the plant's step: the same numbers as
        :meth:`Baumgarte.gamma_into`, :meth:`solve` and ``exceeds_effort``).

        Args:
            nle, u0: as in :meth:`solve`. B: (n, k), or (n, 0) for a command that does not
                depend on f. cons: the constraint's terms (its rows A, drift, A q̇, Φ and s;
                φ = Φ / s). γ is written into :attr:`gamma`, with the constructor's gains;
                the limits of :meth:`set_limits` are checked.

        Returns:
            True when the command u0 + B f is beyond some effort limit; q̈ and f in
            :attr:`ddq` and :attr:`f` (overwritten by the next call).

        Raises:
            numpy.linalg.LinAlgError: the loop has no unique solution (as :meth:`solve`).
        """
        flat, ws = self._flat_of(cons), self._ws
        kkt, loop = self._kkt, self._loop
        if kkt is None:  # bound at the first call (entry): packs, (n,) and (n, k) arrays
            kkt = self._kkt = entry(_K.kkt_inputs, flat, ws, nle, self._nle)
        kkt(flat, ws, nle, self._nle)
        ddq0 = pin.forwardDynamics(self.model, self.data, u0, cons.A, self.gamma)
        lam = self.data.lambda_c
        if loop is None:
            loop = self._loop = entry(_K.loop_checked, self._U, self._D, flat, B, ddq0, lam, u0, ws)
        status = loop(self._U, self._D, flat, B, ddq0, lam, u0, ws)
        if status < 0:
            raise np.linalg.LinAlgError(
                "the loop u = u0 + B f has no unique solution: A M⁻¹ (Aᵀ + B) is singular"
            )
        return status > 0

    def _flat_of(self, cons: ConstraintTerms) -> np.ndarray:
        """The flat array of ``ConstraintTerms.zeros`` that the kernels read: the terms' own
        (one surface), or for stacked rows (k > 1, made without one) a copy of the fields
        read (A, Φ, s, A q̇, drift) into this solver's own."""
        flat = cons._flat
        if flat is not None:
            return flat
        if self._stacked is None:
            self._stacked = ConstraintTerms.zeros(*cons.A.shape)
        own = self._stacked
        for name in ("A", "phi", "scale", "rate", "drift"):
            getattr(own, name)[...] = getattr(cons, name)
        assert own._flat is not None  # zeros() always makes its flat array
        return own._flat


def plastic_impact(
    model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray, A: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity after a plastic impact that enforces A q̇⁺ = 0, and the impulse (k,) [N·s].

    Uses ``pin.impulseDynamics`` (restitution 0): M (q̇⁺ − q̇⁻) = Aᵀ P, A q̇⁺ = 0.
    """
    pin.crba(model, data, q)
    v_after = pin.impulseDynamics(model, data, q, v, A, 0.0, 0.0).copy()
    return v_after, data.impulse_c.copy()

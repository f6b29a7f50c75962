"""Constrained forward dynamics of the arm: q̈ and the contact force f (section 6.2, eq. 2, 28).

In contact the arm obeys (eq. 2, with the k scaled rows A of :mod:`hybrid_force.constraint`)

    M q̈ + C q̇ + g = u + Aᵀ f,       A q̈ + γ = 0,

with the Mills & Goldenberg stabilisation of section 6.2 (φ̈ + 2α φ̇ + β_b² φ = 0):

    γ = drift + 2 α (A q̇) + β_b² φ,    φ = Φ / s  (the scaled constraint value).

``pin.forwardDynamics(model, data, tau, A, γ)`` solves this KKT system; its multiplier
(``data.lambda_c``) is f. f > 0: the surface pushes the tool towards the free side (the tool
presses on it). With the "tip" scaling f is the normal force at the tip in newtons.

The command may depend on f itself: u = u0 + B f (the hybrid law's algebraic loop). The KKT
solution is affine in the torque, f(τ) = f(u0) + L τ', so two (k + 1) calls of
forwardDynamics resolve the loop exactly:

    f = (I − L B)⁻¹ f(u0),      L B = [f(u0 + B e_j) − f(u0)]_j,
    q̈ = q̈(u0) + [q̈(u0 + B e_j) − q̈(u0)]_j f.

Impacts: a plastic impact (restitution 0) at contact with the tool moving into the surface
sets A q̇⁺ = 0 with ``pin.impulseDynamics``; the impulse [N·s] is in the same convention as f.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from hybrid_force._lazy import kernels
from hybrid_force.errors import SimulationError

__all__ = [
    "Baumgarte",
    "constrained_acceleration",
    "free_acceleration",
    "kkt_reference",
    "plastic_impact",
]


@dataclass(frozen=True)
class Baumgarte:
    """Mills & Goldenberg stabilisation gains (section 6.2): φ̈ + 2α φ̇ + β² φ = 0.

    Attributes:
        alpha: α [1/s]. beta: β [1/s]. α = β is critical damping. Defaults give a 20 ms time
            constant, far slower than dt = 1 ms and far faster than the motion.
    """

    alpha: float = 50.0
    beta: float = 50.0

    def __post_init__(self) -> None:
        for name in ("alpha", "beta"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise SimulationError(f"baumgarte {name} must be finite and >= 0, got {value!r}")

    def gamma(self, drift: np.ndarray, rate: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """γ (k,) for pin.forwardDynamics: drift + 2α φ̇ + β² φ."""
        return drift + 2.0 * self.alpha * rate + (self.beta * self.beta) * phi

    def gamma_one(self, drift: float, rate: float, phi: float) -> float:
        """:meth:`gamma` for one constraint, in floats (the same operations, in order)."""
        return drift + 2.0 * self.alpha * rate + (self.beta * self.beta) * phi


def free_acceleration(M: np.ndarray, nle: np.ndarray, u: np.ndarray) -> np.ndarray:
    """q̈ = M⁻¹ (u − C q̇ − g) for an arm out of contact. M: (n, n); nle, u: (n,)."""
    return np.linalg.solve(M, u - nle)


def constrained_acceleration(
    model: pin.Model,
    data: pin.Data,
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
    data.nle[:] = nle
    ddq0 = pin.forwardDynamics(model, data, u0, A, gamma).copy()
    f0 = data.lambda_c.copy()
    if B is None:
        return ddq0, f0
    k = A.shape[0]
    if k == 1:  # one compiled call for the scalar case of the lines below
        ddq1 = pin.forwardDynamics(model, data, u0 + B[:, 0], A, gamma)
        ddq = np.empty_like(ddq0)
        f0[0] = kernels().loop_one(ddq0, f0[0], ddq1, data.lambda_c[0], ddq)
        return ddq, f0
    LB = np.empty((k, k))
    DB = np.empty((ddq0.shape[0], k))
    for j in range(k):
        ddq_j = pin.forwardDynamics(model, data, u0 + B[:, j], A, gamma)
        DB[:, j] = ddq_j - ddq0
        LB[:, j] = data.lambda_c - f0
    f = np.linalg.solve(np.eye(k) - LB, f0)
    return ddq0 + DB @ f, f


def kkt_reference(
    M: np.ndarray,
    nle: np.ndarray,
    u0: np.ndarray,
    B: np.ndarray | None,
    A: np.ndarray,
    gamma: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Independent dense solution of the coupled system (for tests and the reference loop).

    [ M   −(Aᵀ + B) ] [q̈]   [u0 − nle]
    [ A        0    ] [f ] = [  −γ    ]
    """
    n, k = M.shape[0], A.shape[0]
    K = np.zeros((n + k, n + k))
    K[:n, :n] = M
    K[:n, n:] = -(A.T + (0.0 if B is None else B))
    K[n:, :n] = A
    rhs = np.concatenate([u0 - nle, -gamma])
    sol = np.linalg.solve(K, rhs)
    return sol[:n], sol[n:]


def plastic_impact(
    model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray, A: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity after a plastic impact that enforces A q̇⁺ = 0, and the impulse (k,) [N·s].

    Uses ``pin.impulseDynamics`` (restitution 0): M (q̇⁺ − q̇⁻) = Aᵀ P, A q̇⁺ = 0.
    """
    pin.crba(model, data, q)
    v_after = pin.impulseDynamics(model, data, q, v, A, 0.0, 0.0).copy()
    return v_after, data.impulse_c.copy()

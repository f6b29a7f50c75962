"""Stability of the sampled force loop: the largest β a sampled controller may use.

With ideal sensing at the plant's rate the hybrid law's command u = u0 + B f is resolved with
the plant exactly (:mod:`hybrid_force.control.laws.arimoto`). A sampled controller uses
instead the force it measured, and the loop becomes a recursion. Derivation (k = 1; each
eigen-direction of W below for k > 1):

* The plant in contact: M q̈ + h = u + Aᵀ f with A q̈ = −a_drift, so
  f = W⁻¹ (A M⁻¹ (h − u) − a_drift) with W = A M⁻¹ Aᵀ (the constraint's inverse effective
  mass, [m/(N·s²)] for the tip-normalised row).
* The law's force term is B f̃ = β M̂ A⁺ f̃ (eq. 4, 11 through q̈_r; M̂ = m M the controller's
  model, m = ``control.mass_factor``), and A M⁻¹ M̂ A⁺ = m A A⁺ = m, so
  f = c − a f̃ with a = β m / W: what the torque held over a control period produces, for the
  measured force f̃ the controller used; c collects everything else (it varies slowly).
* The sensor reads at tick k the force of the period before, x_k = c − a ỹ_{k−1}; its
  low-pass gives y_k = (1 − α) y_{k−1} + α x_k (α = 1 − e^{−2π f_c T}, α = 1 without filter)
  and the controller uses ỹ_k = y_{k−d} (``force_delay`` = d periods). The homogeneous
  recursion y_k − (1 − α) y_{k−1} + α a y_{k−1−d} = 0 has the characteristic polynomial

      z^{d+1} − (1 − α) z^d + α a = 0,

  and the loop converges iff every root lies inside the unit circle: a < a*(α, d). Without a
  filter a* = 1 for every delay (z^{d+1} = −a); with a filter and no delay a* = 2/α − 1.

So β < β_max = a*(α, d) · W / m, with W at its smallest over the configurations of the run
(:func:`inverse_effective_mass` on the desired path). The bound holds for the plant's own
step being shorter than the control period too (the force then settles within the period
to c − a f̃ and the recursion is per tick).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from hybrid_force.geometry.surfaces import Surface
from hybrid_force.model.robot import Robot

__all__ = ["beta_bound", "inverse_effective_mass", "max_stable_gain", "spectral_radius"]


def spectral_radius(a: float, alpha: float, delay: int) -> float:
    """Largest |z| among the roots of z^{d+1} − (1 − α) z^d + α a (see the module docstring).

    The eigenvalues of the (d+1)×(d+1) companion matrix: cost ∝ d³, for checks and studies;
    :func:`max_stable_gain` does not call it."""
    coefficients = np.zeros(delay + 2)
    coefficients[0] = 1.0
    coefficients[1] = -(1.0 - alpha)
    coefficients[-1] += alpha * a
    return float(np.abs(np.roots(coefficients)).max())


def max_stable_gain(alpha: float, delay: int) -> float:
    """a*(α, d): the loop gain a = β m / W at which the recursion stops converging.

    O(1) in the delay (the eigenvalues of the degree-(d+1) polynomial cost ∝ d³): a root
    crosses the unit circle at z = e^{iθ} when e^{iθ} − b = −c e^{−idθ} (b = 1 − α, c = α a),
    so c = |e^{iθ} − b| and ψ(θ) + dθ = π with ψ = arg(e^{iθ} − b). Both |e^{iθ} − b| and
    ψ(θ) + dθ increase on [0, π], so the first crossing, the smallest c, is the one root θ*
    of ψ(θ) + dθ = π; it lies in (0, π/(d+1)] since ψ(θ) ≥ θ. Below c* = |e^{iθ*} − b| no
    root has reached the circle (at a → 0 the roots are 0 and b, inside it).

    Args:
        alpha: the filter's α in (0, 1] (1: no filter). delay: d ≥ 0 control periods.
    """
    if alpha >= 1.0:
        return 1.0  # z^{d+1} = −a: |z| = a^{1/(d+1)}
    if delay == 0:
        return 2.0 / alpha - 1.0  # z = 1 − α(1 + a)
    b = 1.0 - alpha
    low, high = 0.0, math.pi / (delay + 1)
    for _ in range(200):  # bisection on a monotone function: stops when the bracket is one ulp
        mid = 0.5 * (low + high)
        if mid in (low, high):
            break
        if math.atan2(math.sin(mid), math.cos(mid) - b) + delay * mid < math.pi:
            low = mid
        else:
            high = mid
    theta = 0.5 * (low + high)
    # |e^{iθ} − b|² = (1 − b)² + 4 b sin²(θ/2), without the cancellation of 1 − 2b cos θ + b²
    return math.sqrt(alpha * alpha + 4.0 * b * math.sin(0.5 * theta) ** 2) / alpha


def inverse_effective_mass(
    robot: Robot, surfaces: Sequence[Surface], configurations: Iterable[np.ndarray], row: str
) -> float:
    """min over the configurations of λ_min(A M⁻¹ Aᵀ) [m/(N·s²) for the "tip" row].

    Args:
        robot: the plant. surfaces: the k surfaces. configurations: q (nq,) samples of the run
            (e.g. the desired path). row: ``sim.normalization``, "tip" (n̂ᵀJ) or "joint"
            (the paper's unit row J_Φ/‖J_Φ‖).
    """
    from hybrid_force.control.constraint import Constraint

    constraint = Constraint(list(surfaces))
    smallest = np.inf
    for q in configurations:
        A, _ = constraint.normal_rows(robot.tip_position(q), robot.jacobian(q))
        if row == "joint":
            A = A / np.linalg.norm(A, axis=1, keepdims=True)
        W = A @ np.linalg.solve(robot.mass_matrix(q), A.T)
        smallest = min(smallest, float(np.linalg.eigvalsh(W).min()))
    return smallest


def beta_bound(w_min: float, mass_factor: float, alpha: float, delay: int) -> float:
    """β_max = a*(α, d) · W_min / m (module docstring)."""
    return max_stable_gain(alpha, delay) * w_min / mass_factor

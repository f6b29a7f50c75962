"""Stability of the sampled force loop: the largest β a sampled controller may use, and the
recursions every law's own pre-run checks use (``loop_bounds`` in each law's module, through
:func:`~hybrid_force.control.laws.base.law_loop_bounds`): the force loop with an integral
(:func:`loop_radius`, :func:`max_stable_loop_gain`, :func:`largest_integral_step`), the
feed-through of a force term against the plant (:func:`force_feedthrough`) and the sampled
velocity loop (:func:`velocity_loop_number`).

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
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from hybrid_force.control.constraint import Constraint
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.model.robot import Robot

__all__ = [
    "beta_bound",
    "force_feedthrough",
    "inverse_effective_mass",
    "largest_integral_step",
    "loop_radius",
    "max_stable_gain",
    "max_stable_loop_gain",
    "spectral_radius",
    "velocity_loop_number",
]


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


# --- every law's own loops (hybrid_force.control.laws.*: loop_bounds) -----------------------------
#
# A law whose command holds a force term u ∋ B f̃ (its proportional force gain) and an integral
# term u ∋ −Aᵀ b e_F (e_F = ∫(f̃ − f_d) dt, the supervisor's, advanced at each tick with the
# reading of the tick before) gives on a rigid surface, from f = W⁻¹(A M⁻¹(h − u) − a_drift)
# with the PLANT's W = A M⁻¹ Aᵀ:
#
#     f_k = c − a f̃_k − b E_k,    a = W⁻¹ A M⁻¹ B (per unit of the law's gain),
#     E_k = E_{k−1} + T f̃_{k−1}
#
# and with the sensor of the module docstring (f̃ the reading one period late, filtered, d
# periods more), the characteristic polynomial of the loop is
#
#     (z − (1 − α)) (z − 1) z^d + α (a (z − 1) + b T) = 0.
#
# With b = 0 it is (z − 1) times the polynomial of the module docstring (the root z = 1 is the
# integral's, which then nothing drives); with α = 1, d = 0 it is z² + (a − 1) z + (bT − a),
# stable (Jury) iff a < 1 + bT/2 and bT < 1 + a.


def loop_radius(a: float, bT: float, alpha: float, delay: int) -> float:
    """Largest |z| of (z − (1 − α))(z − 1) z^d + α (a (z − 1) + bT) (the comment above).

    Args:
        a: the proportional loop gain [-]. bT: the integral gain × the control period [-].
        alpha: the sensor filter's α in (0, 1]. delay: d ≥ 0 control periods.
    """
    if bT == 0.0:
        return spectral_radius(a, alpha, delay)
    base = np.polymul([1.0, -(1.0 - alpha)], [1.0, -1.0])  # (z − (1 − α))(z − 1)
    coefficients = np.concatenate([base, np.zeros(delay)])  # × z^d
    coefficients[-2] += alpha * a
    coefficients[-1] += alpha * (bT - a)
    return float(np.abs(np.roots(coefficients)).max())


def _first_crossing(value: Callable[[np.ndarray], np.ndarray], delay: int) -> float:
    """The smallest gain g > 0 at which a root of the loop reaches the unit circle.

    ``value(θ)`` gives, for z = e^{iθ}, the (complex) gain g that puts a root at z: the
    crossings are the θ ∈ (0, π] where it is real (z = e^{−iθ} is the conjugate root, z = 1
    is no crossing for these loops). Im value(θ) turns at most about d times on (0, π], so it
    is sampled at 32 (d + 2) points and each sign change refined by bisection: O(d) work,
    against O(d³) for the polynomial's roots (d = 100 000 periods: about 0.5 s).
    """
    theta = np.linspace(0.0, math.pi, 32 * (delay + 2) + 1)[1:]
    v = value(theta)
    found = [float(v.real[-1])]  # z = −1 (θ = π): the value is real there
    im = v.imag
    change = np.nonzero(np.signbit(im[:-1]) != np.signbit(im[1:]))[0]
    if change.size:
        low, high = theta[change], theta[change + 1]
        sign_low = np.signbit(im[change])
        for _ in range(60):
            mid = 0.5 * (low + high)
            same = np.signbit(value(mid).imag) == sign_low
            low, high = np.where(same, mid, low), np.where(same, high, mid)
        found.extend(value(0.5 * (low + high)).real.tolist())
    positive = [g for g in found if g > 0.0]
    return min(positive) if positive else math.inf


def max_stable_loop_gain(bT: float, alpha: float, delay: int) -> float:
    """The largest proportional loop gain a ≥ 0 for which :func:`loop_radius` < 1 with the
    integral bT: :func:`max_stable_gain` for bT = 0, else the first a at which a root of
    (z − (1 − α))(z − 1) z^d + α (a (z − 1) + bT) reaches the unit circle, where
    a = −(z − (1 − α)) z^d / α − bT / (z − 1) is real (:func:`_first_crossing`, O(d)); 0 when
    even a = 0 is unstable (the integral alone too fast: bT ≥ 1 without a filter)."""
    if bT == 0.0:
        return max_stable_gain(alpha, delay)
    if not bT < largest_integral_step(alpha, delay):
        return 0.0
    b = 1.0 - alpha

    def gain(theta: np.ndarray) -> np.ndarray:
        z = np.exp(1j * theta)
        return -(z - b) * np.exp(1j * delay * theta) / alpha - bT / (z - 1.0)

    return _first_crossing(gain, delay)


def largest_integral_step(alpha: float, delay: int) -> float:
    """The largest bT (integral gain × period) for which a law with no proportional force
    term (a = 0) is stable: the first bT = −(z − (1 − α))(z − 1) z^d / α that is real on the
    unit circle (:func:`_first_crossing`; 1 without filter and delay). The root at z = 1 of
    bT = 0 moves inside for bT > 0."""
    b = 1.0 - alpha

    def step(theta: np.ndarray) -> np.ndarray:
        z = np.exp(1j * theta)
        return -(z - b) * (z - 1.0) * np.exp(1j * delay * theta) / alpha

    return _first_crossing(step, delay)


def force_feedthrough(plant_mass: np.ndarray, A: np.ndarray, B: np.ndarray) -> float:
    """a = ρ(W⁻¹ A M⁻¹ B): the recursion gain of a force term u ∋ B f̃ (comment above).

    Args:
        plant_mass: (n, n) the PLANT's M(q). A: (k, n) the plant's rows at q.
        B: (n, k) the law's force term per unit of its gain, from the CONTROLLER's model.
    """
    Minv_AT = np.linalg.solve(plant_mass, A.T)
    W = A @ Minv_AT
    G = np.linalg.solve(W, Minv_AT.T @ B)
    return float(np.abs(np.linalg.eigvals(G)).max())


def velocity_loop_number(plant_mass: np.ndarray, damping: np.ndarray, period: float) -> float:
    """T λ_max(M⁻¹ G): the sampled velocity loop's number (stable below 2).

    A law whose torque holds a velocity feedback −G q̇ over the control period T (G (n, n) the
    law's joint damping built from the CONTROLLER's model) gives, with the PLANT's M, the held
    acceleration q̈ = −M⁻¹ G q̇_k + …, so over one period q̇_{k+1} = (I − T M⁻¹ G) q̇_k + …: the
    eigenvalues 1 − T λ_i(M⁻¹ G) lie inside the unit circle iff T λ_max(M⁻¹ G) < 2 (the
    position feedback adds T² K/2 to the determinant only, negligible at T K/G ≪ 1). M⁻¹ G has
    real eigenvalues for a symmetric positive semi-definite G (it is similar to
    M^{-1/2} G M^{-1/2}).
    """
    values = np.linalg.eigvals(np.linalg.solve(plant_mass, damping)).real
    return float(values.max()) * period

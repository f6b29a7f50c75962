"""How the surface pushes back: a rigid or compliant normal force, and Coulomb friction.

These are the plant's (:class:`~hybrid_force.sim.plant.Plant`); the controller never reads
them. The scenario's ``[contact]`` table sets them (:class:`ContactSettings`); derivations and
studies are in docs/contact.md.

**Rigid** (``model = "rigid"``, the default, the paper's world): the normal force is the
Lagrange multiplier of the constraint A q̈ + γ = 0 (section 6.2,
:mod:`hybrid_force.sim.dynamics`).

**Compliant** (``model = "compliant"``): the force follows from the penetration
δ = −d [m] (d: the tip's signed metric distance to the surface, > 0 on the free side) and its
rate δ̇ = −ḋ = −A q̇ [m/s], by Hunt and Crossley's law (J. Appl. Mech. 42, 1975)::

    f = k δⁿ (1 + c δ̇)   where δ > 0,   clipped at f ≥ 0 (the surface never pulls);  else 0

with ``stiffness`` k [N/mⁿ], ``damping`` c [s/m] and ``exponent`` n ≥ 1 (1: a linear spring;
3/2: Hertz's sphere on a plane). Why not the linear spring–damper k δ + d δ̇: its damper acts
at δ = 0, so the force jumps to d·δ̇ on touch and would pull while the tool leaves; Hunt and
Crossley's damping vanishes with δ, the force is continuous at touch and at separation, and
its coefficient of restitution falls with the impact speed, e ≈ 1 − (2/3) c v⁻, as measured
on metals. The torque on the arm is Aᵀ f (A = n̂ᵀJ, the "tip" row scaling: f in N).

**Friction** (``friction`` = μ ≥ 0): Coulomb friction at the tip, opposite to the tip's
sliding velocity v_t = (I − n̂n̂ᵀ) J q̇, regularised so that the step stays explicit::

    F_t = −μ f v_t / √(‖v_t‖² + ε²),     ε = ``friction_velocity`` [m/s]

Sliding at ‖v_t‖ ≫ ε it is μ f opposite to v_t within a relative ε²/(2‖v_t‖²); a tangential
push F < μ f does not stick exactly but creeps at v = ε F / √((μ f)² − F²) (documented bound,
tested). It is linear in f for a given velocity, so with a rigid contact the plant adds
−μ Jᵀ t̂ to the loop's B (u = u0 + B f) and solves force and friction together, exactly.

**Time step** (docs/contact.md derives both bounds; semi-implicit Euler):

* compliant: linearised at the operating force f0 the contact is a spring
  k₁ = n k δ0ⁿ⁻¹ (δ0 = (f0/k)^(1/n)) and a damper d = c f0 on the effective mass 1/W along
  the normal, W = λ_max(A M⁻¹ Aᵀ) [1/kg]; with ω² = k₁ W and ζ = d W / (2ω) the step is stable
  iff ω dt < 2 (√(1 + ζ²) − ζ);
* friction: near sticking F_t is a damper of coefficient μ f / ε, explicit in the velocity;
  with W_t the tangential part of J M⁻¹ Jᵀ the step is stable iff (μ f / ε) W_t dt < 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from hybrid_force.errors import ScenarioError, SurfaceError
from hybrid_force.schema import check_fields, param

if TYPE_CHECKING:
    from collections.abc import Sequence

    from hybrid_force.geometry.surface_base import Surface
    from hybrid_force.model.robot import Robot

__all__ = [
    "ContactModel",
    "ContactSettings",
    "compliant_force",
    "creep_velocity",
    "friction_matrix",
    "friction_power",
    "joint_dissipation",
    "largest_stable_dt",
    "regularised_speed",
    "stable_dt_compliant",
    "stable_dt_friction",
    "step_text",
]

ContactModel = Literal["rigid", "compliant"]


@dataclass(frozen=True)
class ContactSettings:
    """The contact model (the scenario's ``[contact]`` table).

    Attributes:
        model: "rigid" (Lagrange multiplier, the paper) or "compliant" (Hunt–Crossley).
        stiffness: k [N/mⁿ] > 0 of the compliant law.
        damping: c [s/m] ≥ 0 of the compliant law.
        exponent: n ≥ 1 of the compliant law.
        friction: Coulomb coefficient μ ≥ 0 (0: frictionless, the paper).
        friction_velocity: regularisation velocity ε [m/s] > 0 of the friction law.
    """

    model: ContactModel = param("rigid", doc="rigid (Lagrange multiplier) or compliant")
    stiffness: float = param(
        1e6, unit="N/m^n", minimum=0.0, strict=True, acts_when=("model", "compliant"),
        doc="k of the compliant law",
    )  # fmt: skip
    damping: float = param(
        0.0, unit="s/m", minimum=0.0, acts_when=("model", "compliant"), doc="c of the compliant law"
    )
    exponent: float = param(
        1.0, minimum=1.0, acts_when=("model", "compliant"), doc="n of the compliant law"
    )
    friction: float = param(0.0, minimum=0.0, doc="Coulomb coefficient μ (0: frictionless)")
    friction_velocity: float = param(
        1e-3, unit="m/s", minimum=0.0, strict=True, acts_when=("friction", ">", 0),
        doc="regularisation velocity ε of friction",
    )  # fmt: skip

    def __post_init__(self) -> None:
        check_fields(self, ScenarioError, "contact.")

    @property
    def compliant(self) -> bool:
        return self.model == "compliant"

    @property
    def ideal(self) -> bool:
        """True for the paper's contact: rigid and frictionless."""
        return self.model == "rigid" and self.friction == 0.0

    def to_dict(self) -> dict[str, Any]:
        """The settings as JSON-able data (stored in a result's meta)."""
        return {
            "model": self.model,
            "stiffness": self.stiffness,
            "damping": self.damping,
            "exponent": self.exponent,
            "friction": self.friction,
            "friction_velocity": self.friction_velocity,
        }


def compliant_force(
    settings: ContactSettings, penetration: np.ndarray, rate: np.ndarray
) -> np.ndarray:
    """Hunt–Crossley normal force f = max(0, k δⁿ (1 + c δ̇)) where δ > 0, else 0.

    Args:
        settings: the contact settings.
        penetration: (k,) δ [m] (> 0 inside the surface).
        rate: (k,) δ̇ [m/s].

    Returns:
        (k,) f ≥ 0 [N].
    """
    inside = np.maximum(penetration, 0.0)
    spring = settings.stiffness * inside**settings.exponent
    return np.maximum(spring * (1.0 + settings.damping * rate), 0.0)


def friction_matrix(
    mu: float, eps: float, normals: np.ndarray, J: np.ndarray, pdot: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The friction torque per newton of normal force, and the sliding speeds.

    The friction torque is τ_f = F f, with column i of F the torque of a unit normal force on
    surface i: −μ Jᵀ v_t,i / √(‖v_t,i‖² + ε²) (module docstring).

    Args:
        mu: μ. eps: ε [m/s].
        normals: (k, 3) unit normals n̂_i at the tip. J: (3, n) tip Jacobian [m/rad or m/m].
        pdot: (3,) tip velocity J q̇ [m/s].

    Returns:
        F: (n, k) [N·m/N or N/N]; speed: (k,) ‖v_t,i‖ [m/s].
    """
    tangential = pdot[None, :] - normals * (normals @ pdot)[:, None]  # (k, 3)
    speed = np.sqrt(np.einsum("ij,ij->i", tangential, tangential))
    direction = tangential / regularised_speed(speed, eps)[:, None]
    return -mu * (J.T @ direction.T), speed


def friction_power(mu: float, eps: float, f: np.ndarray, speed: np.ndarray) -> float:
    """Power dissipated by the regularised friction, Σ μ fᵢ ‖v_t,i‖² / √(‖v_t,i‖² + ε²) [W]."""
    return float(np.sum(mu * np.maximum(f, 0.0) * speed**2 / regularised_speed(speed, eps)))


def regularised_speed(speed: np.ndarray, eps: float) -> np.ndarray:
    """√(s² + ε²) [m/s or rad/s]: the regularised Coulomb law's denominator, F = −μ f v/√(‖v‖²
    + ε²) at the tip and τ = −τ_c q̇/√(q̇² + ε²) at a joint (one law for both)."""
    return np.sqrt(speed**2 + eps**2)


def joint_dissipation(
    damping: np.ndarray, friction: np.ndarray, eps: float, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The joints' own viscous damping and regularised Coulomb friction at the velocity v, as
    damping coefficients: the torque is τ_j = −(d + c(q̇)) q̇ with

        c(q̇) = τ_c / √(q̇² + ε²)     (the tip friction's regularisation, :func:`regularised_speed`)

    so τ_j = −d q̇ − τ_c q̇/√(q̇² + ε²), with d and τ_c the model's ``damping`` and
    ``friction`` (URDF ``<dynamics damping friction>``, MJCF ``damping``/``frictionloss``).
    The plant applies it with the coefficients at the step's start and the velocity at its
    end (:class:`~hybrid_force.sim.plant.Plant`); either way each part dissipates
    d q̇² ≥ 0 and c q̇² ≥ 0 [W].

    Args:
        damping: (n,) d ≥ 0 [N·m·s/rad or N·s/m]. friction: (n,) τ_c ≥ 0 [N·m or N].
        eps: ε [rad/s or m/s] > 0. v: (n,) q̇ [rad/s or m/s].

    Returns:
        (n,) d and (n,) c(q̇) [N·m·s/rad or N·s/m].
    """
    return damping, friction / regularised_speed(np.abs(v), eps)


def creep_velocity(mu: float, eps: float, f: float, push: float) -> float:
    """Steady sliding speed [m/s] of the regularised law under a tangential push [N] below μ f:
    v = ε F / √((μ f)² − F²) (the push balances μ f v / √(v² + ε²)); inf at or beyond μ f."""
    limit = mu * f
    if abs(push) >= limit:
        return math.inf
    return eps * abs(push) / math.sqrt(limit**2 - push**2)


def step_text(dt_max: float) -> str:
    """dt_max [s] rounded *down* to 3 significant digits, as text: a step a user copies from a
    message is stable."""
    if not math.isfinite(dt_max) or dt_max <= 0:
        return f"{dt_max:g}"
    scale = 10.0 ** (math.floor(math.log10(dt_max)) - 2)
    shown = math.floor(dt_max / scale) * scale
    while shown > dt_max:  # the product's round-off
        shown -= scale
    return f"{shown:.3g}"


def _largest_step(omega: float, zeta: float) -> float:
    """Largest stable semi-implicit Euler step of ẍ = −ω² x − 2ζω ẋ: (2/ω)(√(1+ζ²) − ζ)."""
    if omega <= 0.0:
        return math.inf
    return 2.0 / omega * (math.sqrt(1.0 + zeta**2) - zeta)


def stable_dt_compliant(settings: ContactSettings, W: float, f0: float) -> float:
    """Largest stable step [s] of the compliant contact at the operating force f0 [N].

    Args:
        settings: the contact settings (compliant).
        W: λ_max(A M⁻¹ Aᵀ) [1/kg], the inverse effective mass along the normal.
        f0: the operating normal force [N] (the task's f_d); the linearisation point.
    """
    k, n, c = settings.stiffness, settings.exponent, settings.damping
    f0 = max(f0, 0.0)
    if n == 1.0:
        k1 = k
    else:
        delta0 = (f0 / k) ** (1.0 / n)
        k1 = n * k * delta0 ** (n - 1.0)
    omega = math.sqrt(k1 * W)
    zeta = c * f0 * W / (2.0 * omega) if omega > 0 else 0.0
    return _largest_step(omega, zeta)


def stable_dt_friction(settings: ContactSettings, W_t: float, f0: float) -> float:
    """Largest stable step [s] of the regularised friction near sticking at normal force f0 [N]:
    2 ε / (μ f0 W_t), W_t [1/kg] the largest tangential inverse effective mass."""
    rate = settings.friction * max(f0, 0.0) * W_t / settings.friction_velocity
    return math.inf if rate <= 0.0 else 2.0 / rate


def largest_stable_dt(
    settings: ContactSettings,
    robot: Robot,
    surfaces: Sequence[Surface],
    configurations: Sequence[np.ndarray],
    f0: float,
) -> float:
    """The largest stable step [s] of the contact model over some configurations of the arm.

    The smaller of :func:`stable_dt_compliant` (compliant model) and :func:`stable_dt_friction`
    (μ > 0), with W and W_t from M and the tip Jacobian at each configuration and the surfaces'
    normals at its tip; inf for the paper's rigid frictionless contact. Configurations whose
    tip is where a normal is undefined (a cylinder's axis) are skipped.

    Args:
        settings: the contact settings.
        robot: the plant's arm.
        surfaces: the surfaces the tip touches.
        configurations: joint configurations (nq,) to check, e.g. the start and the desired
            joint path's samples.
        f0: the operating normal force [N] (the task's largest f_d).
    """

    if not settings.compliant and settings.friction == 0.0:
        return math.inf
    data = robot.new_data()
    zero = np.zeros(robot.nv)
    best = math.inf
    for q in configurations:
        terms = robot.terms(np.asarray(q, dtype=float), zero, data)
        G = terms.J @ np.linalg.solve(terms.M, terms.J.T)  # (3, 3) tip inverse inertia [1/kg]
        for surface in surfaces:
            try:
                normal = surface.normal(terms.p)
            except SurfaceError:
                continue
            if settings.compliant:
                best = min(best, stable_dt_compliant(settings, float(normal @ G @ normal), f0))
            if settings.friction > 0.0:
                P = np.eye(3) - np.outer(normal, normal)
                W_t = float(np.linalg.eigvalsh(P @ G @ P)[-1])
                best = min(best, stable_dt_friction(settings, W_t, f0))
    return best

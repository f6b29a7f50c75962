"""The arm's dynamics as linear functions of its inertial parameters (Slotine & Li's regressor).

Every body b of a Pinocchio model has 10 dynamic parameters (``Inertia.toDynamicParameters``),
in this order, with the rotational inertia taken about the body frame's origin:

    π_b = (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)     [kg, kg·m, kg·m²]

and the inverse dynamics is linear in θ = (π_1, …, π_B) (B = njoints − 1 moving bodies; the
fixed base, and the links that fixed or locked joints merge into their parent, are not bodies
of their own): ``pin.computeJointTorqueRegressor(q, v, a)`` gives Y_rnea (n, 10 B) with

    Y_rnea(q, v, a) θ = M(q) a + c(q, v) + g(q),          c(q, v) = C(q, v) v.

**Slotine–Li regressor.** An adaptive law needs the torques at two different velocities,
M(q) q̈_r + C(q, q̇) q̇_r + g(q) = Y(q, q̇, q̇_r, q̈_r) θ, with C the Coriolis matrix of the law
(:class:`~hybrid_force.model.robot.RobotTerms`, Pinocchio's ``computeCoriolisMatrix``).
Derivation: Pinocchio's C is the Christoffel one, C(q, v)_ij = Σ_k Γ_ijk v_k with
Γ_ijk = ½(∂M_ij/∂q_k + ∂M_ik/∂q_j − ∂M_jk/∂q_i) (checked in the tests against finite differences
of M, and by the property that characterises it: C(q, v) w = C(q, w) v). Γ_ijk is symmetric in
j, k, so b(v, w) = C(q, v) w is a symmetric bilinear form with b(v, v) = c(q, v), and
polarisation gives, for any w,

    C(q, v) w = b(v, w) = ¼ [c(q, v + w) − c(q, v − w)]

(expand: c(v ± w) = c(v) ± 2 b(v, w) + c(w)). Each c is linear in θ, with regressor
Y_rnea(q, v ± w, 0) computed without gravity, so

    Y(q, q̇, q̇_r, q̈_r) = Y_rnea(q, 0, q̈_r) + ¼ [Y⁰_rnea(q, q̇ + q̇_r, 0) − Y⁰_rnea(q, q̇ − q̇_r, 0)]

(Y⁰: the model with zero gravity): three regressor passes, O(n) each. The terms also split by
kind: M(q) a = Y⁰_rnea(q, 0, a) θ (:meth:`SlotineLiRegressor.inertial`) and g(q) =
Y_rnea(q, 0, 0) θ.

**Visible parameters.** A column of Y that is zero at every state belongs to a parameter the
joint torques never depend on (the mass of a link that only turns about a vertical axis through
its origin, say): no measurement can tell its value. :func:`visible_columns` finds them from the
regressor at random states (:func:`sample_regressors`, fixed seed): Y is analytic in q and
polynomial in (q̇, q̈), so a column that vanishes at generic states vanishes everywhere.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

__all__ = [
    "PARAMETER_LABELS",
    "SlotineLiRegressor",
    "body_names",
    "dynamic_parameters",
    "parameter_names",
    "sample_regressors",
    "visible_columns",
]

#: The 10 dynamic parameters of a body, in Pinocchio's order (inertia about the body origin).
PARAMETER_LABELS: tuple[str, ...] = (
    "m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz"
)  # fmt: skip
_VISIBLE_TOLERANCE = 1e-10  # relative column norm below which a column counts as zero


def dynamic_parameters(model: pin.Model) -> np.ndarray:
    """θ (10 B,): the dynamic parameters of the model's moving bodies, body after body."""
    return np.concatenate(
        [model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)]
    )


def body_names(model: pin.Model) -> tuple[str, ...]:
    """The link each moving joint carries (the first body frame on the joint), else the joint."""
    names = []
    for j in range(1, model.njoints):
        links = [f.name for f in model.frames if f.type == pin.BODY and f.parentJoint == j]
        names.append(links[0] if links else model.names[j])
    return tuple(names)


def parameter_names(model: pin.Model) -> tuple[str, ...]:
    """``"<link>.<label>"`` for each entry of :func:`dynamic_parameters` (e.g. ``link3.mcx``)."""
    return tuple(f"{body}.{label}" for body in body_names(model) for label in PARAMETER_LABELS)


class SlotineLiRegressor:
    """Y(q, q̇, q̇_r, q̈_r) (n, 10 B) with Y θ = M q̈_r + C(q, q̇) q̇_r + g (module docstring).

    Owns two Pinocchio data objects (one for the model with gravity, one for a copy without);
    the arrays returned are new at every call (Pinocchio's bindings return a copy of the
    regressor; each result is used before the next pass on the same data all the same).

    Args:
        model: the arm's Pinocchio model (its gravity is the one g uses).
    """

    def __init__(self, model: pin.Model) -> None:
        self.model = model
        self.data = model.createData()
        self.model0 = model.copy()
        self.model0.gravity = pin.Motion.Zero()
        self.data0 = self.model0.createData()
        self.n = model.nv
        self.zeros = np.zeros(model.nv)

    @property
    def size(self) -> int:
        """Number of parameters p = 10 B (columns of Y)."""
        return 10 * (self.model.njoints - 1)

    def __call__(
        self, q: np.ndarray, v: np.ndarray, qdot_r: np.ndarray, qddot_r: np.ndarray
    ) -> np.ndarray:
        """Y (n, p) with Y θ = M(q) q̈_r + C(q, v) q̇_r + g(q) [N·m or N per parameter unit].

        Args:
            q: (nq,) configuration. v: (n,) joint velocity, the one C is evaluated at.
            qdot_r, qddot_r: (n,) the velocity C multiplies and the acceleration M does.
        """
        Y = pin.computeJointTorqueRegressor(self.model, self.data, q, self.zeros, qddot_r)
        Y += 0.25 * self._velocity(q, v + qdot_r)
        Y -= 0.25 * self._velocity(q, v - qdot_r)
        return Y

    def inertial(self, q: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Y_M (n, p) with Y_M θ = M(q) a, for a (n,) [rad/s² or m/s²]."""
        return pin.computeJointTorqueRegressor(self.model0, self.data0, q, self.zeros, a)

    def coriolis(self, q: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Y_C (n, p) with Y_C θ = C(q, v) w (by polarisation, module docstring)."""
        Y = 0.25 * self._velocity(q, v + w)
        Y -= 0.25 * self._velocity(q, v - w)
        return Y

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """Y_g (n, p) with Y_g θ = g(q)."""
        z = self.zeros
        return pin.computeJointTorqueRegressor(self.model, self.data, q, z, z)

    def _velocity(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Y⁰_rnea(q, v, 0): the regressor of c(q, v) = C(q, v) v (no gravity)."""
        return pin.computeJointTorqueRegressor(self.model0, self.data0, q, v, self.zeros)


def sample_regressors(
    regressor: SlotineLiRegressor, q0: np.ndarray, samples: int = 8, seed: int = 0
) -> np.ndarray:
    """(samples, n, p): Y_rnea(q, v, a) at random states around q0, with a fixed seed.

    q = q0 ⊕ U(−0.5, 0.5) per coordinate [rad or m], v and a standard normal [per s, per s²]:
    generic states near the arm's start, for :func:`visible_columns` and for the scale of an
    adaptation gain.

    Args:
        q0: (nq,) the configuration to sample around (an arm's start).
    """
    model, data = regressor.model, regressor.data
    rng = np.random.default_rng(seed)
    n = model.nv
    out = np.empty((samples, n, regressor.size))
    for i in range(samples):
        q = pin.integrate(model, np.asarray(q0, dtype=float), rng.uniform(-0.5, 0.5, n))
        v, a = rng.standard_normal(n), rng.standard_normal(n)
        out[i] = pin.computeJointTorqueRegressor(model, data, q, v, a)
    return out


def visible_columns(samples: np.ndarray) -> np.ndarray:
    """(p,) bool: the parameters the joint torques depend on (module docstring).

    Args:
        samples: (S, n, p) regressors at generic states (:func:`sample_regressors`); a column
            is visible when its norm over them exceeds 1e-10 times the largest column's.
    """
    norms = np.sqrt(np.square(samples).sum(axis=(0, 1)))
    return norms > _VISIBLE_TOLERANCE * norms.max()

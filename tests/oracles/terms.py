"""The oracles of one step's terms: the robot's from one public method each, the constraint's
from each surface's value, gradient and Hessian with the general k-row algebra in plain numpy.

``robot_terms`` checks :meth:`Robot.terms <hybrid_force.model.robot.Robot.terms>` (six Pinocchio
calls and a kernel); ``constraint_terms`` checks :meth:`Constraint.evaluate
<hybrid_force.control.constraint.Constraint.evaluate>` (the k = 1 kernel and the stacked
numpy algebra), raising the same SurfaceError where the rows are undefined.
Both return new arrays.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hybrid_force.control.constraint import (
    _COND_TOL,
    _GRAD_TOL,
    _ROW_TOL,
    Constraint,
    ConstraintTerms,
)
from hybrid_force.errors import SurfaceError
from hybrid_force.model.robot import LWA, Robot, RobotTerms

__all__ = ["constraint_terms", "robot_terms"]


def robot_terms(robot: Robot, q: np.ndarray, v: np.ndarray) -> RobotTerms:
    """The robot's terms at (q (nq,), v (nv,)), each from its own public method: M, C, g,
    p [m], J (3, n), J̇ (3, n), J̇ v [m/s²] and J v [m/s]."""
    M, C, g = robot.mass_matrix(q), robot.coriolis(q, v), robot.gravity(q)
    J = robot.jacobian(q)
    data = robot.new_data()
    pin.computeJointJacobiansTimeVariation(robot.model, data, q, v)
    Jdot = pin.getFrameJacobianTimeVariation(robot.model, data, robot.tip_id, LWA)[:3].copy()
    return RobotTerms(
        M=M,
        C=C,
        g=g,
        nle=C @ v + g,
        p=robot.tip_position(q),
        J=J,
        Jdot=Jdot,
        Jdot_v=robot.drift(q, v),
        pdot=J @ v,
    )


def constraint_terms(constraint: Constraint, terms: RobotTerms, v: np.ndarray) -> ConstraintTerms:
    """The joint-space view of the constraint's k surfaces at the terms of one state.

    For surface i with value Φ, gradient ∇Φ and Hessian ∇²Φ at the tip p:
    J_Φ = ∇ΦᵀJ, J̇_Φ = (∇²Φ ṗ)ᵀJ + ∇ΦᵀJ̇, the raw drift ṗᵀ∇²Φ ṗ + ∇ΦᵀJ̇ q̇ and the scale s
    (‖∇Φ‖ for the "tip" rows, ‖J_Φ‖ for the "joint" rows) with its rate ṡ; then A = J_Φ / s,
    Ȧ = J̇_Φ / s − J_Φ ṡ / s², A⁺ by SVD and its rate, Q = I − A⁺A, Q̇ = −(Ȧ⁺A + A⁺Ȧ)
    (the package's stacked algebra takes A⁺ = Aᵀ(AAᵀ)⁻¹ and the rate of (AAᵀ)⁻¹ instead).

    Raises:
        SurfaceError: ∇Φ vanishes at the tip, J_Φ is (near) zero, or the
            stacked rows are dependent (cond(AAᵀ) beyond 1e12).
    """
    p, J, pdot = terms.p, terms.J, terms.pdot
    n = J.shape[1]
    rows, rows_dot, scales, scales_dot, norms, values, drifts = [], [], [], [], [], [], []
    for i, surface in enumerate(constraint.surfaces):
        value, grad, hess = surface.evaluate(p)
        grad_norm = float(np.sqrt(grad @ grad))
        if grad_norm < _GRAD_TOL:
            raise SurfaceError(
                f"∇Φ vanishes at tip position {p.tolist()} on surface {i} ({surface!r})"
            )
        h_pdot = hess @ pdot
        row = grad @ J
        row_dot = h_pdot @ J + grad @ terms.Jdot
        row_norm = float(np.sqrt(row @ row))
        if row_norm < _ROW_TOL * grad_norm * (1.0 + float(np.abs(J).max())):
            raise SurfaceError(
                f"J_Φ is (near) zero for surface {i} ({surface!r}) at tip {p.tolist()}"
            )
        if constraint.normalization == "tip":
            scale, scale_dot = grad_norm, float(grad @ h_pdot) / grad_norm
        else:
            scale, scale_dot = row_norm, float(row @ row_dot) / row_norm
        rows.append(row)
        rows_dot.append(row_dot)
        scales.append(scale)
        scales_dot.append(scale_dot)
        norms.append(row_norm)
        values.append(float(value))
        drifts.append(float(pdot @ h_pdot + grad @ terms.Jdot_v))
    J_phi, J_phi_dot = np.array(rows), np.array(rows_dot)
    s, s_dot, raw_drift = np.array(scales)[:, None], np.array(scales_dot)[:, None], np.array(drifts)
    A = J_phi / s  # row by row, and Ȧ by the quotient rule
    Adot = (J_phi_dot * s - J_phi * s_dot) / (s * s)
    sigma = np.linalg.svd(A, compute_uv=False)  # cond(AAᵀ) = (σ_max / σ_min)²
    cond = (sigma[0] / sigma[-1]) ** 2 if sigma[-1] > 0.0 else np.inf
    if not np.isfinite(cond) or cond > _COND_TOL:
        raise SurfaceError(
            f"the {len(rows)} stacked constraint rows are (nearly) dependent at tip "
            f"{p.tolist()} (cond(A Aᵀ) = {cond:.3g})"
        )
    # the pseudo-inverse by SVD and its rate for full row rank (Golub & Pereyra, SIAM J. Numer.
    # Anal. 10, 1973): d(A⁺)/dt = (I − A⁺A) Ȧᵀ (AAᵀ)⁻¹ − A⁺ Ȧ A⁺, with (AAᵀ)⁻¹ = A⁺ᵀA⁺
    A_pinv = np.linalg.pinv(A)
    Q = np.eye(n) - A_pinv @ A
    A_pinv_dot = Q @ Adot.T @ (A_pinv.T @ A_pinv) - A_pinv @ Adot @ A_pinv
    return ConstraintTerms(
        phi=np.array(values),
        distance=np.array([surface.distance(p) for surface in constraint.surfaces]),
        J_phi=J_phi,
        J_phi_n=J_phi / np.array(norms)[:, None],
        scale=s[:, 0],
        A=A,
        Adot=Adot,
        A_pinv=A_pinv,
        A_pinv_dot=A_pinv_dot,
        Q=Q,
        Qdot=-(A_pinv_dot @ A + A_pinv @ Adot),
        rate=A @ v,
        raw_drift=raw_drift,
        drift=raw_drift / s[:, 0],
    )

"""Constrained dynamics (hybrid_force.sim.dynamics): eq. 2 with the stabilisation of section 6.2.

Independent references:
- pin.forwardDynamics called directly with (q, v) (it runs its own crba/nle), the dense
  KKT solve (oracles.plant.kkt), and the defining equations A q̈ + γ = 0, M q̈ + nle = u + Aᵀ f;
- with γ = drift only, Φ̈ = 0 along q + v t + ½ q̈ t² (second difference of Φ(p(q(t))));
- plastic impacts: A v⁺ = 0, M (v⁺ − v⁻) = Aᵀ P, and the hand formula
  v⁺ = v⁻ − M⁻¹Aᵀ (A M⁻¹ Aᵀ)⁻¹ A v⁻;
- the sign and unit of f: an RTR tool pushed into Cylinder(0.4) by a Cartesian force of 10 N
  along −n̂ (hand-built unit normal), with gravity compensated and v = 0, gets f = +10 N with
  the "tip" scaling, from outside and from inside.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from oracles.plant import kkt

from hybrid_force.control.constraint import Constraint
from hybrid_force.errors import RunFailedError, ScenarioError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.model.robot import Robot
from hybrid_force.sim.dynamics import (
    Baumgarte,
    ConstrainedDynamics,
    free_acceleration,
    plastic_impact,
)

L2, L3 = 0.9, 1.0  # RTR link lengths [m]


def _rtr_on_cylinder(angle: float, z: float, elbow_up: bool = True) -> np.ndarray:
    """RTR configuration with the tip at (0.4 cos a, 0.4 sin a, z): closed-form IK."""
    c3 = (0.4 - L2) / L3
    s3 = np.sqrt(1 - c3 * c3) * (1 if elbow_up else -1)
    return np.array([angle, z - L3 * s3, np.arctan2(s3, c3)])


def _cases(rtr: Robot, ur5: Robot) -> list[tuple[Robot, list[Surface], np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(31)
    out = []
    for normal_side in (False, True):
        q = _rtr_on_cylinder(rng.uniform(-3, 3), 7.0, bool(rng.integers(2)))
        out.append((rtr, [Cylinder(0.4, inside=normal_side)], q, rng.uniform(-1, 1, 3)))
    out.append((rtr, [Sphere(1.2, center=(0, 0, 5))], np.array([0.3, 5.0, 1.0]), np.ones(3)))
    for _ in range(2):
        q = rng.uniform(-2, 2, 6)
        out.append((ur5, [Sphere(0.3, center=(0.3, 0.1, 0.3))], q, rng.uniform(-1, 1, 6)))
        out.append(
            (
                ur5,
                [Plane((0, 0, 0.2), (0.2, 0.1, 1.0)), Cylinder(0.4, axis=(1, 0, 0))],
                q,
                rng.uniform(-1, 1, 6),
            )
        )
    return out


@pytest.mark.parametrize("normalization", ["tip", "joint"])
def test_constrained_dynamics_matches_pinocchio_and_kkt(
    rtr: Robot, ur5: Robot, normalization: str
) -> None:
    rng = np.random.default_rng(32)
    baum = Baumgarte(alpha=30.0, beta=40.0)
    for robot, surfaces, q, v in _cases(rtr, ur5):
        ct = Constraint(surfaces, normalization).at(robot, q, v)
        terms = robot.terms(q, v, robot.new_data())
        u = rng.uniform(-20, 20, robot.nv)
        gamma = baum.gamma(ct.drift, ct.rate, ct.phi / ct.scale)
        data = robot.new_data()
        pin.crba(robot.model, data, q)
        ddq, f = ConstrainedDynamics(robot.model, data, ct.A.shape[0]).solve(
            terms.nle, u, None, ct.A, gamma
        )
        # Pinocchio's (q, v) form computes M and nle itself
        data_ref = robot.new_data()
        ddq_pin = pin.forwardDynamics(robot.model, data_ref, q, v, u, ct.A, gamma).copy()
        f_pin = data_ref.lambda_c.copy()
        ddq_kkt, f_kkt = kkt(terms.M, terms.nle, u, None, ct.A, gamma)
        scale = 1 + np.abs(ddq_kkt).max()
        np.testing.assert_allclose(ddq, ddq_pin, atol=1e-9 * scale)
        np.testing.assert_allclose(ddq, ddq_kkt, atol=1e-9 * scale)
        np.testing.assert_allclose(f, f_pin, atol=1e-9 * (1 + np.abs(f_pin).max()))
        np.testing.assert_allclose(f, f_kkt, atol=1e-9 * (1 + np.abs(f_kkt).max()))
        # the defining equations, with M and nle from independent Pinocchio algorithms
        M = robot.mass_matrix(q)
        nle = pin.rnea(robot.model, robot.new_data(), q, v, np.zeros(robot.nv))
        np.testing.assert_allclose(ct.A @ ddq, -gamma, atol=1e-9 * (1 + np.abs(gamma).max()))
        res = M @ ddq + nle - u - ct.A.T @ f
        assert np.abs(res).max() < 1e-9 * (1 + np.abs(u).max() + np.abs(nle).max())


@pytest.mark.parametrize("normalization", ["tip", "joint"])
def test_drift_only_keeps_phi_ddot_zero(rtr: Robot, ur5: Robot, normalization: str) -> None:
    """γ = drift: the resulting q̈ gives Φ̈ = 0 (second difference along q + v t + ½ q̈ t²)."""
    rng = np.random.default_rng(33)
    h = 1e-4
    for robot, surfaces, q, v in _cases(rtr, ur5):
        ct = Constraint(surfaces, normalization).at(robot, q, v)
        terms = robot.terms(q, v, robot.new_data())
        u = terms.g + rng.uniform(-5, 5, robot.nv)
        data = robot.new_data()
        pin.crba(robot.model, data, q)
        ddq, _ = ConstrainedDynamics(robot.model, data, ct.A.shape[0]).solve(
            terms.nle, u, None, ct.A, ct.drift
        )

        def phi(t: float, q=q, v=v, ddq=ddq, robot=robot, surfaces=surfaces) -> np.ndarray:
            p = robot.tip_position(q + v * t + 0.5 * ddq * t * t)
            return np.array([s.phi(p) for s in surfaces])

        phi_ddot = (phi(h) - 2 * phi(0.0) + phi(-h)) / h**2
        # reference magnitude: the size of the terms that cancel
        size = 1 + np.abs(ct.raw_drift).max() + np.abs(ct.J_phi @ ddq).max()
        assert np.abs(phi_ddot).max() < 1e-5 * size, phi_ddot


def test_free_acceleration_matches_aba(ur5: Robot) -> None:
    rng = np.random.default_rng(34)
    for _ in range(3):
        q, v, u = rng.uniform(-2, 2, 6), rng.uniform(-1, 1, 6), rng.uniform(-10, 10, 6)
        terms = ur5.terms(q, v, ur5.new_data())
        ref = pin.aba(ur5.model, ur5.new_data(), q, v, u)
        np.testing.assert_allclose(
            free_acceleration(terms.M, terms.nle, u), ref, atol=1e-9 * (1 + np.abs(ref).max())
        )


# --- impacts ----------------------------------------------------------------------------------
@pytest.mark.parametrize("normalization", ["tip", "joint"])
def test_plastic_impact(rtr: Robot, ur5: Robot, normalization: str) -> None:
    for robot, surfaces, q, v in _cases(rtr, ur5):
        ct = Constraint(surfaces, normalization).at(robot, q, v)
        A = ct.A
        # make the tool move into every surface: A v⁻ < 0
        v_minus = v - A.T @ np.linalg.solve(A @ A.T, A @ v + 0.3)
        assert np.all(A @ v_minus < 0)
        v_plus, P = plastic_impact(robot.model, robot.new_data(), q, v_minus, A)
        M = robot.mass_matrix(q)
        np.testing.assert_allclose(A @ v_plus, 0.0, atol=1e-10)
        np.testing.assert_allclose(M @ (v_plus - v_minus), A.T @ P, atol=1e-9)
        Minv_At = np.linalg.solve(M, A.T)
        ref = v_minus - Minv_At @ np.linalg.solve(A @ Minv_At, A @ v_minus)
        np.testing.assert_allclose(v_plus, ref, atol=1e-10)
        if len(surfaces) == 1:
            assert P[0] > 0  # the surface pushes the tool back
        # a plastic impact loses kinetic energy
        assert v_plus @ M @ v_plus < v_minus @ M @ v_minus


# --- Baumgarte -----------------------------------------------------------------------------------
def test_baumgarte_gamma_formula() -> None:
    b = Baumgarte(alpha=3.0, beta=4.0)
    # γ = drift + 2α φ̇ + β² φ = 1 + 2·3·2 + 16·5
    np.testing.assert_allclose(b.gamma(np.array([1.0]), np.array([2.0]), np.array([5.0])), [93.0])
    np.testing.assert_allclose(
        b.gamma(np.array([1.0, -1.0]), np.array([0.0, 1.0]), np.array([0.0, -0.5])), [1.0, -3.0]
    )
    assert (Baumgarte().alpha, Baumgarte().beta) == (50.0, 50.0)
    np.testing.assert_allclose(Baumgarte(0.0, 0.0).gamma(np.array([7.0]), 1.0, 1.0), [7.0])


@pytest.mark.parametrize(
    ("alpha", "beta", "key"),
    [
        (-1.0, 1.0, "baumgarte_alpha"),
        (1.0, -1.0, "baumgarte_beta"),
        (np.nan, 1.0, "baumgarte_alpha"),
        (1, np.inf, "baumgarte_beta"),
        ("50", 1.0, "baumgarte_alpha"),
        (1.0, True, "baumgarte_beta"),
    ],
)
def test_baumgarte_rejects_bad_gains(alpha: object, beta: object, key: str) -> None:
    """Bad input, not a run-time failure: a BadInputError naming the [sim] key."""
    with pytest.raises(ScenarioError, match=key) as info:
        Baumgarte(alpha=alpha, beta=beta)  # type: ignore[arg-type]
    assert not isinstance(info.value, RunFailedError)


def test_baumgarte_closes_on_the_surface(rtr: Robot) -> None:
    """φ̈ + 2αφ̇ + β²φ = 0 for φ = Φ/s ("tip": φ ≈ metric distance near a cylinder).

    With constant s the stabilised constraint gives A q̈ + drift = −2α rate − β² φ: the
    scaled Φ̈ equals the damped-oscillator right-hand side (checked by second differences).
    """
    b = Baumgarte(alpha=5.0, beta=6.0)
    surface = Plane((0, 0, 7.0), (0, 0, 1))  # s = ‖∇Φ‖ = 1 for a unit plane: φ = z − 7
    q = np.array([0.4, 6.0, 0.9])
    v = np.array([0.3, -0.2, 0.5])
    ct = Constraint(surface).at(rtr, q, v)
    terms = rtr.terms(q, v, rtr.new_data())
    data = rtr.new_data()
    pin.crba(rtr.model, data, q)
    gamma = b.gamma(ct.drift, ct.rate, ct.phi / ct.scale)
    ddq, _ = ConstrainedDynamics(rtr.model, data, ct.A.shape[0]).solve(
        terms.nle, terms.g, None, ct.A, gamma
    )
    h = 1e-4

    def z(t: float) -> float:
        return float(rtr.tip_position(q + v * t + 0.5 * ddq * t * t)[2] - 7.0)

    z0 = z(0.0)
    z_dot = (z(h) - z(-h)) / (2 * h)
    z_ddot = (z(h) - 2 * z0 + z(-h)) / h**2
    assert z_ddot == pytest.approx(-2 * 5.0 * z_dot - 36.0 * z0, abs=1e-5)


# --- sign and unit of f -----------------------------------------------------------------------
@pytest.mark.parametrize("inside", [False, True])
@pytest.mark.parametrize("angle", [0.0, 1.1, -2.4])
def test_pressing_tool_gets_positive_force_in_newtons(
    rtr: Robot, inside: bool, angle: float
) -> None:
    q = _rtr_on_cylinder(angle, 7.0)
    p = rtr.tip_position(q)
    radial = np.array([np.cos(angle), np.sin(angle), 0.0])
    np.testing.assert_allclose(p, 0.4 * radial + [0, 0, 7.0], atol=1e-14)
    # hand-built unit normal pointing to the free side
    n_hat = -radial if inside else radial
    surface = Cylinder(0.4, inside=inside)
    np.testing.assert_allclose(surface.normal(p), n_hat, atol=1e-14)
    v = np.zeros(3)
    J = rtr.jacobian(q)
    g = rtr.gravity(q)
    for normalization in ("tip", "joint"):
        ct = Constraint(surface, normalization).at(rtr, q, v)
        terms = rtr.terms(q, v, rtr.new_data())
        gamma = Baumgarte().gamma(ct.drift, ct.rate, ct.phi / ct.scale)
        np.testing.assert_allclose(gamma, 0.0, atol=1e-10)  # on the surface, at rest
        data = rtr.new_data()
        pin.crba(rtr.model, data, q)
        # a 10 N Cartesian push into the surface (along −n̂), gravity compensated
        u = g + J.T @ (-10.0 * n_hat)
        ddq, f = ConstrainedDynamics(rtr.model, data, ct.A.shape[0]).solve(
            terms.nle, u, None, ct.A, gamma
        )
        if normalization == "tip":
            np.testing.assert_allclose(f, [10.0], rtol=1e-10)
            # u = g − Aᵀ·10 is the same command
            np.testing.assert_allclose(g - ct.A[0] * 10.0, u, atol=1e-12)
            # the joint torque Aᵀ f equals the Jᵀ-mapped Cartesian force n̂ f
            np.testing.assert_allclose(ct.A.T @ f, J.T @ (n_hat * f[0]), atol=1e-11)
        else:
            # same physical force, expressed along the unit joint-space row
            np.testing.assert_allclose(f, [10.0 * np.linalg.norm(n_hat @ J)], rtol=1e-10)
            np.testing.assert_allclose(ct.A.T @ f, J.T @ (n_hat * 10.0), atol=1e-11)
        # the surface holds the tool: the arm stays at rest (q̈ = 0)
        np.testing.assert_allclose(ddq, 0.0, atol=1e-10)


def test_pulling_tool_gets_negative_force(rtr: Robot) -> None:
    """The bilateral solver reports a pull as f < 0 (the simulator's unilateral logic uses it)."""
    q = _rtr_on_cylinder(0.5, 8.0)
    surface = Cylinder(0.4)
    ct = Constraint(surface).at(rtr, q)
    terms = rtr.terms(q, np.zeros(3), rtr.new_data())
    data = rtr.new_data()
    pin.crba(rtr.model, data, q)
    u = terms.g + ct.A[0] * 4.0
    _, f = ConstrainedDynamics(rtr.model, data, ct.A.shape[0]).solve(
        terms.nle, u, None, ct.A, np.zeros(1)
    )
    np.testing.assert_allclose(f, [-4.0], rtol=1e-10)

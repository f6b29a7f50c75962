"""The RTR arm of robots/rtr.urdf against hand-derived closed forms and the paper (21)-(24).

Hand derivation (independent of Pinocchio)
------------------------------------------
Coordinates: q1 rotation about world z, q2 height of link 2, q3 elevation of link 3
(positive raises the tool). Write c1 = cos q1, s1 = sin q1, c3 = cos q3, s3 = sin q3,
e = (c1, s1, 0) the direction of link 2, e⊥ = (-s1, c1, 0), ẑ = (0, 0, 1).

Link 2, thin rod of mass m2 and length l2, point at r ∈ [0, l2]:
    x(r) = r e + q2 ẑ,   ẋ(r) = r q̇1 e⊥ + q̇2 ẑ
    T2 = ½ ∫ (m2/l2) |ẋ|² dr = ½ (m2 l2²/3) q̇1² + ½ m2 q̇2².
Link 3, thin rod of mass m3 and length l3, point at s ∈ [0, l3]:
    x(s) = (l2 + s c3) e + (q2 + s s3) ẑ
    ẋ(s) = (l2 + s c3) q̇1 e⊥ − s s3 q̇3 e + (q̇2 + s c3 q̇3) ẑ
    |ẋ|² = (l2 + s c3)² q̇1² + q̇2² + s² q̇3² + 2 s c3 q̇2 q̇3
    T3 = ½ m3 [(l2² + l2 l3 c3 + l3² c3²/3) q̇1² + q̇2² + (l3²/3) q̇3² + l3 c3 q̇2 q̇3].
T = ½ q̇ᵀ M q̇ gives
    M11 = m2 l2²/3 + m3 (l2² + l2 l3 c3 + l3² c3²/3),  M22 = m2 + m3,
    M23 = M32 = ½ m3 l3 c3,  M33 = m3 l3²/3,  M12 = M13 = 0.
Potential energy V = m2 g0 q2 + m3 g0 (q2 + ½ l3 s3), g0 = 9.81 m/s², so
    g(q) = ∂V/∂q = (0, (m2 + m3) g0, ½ m3 g0 l3 c3)            (the paper's D(q)).
Christoffel symbols C_kj = Σ_i ½ (∂M_kj/∂q_i + ∂M_ki/∂q_j − ∂M_ij/∂q_k) q̇_i; only
M11 and M23 depend on q (on q3). With h = ½ ∂M11/∂q3 = −m3 (½ l2 l3 s3 + ⅓ l3² s3 c3):
    C11 = h q̇3,  C13 = h q̇1,  C31 = −h q̇1,  C23 = ∂M23/∂q3 q̇3 = −½ m3 l3 s3 q̇3,
    every other entry 0.
Tip position and Jacobian:
    p = (c1 (l3 c3 + l2), s1 (l3 c3 + l2), l3 s3 + q2)
    J = [[−s1 (l3 c3 + l2), 0, −c1 s3 l3],
         [ c1 (l3 c3 + l2), 0, −s1 s3 l3],
         [ 0,               1,  c3 l3   ]]
Drift J̇(q, q̇) q̇ (p̈ at q̈ = 0):
    ẍ = −c1 r q̇1² + 2 s1 l3 s3 q̇1 q̇3 − c1 l3 c3 q̇3²,   r = l3 c3 + l2
    ÿ = −s1 r q̇1² − 2 c1 l3 s3 q̇1 q̇3 − s1 l3 c3 q̇3²
    z̈ = −l3 s3 q̇3².

Paper discrepancies (the tests assert the physics above, and document the paper):
* eq. (21): the paper's M23 = ½ m3 l2 l3 cos q3 has an extra factor l2; the physics is
  M23 = ½ m3 l3 cos q3 (the coupling between the vertical slide q2 and the elevation q3
  cannot depend on the length of link 2: the vertical speed of link 3's centre is
  q̇2 + ½ l3 c3 q̇3). With l2 = 0.9 m the paper's value is 10 % too small.
* eq. (22): the paper's C23 = −½ q̇3 m3 l2 l3 sin q3 carries the same extra factor l2;
  the physics is C23 = −½ m3 l3 sin q3 q̇3 (C23 = ∂M23/∂q3 q̇3).
* Every other term of (21), (22), (23), p(q) and (24) agrees with the derivation.

Pinocchio's ``computeCoriolisMatrix`` is built from a spatial-algebra factorisation, which is
not the Christoffel one for every robot; for this arm it coincides with it (measured to
round-off), so the tests compare C itself, and C·q̇ and the skew property separately.

The mass matrix derivation is cross-checked once more numerically: M = Σ m_k J_kᵀ J_k over
Gauss–Legendre points along the rods (exact: the integrand is quadratic in the rod
coordinate), with each point's Jacobian from central finite differences of its position.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from hybrid_force.model.robot import Robot

M2, M3 = 20.0, 20.0  # [kg]
L2, L3 = 0.9, 1.0  # [m]
G0 = 9.81  # [m/s²]
N_STATES = 60


# --- independent reference: the hand derivation above ---------------------------------
def ref_M(q: np.ndarray) -> np.ndarray:
    """(3, 3) mass matrix from the kinetic energy of two thin rods."""
    c3 = np.cos(q[2])
    m11 = M2 * L2**2 / 3 + M3 * (L2**2 + L2 * L3 * c3 + L3**2 * c3**2 / 3)
    m23 = 0.5 * M3 * L3 * c3
    return np.array([[m11, 0, 0], [0, M2 + M3, m23], [0, m23, M3 * L3**2 / 3]])


def ref_M_dot(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(3, 3) Ṁ = Σ_i ∂M/∂q_i v_i (only q3 enters M)."""
    s3, c3 = np.sin(q[2]), np.cos(q[2])
    dm11 = M3 * (-L2 * L3 * s3 - 2 * L3**2 * s3 * c3 / 3)
    dm23 = -0.5 * M3 * L3 * s3
    return v[2] * np.array([[dm11, 0, 0], [0, 0, dm23], [0, dm23, 0]])


def ref_C(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(3, 3) Coriolis matrix from the Christoffel symbols of ref_M."""
    s3, c3 = np.sin(q[2]), np.cos(q[2])
    h = -M3 * (0.5 * L2 * L3 * s3 + L3**2 * s3 * c3 / 3)
    c23 = -0.5 * M3 * L3 * s3 * v[2]
    return np.array([[h * v[2], 0, h * v[0]], [0, 0, c23], [-h * v[0], 0, 0]])


def ref_g(q: np.ndarray) -> np.ndarray:
    """(3,) gravity torques [N, N, N·m]."""
    return np.array([0.0, (M2 + M3) * G0, 0.5 * G0 * M3 * L3 * np.cos(q[2])])


def ref_p(q: np.ndarray) -> np.ndarray:
    """(3,) tip position [m]."""
    r = L3 * np.cos(q[2]) + L2
    return np.array([np.cos(q[0]) * r, np.sin(q[0]) * r, L3 * np.sin(q[2]) + q[1]])


def ref_J(q: np.ndarray) -> np.ndarray:
    """(3, 3) tip Jacobian [m/rad, m/m, m/rad]."""
    s1, c1, s3, c3 = np.sin(q[0]), np.cos(q[0]), np.sin(q[2]), np.cos(q[2])
    r = L3 * c3 + L2
    return np.array([[-s1 * r, 0, -c1 * s3 * L3], [c1 * r, 0, -s1 * s3 * L3], [0, 1, c3 * L3]])


def ref_drift(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(3,) J̇(q, v) v [m/s²]."""
    s1, c1, s3, c3 = np.sin(q[0]), np.cos(q[0]), np.sin(q[2]), np.cos(q[2])
    r = L3 * c3 + L2
    w1, w3 = v[0], v[2]
    return np.array(
        [
            -c1 * r * w1**2 + 2 * s1 * L3 * s3 * w1 * w3 - c1 * L3 * c3 * w3**2,
            -s1 * r * w1**2 - 2 * c1 * L3 * s3 * w1 * w3 - s1 * L3 * c3 * w3**2,
            -L3 * s3 * w3**2,
        ]
    )


# --- the paper's printed formulas (21)-(24), as printed --------------------------------
def paper_M(q: np.ndarray) -> np.ndarray:
    """Eq. (21) as printed (M23 with the extra factor l2)."""
    c3 = np.cos(q[2])
    m11 = M2 * L2**2 / 3 + M3 * (L2**2 + L3**2 * c3**2 / 3 + L2 * L3 * c3)
    m23 = 0.5 * M3 * L2 * L3 * c3
    return np.array([[m11, 0, 0], [0, M2 + M3, m23], [0, m23, M3 * L3**2 / 3]])


def paper_C(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Eq. (22) as printed (C23 with the extra factor l2)."""
    s3, c3 = np.sin(q[2]), np.cos(q[2])
    k = 0.5 * M3 * L2 * L3 * s3 + M3 * L3**2 * s3 * c3 / 3
    c11 = v[2] * (-0.5 * M3 * L2 * L3 * s3 - M3 * L3**2 * s3 * c3 / 3)
    c23 = -0.5 * v[2] * M3 * L2 * L3 * s3
    return np.array([[c11, 0, -v[0] * k], [0, 0, c23], [v[0] * k, 0, 0]])


def paper_D(q: np.ndarray) -> np.ndarray:
    """Eq. (23) as printed."""
    return np.array([0.0, (M2 + M3) * G0, 0.5 * G0 * M3 * L3 * np.cos(q[2])])


def paper_J(q: np.ndarray) -> np.ndarray:
    """Eq. (24) as printed."""
    s1, c1, s3, c3 = np.sin(q[0]), np.cos(q[0]), np.sin(q[2]), np.cos(q[2])
    return np.array(
        [
            [-s1 * (L3 * c3 + L2), 0, -c1 * s3 * L3],
            [c1 * (L3 * c3 + L2), 0, -s1 * s3 * L3],
            [0, 1, c3 * L3],
        ]
    )


# --- helpers ------------------------------------------------------------------------
def _states(seed: int = 7, n: int = N_STATES) -> list[tuple[np.ndarray, np.ndarray]]:
    """n random (q, v) with q1, q3 ∈ [−π, π] rad, q2 ∈ [0, 15] m, v ∈ [−3, 3]."""
    rng = np.random.default_rng(seed)
    q = np.column_stack(
        [rng.uniform(-np.pi, np.pi, n), rng.uniform(0.0, 15.0, n), rng.uniform(-np.pi, np.pi, n)]
    )
    v = rng.uniform(-3.0, 3.0, (n, 3))
    return list(zip(q, v, strict=True))


def _close(actual: np.ndarray, expected: np.ndarray, rel: float = 1e-12) -> None:
    """Equal to round-off: atol = rel · max(1, max|expected|)."""
    atol = rel * max(1.0, float(np.max(np.abs(expected))))
    np.testing.assert_allclose(actual, expected, rtol=0.0, atol=atol)


# --- the hand derivation is right (checked without Pinocchio) ---------------------------
def _rod_points(q: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """(mass, position) of Gauss–Legendre points on both rods (2 points: exact here)."""
    nodes, weights = np.polynomial.legendre.leggauss(2)
    e = np.array([np.cos(q[0]), np.sin(q[0]), 0.0])
    z = np.array([0.0, 0.0, 1.0])
    pts = []
    for x, w in zip(nodes, weights, strict=True):
        r = 0.5 * L2 * (x + 1)
        pts.append((0.5 * w * M2, r * e + q[1] * z))
        s = 0.5 * L3 * (x + 1)
        pts.append((0.5 * w * M3, (L2 + s * np.cos(q[2])) * e + (q[1] + s * np.sin(q[2])) * z))
    return pts


def test_hand_mass_matrix_matches_rod_quadrature() -> None:
    """M = Σ m_k J_kᵀ J_k, J_k by central differences of the point positions."""
    h = 1e-6
    for q, _ in _states(seed=1, n=10):
        M = np.zeros((3, 3))
        for k in range(4):
            cols = []
            for i in range(3):
                dq = np.zeros(3)
                dq[i] = h
                cols.append((_rod_points(q + dq)[k][1] - _rod_points(q - dq)[k][1]) / (2 * h))
            Jk = np.column_stack(cols)
            M += _rod_points(q)[k][0] * Jk.T @ Jk
        _close(M, ref_M(q), rel=1e-8)


def test_hand_gravity_is_gradient_of_potential() -> None:
    h = 1e-6
    for q, _ in _states(seed=2, n=10):

        def potential(qq: np.ndarray) -> float:
            return G0 * sum(m * x[2] for m, x in _rod_points(qq))

        grad = np.array(
            [(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in np.eye(3)]
        )
        _close(grad, ref_g(q), rel=1e-8)


def test_hand_jacobian_and_drift_are_derivatives_of_p() -> None:
    h = 1e-6
    for q, v in _states(seed=3, n=10):
        J_fd = np.column_stack([(ref_p(q + h * e) - ref_p(q - h * e)) / (2 * h) for e in np.eye(3)])
        _close(J_fd, ref_J(q), rel=1e-8)
        drift_fd = (ref_J(q + h * v) - ref_J(q - h * v)) / (2 * h) @ v
        _close(drift_fd, ref_drift(q, v), rel=1e-7)


def test_hand_coriolis_matches_christoffel_of_finite_difference_mass_matrix() -> None:
    """C_kj = Σ_i Γ_kji v_i with ∂M/∂q_i by central differences of ref_M."""
    h = 1e-6
    for q, v in _states(seed=4, n=10):
        dM = [(ref_M(q + h * e) - ref_M(q - h * e)) / (2 * h) for e in np.eye(3)]
        C = np.zeros((3, 3))
        for k in range(3):
            for j in range(3):
                C[k, j] = sum(
                    0.5 * (dM[i][k, j] + dM[j][k, i] - dM[k][i, j]) * v[i] for i in range(3)
                )
        _close(C, ref_C(q, v), rel=1e-8)


# --- Pinocchio on robots/rtr.urdf against the hand derivation ---------------------------
def test_model_layout(rtr: Robot) -> None:
    assert (rtr.nq, rtr.nv) == (3, 3)
    assert rtr.tip == "tip"
    assert [rtr.model.names[i] for i in range(1, rtr.model.njoints)] == ["q1", "q2", "q3"]
    np.testing.assert_array_equal(rtr.model.gravity.linear, [0.0, 0.0, -G0])
    total_mass = sum(inertia.mass for inertia in rtr.model.inertias)
    assert total_mass == pytest.approx(M2 + M3, abs=1e-12)


def _urdf_joints(rtr: Robot) -> list[ET.Element]:
    """The moving joints of rtr.urdf, in file order (q1, q2, q3)."""
    root = ET.parse(rtr.urdf_path).getroot()
    return [j for j in root.findall("joint") if j.get("type") != "fixed"]


def test_q1_turns_freely(rtr: Robot) -> None:
    """rtr.urdf declares q1 continuous: one angle [rad], unbounded, never wrapped.

    The hand formulas are 2π-periodic in q1, so M, g, p and J at q1 = 10 rad or −25 rad
    (outside the old ±6.3 rad limits) still equal them; q2 and q3 keep their URDF limits.
    """
    assert [j.get("type") for j in _urdf_joints(rtr)] == ["continuous", "prismatic", "revolute"]
    lower, upper = rtr.position_limits
    np.testing.assert_array_equal(lower, [-np.inf, -1.0, -3.2])
    np.testing.assert_array_equal(upper, [np.inf, 16.0, 3.2])
    # effort limits as declared, 0 (URDF's "unspecified") read as +inf
    efforts = [float(j.find("limit").get("effort")) for j in _urdf_joints(rtr)]
    np.testing.assert_array_equal(rtr.effort_limits, [e if e > 0 else np.inf for e in efforts])
    assert rtr.euclidean
    for q1 in (10.0, -25.0, 1e3):
        q = np.array([q1, 4.0, 0.6])
        _close(rtr.tip_position(q), ref_p(q))
        _close(rtr.jacobian(q), ref_J(q))
        _close(rtr.mass_matrix(q), ref_M(q))
        _close(rtr.gravity(q), ref_g(q))


def test_positive_q3_raises_the_tool(rtr: Robot) -> None:
    q = np.array([0.4, 2.0, 0.0])
    raised = np.array([0.4, 2.0, 0.1])
    assert rtr.tip_position(raised)[2] > rtr.tip_position(q)[2]


def test_mass_matrix(rtr: Robot) -> None:
    for q, _ in _states():
        M = rtr.mass_matrix(q)
        _close(M, ref_M(q))
        np.testing.assert_array_equal(M, M.T)
        assert np.linalg.eigvalsh(M).min() > 0


def test_coriolis_matrix_equals_christoffel(rtr: Robot) -> None:
    for q, v in _states():
        C = rtr.coriolis(q, v)
        _close(C, ref_C(q, v))
        _close(C @ v, ref_C(q, v) @ v)


def test_gravity(rtr: Robot) -> None:
    for q, _ in _states():
        _close(rtr.gravity(q), ref_g(q))


def test_tip_position(rtr: Robot) -> None:
    for q, _ in _states():
        _close(rtr.tip_position(q), ref_p(q))


def test_jacobian(rtr: Robot) -> None:
    for q, _ in _states():
        _close(rtr.jacobian(q), ref_J(q))


def test_jacobian_matches_finite_difference_of_tip_position(rtr: Robot) -> None:
    h = 1e-6
    for q, _ in _states(n=15):
        cols = [
            (rtr.tip_position(q + h * e) - rtr.tip_position(q - h * e)) / (2 * h) for e in np.eye(3)
        ]
        _close(rtr.jacobian(q), np.column_stack(cols), rel=1e-8)


def test_drift(rtr: Robot) -> None:
    for q, v in _states():
        _close(rtr.drift(q, v), ref_drift(q, v))


def test_drift_matches_finite_difference_of_jacobian(rtr: Robot) -> None:
    """J̇ v against (J(q + h v) − J(q − h v)) / 2h · v."""
    h = 1e-6
    for q, v in _states(n=15):
        jdot = (rtr.jacobian(q + h * v) - rtr.jacobian(q - h * v)) / (2 * h)
        _close(rtr.drift(q, v), jdot @ v, rel=1e-7)


def test_mdot_minus_2c_is_skew_symmetric(rtr: Robot) -> None:
    """Ṁ by central finite differences of Pinocchio's M along v, and exactly by hand."""
    h = 1e-6
    for q, v in _states():
        C = rtr.coriolis(q, v)
        m_dot_fd = (rtr.mass_matrix(q + h * v) - rtr.mass_matrix(q - h * v)) / (2 * h)
        _close(m_dot_fd, ref_M_dot(q, v), rel=1e-8)
        N = m_dot_fd - 2 * C
        _close(N + N.T, np.zeros((3, 3)), rel=1e-8 * max(1.0, float(np.abs(C).max())))
        N_exact = ref_M_dot(q, v) - 2 * C
        _close(N_exact + N_exact.T, np.zeros((3, 3)), rel=1e-12 * float(np.abs(C).max() + 1))


# --- the paper's printed formulas ---------------------------------------------------
def test_paper_terms_that_agree_with_the_physics(rtr: Robot) -> None:
    """(21) except M23, (22) except C23, (23), p(q) and (24) hold for the URDF model."""
    agree = np.ones((3, 3), dtype=bool)
    agree[1, 2] = agree[2, 1] = False
    for q, v in _states():
        _close(rtr.mass_matrix(q)[agree], paper_M(q)[agree])
        C = rtr.coriolis(q, v)
        mask = agree.copy()
        mask[2, 1] = True  # C32 = 0 in both
        _close(C[mask], paper_C(q, v)[mask])
        _close(rtr.gravity(q), paper_D(q))
        _close(rtr.jacobian(q), paper_J(q))


def test_paper_eq21_M23_has_an_extra_factor_l2(rtr: Robot) -> None:
    """Discrepancy: paper (21) M23 = ½ m3 l2 l3 cos q3; physics M23 = ½ m3 l3 cos q3."""
    q = np.array([0.3, 5.0, 0.4])
    physics = 0.5 * M3 * L3 * np.cos(q[2])
    assert rtr.mass_matrix(q)[1, 2] == pytest.approx(physics, abs=1e-12)
    assert paper_M(q)[1, 2] == pytest.approx(L2 * physics, abs=1e-12)
    assert abs(paper_M(q)[1, 2] - physics) > 0.05 * abs(physics)


def test_paper_eq22_C23_has_an_extra_factor_l2(rtr: Robot) -> None:
    """Discrepancy: paper (22) C23 = −½ q̇3 m3 l2 l3 sin q3; physics C23 = −½ m3 l3 sin q3 q̇3."""
    q, v = np.array([0.3, 5.0, 0.4]), np.array([0.5, -0.2, 1.3])
    physics = -0.5 * M3 * L3 * np.sin(q[2]) * v[2]
    assert rtr.coriolis(q, v)[1, 2] == pytest.approx(physics, abs=1e-12)
    assert paper_C(q, v)[1, 2] == pytest.approx(L2 * physics, abs=1e-12)
    assert abs(paper_C(q, v)[1, 2] - physics) > 0.05 * abs(physics)


def test_paper_M_and_C_are_consistent_with_each_other() -> None:
    """Ṁ − 2C is skew for the paper's (21), (22) as printed: C23 = ∂M23/∂q3 q̇3 there too.

    So the extra l2 is one modelling slip in M23 carried into C23 (a simulation with the
    paper's matrices is a consistent but different arm), not an isolated typo.
    """
    for q, v in _states(n=10):
        h = 1e-6
        m_dot_paper = (paper_M(q + h * v) - paper_M(q - h * v)) / (2 * h)
        N = m_dot_paper - 2 * paper_C(q, v)
        _close(N + N.T, np.zeros((3, 3)), rel=1e-7)

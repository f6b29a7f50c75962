"""Constraint layer (hybrid_force.control.constraint): surfaces seen in joint space (issue 3).

Independent references:
- geometric identities of the projection (eq. 5 and below, eq. 7): Q = Qᵀ, Q² = Q, Q Aᵀ = 0,
  Q J_Φnᵀ = 0, J_Φn J_Φnᵀ = 1, A A⁺ = I; Q the same for both row scalings; with k = 1 Q is
  literally I − J_ΦnᵀJ_Φn;
- J_Φ = ∇Φᵀ J with ∇Φ from the surface and J from the robot;
- raw drift = d/dt J_Φ(q + v t) · v, and Ȧ, Ȧ⁺, Q̇ by central finite differences along
  q(t) = q + v t (they are total time derivatives along the motion);
- A q̈ + drift = Φ̈ / s against a second difference of Φ(p(q + v t + ½ q̈ t²));
- singular cases raise SurfaceError, never NaN.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from oracles.terms import constraint_terms

from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.errors import SurfaceError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.model.robot import Robot

NORMALIZATIONS = ("tip", "joint")
H = 1e-6  # central-difference step along q(t) = q + v t [s]


def _rtr_state(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Random RTR state with the elbow well away from q3 = 0, π (radial column non-zero)."""
    q3 = rng.choice([-1, 1]) * rng.uniform(0.4, 2.7)
    q = np.array([rng.uniform(-3, 3), rng.uniform(2, 12), q3])
    return q, rng.uniform(-1.5, 1.5, 3)


def _ur5_state(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return rng.uniform(-2.5, 2.5, 6), rng.uniform(-1.5, 1.5, 6)


def _rtr_cases() -> list[tuple[str, list[Surface]]]:
    return [
        ("cyl", [Cylinder(0.4)]),
        ("cyl_in", [Cylinder(0.4, inside=True)]),
        ("tilted", [Cylinder(0.3, center=(0.2, -0.1, 5.0), axis=(1.0, 0.5, 0.3))]),
        ("sphere", [Sphere(0.7, center=(0.3, 0.2, 6.0))]),
        ("groove", [Plane((0.0, 0.0, 7.0), (0.0, 0.0, 1.0)), Cylinder(0.4)]),
    ]


def _ur5_cases() -> list[tuple[str, list[Surface]]]:
    return [
        ("sphere", [Sphere(0.3, center=(0.3, 0.1, 0.3))]),
        ("cyl", [Cylinder(0.25, center=(0.2, 0.0, 0.0), axis=(0.0, 1.0, 1.0))]),
        ("groove", [Plane((0.0, 0.0, 0.2), (0.2, 0.1, 1.0)), Cylinder(0.4, axis=(1, 0, 0))]),
        ("corner", [Plane((0, 0, 0.2), (0, 0, 1)), Plane((0.3, 0, 0), (1, 0, 0)), Sphere(0.5)]),
    ]


def _check_identities(ct: ConstraintTerms, k: int, n: int) -> None:
    I_n, I_k = np.eye(n), np.eye(k)
    Q, A, Ap, Jn = ct.Q, ct.A, ct.A_pinv, ct.J_phi_n
    assert Q.shape == (n, n) and A.shape == (k, n) and Ap.shape == (n, k) and Jn.shape == (k, n)
    assert np.abs(Q - Q.T).max() < 1e-12
    assert np.abs(Q @ Q - Q).max() < 1e-12
    assert np.abs(Q @ A.T).max() < 1e-11 * (1 + np.abs(A).max())
    assert np.abs(Q @ Jn.T).max() < 1e-11
    np.testing.assert_allclose(np.diag(Jn @ Jn.T), 1.0, atol=1e-13)
    np.testing.assert_allclose(A @ Ap, I_k, atol=1e-11)
    np.testing.assert_allclose(Ap, A.T @ np.linalg.inv(A @ A.T), atol=1e-10 * np.abs(Ap).max())
    # Q projects onto the (n − k)-dimensional tangent space
    assert np.trace(Q) == pytest.approx(n - k, abs=1e-11)
    np.testing.assert_allclose(Q + Ap @ A, I_n, atol=1e-12)


def _fd(fun, h: float = H) -> np.ndarray:
    return (fun(h) - fun(-h)) / (2 * h)


# --- identities ----------------------------------------------------------------------------
@pytest.mark.parametrize("case", range(5))
@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_projection_identities_rtr(rtr: Robot, case: int, normalization: str) -> None:
    _name, surfaces = _rtr_cases()[case]
    con = Constraint(surfaces, normalization=normalization)
    rng = np.random.default_rng(100 + case)
    for _ in range(8):
        q, v = _rtr_state(rng)
        _check_identities(con.at(rtr, q, v), len(surfaces), 3)


@pytest.mark.parametrize("case", range(4))
@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_projection_identities_ur5(ur5: Robot, case: int, normalization: str) -> None:
    _name, surfaces = _ur5_cases()[case]
    con = Constraint(surfaces, normalization=normalization)
    rng = np.random.default_rng(200 + case)
    for _ in range(8):
        q, v = _ur5_state(rng)
        _check_identities(con.at(ur5, q, v), len(surfaces), 6)


def test_single_row_q_is_eq5_literally(rtr: Robot, ur5: Robot) -> None:
    """k = 1: Q = I − J_ΦnᵀJ_Φn (eq. 5), and with "joint" scaling A = J_Φn, A⁺ = J_Φnᵀ."""
    rng = np.random.default_rng(3)
    for robot, surface, state in (
        (rtr, Cylinder(0.4), _rtr_state),
        (ur5, Sphere(0.3, center=(0.3, 0.1, 0.3)), _ur5_state),
    ):
        for _ in range(5):
            q, v = state(rng)
            for normalization in NORMALIZATIONS:
                ct = Constraint(surface, normalization).at(robot, q, v)
                Jn = ct.J_phi / np.linalg.norm(ct.J_phi)
                np.testing.assert_allclose(ct.J_phi_n, Jn, atol=1e-14)
                np.testing.assert_allclose(ct.Q, np.eye(robot.nv) - Jn.T @ Jn, atol=1e-13)
            joint = Constraint(surface, "joint").at(robot, q, v)
            np.testing.assert_allclose(joint.A, joint.J_phi_n, atol=1e-15)
            np.testing.assert_allclose(joint.A_pinv, joint.J_phi_n.T, atol=1e-13)


@pytest.mark.parametrize("robot_name", ["rtr", "ur5"])
def test_q_and_row_directions_same_for_both_scalings(
    rtr: Robot, ur5: Robot, robot_name: str
) -> None:
    robot, cases, state = (
        (rtr, _rtr_cases(), _rtr_state) if robot_name == "rtr" else (ur5, _ur5_cases(), _ur5_state)
    )
    rng = np.random.default_rng(4)
    for _, surfaces in cases:
        q, v = state(rng)
        tip = Constraint(surfaces, "tip").at(robot, q, v)
        joint = Constraint(surfaces, "joint").at(robot, q, v)
        np.testing.assert_allclose(tip.Q, joint.Q, atol=1e-12)
        np.testing.assert_allclose(tip.Qdot, joint.Qdot, atol=1e-9 * (1 + np.abs(tip.Qdot).max()))
        np.testing.assert_allclose(tip.J_phi_n, joint.J_phi_n, atol=1e-14)
        # each row of A is the raw row over a positive scale
        assert np.all(tip.scale > 0) and np.all(joint.scale > 0)
        for ct in (tip, joint):
            np.testing.assert_allclose(ct.A * ct.scale[:, None], ct.J_phi, atol=1e-12)


def test_rows_phi_distance_scale_rate_from_surface_and_robot(rtr: Robot, ur5: Robot) -> None:
    """J_Φ = ∇Φᵀ J; "tip" scale = ‖∇Φ‖, "joint" scale = ‖J_Φ‖; rate = A v; drift = raw / s."""
    rng = np.random.default_rng(5)
    for robot, cases, state in ((rtr, _rtr_cases(), _rtr_state), (ur5, _ur5_cases(), _ur5_state)):
        for _, surfaces in cases:
            q, v = state(rng)
            p, J = robot.tip_position(q), robot.jacobian(q)
            grads = np.array([s.gradient(p) for s in surfaces])
            tip = Constraint(surfaces, "tip").at(robot, q, v)
            joint = Constraint(surfaces, "joint").at(robot, q, v)
            for ct in (tip, joint):
                np.testing.assert_allclose(ct.J_phi, grads @ J, atol=1e-12)
                np.testing.assert_allclose(ct.phi, [s.phi(p) for s in surfaces], atol=1e-12)
                np.testing.assert_allclose(ct.distance, [s.distance(p) for s in surfaces])
                np.testing.assert_allclose(ct.rate, ct.A @ v, atol=1e-12)
                np.testing.assert_allclose(ct.drift, ct.raw_drift / ct.scale, rtol=1e-13)
            np.testing.assert_allclose(tip.scale, np.linalg.norm(grads, axis=1), rtol=1e-14)
            np.testing.assert_allclose(joint.scale, np.linalg.norm(grads @ J, axis=1), rtol=1e-13)
            # "tip" row = n̂ᵀJ with n̂ the unit normal
            normals = grads / np.linalg.norm(grads, axis=1)[:, None]
            np.testing.assert_allclose(tip.A, normals @ J, atol=1e-13)


# --- time derivatives against finite differences ------------------------------------------------
def _check_derivatives(robot: Robot, con: Constraint, q: np.ndarray, v: np.ndarray) -> float:
    """Compare raw_drift, Adot, A_pinv_dot, Qdot with central differences along q + v t."""
    ct = con.at(robot, q, v)

    def at(t: float) -> ConstraintTerms:
        return con.at(robot, q + t * v, v)

    worst = 0.0
    pairs = (
        (ct.raw_drift, _fd(lambda t: at(t).J_phi) @ v),
        (ct.Adot, _fd(lambda t: at(t).A)),
        (ct.A_pinv_dot, _fd(lambda t: at(t).A_pinv)),
        (ct.Qdot, _fd(lambda t: at(t).Q)),
    )
    for exact, fd in pairs:
        err = np.abs(exact - fd).max() / (1 + np.abs(fd).max())
        worst = max(worst, err)
        assert err < 1e-7, (exact, fd)
    return worst


@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_derivatives_match_finite_differences_rtr(rtr: Robot, normalization: str) -> None:
    rng = np.random.default_rng(6)
    for _, surfaces in _rtr_cases():
        con = Constraint(surfaces, normalization)
        for _ in range(3):
            q, v = _rtr_state(rng)
            _check_derivatives(rtr, con, q, v)


@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_derivatives_match_finite_differences_ur5(ur5: Robot, normalization: str) -> None:
    rng = np.random.default_rng(7)
    for _, surfaces in _ur5_cases():
        con = Constraint(surfaces, normalization)
        for _ in range(3):
            q, v = _ur5_state(rng)
            _check_derivatives(ur5, con, q, v)


@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_drift_gives_second_derivative_of_phi(rtr: Robot, ur5: Robot, normalization: str) -> None:
    """A q̈ + drift = Φ̈ / s along q(t) = q + v t + ½ a t² (second central difference)."""
    rng = np.random.default_rng(8)
    h = 1e-4
    for robot, cases, state in ((rtr, _rtr_cases(), _rtr_state), (ur5, _ur5_cases(), _ur5_state)):
        for _, surfaces in cases:
            con = Constraint(surfaces, normalization)
            q, v = state(rng)
            a = rng.uniform(-2, 2, robot.nv)
            ct = con.at(robot, q, v)

            def phi(t: float, q=q, v=v, a=a, surfaces=surfaces, robot=robot) -> np.ndarray:
                p = robot.tip_position(q + v * t + 0.5 * a * t * t)
                return np.array([s.phi(p) for s in surfaces])

            phi_ddot = (phi(h) - 2 * phi(0.0) + phi(-h)) / h**2
            np.testing.assert_allclose(
                ct.A @ a + ct.drift,
                phi_ddot / ct.scale,
                atol=1e-5 * (1 + np.abs(phi_ddot / ct.scale).max()),
            )
            # first derivative: rate = Φ̇ / s
            phi_dot = (phi(h) - phi(-h)) / (2 * h)
            np.testing.assert_allclose(ct.rate, phi_dot / ct.scale, atol=1e-7)


# --- property-based ---------------------------------------------------------------------------
_unit = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    radius=st.floats(0.05, 2.0),
    center=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(3, 9)),
    axis=st.tuples(_unit, _unit, _unit),
    inside=st.booleans(),
    kind=st.sampled_from(["cylinder", "sphere", "plane"]),
    q=st.tuples(st.floats(-3.1, 3.1), st.floats(2, 10), st.floats(-3.1, 3.1)),
    v=st.tuples(_unit, _unit, _unit),
    normalization=st.sampled_from(NORMALIZATIONS),
)
def test_property_random_surfaces_on_rtr(
    rtr: Robot,
    radius: float,
    center: tuple[float, float, float],
    axis: tuple[float, float, float],
    inside: bool,
    kind: str,
    q: tuple[float, float, float],
    v: tuple[float, float, float],
    normalization: str,
) -> None:
    assume(np.linalg.norm(axis) > 0.1)
    if kind == "cylinder":
        surface: Surface = Cylinder(radius, center=center, axis=axis, inside=inside)
    elif kind == "sphere":
        surface = Sphere(radius, center=center, inside=inside)
    else:
        surface = Plane(center, axis)
    con = Constraint(surface, normalization)
    qa, va = np.array(q), np.array(v)
    p = rtr.tip_position(qa)
    _, grad, hess = surface.evaluate(p)
    row = grad @ rtr.jacobian(qa)
    # stay away from singular states (tested separately below)
    assume(np.linalg.norm(grad) > 1e-3 and np.linalg.norm(row) > 1e-3 * np.linalg.norm(grad))
    # and from where ∇Φ turns over a short length ℓ = |∇Φ| / |∇²Φ| (near a cylinder's axis,
    # a sphere's centre): the central differences' relative error (H |ṗ| / ℓ)² stays < 1e-8
    speed = float(np.linalg.norm(rtr.jacobian(qa) @ np.array(v)))
    assume(H * speed < 1e-4 * np.linalg.norm(grad) / max(float(np.linalg.norm(hess)), 1e-300))
    ct = con.at(rtr, qa, va)
    assert all(np.all(np.isfinite(x)) for x in (ct.A, ct.Q, ct.Qdot, ct.A_pinv_dot, ct.drift))
    _check_identities(ct, 1, 3)
    np.testing.assert_allclose(ct.J_phi, row[None, :], atol=1e-12 * (1 + np.abs(row).max()))
    _check_derivatives(rtr, con, qa, va)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    q=st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6),
    v=st.lists(_unit, min_size=6, max_size=6),
    radius=st.floats(0.1, 1.0),
    normal=st.tuples(_unit, _unit, _unit),
    normalization=st.sampled_from(NORMALIZATIONS),
)
def test_property_two_surfaces_on_ur5(
    ur5: Robot,
    q: list[float],
    v: list[float],
    radius: float,
    normal: tuple[float, float, float],
    normalization: str,
) -> None:
    assume(np.linalg.norm(normal) > 0.1)
    surfaces = [Sphere(radius, center=(0.2, 0.1, 0.3)), Plane((0.1, 0.0, 0.2), normal)]
    qa, va = np.array(q), np.array(v)
    p = ur5.tip_position(qa)
    J = ur5.jacobian(qa)
    rows = np.array([s.gradient(p) @ J for s in surfaces])
    sv = np.linalg.svd(rows / np.linalg.norm(rows, axis=1)[:, None], compute_uv=False)
    assume(np.linalg.norm(p - (0.2, 0.1, 0.3)) > 1e-2 and sv[-1] > 1e-2)
    con = Constraint(surfaces, normalization)
    ct = con.at(ur5, qa, va)
    _check_identities(ct, 2, 6)
    _check_derivatives(ur5, con, qa, va)


@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_stacked_rows_equal_the_oracle(ur5: Robot, normalization: str) -> None:
    """k = 2 (the package's stacked numpy algebra) against the oracle's, whose A⁺ comes from
    an SVD and its rate from Golub and Pereyra's formula: every field within 1e-12 of its
    scale (1 + the largest entry), at random UR5 states."""
    rng = np.random.default_rng(29)
    surfaces = [Sphere(0.5, center=(0.2, 0.1, 0.3)), Plane((0.1, 0.0, 0.2), (0.3, -0.2, 1.0))]
    con = Constraint(surfaces, normalization)
    data = ur5.new_data()
    checked = 0
    for _ in range(20):
        q, v = _ur5_state(rng)
        terms = ur5.terms(q, v, data)
        try:
            want = constraint_terms(con, terms, v)
        except SurfaceError:
            with pytest.raises(SurfaceError):
                con.evaluate(terms, v)
            continue
        got = con.evaluate(terms, v)
        for name in ConstraintTerms.__dataclass_fields__:
            a, b = getattr(got, name), getattr(want, name)
            if not isinstance(b, np.ndarray):
                continue
            scale = 1.0 + float(np.abs(b).max())
            assert float(np.abs(a - b).max()) <= 1e-12 * scale, (name, np.abs(a - b).max())
        checked += 1
    assert checked >= 15


# --- singular and bad input -----------------------------------------------------------------
@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_tip_on_cylinder_axis_is_singular(rtr: Robot, normalization: str) -> None:
    q = np.array([0.3, 5.0, 0.8])
    p = rtr.tip_position(q)
    for surface in (Cylinder(0.4, center=p), Cylinder(0.2, center=p, axis=(1, 1, 0)), Sphere(1, p)):
        with pytest.raises(SurfaceError, match="∇Φ vanishes"):
            Constraint(surface, normalization).at(rtr, q, np.ones(3))


@pytest.mark.parametrize("q3", [0.0, np.pi, -np.pi])
@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_rtr_elbow_straight_or_folded_is_singular(
    rtr: Robot, q3: float, normalization: str
) -> None:
    """RTR with q3 = 0 or ±π on the z-axis cylinder: no column of J has a radial component.

    Hand check: ∇Φ = 2 (x, y, 0) is radial; J's columns are tangential (q1), vertical (q2) and
    (−c1 s3 l3, −s1 s3 l3, c3 l3) = (0, 0, ±l3) (q3) at s3 = 0, so J_Φ = 0 exactly.
    """
    q = np.array([0.7, 4.0, q3])
    for surface in (Cylinder(0.4), Cylinder(1.0, inside=True)):
        with pytest.raises(SurfaceError, match="J_Φ is \\(near\\) zero"):
            Constraint(surface, normalization).at(rtr, q, np.array([0.2, -0.1, 0.3]))


@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_near_singular_elbow_is_finite_or_raises(rtr: Robot, normalization: str) -> None:
    """Approaching q3 = 0 never yields NaN/inf: either finite terms or the specific error."""
    for eps in (1e-3, 1e-6, 1e-9, 1e-12, 1e-15, 0.0):
        q = np.array([0.7, 4.0, eps])
        try:
            ct = Constraint(Cylinder(0.4), normalization).at(rtr, q, np.ones(3))
        except SurfaceError:
            continue
        for x in (ct.A, ct.A_pinv, ct.Q, ct.Qdot, ct.A_pinv_dot, ct.drift):
            assert np.all(np.isfinite(x))


@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_identical_stacked_surfaces_are_singular(
    rtr: Robot, ur5: Robot, normalization: str
) -> None:
    with pytest.raises(SurfaceError, match="dependent"):
        Constraint([Cylinder(0.4), Cylinder(0.4)], normalization).at(rtr, [0.3, 5.0, 0.8])
    plane = Plane((0, 0, 0.2), (0, 0, 1))
    with pytest.raises(SurfaceError, match="dependent"):
        Constraint([plane, plane], normalization).at(ur5, [0.1, -1.0, 1.2, 0.3, 0.5, 0.2])
    # parallel planes at different heights: same normal, rows dependent
    with pytest.raises(SurfaceError):
        Constraint([plane, Plane((0, 0, 0.5), (0, 0, 2))], normalization).at(
            ur5, [0.1, -1.0, 1.2, 0.3, 0.5, 0.2]
        )


def test_bad_construction() -> None:
    with pytest.raises(SurfaceError, match="normalization"):
        Constraint(Cylinder(0.4), normalization="unit")  # type: ignore[arg-type]
    with pytest.raises(SurfaceError, match="at least one"):
        Constraint([])
    with pytest.raises(SurfaceError, match=r"surfaces\[1\]"):
        Constraint([Cylinder(0.4), "plane"])  # type: ignore[list-item]
    assert Constraint([Cylinder(0.4), Sphere(1.0)]).k == 2


def test_normal_rows_are_unit_normal_rows_and_first_order_distances() -> None:
    """normal_rows(p, J): n̂ᵀJ and Φ/‖∇Φ‖, checked against the cylinder's geometry by hand."""
    rng = np.random.default_rng(31)
    cons = Constraint([Cylinder(0.4), Plane(point=(0, 0, 1.0), normal=(0, 0, 1))])
    J = rng.standard_normal((3, 5))
    p = np.array([0.3, 0.4, 1.2])  # ρ = 0.5 from the z axis, 0.2 above the plane
    rows, dist = cons.normal_rows(p, J)
    n_cyl = np.array([0.6, 0.8, 0.0])
    np.testing.assert_allclose(rows[0], n_cyl @ J, atol=1e-15)
    np.testing.assert_allclose(rows[1], J[2], atol=1e-15)
    np.testing.assert_allclose(dist, [(0.25 - 0.16) / (2 * 0.5), 0.2], atol=1e-15)
    with pytest.raises(SurfaceError):
        cons.normal_rows(np.array([0.0, 0.0, 2.0]), J)  # on the cylinder's axis

"""The paper's control laws: eq. 4, 9–11, 13, 16, 29–30 (issue 4).

Independent references:
- eq. 10, s₀ᵀs₁ = 0, and s = s₀ + s₁ for tangent velocities (A q̇ = 0);
- q̈_r = qddot_r0 + qddot_r_f·f against a central difference of q̇_r(t) along a smooth motion
  of the RTR arm ON a cylinder (paper's and a tilted one; q(t) by closed-form RTR inverse
  kinematics, q̇ = J⁻¹ṗ exactly), with ė_F = f − f_d known; and along an arbitrary UR5 motion
  with two stacked surfaces;
- the loop-resolved (q̈, f) with B from the law: equal to the dense KKT solve
  (oracles.plant.kkt) and to a hand-built Schur-complement solve; the closed loop eq. 13
  holds to round-off; V̇ from the identity V̇ = sᵀMṡ + ½sᵀṀs + βe_Fᵀė_F (Ṁ by finite
  differences) equals −sᵀK_d s − βγ e_Fᵀe_F (eq. 16);
- free_space_law reproduces M q̈_r + C q̇_r + g − K_d s by hand; gains validation.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin
import pytest
from oracles.control import arimoto_law, free_space_law
from oracles.plant import kkt

from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.laws.arimoto import default_damping_gain, make_gains
from hybrid_force.control.laws.base import ControlTrace, Desired, Gains
from hybrid_force.errors import ControlError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.model.robot import Robot
from hybrid_force.sim.dynamics import Baumgarte, ConstrainedDynamics

L2, L3 = 0.9, 1.0  # RTR link lengths [m] (robots/rtr.urdf)
NORMALIZATIONS = ("tip", "joint")


def _rtr_ik(p: np.ndarray, elbow_up: bool = True) -> np.ndarray:
    """Closed-form RTR inverse kinematics: p = (c1 r, s1 r, l3 s3 + q2), r = l3 c3 + l2."""
    x, y, z = p
    r = np.hypot(x, y)
    c3 = (r - L2) / L3
    s3 = np.sqrt(1.0 - c3 * c3) * (1.0 if elbow_up else -1.0)
    return np.array([np.arctan2(y, x), z - L3 * s3, np.arctan2(s3, c3)])


def _cylinder_path(cyl: Cylinder, z0: float) -> Callable[[float], tuple[np.ndarray, np.ndarray]]:
    """A smooth wobbly helix ON the cylinder: t ↦ (p(t), ṗ(t))."""
    a = np.asarray(cyl.axis)
    e1 = np.cross(a, [0.3, 0.2, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    c = np.asarray(cyl.center)
    r = cyl.radius

    def path(t: float) -> tuple[np.ndarray, np.ndarray]:
        th = 0.3 + 0.8 * t + 0.2 * np.sin(3 * t)
        thd = 0.8 + 0.6 * np.cos(3 * t)
        s = z0 + 0.3 * np.sin(2 * t)
        sd = 0.6 * np.cos(2 * t)
        p = c + s * a + r * (np.cos(th) * e1 + np.sin(th) * e2)
        pd = sd * a + r * thd * (-np.sin(th) * e1 + np.cos(th) * e2)
        return p, pd

    return path


def _desired(t: float, q0: np.ndarray) -> Desired:
    """An analytic q_d(t) with exact q̇_d, q̈_d (independent of the arm's motion)."""
    n = q0.shape[0]
    w = np.linspace(0.7, 1.9, n)
    b = np.linspace(-0.2, 0.3, n)
    return Desired(
        q=q0 + b * t + 0.05 * np.sin(w * t),
        qd=b + 0.05 * w * np.cos(w * t),
        qdd=-0.05 * w * w * np.sin(w * t),
    )


def _momentum_error(t: float, k: int) -> tuple[np.ndarray, np.ndarray]:
    """e_F(t) [N·s] and ė_F(t) [N]."""
    w = np.linspace(1.3, 2.1, k)
    return 0.2 * np.sin(w * t) + 0.05, 0.2 * w * np.cos(w * t)


def _gains(robot: Robot, q: np.ndarray, beta: float = 0.3) -> Gains:
    return make_gains(default_damping_gain(robot.mass_matrix(q), 20.0), 10.0, beta, 20.0, robot.nv)


def _law(
    robot: Robot,
    con: Constraint,
    gains: Gains,
    q: np.ndarray,
    v: np.ndarray,
    des: Desired,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray | None = None,
):
    terms = robot.terms(q, v, robot.new_data())
    ct = con.evaluate(terms, v)
    command, trace = arimoto_law(gains, terms, ct, v, q - des.q, des, e_F, f_d, approach)
    return terms, ct, command, trace


def _contact_state(
    robot: Robot, surface: Cylinder, rng: np.random.Generator, normalization: str
) -> tuple[np.ndarray, np.ndarray, ConstraintTerms]:
    """RTR on the cylinder with a random tangent velocity (A v = 0)."""
    path = _cylinder_path(surface, z0=7.0 if np.allclose(surface.axis, [0, 0, 1]) else 0.0)
    p, _ = path(rng.uniform(0, 6))
    q = _rtr_ik(p, elbow_up=bool(rng.integers(2)))
    ct0 = Constraint(surface, normalization).at(robot, q)
    v = ct0.Q @ rng.uniform(-1, 1, 3)
    return q, v, ct0


# --- eq. 10 -----------------------------------------------------------------------------------
@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_s0_orthogonal_to_s1(rtr: Robot, ur5: Robot, normalization: str) -> None:
    rng = np.random.default_rng(21)
    cases: list[tuple[Robot, list[Surface]]] = [
        (rtr, [Cylinder(0.4)]),
        (rtr, [Plane((0, 0, 7), (0, 0, 1)), Cylinder(0.4)]),
        (ur5, [Sphere(0.3, center=(0.3, 0.1, 0.3))]),
        (ur5, [Plane((0, 0, 0.2), (0.2, 0.1, 1.0)), Cylinder(0.4, axis=(1, 0, 0))]),
    ]
    worst = 0.0
    for robot, surfaces in cases:
        con = Constraint(surfaces, normalization)
        k = len(surfaces)
        for _ in range(10):
            if robot is rtr:
                q = np.array([rng.uniform(-3, 3), rng.uniform(3, 9), rng.uniform(0.4, 2.7)])
            else:
                q = rng.uniform(-2.5, 2.5, 6)
            v = rng.uniform(-1, 1, robot.nv)
            des = _desired(rng.uniform(0, 3), q + rng.uniform(-0.1, 0.1, robot.nv))
            e_F = rng.uniform(-2, 2, k)
            _, ct, _, tr = _law(robot, con, _gains(robot, q), q, v, des, e_F, np.full(k, 10.0))
            scale = np.linalg.norm(tr.s0) * np.linalg.norm(tr.s1)
            worst = max(worst, abs(tr.s0 @ tr.s1) / scale)
            assert abs(tr.s0 @ tr.s1) <= 1e-12 * scale
            # s₁ = −βA⁺e_F, s₀ = Q(q̇ − x): hand formulas
            np.testing.assert_allclose(tr.s1, -0.3 * ct.A_pinv @ e_F, atol=1e-13)
            # for a tangent velocity (A v = 0), s = s₀ + s₁ (eq. 9)
            v_t = ct.Q @ v
            _, _, _, tr_t = _law(robot, con, _gains(robot, q), q, v_t, des, e_F, np.full(k, 10.0))
            np.testing.assert_allclose(tr_t.s, tr_t.s0 + tr_t.s1, atol=1e-12)
            assert abs(tr_t.s0 @ tr_t.s1) <= 1e-12 * (
                np.linalg.norm(tr_t.s0) * np.linalg.norm(tr_t.s1)
            )


# --- gains --------------------------------------------------------------------------------------
def test_make_gains_accepts_scalar_vector_matrix() -> None:
    g = make_gains(5.0, 2.0, 0.0, 3.0, 3)
    np.testing.assert_array_equal(g.Kd, 5.0 * np.eye(3))
    assert (g.Lambda, g.beta, g.gamma) == (2.0, 0.0, 3.0)
    np.testing.assert_array_equal(make_gains([1.0, 2.0, 3.0], 1, 1, 1, 3).Kd, np.diag([1, 2, 3]))
    K = np.array([[2.0, 0.5, 0.0], [0.5, 3.0, 0.1], [0.0, 0.1, 1.0]])
    np.testing.assert_array_equal(make_gains(K, 1, 1, 1, 3).Kd, K)
    assert make_gains(np.int64(4), 1, 1, 1, 2).Kd.dtype == float


@pytest.mark.parametrize(
    ("Kd", "match"),
    [
        (np.array([[1.0, 2.0], [2.0, 1.0]]), "smallest eigenvalue is -1"),
        (np.array([[1.0, 0.5], [0.0, 1.0]]), "symmetric"),
        (-1.0, "smallest eigenvalue is -1"),
        (0.0, "smallest eigenvalue is 0"),
        ([1.0, -2.0], "smallest eigenvalue is -2"),
        ([1.0, np.nan], "non-finite"),
        ([1.0, 2.0, 3.0], r"shape \(3,\)"),
    ],
)
def test_make_gains_rejects_bad_kd(Kd: object, match: str) -> None:
    with pytest.raises(ControlError, match=match) as info:
        make_gains(Kd, 1.0, 0.1, 1.0, 2)  # type: ignore[arg-type]
    assert "Kd" in str(info.value)


@pytest.mark.parametrize(
    ("name", "args"),
    [
        ("Lambda", (0.0, 0.1, 1.0)),
        ("Lambda", (-2.5, 0.1, 1.0)),
        ("Lambda", (np.nan, 0.1, 1.0)),
        ("beta", (1.0, -0.5, 1.0)),
        ("beta", (1.0, np.inf, 1.0)),
        ("gamma", (1.0, 0.1, 0.0)),
        ("gamma", (1.0, 0.1, -3.0)),
    ],
)
def test_make_gains_rejects_bad_scalars(name: str, args: tuple[float, float, float]) -> None:
    bad = args[("Lambda", "beta", "gamma").index(name)]
    with pytest.raises(ControlError) as info:
        make_gains(1.0, *args, 3)
    message = str(info.value)
    assert name in message
    assert repr(bad) in message or str(bad) in message


# --- q̈_r is the time derivative of q̇_r --------------------------------------------------------
def _check_qddot_r(
    robot: Robot,
    con: Constraint,
    motion: Callable[[float], tuple[np.ndarray, np.ndarray]],
    t0: float,
    approach: np.ndarray | None = None,
    h: float = 1e-5,
) -> float:
    """|q̈_r − FD(q̇_r)| / (1 + |FD|) at t0 along the motion t ↦ (q, v)."""
    k = con.k
    q0, _ = motion(0.0)
    gains = _gains(robot, q0)
    f_d = np.full(k, 10.0)

    def trace(t: float) -> ControlTrace:
        q, v = motion(t)
        e_F, _ = _momentum_error(t, k)
        return _law(robot, con, gains, q, v, _desired(t, q0), e_F, f_d, approach)[3]

    tr = trace(t0)
    _, e_F_dot = _momentum_error(t0, k)
    f = e_F_dot + f_d  # ė_F = f − f_d
    qddot_r = tr.qddot_r0 + tr.qddot_r_f @ f
    fd = (trace(t0 + h).qdot_r - trace(t0 - h).qdot_r) / (2 * h)
    err = float(np.abs(qddot_r - fd).max() / (1 + np.abs(fd).max()))
    assert err < 1e-7, (qddot_r, fd)
    return err


@pytest.mark.parametrize("normalization", NORMALIZATIONS)
@pytest.mark.parametrize(
    "surface",
    [
        Cylinder(0.4),
        Cylinder(0.4, inside=True),
        Cylinder(0.4, center=(0.6, 0, 6), axis=(0.3, 1, 0.2)),
    ],
    ids=["paper", "inside", "tilted"],
)
def test_qddot_r_is_derivative_of_qdot_r_on_cylinder(
    rtr: Robot, surface: Cylinder, normalization: str
) -> None:
    """RTR tip moving ON the cylinder (Φ = 0 along the motion), q̇ = J⁻¹ṗ exactly."""
    path = _cylinder_path(surface, z0=7.0 if np.allclose(surface.axis, [0, 0, 1]) else 0.0)

    def motion(t: float) -> tuple[np.ndarray, np.ndarray]:
        p, pd = path(t)
        q = _rtr_ik(p)
        return q, np.linalg.solve(rtr.jacobian(q), pd)

    # the motion really is on the surface
    for t in (0.0, 0.5, 1.7):
        q, v = motion(t)
        assert abs(surface.distance(rtr.tip_position(q))) < 1e-12
        np.testing.assert_allclose(Constraint(surface).at(rtr, q).A @ v, 0.0, atol=1e-12)
    con = Constraint(surface, normalization)
    for t0 in (0.2, 1.1, 2.5):
        _check_qddot_r(rtr, con, motion, t0)
    # with a constant approach velocity term (near phase)
    _check_qddot_r(rtr, con, motion, 0.7, approach=np.array([0.01]))


@pytest.mark.parametrize("normalization", NORMALIZATIONS)
def test_qddot_r_is_derivative_of_qdot_r_two_surfaces_ur5(ur5: Robot, normalization: str) -> None:
    """An arbitrary smooth UR5 motion with a plane + cylinder groove (k = 2)."""
    rng = np.random.default_rng(23)
    qc = rng.uniform(-2, 2, 6)
    w = rng.uniform(0.5, 2.0, 6)

    def motion(t: float) -> tuple[np.ndarray, np.ndarray]:
        return qc + 0.3 * np.sin(w * t), 0.3 * w * np.cos(w * t)

    con = Constraint(
        [Plane((0, 0, 0.2), (0.2, 0.1, 1.0)), Cylinder(0.4, axis=(1, 0, 0))], normalization
    )
    for t0 in (0.3, 1.4):
        _check_qddot_r(ur5, con, motion, t0)


# --- the loop-resolved force and the closed loop ------------------------------------------------
def _schur_solve(
    M: np.ndarray, nle: np.ndarray, u0: np.ndarray, B: np.ndarray, A: np.ndarray, gamma: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Hand-built solve of M q̈ + nle = u0 + (Aᵀ + B) f, A q̈ = −γ by eliminating q̈."""
    G = A.T + B
    Minv_G = np.linalg.solve(M, G)
    Minv_r = np.linalg.solve(M, u0 - nle)
    f = np.linalg.solve(A @ Minv_G, -gamma - A @ Minv_r)
    return Minv_r + Minv_G @ f, f


@pytest.mark.parametrize("normalization", NORMALIZATIONS)
@pytest.mark.parametrize("beta", [0.01, 0.5])
def test_loop_resolved_force_and_closed_loop(rtr: Robot, normalization: str, beta: float) -> None:
    rng = np.random.default_rng(24)
    baum = Baumgarte()
    worst = {"kkt": 0.0, "eq13": 0.0, "Vdot": 0.0}
    for surface in (Cylinder(0.4), Cylinder(0.4, inside=True)):
        con = Constraint(surface, normalization)
        for _ in range(6):
            q, v, _ = _contact_state(rtr, surface, rng, normalization)
            des = _desired(rng.uniform(0, 3), q + rng.uniform(-0.05, 0.05, 3))
            e_F = rng.uniform(-1, 1, 1)
            f_d = np.array([10.0])
            gains = _gains(rtr, q, beta)
            terms, ct, cmd, tr = _law(rtr, con, gains, q, v, des, e_F, f_d)
            assert cmd.B is not None
            np.testing.assert_allclose(cmd.B, beta * terms.M @ ct.A_pinv, atol=1e-12)
            gamma = baum.gamma(ct.drift, ct.rate, ct.phi / ct.scale)
            data = rtr.new_data()
            pin.crba(rtr.model, data, q)
            ddq, f = ConstrainedDynamics(rtr.model, data, ct.A.shape[0]).solve(
                terms.nle, cmd.u0, cmd.B, ct.A, gamma
            )
            ddq_k, f_k = kkt(terms.M, terms.nle, cmd.u0, cmd.B, ct.A, gamma)
            ddq_s, f_s = _schur_solve(terms.M, terms.nle, cmd.u0, cmd.B, ct.A, gamma)
            for ref_ddq, ref_f in ((ddq_k, f_k), (ddq_s, f_s)):
                err = max(
                    np.abs(ddq - ref_ddq).max() / (1 + np.abs(ref_ddq).max()),
                    np.abs(f - ref_f).max() / (1 + np.abs(ref_f).max()),
                )
                worst["kkt"] = max(worst["kkt"], err)
                assert err < 1e-9
            # the coupled system itself
            u = cmd.u0 + cmd.B @ f
            res = terms.M @ ddq + terms.nle - u - ct.A.T @ f
            assert np.abs(res).max() < 1e-9 * (1 + np.abs(u).max())
            np.testing.assert_allclose(ct.A @ ddq, -gamma, atol=1e-9 * (1 + np.abs(gamma).max()))
            # closed loop, eq. 13: M ṡ + C s + K_d s = Aᵀ(ė_F + γ e_F)
            e_F_dot = f - f_d
            s_dot = ddq - (tr.qddot_r0 + tr.qddot_r_f @ f)
            lhs = terms.M @ s_dot + terms.C @ tr.s + gains.Kd @ tr.s
            rhs = ct.A.T @ (e_F_dot + gains.gamma * e_F)
            err13 = np.abs(lhs - rhs).max() / (
                1 + np.abs(rhs).max() + np.abs(gains.Kd @ tr.s).max()
            )
            worst["eq13"] = max(worst["eq13"], err13)
            assert err13 < 1e-10
            # eq. 16 from the identity V̇ = sᵀMṡ + ½sᵀṀs + β e_Fᵀė_F (Ṁ by central differences)
            h = 1e-6
            Mdot = (rtr.mass_matrix(q + h * v) - rtr.mass_matrix(q - h * v)) / (2 * h)
            s = tr.s
            V_dot = s @ terms.M @ s_dot + 0.5 * s @ Mdot @ s + beta * e_F @ e_F_dot
            V_dot_paper = -s @ gains.Kd @ s - beta * gains.gamma * e_F @ e_F
            errV = abs(V_dot - V_dot_paper) / (1 + abs(V_dot_paper))
            worst["Vdot"] = max(worst["Vdot"], errV)
            assert errV < 1e-6
            V = 0.5 * s @ terms.M @ s + 0.5 * beta * e_F @ e_F
            assert abs(tr.V - V) <= 1e-12 * (1 + V)


def test_loop_resolved_force_two_surfaces(ur5: Robot) -> None:
    """k = 2: the loop-resolved (q̈, f) equals both dense references."""
    rng = np.random.default_rng(25)
    con = Constraint([Plane((0, 0, 0.2), (0.2, 0.1, 1.0)), Cylinder(0.4, axis=(1, 0, 0))])
    for _ in range(5):
        q = rng.uniform(-2, 2, 6)
        v = Constraint(con.surfaces).at(ur5, q).Q @ rng.uniform(-1, 1, 6)
        des = _desired(0.5, q + 0.01)
        e_F = rng.uniform(-1, 1, 2)
        terms, ct, cmd, _ = _law(ur5, con, _gains(ur5, q, 0.2), q, v, des, e_F, np.full(2, 5.0))
        gamma = Baumgarte().gamma(ct.drift, ct.rate, ct.phi / ct.scale)
        data = ur5.new_data()
        pin.crba(ur5.model, data, q)
        ddq, f = ConstrainedDynamics(ur5.model, data, ct.A.shape[0]).solve(
            terms.nle, cmd.u0, cmd.B, ct.A, gamma
        )
        ddq_s, f_s = _schur_solve(terms.M, terms.nle, cmd.u0, cmd.B, ct.A, gamma)
        ddq_k, f_k = kkt(terms.M, terms.nle, cmd.u0, cmd.B, ct.A, gamma)
        np.testing.assert_allclose(f, f_s, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(f_k, f_s, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(ddq, ddq_s, rtol=1e-8, atol=1e-8 * (1 + np.abs(ddq_s).max()))
        np.testing.assert_allclose(ddq_k, ddq_s, rtol=1e-8, atol=1e-8 * (1 + np.abs(ddq_s).max()))


def test_beta_zero_has_no_loop(rtr: Robot) -> None:
    """β = 0: B is None and q̈_r does not depend on f (qddot_r_f = 0)."""
    q, v, _ = _contact_state(rtr, Cylinder(0.4), np.random.default_rng(26), "tip")
    des = _desired(0.1, q)
    _, _, cmd, tr = _law(
        rtr, Constraint(Cylinder(0.4)), _gains(rtr, q, 0.0), q, v, des, np.ones(1), np.ones(1)
    )
    assert cmd.B is None
    np.testing.assert_array_equal(tr.qddot_r_f, np.zeros((3, 1)))


# --- free space ----------------------------------------------------------------------------------
def test_free_space_law_by_hand(ur5: Robot) -> None:
    rng = np.random.default_rng(27)
    qc = rng.uniform(-2, 2, 6)
    w = rng.uniform(0.5, 2.0, 6)

    def motion(t: float) -> tuple[np.ndarray, np.ndarray]:
        return qc + 0.3 * np.sin(w * t), 0.3 * w * np.cos(w * t)

    gains = make_gains(rng.uniform(1, 5, 6), 4.0, 0.0, 1.0, 6)

    def law(t: float):
        q, v = motion(t)
        des = _desired(t, qc)
        terms = ur5.terms(q, v, ur5.new_data())
        return free_space_law(gains, terms, v, q - des.q, des)

    for t0 in (0.4, 1.3):
        cmd, tr = law(t0)
        q, v = motion(t0)
        des = _desired(t0, qc)
        qdot_r = des.qd - 4.0 * (q - des.q)
        qddot_r = des.qdd - 4.0 * (v - des.qd)
        s = v - qdot_r
        u = (
            ur5.mass_matrix(q) @ qddot_r
            + ur5.coriolis(q, v) @ qdot_r
            + ur5.gravity(q)
            - gains.Kd @ s
        )
        assert cmd.B is None
        np.testing.assert_allclose(cmd.u0, u, atol=1e-10 * (1 + np.abs(u).max()))
        np.testing.assert_allclose(tr.qdot_r, qdot_r, atol=1e-13)
        np.testing.assert_allclose(tr.s, s, atol=1e-13)
        # q̈_r is the time derivative of q̇_r along the motion
        h = 1e-5
        fd = (law(t0 + h)[1].qdot_r - law(t0 - h)[1].qdot_r) / (2 * h)
        np.testing.assert_allclose(tr.qddot_r0, fd, atol=1e-7 * (1 + np.abs(fd).max()))
        V = 0.5 * s @ ur5.mass_matrix(q) @ s
        assert abs(tr.V - V) <= 1e-12 * (1 + V)

"""The operational-space hybrid law (hybrid_force.control.laws.osc_hybrid, Khatib 1987).

Independent references:
- dynamic consistency: J̄ equals the M-weighted pseudo-inverse M^-½ (J M^-½)⁺ (numpy's pinv),
  J J̄ = I, J M⁻¹ Nᵀ τ₀ = 0 for random τ₀, N² = N; N = 0 on the RTR;
- free space with the exact model: the tip acceleration from Pinocchio's forward dynamics
  (ABA) and classical frame acceleration equals p̈_d − K_v ė − K_p e; a simulated run follows
  the analytic solution of ë + K_v ė + K_p e = 0 to first order in the time step;
- rigid contact: a hand-solved KKT system (with the law's B) gives
  (1 + k_P)(f − f_d) = −k_I e_F at a tangent velocity and Ω p̈ = Ω a_m (the decoupling);
- the near phase touches at ḋ = −λ_a·contact_tol (d̈ + (λ_a + K_n) ḋ + λ_a K_n d = 0);
- on a compliant surface, stable iff K_n (1 + k_P) > k_I (Routh, module docstring);
- the null-space posture converges on the UR5 at the rate ω_n;
- the brief's target on every shipped contact scenario and on a Panda, default gains.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from oracles.laws import OscHybridLaw, normal_directions, osc_hybrid_law
from oracles.terms import constraint_terms, robot_terms

from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.base import Desired, LawInput
from hybrid_force.control.laws.osc_hybrid import OscOptions, check, osc_gains, task_space
from hybrid_force.errors import ControlError, ScenarioError, SurfaceError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.model.robot import LWA, Robot
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

GAINS = osc_gains(
    OscOptions(), approach_rate=10.0
)  # the defaults: ω = 20, ζ = 1, ω_n = 10, k_I = 20
SCENARIOS = ("paper_contact", "paper_approach", "rtr_plane", "rtr_sphere", "ur5_plane")


def _state(robot: Robot, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
    return q, rng.normal(size=robot.nv)


def _tip_acceleration(robot: Robot, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """p̈ from Pinocchio's classical frame acceleration (independent of J̇ in the law)."""
    data = robot.new_data()
    pin.forwardKinematics(robot.model, data, q, v, a)
    return pin.getFrameClassicalAcceleration(robot.model, data, robot.tip_id, LWA).linear


def _desired(rng: np.random.Generator, n: int, p: np.ndarray) -> Desired:
    return Desired(
        q=rng.normal(size=n),
        qd=rng.normal(size=n),
        qdd=rng.normal(size=n),
        p=p + 0.05 * rng.normal(size=3),
        pd=rng.normal(size=3),
        pdd=rng.normal(size=3),
    )


# --------------------------------------------------------------------- operational space
@pytest.mark.parametrize("arm", ["ur5", "panda"])
def test_dynamically_consistent_inverse_and_null_space(arm: str, request, rng) -> None:
    robot = request.getfixturevalue(arm)
    for _ in range(3):
        q, _ = _state(robot, rng)
        M, J = robot.mass_matrix(q), robot.jacobian(q)
        ts = task_space(M, J)
        # the M-weighted pseudo-inverse, from M^-½ by an eigendecomposition and numpy's pinv
        w, V = np.linalg.eigh(M)
        M_inv_half = V @ np.diag(w**-0.5) @ V.T
        assert np.allclose(ts.Jbar, M_inv_half @ np.linalg.pinv(J @ M_inv_half), atol=1e-9)
        assert np.allclose(J @ ts.Jbar, np.eye(3), atol=1e-10)
        assert np.allclose(ts.N @ ts.N, ts.N, atol=1e-10)
        tau0 = rng.normal(size=(robot.nv, 5)) * 10.0
        task_acc = J @ np.linalg.solve(M, ts.N.T @ tau0)
        assert np.abs(task_acc).max() < 1e-10 * np.abs(tau0).max()
        assert np.allclose(ts.Lambda, np.linalg.inv(J @ np.linalg.inv(M) @ J.T), rtol=1e-9)


def test_rtr_has_no_null_space(rtr: Robot, rng) -> None:
    q = np.array([0.3, 6.0, 0.7])
    ts = task_space(rtr.mass_matrix(q), rtr.jacobian(q))
    assert np.array_equal(ts.N, np.zeros((3, 3)))
    assert np.allclose(ts.Jbar, np.linalg.inv(rtr.jacobian(q)), atol=1e-12)


@pytest.mark.parametrize("smallest", [0.0, 1e-8])
def test_a_rank_deficient_jacobian_is_refused(smallest: float) -> None:
    """J M⁻¹ Jᵀ = diag(1, 1, smallest²): cond ∞ or 1e16, above the 1e12 limit."""
    J = np.diag([1.0, 1.0, smallest])
    with pytest.raises(SurfaceError) as info:
        task_space(np.eye(3), J)
    assert info.value.key == "control.law" and info.value.value == "osc_hybrid"
    assert np.allclose(task_space(np.eye(3), np.diag([1.0, 1.0, 1e-5])).Lambda[2, 2], 1e10)


# --------------------------------------------------------------------- free space
@pytest.mark.parametrize("arm", ["rtr", "ur5", "panda"])
def test_free_space_task_acceleration_is_the_linear_servo(arm: str, request, rng) -> None:
    """Exact model: p̈ = p̈_d − K_v ė − K_p e, i.e. ë + K_v ė + K_p e = 0 (module eq. 2–3)."""
    robot = request.getfixturevalue(arm)
    for _ in range(3):
        q, v = _state(robot, rng)
        terms = robot_terms(robot, q, v)
        d = _desired(rng, robot.nv, terms.p)
        command, _ = osc_hybrid_law(GAINS, terms, v, q - d.q, d)
        assert command.B is None
        a = pin.aba(robot.model, robot.new_data(), q, v, command.u0)
        e, e_dot = terms.p - d.p, terms.pdot - d.pd
        expected = d.pdd - GAINS.kv * e_dot - GAINS.kp * e
        assert np.allclose(_tip_acceleration(robot, q, v, a), expected, rtol=1e-8, atol=1e-8)


def test_free_space_run_follows_the_analytic_error() -> None:
    """paper_approach starts 8 m from p_d, off the wall: with ζ = 1 every component of e obeys
    e(t) = (e₀ + (ė₀ + ω e₀) t) e^(−ωt); the simulated run converges to it as O(dt)."""
    deviation = {}
    for dt in (1e-3, 5e-4):
        sc = load_scenario(
            "scenarios/paper_approach.toml",
            overrides={"control.law": "osc_hybrid", "sim.duration": 0.1, "sim.dt": dt},
        )
        r = simulate(sc)
        assert not r.meta["events"]  # still in free space
        e = r.p - r.p_d
        omega, t = 20.0, r.t[:, None]
        e0, e_dot0 = e[0], -sc.path.evaluate(0.0)[1]  # starts at rest
        analytic = (e0 + (e_dot0 + omega * e0) * t) * np.exp(-omega * t)
        deviation[dt] = np.abs(e - analytic).max() / np.abs(e0).max()
    assert deviation[1e-3] < 1e-2
    assert 1.8 < deviation[1e-3] / deviation[5e-4] < 2.2  # first order in dt


# --------------------------------------------------------------------- contact
def _kkt(M, A, B, u0, nle, drift):
    """(q̈, f) of M q̈ = u0 + B f − nle + Aᵀf, A q̈ = −drift, solved by hand (dense)."""
    k, n = A.shape
    K = np.block([[M, -(A.T + B)], [A, np.zeros((k, k))]])
    sol = np.linalg.solve(K, np.concatenate([u0 - nle, -drift]))
    return sol[:n], sol[n:]


def _on_surfaces(name: str, rtr: Robot, ur5: Robot):
    if name == "rtr_cylinder":  # the paper's cylinder, the start of section 6.3
        q = np.array([0.0, 6.0, 2.0])
        p = rtr.tip_position(q)
        r = float(np.hypot(p[0], p[1]))
        return rtr, q, [Cylinder(radius=r, axis=(0.0, 0.0, 1.0))]
    q = np.array([0.3, -1.2, 1.4, -1.6, -1.5, 0.2])
    p = ur5.tip_position(q)
    if name == "ur5_sphere":
        return ur5, q, [Sphere(radius=0.2, center=p - np.array([0.0, 0.0, 0.2]))]
    return ur5, q, [Plane(p, (0.0, 0.0, 1.0)), Plane(p, (1.0, 0.0, 0.0))]  # an edge, k = 2


@pytest.mark.parametrize("normalization", ["tip", "joint"])
@pytest.mark.parametrize("case", ["rtr_cylinder", "ur5_sphere", "ur5_edge"])
def test_rigid_contact_force_and_decoupling(case: str, normalization: str, rtr, ur5, rng) -> None:
    """On the surface at a tangent velocity (ν = 0), exact model, no stabilisation: the force
    is f_d − k_I e_F / (1 + k_P) and the motion along the surface is Ω a_m (on the curved
    surfaces this holds only with the curvature term c: without it f is off by Σ⁻¹ c)."""
    robot, q, surfaces = _on_surfaces(case, rtr, ur5)
    constraint = Constraint(surfaces, normalization=normalization)
    gains = osc_gains(OscOptions(force_p=0.5, force_i=7.0), approach_rate=10.0)
    law = OscHybridLaw(gains, constraint, robot.nv)
    k = constraint.k
    at_rest = np.zeros(robot.nv)
    cons0 = constraint_terms(constraint, robot_terms(robot, q, at_rest), at_rest)
    v = cons0.Q @ rng.normal(size=robot.nv)  # tangent: A v = 0
    terms = robot_terms(robot, q, v)
    cons = constraint_terms(constraint, terms, v)
    d = _desired(rng, robot.nv, terms.p)
    e_F, f_d = rng.normal(size=k), np.array([10.0, 4.0][:k])
    command = law.hybrid(LawInput(terms, v, q - d.q, d, cons, e_F, f_d))
    assert command.B is not None and np.allclose(command.B, 0.5 * cons.A.T)
    qdd, f = _kkt(terms.M, cons.A, command.B, command.u0, terms.nle, cons.drift)
    assert np.allclose(f, f_d - gains.force_i * e_F / 1.5, rtol=1e-8, atol=1e-8)
    W = normal_directions(constraint, terms.p, cons.scale)
    Omega = np.eye(3) - W @ np.linalg.solve(W.T @ W, W.T)
    a_m = d.pdd - gains.kv * (terms.pdot - d.pd) - gains.kp * (terms.p - d.p)
    p_ddot = _tip_acceleration(robot, q, v, qdd)
    assert np.allclose(Omega @ p_ddot, Omega @ a_m, rtol=1e-8, atol=1e-8)


def test_near_phase_touches_at_the_approach_speed() -> None:
    """rtr_plane: λ_a = Λ = 10 < K_n = 40, so the slow pole sets the touch speed λ_a·tol."""
    sc = load_scenario(
        "scenarios/rtr_plane.toml", overrides={"control.law": "osc_hybrid", "sim.duration": 0.9}
    )
    m = simulate(sc).metrics()
    assert m.n_impacts == 1
    assert m.impact_speed == pytest.approx(10.0 * 1e-5, rel=0.05)


@pytest.mark.parametrize(("normal_damping", "stable"), [(30.0, True), (12.0, False)])
def test_compliant_contact_is_stable_iff_Kn_exceeds_kI(normal_damping: float, stable: bool) -> None:
    """Linear spring k_s = 1e6 N/m, k_P = 0, k_I = 20 1/s: the normal loop
    Λ_n s³ + Λ_n K_n s² + k_s s + k_I k_s is stable iff K_n > k_I (Routh)."""
    sc = load_scenario(
        "scenarios/rtr_plane.toml",
        overrides={
            "control.law": "osc_hybrid",
            "control.osc_hybrid.normal_damping": normal_damping,
            "contact.model": "compliant",
            "sim.duration": 4.0,
            "sim.settle_time": 3.0,
        },
    )
    r = simulate(sc)
    in_contact = r.phase[r.t >= 3.0] == 2
    if stable:
        assert in_contact.all()
        assert np.abs(r.f - r.f_d)[r.t >= 3.0].max() < 1e-2
    else:  # the force oscillation grows until the tool bounces off the surface
        assert not in_contact.all()


# --------------------------------------------------------------------- null space
def test_null_space_posture_converges_on_the_ur5(ur5: Robot) -> None:
    """Start on the task point but 0.1 rad away from the posture q* along the null space: the
    posture error decays at ω_n (critically damped), a slow ω_n leaves most of it."""
    q_star = np.array([0.3, -1.2, 1.4, -1.6, -1.5, 0.2])
    p_star = ur5.tip_position(q_star)
    null_dir = np.linalg.svd(ur5.jacobian(q_star))[2][-1]
    desired = Desired(q_star, np.zeros(6), np.zeros(6), p_star, np.zeros(3), np.zeros(3))
    remaining = {}
    for null_omega in (10.0, 0.5):
        law = OscHybridLaw(
            osc_gains(OscOptions(null_omega=null_omega), 10.0),
            Constraint(Plane(p_star, (0, 0, 1))),
            6,
        )
        q, v, data, dt = q_star + 0.1 * null_dir, np.zeros(6), ur5.new_data(), 1e-3
        for _ in range(2000):  # 2 s, semi-implicit Euler
            command = law.free_space(LawInput(robot_terms(ur5, q, v), v, q - q_star, desired))
            v = v + dt * pin.aba(ur5.model, data, q, v, command.u0)
            q = q + dt * v
        assert np.linalg.norm(ur5.tip_position(q) - p_star) < 1e-6
        remaining[null_omega] = np.linalg.norm(q - q_star) / 0.1
    # linear predictions (1 + ω_n t) e^(−ω_n t) at t = 2 s: 4e-8 and 0.74
    assert remaining[10.0] < 1e-5
    assert remaining[0.5] > 0.5


# --------------------------------------------------------------------- settings
def test_options_set_the_gains() -> None:
    sc = load_scenario(
        "scenarios/rtr_plane.toml",
        overrides={
            "control.law": "osc_hybrid",
            "control.osc_hybrid.omega": 5.0,
            "control.osc_hybrid.zeta": 0.7,
            "control.osc_hybrid.force_i": 3.0,
            "control.osc_hybrid.null_omega": 2.0,
            "sim.duration": 0.01,
        },
    )
    info = simulate(sc).meta["controller"]["settings"]
    assert info["kp"] == 25.0 and info["kv"] == pytest.approx(7.0) and info["kn"] == info["kv"]
    assert info["force_i"] == 3.0 and info["null_kp"] == 4.0 and info["null_kd"] == 4.0
    assert info["approach_rate"] == 10.0  # the supervisor's λ_a = Λ
    with pytest.raises(ScenarioError):
        load_scenario("scenarios/rtr_plane.toml", overrides={"control.osc_hybrid.force_p": -1.0})
    with pytest.raises(ScenarioError):
        load_scenario("scenarios/rtr_plane.toml", overrides={"control.osc_hybrid.kp": 1.0})


def test_fewer_than_three_joints_is_refused() -> None:
    context: Any = SimpleNamespace(robot=SimpleNamespace(nv=2))
    with pytest.raises(ControlError) as info:
        check(context)
    assert info.value.key == "control.law" and info.value.value == "osc_hybrid"


# --------------------------------------------------------------------- the target
PANDA_PLANE = """
name = "panda_plane"
[robot]
model = "panda"
[surface]
type = "plane"
point = [0.0, 0.0, 0.3]
normal = [0.0, 0.0, 1.0]
[trajectory]
type = "circle"
center = [0.4, 0.0, 0.3]
radius = 0.1
normal = [0.0, 0.0, 1.0]
omega = 0.3
[initial]
tip = [0.5, 0.0, 0.32]
seed = [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]
[sim]
duration = 8.0
"""


@pytest.mark.parametrize("name", [*SCENARIOS, "panda_plane"])
def test_target_on_every_contact_scenario_with_default_gains(name: str, tmp_path) -> None:
    """Settled position error ≤ 1e-4 m and |f − f_d| ≤ 1e-2 N; on the redundant arms the
    posture (q − q_d, the null space) has converged as well."""
    assert load_scenario(f"scenarios/{SCENARIOS[0]}.toml").sim.settle_time == 5.0
    if name == "panda_plane":
        path = tmp_path / "panda_plane.toml"
        path.write_text(PANDA_PLANE)
    else:
        path = f"scenarios/{name}.toml"
    # 8 s: the settled window [5 s, 8 s] starts 4 s after the last touch (paper_approach, 1 s)
    overrides = {"control.law": "osc_hybrid", "sim.duration": 8.0}
    r = simulate(load_scenario(path, overrides=overrides))
    m = r.metrics()
    assert r.meta["status"] == "ok" and r.meta["contact_at_end"]
    assert m.position_error_max_settled is not None and m.position_error_max_settled <= 1e-4
    assert m.force_error_max_settled is not None and m.force_error_max_settled <= 1e-2
    settled = r.t >= m.settle_time
    assert np.abs(r.q - r.q_d)[settled].max() <= 1e-4

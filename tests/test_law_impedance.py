"""The Cartesian impedance law with force tracking (hybrid_force.control.laws.impedance).

References: the identities Λ⁻¹ = J M⁻¹ Jᵀ (with Pinocchio's own M⁻¹) and ½ ẋᵀΛẋ = the least
kinetic energy that moves the tip at ẋ, for K = ω²Λ, D = 2ζωΛ on the RTR, UR5 and Panda; on a
point mass (three prismatic joints, M = m I) the semi-implicit Euler recurrences of the
predicted closed loops, ẍ + 2ζωẋ + ω²x = 0 in free space and (s + λ_a)(s + 2ζω) d = 0 on the
approach; on a compliant plane (stiffness k_e) the series springs of plain impedance,
f = f_d k_e/(k_e + k_n) with k_n = ω² m, and force tracking's f = f_d at the depth
f_d/k_n + f_d/k_e, reached at the slow root of the normal loop's cubic; on two stacked rigid
surfaces with a model mass error, plain impedance's f_d + (1 − m) W⁻¹ A M⁻¹ (C q̇ + g) from
Pinocchio's inverse dynamics, and force tracking's f_d; the noise σ √(κ_f T / 2) a sampled run
lets through; the issue's target on the five shipped scenarios.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from oracles.laws import cartesian_inertia, impedance_matrices

from hybrid_force import simulate
from hybrid_force.control.clik import inverse_kinematics
from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.impedance import DEFAULTS, ImpedanceGains
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.errors import ControlError, ScenarioError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane
from hybrid_force.geometry.paths import Circle
from hybrid_force.model.robot import Robot
from hybrid_force.result import Result
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.settings import Scenario, SimSettings

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
MASS, G0, DT = 2.5, 9.81, 1e-3
OMEGA, ZETA, KAPPA = DEFAULTS["omega"], DEFAULTS["zeta"], DEFAULTS["force_rate"]


def _options(**options: object) -> ControlSettings:
    return ControlSettings(law="impedance", options={"impedance": options}, supervisor=False)


@pytest.fixture(scope="module")
def point_mass() -> Robot:
    """A point of mass m on three prismatic joints x, y, z (built in code): M = m I, J = I."""
    model = pin.Model()
    joint = 0
    axes = {"x": pin.JointModelPX(), "y": pin.JointModelPY(), "z": pin.JointModelPZ()}
    for name, axis in axes.items():
        joint = model.addJoint(joint, axis, pin.SE3.Identity(), name)
    body = pin.Inertia(MASS, np.zeros(3), 1e-3 * np.eye(3))
    model.appendBodyToJoint(joint, body, pin.SE3.Identity())
    model.addFrame(pin.Frame("tool", joint, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    model.lowerPositionLimit[:], model.upperPositionLimit[:] = -10.0, 10.0
    model.effortLimit[:] = model.velocityLimit[:] = 0.0  # unspecified
    return Robot(model, name="point_mass", urdf_path=Path("point_mass.urdf"), tip="tool")


def _point_run(
    robot: Robot,
    start: list[float],
    control: ControlSettings,
    duration: float,
    plane: float = 0.0,
    **kw: object,
) -> Result:
    """The point mass held at the origin from ``start``, above (or on) the plane z = plane."""
    return simulate(
        Scenario(
            robot=robot,
            surfaces=[Plane(point=(0, 0, plane), normal=(0, 0, 1))],
            path=Circle(center=(-0.1, 0, 0), radius=0.1, normal=(0, 0, 1), omega=0.0),
            q0=np.array(start),
            control=control,
            sim=SimSettings(duration=duration, dt=DT),
            **kw,  # type: ignore[arg-type]
        )
    )


def _euler(a: float, b: float, x0: float, n: int) -> np.ndarray:
    """x (n,) of ẍ = −a ẋ − b x from (x0, 0) by the plant's semi-implicit Euler step."""
    x, v, out = x0, 0.0, np.empty(n)
    for i in range(n):
        out[i] = x
        v += DT * (-a * v - b * x)
        x += DT * v
    return out


# --- the gains --------------------------------------------------------------------------------
def test_stiffness_and_damping_are_the_cartesian_inertia_scaled(
    rtr: Robot, ur5: Robot, panda: Robot, rng: np.random.Generator
) -> None:
    """K = ω²Λ and D = 2ζωΛ are symmetric positive definite, K J M⁻¹ Jᵀ = ω² I, and Λ is the
    tip's inertia: the least kinetic energy ½ q̇ᵀMq̇ with J q̇ = ẋ is ½ ẋᵀΛẋ."""
    for robot in (rtr, ur5, panda):
        lower, upper = robot.position_limits
        for _ in range(5):
            q = rng.uniform(np.maximum(lower, -3.0), np.minimum(upper, 3.0))
            terms = robot.terms(q, np.zeros(robot.nv))
            Lam = cartesian_inertia(terms)
            K, D = impedance_matrices(Lam, OMEGA, ZETA)
            for G in (K, D):
                np.testing.assert_array_equal(G, G.T)
                assert np.linalg.eigvalsh(G).min() > 0.0
            Minv = pin.computeMinverse(robot.model, robot.model.createData(), q)
            Minv = np.triu(Minv) + np.triu(Minv, 1).T  # Pinocchio fills the upper triangle
            inverse = terms.J @ Minv @ terms.J.T  # Λ⁻¹
            np.testing.assert_allclose(K @ inverse, OMEGA**2 * np.eye(3), atol=1e-6)
            np.testing.assert_allclose(D, 2 * ZETA / OMEGA * K, rtol=1e-14)
            xdot = rng.normal(size=3)
            # least-norm solution of J q̇ = ẋ in the metric M
            qdot = Minv @ terms.J.T @ np.linalg.solve(terms.J @ Minv @ terms.J.T, xdot)
            assert qdot @ terms.M @ qdot == pytest.approx(xdot @ Lam @ xdot, rel=1e-8)


# --- closed loops on a point mass -------------------------------------------------------------
@pytest.mark.parametrize("zeta", [0.4, 1.0])
def test_free_space_error_is_the_predicted_second_order_response(
    point_mass: Robot, zeta: float
) -> None:
    """1 cm off p_d, 1 m above a plane: e follows ë + 2ζωė + ω²e = 0, step by step, and the
    continuous solution within the step's O(ω dt) error."""
    control = dataclasses.replace(_options(zeta=zeta), supervisor=True)
    run = _point_run(point_mass, [0.01, 0.0, 0.0], control, 0.3, plane=-1.0)
    assert set(run.phase.tolist()) == {0}
    e = run.p[:, 0] - run.p_d[:, 0]
    np.testing.assert_allclose(e, _euler(2 * zeta * OMEGA, OMEGA**2, 0.01, e.size), atol=1e-13)
    wd = OMEGA * math.sqrt(1 - zeta**2) if zeta < 1 else 0.0
    t = run.t
    if zeta < 1:
        exact = np.exp(-zeta * OMEGA * t) * (np.cos(wd * t) + zeta * OMEGA / wd * np.sin(wd * t))
    else:
        exact = (1 + OMEGA * t) * np.exp(-OMEGA * t)
    np.testing.assert_allclose(e, 0.01 * exact, atol=0.01 * OMEGA * DT)
    np.testing.assert_allclose(run.p[:, 1:], run.p_d[:, 1:], atol=1e-14)  # no coupling


def test_approach_closes_in_at_the_approach_rate_and_touches_gently(point_mass: Robot) -> None:
    """2 cm above the plane, under the supervisor: d follows (s + λ_a)(s + 2ζω) d = 0 until the
    touch, which is at about λ_a·contact_tol; then the force settles at f_d."""
    control = dataclasses.replace(_options(), supervisor=True)
    run = _point_run(point_mass, [0.0, 0.0, 0.02], control, 2.0)
    near = run.phase == 1
    lam = control.Lambda  # the approach rate λ_a (default: Λ)
    d = _euler(lam + 2 * ZETA * OMEGA, 2 * ZETA * OMEGA * lam, 0.02, run.t.size)
    np.testing.assert_allclose(run.p[near, 2], d[near], atol=1e-13)
    m = run.metrics()
    assert m.n_impacts == 1
    assert m.impact_speed is not None and m.impact_speed < 2 * lam * control.contact_tol
    assert run.f[-1] == pytest.approx(run.f_d[-1], abs=1e-9)


@pytest.fixture(scope="module")
def soft_runs(point_mass: Robot) -> dict[bool, Result]:
    """The point mass pressed on a linear-spring plane (k_e = 2e4 N/m), with and without
    force tracking, 3 s."""
    contact = ContactSettings(model="compliant", stiffness=2e4, damping=0.0)
    return {
        tracking: _point_run(
            point_mass, [0.0, 0.0, 0.0], _options(force_tracking=tracking), 3.0, contact=contact
        )
        for tracking in (False, True)
    }


K_E = 2e4
K_N = OMEGA**2 * MASS  # the impedance's normal stiffness k_n = ω² m_n


def test_plain_impedance_on_a_soft_surface_is_two_springs_in_series(
    soft_runs: dict[bool, Result],
) -> None:
    """Plain impedance presses the model's depth f_d/k_n; the tool sinks f/k_e and the spring
    relaxes by as much: f = f_d k_e/(k_e + k_n) (8.99 N for 10 N), short of f_d."""
    run = soft_runs[False]
    f_d = run.f_d[-1]
    assert run.f[-1] == pytest.approx(f_d * K_E / (K_E + K_N), rel=1e-6)
    assert run.p[-1, 2] == pytest.approx(-run.f[-1] / K_E, rel=1e-6)


def test_force_tracking_on_a_soft_surface_reaches_f_d_at_the_predicted_depth_and_rate(
    soft_runs: dict[bool, Result],
) -> None:
    """f → f_d; the reference's depth δ (where the motor's force minus gravity, K(p_r − p),
    points at rest) is f_d/k_n + f_d/k_e. The error decays at the slow root of the normal
    loop m z̈ = −(k_n + k_e) z − 2ζωm ż − φ, φ̇ = κ_f k_e z: m s³ + 2ζωm s² + (k_n + k_e) s +
    κ_f k_e (9.50 1/s; the quasi-static κ_f k_e/(k_e + k_n) = 8.99 1/s)."""
    run = soft_runs[True]
    f_d = run.f_d[-1]
    assert run.f[-1] == pytest.approx(f_d, abs=1e-8)
    p_r = run.p[-1, 2] + (run.u[-1, 2] - MASS * G0) / K_N
    assert -p_r == pytest.approx(f_d / K_N + f_d / K_E, rel=1e-6)
    window = (run.t >= 0.6) & (run.t <= 1.6)
    slope = np.polyfit(run.t[window], np.log(np.abs(run.f[window] - f_d)), 1)[0]
    roots = np.roots([MASS, 2 * ZETA * OMEGA * MASS, K_N + K_E, KAPPA * K_E])
    rate = -roots[np.abs(roots.imag) < 1e-9].real.max()
    assert -slope == pytest.approx(rate, rel=0.01)  # Euler's step: 0.5 % faster


# --- a model mass error on two rigid surfaces (k = 2) -----------------------------------------
@pytest.mark.parametrize("tracking", [False, True])
def test_model_mass_error_in_a_groove(rtr: Robot, tracking: bool) -> None:
    """The RTR in the groove of the cylinder r = 0.4 and the plane z = 10, its model 10 %
    heavy. At q = q_d the plant's M q̈ + C q̇ + g = τ + Aᵀf leaves Aᵀ(f − φ) = −0.1 (C q̇ + g)
    (q̈ = 0 on this circle): plain impedance (φ = f_d) presses f_d − 0.1 W⁻¹AM⁻¹(Cq̇ + g),
    force tracking adapts φ until f = f_d."""
    q0 = inverse_kinematics(rtr, np.array([0.4, 0.0, 10.0]), seed=np.array([0.0, 9.0, 2.0]))
    surfaces = [Cylinder(0.4), Plane(point=(0, 0, 10), normal=(0, 0, -1))]
    control = dataclasses.replace(
        _options(force_tracking=tracking), f_d=(10.0, 5.0), mass_factor=1.1
    )
    run = simulate(
        Scenario(
            robot=rtr,
            surfaces=surfaces,
            path=Circle(center=(0, 0, 10), radius=0.4, normal=(0, 0, 1), omega=1.0),
            q0=q0,
            control=control,
            sim=SimSettings(duration=3.0, dt=DT),
        )
    )
    q, v, f_d = run.q[-1], run.v[-1], np.array([10.0, 5.0])
    np.testing.assert_allclose(run.p[-1], run.p_d[-1], atol=1e-10)
    if tracking:
        np.testing.assert_allclose(run.f[-1], f_d, atol=1e-8)
        return
    data = rtr.model.createData()
    bias = pin.rnea(rtr.model, data, q, v, np.zeros(3))  # C q̇ + g, q̈ = 0
    M = pin.crba(rtr.model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    A = Constraint(surfaces).evaluate(rtr.terms(q, v), v).A
    W = A @ np.linalg.solve(M, A.T)
    expected = f_d - 0.1 * np.linalg.solve(W, A @ np.linalg.solve(M, bias))
    np.testing.assert_allclose(run.f[-1], expected, rtol=1e-7)
    assert expected[1] == pytest.approx(5.0 + 0.1 * 40 * G0, rel=1e-9)  # the arm's weight


# --- the shipped scenarios ---------------------------------------------------------------------
@pytest.mark.parametrize(
    "name", ["paper_contact", "paper_approach", "rtr_plane", "rtr_sphere", "ur5_plane"]
)
def test_target_on_every_shipped_scenario(name: str) -> None:
    """Default gains: position error ≤ 1e-4 m and |f − f_d| ≤ 1e-2 N after 2 s (settled far
    earlier), an approach that touches at about λ_a·contact_tol."""
    sc = load_scenario(
        SCENARIOS / f"{name}.toml",
        overrides={"control.law": "impedance", "sim.duration": 4.0, "sim.settle_time": 2.0},
    )
    run = simulate(sc)
    m = run.metrics()
    assert m.position_error_max_settled is not None and m.position_error_max_settled <= 1e-4
    assert m.force_error_max_settled is not None and m.force_error_max_settled <= 1e-2
    assert run.meta["controller"]["settings"] == DEFAULTS
    if sc.control.supervisor:
        assert m.impact_speed is not None
        assert m.impact_speed < 2 * run.meta["gains"]["approach_rate"] * sc.control.contact_tol


def test_plain_impedance_holds_f_d_where_the_normal_stiffness_varies() -> None:
    """On the UR5's circle the arm's mass along the normal, so k_n = ω² m_n, changes with the
    configuration; the depth kept as the force it asks for still gives f = f_d (exact model,
    rigid surface)."""
    sc = load_scenario(
        SCENARIOS / "ur5_plane.toml",
        overrides={
            "control.law": "impedance",
            "control.impedance.force_tracking": False,
            "sim.duration": 4.0,
            "sim.settle_time": 1.0,
        },
    )
    m = simulate(sc).metrics()
    assert m.force_error_max_settled is not None and m.force_error_max_settled <= 1e-2


def test_sampled_with_force_noise_lets_through_the_predicted_level() -> None:
    """At 500 Hz with σ = 0.1 N of force noise: φ_{k+1} = φ_k + κ_f T (f_d − f − noise), f ≈ φ,
    so the true force wanders by σ √(κ_f T / 2) = 0.01 N; the position stays converged."""
    sigma, rate = 0.1, 500.0
    sc = load_scenario(
        SCENARIOS / "rtr_sphere.toml",
        overrides={
            "control.law": "impedance",
            "control.rate": rate,
            "sensor.force_noise": sigma,
            "sim.duration": 6.0,
            "sim.settle_time": 1.0,
        },
    )
    run = simulate(sc)
    m = run.metrics()
    assert m.force_error_rms_settled == pytest.approx(sigma * math.sqrt(KAPPA / rate / 2), rel=0.3)
    assert m.position_error_max_settled is not None and m.position_error_max_settled <= 1e-4


def test_bad_settings_are_refused_naming_the_key() -> None:
    for bad, error in (({"zeta": 0.0}, ControlError), ({"feedforward": 1}, ControlError)):
        with pytest.raises(error) as info:
            ImpedanceGains(**bad)  # type: ignore[arg-type]
        ((key, value),) = bad.items()
        assert (info.value.key, info.value.value) == (f"control.impedance.{key}", value)
    # ω·dt = 0.6: the explicit step would no longer follow the continuous loop
    with pytest.raises(ScenarioError, match=r"control\.impedance\.omega = 600"):
        load_scenario(
            SCENARIOS / "rtr_sphere.toml",
            overrides={"control.law": "impedance", "control.impedance.omega": 600.0},
        )


@pytest.mark.parametrize("feedforward", [False, True])
def test_path_feedforward_removes_the_predicted_lag(point_mass: Robot, feedforward: bool) -> None:
    """A circle p_d = R e^{iΩt} at Ω = 2 rad/s in free space. Without the feed-forward the
    error obeys ë + 2ζωė + ω²e = −p̈_d: it turns with the path at R Ω² / |ω² − Ω² + 2iζωΩ|
    (4.4e-4 m). The plant's step x⁺ = x + h v⁺, v⁺ = v + h a turns at z = e^{iΩh}: the exact
    steady amplitude |X − R| solves (z − 1)² X / (h² z) = a(X), with a the law's acceleration
    (−Ω²R more with the feed-forward, whose only residue is this step's velocity offset)."""
    radius, rate = 0.1, 2.0
    control = dataclasses.replace(_options(feedforward=feedforward), supervisor=True)
    run = simulate(
        Scenario(
            robot=point_mass,
            surfaces=[Plane(point=(0, 0, -1.0), normal=(0, 0, 1))],
            path=Circle(center=(-radius, 0, 0), radius=radius, normal=(0, 0, 1), omega=rate),
            q0=np.zeros(3),
            control=control,
            sim=SimSettings(duration=2.0, dt=DT),
        )
    )
    error = np.linalg.norm(run.p - run.p_d, axis=1)[run.t >= 1.0]
    z = np.exp(1j * rate * DT)
    to_v = (z - 1) / (DT * z)  # V = to_v X
    path_force = OMEGA**2 + 2j * ZETA * OMEGA * rate - (rate**2 if feedforward else 0.0)
    X = path_force * radius / (to_v * (z - 1) / DT + OMEGA**2 + 2 * ZETA * OMEGA * to_v)
    np.testing.assert_allclose(error, abs(X - radius), rtol=1e-6)
    lag = radius * rate**2 / abs(OMEGA**2 - rate**2 + 2j * ZETA * OMEGA * rate)
    assert error.max() < (0.05 if feedforward else 1.0) * lag

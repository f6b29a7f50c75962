"""hybrid_force.sim.contact and the plant's compliant contact and friction.

References: the defining formulas (Hunt–Crossley, regularised Coulomb) evaluated by hand; a
point mass sliding on a plane (deceleration μ f_n / m); the creep speed of the regularised law;
the eigenvalues of the semi-implicit Euler step for the time-step bound; the energy balance
W_u = ΔT + ΔV + E_friction (first order in dt); the compliant run's static offset predicted
from the law's joint-space projection; the rigid run as k → ∞.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from oracles.plant import OraclePlant
from oracles.run import oracle_run

from hybrid_force import load_robot, simulate
from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.base import Command
from hybrid_force.errors import BadInputError, ScenarioError
from hybrid_force.geometry.builtin_surfaces import Plane
from hybrid_force.model.robot import Robot
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.contact import (
    ContactSettings,
    compliant_force,
    creep_velocity,
    friction_matrix,
    stable_dt_compliant,
    stable_dt_friction,
)
from hybrid_force.sim.plant import Plant
from hybrid_force.sim.settings import SimSettings

MASS, G0 = 2.5, 9.81

_POINT_MASS = """<?xml version="1.0"?>
<robot name="xyz_point">
  <link name="base"/>
  <link name="cx"><inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="cy"><inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="tool"><inertial><mass value="{m}"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="cx"/><axis xyz="1 0 0"/>
    <limit lower="-10" upper="10" effort="0" velocity="100"/></joint>
  <joint name="y" type="prismatic"><parent link="cx"/><child link="cy"/><axis xyz="0 1 0"/>
    <limit lower="-10" upper="10" effort="0" velocity="100"/></joint>
  <joint name="z" type="prismatic"><parent link="cy"/><child link="tool"/><axis xyz="0 0 1"/>
    <limit lower="-10" upper="10" effort="0" velocity="100"/></joint>
</robot>
"""  # noqa: E501


@pytest.fixture(scope="module")
def point_mass(tmp_path_factory: pytest.TempPathFactory) -> Robot:
    """A 2.5 kg point moved by three prismatic joints x, y, z: M = m I, g = (0, 0, m g0)."""
    path = tmp_path_factory.mktemp("robots") / "xyz_point.urdf"
    path.write_text(_POINT_MASS.format(m=MASS))
    return load_robot(path, tip="tool")


# --- the laws, by hand ---------------------------------------------------------------------------
def test_settings_refuse_bad_values_naming_the_key() -> None:
    for kwargs, key in (
        ({"model": "soft"}, "contact.model"),
        ({"stiffness": 0.0}, "contact.stiffness"),
        ({"damping": -1.0}, "contact.damping"),
        ({"exponent": 0.5}, "contact.exponent"),
        ({"friction": -0.1}, "contact.friction"),
        ({"friction_velocity": 0.0}, "contact.friction_velocity"),
    ):
        with pytest.raises(ScenarioError, match=key.replace(".", r"\.")):
            ContactSettings(**kwargs)  # type: ignore[arg-type]


def test_hunt_crossley_force_by_hand_and_never_pulls(rng: np.random.Generator) -> None:
    c = ContactSettings(model="compliant", stiffness=2e5, damping=0.8, exponent=1.5)
    delta, rate = np.array([1e-3, -1e-3, 2e-4]), np.array([0.2, 0.5, -0.1])
    expected = [2e5 * 1e-3**1.5 * (1 + 0.8 * 0.2), 0.0, 2e5 * 2e-4**1.5 * (1 - 0.08)]
    np.testing.assert_allclose(compliant_force(c, delta, rate), expected, rtol=1e-14)
    # the surface never pulls, and the force is continuous at touch (0 at δ = 0 at any rate)
    f = compliant_force(c, rng.uniform(-1e-3, 1e-3, 1000), rng.uniform(-10, 10, 1000))
    assert np.all(f >= 0.0)
    assert np.all(compliant_force(c, np.zeros(5), np.linspace(-5, 5, 5)) == 0.0)


def test_friction_opposes_the_sliding_velocity_with_magnitude_mu_f(
    rng: np.random.Generator,
) -> None:
    mu, eps = 0.3, 1e-9
    J = rng.normal(size=(3, 4))
    for _ in range(20):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        pdot = rng.normal(size=3)
        F, speed = friction_matrix(mu, eps, normal[None, :], J, pdot)
        v_t = pdot - normal * (normal @ pdot)
        assert speed[0] == pytest.approx(np.linalg.norm(v_t), rel=1e-12)
        # F = Jᵀ F_t per newton: recover the tip force from J's pseudo-inverse transpose
        F_t = np.linalg.lstsq(J.T, F[:, 0], rcond=None)[0]
        np.testing.assert_allclose(F_t, -mu * v_t / np.linalg.norm(v_t), rtol=1e-8, atol=1e-12)


def test_creep_speed_balances_the_push() -> None:
    mu, eps, f = 0.4, 1e-3, 20.0
    for push in (0.5, 4.0, 7.9):
        v = creep_velocity(mu, eps, f, push)
        assert mu * f * v / math.sqrt(v**2 + eps**2) == pytest.approx(push, rel=1e-12)
    assert creep_velocity(mu, eps, f, mu * f) == math.inf


@pytest.mark.parametrize("zeta_source", [0.0, 0.3, 2.0])
def test_compliant_time_step_bound_is_where_euler_turns_unstable(zeta_source: float) -> None:
    """Spectral radius of the semi-implicit Euler step of ẍ = −ω²x − 2ζωẋ crosses 1 at the
    bound (the bound itself is derived in docs/contact.md from Jury's conditions)."""
    k, W, f0 = 1e6, 0.2, 10.0
    c = zeta_source * 2 * math.sqrt(k * W) / (f0 * W)  # damping c that gives ζ = zeta_source
    settings = ContactSettings(model="compliant", stiffness=k, damping=c)
    dt_max = stable_dt_compliant(settings, W, f0)
    omega, zeta = math.sqrt(k * W), zeta_source

    def radius(dt: float) -> float:
        step = np.array(
            [
                [1 - (omega * dt) ** 2, dt * (1 - 2 * zeta * omega * dt)],
                [-dt * omega**2, 1 - 2 * zeta * omega * dt],
            ]
        )
        return float(np.abs(np.linalg.eigvals(step)).max())

    assert radius(dt_max * (1 - 1e-6)) <= 1.0 + 1e-12
    assert radius(dt_max * (1 + 1e-4)) > 1.0


def test_hertz_time_step_uses_the_stiffness_at_the_operating_force() -> None:
    k, n, W, f0 = 1e8, 1.5, 0.1, 10.0
    settings = ContactSettings(model="compliant", stiffness=k, exponent=n)
    delta0 = (f0 / k) ** (1 / n)
    k1 = n * f0 / delta0  # d(k δⁿ)/dδ at f0
    assert stable_dt_compliant(settings, W, f0) == pytest.approx(2 / math.sqrt(k1 * W), rel=1e-12)


def test_friction_time_step_bound_is_where_euler_turns_unstable() -> None:
    """Near sticking, v⁺ = v − dt (μ f / ε) W_t v: stable iff the factor is within [−1, 1]."""
    settings = ContactSettings(friction=0.3, friction_velocity=1e-3)
    W_t, f0 = 0.4, 10.0
    dt_max = stable_dt_friction(settings, W_t, f0)
    rate = 0.3 * f0 / 1e-3 * W_t
    assert abs(1 - dt_max * rate) == pytest.approx(1.0, rel=1e-12)


# --- the plant -----------------------------------------------------------------------------------
def _plane_plant(robot: Robot, contact: ContactSettings, plant_type: type[Plant] = Plant) -> Plant:
    plant = plant_type(robot, Constraint(Plane([0, 0, 0], [0, 0, 1])), SimSettings(), 1e-5, contact)
    plant.in_contact = plant.ever_in_contact = True
    return plant


@pytest.mark.parametrize("plant_type", [Plant, OraclePlant])
def test_sliding_point_decelerates_at_mu_fn_over_m(
    point_mass: Robot, plant_type: type[Plant], rng: np.random.Generator
) -> None:
    """A tip sliding on the plane z = 0, pushed down by F_z and along by F_x: the normal force
    is m g0 + F_z and the tangential acceleration (F_t − μ f_n t̂) / m, t̂ the sliding direction."""
    mu = 0.35
    plant = _plane_plant(
        point_mass, ContactSettings(friction=mu, friction_velocity=1e-7), plant_type
    )
    q = np.zeros(3)
    for _ in range(10):
        v = np.append(rng.uniform(-2, 2, 2), 0.0)
        push = np.append(rng.uniform(-5, 5, 2), -rng.uniform(0, 20))
        terms, cons = plant.evaluate(q, v)
        ddq, f = plant.accelerate(terms, cons, Command(push, None), 0.0)
        f_n = MASS * G0 - push[2]
        assert f[0] == pytest.approx(f_n, rel=1e-12)
        t_hat = v[:2] / np.linalg.norm(v[:2])
        expected = (push[:2] - mu * f_n * t_hat) / MASS
        np.testing.assert_allclose(ddq[:2], expected, rtol=1e-9)
        assert abs(ddq[2]) < 1e-9


def test_a_push_below_mu_fn_creeps_at_the_documented_speed(point_mass: Robot) -> None:
    mu, eps, dt = 0.3, 1e-3, 1e-4
    contact = ContactSettings(friction=mu, friction_velocity=eps)
    plant = _plane_plant(point_mass, contact)
    f_n, push = MASS * G0, 0.5 * mu * MASS * G0
    q, v = np.zeros(3), np.zeros(3)
    for i in range(20000):  # 2 s: the creep settles in ~ ε m / (μ f_n) ≪ 1 s
        terms, cons = plant.evaluate(q, v)
        ddq, _ = plant.accelerate(terms, cons, Command(np.array([push, 0.0, 0.0]), None), i * dt)
        q, v = plant.advance(q, v, ddq, Command(np.zeros(3), None), i * dt, dt, cons.distance)
    assert v[0] == pytest.approx(creep_velocity(mu, eps, f_n, push), rel=1e-6)
    assert v[0] < 1e-3  # well below ε: the regularised law sticks up to this creep


def _energy_residual(robot: Robot, contact: ContactSettings, dt: float) -> tuple[float, float]:
    """(W_u − ΔT − ΔV − E_f, E_f) [J] of 0.4 s of the RTR pressed onto the cylinder and driven
    round it by a constant torque on top of gravity."""
    from hybrid_force.control.clik import inverse_kinematics
    from hybrid_force.geometry.builtin_surfaces import Cylinder

    plant = Plant(robot, Constraint(Cylinder(0.4)), SimSettings(), 1e-5, contact)
    q = inverse_kinematics(robot, np.array([0.4, 0.0, 7.0]), seed=np.array([0.0, 6.0, 2.0]))
    q, v = plant.touch(q, np.zeros(3), 0.0)
    data = robot.new_data()

    def energy(q: np.ndarray, v: np.ndarray) -> float:
        return float(pin.computeKineticEnergy(robot.model, data, q, v)) + float(
            pin.computePotentialEnergy(robot.model, data, q)
        )

    e0, work = energy(q, v), 0.0
    for i in range(round(0.4 / dt)):
        terms, cons = plant.evaluate(q, v)
        # gravity compensated, the tip pressed in with 30 N, turned and lifted
        u = terms.g - 30.0 * cons.A[0] + np.array([20.0, 5.0, 0.0])
        ddq, _ = plant.accelerate(terms, cons, Command(u, None), i * dt)
        q_new, v_new = plant.advance(q, v, ddq, Command(u, None), i * dt, dt, cons.distance)
        work += float(u @ (q_new - q))  # W_u = ∫ u·q̇ dt over the step
        q, v = q_new.copy(), v_new.copy()
        assert plant.in_contact
    return work - (energy(q, v) - e0) - plant.friction_energy, plant.friction_energy


def test_energy_balance_closes_with_friction_as_without(rtr_urdf: Path) -> None:
    """W_u = ΔT + ΔV + E_friction; the residual is the O(dt) error of the step, the same with
    and without friction: it halves with dt in both cases, and friction's loss is far larger."""
    robot = load_robot(rtr_urdf)
    frictionless = [_energy_residual(robot, ContactSettings(), dt)[0] for dt in (2e-4, 1e-4)]
    with_friction = [
        _energy_residual(robot, ContactSettings(friction=0.3), dt) for dt in (2e-4, 1e-4)
    ]
    (r1, loss), (r2, _) = with_friction
    for a, b in (frictionless, (r1, r2)):
        assert abs(b) < 0.6 * abs(a)  # first order: halves with dt (plus round-off)
    assert abs(r2) < 0.02 * loss
    assert abs(r2) < 3 * abs(frictionless[1]) + 1e-6 * loss


def test_compliant_plant_force_and_acceleration_by_hand(point_mass: Robot) -> None:
    c = ContactSettings(model="compliant", stiffness=1e5, damping=0.5, friction=0.2)
    plant = _plane_plant(point_mass, c)
    q, v = np.array([0.1, 0.0, -2e-4]), np.array([0.3, 0.0, -0.05])  # inside, moving in
    u = np.array([1.0, 0.0, -4.0])
    terms, cons = plant.evaluate(q, v)
    ddq, f = plant.accelerate(terms, cons, Command(u, None), 0.0)
    f_n = 1e5 * 2e-4 * (1 + 0.5 * 0.05)
    assert f[0] == pytest.approx(f_n, rel=1e-12)
    expected = (u + np.array([-0.2 * f_n, 0.0, f_n]) - np.array([0, 0, MASS * G0])) / MASS
    np.testing.assert_allclose(ddq, expected, rtol=1e-4)  # friction regularised at ε = 1e-3
    # out of the surface: free, and a release event
    terms, cons = plant.evaluate(np.array([0.1, 0.0, 1e-3]), v)
    ddq, f = plant.accelerate(terms, cons, Command(u, None), 0.5)
    assert f[0] == 0.0 and not plant.in_contact
    assert plant.events[-1].kind == "release"


# --- runs ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def paper():  # type: ignore[no-untyped-def]
    return load_scenario(Path(__file__).parents[1] / "scenarios" / "paper_contact.toml")


def _run(sc, contact: ContactSettings, dt: float, duration: float = 3.0):  # type: ignore[no-untyped-def]
    sim = dataclasses.replace(sc.sim, duration=duration, dt=dt)
    return simulate(dataclasses.replace(sc, sim=sim, contact=contact))


@pytest.mark.slow
def test_compliant_contact_converges_to_the_rigid_run(paper) -> None:  # type: ignore[no-untyped-def]
    """At k = 1e7 N/m the settled force error is the rigid run's within 1e-3 N; the tip sits
    δ = f_d / k inside, and the law's position loop, settled in joint space (Q e = 0), leaves
    it at J A⁺ (−δ): |p − p_d| = δ ‖J Jᵀ n̂‖ / (n̂ᵀ J Jᵀ n̂), the difference from the rigid run."""
    rigid = _run(paper, ContactSettings(), 1e-4)
    robot, f_d, late = paper.robot, 10.0, slice(-5000, None)
    for k in (1e6, 1e7):
        soft = _run(paper, ContactSettings(model="compliant", stiffness=k), 1e-4)
        assert soft.status == "ok" and soft.meta["contact_at_end"]
        force_gap = np.abs(np.abs(soft.f[late] - f_d) - np.abs(rigid.f[late] - f_d)).max()
        assert force_gap <= 1e-3
        terms = robot.terms(soft.q[-1], np.zeros(3), robot.new_data())
        n = paper.surfaces[0].normal(terms.p)
        JJ = terms.J @ terms.J.T
        predicted = f_d / k * np.linalg.norm(JJ @ n) / (n @ JJ @ n)
        error = np.linalg.norm(soft.p[-1] - soft.p_d[-1])
        rigid_error = np.linalg.norm(rigid.p[-1] - rigid.p_d[-1])
        assert error - rigid_error == pytest.approx(predicted, rel=1e-3)


def test_compliant_and_friction_runs_agree_with_the_reference_plant(paper, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    for contact in (
        ContactSettings(friction=0.3),
        ContactSettings(model="compliant", stiffness=1e5, damping=0.5, friction=0.2),
    ):
        fast = _run(paper, contact, 1e-3, duration=0.5)
        sim = dataclasses.replace(paper.sim, duration=0.5, dt=1e-3)
        slow = oracle_run(monkeypatch, dataclasses.replace(paper, sim=sim, contact=contact))
        np.testing.assert_allclose(fast.q, slow.q, atol=1e-9)
        np.testing.assert_allclose(fast.f, slow.f, atol=1e-6)
        assert fast.meta["friction_energy"] == pytest.approx(slow.meta["friction_energy"], rel=1e-6)
        assert fast.meta["friction_energy"] > 0


def test_a_step_too_long_for_the_contact_is_refused(paper, repo_root: Path, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ScenarioError, match=r"largest stable step .* is ([0-9.e-]+) s"):
        _run(paper, ContactSettings(model="compliant", stiffness=1e9), 1e-3)
    text = (repo_root / "scenarios" / "paper_contact.toml").read_text()
    bad = tmp_path / "stiff.toml"
    bad.write_text(
        text.replace("[sim]", '[contact]\nmodel = "compliant"\nstiffness = 1e9\n\n[sim]')
    )
    with pytest.raises(ScenarioError, match=r"sim\.dt = 0\.001.*largest stable step") as info:
        load_scenario(bad)
    assert info.value.key == "sim.dt" and str(bad) in str(info.value)
    # the step the message names is accepted
    dt_max = float(str(info.value).split("along the path is ")[1].split(" s")[0])
    bad.write_text(bad.read_text().replace("dt = 1e-3", f"dt = {0.999 * dt_max!r}"))
    assert load_scenario(bad).sim.dt < 1e-3
    bad.write_text(bad.read_text().replace("[sim]", '[sim]\nintegrator = "rk4"'))
    with pytest.raises(BadInputError, match=r"sim\.integrator"):
        load_scenario(bad)


def test_step_text_never_rounds_up(rng: np.random.Generator) -> None:
    from hybrid_force.sim.contact import step_text

    for dt in 10.0 ** rng.uniform(-7, 0, 500):
        shown = float(step_text(dt))
        assert shown <= dt and shown >= dt * (1 - 1e-2)

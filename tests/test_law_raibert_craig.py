"""The raibert_craig law (hybrid_force.control.laws.raibert_craig) against hand derivations:
the selection matrix, the force feed-through B, the force loop of a point mass on a rigid and
on a compliant plane, the contact mode's growth rate (original unstable, corrected stable), and
the common target on every shipped contact scenario."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.base import Desired, LawInput
from hybrid_force.control.laws.raibert_craig import RaibertCraigWorkspace, selection_matrix
from hybrid_force.control.supervisor import ControlSettings, HybridController
from hybrid_force.errors import ControlError, RunFailedError
from hybrid_force.geometry.builtin_surfaces import Plane
from hybrid_force.geometry.paths import FunctionPath
from hybrid_force.model.loading import load_robot
from hybrid_force.model.robot import Robot
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.loop import simulate
from hybrid_force.sim.settings import Scenario, SimSettings
from hybrid_force.studies.hybrid_stability import (
    FOLDED,
    STEEP_NORMAL,
    closed_loop_matrix,
    contact_mode_growth,
    steep_plane_scenario,
)

SCENARIOS = Path(__file__).parents[1] / "scenarios"
LAW = {"control.law": "raibert_craig"}


def _law(controller: HybridController) -> RaibertCraigWorkspace:
    law = controller.law
    assert isinstance(law, RaibertCraigWorkspace)
    return law


# --------------------------------------------------------------------------- selection matrix
def test_selection_matrix_projects_off_one_or_two_normals(rng: np.random.Generator) -> None:
    for k in (1, 2):
        N = rng.normal(size=(3, k))
        N /= np.linalg.norm(N, axis=0)
        S = selection_matrix(N)
        np.testing.assert_allclose(S @ S, S, atol=1e-14)
        np.testing.assert_allclose(S, S.T, atol=1e-15)
        np.testing.assert_allclose(S @ N, 0.0, atol=1e-14)
        assert np.linalg.matrix_rank(S, tol=1e-9) == 3 - k
        # a direction orthogonal to every normal passes unchanged
        t = np.cross(N[:, 0], N[:, -1]) if k == 2 else np.cross(N[:, 0], rng.normal(size=3))
        np.testing.assert_allclose(S @ t, t, atol=1e-14)


# --------------------------------------------------------------------------- the force loop
def _paper_contact_controller(**options: float | str) -> tuple[HybridController, Scenario]:
    overrides: dict[str, object] = {**LAW, "sim.duration": 0.1}
    overrides.update({f"control.raibert_craig.{k}": v for k, v in options.items()})
    sc = load_scenario(SCENARIOS / "paper_contact.toml", overrides=overrides)
    controller = HybridController(
        sc.robot, Constraint(sc.surfaces), sc.path, sc.q0, sc.control, dt=sc.sim.dt
    )
    return controller, sc


def test_feed_through_is_the_proportional_force_term_and_agrees_with_the_integral() -> None:
    """B = k_p Jᵀn̂ (hand derivation: u ∋ −Jᵀn̂ k_p (f_d − f)); and the integral term is
    k_i Jᵀn̂ ∫f, so a force held for one step dt moves the next u0 by (k_i dt / k_p) B per N
    (central differences through the supervisor's integrator)."""
    ctrl_a, sc = _paper_contact_controller(kp=0.7, ki=40.0)
    ctrl_b, _ = _paper_contact_controller(kp=0.7, ki=40.0)
    robot, q, v = sc.robot, sc.q0, np.array([0.3, -0.2, 0.1])
    terms = robot.terms(q, v)
    cons = ctrl_a.constraint.evaluate(terms, v)
    cmd = ctrl_a.command(0.0, q, v, terms, cons)
    assert cmd.B is not None
    normal = sc.surfaces[0].normal(robot.tip_position(q))
    np.testing.assert_allclose(cmd.B[:, 0], 0.7 * robot.jacobian(q).T @ normal, rtol=1e-12)
    ctrl_b.command(0.0, q, v, terms, cons)
    dt, h, f_d = sc.sim.dt, 1e-3, ctrl_a.f_d_contact
    ctrl_a.update(dt, f_d + h)
    ctrl_b.update(dt, f_d - h)
    u_plus = ctrl_a.command(dt, q, v, terms, cons).u0
    u_minus = ctrl_b.command(dt, q, v, terms, cons).u0
    np.testing.assert_allclose(
        (u_plus - u_minus) / (2 * h), (40.0 * dt / 0.7) * cmd.B[:, 0], rtol=1e-8, atol=1e-9
    )


def _point_mass(tmp_path: Path, mass: float) -> Robot:
    """Three prismatic joints x, y, z and one mass at the tip: M = mass·I, J = I."""
    joints, links = [], ['<link name="world"/>']
    parent = "world"
    for axis, xyz in (("x", "1 0 0"), ("y", "0 1 0"), ("z", "0 0 1")):
        child = f"slider_{axis}"
        inertial = (
            f'<inertial><mass value="{mass}"/><inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" '
            'iyz="0" izz="1e-3"/></inertial>'
            if axis == "z"
            else ""
        )
        links.append(f'<link name="{child}">{inertial}</link>')
        joints.append(
            f'<joint name="{axis}" type="prismatic"><parent link="{parent}"/>'
            f'<child link="{child}"/><axis xyz="{xyz}"/>'
            '<limit lower="-5" upper="5" effort="0" velocity="100"/></joint>'
        )
        parent = child
    text = f'<?xml version="1.0"?><robot name="point">{"".join(links + joints)}</robot>'
    path = tmp_path / "point.urdf"
    path.write_text(text)
    return load_robot(path, tip="slider_z")


def _pressing_point_mass(
    robot: Robot, contact: ContactSettings, mass_factor: float, duration: float
) -> Scenario:
    """The point mass at (0.3, 0.2, 0) holding that point on the plane z = 0 with 10 N."""
    point = np.array([0.3, 0.2, 0.0])
    zero = np.zeros(3)
    return Scenario(
        robot=robot,
        surfaces=(Plane(zero, [0.0, 0.0, 1.0]),),
        path=FunctionPath(lambda t: point, lambda t: zero, lambda t: zero),
        q0=point,
        control=ControlSettings(law="raibert_craig", supervisor=False, mass_factor=mass_factor),
        sim=SimSettings(duration=duration, settle_time=0.0),
        contact=contact,
        name="point_mass",
    )


def test_point_mass_on_a_rigid_plane_force_error_decays_at_the_pi_rate(tmp_path: Path) -> None:
    """Rigid contact: f = f_cmd + d, with d = (1 − μ) m g the weight the model (masses × μ)
    does not compensate; with e_F(0) = 0 and the supervisor's e_F += dt (f − f_d),
    f_k − f_d = d / (1 + k_p) · (1 − λ_f dt)^k, λ_f = k_i / (1 + k_p) (module eq. 4)."""
    m, mu = 2.0, 0.8
    sc = _pressing_point_mass(_point_mass(tmp_path, m), ContactSettings(), mu, 0.3)
    res = simulate(sc)
    kp, ki = 0.5, 1.5 * sc.control.gamma  # the defaults: k_i = (1 + k_p) γ
    d = (1.0 - mu) * m * 9.81
    k = np.arange(res.n_samples)
    expected = d / (1 + kp) * (1 - ki / (1 + kp) * sc.sim.dt) ** k
    np.testing.assert_allclose(res.f - 10.0, expected, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(res.p[:, :2], [[0.3, 0.2]] * res.n_samples, atol=1e-9)


def test_point_mass_on_a_compliant_plane_settles_at_the_slowest_closed_loop_root(
    tmp_path: Path,
) -> None:
    """Linear spring k: with δ = −z, m z⃛ + D_n z̈ + (1 + k_p) k ż + k_i k (z + f_d/k) = 0
    (differentiate m z̈ = −(1 + k_p)(f_d − f) + k_i e_F − D_n ż), D_n = (ω_p + ω_d) m. Late
    in the run |f − f_d| decays at the real part of the slowest root (−23.1 /s for k = 2e4
    N/m: not the rigid limit λ_f = 20 /s)."""
    m, k_e = 2.0, 2e4
    sc = _pressing_point_mass(
        _point_mass(tmp_path, m), ContactSettings(model="compliant", stiffness=k_e), 1.0, 0.8
    )
    res = simulate(sc)
    c = sc.control
    kp, ki, Dn = 0.5, 1.5 * c.gamma, (c.Lambda + c.kd_rate) * m
    slowest = max(np.roots([m, Dn, (1 + kp) * k_e, ki * k_e]).real)
    late = (res.t >= 0.4) & (res.t <= 0.8)
    error = np.abs(res.f[late] - 10.0)
    rate = np.polyfit(res.t[late], np.log(error), 1)[0]
    assert rate == pytest.approx(slowest, rel=0.02)
    assert abs(slowest + 20.0) > 2.0  # the test tells the third-order root from λ_f


# --------------------------------------------------------------------------- stability
WORK = np.array([0.0, 5.0, 0.5])  # the RTR stretched out, 1.78 m from its column
PUBLISHED = {"decouple": False}


@pytest.mark.parametrize("stiffness", [1e8, 1e11])
def test_contact_mode_growth_matches_the_energy_balance(rtr: Robot, stiffness: float) -> None:
    """The closed loop linearised by central differences (plant + law + integral) has the
    contact mode's growth rate of the energy balance (hybrid_force.studies.hybrid_stability
    eq. 1) within 1 %, for a contact of 1e8 and of 1e11 N/m alike: with the gains set at the
    folded start and the arm stretched out on the steep plane, the published original's
    vibration grows (σ ≈ +72 /s), the published corrected's decays; with the projection P the
    feedback does no work on it and σ = −(ω_p + ω_d)/2 + λ_f/2 = −45 /s for both forms."""
    rates = {}
    for form in ("original", "corrected"):
        for decouple in (False, True):
            options = {"form": form, "decouple": decouple}
            jacobian, ctrl = closed_loop_matrix(rtr, WORK, FOLDED, STEEP_NORMAL, options, stiffness)
            eig = np.linalg.eigvals(jacobian)
            fast = eig[np.argmax(np.abs(eig.imag))]
            gains = _law(ctrl).gains
            predicted = contact_mode_growth(
                gains, rtr.mass_matrix(WORK), rtr.jacobian(WORK), STEEP_NORMAL
            )
            assert fast.real == pytest.approx(predicted, rel=0.01)
            rates[form, decouple] = fast.real, eig.real.max()
    c = ControlSettings()
    neutral = -(c.Lambda + c.kd_rate) / 2 + c.gamma / 2
    assert rates["original", False][0] > 50.0
    assert rates["corrected", False][0] < -50.0 and rates["corrected", False][1] < -5.0
    for form in ("original", "corrected"):
        assert rates[form, True][0] == pytest.approx(neutral, rel=0.01)
        assert rates[form, True][1] < -5.0  # every mode decays


def _feedback_power(ctrl: HybridController, robot: Robot, v: np.ndarray) -> float:
    """q̇ᵀ u_pos [W] of the law at rest on its target (e = 0) at WORK with the velocity v."""
    law = _law(ctrl)
    zero = np.zeros(3)
    at_rest = Desired(q=WORK, qd=zero, qdd=zero, p=robot.tip_position(WORK), pd=zero, pdd=zero)
    terms = robot.terms(WORK, v)
    cons = ctrl.constraint.evaluate(terms, v)
    law.hybrid(LawInput(terms, v, zero, at_rest, cons, np.zeros(1), np.array([10.0])))
    return float(v @ law.last_u_pos)


def test_corrected_position_servo_is_passive_the_original_feeds_the_contact_mode(
    rtr: Robot, rng: np.random.Generator
) -> None:
    """At e = 0 the position part is the damper alone: its power q̇ᵀu_pos ≤ 0 for every q̇ in
    the corrected form (−‖·‖² of Jᵀ S D_x S J), while the original's answer to the contact
    vibration φ = M⁻¹Jᵀn̂ has positive power (hybrid_force.studies.hybrid_stability)."""
    phi = np.linalg.solve(rtr.mass_matrix(WORK), rtr.jacobian(WORK).T @ STEEP_NORMAL)
    options = {"form": "corrected", **PUBLISHED}
    _, corrected = closed_loop_matrix(rtr, WORK, FOLDED, STEEP_NORMAL, options, 1e9)
    assert max(_feedback_power(corrected, rtr, v) for v in rng.normal(size=(200, 3))) <= 1e-9
    assert _feedback_power(corrected, rtr, phi) <= 0.0
    options = {"form": "original", **PUBLISHED}
    _, original = closed_loop_matrix(rtr, WORK, FOLDED, STEEP_NORMAL, options, 1e9)
    assert _feedback_power(original, rtr, phi) > 0.0


def test_published_original_loses_the_steep_compliant_plane_the_corrected_holds_it(
    rtr: Robot,
) -> None:
    """The study run (benchmarks/study_raibert_craig.py) on a faster move: sliding out from the
    folded start, the published original's force swings by more than f_d (the contact is lost)
    once the arm is stretched out (σ > 0 there), the corrected's stays within 10 % of f_d after
    the first 0.5 s."""
    errors = {}
    for form in ("corrected", "original"):
        sc = steep_plane_scenario(
            {"form": form, **PUBLISHED}, move_time=2.0, duration=3.0, robot=rtr
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                res = simulate(sc)
            except RunFailedError as exc:  # a diverged run keeps what it computed
                assert exc.result is not None
                res = exc.result
        late = res.t >= 0.5
        errors[form] = float(np.max(np.abs(res.f[late] - 10.0)))
    assert errors["corrected"] < 0.1 * 10.0
    assert errors["original"] > 10.0


def test_without_the_projection_a_large_tangential_error_pulls_the_tool_off() -> None:
    """paper_contact starts 3 m below its path. The published corrected form's tangential
    spring w = S K_x S e accelerates the tip along n̂ too, so the rigid surface would have to
    pull with f = f_d + d/(1 + k_p), d = −(A M⁻¹ Aᵀ)⁻¹ A M⁻¹ Jᵀ w (+ the path's normal
    acceleration, small): the tool is released at t = 0. With P (default) it stays on."""
    controller, sc = _paper_contact_controller(**PUBLISHED)
    robot, q = sc.robot, sc.q0
    terms = robot.terms(q, np.zeros(3))
    normal = sc.surfaces[0].normal(terms.p)
    S = np.eye(3) - np.outer(normal, normal)
    w = S @ _law(controller).gains.Kx @ S @ (sc.path.position(0.0) - terms.p)
    a = robot.jacobian(q).T @ normal
    phi = np.linalg.solve(robot.mass_matrix(q), a)
    predicted = 10.0 - (phi @ robot.jacobian(q).T @ w) / (a @ phi) / 1.5
    for decouple in (False, True):
        overrides = {**LAW, "sim.duration": 0.05, "control.raibert_craig.decouple": decouple}
        sc = load_scenario(SCENARIOS / "paper_contact.toml", overrides=overrides)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "the tool left the surface": the point
                res = simulate(sc)
        except RunFailedError as exc:
            if exc.reason != "lost contact":
                raise
            assert exc.result is not None and not decouple
            res = exc.result
        releases = [e for e in res.events if e["kind"] == "release"]
        if decouple:
            assert not releases and res.meta["contact_at_end"] is True
        else:
            assert releases[0]["t"] == 0.0
            assert releases[0]["force"] == pytest.approx(predicted, rel=0.01)


# --------------------------------------------------------------------------- target, options
@pytest.mark.parametrize(
    "name", ["paper_contact", "paper_approach", "rtr_plane", "rtr_sphere", "ur5_plane"]
)
def test_default_gains_reach_the_common_target(name: str) -> None:
    """Position ≤ 1e-4 m and |f − f_d| ≤ 1e-2 N after settling (t ≥ 5 s), default gains."""
    sc = load_scenario(SCENARIOS / f"{name}.toml", overrides={**LAW, "sim.duration": 6.0})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the UR5's first torque reaches its effort limit
        res = simulate(sc)
    m = res.metrics()
    assert m.position_error_max_settled is not None and m.position_error_max_settled <= 1e-4
    assert m.force_error_max_settled is not None and m.force_error_max_settled <= 1e-2
    assert res.meta["controller"]["settings"]["form"] == "corrected"


def test_the_approach_lands_at_the_supervisors_speed() -> None:
    """Near the surface the normal rate follows ḋ = −λ_a d, so the tool touches at about
    λ_a · contact_tol = 1e-4 m/s (rtr_plane, starting 2 cm above the plane)."""
    sc = load_scenario(SCENARIOS / "rtr_plane.toml", overrides={**LAW, "sim.duration": 1.0})
    res = simulate(sc)
    impacts = [e for e in res.events if e["kind"] == "impact"]
    assert len(impacts) == 1
    c = sc.control
    assert impacts[0]["speed"] == pytest.approx(c.Lambda * c.contact_tol, rel=0.05)


def test_options_are_checked() -> None:
    with pytest.raises(ControlError, match="one of 'corrected', 'original'"):
        ControlSettings(law="raibert_craig", options={"raibert_craig": {"form": "fixed"}})
    with pytest.raises(ControlError):
        ControlSettings(law="raibert_craig", options={"raibert_craig": {"kp": -0.1}})
    ControlSettings(law="raibert_craig", options={"raibert_craig": {"kp": 0.0}})  # P-free: ok


def test_gains_scale_with_the_arm_at_its_start() -> None:
    """K_x = ω_p ω_d Λ₀ with Λ₀ = (J M⁻¹ Jᵀ)⁻¹ at q₀: with K_q = ω_p ω_d M(q₀) both forms give
    the same tip stiffness at q₀, J⁻ᵀ K_q J⁻¹ = K_x (square J)."""
    ctrl, sc = _paper_contact_controller()
    gains = _law(ctrl).gains
    J0 = sc.robot.jacobian(sc.q0)
    J_inv = np.linalg.inv(J0)
    np.testing.assert_allclose(J_inv.T @ gains.Kq @ J_inv, gains.Kx, rtol=1e-10)
    c = sc.control
    assert gains.position_rate * gains.damping_rate == pytest.approx(c.Lambda * c.kd_rate)
    assert gains.force_rate == pytest.approx(c.gamma)
    assert math.isnan(ctrl.law.V)

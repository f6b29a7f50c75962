"""hybrid_force.sim.plant: effort saturation (sat(u0 + B f), the consistent held set), and
the limits a run reports or stops at (sim.torque_limits, sim.joint_limits).

References: the defining equations of the constrained dynamics (M q̈ + h = τ + Aᵀ f, A q̈ = −γ)
evaluated with the reference terms, and clipping by hand.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from oracles.plant import OraclePlant
from oracles.terms import constraint_terms, robot_terms

from hybrid_force import RunWarning, load_robot, simulate
from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.base import Command
from hybrid_force.errors import RunFailedError
from hybrid_force.geometry.builtin_surfaces import Cylinder
from hybrid_force.geometry.paths import paper_helix
from hybrid_force.model.robot import Robot
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.plant import Plant
from hybrid_force.sim.settings import Scenario, SimSettings


def _rtr_with_limits(
    tmp_path: Path, rtr_urdf: Path, effort: float, velocity: float = 100.0
) -> Path:
    """The bundled RTR with the same effort limit [N·m or N] on every joint."""
    text = rtr_urdf.read_text().replace('effort="0"', f'effort="{effort}"')
    text = text.replace('velocity="100"', f'velocity="{velocity}"')
    out = tmp_path / "rtr_limited.urdf"
    out.write_text(text)
    return out


def _on_the_cylinder(robot: Robot) -> np.ndarray:
    from hybrid_force.control.clik import inverse_kinematics

    return inverse_kinematics(robot, paper_helix().position(0.3), seed=np.array([0.0, 6.0, 2.0]))


@pytest.mark.parametrize("plant_type", [Plant, OraclePlant])
def test_saturated_loop_satisfies_the_dynamics_with_clipped_torque(
    tmp_path: Path, rtr_urdf: Path, plant_type: type[Plant]
) -> None:
    robot = load_robot(_rtr_with_limits(tmp_path, rtr_urdf, effort=40.0))
    effort = robot.effort_limits
    con = Constraint(Cylinder(0.4))
    plant = plant_type(robot, con, SimSettings(), 1e-5)
    plant.in_contact = True
    rng = np.random.default_rng(7)
    q = _on_the_cylinder(robot)
    saturated_cases = 0
    for _ in range(20):
        v = con.at(robot, q).Q @ rng.uniform(-0.5, 0.5, 3)
        terms, cons = plant.evaluate(q, v)
        assert cons is not None
        u0 = rng.uniform(-80.0, 80.0, 3)
        B = rng.uniform(-0.5, 0.5, (3, 1))
        ddq, f = plant.accelerate(terms, cons, Command(u0, B), 0.0)
        if not plant.in_contact:  # released: nothing more to check here
            plant.in_contact = True
            continue
        tau = u0 + B @ f if plant.applied is None else plant.applied
        commanded = u0 + B @ f
        # the applied torque never exceeds a limit; where it is below, it is the command
        assert np.all(np.abs(tau) <= effort * (1 + 1e-12))
        below = np.abs(tau) < effort * (1 - 1e-12)
        np.testing.assert_allclose(tau[below], commanded[below], rtol=0, atol=1e-9)
        # a saturated joint holds the limit with the sign of its command
        held = ~below
        np.testing.assert_array_equal(np.abs(tau[held]), effort[held])
        saturated_cases += int(held.any())
        # the constrained dynamics hold with that torque (independent reference terms)
        ref = robot_terms(robot, q, v)
        refc = constraint_terms(con, ref, v)
        gamma = SimSettings().baumgarte.gamma(refc.drift, refc.rate, refc.phi / refc.scale)
        residual = ref.M @ ddq + ref.nle - tau - refc.A.T @ f
        assert np.abs(residual).max() <= 1e-9 * (1 + np.abs(tau).max())
        assert np.abs(refc.A @ ddq + gamma).max() <= 1e-9 * (1 + np.abs(ddq).max())
    assert saturated_cases >= 5  # the case exercised the limits


def test_free_plant_clips_the_command(tmp_path: Path, rtr_urdf: Path) -> None:
    robot = load_robot(_rtr_with_limits(tmp_path, rtr_urdf, effort=3.0))
    plant = Plant(robot, Constraint(Cylinder(0.4)), SimSettings(), 1e-5)
    q, v = np.array([0.1, 6.0, 1.0]), np.zeros(3)
    terms, cons = plant.evaluate(q, v)
    ddq, f = plant.accelerate(terms, cons, Command(np.array([10.0, -1.0, -7.0]), None), 0.0)
    np.testing.assert_array_equal(plant.applied, [3.0, -1.0, -3.0])
    expected = np.linalg.solve(terms.M, np.array([3.0, -1.0, -3.0]) - terms.nle)
    np.testing.assert_allclose(ddq, expected, rtol=1e-12, atol=1e-12)
    assert not f.any()
    off = Plant(robot, Constraint(Cylinder(0.4)), SimSettings(torque_limits=False), 1e-5)
    off.accelerate(terms, cons, Command(np.array([10.0, -1.0, -7.0]), None), 0.0)
    assert off.applied is None and off.effort is None


class _Constant:
    """A controller that always demands the same torque."""

    def __init__(self, u: np.ndarray) -> None:
        self.u = u

    def command(self, t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray) -> np.ndarray:
        return self.u


def _free_scenario(tmp_path: Path, rtr_urdf: Path, effort: float) -> Scenario:
    model = _rtr_with_limits(tmp_path, rtr_urdf, effort=effort)
    sc = load_scenario(
        Path(__file__).parents[1] / "scenarios" / "paper_approach.toml",
        {"robot.model": str(model), "sim.duration": 0.2},
    )
    return sc


def test_a_demand_beyond_the_limit_gets_exactly_the_limit(tmp_path: Path, rtr_urdf: Path) -> None:
    sc = _free_scenario(tmp_path, rtr_urdf, effort=2.0)
    demand = np.array([5.0, 0.0, -0.5])
    with pytest.warns(RunWarning, match="held at the limit for 0.201 s"):
        res = simulate(sc, controller=_Constant(demand))
    np.testing.assert_array_equal(res.u[:, 0], 2.0)  # q1: the limit, exactly
    np.testing.assert_array_equal(res.u[:, 2], -0.5)  # q3: below it, as commanded
    np.testing.assert_array_equal(res.u_cmd, np.tile(demand, (res.n_samples, 1)))
    summary = res.summary()
    assert summary["effort_exceeded"] == ["q1"]
    assert summary["saturated_time"] == {"q1": pytest.approx(res.n_samples * sc.sim.dt)}
    # switched off: the command is applied as is, and still reported
    off = dataclasses.replace(sc, sim=dataclasses.replace(sc.sim, torque_limits=False))
    with pytest.warns(RunWarning, match="applied it unsaturated"):
        res_off = simulate(off, controller=_Constant(demand))
    np.testing.assert_array_equal(res_off.u[:, 0], 5.0)
    assert res_off.summary()["saturated_time"] == {}


def test_joint_limits_report_an_event_or_stop_the_run(tmp_path: Path, rtr_urdf: Path) -> None:
    # q3 is pushed hard toward its upper limit 3.2 rad from about 1.3 rad
    sc = _free_scenario(tmp_path, rtr_urdf, effort=1e3)
    push = _Constant(np.array([0.0, 0.0, 400.0]))
    sc = dataclasses.replace(sc, sim=dataclasses.replace(sc.sim, duration=0.5))
    with pytest.warns(RunWarning, match="joint q3 left its range"):
        res = simulate(sc, controller=push)
    crossed = np.flatnonzero(res.q[:, 2] > 3.2 * (1 + 1e-9))
    assert crossed.size > 0
    events = [e for e in res.events if e["kind"] == "joint_limit"]
    assert [(e["joint"], e["t"], e["limit"]) for e in events] == [
        ("q3", pytest.approx(res.t[crossed[0]]), 3.2)
    ]
    stop = dataclasses.replace(sc, sim=dataclasses.replace(sc.sim, joint_limits="stop"))
    with pytest.raises(RunFailedError, match="joint q3 left its range") as info:
        simulate(stop, controller=push)
    assert info.value.reason == "joint limit"
    kept = info.value.result
    assert kept is not None and kept.meta["reason"] == "joint limit"
    assert kept.n_samples == crossed[0] + 1  # up to and with the first sample beyond


def test_release_applies_the_free_command_not_the_contact_solution(
    tmp_path: Path, rtr_urdf: Path
) -> None:
    robot = load_robot(_rtr_with_limits(tmp_path, rtr_urdf, effort=40.0))
    effort = robot.effort_limits
    con = Constraint(Cylinder(0.4))
    plant = Plant(robot, con, SimSettings(), 1e-5)
    q, v = _on_the_cylinder(robot), np.zeros(3)
    rng = np.random.default_rng(11)
    released = ambiguous = 0
    for _ in range(400):
        plant.in_contact = True
        terms, cons = plant.evaluate(q, v)
        assert cons is not None
        u0 = rng.uniform(-60.0, 60.0, 3)
        B = rng.uniform(-2.0, 2.0, (3, 1))
        try:
            ddq, f = plant.accelerate(terms, cons, Command(u0, B), 0.0)
        except np.linalg.LinAlgError:  # a random B can make the held set ambiguous
            ambiguous += 1  # (tests/test_saturation.py: the plant refuses to choose)
            continue
        if plant.in_contact:
            continue
        released += 1
        # off the surface f = 0, so the torque is the clipped u0 (B f vanishes)
        tau = np.clip(u0, -effort, effort)
        applied = u0 if plant.applied is None else plant.applied
        np.testing.assert_array_equal(applied, tau)
        expected = np.linalg.solve(terms.M, tau - terms.nle)
        np.testing.assert_allclose(ddq, expected, rtol=1e-10, atol=1e-10)
        assert not f.any()
    assert released >= 10 and ambiguous < 40


def test_the_contact_is_chosen_once_when_the_plant_is_built(rtr: Robot) -> None:
    """Rigid (the default) or compliant: the strategy the plant holds for the whole run; the
    oracle plant holds the readable rigid contact."""
    from oracles.plant import OracleRigidContact

    from hybrid_force.sim.compliant_contact import CompliantContact
    from hybrid_force.sim.contact import ContactSettings
    from hybrid_force.sim.rigid_contact import RigidContact

    con = Constraint(Cylinder(0.4))
    rigid = Plant(rtr, con, SimSettings(), 1e-5)
    soft = Plant(rtr, con, SimSettings(), 1e-5, ContactSettings(model="compliant"))
    oracle = OraclePlant(rtr, con, SimSettings(), 1e-5)
    assert type(rigid.surface_contact) is RigidContact and rigid.surface_contact.arm is rigid
    assert type(soft.surface_contact) is CompliantContact and soft.surface_contact.arm is soft
    assert type(oracle.surface_contact) is OracleRigidContact
    assert rigid.surface_contact._compiled_step and not oracle.surface_contact._compiled_step

"""The joints' own damping and Coulomb friction in the plant (issue 28 item 2).

References: a 1-joint pendulum written here, by hand: without gravity torque the damped
joint's velocity decays as q̇₀(1 − d dt/I)^k under semi-implicit Euler (exactly) and as
q̇₀ e^(−d t/I) in continuous time; with gravity, a hand-written RK4 of
I θ̈ = −m g l sin θ − d θ̇ − τ_c θ̇/√(θ̇² + ε²). The energy balance
W_u = ΔT + ΔV + E_joint_damping + E_joint_friction (first order in dt) on the RTR pressed onto
the paper's cylinder; a model whose damping and friction are 0 runs bit-identically.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hybrid_force import load_robot, simulate
from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.base import Command
from hybrid_force.errors import RobotError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane
from hybrid_force.model.robot import Robot
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.contact import joint_dissipation
from hybrid_force.sim.plant import Plant
from hybrid_force.sim.settings import SimSettings

MASS, LENGTH, IYY, G0 = 2.0, 0.5, 0.01, 9.81
INERTIA = MASS * LENGTH**2 + IYY  # about the joint axis [kg·m²]

_ZERO = '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>'
_PENDULUM = """<?xml version="1.0"?>
<robot name="pendulum">
  <link name="world"/>
  <link name="carriage"><inertial><mass value="0"/>{zero}</inertial></link>
  <link name="arm">
    <inertial><origin xyz="{com}"/><mass value="{m}"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="{izz}"/></inertial>
  </link>
  <link name="tip"/>
  <joint name="slide" type="prismatic"><parent link="world"/><child link="carriage"/>
    <axis xyz="{axis}"/><limit lower="-1000" upper="1000" effort="0" velocity="1000"/></joint>
  <joint name="hinge" type="revolute"><parent link="carriage"/><child link="arm"/>
    <axis xyz="{axis}"/><limit lower="-3" upper="3" effort="0" velocity="100"/>
    <dynamics damping="{d}" friction="{c}"/></joint>
  <joint name="tip_joint" type="fixed"><parent link="arm"/><child link="tip"/>
    <origin xyz="{com}"/></joint>
</robot>
"""


def _pendulum(tmp_path: Path, d: float, c: float, axis_up: bool = False) -> Robot:
    """A point-like mass m at l from a hinge, I = m l² + I_c about it, on a massless slider
    along the hinge's own axis (the toolkit's arms have ≥ 2 joints): the slider's motion is
    orthogonal to the swing, so M = diag(m, I) and the hinge's equation is the 1-joint one.
    Hanging from a horizontal hinge (y; θ = 0 down); ``axis_up``: a vertical hinge with the
    arm horizontal, where gravity exerts no torque on it (the slider falls, unrelated)."""
    if axis_up:
        fields = {"com": f"{LENGTH} 0 0", "iyy": 0.01, "izz": IYY, "axis": "0 0 1"}
    else:
        fields = {"com": f"0 0 -{LENGTH}", "iyy": IYY, "izz": 0.01, "axis": "0 1 0"}
    text = _PENDULUM.format(zero=_ZERO, m=MASS, d=d, c=c, **fields)
    path = tmp_path / f"pendulum_{d}_{c}_{axis_up}.urdf"
    path.write_text(text)
    return load_robot(path, tip="tip")


def _swing(robot: Robot, q0: float, v0: float, dt: float, steps: int) -> np.ndarray:
    """(steps + 1, 2) [θ, θ̇] of the hinge swinging freely, no torque, far from the surface."""
    far = Plane((0.0, 0.0, -1000.0), (0.0, 0.0, 1.0))
    # the plant's implicit joint damping uses sim.dt: the step the loop makes
    plant = Plant(robot, Constraint([far]), SimSettings(dt=dt), 1e-5)
    q, v = np.array([0.0, q0]), np.array([0.0, v0])
    out = [np.array([q0, v0])]
    zero = Command(np.zeros(2), None)
    for i in range(steps):
        terms, cons = plant.evaluate(q, v)
        assert cons is not None
        ddq, _ = plant.accelerate(terms, cons, zero, i * dt)
        q, v = plant.advance(q, v, ddq, zero, i * dt, dt, cons.distance)
        q, v = q.copy(), v.copy()
        out.append(np.array([q[1], v[1]]))
    assert not plant.in_contact
    return np.array(out)


def test_the_model_reads_the_urdf_dynamics(tmp_path: Path) -> None:
    robot = _pendulum(tmp_path, 0.7, 0.3)
    assert np.array(robot.model.damping).tolist() == [0.0, 0.7]
    assert np.array(robot.model.friction).tolist() == [0.0, 0.3]


def test_a_damped_joint_decays_as_minus_d_qdot(tmp_path: Path) -> None:
    """No gravity torque (vertical hinge): I θ̈ = −d θ̇. The plant's step takes the damping at
    the step's end velocity, I (θ̇_{k+1} − θ̇_k) = −d dt θ̇_{k+1}, so θ̇_k = θ̇₀ (1 + d dt / I)^−k;
    θ̇₀ e^(−d t / I) as dt → 0."""
    d, dt, steps, v0 = 0.3, 1e-3, 2000, 2.0
    robot = _pendulum(tmp_path, d, 0.0, axis_up=True)
    M = pin.crba(robot.model, robot.new_data(), np.zeros(2))
    np.testing.assert_allclose(np.triu(M), np.diag([MASS, INERTIA]), rtol=1e-12, atol=1e-15)
    v = _swing(robot, 0.0, v0, dt, steps)[:, 1]
    k = np.arange(steps + 1)
    np.testing.assert_allclose(v, v0 * (1.0 + d * dt / INERTIA) ** -k.astype(float), rtol=1e-11)
    # the continuous decay, within the step's first-order error
    t = k * dt
    exact = v0 * np.exp(-d * t / INERTIA)
    assert np.abs(v - exact).max() <= d * d / INERTIA**2 * dt * t.max() * v0


def _rk4_pendulum(d: float, c: float, eps: float, q0: float, dt: float, steps: int) -> np.ndarray:
    """RK4 of I θ̈ = −m g l sin θ − d θ̇ − c θ̇/√(θ̇² + ε²) (by hand, θ = 0 hanging)."""

    def f(x: np.ndarray) -> np.ndarray:
        th, om = x
        torque = -MASS * G0 * LENGTH * math.sin(th) - d * om - c * om / math.sqrt(om**2 + eps**2)
        return np.array([om, torque / INERTIA])

    x = np.array([q0, 0.0])
    out = [x]
    for _ in range(steps):
        k1 = f(x)
        k2 = f(x + 0.5 * dt * k1)
        k3 = f(x + 0.5 * dt * k2)
        k4 = f(x + dt * k3)
        x = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(x)
    return np.array(out)


def test_a_damped_pendulum_with_friction_swings_as_its_equation(tmp_path: Path) -> None:
    d, c, dt, steps, q0 = 0.2, 0.05, 1e-4, 20000, 0.5
    robot = _pendulum(tmp_path, d, c)
    plant = _swing(robot, q0, 0.0, dt, steps)
    eps = SimSettings().joint_friction_velocity
    ref = _rk4_pendulum(d, c, eps, q0, dt, steps)
    # semi-implicit Euler against RK4 at the same step: the Euler step's O(dt) error
    assert np.abs(plant[:, 0] - ref[:, 0]).max() < 3e-4 * q0  # 1.5e-4: halves with dt
    # it decays: the amplitude of the last swing well below the start (d alone: e^(−d t/2I))
    late = np.abs(plant[-5000:, 0]).max()
    assert late < q0 * math.exp(-d * 1.5 / (2 * INERTIA))


def _damped_rtr(tmp_path: Path, rtr_urdf: Path, d: float, c: float) -> Path:
    """The bundled RTR with <dynamics damping friction> on its three joints."""
    text = rtr_urdf.read_text()
    dyn = f'<dynamics damping="{d}" friction="{c}"/>'
    for name in ("q1", "q2", "q3"):
        head = f'<joint name="{name}"'
        start = text.index(head)
        end = text.index("</joint>", start)
        text = text[:end] + dyn + text[end:]
    out = tmp_path / f"rtr_damped_{d}_{c}.urdf"
    out.write_text(text)
    return out


def _balance(robot: Robot, dt: float) -> tuple[float, float]:
    """(W_u − ΔT − ΔV − E_joints, E_joints) [J] over 0.4 s of the RTR pressed onto the
    cylinder and driven round it (as tests/test_contact.py's balance, joints damped here)."""
    from hybrid_force.control.clik import inverse_kinematics

    plant = Plant(robot, Constraint(Cylinder(0.4)), SimSettings(dt=dt), 1e-5)
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
        u = terms.g - 30.0 * cons.A[0] + np.array([20.0, 5.0, 0.0])
        ddq, _ = plant.accelerate(terms, cons, Command(u, None), i * dt)
        q_new, v_new = plant.advance(q, v, ddq, Command(u, None), i * dt, dt, cons.distance)
        work += float(u @ (q_new - q))
        q, v = q_new.copy(), v_new.copy()
        assert plant.in_contact
    lost = plant.joint_damping_energy + plant.joint_friction_energy
    assert plant.joint_damping_energy > 0 and plant.joint_friction_energy > 0
    return work - (energy(q, v) - e0) - lost, lost


def test_the_energy_balance_closes_with_the_joints_dissipation(
    tmp_path: Path, rtr_urdf: Path
) -> None:
    """The same tolerance as test_contact's balance: the residual halves with dt and stays
    below 2 % of what the joints dissipate."""
    robot = load_robot(_damped_rtr(tmp_path, rtr_urdf, 2.0, 1.0))
    (r1, loss), (r2, _) = (_balance(robot, dt) for dt in (2e-4, 1e-4))
    assert abs(r2) < 0.6 * abs(r1)
    assert abs(r2) < 0.02 * loss


def test_a_model_with_zero_damping_runs_bit_identically(tmp_path: Path, rtr_urdf: Path) -> None:
    scenario = Path(__file__).parents[1] / "scenarios" / "paper_contact.toml"
    runs = []
    for model in (rtr_urdf, _damped_rtr(tmp_path, rtr_urdf, 0.0, 0.0)):
        sc = load_scenario(scenario, {"robot.model": str(model), "sim.duration": 0.3})
        runs.append(simulate(sc))
    plain, zero = runs
    for name in ("q", "v", "u", "f", "p"):
        np.testing.assert_array_equal(getattr(plain, name), getattr(zero, name))
    assert zero.meta["joint_damping_energy"] == zero.meta["joint_friction_energy"] == 0.0


def test_a_damped_run_logs_the_joints_energy(tmp_path: Path, rtr_urdf: Path) -> None:
    scenario = Path(__file__).parents[1] / "scenarios" / "paper_contact.toml"
    model = _damped_rtr(tmp_path, rtr_urdf, 1.0, 0.5)
    sc = load_scenario(scenario, {"robot.model": str(model), "sim.duration": 0.3})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = simulate(sc)
    summary = res.summary()
    assert summary["joint_damping_energy"] > 0 and summary["joint_friction_energy"] > 0
    # the controller's own model is the plant's file: it does not compensate them, so the
    # run differs from the undamped one
    plain = simulate(load_scenario(scenario, {"robot.model": str(rtr_urdf), "sim.duration": 0.3}))
    assert np.abs(res.q - plain.q).max() > 1e-9


def test_joint_dissipation_by_hand() -> None:
    d, c, eps = np.array([0.5, 0.0]), np.array([0.2, 1.0]), 1e-3
    v = np.array([2.0, -0.5])
    dd, cc = joint_dissipation(d, c, eps, v)
    np.testing.assert_array_equal(dd, d)
    np.testing.assert_allclose(cc * v, c * v / np.sqrt(v**2 + eps**2), rtol=1e-15)
    assert np.all(cc >= 0)  # the torque −(d + c) q̇ opposes the velocity


def test_a_stiff_wrist_with_friction_stays_stable(tmp_path: Path) -> None:
    """τ_c/ε = 1e3 N·m·s/rad on I = 0.011 kg·m²: an explicit step would need dt < 2.2e-5 s;
    the plant's implicit one settles at dt = 1 ms (and stays at rest)."""
    text = _PENDULUM.format(
        zero=_ZERO, m=1e-3, d=0.0, c=1.0, com="1 0 0", iyy=0.01, izz=0.01, axis="0 0 1"
    )
    path = tmp_path / "wrist.urdf"
    path.write_text(text)
    robot = load_robot(path, tip="tip")
    v = _swing(robot, 0.0, 5.0, 1e-3, 200)[:, 1]
    assert np.all(np.isfinite(v)) and abs(v[-1]) < 1e-6
    assert np.all(np.abs(np.diff(v)) <= np.abs(v[:-1]) + 1e-15)  # monotone decay, no flip


def test_negative_joint_damping_is_refused(tmp_path: Path) -> None:
    robot = _pendulum(tmp_path, 0.1, 0.0)
    robot.model.damping[1] = -1.0
    with pytest.raises(RobotError, match="hinge has damping -1"):
        Plant(robot, Constraint([Plane((0.0, 0.0, -50.0), (0.0, 0.0, 1.0))]), SimSettings(), 1e-5)

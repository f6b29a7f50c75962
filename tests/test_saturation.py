"""Torque saturation in contact (issue 28 item 4): the consistent set of held joints.

Reference: brute force over all 3^n held sets (each joint held at +e, free, or held at −e),
each solved with the dense KKT system of :func:`oracles.plant.kkt`
and checked for consistency (held joints' command beyond the limit on their side, free
joints' within); the plant's held set must be the unique consistent one.
"""

from __future__ import annotations

import itertools
import warnings
from typing import Any

import numpy as np
import pytest
from oracles.plant import kkt

from hybrid_force import simulate
from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.base import Command
from hybrid_force.geometry.builtin_surfaces import Plane
from hybrid_force.model.robot import Robot
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.plant import Plant
from hybrid_force.sim.rigid_contact import RigidContact
from hybrid_force.sim.run_checks import joint_names, saturated_time
from hybrid_force.sim.saturation import _enumerate, saturation_solutions
from hybrid_force.sim.settings import SimSettings


def _brute_force(
    M: np.ndarray,
    nle: np.ndarray,
    A: np.ndarray,
    gamma: np.ndarray,
    u0: np.ndarray,
    B: np.ndarray,
    effort: np.ndarray,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Every consistent (signs, f) over all 3^n held sets, by dense KKT solves."""
    out = []
    for signs in itertools.product((-1, 0, 1), repeat=u0.shape[0]):
        s = np.array(signs)
        held = s != 0
        u0h, Bh = u0.copy(), B.copy()
        u0h[held], Bh[held] = s[held] * effort[held], 0.0
        _, f = kkt(M, nle, u0h, Bh, A, gamma)
        x = u0 + B @ f
        tol = 1e-9 * (1.0 + np.abs(x))
        ok = np.where(held, s * x >= effort - tol, np.abs(x) <= effort + tol)
        if ok.all():
            out.append((s, f))
    return out


def _held(applied: np.ndarray, commanded: np.ndarray, effort: np.ndarray) -> np.ndarray:
    """Signs of the joints held at a limit: ±e exactly and different from the command."""
    held = (np.abs(applied) == effort) & (applied != commanded)
    return (np.sign(applied) * held).astype(np.int64)


@pytest.mark.parametrize("name", ["rtr", "ur5", "panda"])
def test_the_held_set_is_the_unique_consistent_one(
    name: str, request: pytest.FixtureRequest, rng: np.random.Generator
) -> None:
    robot: Robot = request.getfixturevalue(name)
    n = robot.nv
    lower, upper = robot.position_limits
    lower, upper = np.maximum(lower, -3.0), np.minimum(upper, 3.0)
    checked = ambiguous = saturated = 0
    for trial in range(12):
        q = rng.uniform(lower, upper)
        v = rng.uniform(-0.5, 0.5, n)
        data = robot.new_data()
        tip = robot.terms(q, v, data).p.copy()
        normal = rng.normal(size=3)
        constraint = Constraint([Plane(tip, normal / np.linalg.norm(normal))])
        plant = Plant(robot, constraint, SimSettings(), 1e-5)
        plant.in_contact = True
        terms, cons = plant.evaluate(q, v)
        assert cons is not None
        A = cons.A.copy()
        gamma = SimSettings().baumgarte.gamma(cons.drift, cons.rate, cons.phi / cons.scale)
        # the plant's own M and C q̇ + g: with the joints' damping (the Panda's URDF has 0.003)
        M, nle = plant._M(terms).copy(), plant._nle(terms).copy()
        u0 = rng.normal(scale=20.0, size=n)
        # the paper law's structure B = β M A⁺ (arimoto.py) for half the trials, random else
        A_pinv = A.T / float((A @ A.T)[0, 0])
        B = 2.0 * (M @ A_pinv) if trial % 2 else rng.normal(scale=0.3, size=(n, 1))
        _, f_free = kkt(M, nle, u0, B, A, gamma)
        # tight limits: every joint's unsaturated torque within 0.3 to 1.5 of its limit
        effort = np.abs(u0 + B @ f_free) * rng.uniform(0.3, 1.5, n)
        plant.effort = effort
        contact = plant.surface_contact
        assert isinstance(contact, RigidContact)
        contact.unilateral = False  # the comparison holds whatever the sign of f
        expected = _brute_force(M, nle, A, gamma, u0, B, effort)
        assert expected, "a solution always exists for one surface (module docstring)"
        if len(expected) > 1:
            ambiguous += 1
            with pytest.raises(np.linalg.LinAlgError, match="consistent sets"):
                plant.accelerate(terms, cons, Command(u0, B), 0.0)
            continue
        _, f = plant.accelerate(terms, cons, Command(u0, B), 0.0)
        signs, f_ref = expected[0]
        applied = u0 + B @ f if plant.applied is None else plant.applied
        np.testing.assert_array_equal(_held(applied, u0 + B @ f, effort), signs)
        np.testing.assert_allclose(f, f_ref, rtol=1e-9, atol=1e-9)
        # the solver's own (k = 1 sweep) and enumeration (k > 1 path) agree on it
        W = contact._force_per_torque(terms, cons)
        tau = u0 + B @ f_free
        f_bar = f_free + W @ tau
        sweep = saturation_solutions(u0, B, f_bar, W, effort)
        listed = _enumerate(u0, B, f_bar, W, effort)
        assert len(sweep) == len(listed) == 1
        np.testing.assert_array_equal(sweep[0][0], signs)
        np.testing.assert_array_equal(listed[0][0], signs)
        checked += 1
        saturated += int(np.count_nonzero(signs) >= 2)
    assert checked >= 6 and checked + ambiguous == 12
    assert saturated >= 4  # most trials hold two joints or more


def test_ur5_plane_at_500_newtons_holds_wrist_1_on_the_side_of_its_command() -> None:
    """ur5_plane with f_d = 500 N: the force no longer jumps between two solutions (364 and
    502 N in issue 28) and every held joint is held on the side of its command."""
    sc = load_scenario("scenarios/ur5_plane.toml", {"control.f_d": 500.0, "sim.duration": 3.0})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the start saturates two joints (their warning)
        res = simulate(sc)
    assert res.u_cmd is not None
    effort = sc.robot.effort_limits
    held = _held(res.u, res.u_cmd, effort)
    beyond = np.abs(res.u_cmd) > effort
    # held exactly where the command is beyond its limit, on its side
    np.testing.assert_array_equal(held != 0, beyond)
    np.testing.assert_array_equal(held[beyond], np.sign(res.u_cmd[beyond]))
    f = res.f.ravel()
    contact = np.flatnonzero(res.phase == 2)
    steady = contact[contact > contact[0] + 1000]  # a second after the touch
    assert steady.size > 1000
    assert np.abs(np.diff(f[steady])).max() < 1.0  # [N] per step; was 150 N jumps
    # the summary's saturated time is the time a limit was applied, joint by joint
    names = joint_names(sc.robot)
    expected = {
        name: np.count_nonzero(held[:, j]) * sc.sim.dt
        for j, name in enumerate(names)
        if held[:, j].any()
    }
    assert expected.keys() == res.meta["saturated_time"].keys()
    for name, seconds in expected.items():
        assert res.meta["saturated_time"][name] == pytest.approx(seconds)
    assert saturated_time(names, effort, res.u, res.u_cmd, sc.sim.dt) == res.meta["saturated_time"]


def _old_active_set(
    contact: RigidContact, terms: Any, cons: Any, cmd: Command, ddq: np.ndarray, f: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The iteration this replaced (kept here as the bug's reference): fix the joints beyond
    their limit at the limit of the first, unsaturated pass, resolve, never release."""
    effort = contact.arm.effort
    assert effort is not None and cmd.B is not None
    u = cmd.u0 + cmd.B @ f
    over = np.abs(u) > effort
    if not over.any():
        return ddq, f
    fixed = np.zeros(u.shape[0], dtype=bool)
    u0, B = cmd.u0.copy(), cmd.B.copy()
    for _ in range(u.shape[0]):
        fixed |= over
        u0[over] = np.clip(u[over], -effort[over], effort[over])
        B[over] = 0.0
        ddq, f = contact._constrained(terms, cons, Command(u0, B))
        u = u0 + B @ f
        over = ~fixed & (np.abs(u) > effort)
        if not over.any():
            break
    contact.arm.applied = u
    return ddq.copy(), f.copy()


def test_on_the_old_iterations_states_the_held_set_is_unique_and_on_the_commands_side(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """ur5_plane, f_d = 500 N, run with the old iteration: wherever it held wrist 1 at −28 N·m
    under a positive command (91 samples in 3 s), the consistent set at that very state is
    unique and does not (wrist 1 is within its limit there, f ≈ 400 N, not the ≈ 495 N the
    wrong hold gave)."""
    seen: list[tuple[int, np.ndarray, float, float, float, float]] = []

    def replay(self: RigidContact, terms: Any, cons: Any, cmd: Command, ddq: Any, f: Any) -> Any:
        effort = self.arm.effort
        assert effort is not None and cmd.B is not None
        if not np.any(np.abs(cmd.u0 + cmd.B @ f) > effort):
            return ddq, f
        W = self._force_per_torque(terms, cons)
        found = saturation_solutions(cmd.u0, cmd.B, f + W @ (cmd.u0 + cmd.B @ f), W, effort)
        ddq, f = _old_active_set(self, terms, cons, cmd, ddq, f)
        applied = self.arm.applied
        assert applied is not None
        commanded = float((cmd.u0 + cmd.B @ f)[3])
        held = float(applied[3])
        seen.append((len(found), found[0][0], float(found[0][1][0]), held, commanded, float(f[0])))
        return ddq, f

    monkeypatch.setattr(RigidContact, "_saturated", replay)
    sc = load_scenario("scenarios/ur5_plane.toml", {"control.f_d": 500.0, "sim.duration": 3.0})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        simulate(sc)
    assert all(count == 1 for count, *_ in seen)  # one consistent set at every state
    wrong = [s for s in seen if s[3] == -28.0 and s[4] > 0.0]  # wrist 1 held against it
    assert len(wrong) > 50  # 91 in these 3 s
    for _, signs, f_new, _, _, f_old in wrong:
        assert signs[3] != -1  # the consistent set never holds it there
        assert f_old - f_new > 50.0  # the jump the wrong hold made (≈ 495 against ≈ 400 N)

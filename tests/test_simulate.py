"""Closed-loop simulation: the paper's two experiments (sections 6.3, 6.4) and the loop's rules.

The targets are those of issue 5, checked on full 20 s runs at dt = 1 ms.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from oracles.run import oracle_run

from hybrid_force import (
    BadInputError,
    Circle,
    ControlSettings,
    Cylinder,
    Plane,
    Result,
    Scenario,
    SimSettings,
    inverse_kinematics,
    load_robot,
    paper_helix,
    simulate,
)
from hybrid_force.errors import RunFailedError, RunWarning
from hybrid_force.phases import CONTACT


def _contact_scenario(robot, duration: float, **sim) -> Scenario:
    """Section 6.3: on the cylinder of eq. 26, 3 m below the helix of eq. 25."""
    q0 = inverse_kinematics(robot, np.array([0.4, 0.0, 7.0]), seed=np.array([0.0, 6.0, 2.0]))
    return Scenario(
        robot=robot,
        surfaces=[Cylinder(0.4)],
        path=paper_helix(),
        q0=q0,
        control=ControlSettings(supervisor=False),
        sim=SimSettings(duration=duration, **sim),
        name="paper_contact",
    )


def _approach_scenario(robot, duration: float, **sim) -> Scenario:
    """Section 6.4: from (0.1, 0.1, 2) inside the cylinder, approach, then press on its wall."""
    q0 = inverse_kinematics(robot, np.array([0.1, 0.1, 2.0]), seed=np.array([0.5, 1.0, 2.0]))
    return Scenario(
        robot=robot,
        surfaces=[Cylinder(0.4, inside=True)],
        path=paper_helix(),
        q0=q0,
        control=ControlSettings(),
        sim=SimSettings(duration=duration, **sim),
        name="paper_approach",
    )


@pytest.fixture(scope="module")
def contact_run(rtr) -> Result:
    return simulate(_contact_scenario(rtr, 20.0))


@pytest.fixture(scope="module")
def approach_run(rtr) -> Result:
    return simulate(_approach_scenario(rtr, 20.0))


def test_paper_contact_meets_the_targets(contact_run: Result) -> None:
    r = contact_run
    e = r.p - r.p_d
    norm = np.linalg.norm(e, axis=1)
    assert norm[0] == pytest.approx(3.0, abs=1e-9)  # starts 3 m below the helix
    assert norm[r.t >= 3.0].max() < 1e-3
    late = r.t >= 5.0
    assert np.abs(e[late]).max() < 1e-6
    assert np.abs(r.f - r.f_d)[late].max() < 1e-4
    assert np.all(r.phase == CONTACT)
    assert np.abs(r.phi).max() <= 1e-9
    assert r.meta["status"] == "ok"


def test_lyapunov_function_never_increases_in_contact(contact_run: Result) -> None:
    """Section 5.1: V̇ = −sᵀK_d s − βγ e_F² ≤ 0 with constant f_d; check it numerically."""
    V = contact_run.V
    increase = np.diff(V) - (1e-9 * V[:-1] + 1e-20)
    assert increase.max() <= 0.0
    assert V[-1] < 1e-12 * V[0]  # and it really decreases, by many orders of magnitude


def test_paper_approach_meets_the_targets(approach_run: Result) -> None:
    r = approach_run
    kinds = [e["kind"] for e in r.meta["events"]]
    assert "contact" in kinds and "near" in kinds
    assert "release" not in kinds  # the surface never had to pull
    impacts = [e for e in r.meta["events"] if e["kind"] == "impact"]
    assert len(impacts) == 1 and impacts[0]["speed"] < 0.3
    contact = r.phase == CONTACT
    t_contact = r.t[np.argmax(contact)]
    assert np.all(contact[r.t >= t_contact])  # stays in contact once there
    assert r.f[contact].min() >= 0.0
    assert np.abs(r.phi[contact]).max() <= 1e-9
    # the tool starts inside the cylinder (Φ of eq. 26 negative), on the free side
    assert r.phi[0] == pytest.approx(0.4 - np.hypot(0.1, 0.1), abs=1e-12)
    end = r.t >= r.t[-1] - 1.0
    assert np.abs((r.p - r.p_d)[end]).max() < 1e-6
    assert np.abs(r.f - r.f_d)[end].max() < 1e-4
    # near phase: f_d = max(P·f, 0) with the measured f = 0 before contact
    assert np.all(r.f_d[r.phase == 1] == 0.0)


def test_phases_switch_at_the_documented_distances(approach_run: Result) -> None:
    r = approach_run
    free, near = r.phase == 0, r.phase == 1
    assert r.phi[free].min() > 0.05
    assert r.phi[near].max() <= 0.05 and r.phi[near].min() > 1e-5


@pytest.mark.parametrize("which", ["contact", "approach"])
def test_fast_loop_equals_the_reference_step(rtr, which: str, monkeypatch) -> None:
    """The fast step (one Pinocchio pass, scalar constraint algebra, forwardDynamics) and the
    straightforward one (separate calls, general algebra, dense KKT) give the same run."""
    make = _contact_scenario if which == "contact" else _approach_scenario
    duration = 0.3 if which == "contact" else 1.2  # the approach run reaches contact at 0.9 s
    fast = simulate(make(rtr, duration))
    ref = oracle_run(monkeypatch, make(rtr, duration))
    assert [e["kind"] for e in fast.meta["events"]] == [e["kind"] for e in ref.meta["events"]]
    np.testing.assert_allclose(fast.q, ref.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.v, ref.v, rtol=0, atol=1e-7)
    np.testing.assert_allclose(fast.f, ref.f, rtol=0, atol=1e-6 * (1 + np.abs(ref.f).max()))
    np.testing.assert_array_equal(fast.phase, ref.phase)


def _panda_plane_scenario(duration: float, **sim) -> Scenario:
    """A 7-joint arm (redundant CLIK, posture term) tracing a circle on the plane z = 0.3 m."""
    panda = load_robot("panda")
    circle = Circle(center=(0.4, 0.1, 0.3), radius=0.1, normal=(0, 0, 1), omega=1.0)
    seed = np.array([0, -0.3, 0, -2.2, 0, 1.9, 0.785])
    return Scenario(
        robot=panda,
        surfaces=[Plane(point=(0, 0, 0.3), normal=(0, 0, 1))],
        path=circle,
        q0=inverse_kinematics(panda, circle.position(0.0), seed=seed),
        control=ControlSettings(supervisor=False),
        sim=SimSettings(duration=duration, **sim),
    )


def _groove_scenario(robot, duration: float, **sim) -> Scenario:
    """k = 2: the groove between the plane z = 10 and the cylinder r = 0.4, model mass × 1.1."""
    q0 = inverse_kinematics(robot, np.array([0.4, 0.0, 10.0]), seed=np.array([0.0, 9.0, 2.0]))
    return Scenario(
        robot=robot,
        surfaces=[Cylinder(0.4), Plane(point=(0, 0, 10), normal=(0, 0, -1))],
        path=Circle(center=(0, 0, 10), radius=0.4, normal=(0, 0, 1), omega=1.0),
        q0=q0,
        control=ControlSettings(supervisor=False, f_d=(10.0, 5.0), mass_factor=1.1),
        sim=SimSettings(duration=duration, **sim),
    )


@pytest.mark.parametrize("which", ["panda_plane", "groove_mass_error"])
def test_fast_loop_equals_the_reference_step_beyond_the_paper(rtr, which: str, monkeypatch) -> None:
    """The same equality for a redundant 7-joint arm on a plane, and for two stacked surfaces
    (k = 2: general constraint algebra, the k × k loop solve) with a controller model error."""
    sc = _panda_plane_scenario(0.3) if which == "panda_plane" else _groove_scenario(rtr, 0.3)
    fast, ref = simulate(sc), oracle_run(monkeypatch, sc)
    np.testing.assert_allclose(fast.q, ref.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.v, ref.v, rtol=0, atol=1e-7)
    np.testing.assert_allclose(fast.u, ref.u, rtol=0, atol=1e-7 * (1 + np.abs(ref.u).max()))
    np.testing.assert_allclose(fast.f, ref.f, rtol=0, atol=1e-6 * (1 + np.abs(ref.f).max()))
    assert np.abs(fast.f).min() > 1.0  # in contact, pressing, the whole run


def test_user_defined_surface_and_path_run_and_save(rtr, tmp_path, monkeypatch) -> None:
    """A FunctionSurface (the paper's cylinder by hand) and a FunctionPath (the helix of eq. 25
    by hand, derivatives by finite differences): the fast loop (surface and path in Python,
    the rest compiled) equals the reference step, and the result can be saved and loaded."""
    from hybrid_force import FunctionPath, FunctionSurface, load_result

    surface = FunctionSurface(
        phi=lambda p: p[0] ** 2 + p[1] ** 2 - 0.16,
        gradient=lambda p: np.array([2 * p[0], 2 * p[1], 0.0]),
        hessian=lambda p: np.diag([2.0, 2.0, 0.0]),
    )
    path = FunctionPath(lambda t: np.array([0.4 * np.cos(t), 0.4 * np.sin(t), 10 + t / 10]))
    q0 = inverse_kinematics(rtr, np.array([0.4, 0.0, 7.0]), seed=np.array([0.0, 6.0, 2.0]))

    sc = Scenario(
        robot=rtr,
        surfaces=[surface],
        path=path,
        q0=q0,
        control=ControlSettings(supervisor=False),
        sim=SimSettings(duration=0.3),
    )
    fast, ref = simulate(sc), oracle_run(monkeypatch, sc)
    np.testing.assert_allclose(fast.q, ref.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.f, ref.f, rtol=0, atol=1e-6 * (1 + np.abs(ref.f).max()))
    assert np.abs(fast.phi).max() <= 1e-12  # stays on the surface
    assert fast.meta["path"]["type"] == "function"
    fast.save(tmp_path / "run.npz")
    back = load_result(tmp_path / "run.npz")
    np.testing.assert_array_equal(back.q, fast.q)
    assert back.meta["path"]["type"] == "function"


def test_rk4_integrator_also_converges(rtr) -> None:
    r = simulate(_contact_scenario(rtr, 4.0, integrator="rk4"))
    assert np.linalg.norm(r.p - r.p_d, axis=1)[-1] < 1e-9
    assert abs(r.f[-1] - r.f_d[-1]) < 1e-6


def test_joint_normalization_reproduces_the_paper_literally(rtr) -> None:
    """With the paper's unit joint-space row J_Φn, f is a generalised force, not newtons:
    f_paper = ‖n̂ᵀJ‖ f_newton. Both laws converge to their own f_d."""
    r = simulate(_contact_scenario(rtr, 4.0, normalization="joint"))
    assert abs(r.f[-1] - 10.0) < 1e-6
    assert np.linalg.norm(r.p - r.p_d, axis=1)[-1] < 1e-9


def test_two_stacked_surfaces_groove(rtr) -> None:
    """A tool in the groove of a plane z = 10 and the cylinder r = 0.4: k = 2 rows."""
    q0 = inverse_kinematics(rtr, np.array([0.4, 0.0, 10.0]), seed=np.array([0.0, 9.0, 2.0]))
    circle = Circle(center=(0, 0, 10), radius=0.4, normal=(0, 0, 1), omega=1.0)
    sc = Scenario(
        robot=rtr,
        surfaces=[Cylinder(0.4), Plane(point=(0, 0, 10), normal=(0, 0, -1))],
        path=circle,
        q0=q0,
        control=ControlSettings(supervisor=False, f_d=(10.0, 5.0)),
        sim=SimSettings(duration=3.0),
    )
    r = simulate(sc)
    assert r.f.shape == (len(r.t), 2)
    np.testing.assert_allclose(r.f[-1], [10.0, 5.0], atol=1e-6)
    assert np.abs(r.phi).max() <= 1e-9
    assert np.linalg.norm(r.p[-1] - r.p_d[-1]) < 1e-9


@pytest.mark.parametrize("factor", [0.9, 1.1])
def test_model_mismatch_degrades_but_stays_bounded(rtr, factor: float) -> None:
    exact = simulate(_contact_scenario(rtr, 4.0))
    sc = _contact_scenario(rtr, 4.0)
    sc = Scenario(
        **{**sc.__dict__, "control": ControlSettings(supervisor=False, mass_factor=factor)}
    )
    r = simulate(sc)
    err = np.linalg.norm(r.p - r.p_d, axis=1)[-1]
    ferr = abs(r.f[-1] - r.f_d[-1])
    assert err > 100 * np.linalg.norm(exact.p - exact.p_d, axis=1)[-1]  # it degrades
    assert err < 1e-2 and ferr < 5.0  # but stays bounded


def test_runaway_stops_with_a_partial_failed_result(rtr, tmp_path) -> None:
    sc = _contact_scenario(rtr, 2.0, max_velocity=5.0)  # the 6.3 start needs > 5 m/s
    with pytest.raises(RunFailedError) as info:
        simulate(sc)
    assert info.value.reason == "diverged"
    partial = info.value.result
    assert partial is not None and partial.meta["status"] == "failed"
    assert 0 < len(partial.t) < 2001
    assert "runaway" in str(info.value) and "t =" in str(info.value)
    path = partial.save(tmp_path / "failed.npz")
    assert Result.load(path).meta["status"] == "failed"


def test_result_round_trip_of_a_real_run(rtr, tmp_path) -> None:
    with pytest.warns(RunWarning, match="never touched the surface"):  # 0.3 s: still above it
        r = simulate(_approach_scenario(rtr, 0.3))
    back = Result.load(r.save(tmp_path / "r.npz"))
    for name in ("t", "q", "v", "q_d", "u", "p", "p_d", "f", "f_d", "phi", "V", "phase"):
        np.testing.assert_array_equal(getattr(back, name), getattr(r, name))
    assert back.meta["events"] == r.meta["events"]


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [
        ({"dt": 0.0}, "dt"),
        ({"dt": -1e-3}, "dt"),
        ({"dt": 1.0, "duration": 0.5}, "larger"),
        ({"duration": 0.0}, "duration"),
        ({"integrator": "leapfrog"}, "integrator"),
    ],
)
def test_bad_time_settings_are_rejected_up_front(kwargs: dict, word: str) -> None:
    with pytest.raises(BadInputError, match=word):
        SimSettings(**kwargs)


def test_wrong_branch_is_detected_recorded_and_warned(rtr, monkeypatch) -> None:
    """Issue 5's second trap: Q removes every error along J_Φn, so an arm on the mirrored RTR
    elbow (q3 → −q3) can never reach a q_d on the other branch; the controller must say so."""
    import hybrid_force.control.supervisor as supervisor

    p0 = np.array([0.4, 0.0, 10.0])  # on the cylinder and on the helix at t = 0
    mirrored = inverse_kinematics(rtr, p0, seed=np.array([0.0, 11.0, -2.0]))
    upright = inverse_kinematics(rtr, p0, seed=np.array([0.0, 9.0, 2.0]))
    assert mirrored[2] < 0 < upright[2]  # the two elbow branches of the same tip position
    monkeypatch.setattr(supervisor, "inverse_kinematics", lambda *a, **k: upright.copy())
    sc = Scenario(
        robot=rtr,
        surfaces=[Cylinder(0.4)],
        path=paper_helix(),
        q0=mirrored,
        control=ControlSettings(supervisor=False),
        sim=SimSettings(duration=2.5),
    )
    with pytest.warns(RunWarning, match="branch"):  # the run's one channel of warnings
        r = simulate(sc)
    note = next(w for w in r.meta["warnings"] if "branch" in w)
    assert note.startswith("at t = ") and "had not halved since t = " in note
    branch = [e for e in r.meta["events"] if e["kind"] == "branch"]
    assert len(branch) == 1 and 1.0 <= branch[0]["t"] <= 2.5
    assert np.linalg.norm(r.p[-1] - r.p_d[-1]) > 1.0  # the error really persists


def test_model_error_offset_is_not_mistaken_for_a_branch(rtr) -> None:
    """With 20 % too light a model and soft gains the tip settles ~0.1 m off along the cylinder
    axis (no integral action against mis-modelled gravity): an error along the surface, which
    the law can see, so no 'branch' event and no warning (warnings are errors in the suite)."""
    sc = _contact_scenario(rtr, 4.0)
    control = ControlSettings(supervisor=False, mass_factor=0.8, kd_rate=10.0, Lambda=2.0)
    r = simulate(Scenario(**{**sc.__dict__, "control": control}))
    offset = np.linalg.norm(r.p[-1] - r.p_d[-1])
    g = 9.81
    assert offset == pytest.approx((1 - 0.8) * g / (0.8 * 10.0 * 2.0), rel=0.05)  # (1−f)g/(fκΛ)
    assert not [e for e in r.meta["events"] if e["kind"] == "branch"]


def test_off_axis_circle_error_is_first_order_in_dt(rtr) -> None:
    """On a path whose joint accelerations do not vanish (a circle on the plane z = 5 off the
    base axis) a small steady error remains; it halves with dt, so it is the O(dt) error of
    the explicit integration of the plant, not a missing term of the control law."""
    circle = Circle(center=(0.5, 0.3, 5.0), radius=0.3, normal=(0, 0, 1), omega=0.5)
    q0 = inverse_kinematics(rtr, circle.position(0.0), seed=np.array([0.3, 5.0, 1.0]))
    errors = []
    for dt in (1e-3, 5e-4):
        sc = Scenario(
            robot=rtr,
            surfaces=[Plane(point=(0, 0, 5.0), normal=(0, 0, 1))],
            path=circle,
            q0=q0,
            control=ControlSettings(supervisor=False),
            sim=SimSettings(duration=5.0, dt=dt),
        )
        r = simulate(sc)
        errors.append(np.linalg.norm(r.p[-1] - r.p_d[-1]))
    assert 1e-7 < errors[0] < 1e-4
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.1)


def test_stacked_surfaces_with_an_approach_are_refused(rtr) -> None:
    """Contact with a subset of stacked surfaces is not implemented: refused when the
    Scenario is built, before any run."""
    q0 = inverse_kinematics(rtr, np.array([0.4, 0.0, 10.0]), seed=np.array([0.0, 9.0, 2.0]))
    with pytest.raises(BadInputError, match="supervisor = false"):
        Scenario(
            robot=rtr,
            surfaces=[Cylinder(0.4), Plane(point=(0, 0, 10), normal=(0, 0, -1))],
            path=Circle(center=(0, 0, 10), radius=0.4, normal=(0, 0, 1), omega=1.0),
            q0=q0,
            control=ControlSettings(supervisor=True),
            sim=SimSettings(duration=0.1),
        )


# --- a run never lies, and keeps what it computed --------------------------------------------
def _paper_contact(**overrides: object) -> Scenario:
    from hybrid_force.scenario.loader import load_scenario

    return load_scenario(
        Path(__file__).resolve().parents[1] / "scenarios" / "paper_contact.toml", overrides
    )


def test_logged_contact_is_the_real_contact_state() -> None:
    """Kicked off the surface at t = 0 (q̇3 = −3 rad/s), the tool flies and lands again: samples
    logged as contact are exactly those on the surface (geometric check on phi), and the worst
    distance in contact counts contact samples only."""
    result = simulate(_paper_contact(**{"initial.v": [0.0, 0.0, -3.0], "sim.duration": 1.0}))
    kinds = [e["kind"] for e in result.events]
    assert "release" in kinds and "impact" in kinds  # it left and came back
    contact = result.phase == CONTACT
    assert np.all(np.abs(result.phi[contact]) < 1e-9)
    off = result.phi > 1e-6
    assert off.sum() > 10 and not np.any(contact & off)
    summary = result.summary()
    assert summary["worst_constraint_violation"] < 1e-9
    assert summary["contact_at_end"] is True and summary["lost_contact"] is False


def test_lost_contact_without_supervisor_fails_with_its_result() -> None:
    from hybrid_force.errors import RunFailedError

    sc = _paper_contact(**{"initial.v": [0.0, 0.0, 3.0], "control.f_d": 0.0, "sim.duration": 1.0})
    with (
        pytest.warns(UserWarning, match="left the surface"),
        pytest.raises(RunFailedError, match="lost contact") as info,
    ):
        simulate(sc)
    assert info.value.reason == "lost contact"
    result = info.value.result
    assert result.status == "failed" and result.meta["reason"] == "lost contact"
    assert result.n_samples == 1001  # the whole run is kept
    assert result.phi[-1] > sc.control.contact_tol  # really off the surface at the end
    releases = [e["t"] for e in result.events if e["kind"] == "release"]
    assert result.meta["left_at"] == releases[-1]
    assert result.summary()["lost_contact"] is True


@pytest.mark.parametrize(
    ("raised", "error", "reason"),
    [(KeyboardInterrupt, "RunFailedError", "interrupted"),
     (RuntimeError, "RunFailedError", "error")],
)  # fmt: skip
def test_a_run_stopped_by_any_exception_keeps_its_samples(
    raised: type[BaseException], error: str, reason: str
) -> None:
    import hybrid_force.errors as errors

    def stop_half_way(fraction: float) -> None:
        if fraction >= 0.5:
            raise raised("stop")

    with pytest.raises(getattr(errors, error)) as info:
        simulate(_paper_contact(**{"sim.duration": 0.4}), progress=stop_half_way)
    result = info.value.result
    assert type(info.value).__name__ == error and info.value.reason == reason
    assert result.status == "failed" and result.meta["reason"] == reason
    assert 150 < result.n_samples < 250 and np.all(np.diff(result.t) > 0)
    assert np.all(np.isfinite(result.q)) and result.events[-1]["kind"] == reason
    if raised is RuntimeError:
        assert "RuntimeError: stop" in result.meta["error"]


def test_desired_path_failing_mid_run_stops_with_its_result(monkeypatch) -> None:
    """The CLIK raises ReachError when J becomes singular on the desired path (the loader
    refuses such paths when it can find them; a user's FunctionPath can still get there)."""
    from hybrid_force.control.clik import DesiredJointPath
    from hybrid_force.errors import ReachError, RunFailedError

    advance = DesiredJointPath.advance

    def singular_after(self, dt: float) -> None:
        if self.t >= 0.2:
            raise ReachError("the tip Jacobian is singular on the desired path (test)")
        advance(self, dt)

    monkeypatch.setattr(DesiredJointPath, "advance", singular_after)
    with pytest.raises(RunFailedError, match="desired path cannot be followed") as info:
        simulate(_paper_contact(**{"sim.duration": 0.5}))
    assert info.value.reason == "path"
    result = info.value.result
    assert result.status == "failed" and result.meta["reason"] == "path"
    assert result.t[-1] == pytest.approx(0.2) and np.all(np.isfinite(result.q))


# --- a sampled controller: its own rate, its sensors ------------------------------------------
def _sampled(duration: float, *, dt: float = 1e-3, rate: float | None = None, **sensor) -> Result:
    import dataclasses

    from hybrid_force.sim.sensors import SensorSettings

    sc = _paper_contact(**{"sim.duration": duration, "sim.dt": dt})
    control = dataclasses.replace(sc.control, rate=rate)
    return simulate(dataclasses.replace(sc, control=control, sensor=SensorSettings(**sensor)))


def _settled_errors(result: Result) -> tuple[np.ndarray, float]:
    """Largest |p − p_d| per axis [m] and |f − f_d| [N] for t ≥ 5 s (true force)."""
    late = result.t >= 5.0
    return np.abs(result.p - result.p_d)[late].max(axis=0), float(
        np.abs(result.f - result.f_d)[late].max()
    )


def test_a_1khz_controller_on_a_10khz_plant_meets_the_targets() -> None:
    """Section 6.3, plant at dt = 0.1 ms, controller at 1 kHz (its torque held 10 steps)."""
    result = _sampled(6.0, dt=1e-4, rate=1000.0)
    assert result.meta["settings"]["control_rate"] == pytest.approx(1000.0)
    pos, force = _settled_errors(result)
    assert np.all(pos <= 1e-6) and force <= 1e-3
    # zero-order hold: the command changes only at ticks, every 10 plant steps
    changes = np.flatnonzero(np.any(np.diff(result.u, axis=0) != 0.0, axis=1)) + 1
    assert changes.size > 100 and np.all(changes % 10 == 0)


def test_force_measured_one_control_period_late_meets_the_targets() -> None:
    result = _sampled(6.0, force_delay=1)
    pos, force = _settled_errors(result)
    assert np.all(pos <= 1e-6) and force <= 1e-3
    # the measured force is the true one a period (and a plant step) earlier
    np.testing.assert_array_equal(result.f_meas[100:], result.f[98:-2])


def test_a_biased_force_sensor_shifts_the_true_force_by_the_bias() -> None:
    """The law regulates what it measures: f_meas → f_d, so the true force → f_d − bias."""
    bias = 1.5
    # the true force then misses f_d by the bias, above the 1 N tolerance: reported
    with pytest.warns(RunWarning, match="the force error did not settle: RMS .* = 1.5 N"):
        result = _sampled(6.0, force_bias=bias)
    late = result.t >= 5.0
    np.testing.assert_allclose(result.f_meas[late], 10.0, atol=1e-9)
    np.testing.assert_allclose(result.f[late], 10.0 - bias, atol=1e-9)


def test_noisy_sensing_is_reproducible_from_the_seed() -> None:
    import dataclasses

    from hybrid_force.sim.sensors import SensorSettings

    sc = _paper_contact(**{"sim.duration": 0.3})
    noisy = dataclasses.replace(sc, sensor=SensorSettings(force_noise=0.5, joint_noise=1e-5))
    a, b = simulate(noisy), simulate(noisy)
    c = simulate(dataclasses.replace(noisy, sim=dataclasses.replace(noisy.sim, seed=1)))
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.f_meas, b.f_meas)
    assert not np.array_equal(a.f_meas, c.f_meas)
    assert a.meta["sensor"]["force_noise"] == 0.5 and a.meta["settings"]["seed"] == 0


def test_ideal_sensing_records_the_true_force_as_measured() -> None:
    result = simulate(_paper_contact(**{"sim.duration": 0.05}))
    np.testing.assert_array_equal(result.f_meas, result.f)
    assert result.meta["settings"]["control_rate"] == pytest.approx(1000.0)


def test_a_control_rate_that_is_not_whole_plant_steps_is_refused() -> None:
    import dataclasses

    from hybrid_force.errors import BadInputError

    sc = _paper_contact(**{"sim.duration": 0.05})
    for rate in (300.0, 2000.0):
        with pytest.raises(BadInputError, match=r"control\.rate"):
            dataclasses.replace(sc, control=dataclasses.replace(sc.control, rate=rate))


def test_the_loop_calling_the_law_directly_equals_the_control_sides_command(
    rtr, monkeypatch
) -> None:
    """Exact control on the plant's model: the loop calls the supervisor's command itself
    (ControlSide.law_command), the same run bit for bit as through ControlSide.command; a
    sampled control side has no such shortcut."""
    import hybrid_force.sim.control_side as control_side
    from hybrid_force.sim.control_side import build_control_side

    sc = _contact_scenario(rtr, 0.3)
    exact = build_control_side(sc, None, sc.q0)
    assert exact.law_command is not None and not exact.measured
    import dataclasses

    from hybrid_force.sim.sensors import SensorSettings

    sampled = build_control_side(
        dataclasses.replace(sc, sensor=SensorSettings(force_delay=1)), None, sc.q0
    )
    assert sampled.measured and sampled.law_command is None
    direct = simulate(sc)
    built = control_side.build_control_side

    def without_shortcut(*args: object) -> control_side.ControlSide:
        side = built(*args)
        side.law_command = None
        return side

    monkeypatch.setattr("hybrid_force.sim.loop.build_control_side", without_shortcut)
    through = simulate(sc)
    for name in ("q", "v", "u", "f", "V", "q_d", "p_d"):
        np.testing.assert_array_equal(getattr(direct, name), getattr(through, name))

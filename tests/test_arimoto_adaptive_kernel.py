"""The compiled adaptive law (:class:`AdaptiveArimotoWorkspace`, the kernels of
hybrid_force/control/laws/_arimoto_adaptive_kernels.py around Pinocchio's regressor) against
its numpy oracle (``AdaptiveArimotoLaw`` of tests/oracles/laws.py, the three-pass regressor
of hybrid_force.model.regressor), step by step and over whole runs.

Both sides are the same formulas in a different order (and Y in two passes instead of three),
so they agree to round-off: max|fast − reference| ≤ 1e-12 · scale per law call and update, the
scale being the largest magnitude of the reference or, where a result cancels, of the terms it
is made of; whole runs (0.2 s, each side its own controller: compiled or reference CLIK,
constraint, plant step) to ≤ 1e-10 · scale in q, v, u, f and the logged estimates.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from oracles.laws import AdaptiveArimotoLaw, oracle_of
from oracles.run import oracle_run
from oracles.terms import constraint_terms

from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.arimoto import make_gains
from hybrid_force.control.laws.arimoto_adaptive import AdaptiveArimotoWorkspace, make_adaptation
from hybrid_force.control.laws.base import Desired, LawContext, LawInput, build_law
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.geometry.builtin_surfaces import Plane, Sphere
from hybrid_force.model.robot import Robot
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

RTOL = 1e-12  # one call or update, relative to the compared array's scale
RUN_RTOL = 1e-10  # whole runs
ARMS = ("rtr", "ur5", "panda")
TWO_PLANES = (
    Plane(point=(0, 0, 0.3), normal=(0, 0, 1)),
    Plane(point=(0.5, 0, 0), normal=(1, 0, 0)),
)
WORST: dict[str, float] = {}  # largest measured |fast − reference| / scale per quantity


def _close(what: str, got: object, ref: object, scale: float | np.ndarray | None = None) -> None:
    """max|got − ref| / scale ≤ RTOL (scale: max|ref| unless given; may be per entry)."""
    got_a, ref_a = np.asarray(got, dtype=float), np.asarray(ref, dtype=float)
    assert got_a.shape == ref_a.shape, f"{what}: shape {got_a.shape} != {ref_a.shape}"
    assert np.all(np.isfinite(got_a)) and np.all(np.isfinite(ref_a)), what
    if scale is None:
        scale = float(np.abs(ref_a).max(initial=0.0))
    err = np.abs(got_a - ref_a)
    rel = float(
        np.max(np.where(err == 0, 0.0, err / np.where(scale > 0, scale, 1e-300)), initial=0)
    )
    WORST[what] = max(WORST.get(what, 0.0), rel)
    assert rel <= RTOL, f"{what}: max|fast − reference| / scale = {rel:.3g} > {RTOL:g}"


@pytest.fixture(scope="module")
def arms(rtr: Robot, ur5: Robot, panda: Robot) -> dict[str, Robot]:
    return {"rtr": rtr, "ur5": ur5, "panda": panda}


def _laws(
    robot: Robot, k: int, beta: float, rng: np.random.Generator
) -> tuple[AdaptiveArimotoLaw, AdaptiveArimotoWorkspace]:
    """Both forms with the same gains and adaptation (a model 10 % light, θ̂(0) = 0.9 θ)."""
    n = robot.nv
    q0 = robot.neutral()
    M0 = 0.9 * robot.mass_matrix(q0)
    G = rng.normal(size=(n, n))
    Kd = 20.0 * M0 + 0.1 * (G @ G.T)
    gains = make_gains(0.5 * (Kd + Kd.T), 10.0, beta, 20.0, n)
    adaptation = make_adaptation(robot, q0, M0, gains, 0.9, 5.0)
    return (
        AdaptiveArimotoLaw(robot, gains, adaptation),
        AdaptiveArimotoWorkspace(robot, k, gains, adaptation),
    )


def _u0_scale(law: AdaptiveArimotoLaw, q: np.ndarray, v: np.ndarray, trace, force) -> float:
    """Size of the terms u0 is a sum of: each Y_ij θ̂_j, K_d s and Aᵀ(f_d − γ e_F)."""
    Y = law.regressor(q, v, trace.qdot_r, trace.qddot_r0)
    Kd = law.gains.Kd
    return float(
        (np.abs(Y) @ np.abs(law.theta)).max()
        + (np.abs(Kd) @ np.abs(trace.s)).max()
        + (0.0 if force is None else np.abs(force).max())
    )


@pytest.mark.parametrize("beta", [0.0, 0.01])
@pytest.mark.parametrize("k", [1, 2])
@pytest.mark.parametrize("arm", ARMS)
def test_compiled_law_equals_the_reference_over_steps(
    arms: dict[str, Robot], arm: str, k: int, beta: float
) -> None:
    """Free-space and hybrid calls interleaved (with and without the approach term), each
    followed by an update at a random force, on both forms: u0, B, V, σ, the trace and θ̂
    after every update agree; θ̂ moves (dt = 20 ms, so the updates are not negligible)."""
    robot = arms[arm]
    rng = np.random.default_rng(2024 + 10 * k + int(100 * beta))
    constraint = Constraint([Sphere(0.3, center=(0.2, 0.1, 0.4))] if k == 1 else list(TWO_PLANES))
    ref, fast = _laws(robot, k, beta, rng)
    n, dt = robot.nv, 0.02
    lower, upper = robot.position_limits
    moved = np.zeros_like(ref.theta)  # Σ |Δθ̂| of the reference: the scale of θ̂'s round-off
    for step in range(9):
        q = rng.uniform(np.maximum(lower, -3.0), np.minimum(upper, 3.0))
        v = rng.uniform(-1, 1, n)
        terms = robot.terms(q, v, robot.new_data())
        cons = constraint_terms(constraint, terms, v)
        desired = Desired(
            q=q + rng.uniform(-0.1, 0.1, n), qd=rng.uniform(-1, 1, n), qdd=rng.uniform(-2, 2, n)
        )
        e_q = q - desired.q
        if step % 3 == 2:
            e_F = f_d = np.zeros(k)
            got = fast.free_space(LawInput(terms, v, e_q, desired))
            want = ref.free_space(LawInput(terms, v, e_q, desired))
            force = None
            assert got.B is None and want.B is None
        else:
            e_F, f_d = rng.uniform(-1, 1, k), rng.uniform(0, 20, k)
            approach = rng.uniform(-0.5, 0.5, k) if step % 3 == 1 else None
            got = fast.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d, approach))
            want = ref.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d, approach))
            force = cons.A.T @ (f_d - fast.gains.gamma * e_F)
            if beta == 0.0:
                assert got.B is None and want.B is None
            else:
                assert got.B is not None and want.B is not None
                _close("B", got.B, want.B)
        trace, ref_trace = fast.trace(e_q, e_F, f_d), ref.trace(e_q, e_F, f_d)
        _close("u0", got.u0, want.u0, _u0_scale(ref, q, v, ref_trace, force))
        _close("V", fast.V, ref.V)
        assert trace.V == fast.V
        _close("sigma", fast.sigma, ref.sigma)
        for name in ("e_q", "s", "s0", "s1", "e_F", "qdot_r", "qddot_r0", "f_d"):
            _close(f"trace.{name}", getattr(trace, name), getattr(ref_trace, name))
        if ref_trace.qddot_r_f is None:
            assert trace.qddot_r_f is None
        else:
            _close("trace.qddot_r_f", trace.qddot_r_f, ref_trace.qddot_r_f)
        f = rng.uniform(5, 15, k)
        before = ref.theta.copy()
        fast.update(dt, f)
        ref.update(dt, f)
        moved += np.abs(ref.theta - before)
        _close("theta", fast.theta, ref.theta, np.abs(ref.theta) + moved)
    adapted = ref.adaptation.adapted
    assert np.all(moved[adapted] > 0) and np.all(moved[~adapted] == 0)
    np.testing.assert_array_equal(fast.theta[~adapted], ref.adaptation.theta0[~adapted])


def test_update_before_any_call_does_nothing(rtr: Robot) -> None:
    _, fast = _laws(rtr, 1, 0.01, np.random.default_rng(0))
    theta = fast.theta.copy()
    fast.update(1e-3, np.ones(1))
    np.testing.assert_array_equal(fast.theta, theta)


def test_the_factory_builds_the_compiled_law_and_its_oracle_the_same_settings(rtr: Robot) -> None:
    q0 = np.array([0.3, 6.0, 0.5])
    settings = ControlSettings(law="arimoto_adaptive")
    M0 = rtr.mass_matrix(q0)
    gains = make_gains(20.0 * M0, 10.0, 0.01, 20.0, rtr.nv)
    constraint = Constraint([Sphere(0.3)])
    law = build_law(LawContext(rtr, constraint, settings, gains, M0, q0, 1e-3))
    assert type(law) is AdaptiveArimotoWorkspace
    oracle = oracle_of(law, rtr)
    assert type(oracle) is AdaptiveArimotoLaw
    assert oracle.info() == law.info()


def _run(name: str, reference: pytest.MonkeyPatch | None, **overrides: object):
    """The run, with the oracle plant and the reference controller when given a monkeypatch."""
    scenario = load_scenario(
        f"scenarios/{name}.toml",
        overrides={"control.law": "arimoto_adaptive", "sim.duration": 0.2, **overrides},
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ur5_plane's start saturates two joints
        return simulate(scenario) if reference is None else oracle_run(reference, scenario)


@pytest.mark.parametrize(
    "name, overrides",
    [
        ("paper_contact", {"sim.model_mass_factor": 0.9}),
        ("paper_approach", {"sim.model_mass_factor": 0.9, "sim.duration": 1.0}),
        ("ur5_plane", {"sim.model_mass_factor": 0.9, "sim.duration": 0.6}),  # contact at 0.3 s
        ("panda_pipe_tilt", {"sim.model_mass_factor": 0.9}),
    ],
)
def test_whole_runs_compiled_equal_the_reference(
    name: str, overrides: dict, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Compiled controller and plant against the reference ones (oracle_run): q, v, u,
    f and the estimates θ̂ agree to 1e-10 of their largest value over the run."""
    fast, ref = _run(name, None, **overrides), _run(name, monkeypatch, **overrides)
    assert fast.meta["status"] == ref.meta["status"] == "ok"
    np.testing.assert_array_equal(fast.phase, ref.phase)
    assert fast.law_log.shape == ref.law_log.shape and fast.law_log.shape[1] > 0
    for field in ("q", "v", "u", "f", "law_log"):
        got, want = getattr(fast, field), getattr(ref, field)
        err = float(np.abs(got - want).max())
        scale = float(np.abs(want).max())
        WORST[f"run.{name}.{field}"] = err / scale if scale > 0 else err
        assert err <= RUN_RTOL * scale, f"{name}.{field}: {err:.3g} > {RUN_RTOL:g} × {scale:.3g}"
    # the estimates moved, and the runs reached contact: the update and B were compared too
    assert np.abs(ref.law_log[-1] - ref.law_log[0]).max() > 0
    assert np.abs(ref.f).max() > 0


def test_compiled_law_on_a_non_euclidean_arm(rtr_urdf: Path) -> None:
    """rtr.urdf's continuous q1 as Pinocchio's unit complex number (nq = 4, nv = 3): q = q_d ⊕
    e_q by ``pinocchio.integrate`` (not the kernel's addition), the rest as on Euclidean arms."""
    model = pin.buildModelFromUrdf(str(rtr_urdf))
    robot = Robot(model, name="rtr_rubz", urdf_path=rtr_urdf, tip="tip")
    assert robot.euclidean is False and (robot.nq, robot.nv) == (4, 3)
    rng = np.random.default_rng(7)
    ref, fast = _laws(robot, 1, 0.01, rng)
    constraint = Constraint([Sphere(0.3, center=(0.2, 0.1, 0.4))])
    for step in range(4):
        q = pin.integrate(model, robot.neutral(), rng.uniform(-1, 1, 3))
        v = rng.uniform(-1, 1, 3)
        terms = robot.terms(q, v, robot.new_data())
        cons = constraint_terms(constraint, terms, v)
        q_d = pin.integrate(model, q, rng.uniform(-0.1, 0.1, 3))
        desired = Desired(q=q_d, qd=rng.uniform(-1, 1, 3), qdd=rng.uniform(-2, 2, 3))
        e_q = pin.difference(model, q_d, q)
        e_F, f_d = rng.uniform(-1, 1, 1), rng.uniform(0, 20, 1)
        if step % 2:
            got, want = (
                fast.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d)),
                ref.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d)),
            )
            assert got.B is not None and want.B is not None
            _close("rubz.B", got.B, want.B)
            force = cons.A.T @ (f_d - fast.gains.gamma * e_F)
        else:
            got, want = (
                fast.free_space(LawInput(terms, v, e_q, desired)),
                ref.free_space(LawInput(terms, v, e_q, desired)),
            )
            force = None
        ref_trace = ref.trace(e_q, e_F, f_d)
        _close("rubz.u0", got.u0, want.u0, _u0_scale(ref, q, v, ref_trace, force))
        _close("rubz.V", fast.V, ref.V)
        f = rng.uniform(5, 15, 1)
        fast.update(0.02, f)
        ref.update(0.02, f)
        _close("rubz.theta", fast.theta, ref.theta)


def test_the_parameter_layout_is_the_kernels() -> None:
    """The workspace fills the kernels' parameter vector by position (no Numba at build)."""
    from hybrid_force.control.laws import _arimoto_adaptive_kernels as kernels
    from hybrid_force.control.laws import arimoto_adaptive

    layout = [kernels.LAMBDA, kernels.BETA, kernels.GAMMA, kernels.EUCLIDEAN, kernels.ENERGY]
    assert [*layout, kernels.SIGMA, kernels.Z_MIN] == list(range(7))
    assert arimoto_adaptive._SIGMA == kernels.SIGMA

"""The compiled raibert_craig law (RaibertCraigWorkspace, control/laws/_raibert_craig_kernels.py)
against its numpy oracle (RaibertCraigLaw of tests/oracles/laws.py).

1. One step on random states of the RTR, the UR5 and the Panda (fixed seed), in free space,
   near the surface (the approach torque) and in contact, with one surface and with two
   stacked planes, both forms, both feed-forwards, with and without the projection P, and
   k_p = 0 (no feed-through): u0, B and u_pos agree to ≤ 1e-12 relative.
2. At a zero pivot of J Jᵀ the kernel takes the SVD's pseudo-inverse, as the oracle.
3. Whole 0.2 s runs, compiled against the oracle controller on the reference plant and
   against the compiled loop with the law's oracle alone, agree to ≤ 1e-10 in q, u, f.

Relative: max|fast − reference| ≤ tolerance · max|reference| of the compared array.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from oracles.laws import RaibertCraigLaw
from oracles.run import oracle_run
from oracles.terms import constraint_terms, robot_terms

import hybrid_force.control.laws.raibert_craig as rc
from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.laws.base import Desired, LawInput
from hybrid_force.control.laws.raibert_craig import RaibertCraigGains, RaibertCraigWorkspace
from hybrid_force.geometry.builtin_surfaces import Plane, Sphere
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.model.robot import Robot, RobotTerms
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

SCENARIOS = Path(__file__).parents[1] / "scenarios"
ARMS = ("rtr", "ur5", "panda")
RTOL = 1e-12
RUN_RTOL = 1e-10
TWO_PLANES = (Plane((0.0, 0.0, 0.3), (0.0, 0.1, 1.0)), Plane((0.4, 0.0, 0.0), (1.0, 0.2, 0.1)))
WORST: dict[str, float] = {}  # largest |fast − reference| / scale per quantity (inspect)


@pytest.fixture(scope="module")
def arms(rtr: Robot, ur5: Robot, panda: Robot) -> dict[str, Robot]:
    return {"rtr": rtr, "ur5": ur5, "panda": panda}


def _close(what: str, got: np.ndarray, ref: np.ndarray, scale: float) -> None:
    assert got.shape == ref.shape, f"{what}: shape {got.shape} != {ref.shape}"
    assert np.all(np.isfinite(got)) and np.all(np.isfinite(ref)), what
    err = float(np.abs(got - ref).max(initial=0.0))
    rel = err / scale if scale > 0 else (0.0 if err == 0 else math.inf)
    WORST[what] = max(WORST.get(what, 0.0), rel)
    assert err <= RTOL * scale, (
        f"{what}: max|fast − reference| = {err:.3g} > {RTOL:g} × {scale:.3g}"
    )


def _spd(rng: np.random.Generator, m: int, size: float) -> np.ndarray:
    G = rng.normal(size=(m, m))
    K = G @ G.T + m * np.eye(m)
    return size * 0.5 * (K + K.T) / m


def _gains(
    robot: Robot, rng: np.random.Generator, form: str, feedforward: str, decouple: bool, kp: float
) -> RaibertCraigGains:
    """Random symmetric positive definite gains (the algebra is general, not K = κ M(q₀))."""
    n = robot.nv
    return RaibertCraigGains(
        form=form,
        feedforward=feedforward,
        position_rate=10.0,
        damping_rate=20.0,
        Kq=_spd(rng, n, 200.0),
        Dq=_spd(rng, n, 30.0),
        Kx=_spd(rng, 3, 2000.0),
        Dx=_spd(rng, 3, 300.0),
        kp=kp,
        ki=30.0,
        decouple=decouple,
    )


def _state(
    robot: Robot, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, RobotTerms, Desired]:
    """q uniform within the joint limits (±π when unbounded), v in [−2, 2], a random desired."""
    lo, hi = robot.position_limits
    lo, hi = np.where(np.isfinite(lo), lo, -math.pi), np.where(np.isfinite(hi), hi, math.pi)
    q = lo + (hi - lo) * rng.random(robot.nq)
    v = rng.uniform(-2.0, 2.0, robot.nv)
    terms = robot.terms(q, v, robot.new_data())
    n = robot.nv
    desired = Desired(
        q=q + rng.uniform(-0.1, 0.1, n),
        qd=rng.uniform(-1, 1, n),
        qdd=rng.uniform(-2, 2, n),
        p=terms.p + rng.uniform(-0.05, 0.05, 3),
        pd=rng.uniform(-0.5, 0.5, 3),
        pdd=rng.uniform(-2, 2, 3),
    )
    return q, v, terms, desired


def _surfaces(k: int, python_gradients: bool) -> tuple[Surface, ...]:
    if k == 2:
        return TWO_PLANES
    if python_gradients:  # the sphere of radius 0.3 m as a function: ∇Φ in Python
        c = np.array([0.2, 0.1, 0.4])
        return (FunctionSurface(lambda p: float((p - c) @ (p - c)) - 0.09),)
    return (Sphere(0.3, center=(0.2, 0.1, 0.4)),)


def _compare_step(
    fast: RaibertCraigWorkspace,
    ref: RaibertCraigLaw,
    terms: RobotTerms,
    cons: ConstraintTerms | None,
    v: np.ndarray,
    e_q: np.ndarray,
    desired: Desired,
    e_F: np.ndarray,
    f_d: np.ndarray,
    approach: np.ndarray | None,
    what: str,
) -> None:
    if cons is None:
        cmd = fast.free_space(LawInput(terms, v, e_q, desired))
        ref_cmd = ref.free_space(LawInput(terms, v, e_q, desired))
    else:
        cmd = fast.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d, approach))
        ref_cmd = ref.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d, approach))
    _close(f"{what}.u0", cmd.u0, ref_cmd.u0, float(np.abs(ref_cmd.u0).max()))
    _close(f"{what}.u_pos", fast.last_u_pos, ref.last_u_pos, float(np.abs(ref.last_u_pos).max()))
    if ref_cmd.B is None:
        assert cmd.B is None
    else:
        assert cmd.B is not None
        _close(f"{what}.B", cmd.B, ref_cmd.B, float(np.abs(ref_cmd.B).max()))


# --------------------------------------------------------------------------- 1. one step
@pytest.mark.parametrize("decouple", [True, False])
@pytest.mark.parametrize("form", ["corrected", "original"])
@pytest.mark.parametrize("k", [1, 2])
@pytest.mark.parametrize("arm", ARMS)
def test_kernel_equals_the_reference_on_random_states(
    arms: dict[str, Robot], arm: str, k: int, form: str, decouple: bool
) -> None:
    robot = arms[arm]
    rng = np.random.default_rng(3201 + 7 * k)
    for feedforward, kp in (("model", 0.5), ("gravity", 0.0)):
        gains = _gains(robot, rng, form, feedforward, decouple, kp)
        surfaces = _surfaces(k, python_gradients=False)
        fast = RaibertCraigWorkspace(gains, surfaces, 12.0)
        ref = RaibertCraigLaw(gains, surfaces, 12.0)
        con = Constraint(list(surfaces))
        for step in range(12):  # one workspace: free, near and contact calls interleaved
            _, v, terms, desired = _state(robot, rng)
            cons = constraint_terms(con, terms, v)
            e_q = rng.uniform(-0.1, 0.1, robot.nv)
            e_F = rng.uniform(-1, 1, k)
            f_d = rng.uniform(0, 20, k)
            phase = step % 3
            if phase == 0:
                _compare_step(fast, ref, terms, None, v, e_q, desired, e_F, f_d, None, "free")
            elif phase == 1:
                approach = rng.uniform(-0.5, 0.5, k)
                zero = np.zeros(k)
                _compare_step(fast, ref, terms, cons, v, e_q, desired, zero, zero, approach, "near")
            else:
                _compare_step(fast, ref, terms, cons, v, e_q, desired, e_F, f_d, None, "contact")


@pytest.mark.parametrize("arm", ARMS)
def test_kernel_with_gradients_from_python_and_terms_without_packs(
    arms: dict[str, Robot], arm: str
) -> None:
    """A FunctionSurface (∇Φ given to the kernel) and the reference's robot terms (no packs)."""
    robot = arms[arm]
    rng = np.random.default_rng(3202)
    gains = _gains(robot, rng, "corrected", "model", True, 0.5)
    surfaces = _surfaces(1, python_gradients=True)
    fast = RaibertCraigWorkspace(gains, surfaces, 12.0)
    ref = RaibertCraigLaw(gains, surfaces, 12.0)
    con = Constraint(list(surfaces))
    for step in range(6):
        q, v, _, desired = _state(robot, rng)
        terms = robot_terms(robot, q, v)
        cons = constraint_terms(con, terms, v)
        e_q = rng.uniform(-0.1, 0.1, robot.nv)
        approach = rng.uniform(-0.5, 0.5, 1) if step % 2 else None
        e_F, f_d = rng.uniform(-1, 1, 1), rng.uniform(0, 20, 1)
        _compare_step(fast, ref, terms, cons, v, e_q, desired, e_F, f_d, approach, "function")


# --------------------------------------------------------------------------- 2. singular J
def test_a_singular_jacobian_takes_the_pseudo_inverse_of_the_svd(rtr: Robot) -> None:
    """J Jᵀ with a zero pivot: the kernel's J⁺ is the SVD's pseudo-inverse, as the oracle's;
    the workspace returns its numbers in its own arrays, at the singular step and the next."""
    rng = np.random.default_rng(3203)
    gains = _gains(rtr, rng, "original", "model", True, 0.5)
    surfaces = _surfaces(1, python_gradients=False)
    fast = RaibertCraigWorkspace(gains, surfaces, 12.0)
    ref = RaibertCraigLaw(gains, surfaces, 12.0)
    con = Constraint(list(surfaces))
    _, v, terms, desired = _state(rtr, rng)
    cons = constraint_terms(con, terms, v)
    e_q, e_F, f_d = rng.uniform(-0.1, 0.1, 3), np.array([0.3]), np.array([10.0])
    singular = RobotTerms.zeros(3)
    for name in ("M", "C", "g", "nle", "p", "J", "Jdot", "Jdot_v", "pdot"):
        getattr(singular, name)[...] = getattr(terms, name)
    singular.J[2] = 0.0  # the tip cannot move along z: rank 2
    u_pos, u0 = fast.last_u_pos, fast._u0
    _compare_step(fast, ref, singular, cons, v, e_q, desired, e_F, f_d, None, "singular")
    assert fast.last_u_pos is u_pos
    assert fast.hybrid(LawInput(singular, v, e_q, desired, cons, e_F, f_d)).u0 is u0
    _compare_step(fast, ref, terms, cons, v, e_q, desired, e_F, f_d, None, "after singular")


# --------------------------------------------------------------------------- 3. whole runs
RUNS: dict[str, tuple[str, dict[str, object]]] = {
    "paper_contact": ("paper_contact", {}),  # RTR in contact from t = 0
    "paper_contact_original": (
        "paper_contact",
        {
            "control.raibert_craig.form": "original",
            "control.raibert_craig.decouple": False,
            "control.raibert_craig.feedforward": "gravity",
        },
    ),
    "paper_contact_model_mass": ("paper_contact", {"sim.model_mass_factor": 0.9}),
    "paper_contact_sampled": ("paper_contact", {"control.rate": 500.0}),  # B meets a reading
    "ur5_plane": ("ur5_plane", {}),  # UR5 free, then near the plane
    "ur5_plane_contact": (
        "ur5_plane",
        {"initial.tip": [0.5, 0.1, 0.3], "control.supervisor": False},
    ),
    "panda_pipe_tilt": ("panda_pipe_tilt", {}),  # Panda in contact in the pipe, the pose CLIK
}


def _compare_runs(a: object, b: object, what: str) -> None:
    for name in ("q", "u", "f"):
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        assert x.shape == y.shape
        scale = float(np.abs(y).max(initial=0.0))
        err = float(np.abs(x - y).max(initial=0.0))
        WORST[f"{what}.{name}"] = max(WORST.get(f"{what}.{name}", 0.0), err / (scale or 1.0))
        assert err <= RUN_RTOL * scale, f"{what}.{name}: {err:.3g} > {RUN_RTOL:g} × {scale:.3g}"


@pytest.mark.parametrize("name", list(RUNS))
def test_whole_runs_compiled_equal_the_reference(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    file, extra = RUNS[name]
    overrides = {"control.law": "raibert_craig", "sim.duration": 0.2, **extra}
    sc = load_scenario(SCENARIOS / f"{file}.toml", overrides=overrides)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the UR5's first torque reaches its effort limit
        fast = simulate(sc)
        reference = oracle_run(monkeypatch, sc)
        built: list[RaibertCraigLaw] = []

        def numpy_law(*args: object) -> RaibertCraigLaw:  # the compiled loop, the numpy law
            built.append(RaibertCraigLaw(*args))  # type: ignore[arg-type]
            return built[-1]

        monkeypatch.setattr(rc, "RaibertCraigWorkspace", numpy_law)
        law_reference = simulate(sc)
    assert built and type(built[0]) is RaibertCraigLaw
    assert fast.meta["status"] == reference.meta["status"] == "ok"
    if name != "ur5_plane":
        assert float(np.abs(fast.f).max()) > 1.0  # the run is in contact
    _compare_runs(fast, reference, f"{name} vs reference loop")
    _compare_runs(fast, law_reference, f"{name} vs reference law")

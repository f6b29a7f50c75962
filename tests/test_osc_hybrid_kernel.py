"""The compiled osc_hybrid law (OscHybridWorkspace, its kernel) against its numpy oracle
(OscHybridLaw of tests/oracles/laws.py).

1. one step on random states of rtr, ur5 and panda, in free space, near and in contact, on one
   surface (cylinder, sphere, plane, a FunctionSurface whose gradient stays in Python) and on
   two stacked planes (k = 2), both row scalings, k_P = 0 and > 0: every output (u0, B and the
   trace: a, F0, φ, Nᵀτ₀, Λ, J̄) within 1e-12 of the reference's scale;
2. singular configurations: the same SurfaceError with the same message, and an
   M without Cholesky factor solved by LU as the oracle's numpy solve;
3. whole 0.2 s runs (0.4 s for free → near → contact), the compiled law against the reference
   law in the same (compiled) loop, and against the oracle controller on the reference plant:
   q, v, u, f within
   1e-10 of their scale.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from oracles.laws import OscHybridLaw
from oracles.run import oracle_run
from oracles.terms import constraint_terms, robot_terms

import hybrid_force.control.laws.osc_hybrid as osc
from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.base import Desired, LawInput
from hybrid_force.control.laws.osc_hybrid import (
    OscHybridWorkspace,
    OscOptions,
    osc_gains,
)
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.errors import ControlError, SurfaceError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.paths import Circle
from hybrid_force.model.robot import Robot, RobotTerms
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate
from hybrid_force.sim.settings import Scenario, SimSettings

RTOL = 1e-12  # one step, relative to the scale of the reference array
RUN_TOL = 1e-10  # whole runs
WORST: dict[str, float] = {}  # largest |compiled − reference| / scale seen (inspect after a run)


def _close(what: str, got: np.ndarray, ref: np.ndarray) -> None:
    got, ref = np.asarray(got, dtype=float), np.asarray(ref, dtype=float)
    assert got.shape == ref.shape, f"{what}: shape {got.shape} != {ref.shape}"
    assert np.all(np.isfinite(got)) and np.all(np.isfinite(ref)), what
    scale = float(np.abs(ref).max(initial=0.0))
    err = float(np.abs(got - ref).max(initial=0.0))
    rel = err / scale if scale > 0 else (0.0 if err == 0 else math.inf)
    WORST[what] = max(WORST.get(what, 0.0), rel)
    assert err <= RTOL * scale, f"{what}: max|compiled − reference| = {err:.3g}, scale {scale:.3g}"


def _random_state(robot: Robot, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """q uniform within the joint limits (±π for an unbounded joint), v uniform in [−2, 2]."""
    lo, hi = robot.position_limits
    lo, hi = np.where(np.isfinite(lo), lo, -math.pi), np.where(np.isfinite(hi), hi, math.pi)
    return lo + (hi - lo) * rng.random(robot.nq), rng.uniform(-2.0, 2.0, robot.nv)


def _function_sphere(center: np.ndarray, radius: float) -> FunctionSurface:
    """A sphere as a FunctionSurface (no closed form: its ∇Φ is evaluated in Python)."""
    c = np.asarray(center, dtype=float)
    return FunctionSurface(
        lambda p: float((p - c) @ (p - c) - radius * radius),
        lambda p: 2.0 * (p - c),
        lambda p: 2.0 * np.eye(3),
    )


def _surfaces(case: str, p: np.ndarray) -> list:
    """Surfaces through (or within a few mm of) the tip p, of each kind."""
    if case == "cylinder":
        return [Cylinder(radius=float(np.hypot(p[0], p[1])) + 1e-3, axis=(0.0, 0.0, 1.0))]
    if case == "sphere":
        return [Sphere(radius=0.3, center=p - np.array([0.0, 0.1, 0.3]))]
    if case == "plane":
        return [Plane(p + 2e-3, (0.2, -0.3, 1.0))]
    if case == "function":
        return [_function_sphere(p - np.array([0.2, 0.0, 0.25]), 0.32)]
    return [Plane(p, (0.0, 0.0, 1.0)), Plane(p, (1.0, 0.3, 0.0))]  # "edge": k = 2


def _compare_step(robot: Robot, case: str, normalization: str, force_p: float, rng) -> None:
    q, v = _random_state(robot, rng)
    terms = robot_terms(robot, q, v)
    constraint = Constraint(_surfaces(case, terms.p), normalization=normalization)
    gains = osc_gains(OscOptions(force_p=force_p, force_i=7.0, null_omega=3.0), approach_rate=8.0)
    ref, fast = (
        OscHybridLaw(gains, constraint, robot.nv),
        OscHybridWorkspace(gains, constraint, robot.nv),
    )
    n, k = robot.nv, constraint.k
    desired = Desired(
        q=rng.normal(size=n),
        qd=rng.normal(size=n),
        qdd=rng.normal(size=n),
        p=terms.p + 0.05 * rng.normal(size=3),
        pd=rng.normal(size=3),
        pdd=rng.normal(size=3),
    )
    cons = constraint_terms(constraint, terms, v)
    e_q, e_F, f_d = q - desired.q, rng.normal(size=k), 10.0 * rng.random(k)
    for phase in ("free", "near", "contact"):
        if phase == "free":
            c_ref = ref.free_space(LawInput(terms, v, e_q, desired))
            c_fast = fast.free_space(LawInput(terms, v, e_q, desired))
        else:
            approach = rng.normal(size=k) if phase == "near" else None
            c_ref = ref.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d, approach))
            c_fast = fast.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d, approach))
        what = f"{robot.name}/{case}/{phase}"
        _close(f"{what}: u0", c_fast.u0, c_ref.u0)
        assert (c_fast.B is None) == (c_ref.B is None), what
        if c_ref.B is not None:
            assert c_fast.B is not None
            _close(f"{what}: B", c_fast.B, c_ref.B)
        t_ref, t_fast = ref.last, fast.last
        assert t_ref is not None and t_fast is not None
        for name in ("a", "F0", "phi", "null_torque"):
            _close(f"{what}: {name}", getattr(t_fast, name), getattr(t_ref, name))
        for name in ("Lambda", "Jbar", "J"):
            _close(f"{what}: {name}", getattr(t_fast.task, name), getattr(t_ref.task, name))


@pytest.mark.parametrize("arm", ["rtr", "ur5", "panda"])
@pytest.mark.parametrize("case", ["cylinder", "sphere", "plane", "function", "edge"])
def test_one_step_equals_the_reference(arm: str, case: str, request, rng) -> None:
    robot = request.getfixturevalue(arm)
    for i in range(8):
        _compare_step(robot, case, ("tip", "joint")[i % 2], (0.0, 0.5)[(i // 2) % 2], rng)


def test_model_terms_without_packs_and_the_buffers_reused(ur5: Robot, rng) -> None:
    """Terms made by oracles.terms.robot_terms (no packs) and by Robot.terms (packs) give the same
    command; the workspace returns its own arrays, overwritten by the next call."""
    constraint = Constraint(Plane((0.0, 0.0, 0.3), (0.0, 0.0, 1.0)))
    fast = OscHybridWorkspace(osc_gains(OscOptions(), 10.0), constraint, ur5.nv)
    q, v = _random_state(ur5, rng)
    packed = ur5.terms(q, v, out=RobotTerms.zeros(ur5.nv))
    d = Desired(q, np.zeros(6), np.zeros(6), packed.p.copy(), np.zeros(3), np.zeros(3))
    u_packed = fast.free_space(LawInput(packed, v, np.zeros(6), d)).u0.copy()
    command = fast.free_space(LawInput(robot_terms(ur5, q, v), v, np.zeros(6), d))
    _close("packed vs plain terms", command.u0, u_packed)
    assert command.u0 is fast.u0
    with pytest.raises(ControlError, match="needs the task-space path"):
        fast.free_space(LawInput(packed, v, np.zeros(6), Desired(q, np.zeros(6), np.zeros(6))))


# --------------------------------------------------------------------- singular configurations
def _terms(M: np.ndarray, J: np.ndarray) -> RobotTerms:
    n = M.shape[0]
    terms = RobotTerms.zeros(n)
    terms.M[:] = M
    terms.J[:] = J
    return terms


@pytest.mark.parametrize("smallest", [0.0, 1e-8, 1e-5])
def test_a_rank_deficient_jacobian_raises_the_reference_error(smallest: float) -> None:
    """J M⁻¹ Jᵀ = diag(1, 1, smallest²): refused with the reference's error and message
    (cond ∞ or 1e16), accepted at cond 1e10 with the reference's Λ."""
    terms = _terms(np.eye(3), np.diag([1.0, 1.0, smallest]))
    constraint = Constraint(Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
    gains = osc_gains(OscOptions(), 10.0)
    d = Desired(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))
    ref, fast = OscHybridLaw(gains, constraint, 3), OscHybridWorkspace(gains, constraint, 3)
    v = np.zeros(3)
    if smallest == 1e-5:
        fast.free_space(LawInput(terms, v, v, d))
        ref.free_space(LawInput(terms, v, v, d))
        assert ref.last is not None
        _close("Λ at cond 1e10", fast.Lambda, ref.last.task.Lambda)
        return
    with pytest.raises(SurfaceError) as expected:
        ref.free_space(LawInput(terms, v, v, d))
    with pytest.raises(SurfaceError) as got:
        fast.free_space(LawInput(terms, v, v, d))
    assert str(got.value) == str(expected.value)
    assert got.value.key == "control.law" and got.value.value == "osc_hybrid"


@pytest.mark.parametrize("q3", [0.0, math.pi])
def test_the_rtr_stretched_or_folded_raises_the_reference_error(rtr: Robot, q3: float) -> None:
    """The RTR with its last link along the second (q₃ = 0 or π): J of rank 2, in contact."""
    q = np.array([0.3, 6.0, q3])
    v = np.zeros(3)
    terms = rtr.terms(q, v, out=RobotTerms.zeros(3))
    constraint = Constraint(Plane(terms.p - 0.1, (0.0, 0.0, 1.0)))
    cons = constraint_terms(constraint, terms, v)
    gains = osc_gains(OscOptions(), 10.0)
    d = Desired(q, v, v, terms.p.copy(), np.zeros(3), np.zeros(3))
    ref, fast = OscHybridLaw(gains, constraint, 3), OscHybridWorkspace(gains, constraint, 3)
    messages = []
    for law in (ref, fast):
        with pytest.raises(SurfaceError) as info:
            law.hybrid(LawInput(terms, v, v, d, cons, np.zeros(1), np.ones(1)))
        messages.append(str(info.value))
    assert messages[0] == messages[1]


def test_a_mass_matrix_without_cholesky_factor_is_solved_by_lu() -> None:
    """M indefinite (no Cholesky factor) but J M⁻¹ Jᵀ well conditioned: the kernel solves
    M⁻¹Jᵀ by LU with partial pivoting, as the oracle's numpy solve (free space and contact)."""
    terms = _terms(np.diag([2.0, -1.0, 3.0]), np.eye(3))
    terms.p[:] = (0.1, 0.2, 0.3)
    terms.Jdot_v[:] = (0.5, -0.2, 0.1)
    constraint = Constraint(Plane((0.1, 0.2, 0.3), (0.0, 0.6, 0.8)))
    v = np.array([0.3, -0.1, 0.2])
    cons = constraint_terms(constraint, terms, v)
    gains = osc_gains(OscOptions(force_p=0.4), 10.0)
    d = Desired(np.zeros(3), np.ones(3), np.ones(3), np.zeros(3), np.ones(3), np.ones(3))
    ref, fast = OscHybridLaw(gains, constraint, 3), OscHybridWorkspace(gains, constraint, 3)
    e_F, f_d = np.array([0.2]), np.array([10.0])
    for contact in (False, True):
        if contact:
            c_ref = ref.hybrid(LawInput(terms, v, v, d, cons, e_F, f_d))
            c_fast = fast.hybrid(LawInput(terms, v, v, d, cons, e_F, f_d))
            assert c_ref.B is not None and c_fast.B is not None
            _close("indefinite M: B", c_fast.B, c_ref.B)
        else:
            c_ref = ref.free_space(LawInput(terms, v, v, d))
            c_fast = fast.free_space(LawInput(terms, v, v, d))
        _close("indefinite M: u0", c_fast.u0, c_ref.u0)
        assert ref.last is not None and fast.last is not None
        _close("indefinite M: F0", fast.last.F0, ref.last.F0)
        _close("indefinite M: phi", fast.last.phi, ref.last.phi)


# --------------------------------------------------------------------- whole runs
def _groove(rtr: Robot, duration: float) -> Scenario:
    """k = 2: the groove between the plane z = 10 and the cylinder r = 0.4, model mass × 1.1."""
    from hybrid_force.control.clik import inverse_kinematics

    q0 = inverse_kinematics(rtr, np.array([0.4, 0.0, 10.0]), seed=np.array([0.0, 9.0, 2.0]))
    return Scenario(
        robot=rtr,
        surfaces=[Cylinder(0.4), Plane(point=(0, 0, 10), normal=(0, 0, -1))],
        path=Circle(center=(0, 0, 10), radius=0.4, normal=(0, 0, 1), omega=1.0),
        q0=q0,
        control=ControlSettings(
            supervisor=False,
            f_d=(10.0, 5.0),
            mass_factor=1.1,
            law="osc_hybrid",
            options={"osc_hybrid": {"force_p": 0.3}},
        ),
        sim=SimSettings(duration=duration),
    )


def _scenario(name: str, rtr: Robot) -> Scenario:
    if name == "groove":
        return _groove(rtr, 0.2)
    overrides: dict[str, object] = {"control.law": "osc_hybrid", "sim.duration": 0.2}
    if name == "rtr_plane":  # 12 mm above the plane: free, near (from 0.036 s), contact (0.24 s)
        overrides.update(
            {
                "initial.tip": [0.6, 0.0, 5.012],
                "control.max_dist": 0.01,
                "control.approach_rate": 60.0,
                "sim.duration": 0.4,
            }
        )
    return load_scenario(f"scenarios/{name}.toml", overrides=overrides)


@pytest.mark.parametrize("name", ["paper_contact", "rtr_plane", "ur5_plane", "groove"])
def test_whole_runs_equal_the_reference_law(name: str, rtr: Robot, monkeypatch) -> None:
    """The same loop with the compiled law and with the numpy law: q, u, f within 1e-10."""
    built: list[object] = []

    def compiled(gains, constraint, n):  # type: ignore[no-untyped-def]
        built.append(law := OscHybridWorkspace(gains, constraint, n))
        return law

    def reference(gains, constraint, n):  # type: ignore[no-untyped-def]
        built.append(law := OscHybridLaw(gains, constraint, n))
        return law

    with monkeypatch.context() as patch:
        patch.setattr(osc, "OscHybridWorkspace", compiled)
        fast = simulate(_scenario(name, rtr))
        patch.setattr(osc, "OscHybridWorkspace", reference)
        ref = simulate(_scenario(name, rtr))
    assert [type(law) for law in built] == [OscHybridWorkspace, OscHybridLaw]
    assert fast.meta["controller"]["settings"] == ref.meta["controller"]["settings"]
    np.testing.assert_array_equal(fast.phase, ref.phase)
    if name == "rtr_plane":
        assert set(fast.phase.tolist()) == {0, 1, 2}
    for field in ("q", "v", "u", "f"):
        got, want = getattr(fast, field), getattr(ref, field)
        scale = 1.0 + float(np.abs(want).max())
        err = float(np.abs(got - want).max())
        WORST[f"run {name}: {field}"] = err / scale
        assert err <= RUN_TOL * scale, f"{name}: {field} differs by {err:.3g} (scale {scale:.3g})"


@pytest.mark.parametrize("name", ["paper_contact", "ur5_plane"])
def test_whole_runs_equal_the_reference_run(
    name: str, rtr: Robot, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Against the all-numpy loop (ReferenceController, the numpy law and CLIK, the oracle
    plant): q, v, u, f within 1e-10 of their scale."""
    sc = _scenario(name, rtr)
    fast = simulate(sc)
    ref = oracle_run(monkeypatch, sc)
    np.testing.assert_array_equal(fast.phase, ref.phase)
    for field in ("q", "v", "u", "f"):
        got, want = getattr(fast, field), getattr(ref, field)
        scale = 1.0 + float(np.abs(want).max())
        err = float(np.abs(got - want).max())
        WORST[f"reference run {name}: {field}"] = err / scale
        assert err <= RUN_TOL * scale, f"{name}: {field} differs by {err:.3g} (scale {scale:.3g})"

"""The impedance law's compiled step (hybrid_force.control.laws._impedance_kernels, through
ImpedanceWorkspace) against its numpy oracle (ImpedanceLaw of tests/oracles/laws.py).

1. One step on random states of the RTR, UR5 and Panda (fixed seed), with one and with two
   surfaces, in free space, near the surface (the approach's reference) and in contact (force
   tracking on and off, with and without feed-forward): u, K, D, the depth δ and, after an
   update, the preload φ agree to 1e-12 relative to the largest entry of the reference (the
   preload exactly: the same operations).
2. Singular J M⁻¹ Jᵀ (a tip that cannot move along one axis) and singular M raise the same
   SurfaceError with the same message on both paths.
3. Whole short runs of paper_contact (0.2 s, contact) and ur5_plane (0.2 s near the plane,
   0.4 s to include the touch at 0.284 s), compiled law vs its oracle (all else the same),
   agree to 1e-10 in q, q̇, u and f.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from oracles.laws import ImpedanceLaw
from oracles.terms import constraint_terms

import hybrid_force.control.laws.impedance as impedance
from hybrid_force import simulate
from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.base import Command, Desired, LawContext, LawInput
from hybrid_force.control.laws.impedance import ImpedanceGains, ImpedanceWorkspace
from hybrid_force.errors import SurfaceError
from hybrid_force.geometry.builtin_surfaces import Plane, Sphere
from hybrid_force.model.robot import Robot, RobotTerms
from hybrid_force.phases import CONTACT, NEAR
from hybrid_force.result import Result
from hybrid_force.scenario.loader import load_scenario

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
RTOL = 1e-12
RUN_RTOL = 1e-10
DT = 1e-3
TWO_PLANES = (Plane((0.0, 0.0, 0.3), (0.0, 0.1, 1.0)), Plane((0.4, 0.0, 0.0), (1.0, 0.2, 0.1)))

WORST: dict[str, float] = {}  # largest |compiled − reference| / scale per quantity


def _close(what: str, got: np.ndarray, ref: np.ndarray, scale: float | None = None) -> None:
    """max|got − ref| ≤ RTOL · scale, scale = max|ref| unless given."""
    got, ref = np.asarray(got, dtype=float), np.asarray(ref, dtype=float)
    if scale is None:
        scale = float(np.abs(ref).max(initial=0.0))
    assert got.shape == ref.shape, f"{what}: shape {got.shape} != {ref.shape}"
    assert np.all(np.isfinite(got)) and np.all(np.isfinite(ref)), what
    err = float(np.abs(got - ref).max(initial=0.0))
    rel = err / scale if scale > 0 else (0.0 if err == 0 else math.inf)
    WORST[what] = max(WORST.get(what, 0.0), rel)
    assert err <= RTOL * scale, f"{what}: {err:.3g} > {RTOL:g} × {scale:.3g}\n{got}\n{ref}"


def _random_case(
    robot: Robot, rng: np.random.Generator
) -> tuple[RobotTerms, np.ndarray, np.ndarray, Desired]:
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
        pdd=rng.uniform(-1, 1, 3),
    )
    return terms, v, q - desired.q, desired


def _compare(
    what: str,
    fast: ImpedanceWorkspace,
    cmd: Command,
    ref: ImpedanceLaw,
    ref_cmd: Command,
) -> None:
    assert cmd.B is None and ref_cmd.B is None
    _close(f"{what}.u", cmd.u0, ref_cmd.u0)
    _close(f"{what}.K", fast.stiffness, ref.stiffness)
    _close(f"{what}.D", fast.damping, ref.damping)
    np.testing.assert_array_equal(fast.stiffness, fast.stiffness.T)


@pytest.mark.parametrize("feedforward", [True, False])
@pytest.mark.parametrize("force_tracking", [True, False])
@pytest.mark.parametrize("k", [1, 2])
@pytest.mark.parametrize("arm", ["rtr", "ur5", "panda"])
def test_kernel_equals_the_numpy_reference(
    request: pytest.FixtureRequest, arm: str, k: int, force_tracking: bool, feedforward: bool
) -> None:
    robot: Robot = request.getfixturevalue(arm)
    rng = np.random.default_rng(3200 + 10 * k + 2 * force_tracking + feedforward)
    surfaces = [Sphere(0.3, center=(0.2, 0.1, 0.4))] if k == 1 else list(TWO_PLANES)
    con = Constraint(surfaces)
    gains = ImpedanceGains(
        omega=25.0, zeta=0.8, force_tracking=force_tracking, force_rate=7.0,
        feedforward=feedforward,
    )  # fmt: skip
    fast, ref = ImpedanceWorkspace(gains, con, k), ImpedanceLaw(gains, con, k)
    for step in range(12):  # one law each, the phases interleaved, a touch every contact run
        terms, v, e_q, desired = _random_case(robot, rng)
        cons = constraint_terms(con, terms, v)
        phase = ("free", "near", "contact", "contact")[step % 4]
        if phase == "free":
            cmd = fast.free_space(LawInput(terms, v, e_q, desired))
            ref_cmd = ref.free_space(LawInput(terms, v, e_q, desired))
        elif phase == "near":
            approach = -rng.uniform(0.5, 2.0) * cons.distance
            cmd = fast.hybrid(
                LawInput(terms, v, e_q, desired, cons, np.zeros(k), np.zeros(k), approach)
            )
            ref_cmd = ref.hybrid(
                LawInput(terms, v, e_q, desired, cons, np.zeros(k), np.zeros(k), approach)
            )
        else:
            f_d = rng.uniform(0.0, 20.0, k)
            e_F = rng.uniform(-1, 1, k)
            cmd = fast.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d))
            ref_cmd = ref.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d))
            _close("contact.offset", fast.offset, ref.offset)
        _compare(phase, fast, cmd, ref, ref_cmd)
        f = rng.uniform(0.0, 20.0, k)
        fast.update(DT, f)
        ref.update(DT, f)
        np.testing.assert_array_equal(fast.preload, ref.preload)  # the same operations
        assert fast._in_contact == ref._in_contact


def test_singular_configurations_raise_the_same_error(rtr: Robot) -> None:
    """J M⁻¹ Jᵀ singular (a zero row of J) and M singular (zero): same error, same message."""
    con = Constraint([Sphere(0.3, center=(0.2, 0.1, 0.4))])
    gains = ImpedanceGains()
    rng = np.random.default_rng(32)
    terms, v, e_q, desired = _random_case(rtr, rng)
    cons = constraint_terms(con, terms, v)
    bad_J, bad_M = RobotTerms.zeros(rtr.nv), RobotTerms.zeros(rtr.nv)
    for bad in (bad_J, bad_M):
        for name in ("M", "C", "g", "nle", "p", "J", "Jdot", "Jdot_v", "pdot"):
            getattr(bad, name)[...] = getattr(terms, name)
    bad_J.J[2] = 0.0
    bad_M.M[...] = 0.0
    for bad in (bad_J, bad_M):
        messages = []
        for law in (ImpedanceWorkspace(gains, con, 1), ImpedanceLaw(gains, con, 1)):
            with pytest.raises(SurfaceError) as info:
                law.free_space(LawInput(bad, v, e_q, desired))
            messages.append(str(info.value))
            with pytest.raises(SurfaceError) as info:
                law.hybrid(LawInput(bad, v, e_q, desired, cons, np.zeros(1), np.ones(1)))
            messages.append(str(info.value))
        assert len(set(messages)) == 1, messages
        assert "cannot move in every direction" in messages[0]


def _runs(
    name: str, duration: float, monkeypatch: pytest.MonkeyPatch, **overrides: object
) -> tuple[Result, Result]:
    """The scenario run with the compiled impedance law, then with its reference."""
    sc = load_scenario(
        SCENARIOS / f"{name}.toml",
        {"control.law": "impedance", "sim.duration": duration, **overrides},
    )
    fast = simulate(sc)
    laws: list[object] = []

    def oracle(*args):  # type: ignore[no-untyped-def]
        laws.append(law := ImpedanceLaw(*args))
        return law

    with monkeypatch.context() as m:
        m.setattr(impedance, "ImpedanceWorkspace", oracle)  # what the factory builds
        ref = simulate(sc)
    assert len(laws) == 1 and type(laws[0]) is ImpedanceLaw  # the oracle did run
    return fast, ref


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize(
    ("name", "duration", "overrides"),
    [
        ("paper_contact", 0.2, {}),
        ("paper_contact", 0.2, {"control.impedance.force_tracking": False}),
        ("ur5_plane", 0.2, {"control.impedance.feedforward": False}),  # near only
        ("ur5_plane", 0.4, {}),  # near, then contact from t = 0.284 s
    ],
)
def test_whole_runs_equal_the_reference_law(
    monkeypatch: pytest.MonkeyPatch, name: str, duration: float, overrides: dict[str, object]
) -> None:
    fast, ref = _runs(name, duration, monkeypatch, **overrides)
    assert fast.phase.tolist() == ref.phase.tolist()
    for field in ("q", "v", "u", "f"):
        got, want = getattr(fast, field), getattr(ref, field)
        scale = float(np.abs(want).max()) + 1e-300
        err = float(np.abs(got - want).max())
        WORST[f"run.{name}.{field}"] = max(WORST.get(f"run.{name}.{field}", 0.0), err / scale)
        assert err <= RUN_RTOL * scale, f"{name}.{field}: {err:.3g} > {RUN_RTOL:g} × {scale:.3g}"
    expected = (
        {CONTACT} if name == "paper_contact" else {NEAR, CONTACT} if duration > 0.3 else {NEAR}
    )
    assert set(ref.phase.tolist()) == expected


def test_the_compiled_form_is_what_the_registry_builds(rtr: Robot) -> None:
    sc = load_scenario(SCENARIOS / "paper_contact.toml", {"control.law": "impedance"})
    context = LawContext(  # the factory reads the robot, constraint, settings and dt
        rtr, Constraint(sc.surfaces), sc.control, None, np.eye(3), sc.q0, DT
    )
    assert type(impedance.build(context)) is ImpedanceWorkspace

"""Each law's own pre-run checks (issue 27, class 4), on the controller's model.

The bounds are derived in each law's ``loop_bounds`` and in hybrid_force.control.force_loop;
here the loader refuses what they refuse (exit 2 naming the key, the value and the bound),
and short simulations, built past the loader, check each bound from both sides.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hybrid_force import simulate
from hybrid_force.cli import main
from hybrid_force.control.force_loop import loop_radius, max_stable_loop_gain
from hybrid_force.errors import RunFailedError, ScenarioError
from hybrid_force.scenario.loader import load_scenario

# the runs past a bound chatter and miss f_d: what they warn about is tests/test_run_warnings.py
pytestmark = pytest.mark.filterwarnings("ignore::hybrid_force.errors.RunWarning")

ROOT = Path(__file__).resolve().parents[1]
CONTACT = ROOT / "scenarios" / "paper_contact.toml"


def _run(scenario: object) -> object:
    try:
        return simulate(scenario)  # type: ignore[arg-type]
    except RunFailedError as exc:
        return exc.result


def _cli(capsys: pytest.CaptureFixture[str], tmp_path: Path, *sets: str) -> tuple[int, str]:
    args = ["run", str(CONTACT), "--quiet", "--out", str(tmp_path / "out")]
    for s in ("sim.duration=0.05", *sets):
        args += ["--set", s]
    code = main(args)
    return code, capsys.readouterr().err


def test_the_integral_recursion_reduces_to_the_known_cases() -> None:
    """bT = 0: the paper's a* (1 without a filter); α = 1, d = 0: Jury's a < 1 + bT/2."""
    assert max_stable_loop_gain(0.0, 1.0, 1) == 1.0
    assert max_stable_loop_gain(0.02, 1.0, 0) == pytest.approx(1.01, rel=1e-9)
    a = max_stable_loop_gain(0.02, 1.0, 1)
    assert (
        loop_radius(a * (1 - 1e-6), 0.02, 1.0, 1) < 1.0 < loop_radius(a * (1 + 1e-6), 0.02, 1.0, 1)
    )


# --------------------------------------------------------------------------- (a) no inherited β
def test_osc_hybrid_is_not_refused_for_the_paper_laws_beta_bound() -> None:
    """A controller model 15× the plant's, force read one period late: the paper's β bound
    W/(m) = 0.124/15 < β = 0.01 refuses arimoto (its default β), while osc_hybrid, which has
    no β, loads (its own loops are stable: T·15·K_v = 0.6 < 2, force_p = 0)."""
    sets = {"sensor.force_delay": 1, "sim.model_mass_factor": 15.0}
    with pytest.raises(
        ScenarioError, match=r"control\.beta = 0\.01: .*beta must stay below 0\.008"
    ):
        load_scenario(CONTACT, sets)
    sc = load_scenario(CONTACT, {**sets, "control.law": "osc_hybrid"})
    assert sc.control.law == "osc_hybrid"


def test_a_law_without_K_d_is_not_held_to_the_K_d_step_check() -> None:
    """At a 100 Hz controller the paper's default K_d = 100 M(q0) fails T·λ_max(M_c⁻¹K_d) =
    1 > 0.5 (tests/test_scenario.py); osc_hybrid does not read K_d, and its own loops pass
    (T·K_v = 0.4 < 2, k_I T = 0.2 below the integral's bound)."""
    with pytest.raises(ScenarioError, match=r"control\.Kd = "):
        load_scenario(CONTACT, {"control.rate": 100})
    sc = load_scenario(CONTACT, {"control.rate": 100, "control.law": "osc_hybrid"})
    assert sc.control.rate == 100


# --------------------------------------------------------------------------- (b) force gains
@pytest.mark.parametrize(("law", "key"), [("osc_hybrid", "force_p"), ("raibert_craig", "kp")])
def test_a_force_gain_of_1_5_is_refused_when_the_force_is_sampled(
    law: str, key: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, err = _cli(
        capsys, tmp_path, f"control.law={law}", f"control.{law}.{key}=1.5",
        "sim.model_mass_factor=2.0", "sensor.force_delay=1",
    )  # fmt: skip
    assert code == 2
    assert f"paper_contact.toml: control.{law}.{key} = 1.5:" in err
    assert "unless " + key + " < 1.0" in err and "oscillates and grows" in err
    assert not (tmp_path / "out" / "summary.json").exists()


@pytest.mark.parametrize(("law", "key"), [("osc_hybrid", "force_p"), ("raibert_craig", "kp")])
def test_with_the_exact_loop_a_force_gain_of_1_5_runs_without_bouncing(law: str, key: str) -> None:
    """Ideal sensing at the plant's rate: u = u0 + B f is solved with the plant's f, so
    (1 + k_P)(f − f_d) = … has no recursion at all: no bound on k_P, with any model mass
    (B = k_P Aᵀ is a force, applied as one). The run stays on the surface."""
    sc = load_scenario(
        CONTACT,
        {"control.law": law, f"control.{law}.{key}": 1.5, "sim.model_mass_factor": 2.0,
         "sim.duration": 1.0},
    )  # fmt: skip
    r = simulate(sc)
    kinds = [e["kind"] for e in r.meta["events"]]
    assert "release" not in kinds and r.meta["status"] == "ok"
    assert float(np.abs(r.f - r.f_d)[r.t >= 0.5].max()) < 0.1


# --------------------------------------------------------------------------- (c) by simulation
@pytest.mark.parametrize(("factor", "settles"), [(0.95, True), (1.05, False)])
def test_the_force_p_bound_brackets_the_runs(factor: float, settles: bool) -> None:
    """osc_hybrid on section 6.3, force read one period late: k_P just inside the derived
    bound settles, just outside the force oscillates and grows until the tool leaves."""
    bound = max_stable_loop_gain(20.0 * 1e-3, 1.0, 1)  # k_I = 20 1/s, T = 1 ms, ρ = 1
    base = load_scenario(
        CONTACT, {"control.law": "osc_hybrid", "sensor.force_delay": 1, "sim.duration": 0.6}
    )
    options = {"osc_hybrid": {"force_p": factor * bound}}
    r = _run(dataclasses.replace(base, control=dataclasses.replace(base.control, options=options)))
    error = np.abs(r.f - r.f_d)[r.t >= 0.4]  # type: ignore[attr-defined]
    if settles:
        assert r.t[-1] == pytest.approx(0.6) and float(error.max()) < 1e-2  # type: ignore[attr-defined]
    else:
        assert r.t[-1] < 0.6 or float(error.max()) > 1.0  # type: ignore[attr-defined]


def test_the_raibert_craig_kp_bound_is_the_same_recursion() -> None:
    """Raibert–Craig's kp enters as osc_hybrid's force_p does (B = k_p Aᵀ, integral k_i =
    (1 + k_p) γ): 1.05 × its bound, computed with its own k_i, oscillates and leaves."""
    kp = 1.0
    for _ in range(5):  # k_i depends on k_p: the fixed point of the bound
        kp = max_stable_loop_gain((1.0 + kp) * 20.0 * 1e-3, 1.0, 1)
    base = load_scenario(
        CONTACT, {"control.law": "raibert_craig", "sensor.force_delay": 1, "sim.duration": 0.6}
    )
    options = {"raibert_craig": {"kp": 1.05 * kp, "ki": (1.0 + kp) * 20.0}}
    r = _run(dataclasses.replace(base, control=dataclasses.replace(base.control, options=options)))
    error = np.abs(r.f - r.f_d)[r.t >= 0.4]  # type: ignore[attr-defined]
    assert r.t[-1] < 0.6 or float(error.max()) > 1.0  # type: ignore[attr-defined]


# --------------------------------------------------------------------------- the velocity loop
def test_a_controller_25_times_the_plants_mass_is_refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """T (κ + Λ) m = 1e-3 · 110 · 25 = 2.75 ≥ 2, though T·λ_max(M_c⁻¹K_d) = κT = 0.1."""
    code, err = _cli(capsys, tmp_path, "sim.model_mass_factor=25")
    assert code == 2
    assert "paper_contact.toml: sim.model_mass_factor = 25.0:" in err
    assert "T·λ_max(M⁻¹(K_d + Λ M_c)) < 2; here it reaches 2.75" in err


@pytest.mark.parametrize(("mass_factor", "stable"), [(17.0, True), (19.5, False)])
def test_the_velocity_loop_bound_brackets_the_runs(mass_factor: float, stable: bool) -> None:
    """The bound is m < 2 / (T (κ + Λ)) = 18.2: at 17 the run goes on (the loader accepts
    it), at 19.5 (refused by the loader, run here past it) it diverges within 0.1 s."""
    sets = {"sim.duration": 0.1}
    if stable:
        load_scenario(CONTACT, {**sets, "sim.model_mass_factor": mass_factor})
    else:
        with pytest.raises(ScenarioError, match=r"sim\.model_mass_factor = 19\.5"):
            load_scenario(CONTACT, {**sets, "sim.model_mass_factor": mass_factor})
    base = load_scenario(CONTACT, sets)
    sc = dataclasses.replace(
        base, control=dataclasses.replace(base.control, mass_factor=mass_factor)
    )
    r = _run(sc)
    assert (r.meta["status"] == "ok") is stable  # type: ignore[attr-defined]
    if not stable:
        assert r.meta["reason"] == "diverged"  # type: ignore[attr-defined]


@pytest.mark.parametrize(("gamma", "stable"), [(2050.0, True), (2250.0, False)])
def test_the_force_integral_bound_brackets_the_runs(gamma: float, stable: bool) -> None:
    """The paper's law, exact loop: (1 + a) f = c − b E with E advanced explicitly, so
    b T < 2 (1 + a), b ≈ γ, a = β/W = 0.08 on section 6.3: γ < 2153 1/s. Just inside the
    force settles; just outside it oscillates until the tool leaves the surface."""
    sets = {"sim.duration": 0.3, "control.gamma": gamma}
    if stable:
        load_scenario(CONTACT, sets)
    else:
        with pytest.raises(ScenarioError, match=r"control\.gamma = 2250\.0: .*b·T < 2\.161"):
            load_scenario(CONTACT, sets)
    base = load_scenario(CONTACT, {"sim.duration": 0.3})
    r = _run(dataclasses.replace(base, control=dataclasses.replace(base.control, gamma=gamma)))
    error = float(np.abs(r.f - r.f_d)[r.t >= 0.2].max())  # type: ignore[attr-defined]
    assert (error < 1e-3) if stable else (r.meta["status"] == "failed" and error > 100.0)  # type: ignore[attr-defined]


# --------------------------------------------------------------------------- control.model
def _scaled_rtr(tmp_path: Path, factor: float) -> Path:
    """The RTR URDF with every link's mass and inertia × factor."""
    import re

    text = (ROOT / "robots" / "rtr.urdf").read_text()
    pattern = re.compile(r'((?:value|ixx|iyy|izz|ixy|ixz|iyz)=)"([-0-9.eE+]+)"')
    text = pattern.sub(lambda m: f'{m.group(1)}"{float(m.group(2)) * factor!r}"', text)
    path = tmp_path / f"rtr_x{factor:g}.urdf"
    path.write_text(text)
    return path


def test_the_checks_use_control_model_not_the_plant(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A controller model 25× the plant's (control.model) is refused by the velocity loop;
    one 2× halves the paper's sampled β bound (0.124 → 0.062): β = 0.1 loads with the plant's
    own model and is refused with the heavy one, naming the key and the bound."""
    heavy = _scaled_rtr(tmp_path, 25.0)
    code, err = _cli(capsys, tmp_path, f"control.model={heavy}")
    assert code == 2 and f'control.model = "{heavy}": ' in err
    assert "here it reaches 2.75" in err
    sets = {"sensor.force_delay": 1, "control.beta": 0.1, "sim.duration": 0.1}
    load_scenario(CONTACT, sets)
    double = _scaled_rtr(tmp_path, 2.0)
    with pytest.raises(
        ScenarioError, match=r"control\.beta = 0\.1: .*beta must stay below 0\.06206"
    ):
        load_scenario(CONTACT, {**sets, "control.model": str(double)})
    # osc_hybrid's force_p bound does not depend on the model's masses (B = k_P Aᵀ is a force)
    code, err = _cli(
        capsys, tmp_path, f"control.model={double}", "control.law=osc_hybrid",
        "control.osc_hybrid.force_p=1.5", "sensor.force_delay=1",
    )  # fmt: skip
    assert (
        code == 2 and "control.osc_hybrid.force_p = 1.5: " in err and "unless force_p < 1.0" in err
    )


@pytest.mark.parametrize(
    ("law", "inside", "outside"),
    [
        ("osc_hybrid", 45.0, 55.0),  # T m max(K_v, K_n, d_n) = 1e-3 · m · 40 < 2: m < 50
        ("raibert_craig", 17.0, 19.5),  # T m (ω_p + ω_d) = 1e-3 · m · 110 < 2: m < 18.2
        ("impedance", 30.0, 36.0),  # T m 2ζω = 1e-3 · m · 60 < 2: m < 33.3
    ],
)
def test_each_laws_velocity_loop_bound_brackets_the_runs(
    law: str, inside: float, outside: float
) -> None:
    """Every law's own velocity loop with a controller model m times the plant's: the loader
    accepts m inside its bound and refuses m outside, where the run (built past the loader)
    diverges within 0.03 s; inside it runs its 0.2 s."""
    sets = {"sim.duration": 0.2, "control.law": law}
    load_scenario(CONTACT, {**sets, "sim.model_mass_factor": inside})
    with pytest.raises(ScenarioError, match=rf"sim\.model_mass_factor = {outside}: .*< 2; here"):
        load_scenario(CONTACT, {**sets, "sim.model_mass_factor": outside})
    base = load_scenario(CONTACT, sets)
    for m, stable in ((inside, True), (outside, False)):
        r = _run(
            dataclasses.replace(base, control=dataclasses.replace(base.control, mass_factor=m))
        )
        assert (r.meta["status"] == "ok") is stable  # type: ignore[attr-defined]
        if not stable:
            assert r.meta["reason"] == "diverged" and r.t[-1] < 0.03  # type: ignore[attr-defined]


def _bisected(stable: Any, high: float) -> float:
    """The largest x in [0, high] with stable(x), by bisection (the oracle's search)."""
    low = 0.0
    for _ in range(60):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if stable(mid) else (low, mid)
    return low


def test_crossing_bounds_are_the_polynomial_roots_bisected() -> None:
    from hybrid_force.control.force_loop import largest_integral_step

    rng = np.random.default_rng(11)
    for _ in range(120):
        alpha = 1.0 if rng.random() < 0.3 else float(rng.uniform(0.02, 1.0))
        delay = int(rng.integers(0, 25))
        step = _bisected(lambda x, al=alpha, d=delay: loop_radius(0.0, x, al, d) < 1.0, 4.0)
        assert largest_integral_step(alpha, delay) == pytest.approx(step, rel=1e-9)
        bT = float(rng.uniform(0.0, 0.9 * step))
        a = _bisected(
            lambda x, b=bT, al=alpha, d=delay: loop_radius(x, b, al, d) < 1.0,
            2.0 / alpha + bT + 1.0,
        )
        assert max_stable_loop_gain(bT, alpha, delay) == pytest.approx(a, rel=1e-9)


def test_crossing_bounds_are_bounded_work_at_the_largest_delay() -> None:
    import time

    from hybrid_force.control.force_loop import largest_integral_step
    from hybrid_force.sim.sensors import MAX_FORCE_DELAY

    start = time.perf_counter()
    step = largest_integral_step(0.3, MAX_FORCE_DELAY)
    assert 0.0 < step < 1e-3
    assert max_stable_loop_gain(0.5 * step, 0.3, MAX_FORCE_DELAY) > 0.0
    assert time.perf_counter() - start < 30.0  # O(d): a few seconds (the roots: O(d³), hours)

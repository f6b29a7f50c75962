"""Tests of hybrid_force.control.force_loop: the sampled force loop's stability bound."""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from hybrid_force import simulate
from hybrid_force.control.force_loop import (
    beta_bound,
    inverse_effective_mass,
    max_stable_gain,
    spectral_radius,
)
from hybrid_force.errors import RunWarning
from hybrid_force.scenario.loader import load_scenario

CONTACT = Path(__file__).resolve().parents[1] / "scenarios" / "paper_contact.toml"


@pytest.mark.parametrize("delay", [0, 1, 2, 5])
def test_without_a_filter_the_bound_is_one_for_every_delay(delay: int) -> None:
    """z^{d+1} = −a: |z| = a^{1/(d+1)}, so the loop converges exactly for a < 1."""
    assert max_stable_gain(1.0, delay) == 1.0
    assert spectral_radius(0.81, 1.0, delay) == pytest.approx(0.81 ** (1 / (delay + 1)))
    assert spectral_radius(1.0 - 1e-9, 1.0, delay) < 1.0 < spectral_radius(1.0 + 1e-9, 1.0, delay)


def test_with_a_filter_and_no_delay_the_pole_is_one_minus_alpha_times_one_plus_a() -> None:
    alpha = 1.0 - math.exp(-2.0 * math.pi * 50.0 * 1e-3)
    assert max_stable_gain(alpha, 0) == pytest.approx(2.0 / alpha - 1.0)
    assert spectral_radius(3.0, alpha, 0) == pytest.approx(abs(1.0 - alpha * 4.0))


@pytest.mark.parametrize("delay", [1, 2, 3])
def test_the_bisected_bound_puts_a_root_on_the_unit_circle(delay: int) -> None:
    alpha = 0.27
    a = max_stable_gain(alpha, delay)
    assert spectral_radius(a * (1 - 1e-6), alpha, delay) < 1.0
    assert spectral_radius(a * (1 + 1e-6), alpha, delay) > 1.0
    assert 1.0 < a < 2.0 / alpha - 1.0  # a filter helps, a delay takes part of it back


def test_inverse_effective_mass_of_the_rtr_on_the_cylinder_by_hand() -> None:
    """At the 6.3 start, 0.9 + cos q3 = 0.4 (q3 = 120°): only q3 moves the tip radially,
    n̂ᵀJ = (0, 0, −sin q3); the (q2, q3) block of M is [[m2 + m3, ½ m3 l3 cos q3],
    [·, m3 l3²/3]] = [[40, −5], [−5, 20/3]], so (M⁻¹)₃₃ = 40 / (800/3 − 25) = 24/145 and
    W = sin² q3 · 24/145 = 18/145."""
    scenario = load_scenario(CONTACT)
    w = inverse_effective_mass(scenario.robot, scenario.surfaces, [scenario.q0], "tip")
    assert w == pytest.approx(18.0 / 145.0, rel=1e-9)
    # the paper's unit row J_Φ/‖J_Φ‖ = (0, 0, −1): W = (M⁻¹)₃₃ = 24/145
    joint = inverse_effective_mass(scenario.robot, scenario.surfaces, [scenario.q0], "joint")
    assert joint == pytest.approx(24.0 / 145.0, rel=1e-9)
    assert beta_bound(w, 2.0, 1.0, 1) == pytest.approx(9.0 / 145.0, rel=1e-9)


@pytest.mark.parametrize(("factor", "converges"), [(0.9, True), (1.1, False)])
def test_the_predicted_bound_brackets_the_runs(factor: float, converges: bool) -> None:
    """Section 6.3 at 1 kHz, force read one period late: β at 0.9 of the bound converges to
    round-off, at 1.1 the force oscillates and never settles (the loader refuses it; the
    Python API runs it, to study it)."""
    base = load_scenario(CONTACT, {"sim.duration": 3.0, "sensor.force_delay": 1})
    w = inverse_effective_mass(base.robot, base.surfaces, [base.q0], "tip")
    beta = factor * beta_bound(w, 1.0, 1.0, 1)
    with warnings.catch_warnings():  # the unstable run warns that it chatters (asserted below)
        warnings.simplefilter("ignore", RunWarning)
        result = simulate(
            dataclasses.replace(base, control=dataclasses.replace(base.control, beta=beta))
        )
    late = result.t >= 2.0
    error = float(np.abs(result.f - result.f_d)[late].max())
    assert (error < 1e-6) if converges else (error > 1.0)
    assert (result.meta["behaviour"]["chatter"] == 0) is converges
    assert any("chattered" in w for w in result.meta["warnings"]) is not converges


def test_the_loader_refuses_a_beta_beyond_the_bound_and_accepts_one_below() -> None:
    from hybrid_force.errors import ScenarioError

    bound = 18.0 / 145.0  # the hand value above, mass factor 1, no filter
    load_scenario(CONTACT, {"sensor.force_delay": 1, "control.beta": 0.99 * bound})
    with pytest.raises(ScenarioError, match=r"control\.beta = .*oscillates.*0\.1241"):
        load_scenario(CONTACT, {"sensor.force_delay": 1, "control.beta": 1.01 * bound})
    # ideal sensing at the plant's rate: the exact loop, no bound
    load_scenario(CONTACT, {"control.beta": 10.0 * bound})

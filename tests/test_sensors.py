"""Tests of hybrid_force.sim.sensors: the measurement model against its definitions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hybrid_force.errors import BadInputError, ScenarioError
from hybrid_force.sim.sensors import Sensors, SensorSettings

T = 1e-3  # control period [s]


def test_ideal_sensing_returns_the_state_itself() -> None:
    settings = SensorSettings()
    assert settings.ideal
    sensors = Sensors(settings, T, seed=1)
    q, v, f = np.array([0.1, 2.0]), np.array([-1.0, 3.0]), np.array([7.5])
    q_m, v_m, f_m = sensors.measure(q, v, f)
    np.testing.assert_array_equal(q_m, q)
    np.testing.assert_array_equal(v_m, v)
    np.testing.assert_array_equal(f_m, f)
    q_m[0] = 99.0  # new arrays: the plant's state is never aliased
    assert q[0] == 0.1


def test_low_pass_step_response_is_the_exact_first_order_one() -> None:
    """A unit step held from the second tick: y_k = 1 − exp(−2π f_c k T) exactly (the
    discretisation is exact for an input held over the period)."""
    cutoff = 50.0
    sensors = Sensors(SensorSettings(force_cutoff=cutoff), T, seed=0)
    out = [sensors.measure(np.zeros(1), np.zeros(1), np.array([0.0]))[2][0]]
    out += [sensors.measure(np.zeros(1), np.zeros(1), np.array([1.0]))[2][0] for _ in range(40)]
    k = np.arange(41)
    expected = 1.0 - np.exp(-2.0 * math.pi * cutoff * k * T)
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-15)


def test_delay_is_whole_control_periods_and_holds_the_first_sample() -> None:
    sensors = Sensors(SensorSettings(force_delay=3), T, seed=0)
    out = [sensors.measure(np.zeros(1), np.zeros(1), np.array([float(k)]))[2][0] for k in range(8)]
    assert out == [0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0]


def test_noise_has_its_standard_deviation_and_bias_and_is_reproducible() -> None:
    settings = SensorSettings(force_noise=0.5, force_bias=2.0, joint_noise=1e-3, velocity_noise=0.1)
    assert not settings.ideal
    samples = []
    for seed in (7, 7, 8):
        sensors = Sensors(settings, T, seed=seed)
        rows = [sensors.measure(np.zeros(3), np.zeros(3), np.array([10.0])) for _ in range(4000)]
        samples.append(rows)
    f = np.array([r[2][0] for r in samples[0]])
    q = np.array([r[0] for r in samples[0]])
    v = np.array([r[1] for r in samples[0]])
    # 4000 samples: the sample mean is within 4 σ/√N of 12 N, the std within 5 % of σ
    assert abs(f.mean() - 12.0) < 4 * 0.5 / math.sqrt(4000)
    assert f.std() == pytest.approx(0.5, rel=0.05)
    assert q.std() == pytest.approx(1e-3, rel=0.05) and v.std() == pytest.approx(0.1, rel=0.05)
    same = all(np.array_equal(a[2], b[2]) for a, b in zip(samples[0], samples[1], strict=True))
    other = any(not np.array_equal(a[2], b[2]) for a, b in zip(samples[0], samples[2], strict=True))
    assert same and other


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"force_noise": -1.0}, "sensor.force_noise"),
        ({"force_cutoff": -5.0}, "sensor.force_cutoff"),
        ({"force_delay": 1.5}, "sensor.force_delay"),
        ({"force_delay": -1}, "sensor.force_delay"),
        ({"joint_noise": float("nan")}, "sensor.joint_noise"),
        ({"velocity_noise": "0.1"}, "sensor.velocity_noise"),
        ({"force_bias": True}, "sensor.force_bias"),
    ],
)
def test_bad_settings_are_refused_naming_the_key(kwargs: dict, key: str) -> None:
    with pytest.raises(ScenarioError, match=key.replace(".", r"\.")) as info:
        SensorSettings(**kwargs)
    assert isinstance(info.value, BadInputError)

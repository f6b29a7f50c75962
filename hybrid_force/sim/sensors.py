"""What the controller measures: encoders and a force sensor, noisy, biased, filtered, late.

A real controller never reads the plant. At each control tick (period T [s]) it reads

* joint positions and velocities: q̃ = q + n_q, ṽ = v + n_v, with white Gaussian noise of
  standard deviation ``joint_noise`` [rad or m] and ``velocity_noise`` [rad/s or m/s];
* the contact force along each surface normal [N]: the true force plus a constant
  ``force_bias`` and white Gaussian noise of standard deviation ``force_noise``, through a
  first-order low-pass filter of cut-off ``force_cutoff`` [Hz] (0: none), available
  ``force_delay`` whole control periods later.

The filter is the exact discretisation, for an input held over the period, of
τ ẏ = x − y with τ = 1 / (2π f_c): y_k = y_{k−1} + α (x_k − y_{k−1}), α = 1 − exp(−2π f_c T);
its first output is its first input (no start-up transient from 0). Before ``force_delay``
periods have passed, the delayed output is the first filtered sample.

The noise comes from ``numpy.random.default_rng(seed)``: a run is reproducible from its seed
(``sim.seed``). Default settings are ideal sensing: the measurement is the plant's state.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid_force.errors import ScenarioError
from hybrid_force.schema import check_fields, param

__all__ = ["MAX_FORCE_DELAY", "SensorSettings", "Sensors"]


MAX_FORCE_DELAY = 100_000
"""The longest force delay [control periods] (docs/scenarios.md, [sensor]): 100 s at 1 kHz.
The delay line holds one reading per period up to it (a 10**9-period delay would keep every
reading of the run in memory); the stability check costs the same for any delay."""


@dataclass(frozen=True)
class SensorSettings:
    """The measurement model (the scenario's ``[sensor]`` table).

    Attributes:
        force_noise: σ of the white force noise [N], ≥ 0.
        force_bias: constant force offset [N].
        force_cutoff: cut-off frequency of the first-order low-pass [Hz], ≥ 0 (0: none).
        force_delay: delay of the force measurement in whole control periods, ≥ 0.
        joint_noise: σ of the joint position noise [rad or m], ≥ 0.
        velocity_noise: σ of the joint velocity noise [rad/s or m/s], ≥ 0.
    """

    force_noise: float = param(0.0, unit="N", minimum=0.0, doc="σ of the white force noise")
    force_bias: float = param(0.0, unit="N", doc="constant force offset")
    force_cutoff: float = param(
        0.0, unit="Hz", minimum=0.0, doc="cut-off of the first-order low-pass (0: none)"
    )
    force_delay: int = param(
        0, minimum=0, maximum=MAX_FORCE_DELAY, doc="delay of the force, in control periods"
    )
    joint_noise: float = param(
        0.0, unit="rad or m", minimum=0.0, doc="σ of the joint position noise"
    )
    velocity_noise: float = param(
        0.0, unit="rad/s or m/s", minimum=0.0, doc="σ of the joint velocity noise"
    )

    def __post_init__(self) -> None:
        check_fields(self, ScenarioError, "sensor.")

    @property
    def ideal(self) -> bool:
        """True when the measurement is exactly the plant's state (every setting zero)."""
        return not (
            self.force_noise
            or self.force_bias
            or self.force_cutoff
            or self.force_delay
            or self.joint_noise
            or self.velocity_noise
        )

    def to_dict(self) -> dict[str, Any]:
        """The settings as JSON-able data (stored in a result's meta)."""
        return {
            "force_noise": self.force_noise,
            "force_bias": self.force_bias,
            "force_cutoff": self.force_cutoff,
            "force_delay": self.force_delay,
            "joint_noise": self.joint_noise,
            "velocity_noise": self.velocity_noise,
        }


class Sensors:
    """The measurement of one run: call :meth:`measure` once per control tick.

    Args:
        settings: the measurement model.
        period: the control period T [s].
        seed: seed of the noise (``sim.seed``).
    """

    def __init__(self, settings: SensorSettings, period: float, seed: int) -> None:
        self.settings = settings
        self.period = float(period)
        self._rng = np.random.default_rng(seed)
        cutoff = settings.force_cutoff
        self.alpha = 1.0 - math.exp(-2.0 * math.pi * cutoff * self.period) if cutoff else 1.0
        self._filtered: np.ndarray | None = None
        self._line: collections.deque[np.ndarray] = collections.deque(
            maxlen=settings.force_delay + 1
        )

    def measure(
        self, q: np.ndarray, v: np.ndarray, f: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The controller's readings at a tick.

        Args:
            q: (n,) joint positions. v: (n,) joint velocities. f: (k,) true contact force [N]
                (the plant's force at the tick: 0 off the surface).

        Returns:
            (q̃ (n,), ṽ (n,), f̃ (k,)), new arrays.
        """
        s = self.settings
        q_m = q + self._rng.normal(0.0, s.joint_noise, q.shape) if s.joint_noise else q.copy()
        v_m = v + self._rng.normal(0.0, s.velocity_noise, v.shape) if s.velocity_noise else v.copy()
        raw = f + s.force_bias
        if s.force_noise:
            raw = raw + self._rng.normal(0.0, s.force_noise, f.shape)
        if self._filtered is None:
            self._filtered = np.array(raw, dtype=float)
        else:
            self._filtered = self._filtered + self.alpha * (raw - self._filtered)
        self._line.append(self._filtered)
        return q_m, v_m, self._line[0].copy()

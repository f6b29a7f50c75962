"""A whole run on the oracles: the numpy plant and the numpy controller, the loop unchanged."""

from __future__ import annotations

import pytest

from hybrid_force.result import Result
from hybrid_force.sim.loop import simulate
from hybrid_force.sim.settings import Scenario
from oracles.control import use_oracle_control
from oracles.plant import use_oracle_plant


def oracle_run(monkeypatch: pytest.MonkeyPatch, scenario: Scenario) -> Result:
    """The run of ``scenario`` with :class:`~oracles.plant.OraclePlant` and the oracle
    controller (:func:`~oracles.control.use_oracle_control`), patched for this run only."""
    with monkeypatch.context() as patch:
        use_oracle_plant(patch)
        use_oracle_control(patch)
        return simulate(scenario)

"""Events (hybrid_force.events): the stored form round-trips, every kind a run can record is
known, and a real run's events are what its phases and plant say."""

from __future__ import annotations

import numpy as np
import pytest

from hybrid_force.errors import BadInputError
from hybrid_force.events import (
    EVENT_KINDS,
    Branch,
    Impact,
    LimitCrossed,
    PhaseChange,
    Release,
    RunStopped,
    Touch,
    event_from_dict,
)
from hybrid_force.phases import Phase

EXAMPLES = [
    PhaseChange(0.5, Phase.NEAR),
    PhaseChange(1.0, Phase.CONTACT),
    Touch(0.1, 2e-3),
    Impact(0.2, 0.05, 1e-4),
    Release(0.3, -1.5),
    Branch(4.0, 0.02),
    LimitCrossed(2.0, "elbow", 1.57, "joint_limit"),
    LimitCrossed(2.5, "elbow", 3.0, "velocity_limit"),
    RunStopped(7.0, "diverged"),
    RunStopped(7.0, "lost contact"),
]


@pytest.mark.parametrize("event", EXAMPLES, ids=lambda e: e.kind)
def test_stored_form_round_trips(event) -> None:
    stored = event.to_dict()
    assert stored["t"] == event.t and stored["kind"] == event.kind
    assert stored["kind"] in EVENT_KINDS
    assert event_from_dict(stored) == event


def test_stored_forms_carry_the_fields_documented_for_each_kind() -> None:
    assert PhaseChange(1.0, Phase.CONTACT).to_dict() == {"t": 1.0, "kind": "contact"}
    assert Impact(0.2, 0.05, 1e-4).to_dict() == {
        "t": 0.2, "kind": "impact", "impulse": 0.05, "speed": 1e-4
    }  # fmt: skip
    assert LimitCrossed(2.0, "elbow", 1.57, "joint_limit").to_dict() == {
        "t": 2.0, "kind": "joint_limit", "joint": "elbow", "limit": 1.57
    }  # fmt: skip
    assert RunStopped(7.0, "path").to_dict() == {"t": 7.0, "kind": "path"}


def test_unknown_kind_and_foreign_fields_are_refused() -> None:
    with pytest.raises(BadInputError, match="not one of"):
        event_from_dict({"t": 0.0, "kind": "explosion"})
    with pytest.raises(BadInputError):
        event_from_dict({"t": 0.0, "kind": "impact", "colour": "red"})


def test_an_approach_run_records_its_phases_and_one_impact_in_time_order() -> None:
    from hybrid_force.scenario.loader import load_scenario
    from hybrid_force.sim.loop import simulate

    sc = load_scenario("scenarios/rtr_plane.toml", overrides={"sim.duration": 3.0})
    result = simulate(sc)
    events = [event_from_dict(e) for e in result.events]
    kinds = [e.kind for e in events]
    assert kinds[0] == "near" and kinds.count("impact") == 1
    times = np.array([e.t for e in events])
    # the supervisor enters contact within contact_tol, the plant touches then or a step later
    t_contact, t_impact = (times[kinds.index(k)] for k in ("contact", "impact"))
    assert 0 <= t_impact - t_contact <= sc.sim.dt
    assert np.all(np.diff(times) >= 0)
    impact = next(e for e in events if isinstance(e, Impact))
    # the supervisor's approach touches at about approach_rate · contact_tol (its docstring)
    assert 0 < impact.speed < 10 * sc.control.Lambda * sc.control.contact_tol

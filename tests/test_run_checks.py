"""Tests of hybrid_force.sim.run_checks: log memory, limit violations, contact outcome."""

from __future__ import annotations

import numpy as np
import pytest

from hybrid_force.errors import BadInputError
from hybrid_force.sim.run_checks import (
    LOG_COPIES,
    check_log_memory,
    contact_outcome,
    describe,
    limit_violations,
)

INF = np.inf


def test_limit_violations_found_by_hand() -> None:
    """Joint a leaves [−1, 1] at sample 2 (worst 1.5 at t = 0.3); joint b never does; joint c
    is unbounded; b's command exceeds |u| ≤ 10 at t = 0.1 and 0.3 (worst −12)."""
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    q = np.array(
        [[0.0, 0.0, 99.0], [0.5, 0.1, -99.0], [1.2, 0.2, 1e9], [1.5, 0.3, 0.0], [0.9, 0.4, 0.0]]
    )
    u = np.array([[0.0, 1.0, 1e6], [0.0, 11.0, 0.0], [0.0, 9.0, 0.0], [0.0, -12.0, 0.0], [0, 0, 0]])
    out = limit_violations(
        ["a", "b", "c"],
        np.array([-1.0, -1.0, -INF]),
        np.array([1.0, 1.0, INF]),
        np.array([INF, 10.0, INF]),
        t,
        q,
        u,
    )
    assert out["position"] == [
        {"joint": "a", "first_t": 0.2, "worst": 1.5, "worst_t": 0.3, "limit": 1.0, "samples": 2}
    ]
    assert out["effort"] == [
        {"joint": "b", "first_t": 0.1, "worst": -12.0, "worst_t": 0.3, "limit": 10.0, "samples": 2}
    ]
    notes = describe(out, {"lost_contact": False})
    assert len(notes) == 2 and "joint a left its range" in notes[0] and "-12" in notes[1]


def test_a_value_on_its_limit_is_not_a_violation_and_the_lower_bound_counts() -> None:
    t = np.array([0.0, 1.0])
    q = np.array([[1.0], [-1.0 - 1e-3]])
    out = limit_violations(["j"], np.array([-1.0]), np.array([1.0]), np.array([5.0]),
                           t, q, np.array([[5.0], [-5.0]]))  # fmt: skip
    assert [v["limit"] for v in out["position"]] == [-1.0] and out["effort"] == []


def test_non_finite_samples_are_skipped() -> None:
    t = np.array([0.0, 1.0])
    q = np.array([[0.0], [np.nan]])
    out = limit_violations(["j"], np.array([-1.0]), np.array([1.0]), np.array([1.0]),
                           t, q, np.array([[0.0], [np.inf]]))  # fmt: skip
    assert out == {"position": [], "velocity": [], "effort": []}


@pytest.mark.parametrize(
    ("ever", "end", "events", "expected"),
    [
        (True, True, [], {"contact_at_end": True, "lost_contact": False, "left_at": None}),
        (
            True,
            False,
            [{"t": 0.5, "kind": "release"}, {"t": 0.7, "kind": "impact"},
             {"t": 0.9, "kind": "release"}],
            {"contact_at_end": False, "lost_contact": True, "left_at": 0.9},
        ),
        (False, False, [], {"contact_at_end": False, "lost_contact": False, "left_at": None}),
    ],
)  # fmt: skip
def test_contact_outcome(ever: bool, end: bool, events: list, expected: dict) -> None:
    assert contact_outcome(ever, end, events) == expected


def test_log_memory_is_refused_naming_duration_and_dt(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("hybrid_force.sim.run_checks.available_memory", lambda: 10**9)
    # 1e6 samples × 20 numbers × 8 bytes × 3 copies = 4.8e8 bytes: fits in 1e9
    assert check_log_memory(10**6, 20, 1000.0, 1e-3) == LOG_COPIES * 10**6 * 20 * 8
    with pytest.raises(BadInputError, match=r"sim.duration = 10000 s at sim.dt = 0.001 s"):
        check_log_memory(10**7, 20, 1e4, 1e-3)
    monkeypatch.setattr("hybrid_force.sim.run_checks.available_memory", lambda: None)
    check_log_memory(10**9, 20, 1e6, 1e-3)  # unknown memory: nothing refused

"""Tests of hybrid_force.phases: one definition of the phase codes, shared by every module."""

from __future__ import annotations

from hybrid_force import phases, result
from hybrid_force.control import supervisor
from hybrid_force.phases import CONTACT, FREE, NEAR, PHASE_NAMES, Phase
from hybrid_force.viz import _run_data, replay


def test_codes_names_and_labels() -> None:
    assert (FREE, NEAR, CONTACT) == (0, 1, 2)
    assert all(type(c) is int for c in (FREE, NEAR, CONTACT))  # plain ints for the kernels
    assert PHASE_NAMES == ("free", "near", "contact")
    assert [p.label for p in Phase] == list(PHASE_NAMES)
    assert Phase(2) is Phase.CONTACT and Phase.CONTACT == CONTACT


def test_every_module_uses_the_same_definition() -> None:
    assert (supervisor.FREE, supervisor.NEAR, supervisor.CONTACT) == (FREE, NEAR, CONTACT)
    assert supervisor.PHASE_NAMES is phases.PHASE_NAMES
    assert tuple(Phase) == (result.PHASE_FREE, result.PHASE_NEAR, result.PHASE_CONTACT)
    assert _run_data.CONTACT is phases.CONTACT and replay.PHASE_NAMES is phases.PHASE_NAMES

"""Tests of hybrid_force.phases: one definition of the phase codes, shared by every module."""

from __future__ import annotations

import ast
from pathlib import Path

from hybrid_force import phases, result
from hybrid_force.phases import CONTACT, FREE, NEAR, PHASE_NAMES, Phase
from hybrid_force.viz import _run_data


def test_codes_names_and_labels() -> None:
    assert (FREE, NEAR, CONTACT) == (0, 1, 2)
    assert all(type(c) is int for c in (FREE, NEAR, CONTACT))  # plain ints for the kernels
    assert PHASE_NAMES == ("free", "near", "contact")
    assert [p.label for p in Phase] == list(PHASE_NAMES)
    assert Phase(2) is Phase.CONTACT and Phase.CONTACT == CONTACT


def test_every_module_uses_the_same_definition() -> None:
    # one home: no other module of the package binds the codes or their names
    assert tuple(Phase) == (result.PHASE_FREE, result.PHASE_NEAR, result.PHASE_CONTACT)
    assert _run_data.CONTACT is phases.CONTACT
    package = Path(phases.__file__).parent
    for path in sorted(package.rglob("*.py")):
        if path.name == "phases.py" or path.stem.endswith("kernels"):
            continue  # Numba kernels hold the codes as literals (their tests check the values)
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Assign):
                bound = {n.id for t in node.targets for n in ast.walk(t) if isinstance(n, ast.Name)}
                assert not bound & {"FREE", "NEAR", "CONTACT", "PHASE_NAMES"}, path

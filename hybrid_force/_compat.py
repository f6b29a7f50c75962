"""The module paths of versions before 0.2, kept importable.

Version 0.2 grouped the modules into layers (``model/``, ``geometry/``, ``control/``,
``sim/``, ``scenario/``, ``viz/``, ``studies/``). ``import hybrid_force.robot`` and
``from hybrid_force.simulate import Scenario`` keep working: the old name is the same module
object as the new one (so ``monkeypatch.setattr("hybrid_force.robot.X", ...)`` patches the
module the code uses). ``hybrid_force.control`` and ``hybrid_force.scenario`` are packages
now and re-export what the old modules held.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
from collections.abc import Sequence
from importlib.machinery import ModuleSpec
from types import ModuleType

MOVED: dict[str, str] = {
    "hybrid_force.robot": "hybrid_force.model.robot",
    "hybrid_force.urdf_check": "hybrid_force.model.urdf_check",
    "hybrid_force._registry": "hybrid_force.model.registry",
    "hybrid_force.model_report": "hybrid_force.model.report",
    "hybrid_force.surfaces": "hybrid_force.geometry.surfaces",
    "hybrid_force.paths": "hybrid_force.geometry.paths",
    "hybrid_force.constraint": "hybrid_force.control.constraint",
    "hybrid_force.clik": "hybrid_force.control.clik",
    "hybrid_force.controller": "hybrid_force.control.controller",
    "hybrid_force.force_loop": "hybrid_force.control.force_loop",
    "hybrid_force.supervisor": "hybrid_force.control.supervisor",
    "hybrid_force.sensors": "hybrid_force.sim.sensors",
    "hybrid_force.dynamics": "hybrid_force.sim.dynamics",
    "hybrid_force.simulate": "hybrid_force.sim.loop",
    "hybrid_force.run_checks": "hybrid_force.sim.run_checks",
    "hybrid_force.plots": "hybrid_force.viz.plots",
    "hybrid_force.replay": "hybrid_force.viz.replay",
    "hybrid_force.sweep": "hybrid_force.studies.sweep",
}


class _Alias(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds an old module name and loads it as the module at its new place."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None,
        target: ModuleType | None = None,
    ) -> ModuleSpec | None:
        if fullname not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: ModuleSpec) -> ModuleType:
        return importlib.import_module(MOVED[spec.name])

    def exec_module(self, module: ModuleType) -> None:
        pass  # the new module is already executed


def install() -> None:
    """Make the old names importable (idempotent)."""
    if not any(isinstance(f, _Alias) for f in sys.meta_path):
        sys.meta_path.append(_Alias())

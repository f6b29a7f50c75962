"""hybrid_force: hybrid position–force control of robot arms on known rigid surfaces.

Reproduces and extends *Modified position-force control for a manipulator geometrically
constrained by round obstacles* (modified Arimoto law with joint-space orthogonalisation),
on Pinocchio and URDF. The names a user needs (``__all__``) are importable from here; every
other name from the module that defines it. See README.md.
"""

from __future__ import annotations

import importlib

from hybrid_force._version import VERSION as __version__
from hybrid_force.control.clik import ClikSettings, inverse_kinematics
from hybrid_force.control.controller import Controller, ControllerModel
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.control.tool import ToolSettings
from hybrid_force.errors import (
    BadInputError,
    ControlError,
    HybridForceError,
    MissingExtraError,
    ModelWarning,
    PathError,
    ReachError,
    RobotError,
    RunFailedError,
    RunWarning,
    ScenarioError,
    SurfaceError,
)
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.on_surface import check_on_surface
from hybrid_force.geometry.paths import Circle, FunctionPath, Helix, Path, paper_helix
from hybrid_force.geometry.raster import RasterPath
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.geometry.waypoints import WaypointPath
from hybrid_force.metrics import Metrics
from hybrid_force.model.loading import load_robot
from hybrid_force.model.robot import Robot
from hybrid_force.result import Result, load_result
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.loop import simulate
from hybrid_force.sim.sensors import SensorSettings
from hybrid_force.sim.settings import Scenario, SimSettings

# The edges (figures, 3D replay, sweeps, comparisons) load on first use, so `import
# hybrid_force` and a plain `hybrid-force run` do not pay for them (PEP 562 module
# __getattr__). Each name is read from the module that defines it.
_LAZY = {
    "plot_result": "hybrid_force.viz.run_figures",
    "plot_sweep": "hybrid_force.viz.sweep_plots",
    "Replay": "hybrid_force.viz.scene",
    "write_html": "hybrid_force.viz.replay",
    "run_sweep": "hybrid_force.studies.sweep",
    "run_compare": "hybrid_force.studies.compare",
}


def __getattr__(name: str) -> object:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'hybrid_force' has no attribute {name!r}")
    value: object = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


__all__ = [
    "BadInputError",
    "Circle",
    "ClikSettings",
    "ContactSettings",
    "ControlError",
    "ControlSettings",
    "Controller",
    "ControllerModel",
    "Cylinder",
    "FunctionPath",
    "FunctionSurface",
    "Helix",
    "HybridForceError",
    "Metrics",
    "MissingExtraError",
    "ModelWarning",
    "Path",
    "PathError",
    "Plane",
    "RasterPath",
    "ReachError",
    "Replay",
    "Result",
    "Robot",
    "RobotError",
    "RunFailedError",
    "RunWarning",
    "Scenario",
    "ScenarioError",
    "SensorSettings",
    "SimSettings",
    "Sphere",
    "Surface",
    "SurfaceError",
    "ToolSettings",
    "WaypointPath",
    "__version__",
    "check_on_surface",
    "inverse_kinematics",
    "load_result",
    "load_robot",
    "load_scenario",
    "paper_helix",
    "plot_result",
    "plot_sweep",
    "run_compare",
    "run_sweep",
    "simulate",
    "write_html",
]

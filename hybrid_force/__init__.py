"""hybrid_force: hybrid position–force control of robot arms on known rigid surfaces.

Reproduces and extends *Modified position-force control for a manipulator geometrically
constrained by round obstacles* (modified Arimoto law with joint-space orthogonalisation),
on Pinocchio and URDF. The public names are re-exported here; see README.md.
"""

from __future__ import annotations

import sys as _sys

from hybrid_force import _compat
from hybrid_force.control.clik import ClikSettings, DesiredJointPath, inverse_kinematics
from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.controller import Controller, ControllerModel
from hybrid_force.control.laws.arimoto import (
    Command,
    ControlTrace,
    Desired,
    Gains,
    LawWorkspace,
    default_damping_gain,
    make_gains,
)
from hybrid_force.control.supervisor import (
    CONTACT,
    FREE,
    NEAR,
    ControlSettings,
    HybridController,
)
from hybrid_force.control.tool import ToolSettings
from hybrid_force.errors import (
    BadInputError,
    ContactSettingsError,
    ControlError,
    DimensionError,
    DivergenceError,
    FrameError,
    GainError,
    HybridForceError,
    JointLimitError,
    LostContactError,
    MissingExtraError,
    OutputError,
    PathWarning,
    ReachError,
    ResultFileError,
    RobotError,
    RunFailedError,
    RunInterruptedError,
    RunWarning,
    ScenarioError,
    ScenarioValueError,
    SimSettingsError,
    SimulationError,
    SingularConfigurationError,
    SurfaceError,
    SurfaceParameterError,
    UnknownRobotError,
    URDFError,
    ViewerError,
)
from hybrid_force.geometry.paths import (
    Circle,
    FunctionPath,
    Helix,
    OnSurfaceReport,
    Path,
    PathParameterError,
    check_on_surface,
    paper_helix,
    path_from_dict,
)
from hybrid_force.geometry.raster import RasterPath
from hybrid_force.geometry.surfaces import (
    Cylinder,
    FunctionSurface,
    Plane,
    Sphere,
    Surface,
    surface_from_dict,
)
from hybrid_force.geometry.waypoints import WaypointPath
from hybrid_force.model.robot import Robot, RobotTerms, load_robot
from hybrid_force.result import Metrics, Result, load_result
from hybrid_force.scenario.loader import load_scenario, parse_override
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.dynamics import (
    Baumgarte,
    ConstrainedDynamics,
    constrained_acceleration,
    free_acceleration,
    plastic_impact,
)
from hybrid_force.sim.loop import Scenario, SimSettings, simulate
from hybrid_force.sim.sensors import SensorSettings

__version__: str  # the version in pyproject.toml, as installed: read on first use (below)

# Module paths of versions before 0.2 (hybrid_force.robot, hybrid_force.simulate, ...) stay
# importable. hybrid_force.simulate is seeded here: it names the function above, which the
# import system would otherwise replace by the module on `import hybrid_force.simulate`.
_compat.install()
_sys.modules.setdefault("hybrid_force.simulate", _sys.modules["hybrid_force.sim.loop"])

# The edges (figures, 3D replay, sweeps) and the version (importlib.metadata) load on first use,
# so `import hybrid_force` and a plain `hybrid-force run` do not pay for them (PEP 562 module
# __getattr__).
_LAZY = {
    "PlotError": "hybrid_force.viz.plots",
    "plot_result": "hybrid_force.viz.plots",
    "plot_sweep": "hybrid_force.viz.plots",
    "Replay": "hybrid_force.viz.replay",
    "ReplaySettings": "hybrid_force.viz.replay",
    "serve": "hybrid_force.viz.replay",
    "write_html": "hybrid_force.viz.replay",
    "expand": "hybrid_force.studies.sweep",
    "run_sweep": "hybrid_force.studies.sweep",
}


def __getattr__(name: str) -> object:
    value: object
    if name == "__version__":
        value = _installed_version()
    else:
        module = _LAZY.get(name)
        if module is None:
            raise AttributeError(f"module 'hybrid_force' has no attribute {name!r}")
        import importlib

        value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def _installed_version() -> str:
    """One source: the version in pyproject.toml, as installed (importlib.metadata: ~0.02 s)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("hybrid_force")
    except PackageNotFoundError:  # run from a source tree that is not installed
        return "0+unknown"


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY) | {"__version__"})


__all__ = [
    "CONTACT",
    "FREE",
    "NEAR",
    "BadInputError",
    "Baumgarte",
    "Circle",
    "ClikSettings",
    "Command",
    "ConstrainedDynamics",
    "Constraint",
    "ConstraintTerms",
    "ContactSettings",
    "ContactSettingsError",
    "ControlError",
    "ControlSettings",
    "ControlTrace",
    "Controller",
    "ControllerModel",
    "Cylinder",
    "Desired",
    "DesiredJointPath",
    "DimensionError",
    "DivergenceError",
    "FrameError",
    "FunctionPath",
    "FunctionSurface",
    "GainError",
    "Gains",
    "Helix",
    "HybridController",
    "HybridForceError",
    "JointLimitError",
    "LawWorkspace",
    "LostContactError",
    "Metrics",
    "MissingExtraError",
    "OnSurfaceReport",
    "OutputError",
    "Path",
    "PathParameterError",
    "PathWarning",
    "Plane",
    "PlotError",
    "RasterPath",
    "ReachError",
    "Replay",
    "ReplaySettings",
    "Result",
    "ResultFileError",
    "Robot",
    "RobotError",
    "RobotTerms",
    "RunFailedError",
    "RunInterruptedError",
    "RunWarning",
    "Scenario",
    "ScenarioError",
    "ScenarioValueError",
    "SensorSettings",
    "SimSettings",
    "SimSettingsError",
    "SimulationError",
    "SingularConfigurationError",
    "Sphere",
    "Surface",
    "SurfaceError",
    "SurfaceParameterError",
    "ToolSettings",
    "URDFError",
    "UnknownRobotError",
    "ViewerError",
    "WaypointPath",
    "__version__",
    "check_on_surface",
    "constrained_acceleration",
    "default_damping_gain",
    "expand",
    "free_acceleration",
    "inverse_kinematics",
    "load_result",
    "load_robot",
    "load_scenario",
    "make_gains",
    "paper_helix",
    "parse_override",
    "path_from_dict",
    "plastic_impact",
    "plot_result",
    "plot_sweep",
    "run_sweep",
    "serve",
    "simulate",
    "surface_from_dict",
    "write_html",
]

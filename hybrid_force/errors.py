"""One exception tree for hybrid_force.

Every error names what was wrong (the file, the frame, the parameter, the value)
and, where there is a finite set of valid choices, lists them. Anything a user
can cause with bad input is a subclass of :class:`BadInputError`; the command
line maps those to exit status 2 and prints ``error: <message>``.
A run that fails at run time raises :class:`SimulationError` (exit status 1).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # for annotations only: errors.py imports nothing of the package at run time
    from hybrid_force.result import Result

__all__ = [
    "BadInputError",
    "ContactSettingsError",
    "ControlError",
    "DimensionError",
    "DivergenceError",
    "FeatureUnavailableError",
    "FrameError",
    "GainError",
    "HybridForceError",
    "HybridForceWarning",
    "JointLimitError",
    "LostContactError",
    "MissingExtraError",
    "ModelWarning",
    "OutputError",
    "PathParameterError",
    "PathWarning",
    "PlotError",
    "ReachError",
    "ResultFileError",
    "RobotError",
    "RunFailedError",
    "RunInterruptedError",
    "RunWarning",
    "ScenarioError",
    "ScenarioValueError",
    "SensorError",
    "SimSettingsError",
    "SimulationError",
    "SingularConfigurationError",
    "SurfaceError",
    "SurfaceParameterError",
    "SweepError",
    "URDFError",
    "UnknownRobotError",
    "ViewerError",
    "did_you_mean",
]


class HybridForceError(Exception):
    """Base class of every error raised by hybrid_force."""


class BadInputError(HybridForceError, ValueError):
    """Input given by the user (file, parameter, option) is invalid.

    Attributes:
        key: the offending key as a scenario file spells it (``"surface.radius"``), or None
            where the error is not about one key.
        value: the offending value (None when ``key`` is None or the key is missing).
        file: the scenario file, when the error comes from one.
    """

    def __init__(
        self,
        message: str,
        *,
        key: str | None = None,
        value: object = None,
        file: str | None = None,
    ) -> None:
        super().__init__(message)
        self.key, self.value, self.file = key, value, file


# --- robot model -----------------------------------------------------------
class RobotError(BadInputError):
    """A robot model could not be loaded or used."""


class UnknownRobotError(RobotError):
    """A robot name is neither bundled, in example-robot-data, nor a file."""


class URDFError(RobotError):
    """A URDF file is missing, malformed or physically impossible."""


class FrameError(RobotError):
    """A frame name does not exist in the model."""


class DimensionError(BadInputError):
    """An array has the wrong length or shape (e.g. q of the wrong size)."""


# --- surfaces and constraints ----------------------------------------------
class SurfaceError(BadInputError):
    """A surface or constraint is invalid."""


class SurfaceParameterError(SurfaceError):
    """A surface parameter (radius, axis, normal, ...) is invalid."""


class SingularConfigurationError(SurfaceError):
    """∇Φ vanishes, or J_Φ is (near) zero, so J_Φn is undefined."""


# --- control -----------------------------------------------------------------
class ControlError(BadInputError):
    """A controller or desired path cannot be built or evaluated."""


class GainError(ControlError):
    """A gain breaks the paper's assumptions (K_d > 0, Λ > 0, β ≥ 0, γ > 0)."""


class ReachError(ControlError):
    """A task-space point is out of reach, or the Jacobian is singular on the path."""


# --- simulation, results, edges ----------------------------------------------
class SimulationError(HybridForceError):
    """A simulation failed at run time (not bad input)."""


class RunFailedError(SimulationError):
    """A run that started and did not finish as asked; ``result`` holds what it computed.

    ``result`` is the :class:`~hybrid_force.result.Result` up to the failure (its meta has
    ``status = "failed"`` and ``reason``), or None when nothing was recorded. ``reason`` is a
    short tag: "diverged", "joint limit", "lost contact", "interrupted", "path", "error".
    """

    reason = "error"

    def __init__(self, message: str, result: Result | None = None) -> None:
        super().__init__(message)
        self.result = result


class DivergenceError(RunFailedError):
    """Non-finite state or a runaway; ``result`` holds the run up to the failure."""

    reason = "diverged"


class JointLimitError(RunFailedError):
    """A joint crossed its position or velocity limit with ``sim.joint_limits = "stop"``."""

    reason = "joint limit"


class LostContactError(RunFailedError):
    """A run that started in contact without the supervisor ended off the surface."""

    reason = "lost contact"


class RunInterruptedError(RunFailedError):
    """Ctrl-C (SIGINT) or SIGTERM stopped the run; ``signal`` names which."""

    reason = "interrupted"

    def __init__(self, message: str, result: Result | None = None, signal: str = "SIGINT") -> None:
        super().__init__(message, result)
        self.signal = signal


class HybridForceWarning(UserWarning):
    """Base class of the warnings hybrid_force issues (the CLI prints ``warning: <message>``)."""


class ModelWarning(HybridForceWarning):
    """A model loaded, but its parser reported problems (e.g. a visual element it skipped)."""


class RunWarning(HybridForceWarning):
    """A run finished but did something the user must know: it left a joint's range,
    exceeded an effort limit, or lost contact with the surface (also in its summary)."""


class PathWarning(HybridForceWarning):
    """A desired path was built from input it had to adjust: a waypoint given in world
    coordinates lay farther from its surface than the tolerance and was projected onto it."""


class OutputError(BadInputError):
    """An output path cannot be used: not writable, locked by another run, or it would
    overwrite an input or another output of the same run."""


class SensorError(BadInputError):
    """A sensor setting (the ``[sensor]`` table) or the control rate is invalid."""


class ScenarioError(BadInputError):
    """A scenario file is invalid; the message names the file, table.key and value."""


class ScenarioValueError(BadInputError):
    """A field of a :class:`~hybrid_force.sim.loop.Scenario` built in Python is invalid.

    Raised by ``Scenario(...)`` itself: a wrong type or shape (robot, surfaces, path, q0, v0,
    control, sim, name, description, source), settings that do not fit the robot or the
    surfaces (K_d's size, one f_d per surface), a run starting in contact whose desired path
    or start is off a surface, or a start inside the solid. The message names the field.
    """


class SimSettingsError(BadInputError):
    """A simulation setting (:class:`~hybrid_force.sim.loop.SimSettings`, ``Baumgarte``) is
    invalid; the message names the setting as the scenario file's ``[sim]`` key spells it."""


class ContactSettingsError(BadInputError):
    """A contact setting (the ``[contact]`` table,
    :class:`~hybrid_force.sim.contact.ContactSettings`) is invalid, or the time step is too
    long for it."""


class ResultFileError(BadInputError):
    """A result file is missing, truncated or not a hybrid_force result."""


class ViewerError(BadInputError):
    """The 3D replay cannot be produced (missing model, port in use, ...)."""


# --- edges: command line, figures, sweeps, paths --------------------------------------------
class PathParameterError(BadInputError):
    """A path parameter (radius, axis, omega, ...) or a check_on_surface argument is invalid."""


class PlotError(BadInputError):
    """A run or a sweep file cannot be plotted (missing array, wrong shape, unknown column, ...)."""


class SweepError(BadInputError):
    """A sweep specification (grid, random range, samples, output directory) is invalid."""


class MissingExtraError(BadInputError):
    """A part of the toolkit was asked for whose optional library is not installed: figures
    (matplotlib, the ``plots`` extra), the 3D replay (meshcat, ``replay``) or the Dask engine
    (dask and distributed, ``dask``). The message names the extra to install.

    Attributes:
        module: the library that cannot be imported (``"matplotlib"``).
        extra: the extra that installs it (``"plots"``): ``pip install "hybrid_force[plots]"``.
        key, value: as for every :class:`BadInputError`: ``"extra"`` and the extra's name.
    """

    def __init__(self, message: str, *, module: str, extra: str) -> None:
        super().__init__(message, key="extra", value=extra)
        self.module, self.extra = module, extra


class FeatureUnavailableError(HybridForceError):
    """A subcommand's module (e.g. hybrid_force.viz.replay) is not installed in this checkout."""


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """Return ``" (did you mean 'x'?)"`` for the closest choice, or ``""``."""
    import difflib  # here: only a refused name needs it (~5 ms of a command's start)

    close = difflib.get_close_matches(word, list(choices), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""

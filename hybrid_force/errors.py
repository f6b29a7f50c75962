"""One exception tree for hybrid_force: twelve classes, each with the attributes of its cause.

Every error names what was wrong (the file, the frame, the parameter, the value) and, where
there is a finite set of valid choices, lists them. Anything a user can cause with bad input is
a :class:`BadInputError` (``key``, ``value``, ``file``, ``choices``); the command line maps those
to exit status 2 and prints ``error: <message>``. A run that starts and does not finish raises
:class:`RunFailedError` (exit status 1), whose ``reason`` says why and whose ``result`` holds the
run up to the failure.

============================  ======================================================
class                         raised for
============================  ======================================================
``HybridForceError``          the base of every error of the toolkit
``BadInputError``             any invalid input (arrays of the wrong shape, an output
                              path, a result file, a figure, the replay, a sweep, ...)
``ScenarioError``             a scenario: its file, or Scenario and the settings in Python
``RobotError``                a robot model (unknown name, URDF, frame)
``SurfaceError``              a surface (a parameter), or a configuration singular for it
``PathError``                 a desired path (a parameter, or a point off its surface)
``ControlError``              a controller or its gains
``ReachError``                a point out of reach, a Jacobian singular on the path
``MissingExtraError``         an optional library (extra) or part that is not installed
``RunFailedError``            a run that started and did not finish (``reason``)
``ModelWarning``              a model loaded, but its parser reported problems
``RunWarning``                a run, or its input, did something the user must know
============================  ======================================================
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from typing import Any

__all__ = [
    "OWN_WARNINGS",
    "BadInputError",
    "ControlError",
    "HybridForceError",
    "MissingExtraError",
    "ModelWarning",
    "PathError",
    "ReachError",
    "RobotError",
    "RunFailedError",
    "RunWarning",
    "ScenarioError",
    "SurfaceError",
    "did_you_mean",
]


class HybridForceError(Exception):
    """Base class of every error raised by hybrid_force."""


class BadInputError(HybridForceError, ValueError):
    """Input given by the user (file, parameter, option, array) is invalid.

    Attributes:
        key: the offending key as a scenario file spells it (``"surface.radius"``), or None
            where the error is not about one key.
        value: the offending value (None when ``key`` is None or the key is missing).
        file: the file the error comes from (a scenario, a model, a result), when there is one.
        choices: the valid choices, when there is a finite set of them (else None).
    """

    def __init__(
        self,
        message: str,
        *,
        key: str | None = None,
        value: object = None,
        file: str | None = None,
        choices: Iterable[str] | None = None,
    ) -> None:
        super().__init__(message)
        self.key, self.value, self.file = key, value, file
        self.choices = None if choices is None else tuple(choices)


class ScenarioError(BadInputError):
    """A scenario is invalid: its file (the message names the file, ``table.key`` and value), or
    a :class:`~hybrid_force.sim.settings.Scenario` or one of its settings (sim, contact,
    sensor) built in Python (the message names the field as the file's key spells it)."""


class RobotError(BadInputError):
    """A robot model could not be found, loaded or used: a name that is neither bundled, in
    example-robot-data nor a file, a URDF that is missing, malformed or physically impossible,
    a frame the model does not have."""


class SurfaceError(BadInputError):
    """A surface is invalid (a parameter: radius, axis, normal, ...), or the configuration is
    singular for the contact: ∇Φ vanishes, J_Φ is (near) zero, stacked constraint rows are
    dependent, or the tip's J M⁻¹ Jᵀ is singular (so the law cannot act along the normal)."""


class PathError(BadInputError):
    """A desired path is invalid: a parameter (radius, axis, omega, waypoints, ...), or a
    check_on_surface argument."""


class ControlError(BadInputError):
    """A controller or desired path cannot be built or evaluated, e.g. a gain that breaks the
    law's assumptions (K_d > 0, Λ > 0, β ≥ 0, γ > 0)."""


class ReachError(ControlError):
    """A task-space point is out of reach, or the Jacobian is singular on the path."""


class MissingExtraError(BadInputError):
    """A part of the toolkit was asked for whose optional library is not installed: figures
    (matplotlib, the ``plots`` extra), the 3D replay (meshcat, ``replay``) or the Dask engine
    (dask and distributed, ``dask``), or a subcommand's module missing from this checkout. The
    message names the extra to install.

    Attributes:
        module: the module that cannot be imported (``"matplotlib"``).
        extra: the extra that installs it (``"plots"``): ``pip install "hybrid_force[plots]"``;
            None for a module of the toolkit itself.
        key, value: as for every :class:`BadInputError`: ``"extra"`` and the extra's name.
    """

    def __init__(self, message: str, *, module: str, extra: str | None = None) -> None:
        super().__init__(message, key="extra", value=extra)
        self.module, self.extra = module, extra


class RunFailedError(HybridForceError):
    """A run that started and did not finish as asked; ``result`` holds what it computed.

    Attributes:
        reason: a short tag of why: ``"diverged"`` (non-finite state, runaway, singular
            constraint), ``"joint limit"`` (a joint crossed a limit with
            ``sim.joint_limits = "stop"``), ``"lost contact"`` (a run that started in contact
            without the supervisor ended off the surface), ``"interrupted"`` (Ctrl-C or
            SIGTERM), ``"path"`` (the desired path cannot be followed), ``"error"`` (anything
            else, e.g. lost runs of a sweep).
        result: the :class:`~hybrid_force.result.Result` up to the failure (its meta has
            ``status = "failed"`` and ``reason``), or None when nothing was recorded.
        signal: for ``reason = "interrupted"``, the signal that stopped the run
            (``"SIGINT"`` or ``"SIGTERM"``); None otherwise.
    """

    def __init__(
        self,
        message: str,
        result: Any = None,
        *,
        reason: str = "error",
        signal: str | None = None,
    ) -> None:
        super().__init__(message)
        self.result, self.reason = result, reason
        self.signal = signal if signal is not None or reason != "interrupted" else "SIGINT"


class ModelWarning(UserWarning):
    """A model loaded, but its parser reported problems (e.g. a visual element it skipped)."""


class RunWarning(UserWarning):
    """A run finished but did something the user must know: it left a joint's range, exceeded
    an effort limit, or lost contact with the surface (also in its summary); or its input was
    adjusted: a waypoint given in world coordinates lay farther from its surface than the
    tolerance and was projected onto it (the CLI prints ``warning: <message>``)."""


#: The warnings of the toolkit (the command line prints them as ``warning: <message>``; a run's
#: summary keeps them): ``warnings.simplefilter("error", ...)`` each, or ``issubclass`` both.
OWN_WARNINGS: tuple[type[UserWarning], ...] = (ModelWarning, RunWarning)


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """Return ``" (did you mean 'x'?)"`` for the closest choice, or ``""``."""
    close = difflib.get_close_matches(word, list(choices), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""

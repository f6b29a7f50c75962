"""What the replay's drawing modules read of a replay: its settings (:class:`ReplaySettings`)
and the frames it resampled (:class:`ReplayView`, which :class:`~hybrid_force.viz.scene.Replay`
satisfies), declared below the modules that draw them so that none imports the replay."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from hybrid_force.errors import BadInputError
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.model.robot import Robot
from hybrid_force.result import Result

__all__ = ["ReplaySettings", "ReplayView"]


@dataclass(frozen=True)
class ReplaySettings:
    """How a run is drawn.

    Attributes:
        fps: animation frames per second [1/s]; the run is resampled at this rate.
        force_scale: arrow length per newton [m/N].
        force_cap: longest arrow [m].
        max_path_points: at most this many points per path polyline.
        surface_opacity: opacity of the surfaces in (0, 1].
        margin: extra size around the motion for surfaces [m] (at least; 10 % of the span
            is used if larger).
        tip_radius: radius of the tip marker sphere [m].
        tool_length: length of the tool axis drawn for a run with ``[tool] orientation =
            "normal"``: a rod from the tip back along the axis [m].
        max_removal_points: at most this many points in the removal layer of a run with
            ``[removal]`` (a larger grid is averaged into voxels; docs/replay.md).
    """

    fps: float = 30.0
    force_scale: float = 0.02
    force_cap: float = 0.5
    max_path_points: int = 1500
    surface_opacity: float = 0.3
    margin: float = 0.2
    tip_radius: float = 0.045
    tool_length: float = 0.15
    max_removal_points: int = 40_000

    def __post_init__(self) -> None:
        for name in ("fps", "force_scale", "force_cap", "margin", "tip_radius", "tool_length"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise BadInputError(f"ReplaySettings.{name} must be a number, got {value!r}")
            if not math.isfinite(value) or value <= 0.0:
                raise BadInputError(f"ReplaySettings.{name} must be finite and > 0, got {value!r}")
        if self.fps > 1000.0:
            raise BadInputError(f"ReplaySettings.fps must be <= 1000, got {self.fps!r}")
        if not 0.0 < self.surface_opacity <= 1.0:
            raise BadInputError(
                f"ReplaySettings.surface_opacity must be in (0, 1], got {self.surface_opacity!r}"
            )
        for name, least in (("max_path_points", 2), ("max_removal_points", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise BadInputError(f"ReplaySettings.{name} must be an int, got {value!r}")
            if value < least:
                raise BadInputError(f"ReplaySettings.{name} must be >= {least}, got {value}")


class ReplayView(Protocol):
    """A replay's data, resampled at ``settings.fps``: n_frames frames of q (n_frames, nq),
    tip p (n_frames, 3) [m], force f (n_frames, k) [N] and phase (n_frames,)."""

    result: Result
    settings: ReplaySettings
    robot: Robot
    surfaces: list[Surface | None]
    frame_q: np.ndarray
    frame_p: np.ndarray
    frame_f: np.ndarray
    frame_phase: np.ndarray

    @property
    def n_frames(self) -> int: ...
    @property
    def duration(self) -> float: ...
    @property
    def tool_axis(self) -> np.ndarray | None: ...
    def draw(self, vis: Any, *, play: bool = True, repetitions: int = 1) -> None: ...

"""The replay scene: a run prepared for display as meshcat geometry and a real-time animation.

:class:`Replay` loads the run's robot (with its visual geometry, :mod:`.robot_visuals`) and
surfaces, resamples the run at ``fps`` frames per second and draws the scene on any meshcat
visualizer: the one recording the self-contained page (:mod:`.html_page`) or a live server's
(:mod:`.live_server`). The fixed objects are drawn by :mod:`.scene_objects`, the animation
that moves them built by :mod:`.scene_animation`. The scene's nodes are listed in
:mod:`hybrid_force.viz.replay`.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from pinocchio.visualize import MeshcatVisualizer

from hybrid_force._extras import require as require_extra
from hybrid_force.errors import BadInputError, HybridForceError
from hybrid_force.geometry.surfaces import surface_from_dict
from hybrid_force.model.loading import _is_path, load_robot, model_kind, robot_from_text
from hybrid_force.phases import PHASE_NAMES
from hybrid_force.result import Result
from hybrid_force.viz.html_page import _atomic_write_text, _RecordingWindow, _static_page
from hybrid_force.viz.live_server import _serve_replay
from hybrid_force.viz.replay_view import ReplaySettings
from hybrid_force.viz.robot_visuals import _load_options, visual_geometry
from hybrid_force.viz.scene_animation import animate
from hybrid_force.viz.scene_objects import (
    ROBOT_ROOT,
    ROOT,
    draw_static,
    motion_points,
    set_camera,
)
from hybrid_force.viz.scene_removal import (
    REMOVAL_NODE,
    RemovalLayer,
    draw_removal,
    legend,
    removal_layer,
)

__all__ = ["Replay"]


# --------------------------------------------------------------------------- helpers
def _load_result(result_or_path: Result | str | os.PathLike[str]) -> Result:
    """The Result itself, or Result.load(path) (BadInputError on a bad file)."""
    if isinstance(result_or_path, Result):
        return result_or_path
    if isinstance(result_or_path, (str, os.PathLike)):
        return Result.load(result_or_path)
    raise BadInputError(
        "replay: expected a Result or the path of a result.npz, got "
        f"{type(result_or_path).__name__}"
    )


# --------------------------------------------------------------------------- the replay
class Replay:
    """A run prepared for display: robot visuals, surfaces, paths and resampled frames.

    Args:
        result: a :class:`Result` or the path of a saved ``result.npz``.
        settings: :class:`ReplaySettings` (frame rate, force arrow scale, ...).

    Raises:
        MissingExtraError: meshcat cannot be imported (the ``replay`` extra).
        BadInputError: the file is missing, truncated or not a result.
        BadInputError: the result's robot model cannot be loaded, or a surface cannot be rebuilt.

    Attributes:
        result: the run.
        robot: the :class:`~hybrid_force.model.robot.Robot` of ``meta["robot"]``.
        surfaces: the surfaces of ``meta["surfaces"]`` (function surfaces are not drawn).
        frame_times: (F,) times of the animation frames [s] (t[0] + i / fps).
        frame_q: (F, nq) configurations at the frames (interpolated) [rad or m].
        frame_p: (F, 3) tip positions at the frames [m].
        frame_f: (F, k) contact forces at the frames [N].
        frame_phase: (F,) phase at the frames (of the latest sample at or before the frame).
        removal: the removal layer of a run with ``[removal]`` (the final depth as coloured
            points, :mod:`.scene_removal`), or None.
    """

    def __init__(
        self, result: Result | str | os.PathLike[str], settings: ReplaySettings | None = None
    ) -> None:
        require_extra("replay", "the 3D replay")  # before loading anything: it draws with meshcat
        self.settings = settings if settings is not None else ReplaySettings()
        self.result = _load_result(result)
        if self.result.n_samples < 1:
            raise BadInputError("cannot replay a result without samples (N = 0)")
        self.robot = self._load_robot()
        self.surfaces = self._load_surfaces()
        self._resample()
        self.removal: RemovalLayer | None = removal_layer(
            self.result, self.settings.max_removal_points
        )

    # ------------------------------------------------------------------ loading
    def _load_robot(self) -> Any:
        """The run's arm: rebuilt from the model text ``meta["robot"]`` stores
        (:func:`~hybrid_force.model.loading.robot_from_text`: no xacro file is expanded and the
        model file is not read), or a registry arm by its name. A result saved before results
        stored the text replays a plain URDF or MJCF file read again, never a xacro file."""

        info = self.result.meta.get("robot")
        if not isinstance(info, dict) or not isinstance(info.get("model"), str):
            raise BadInputError(
                f"result '{self.result.meta.get('name')}' has no robot model in meta['robot'] "
                f"(got {info!r}); expected {{'model': <name or model path>, 'tip': <frame>}}"
            )
        model = info["model"]
        tip = info.get("tip")
        tip = tip if isinstance(tip, str) else None
        options = _load_options(self.result.meta)
        text, fmt = info.get("model_text"), info.get("model_format")
        if text is not None and not (isinstance(text, str) and fmt in ("urdf", "mjcf")):
            raise BadInputError(
                f"result's robot '{model}': meta['robot'] has a model_text that is not a "
                f"URDF or MJCF text (model_format {fmt!r})"
            )
        if text is None and _is_path(model) and model_kind(model) == "xacro":
            raise BadInputError(
                f"result's robot '{model}' is a xacro file and the result does not store its "
                "expansion (it was saved by an older version): replaying it would expand the "
                "file, which may run code it carries; run the scenario again to replay it"
            )

        def load(**extra: Any) -> Any:
            if isinstance(text, str):
                kept = {k: v for k, v in options.items() if k != "xacro_args"}
                return robot_from_text(text, str(fmt), model, tip, **kept, **extra)
            return load_robot(model, tip=tip, **options, **extra)

        try:
            robot = load()
            if robot.nq != self.result.nq and "lock_off_chain" not in options:
                # a result made before joints off the tip's chain were locked by default
                unlocked = load(lock_off_chain=False)
                robot = unlocked if unlocked.nq == self.result.nq else robot
        except HybridForceError as exc:
            raise BadInputError(f"result's robot '{model}' cannot be found: {exc}") from exc
        except (OSError, ValueError, RuntimeError) as exc:
            raise BadInputError(f"result's robot '{model}' cannot be found: {exc}") from exc
        if robot.nq != self.result.nq:
            raise BadInputError(
                f"result's robot '{model}' has nq = {robot.nq} but the result's q has "
                f"{self.result.nq} columns"
            )
        return robot

    def _load_surfaces(self) -> list[Any]:

        out: list[Any] = []
        for i, d in enumerate(self.result.meta.get("surfaces") or []):
            if isinstance(d, dict) and d.get("type") == "function":
                out.append(None)  # a FunctionSurface cannot be rebuilt: not drawn
                continue
            try:
                out.append(surface_from_dict(d))
            except HybridForceError as exc:
                raise BadInputError(f"result's surface {i} cannot be rebuilt: {exc}") from exc
        return out

    # ------------------------------------------------------------------ resampling
    def _resample(self) -> None:
        r = self.result
        t = r.t
        fps = float(self.settings.fps)
        span = float(t[-1] - t[0])
        n_frames = math.floor(span * fps + 1e-9) + 1
        times = t[0] + np.arange(n_frames) / fps
        self.frame_times: np.ndarray = times
        self.frame_q: np.ndarray = self._interp_q(times)
        self.frame_p: np.ndarray = np.column_stack(
            [np.interp(times, t, r.p[:, j]) for j in range(3)]
        )
        f = r.f.reshape(r.n_samples, -1)
        self.frame_f: np.ndarray = np.column_stack(
            [np.interp(times, t, f[:, j]) for j in range(f.shape[1])]
        )
        latest = np.clip(
            np.searchsorted(t, times + 1e-12 * max(1.0, span), side="right") - 1, 0, None
        )
        self.frame_phase: np.ndarray = r.phase[latest]

    def _interp_q(self, times: np.ndarray) -> np.ndarray:
        """Configurations at ``times``: linear per joint, or pin.interpolate if nq > nv."""
        r = self.result
        model = self.robot.model
        if model.nq == model.nv:
            return np.column_stack([np.interp(times, r.t, r.q[:, j]) for j in range(r.nq)])

        out = np.empty((times.size, r.nq))
        for i, tau in enumerate(times):
            k = int(np.clip(np.searchsorted(r.t, tau, side="right") - 1, 0, r.n_samples - 1))
            if k == r.n_samples - 1:
                out[i] = r.q[k]
                continue
            alpha = (tau - r.t[k]) / (r.t[k + 1] - r.t[k])
            out[i] = pin.interpolate(model, r.q[k], r.q[k + 1], float(alpha))
        return out

    # ------------------------------------------------------------------ properties
    @property
    def n_frames(self) -> int:
        """Number of animation frames F."""
        return int(self.frame_times.size)

    @property
    def duration(self) -> float:
        """Animation length (F − 1) / fps [s]."""
        return (self.n_frames - 1) / float(self.settings.fps)

    def node_paths(self) -> dict[str, Any]:
        """Scene paths (meshcat, '/'-separated) of the drawn objects, by role."""
        robot_nodes = [f"/meshcat/{ROBOT_ROOT}/visuals/{g.name}" for g in self._visual_objects()]
        return {
            "robot": robot_nodes,
            "surfaces": [
                f"/meshcat/{ROOT}/surfaces/surface_{i}"
                for i, s in enumerate(self.surfaces)
                if s is not None
            ],
            "desired_path": f"/meshcat/{ROOT}/paths/desired",
            "actual_path": f"/meshcat/{ROOT}/paths/actual",
            "tip": f"/meshcat/{ROOT}/tip",
            "phase_markers": [f"/meshcat/{ROOT}/tip/{name}" for name in PHASE_NAMES],
            "force_arrows": [
                f"/meshcat/{ROOT}/force/arrow_{i}" for i in range(self.frame_f.shape[1])
            ],
            "tool_axis": None if self.tool_axis is None else f"/meshcat/{ROOT}/tool_axis",
            "removal": None if self.removal is None else f"/meshcat/{ROOT}/{REMOVAL_NODE}",
        }

    @property
    def tool_axis(self) -> np.ndarray | None:
        """(3,) the tool axis in the tip frame, for a run that controlled its direction
        (``meta["tool"]["orientation"] == "normal"``); else None (no axis is drawn)."""
        tool = self.result.meta.get("tool")
        if not isinstance(tool, dict) or tool.get("orientation") != "normal":
            return None
        try:
            axis = np.asarray(tool.get("axis"), dtype=float).reshape(3)
        except (TypeError, ValueError):
            return None
        norm = float(np.linalg.norm(axis))
        return axis / norm if np.isfinite(norm) and norm > 0 else None

    def _visual_objects(self) -> list[Any]:
        return list(self._visual_model().geometryObjects)

    def _visual_model(self) -> Any:
        """The robot's visual geometry model (built once; see :func:`visual_geometry`)."""
        cached = getattr(self, "_visual_model_cache", None)
        if cached is not None:
            return cached
        visual = visual_geometry(self.robot)
        self._visual_model_cache = visual
        return visual

    # ------------------------------------------------------------------ drawing
    def draw(self, vis: Any, *, play: bool = True, repetitions: int = 1) -> None:
        """Send the whole scene and its animation to the meshcat visualizer ``vis``.

        Args:
            vis: a ``meshcat.Visualizer`` (live, or over a recording window).
            play: start playing at once.
            repetitions: how many times the animation plays.
        """

        visual_model = self._visual_model()
        viz = MeshcatVisualizer(self.robot.model, None, visual_model)
        viz.initViewer(viewer=vis)
        viz.loadViewerModel(rootNodeName=ROBOT_ROOT)
        draw_static(vis, self)
        if self.removal is not None:
            draw_removal(vis[ROOT], self.removal)
        set_camera(vis, self.view_center(), self.result.p_d)
        animate(vis, viz, self, play=play, repetitions=repetitions)

    def view_center(self) -> np.ndarray:
        """(3,) point of the run's world frame shown at the centre of the view [m].

        The centre of the bounding box of the desired path (the task), or of the actual path if
        the desired one is not finite.
        """
        pts = self.result.p_d[np.all(np.isfinite(self.result.p_d), axis=1)]
        if not pts.size:
            pts = motion_points(self.result)
        if not pts.size:
            return np.zeros(3)
        return 0.5 * (pts.min(axis=0) + pts.max(axis=0))

    # ------------------------------------------------------------------ outputs
    def html(self) -> str:
        """The self-contained HTML recording (string; JavaScript inlined, no network access)."""
        import meshcat

        window = _RecordingWindow()
        vis = meshcat.Visualizer(window=window)
        self.draw(vis, play=True, repetitions=1)
        return _static_page(window.commands, self._page_info())

    def _page_info(self) -> dict[str, Any]:
        return {
            "name": self.result.meta.get("name"),
            "fps": float(self.settings.fps),
            "t0": float(self.frame_times[0]),
            "duration": self.duration,
            "n_frames": self.n_frames,
            "scene_offset": (-self.view_center()).tolist(),
            "nodes": self.node_paths(),
            "removal": None if self.removal is None else legend(self.removal),
        }

    def write_html(self, path: str | os.PathLike[str]) -> Path:
        """Write :meth:`html` to ``path`` atomically (temp file + rename); return the path."""
        return _atomic_write_text(Path(path), self.html())

    def serve(self, *, port: int | None = None, loop: bool = False) -> None:
        """Play the run in a live meshcat server; see :func:`serve`."""
        _serve_replay(self, port=port, loop=loop)

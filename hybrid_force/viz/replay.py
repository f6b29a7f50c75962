"""Browser 3D replay of a run with meshcat: a self-contained HTML recording or a live viewer.

A :class:`Replay` turns a :class:`~hybrid_force.result.Result` (or a saved ``result.npz``) into a
meshcat scene:

* the arm with its URDF *visual* geometry (primitives or meshes, no collision geometry), loaded
  through :class:`pinocchio.visualize.MeshcatVisualizer`, under ``/meshcat/robot/visuals/<name>``;
* every surface of the constraint, translucent, sized around the motion (a cylinder segment
  spanning the motion along its axis, a sphere, a square plate for a plane), under
  ``/meshcat/replay/surfaces/surface_<i>``;
* the desired tip path ``p_d`` (dashed colour, ``/meshcat/replay/paths/desired``) and the actual
  tip path ``p`` (``/meshcat/replay/paths/actual``) as polylines, thinned to a bounded number of
  points;
* the tip marker ``/meshcat/replay/tip`` whose visible child shows the phase
  (``free`` grey, ``near`` orange, ``contact`` green);
* one force arrow per surface, ``/meshcat/replay/force/arrow_<i>``: it ends at the tip and points
  along −n̂ (n̂ = unit surface normal to the free side), i.e. it shows the force the tool applies on
  the surface; its length is ``force_scale · |f|`` [m] capped at ``force_cap``; it is hidden when
  f = 0.

Time runs at real speed: the run is resampled at ``fps`` frames per second (linear interpolation
of q, p and f between samples; the phase of the latest sample) into a
:class:`meshcat.animation.Animation`; meshcat's own play / pause / reset / time controls drive it.
Animation time τ [s] = t − t[0].

Outputs:

* :func:`write_html`: one self-contained HTML file (meshcat's JavaScript inlined, the scene as
  inline base64 msgpack commands decoded synchronously) that makes no network request;
* :func:`serve`: a live meshcat server bound to 127.0.0.1 only; prints its URL, plays the run once
  a browser connects and always shuts the server process down (also on Ctrl-C, SIGTERM, or if
  this process dies);
* :func:`show`: an ``IPython.display.HTML`` iframe of the static recording for notebooks
  (``from hybrid_force import replay; replay.show(result)``);
* :func:`replay_command`: the ``hybrid-force replay`` subcommand.

The page exposes ``window.viewer`` (meshcat's viewer; ``viewer.animator`` seeks and plays) and
``window.hybridForceReplay`` (``fps``, ``t0``, ``duration``, ``n_frames``, ``nodes``: the scene
paths above) for scripts and tests.
"""

from __future__ import annotations

import base64
import contextlib
import html as html_lib
import json
import math
import os
import select
import signal
import subprocess
import sys
import threading
import time
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hybrid_force._atomic import atomic_file
from hybrid_force.errors import BadInputError, HybridForceError, ModelWarning, ViewerError
from hybrid_force.phases import PHASE_NAMES
from hybrid_force.result import Result

__all__ = [
    "LiveServer",
    "Replay",
    "ReplaySettings",
    "html",
    "replay_command",
    "serve",
    "show",
    "write_html",
]

#: Colours (0xRRGGBB) of the tip marker per phase: 0 free, 1 near, 2 contact.
PHASE_COLORS: tuple[int, int, int] = (0x8C8C8C, 0xF08C1E, 0x2CA02C)
_SURFACE_COLORS: tuple[int, ...] = (0x4A90D9, 0xB07AD9, 0x49B6A6, 0xD9C24A)
_DESIRED_COLOR = 0x1F77B4
_ACTUAL_COLOR = 0xD62728
_FORCE_COLOR = 0xE0C000
_ROOT = "replay"
_ROBOT_ROOT = "robot"
#: Repetitions used for an endlessly looping live replay.
_LOOP_REPETITIONS = 1_000_000
_SERVER_START_TIMEOUT = 30.0  # [s]
_ZMQ_TIMEOUT_MS = 30_000


# --------------------------------------------------------------------------- settings
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
    """

    fps: float = 30.0
    force_scale: float = 0.02
    force_cap: float = 0.5
    max_path_points: int = 1500
    surface_opacity: float = 0.3
    margin: float = 0.2
    tip_radius: float = 0.045

    def __post_init__(self) -> None:
        for name in ("fps", "force_scale", "force_cap", "margin", "tip_radius"):
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
        if isinstance(self.max_path_points, bool) or not isinstance(self.max_path_points, int):
            raise BadInputError(
                f"ReplaySettings.max_path_points must be an int, got {self.max_path_points!r}"
            )
        if self.max_path_points < 2:
            raise BadInputError(
                f"ReplaySettings.max_path_points must be >= 2, got {self.max_path_points}"
            )


# --------------------------------------------------------------------------- helpers
def _load_result(result_or_path: Result | str | os.PathLike[str]) -> Result:
    """The Result itself, or Result.load(path) (ResultFileError on a bad file)."""
    if isinstance(result_or_path, Result):
        return result_or_path
    if isinstance(result_or_path, (str, os.PathLike)):
        return Result.load(result_or_path)
    raise BadInputError(
        "replay: expected a Result or the path of a result.npz, got "
        f"{type(result_or_path).__name__}"
    )


def _rotation_y_to(direction: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) that maps the unit y axis onto the unit vector ``direction``."""
    import pinocchio as pin

    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    quat = pin.Quaternion.FromTwoVectors(np.array([0.0, 1.0, 0.0]), d)
    return np.asarray(quat.toRotationMatrix())


def _rotation_z_to(direction: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) that maps the unit z axis onto the unit vector ``direction``."""
    import pinocchio as pin

    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    quat = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), d)
    return np.asarray(quat.toRotationMatrix())


def _homogeneous(rotation: np.ndarray | None = None, translation: Any = (0, 0, 0)) -> np.ndarray:
    """4×4 homogeneous transform from a (3, 3) rotation and a (3,) translation [m]."""
    T = np.eye(4)
    if rotation is not None:
        T[:3, :3] = rotation
    T[:3, 3] = np.asarray(translation, dtype=float)
    return T


def _thin_polyline(t: np.ndarray, points: np.ndarray, max_points: int) -> np.ndarray:
    """Indices (M,) ≤ max_points of a polyline, spread evenly in time plus arc length.

    The parameter s = τ/T + ℓ/L (τ elapsed time, ℓ arc length, T and L their totals) grows
    fast where the path moves fast, so fast segments keep enough points and slow ones are
    not over-sampled. The first and last samples are always kept.
    """
    n = points.shape[0]
    if n <= max_points:
        return np.arange(n)
    finite = np.all(np.isfinite(points), axis=1)
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    steps[~(finite[1:] & finite[:-1])] = 0.0
    arc = np.concatenate(([0.0], np.cumsum(steps)))
    span_t = float(t[-1] - t[0])
    s = (t - t[0]) / span_t if span_t > 0 else np.zeros(n)
    if arc[-1] > 0:
        s = s + arc / arc[-1]
    targets = np.linspace(0.0, float(s[-1]), max_points)
    idx = np.unique(np.clip(np.searchsorted(s, targets), 0, n - 1))
    idx = np.unique(np.concatenate(([0], idx, [n - 1])))
    return idx[finite[idx]]


def _pack_command(command: Any) -> bytes:
    """msgpack bytes of a meshcat command (what the websocket would carry)."""
    import umsgpack

    return umsgpack.packb(command.lower())


class _OpenCylinderGeometry:
    """Factory for a meshcat CylinderGeometry without end caps (a surface, not a solid)."""

    @staticmethod
    def make(height: float, radius: float) -> Any:
        import meshcat.geometry as mg

        class OpenCylinder(mg.Cylinder):
            def lower(self, object_data: Any) -> dict[str, Any]:
                out = super().lower(object_data)
                out["openEnded"] = True
                out["heightSegments"] = 1
                return out

        return OpenCylinder(height, radius)


class _RecordingWindow:
    """A meshcat window that records commands instead of sending them (for static HTML)."""

    def __init__(self) -> None:
        self.commands: list[bytes] = []

    def send(self, command: Any) -> None:
        self.commands.append(_pack_command(command))


class _PlacementCapture:
    """Stand-in for ``MeshcatVisualizer.viewer`` that records ``set_transform`` per node name."""

    def __init__(self) -> None:
        self.transforms: dict[str, np.ndarray] = {}

    def __getitem__(self, name: str) -> _PlacementCapture._Node:
        return _PlacementCapture._Node(self, name)

    class _Node:
        def __init__(self, owner: _PlacementCapture, name: str) -> None:
            self.owner = owner
            self.name = name

        def set_transform(self, matrix: np.ndarray) -> None:
            self.owner.transforms[self.name] = np.array(matrix, dtype=float)

        def set_property(self, key: str, value: Any) -> None:
            """Ignored (visibility of visuals is set once on the real viewer)."""


# --------------------------------------------------------------------------- the replay
class Replay:
    """A run prepared for display: robot visuals, surfaces, paths and resampled frames.

    Args:
        result: a :class:`Result` or the path of a saved ``result.npz``.
        settings: :class:`ReplaySettings` (frame rate, force arrow scale, ...).

    Raises:
        ResultFileError: the file is missing, truncated or not a result.
        ViewerError: the result's robot model cannot be loaded, or a surface cannot be rebuilt.

    Attributes:
        result: the run.
        robot: the :class:`~hybrid_force.model.robot.Robot` of ``meta["robot"]``.
        surfaces: the surfaces of ``meta["surfaces"]`` (function surfaces are not drawn).
        frame_times: (F,) times of the animation frames [s] (t[0] + i / fps).
        frame_q: (F, nq) configurations at the frames (interpolated) [rad or m].
        frame_p: (F, 3) tip positions at the frames [m].
        frame_f: (F, k) contact forces at the frames [N].
        frame_phase: (F,) phase at the frames (of the latest sample at or before the frame).
    """

    def __init__(
        self, result: Result | str | os.PathLike[str], settings: ReplaySettings | None = None
    ) -> None:
        self.settings = settings if settings is not None else ReplaySettings()
        self.result = _load_result(result)
        if self.result.n_samples < 1:
            raise ViewerError("cannot replay a result without samples (N = 0)")
        self.robot = self._load_robot()
        self.surfaces = self._load_surfaces()
        self._resample()

    # ------------------------------------------------------------------ loading
    def _load_robot(self) -> Any:
        from hybrid_force.model.robot import load_robot

        info = self.result.meta.get("robot")
        if not isinstance(info, dict) or not isinstance(info.get("model"), str):
            raise ViewerError(
                f"result '{self.result.meta.get('name')}' has no robot model in meta['robot'] "
                f"(got {info!r}); expected {{'model': <name or model path>, 'tip': <frame>}}"
            )
        model = info["model"]
        tip = info.get("tip")
        options = _load_options(self.result.meta)
        try:
            robot = load_robot(model, tip=tip if isinstance(tip, str) else None, **options)
            if robot.nq != self.result.nq and "lock_off_chain" not in options:
                # a result made before joints off the tip's chain were locked by default
                unlocked = load_robot(
                    model, tip=tip if isinstance(tip, str) else None, **options,
                    lock_off_chain=False,
                )  # fmt: skip
                robot = unlocked if unlocked.nq == self.result.nq else robot
        except HybridForceError as exc:
            raise ViewerError(f"result's robot '{model}' cannot be found: {exc}") from exc
        except (OSError, ValueError, RuntimeError) as exc:
            raise ViewerError(f"result's robot '{model}' cannot be found: {exc}") from exc
        if robot.nq != self.result.nq:
            raise ViewerError(
                f"result's robot '{model}' has nq = {robot.nq} but the result's q has "
                f"{self.result.nq} columns"
            )
        return robot

    def _load_surfaces(self) -> list[Any]:
        from hybrid_force.geometry.surfaces import surface_from_dict

        out: list[Any] = []
        for i, d in enumerate(self.result.meta.get("surfaces") or []):
            if isinstance(d, dict) and d.get("type") == "function":
                out.append(None)  # a FunctionSurface cannot be rebuilt: not drawn
                continue
            try:
                out.append(surface_from_dict(d))
            except HybridForceError as exc:
                raise ViewerError(f"result's surface {i} cannot be rebuilt: {exc}") from exc
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
        import pinocchio as pin

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
        robot_nodes = [f"/meshcat/{_ROBOT_ROOT}/visuals/{g.name}" for g in self._visual_objects()]
        return {
            "robot": robot_nodes,
            "surfaces": [
                f"/meshcat/{_ROOT}/surfaces/surface_{i}"
                for i, s in enumerate(self.surfaces)
                if s is not None
            ],
            "desired_path": f"/meshcat/{_ROOT}/paths/desired",
            "actual_path": f"/meshcat/{_ROOT}/paths/actual",
            "tip": f"/meshcat/{_ROOT}/tip",
            "phase_markers": [f"/meshcat/{_ROOT}/tip/{name}" for name in PHASE_NAMES],
            "force_arrows": [
                f"/meshcat/{_ROOT}/force/arrow_{i}" for i in range(self.frame_f.shape[1])
            ],
        }

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
        import meshcat.animation as ma
        from pinocchio.visualize import MeshcatVisualizer

        visual_model = self._visual_model()
        viz = MeshcatVisualizer(self.robot.model, None, visual_model)
        viz.initViewer(viewer=vis)
        viz.loadViewerModel(rootNodeName=_ROBOT_ROOT)
        self._draw_static(vis)
        self._set_camera(vis)

        anim = ma.Animation(default_framerate=self.settings.fps)
        # robot: record every visual's placement per frame; animate only those that move
        capture = _PlacementCapture()
        viz.viewer = capture
        placements: dict[str, list[np.ndarray]] = {}
        for q in self.frame_q:
            viz.display(q)
            for name, T in capture.transforms.items():
                placements.setdefault(name, []).append(T)
        viz.viewer = vis
        for name, mats in placements.items():
            stack = np.stack(mats)
            vis[name].set_transform(stack[0])
            if np.max(np.abs(stack - stack[0])) > 1e-12:
                for i, T in enumerate(stack):
                    with anim.at_frame(vis, i) as frame:
                        frame[name].set_transform(T)
        self._animate_tip_and_force(vis, anim)
        vis.set_animation(anim, play=play, repetitions=repetitions)

    def _motion_points(self) -> np.ndarray:
        pts = np.vstack([self.result.p, self.result.p_d])
        return pts[np.all(np.isfinite(pts), axis=1)]

    def _draw_static(self, vis: Any) -> None:
        import meshcat.geometry as mg

        s = self.settings
        root = vis[_ROOT]
        pts = self._motion_points()
        for i, surface in enumerate(self.surfaces):
            if surface is None:
                continue
            color = _SURFACE_COLORS[i % len(_SURFACE_COLORS)]
            material = mg.MeshLambertMaterial(
                color=color, opacity=s.surface_opacity, transparent=True, side=2
            )
            material.depthWrite = False
            geometry, transform = self._surface_geometry(surface, pts)
            node = root["surfaces"][f"surface_{i}"]
            node.set_object(mg.Mesh(geometry, material))
            node.set_transform(transform)
        # paths
        r = self.result
        for name, data, color in (
            ("desired", r.p_d, _DESIRED_COLOR),
            ("actual", r.p, _ACTUAL_COLOR),
        ):
            idx = _thin_polyline(r.t, data, s.max_path_points)
            positions = np.ascontiguousarray(data[idx].T, dtype=np.float32)
            root["paths"][name].set_object(
                mg.Line(mg.PointsGeometry(positions), mg.LineBasicMaterial(color=color))
            )
        # tip marker: one sphere per phase, only the current phase visible
        for phase, pname in enumerate(PHASE_NAMES):
            root["tip"][pname].set_object(
                mg.Mesh(mg.Sphere(s.tip_radius), mg.MeshLambertMaterial(color=PHASE_COLORS[phase]))
            )
        # force arrows: unit length along +y, head at the group's origin (the tip)
        head = 0.25
        for i in range(self.frame_f.shape[1]):
            arrow = root["force"][f"arrow_{i}"]
            material = mg.MeshLambertMaterial(color=_FORCE_COLOR)
            arrow["shaft"].set_object(mg.Mesh(mg.Cylinder(1.0 - head, radius=0.012), material))
            arrow["shaft"].set_transform(_homogeneous(translation=(0, head + (1 - head) / 2, 0)))
            arrow["head"].set_object(
                mg.Mesh(mg.Cylinder(head, radiusTop=0.035, radiusBottom=0.0), material)
            )
            arrow["head"].set_transform(_homogeneous(translation=(0, head / 2, 0)))

    def _surface_geometry(self, surface: Any, pts: np.ndarray) -> tuple[Any, np.ndarray]:
        """(meshcat geometry, 4×4 placement) of a surface patch sized around the motion."""
        import meshcat.geometry as mg

        kind = surface.kind
        margin = self.settings.margin
        if kind == "cylinder":
            axis = np.asarray(surface.axis, dtype=float)
            center = np.asarray(surface.center, dtype=float)
            along = (pts - center) @ axis if pts.size else np.zeros(1)
            lo, hi = float(along.min()), float(along.max())
            pad = max(margin, 0.1 * (hi - lo))
            lo, hi = lo - pad, hi + pad
            mid = center + 0.5 * (lo + hi) * axis
            geom = _OpenCylinderGeometry.make(hi - lo, float(surface.radius))
            return geom, _homogeneous(_rotation_y_to(axis), mid)
        if kind == "sphere":
            return mg.Sphere(float(surface.radius)), _homogeneous(
                translation=np.asarray(surface.center, dtype=float)
            )
        if kind == "plane":
            normal = np.asarray(surface.normal_vector, dtype=float)
            point = np.asarray(surface.point, dtype=float)
            if pts.size:
                centroid = pts.mean(axis=0)
                foot = centroid - float((centroid - point) @ normal) * normal
                rel = pts - foot
                rel = rel - np.outer(rel @ normal, normal)
                half = float(np.max(np.linalg.norm(rel, axis=1)))
            else:
                foot, half = point, 0.0
            side = 2.0 * (half + max(margin, 0.1 * half))
            return mg.Box([side, side, 0.004]), _homogeneous(_rotation_z_to(normal), foot)
        raise ViewerError(f"cannot draw surface type {kind!r}; valid: cylinder, sphere, plane")

    def _animate_tip_and_force(self, vis: Any, anim: Any) -> None:
        root = vis[_ROOT]
        tip_node = root["tip"]
        force_root = root["force"]
        n_k = self.frame_f.shape[1]
        for i in range(self.n_frames):
            p = self.frame_p[i]
            phase = int(self.frame_phase[i])
            arrows = [self._arrow_pose(k, p, self.frame_f[i, k]) for k in range(n_k)]
            if i == 0:  # the initial state, before the animation starts
                tip_node.set_transform(_homogeneous(translation=p))
                for j, pname in enumerate(PHASE_NAMES):
                    tip_node[pname].set_property("visible", j == phase)
                for k, (T, length, visible) in enumerate(arrows):
                    node = force_root[f"arrow_{k}"]
                    node.set_transform(T)
                    node.set_property("scale", [1.0, length, 1.0])
                    node.set_property("visible", visible)
            with anim.at_frame(vis, i) as frame:
                ftip = frame[_ROOT]["tip"]
                ftip.set_transform(_homogeneous(translation=p))
                for j, pname in enumerate(PHASE_NAMES):
                    ftip[pname].set_property("visible", "boolean", j == phase)
                for k, (T, length, visible) in enumerate(arrows):
                    node = frame[_ROOT]["force"][f"arrow_{k}"]
                    node.set_transform(T)
                    node.set_property("scale", "vector3", [1.0, length, 1.0])
                    node.set_property("visible", "boolean", visible)

    def _arrow_pose(self, k: int, p: np.ndarray, f: float) -> tuple[np.ndarray, float, bool]:
        """(4×4 placement, length [m], visible) of force arrow k at tip p for force f [N].

        The arrow's local +y axis is the unit normal n̂ to the free side (the arrow, drawn from
        +y towards its head at the origin, points along −n̂ for f > 0: the force on the surface).
        """
        s = self.settings
        surface = self.surfaces[k] if k < len(self.surfaces) else None
        if surface is None or not (f != 0.0 and math.isfinite(f)):
            return _homogeneous(translation=p), 1e-6, False
        try:
            n: np.ndarray = np.asarray(surface.normal(p), dtype=np.float64)
        except HybridForceError:
            return _homogeneous(translation=p), 1e-6, False
        direction = n if f > 0 else -n
        length = min(s.force_scale * abs(float(f)), s.force_cap)
        return _homogeneous(_rotation_y_to(direction), p), max(length, 1e-6), True

    def view_center(self) -> np.ndarray:
        """(3,) point of the run's world frame shown at the centre of the view [m].

        The centre of the bounding box of the desired path (the task), or of the actual path if
        the desired one is not finite.
        """
        pts = self.result.p_d[np.all(np.isfinite(self.result.p_d), axis=1)]
        if not pts.size:
            pts = self._motion_points()
        if not pts.size:
            return np.zeros(3)
        return 0.5 * (pts.min(axis=0) + pts.max(axis=0))

    def _set_camera(self, vis: Any) -> None:
        """Centre the view on the task: shift the scene and the grid, place the camera.

        meshcat's orbit controls turn about the three.js origin, so the run's world frame
        (``/meshcat``, holding the robot and every replay object) is translated by −c, c =
        :meth:`view_center`; the grid and axes are shifted likewise so they stay on z = 0 of the
        run. Positions in the run's world frame are positions relative to the ``/meshcat`` node.
        """
        center = self.view_center()
        pts = self.result.p_d[np.all(np.isfinite(self.result.p_d), axis=1)]
        half = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) / 2 if pts.size else 0.0
        radius = max(half, 1.2)
        shift = _homogeneous(translation=-center)
        vis.set_transform(shift)
        vis["/Grid"].set_transform(shift)
        vis["/Axes"].set_transform(shift)
        # camera position in the y-up 'rotated' frame: (x, z_up, -y)
        eye = 2.4 * radius * np.array([0.8, 0.45, 0.6])
        vis["/Cameras/default/rotated/<object>"].set_property("position", eye.tolist())

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
        }

    def write_html(self, path: str | os.PathLike[str]) -> Path:
        """Write :meth:`html` to ``path`` atomically (temp file + rename); return the path."""
        return _atomic_write_text(Path(path), self.html())

    def serve(self, *, port: int | None = None, loop: bool = False) -> None:
        """Play the run in a live meshcat server; see :func:`serve`."""
        _serve_replay(self, port=port, loop=loop)


# --------------------------------------------------------------------------- robot and visuals
def _load_options(meta: dict[str, Any]) -> dict[str, Any]:
    """The :func:`~hybrid_force.model.robot.load_robot` options a result's meta records.

    From ``meta["robot"]`` (``package_dirs``, ``xacro_args``, ``lock_off_chain``: what
    :attr:`~hybrid_force.model.robot.Robot.reference` gives). A key ``meta["robot"]`` lacks is taken
    from the scenario's ``[robot]`` table (``meta["scenario"]["robot"]``): ``xacro_args`` and
    ``lock_off_chain`` as written; ``package_dirs`` (relative to the scenario file) only when
    the scenario's ``robot.model`` is a relative path without ``..`` whose parts end
    ``meta["robot"]["model"]`` (the scenario's folder is then known). Values of the wrong type
    are ignored (the arm is then loaded without them).
    """
    robot_meta = meta.get("robot")
    info: dict[str, Any] = robot_meta if isinstance(robot_meta, dict) else {}
    scenario = meta.get("scenario")
    table = scenario.get("robot") if isinstance(scenario, dict) else None
    table = table if isinstance(table, dict) else {}
    out: dict[str, Any] = {}
    args = info.get("xacro_args", table.get("xacro_args"))
    if isinstance(args, dict) and args:
        texts = {str(k): _toml_text(v) for k, v in args.items()}
        if all(isinstance(v, str) for v in texts.values()):
            out["xacro_args"] = texts
    lock = info.get("lock_off_chain", table.get("lock_off_chain"))
    if isinstance(lock, bool):
        out["lock_off_chain"] = lock
    dirs = info.get("package_dirs")
    if dirs is None:
        dirs = _scenario_package_dirs(info.get("model"), table)
    if isinstance(dirs, list) and dirs and all(isinstance(d, str) and d for d in dirs):
        out["package_dirs"] = list(dirs)
    return out


def _toml_text(value: object) -> str | None:
    """A scenario's xacro argument as the loader passes it (a TOML number or boolean as its
    text), or None for a value the loader refuses."""
    from hybrid_force.scenario.loader import xacro_argument_text

    try:
        return xacro_argument_text(value)
    except TypeError:
        return None


def _scenario_package_dirs(model: object, table: dict[str, Any]) -> list[str] | None:
    """The scenario's ``robot.package_dirs`` made absolute, when its folder can be told."""
    dirs, written = table.get("package_dirs"), table.get("model")
    if not (isinstance(dirs, list) and isinstance(model, str) and isinstance(written, str)):
        return None
    rel = Path(written)
    if rel.is_absolute() or ".." in rel.parts or not rel.parts:
        return None
    full = Path(model)
    if len(full.parts) <= len(rel.parts) or full.parts[-len(rel.parts) :] != rel.parts:
        return None
    folder = full.parents[len(rel.parts) - 1]
    return [os.path.normpath(folder / d) for d in dirs if isinstance(d, str) and d]


#: Edge of the cube drawn in place of a mesh that cannot be found or read [m].
PLACEHOLDER_SIZE = 0.05


def visual_geometry(robot: Any) -> Any:
    """The visual ``pinocchio.GeometryModel`` of a robot, with a placeholder for every mesh
    that cannot be found or read: a mesh never makes it an error.

    A URDF's (or xacro's expansion's) ``<visual><geometry><mesh filename=...>`` URIs are
    resolved here: ``package://NAME/rest`` as ``NAME/rest`` in the first of
    ``robot.package_dirs`` that holds it, ``file://path`` and plain paths (relative ones to
    the model file's folder, then to each package folder). An MJCF file's ``<asset><mesh
    file=...>`` resolve against its folder (and ``<compiler meshdir>`` or ``assetdir``).
    Each file found is loaded first by coal's cached mesh loader (which Pinocchio then reuses
    for a URDF); Pinocchio builds the geometry (``pin.buildGeomFromUrdfString`` /
    ``pin.buildGeomFromMJCF``) from a copy of the XML whose readable meshes are absolute
    paths and whose missing or unreadable ones are a cube of :data:`PLACEHOLDER_SIZE` at the
    visual's origin. Each such
    mesh gives one :class:`~hybrid_force.errors.ModelWarning` naming its URI, the link(s)
    (MJCF: bodies) that use it and why. Should Pinocchio still fail on the meshes, every mesh
    of the robot becomes a placeholder, with one warning saying why.

    Raises:
        ViewerError: the model file cannot be read or parsed any more.
    """
    import pinocchio as pin

    label = f"robot '{robot.name}'"
    if str(robot.urdf_path) != robot.name:
        label += f" ({robot.urdf_path})"
    try:
        return _build_visuals(robot, pin, placeholders_only=False, label=label)
    except ViewerError:
        raise
    except (RuntimeError, ValueError, IndexError) as exc:  # a mesh Pinocchio cannot use
        why = " ".join(str(exc).split("message:", 1)[-1].split())
    try:
        visual = _build_visuals(robot, pin, placeholders_only=True, label=label)
    except ViewerError:
        raise
    except (RuntimeError, ValueError, IndexError, OSError) as exc:
        raise ViewerError(f"cannot load the visual geometry of {label}: {exc}") from exc
    warnings.warn(
        f"{label}: Pinocchio cannot read its meshes ({why}); every mesh is drawn as a "
        f"{PLACEHOLDER_SIZE:g} m cube",
        ModelWarning,
        stacklevel=3,
    )
    return visual


class _Meshes:
    """Mesh files of one robot: resolved, loaded once, or why they are placeholders."""

    def __init__(self, all_missing: bool) -> None:
        import coal

        self.loader = coal.CachedMeshLoader()
        self.all_missing = all_missing
        self.missing: dict[str, tuple[list[str], str]] = {}  # URI: (owners, why)

    def usable(self, uri: str, path: Path | None, scale: str | None, owner: str, why: str) -> bool:
        """Whether the file ``path`` (None: not found, ``why``) can be drawn; else record
        ``uri`` and ``owner`` for the warning."""
        if path is not None and not self.all_missing:
            try:
                self.loader.load(str(path), _scale(scale))
                return True
            except (RuntimeError, ValueError) as exc:
                message = " ".join(str(exc).split("message:", 1)[-1].split())
                why = f"cannot be read ({message})"
        owners, _ = self.missing.setdefault(uri, ([], why))
        if owner not in owners:
            owners.append(owner)
        return False


def _scale(text: str | None) -> np.ndarray:
    """A mesh's scale attribute as 3 numbers (1 1 1 when absent or unreadable)."""
    try:
        values = [float(x) for x in (text or "").split()]
    except ValueError:
        values = []
    return np.array(values if len(values) == 3 else [1.0, 1.0, 1.0])


def _build_visuals(robot: Any, pin: Any, *, placeholders_only: bool, label: str) -> Any:
    """Build the visual geometry from a copy of the model's XML (see :func:`visual_geometry`);
    warn about each mesh drawn as a placeholder (not when ``placeholders_only``)."""
    import tempfile

    try:
        if robot.kind == "mjcf":
            root = ET.parse(robot.urdf_path).getroot()
        else:
            root = ET.fromstring(robot.urdf_xml)
    except (OSError, ET.ParseError) as exc:
        raise ViewerError(f"cannot load the visual geometry of {label}: {exc}") from exc
    base = Path(robot.urdf_path).resolve().parent
    dirs = [str(d) for d in robot.package_dirs]
    meshes = _Meshes(all_missing=placeholders_only)
    if robot.kind == "mjcf":
        _mjcf_meshes(root, base, meshes)
        with tempfile.TemporaryDirectory(prefix="hybrid_force_visuals_") as tmp:
            copy = Path(tmp) / Path(robot.urdf_path).name
            ET.ElementTree(root).write(copy, encoding="unicode")
            # (its binding takes no CachedMeshLoader: the meshes checked are loaded again)
            visual = pin.buildGeomFromMJCF(robot.model, str(copy), pin.GeometryType.VISUAL)
    else:
        _urdf_meshes(root, base, dirs, meshes)
        visual = pin.buildGeomFromUrdfString(
            robot.model, ET.tostring(root, encoding="unicode"), pin.GeometryType.VISUAL,
            package_dirs=dirs, mesh_loader=meshes.loader,
        )  # fmt: skip
    if not placeholders_only:
        what = "body" if robot.kind == "mjcf" else "link"
        for uri, (owners, why) in meshes.missing.items():
            names = ", ".join(f"'{o}'" for o in owners)
            warnings.warn(
                f"{label}: mesh '{uri}' of {what}{'s' if len(owners) > 1 else ''} {names} "
                f"{why}; drawn as a {PLACEHOLDER_SIZE:g} m cube",
                ModelWarning,
                stacklevel=4,
            )
    return visual


def _resolve_mesh(uri: str, base: Path, dirs: list[str]) -> Path | None:
    """The file a URDF mesh URI names, or None (see :func:`visual_geometry`): for
    ``package://NAME/rest``, the first ``DIR/NAME/rest`` that exists (as Pinocchio does)."""
    if uri.startswith("package://"):
        name, _, rest = uri[len("package://") :].partition("/")
        ok = name not in ("", ".", "..") and rest
        candidates = [Path(d) / name / rest for d in dirs] if ok else []
    else:
        path = Path(uri.removeprefix("file://"))
        if "://" in uri.removeprefix("file://"):
            candidates = []  # http:// and the like: never fetched
        elif path.is_absolute():
            candidates = [path]
        else:
            candidates = [base / path, *(Path(d) / path for d in dirs)]
    for candidate in candidates:
        if uri and candidate.is_file():
            return candidate.resolve()
    return None


def _placeholder_box(half: bool) -> str:
    """The size attribute of the placeholder cube: full edges (URDF) or half (MJCF) [m]."""
    edge = PLACEHOLDER_SIZE / 2 if half else PLACEHOLDER_SIZE
    return f"{edge:g} {edge:g} {edge:g}"


def _urdf_meshes(root: ET.Element, base: Path, dirs: list[str], meshes: _Meshes) -> None:
    """Make a URDF tree's visual meshes absolute paths, or placeholder boxes when they are
    missing or unreadable (recorded in ``meshes``)."""
    where = f"not found (package folders: {', '.join(dirs) or 'none'})"
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            geometry = visual.find("geometry")
            mesh = geometry.find("mesh") if geometry is not None else None
            if geometry is None or mesh is None:
                continue
            uri = mesh.get("filename", "")
            found = _resolve_mesh(uri, base, dirs)
            if meshes.usable(uri, found, mesh.get("scale"), link.get("name", "?"), where):
                mesh.set("filename", str(found))
                continue
            geometry.remove(mesh)
            ET.SubElement(geometry, "box", size=_placeholder_box(half=False))


def _mjcf_meshes(root: ET.Element, base: Path, meshes: _Meshes) -> None:
    """Make an MJCF tree's mesh assets absolute paths; replace the geoms of a missing or
    unreadable one by placeholder boxes (recorded in ``meshes`` under the file as written)."""
    folder = base
    for compiler in root.iter("compiler"):
        sub = compiler.get("meshdir") or compiler.get("assetdir")
        if sub:
            folder = base / sub
        for key in ("meshdir", "assetdir"):
            compiler.attrib.pop(key, None)
    assets: dict[str, tuple[str, Path | None, str | None]] = {}  # name: (file, path, scale)
    for asset in root.iter("asset"):
        for mesh in list(asset.findall("mesh")):
            file = mesh.get("file")
            if not file:
                continue
            path = Path(file) if Path(file).is_absolute() else folder / file
            found = path.resolve() if path.is_file() else None
            assets[mesh.get("name") or Path(file).stem] = (file, found, mesh.get("scale"))
            if found is not None:
                mesh.set("file", str(found))
    gone: set[str] = set()
    for body in [*root.iter("worldbody"), *root.iter("body")]:
        for geom in body.findall("geom"):
            name = geom.get("mesh")
            if name is None or name not in assets:
                continue
            file, found, scale = assets[name]
            owner = body.get("name", "world") if body.tag == "body" else "world"
            why = f"not found (in {folder})"
            if name not in gone and meshes.usable(file, found, scale, owner, why):
                continue
            gone.add(name)
            meshes.usable(file, None, None, owner, why)  # the owner joins the warning
            del geom.attrib["mesh"]
            geom.set("type", "box")
            geom.set("size", _placeholder_box(half=True))
    for asset in root.iter("asset"):
        for mesh in list(asset.findall("mesh")):
            if (mesh.get("name") or Path(mesh.get("file", "")).stem) in gone:
                asset.remove(mesh)


# --------------------------------------------------------------------------- static page
_MAIN_JS: list[str] = []


def _meshcat_js() -> str:
    """meshcat's bundled viewer JavaScript (main.min.js), read once."""
    if not _MAIN_JS:
        import meshcat

        js = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
        try:
            _MAIN_JS.append(js.read_text(encoding="utf-8"))
        except OSError as exc:
            raise ViewerError(f"meshcat's viewer JavaScript '{js}' cannot be read: {exc}") from exc
    return _MAIN_JS[0]


def _static_page(commands: list[bytes], info: dict[str, Any]) -> str:
    """A complete HTML page that builds the scene from ``commands`` without any request."""
    js = _meshcat_js().replace("</script", "<\\/script")
    blobs = ",\n".join(f'"{base64.b64encode(c).decode("ascii")}"' for c in commands)
    info_json = json.dumps(info).replace("</", "<\\/")
    title = html_lib.escape(f"hybrid_force replay: {info.get('name') or 'run'}")
    return f"""<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
body {{ margin: 0; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<script>
{js}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
window.viewer = viewer;
(function () {{
  var commands = [
{blobs}
  ];
  for (var i = 0; i < commands.length; i++) {{
    var text = atob(commands[i]);
    var bytes = new Uint8Array(text.length);
    for (var j = 0; j < text.length; j++) {{ bytes[j] = text.charCodeAt(j); }}
    viewer.handle_command_bytearray(bytes);
  }}
  var info = {info_json};
  info.ready = true;
  window.hybridForceReplay = info;
}})();
</script>
</body>
</html>
"""


def _atomic_write_text(target: Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``target`` through a temp file in its folder and os.replace."""
    if target.is_dir():
        raise ViewerError(f"cannot write HTML to '{target}': it is a directory")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ViewerError(
            f"cannot write HTML to '{target}': cannot create directory '{target.parent}': {exc}"
        ) from exc
    try:
        with atomic_file(target, "w", encoding="utf-8") as fh:
            fh.write(text)
    except OSError as exc:
        raise ViewerError(f"cannot write HTML to '{target}': {exc}") from exc
    return target


# --------------------------------------------------------------------------- live server
class _ZmqWindow:
    """A meshcat window talking to a server over zmq REQ with timeouts (never hangs forever)."""

    def __init__(self, zmq_url: str) -> None:
        import zmq

        self._zmq = zmq
        self.context: Any = zmq.Context.instance()
        self.socket = self.context.socket(zmq.REQ)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.setsockopt(zmq.SNDTIMEO, _ZMQ_TIMEOUT_MS)
        self.socket.connect(zmq_url)

    def _request(self, frames: list[bytes], timeout_ms: int = _ZMQ_TIMEOUT_MS) -> bytes:
        self.socket.send_multipart(frames)
        if not self.socket.poll(timeout_ms):
            raise ViewerError(f"the meshcat server did not answer within {timeout_ms / 1000:g} s")
        return self.socket.recv()

    def send(self, command: Any) -> None:
        import umsgpack

        data = command.lower()
        reply = self._request(
            [data["type"].encode("utf-8"), data["path"].encode("utf-8"), umsgpack.packb(data)]
        )
        if reply != b"ok":
            raise ViewerError(f"the meshcat server refused a command: {reply!r}")

    def wait_for_browser(self, timeout: float | None = None) -> bool:
        """Block until a browser is connected (True) or ``timeout`` [s] passed (False).

        Polls in short slices so Ctrl-C stays responsive. After a timeout the socket is
        unusable for further commands (REQ state); the caller then closes it.
        """
        self.socket.send(b"wait")
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if self.socket.poll(200):
                self.socket.recv()
                return True
            if deadline is not None and time.monotonic() > deadline:
                return False

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.socket.close(linger=0)


class LiveServer:
    """A meshcat server subprocess bound to 127.0.0.1 only (context manager).

    Args:
        port: web port; None picks the first free port from 7000 up.

    Raises:
        ViewerError: the port is in use or invalid, or the server did not start.

    ``url`` is the page to open; ``visualizer()`` returns a ``meshcat.Visualizer`` connected to
    it. ``close()`` (or leaving the ``with`` block) terminates the process and waits for it; the
    server also exits by itself if this process dies.
    """

    def __init__(self, port: int | None = None) -> None:
        if port is not None and (
            isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535
        ):
            raise ViewerError(f"port must be an int in 1..65535 or None (pick one), got {port!r}")
        self.port_requested = port
        self.process: subprocess.Popen[bytes] | None = None
        self._window: _ZmqWindow | None = None
        self.zmq_url = ""
        self.url = ""
        self._start()

    def _start(self) -> None:
        import hybrid_force

        package_parent = str(Path(hybrid_force.__file__).resolve().parent.parent)
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(
            [package_parent, *filter(None, [env.get("PYTHONPATH", "")])]
        )
        args = [
            sys.executable,
            "-u",
            "-c",
            "from hybrid_force.viz.replay import _server_main; _server_main()",
            str(os.getpid()),
            "" if self.port_requested is None else str(self.port_requested),
        ]
        self.process = subprocess.Popen(
            args,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
        )
        try:
            self._read_urls()
            self._window = _ZmqWindow(self.zmq_url)
        except BaseException:
            self.close()
            raise

    def _read_urls(self) -> None:
        proc = self.process
        assert proc is not None and proc.stdout is not None
        deadline = time.monotonic() + _SERVER_START_TIMEOUT
        buffer = b""
        while not (b"zmq_url=" in buffer and b"web_url=" in buffer and buffer.endswith(b"\n")):
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise ViewerError(
                    f"the meshcat server did not start within {_SERVER_START_TIMEOUT:g} s"
                )
            ready, _, _ = select.select([proc.stdout], [], [], min(remaining, 0.2))
            if ready:
                chunk = os.read(proc.stdout.fileno(), 4096)
                if chunk:
                    buffer += chunk
                    continue
            if proc.poll() is not None:
                err = proc.stderr.read().decode("utf-8", "replace") if proc.stderr else ""
                if "port in use" in err:
                    raise ViewerError(
                        f"port {self.port_requested} on 127.0.0.1 is already in use; choose "
                        "another port or omit it to pick a free one"
                    )
                raise ViewerError(
                    f"the meshcat server exited with status {proc.returncode}: "
                    f"{err.strip()[-800:] or '(no output)'}"
                )
        for line in buffer.decode("utf-8", "replace").splitlines():
            if line.startswith("zmq_url="):
                self.zmq_url = line.split("=", 1)[1].strip()
            elif line.startswith("web_url="):
                self.url = line.split("=", 1)[1].strip()

    @property
    def pid(self) -> int | None:
        """Process id of the server subprocess (None once closed)."""
        return None if self.process is None else self.process.pid

    def visualizer(self) -> Any:
        """A ``meshcat.Visualizer`` sending to this server."""
        import meshcat

        if self._window is None:
            raise ViewerError("the meshcat server is closed")
        return meshcat.Visualizer(window=self._window)

    def wait_for_browser(self, timeout: float | None = None) -> bool:
        """Block until a browser has connected (True), or ``timeout`` [s] passed (False)."""
        if self._window is None:
            raise ViewerError("the meshcat server is closed")
        return self._window.wait_for_browser(timeout)

    def close(self) -> None:
        """Terminate the server process and wait for it (idempotent)."""
        if self._window is not None:
            self._window.close()
            self._window = None
        proc = self.process
        if proc is None:
            return
        self.process = None
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                with contextlib.suppress(OSError):
                    stream.close()

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.close()


def _server_main() -> None:
    """Entry point of the server subprocess: meshcat's bridge with its web port on 127.0.0.1.

    argv: [parent pid, port or ""]. Exits when the parent process goes away, on SIGTERM, and
    ignores SIGINT (the parent shuts it down after Ctrl-C). Prints ``zmq_url=`` and ``web_url=``.
    """
    import functools
    import warnings

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = int(sys.argv[1])
    port = int(sys.argv[2]) if len(sys.argv) > 2 and sys.argv[2] else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import tornado.ioloop
        from meshcat.servers import zmqserver

    class LoopbackBridge(zmqserver.ZMQWebSocketBridge):
        def make_app(self) -> Any:
            app = super().make_app()
            app.listen = functools.partial(app.listen, address="127.0.0.1")
            return app

    try:
        bridge = LoopbackBridge(host="127.0.0.1", port=port)
    except OSError as exc:
        print(f"error: port in use: {port}: {exc}", file=sys.stderr, flush=True)
        sys.exit(3)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    loop = tornado.ioloop.IOLoop.current()

    def _watch_parent() -> None:
        if os.getppid() != parent:
            loop.stop()

    tornado.ioloop.PeriodicCallback(_watch_parent, 500).start()
    signal.signal(signal.SIGTERM, lambda *_: loop.add_callback_from_signal(loop.stop))
    bridge.run()


@contextlib.contextmanager
def _signals_raise_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise KeyboardInterrupt (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def _handler(signum: int, frame: object) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    old: dict[signal.Signals, Any] = {}
    for sig in (signal.SIGTERM, signal.SIGHUP):
        old[sig] = signal.signal(sig, _handler)
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def _serve_replay(
    replay: Replay,
    *,
    port: int | None,
    loop: bool,
    browser_timeout: float | None = None,
    announce: Callable[[str], None] | None = None,
) -> None:
    say = announce if announce is not None else (lambda msg: print(msg, flush=True))
    with _signals_raise_interrupt(), LiveServer(port) as server:
        vis = server.visualizer()
        replay.draw(vis, play=True, repetitions=_LOOP_REPETITIONS if loop else 1)
        say(f"replay of '{replay.result.meta.get('name') or 'run'}' at {server.url}")
        say("open it in a browser; Ctrl-C stops the server")
        if not server.wait_for_browser(browser_timeout):
            say("no browser connected; stopping the server")
            return
        if loop:
            while True:
                time.sleep(0.5)
        time.sleep(replay.duration + 0.5)


# --------------------------------------------------------------------------- public functions
def html(result_or_path: Result | str | os.PathLike[str], *, fps: float = 30.0) -> str:
    """The self-contained HTML replay of a run as a string (see :meth:`Replay.html`)."""
    return Replay(result_or_path, ReplaySettings(fps=fps)).html()


def write_html(
    result_or_path: Result | str | os.PathLike[str],
    path: str | os.PathLike[str],
    *,
    fps: float = 30.0,
) -> Path:
    """Write the self-contained HTML replay of a run to ``path`` atomically; return the path.

    The page has meshcat's viewer JavaScript inlined and makes no network request; it plays the
    run at real speed, resampled at ``fps`` frames per second.

    Raises:
        ResultFileError: ``result_or_path`` is a missing, truncated or non-result file.
        ViewerError: the result's robot cannot be found, or ``path`` cannot be written.
    """
    return Replay(result_or_path, ReplaySettings(fps=fps)).write_html(path)


def serve(
    result_or_path: Result | str | os.PathLike[str],
    *,
    port: int | None = None,
    loop: bool = False,
    fps: float = 30.0,
    browser_timeout: float | None = None,
) -> None:
    """Replay a run in a live meshcat viewer served on 127.0.0.1 only.

    Starts a meshcat server subprocess (web port ``port``, or the first free one from 7000),
    prints its URL, waits until a browser connects, plays the run in real time (forever with
    ``loop=True``) and returns; the server process is terminated in every case, including
    Ctrl-C (KeyboardInterrupt is re-raised after the shutdown), SIGTERM/SIGHUP (turned into
    KeyboardInterrupt) and the death of this process (the server watches its parent).

    Args:
        browser_timeout: stop waiting for a browser after this many seconds [s] (None: wait).

    Raises:
        ResultFileError, ViewerError: as :func:`write_html`; ViewerError also when ``port``
            is already in use.
    """
    replay = Replay(result_or_path, ReplaySettings(fps=fps))
    _serve_replay(replay, port=port, loop=loop, browser_timeout=browser_timeout)


def show(
    result_or_path: Result | str | os.PathLike[str], *, fps: float = 30.0, height: int = 480
) -> Any:
    """Notebook display: an ``IPython.display.HTML`` iframe holding the static replay.

    Works offline and without a server (the recording is inlined with ``srcdoc``)::

        from hybrid_force import replay
        replay.show(result)
    """
    from IPython.display import HTML

    page = Replay(result_or_path, ReplaySettings(fps=fps)).html()
    return HTML(
        f'<div style="height: {int(height)}px; width: 100%; resize: both; overflow: hidden">'
        f'<iframe srcdoc="{html_lib.escape(page, quote=True)}" '
        'style="width: 100%; height: 100%; border: none"></iframe></div>'
    )


def replay_command(args: Any) -> int:
    """The ``hybrid-force replay RESULT.npz [--html FILE] [--port N]`` subcommand.

    ``args.result``: path of a result.npz; ``args.html``: write the HTML there instead of serving
    (None to serve); ``args.port``: web port of the live server (None: pick a free one).
    Returns 0 on success, 130 after Ctrl-C; bad input raises BadInputError (exit 2 in the CLI).
    """
    html_path = getattr(args, "html", None)
    if html_path is not None:
        from hybrid_force.run_output import RunOutput

        # never write the page over the result it replays, or over its summary or figures
        source = Path(args.result)
        html_path = RunOutput(source.parent, inputs=[source]).check_extra("--html", html_path)
        out = write_html(args.result, html_path)
        size = out.stat().st_size
        print(f"wrote {out} ({size / 1e6:.2f} MB)")
        return 0
    try:
        serve(args.result, port=getattr(args, "port", None))
    except KeyboardInterrupt:
        print("interrupted; meshcat server stopped", file=sys.stderr)
        return 130
    return 0

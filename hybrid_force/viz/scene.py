"""The replay scene: a run as meshcat geometry and a real-time animation.

:class:`Replay` loads the run's robot (with its visual geometry, :mod:`.robot_visuals`) and
surfaces, resamples the run at ``fps`` frames per second and draws the scene on any meshcat
visualizer: the one recording the self-contained page (:mod:`.html_page`) or a live server's
(:mod:`.live_server`). The scene's nodes are listed in :mod:`hybrid_force.viz.replay`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hybrid_force.errors import BadInputError, HybridForceError, ViewerError
from hybrid_force.phases import PHASE_NAMES
from hybrid_force.result import Result
from hybrid_force.viz.html_page import _atomic_write_text, _RecordingWindow, _static_page
from hybrid_force.viz.live_server import _serve_replay
from hybrid_force.viz.robot_visuals import _load_options, visual_geometry

__all__ = ["PHASE_COLORS", "Replay", "ReplaySettings"]

#: Colours (0xRRGGBB) of the tip marker per phase: 0 free, 1 near, 2 contact.
PHASE_COLORS: tuple[int, int, int] = (0x8C8C8C, 0xF08C1E, 0x2CA02C)
_SURFACE_COLORS: tuple[int, ...] = (0x4A90D9, 0xB07AD9, 0x49B6A6, 0xD9C24A)
_DESIRED_COLOR = 0x1F77B4
_ACTUAL_COLOR = 0xD62728
_FORCE_COLOR = 0xE0C000
_TOOL_COLOR = 0x303030
_ROOT = "replay"
_ROBOT_ROOT = "robot"


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
        tool_length: length of the tool axis drawn for a run with ``[tool] orientation =
            "normal"``: a rod from the tip back along the axis [m].
    """

    fps: float = 30.0
    force_scale: float = 0.02
    force_cap: float = 0.5
    max_path_points: int = 1500
    surface_opacity: float = 0.3
    margin: float = 0.2
    tip_radius: float = 0.045
    tool_length: float = 0.15

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


def _rotation_onto(axis: int, direction: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) that maps the unit vector of ``axis`` (0 x, 1 y, 2 z) onto the
    unit vector along ``direction`` (3,)."""
    import pinocchio as pin

    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    quat = pin.Quaternion.FromTwoVectors(np.eye(3)[axis], d)
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
            "tool_axis": None if self.tool_axis is None else f"/meshcat/{_ROOT}/tool_axis",
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

    def _tool_poses(self) -> list[np.ndarray]:
        """4×4 placement of the tool rod per frame: +y along −a (a = R(q) â), origin at the tip."""
        import pinocchio as pin

        axis = self.tool_axis
        assert axis is not None
        model, data, fid = self.robot.model, self.robot.new_data(), self.robot.tip_id
        poses = []
        for q in self.frame_q:
            pin.forwardKinematics(model, data, q)
            M = pin.updateFramePlacement(model, data, fid)
            poses.append(_homogeneous(_rotation_onto(1, -(M.rotation @ axis)), M.translation))
        return poses

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
        if self.tool_axis is not None:
            for i, T in enumerate(self._tool_poses()):
                if i == 0:
                    vis[_ROOT]["tool_axis"].set_transform(T)
                with anim.at_frame(vis, i) as frame:
                    frame[_ROOT]["tool_axis"].set_transform(T)
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
        if self.tool_axis is not None:  # the tool: a rod from the tip back along its axis
            rod = root["tool_axis"]["rod"]
            rod.set_object(
                mg.Mesh(
                    mg.Cylinder(s.tool_length, radius=0.006),
                    mg.MeshLambertMaterial(color=_TOOL_COLOR),
                )
            )
            rod.set_transform(_homogeneous(translation=(0, s.tool_length / 2, 0)))

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
            return geom, _homogeneous(_rotation_onto(1, axis), mid)
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
            return mg.Box([side, side, 0.004]), _homogeneous(_rotation_onto(2, normal), foot)
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
        return _homogeneous(_rotation_onto(1, direction), p), max(length, 1e-6), True

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

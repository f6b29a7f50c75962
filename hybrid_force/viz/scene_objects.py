"""The replay's fixed meshcat objects: surfaces, paths, tip markers, force arrows, tool rod.

:func:`draw_static` sends every object of a :class:`~hybrid_force.viz.scene.Replay` that does
not depend on the frame (its geometry and material) to a meshcat visualizer, and
:func:`set_camera` centres the view on the task; the animation that moves them is built in
:mod:`hybrid_force.viz.scene_animation`. The node paths are listed in
:mod:`hybrid_force.viz.replay`. Lengths in metres, forces in newtons.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from hybrid_force.errors import BadInputError, HybridForceError
from hybrid_force.phases import PHASE_NAMES

if TYPE_CHECKING:  # annotations only
    from hybrid_force.result import Result
    from hybrid_force.viz.replay_view import ReplaySettings, ReplayView

__all__ = ["PHASE_COLORS", "arrow_pose", "draw_static", "motion_points", "set_camera"]

#: Colours (0xRRGGBB) of the tip marker per phase: 0 free, 1 near, 2 contact.
PHASE_COLORS: tuple[int, int, int] = (0x8C8C8C, 0xF08C1E, 0x2CA02C)
_SURFACE_COLORS: tuple[int, ...] = (0x4A90D9, 0xB07AD9, 0x49B6A6, 0xD9C24A)
_DESIRED_COLOR = 0x1F77B4
_ACTUAL_COLOR = 0xD62728
_FORCE_COLOR = 0xE0C000
_TOOL_COLOR = 0x303030
#: The scene nodes of the replay's own objects and of the robot's visuals.
ROOT = "replay"
ROBOT_ROOT = "robot"


def _rotation_onto(axis: int, direction: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) that maps the unit vector of ``axis`` (0 x, 1 y, 2 z) onto the
    unit vector along ``direction`` (3,)."""

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


def motion_points(result: Result) -> np.ndarray:
    """(M, 3) the finite points of the run's actual and desired tip paths [m]."""
    pts = np.vstack([result.p, result.p_d])
    return pts[np.all(np.isfinite(pts), axis=1)]


def draw_static(vis: Any, replay: ReplayView) -> None:
    """Send the replay's surfaces, paths, tip markers, force arrows and tool rod to ``vis``
    (a ``meshcat.Visualizer``), each at rest; :mod:`.scene_animation` moves them."""
    import meshcat.geometry as mg

    s = replay.settings
    root = vis[ROOT]
    pts = motion_points(replay.result)
    for i, surface in enumerate(replay.surfaces):
        if surface is None:
            continue
        color = _SURFACE_COLORS[i % len(_SURFACE_COLORS)]
        # depthWrite as a keyword: meshcat sends only its own and the keyword properties
        material = mg.MeshLambertMaterial(
            color=color, opacity=s.surface_opacity, transparent=True, side=2, depthWrite=False
        )
        geometry, transform = _surface_geometry(surface, pts, s.margin)
        node = root["surfaces"][f"surface_{i}"]
        node.set_object(mg.Mesh(geometry, material))
        node.set_transform(transform)
    # paths
    r = replay.result
    for name, data, color in (
        ("desired", r.p_d, _DESIRED_COLOR),
        ("actual", r.p, _ACTUAL_COLOR),
    ):
        idx = _thin_polyline(r.t, data, s.max_path_points)
        positions = np.ascontiguousarray(data[idx].T, dtype=np.float32)
        root["paths"][name].set_object(
            mg.Line(mg.PointsGeometry(positions), mg.LineBasicMaterial(color=color))
        )
    # tip marker: one sphere per phase, only the current phase visible; a ball-end tool's
    # marker is its ball (the tip is its centre: the ball touches the drawn part)
    tool = r.meta.get("tool")
    ball = tool.get("radius", 0.0) if isinstance(tool, dict) else 0.0
    size = float(ball) if isinstance(ball, int | float) and ball > 0 else s.tip_radius
    for phase, pname in enumerate(PHASE_NAMES):
        root["tip"][pname].set_object(
            mg.Mesh(mg.Sphere(size), mg.MeshLambertMaterial(color=PHASE_COLORS[phase]))
        )
    # force arrows: unit length along +y, head at the group's origin (the tip)
    head = 0.25
    for i in range(replay.frame_f.shape[1]):
        arrow = root["force"][f"arrow_{i}"]
        material = mg.MeshLambertMaterial(color=_FORCE_COLOR)
        arrow["shaft"].set_object(mg.Mesh(mg.Cylinder(1.0 - head, radius=0.012), material))
        arrow["shaft"].set_transform(_homogeneous(translation=(0, head + (1 - head) / 2, 0)))
        arrow["head"].set_object(
            mg.Mesh(mg.Cylinder(head, radiusTop=0.035, radiusBottom=0.0), material)
        )
        arrow["head"].set_transform(_homogeneous(translation=(0, head / 2, 0)))
    if replay.tool_axis is not None:  # the tool: a rod from the tip back along its axis
        rod = root["tool_axis"]["rod"]
        rod.set_object(
            mg.Mesh(
                mg.Cylinder(s.tool_length, radius=0.006),
                mg.MeshLambertMaterial(color=_TOOL_COLOR),
            )
        )
        rod.set_transform(_homogeneous(translation=(0, s.tool_length / 2, 0)))


def _surface_geometry(surface: Any, pts: np.ndarray, margin: float) -> tuple[Any, np.ndarray]:
    """(meshcat geometry, 4×4 placement) of a surface patch sized around the motion's points
    pts (M, 3), at least ``margin`` [m] beyond them: the surface's own grid
    (``Surface.patch``) as a triangle mesh, or a mesh part's own triangles."""
    import meshcat.geometry as mg

    if callable(getattr(surface, "triangles", None)):  # a mesh part draws its own triangles
        vertices, triangles = surface.triangles(pts, margin)
        return (
            mg.TriangularMeshGeometry(
                np.ascontiguousarray(vertices, dtype=np.float32),
                np.ascontiguousarray(triangles, dtype=np.uint32),
            ),
            np.eye(4),
        )
    grid = surface.patch(pts, margin)
    if grid is None:
        raise BadInputError(f"cannot draw surface {surface!r}: it gives no patch (Surface.patch)")
    n, m, _ = grid.shape
    corner = (np.arange(n - 1)[:, None] * m + np.arange(m - 1)[None, :]).ravel()
    faces = np.concatenate(
        [
            np.stack([corner, corner + m, corner + 1], axis=1),
            np.stack([corner + 1, corner + m, corner + m + 1], axis=1),
        ]
    )
    vertices = np.ascontiguousarray(grid.reshape(-1, 3), dtype=np.float32)
    return mg.TriangularMeshGeometry(vertices, faces.astype(np.uint32)), np.eye(4)


def arrow_pose(
    surface: Any, p: np.ndarray, f: float, settings: ReplaySettings
) -> tuple[np.ndarray, float, bool]:
    """(4×4 placement, length [m], visible) of the force arrow of ``surface`` (None: not
    drawn) at tip p (3,) [m] for its force f [N].

    The arrow's local +y axis is the unit normal n̂ to the free side (the arrow, drawn from
    +y towards its head at the origin, points along −n̂ for f > 0: the force on the surface).
    """
    s = settings
    if surface is None or not (f != 0.0 and math.isfinite(f)):
        return _homogeneous(translation=p), 1e-6, False
    try:
        n: np.ndarray = np.asarray(surface.normal(p), dtype=np.float64)
    except HybridForceError:
        return _homogeneous(translation=p), 1e-6, False
    direction = n if f > 0 else -n
    length = min(s.force_scale * abs(float(f)), s.force_cap)
    return _homogeneous(_rotation_onto(1, direction), p), max(length, 1e-6), True


def set_camera(vis: Any, center: np.ndarray, p_d: np.ndarray) -> None:
    """Centre the view on the task: shift the scene and the grid, place the camera.

    meshcat's orbit controls turn about the three.js origin, so the run's world frame
    (``/meshcat``, holding the robot and every replay object) is translated by −c, c =
    ``center`` (3,) [m] (:meth:`~hybrid_force.viz.scene.Replay.view_center`); the grid and
    axes are shifted likewise so they stay on z = 0 of the run. Positions in the run's world
    frame are positions relative to the ``/meshcat`` node. The camera's distance grows with
    the size of the desired path p_d (N, 3) [m].
    """
    pts = p_d[np.all(np.isfinite(p_d), axis=1)]
    half = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) / 2 if pts.size else 0.0
    radius = max(half, 1.2)
    shift = _homogeneous(translation=-center)
    vis.set_transform(shift)
    vis["/Grid"].set_transform(shift)
    vis["/Axes"].set_transform(shift)
    # camera position in the y-up 'rotated' frame: (x, z_up, -y)
    eye = 2.4 * radius * np.array([0.8, 0.45, 0.6])
    vis["/Cameras/default/rotated/<object>"].set_property("position", eye.tolist())

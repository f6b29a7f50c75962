"""The replay's animation: every moving node's placement at each frame of a run.

:func:`animate` records, for each frame of a :class:`~hybrid_force.viz.scene.Replay`, the
robot's visual placements (only those that move are animated), the tip marker and the
visibility of its phase, the force arrows' placement, length and visibility, and the tool rod,
into one ``meshcat.animation.Animation``; meshcat's own controls play it at the replay's
``fps``. The objects it moves are drawn by :mod:`hybrid_force.viz.scene_objects`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from hybrid_force.phases import PHASE_NAMES
from hybrid_force.viz.scene_objects import ROOT, _homogeneous, _rotation_onto, arrow_pose

if TYPE_CHECKING:  # annotations only
    from hybrid_force.viz.replay_view import ReplayView

__all__ = ["animate"]


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


def animate(
    vis: Any, viz: Any, replay: ReplayView, *, play: bool = True, repetitions: int = 1
) -> None:
    """Send the replay's animation to ``vis`` (a ``meshcat.Visualizer``) and set every moving
    node at its first frame.

    Args:
        vis: the visualizer the static scene was drawn on.
        viz: the ``pinocchio.visualize.MeshcatVisualizer`` of the robot's visuals on ``vis``.
        replay: the run, resampled at its frames.
        play: start playing at once.
        repetitions: how many times the animation plays.
    """
    import meshcat.animation as ma

    anim = ma.Animation(default_framerate=replay.settings.fps)
    # robot: record every visual's placement per frame; animate only those that move
    capture = _PlacementCapture()
    viz.viewer = capture
    placements: dict[str, list[np.ndarray]] = {}
    for q in replay.frame_q:
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
    _animate_tip_and_force(vis, anim, replay)
    if replay.tool_axis is not None:
        for i, T in enumerate(_tool_poses(replay)):
            if i == 0:
                vis[ROOT]["tool_axis"].set_transform(T)
            with anim.at_frame(vis, i) as frame:
                frame[ROOT]["tool_axis"].set_transform(T)
    vis.set_animation(anim, play=play, repetitions=repetitions)


def _animate_tip_and_force(vis: Any, anim: Any, replay: ReplayView) -> None:
    """Tip marker (placement, visible phase) and force arrows at every frame."""
    root = vis[ROOT]
    tip_node = root["tip"]
    force_root = root["force"]
    n_k = replay.frame_f.shape[1]
    # a surface per force column; a missing or function surface has no arrow
    surfaces = [replay.surfaces[k] if k < len(replay.surfaces) else None for k in range(n_k)]
    for i in range(replay.n_frames):
        p = replay.frame_p[i]
        phase = int(replay.frame_phase[i])
        arrows = [
            arrow_pose(surfaces[k], p, replay.frame_f[i, k], replay.settings) for k in range(n_k)
        ]
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
            ftip = frame[ROOT]["tip"]
            ftip.set_transform(_homogeneous(translation=p))
            for j, pname in enumerate(PHASE_NAMES):
                ftip[pname].set_property("visible", "boolean", j == phase)
            for k, (T, length, visible) in enumerate(arrows):
                node = frame[ROOT]["force"][f"arrow_{k}"]
                node.set_transform(T)
                node.set_property("scale", "vector3", [1.0, length, 1.0])
                node.set_property("visible", "boolean", visible)


def _tool_poses(replay: ReplayView) -> list[np.ndarray]:
    """4×4 placement of the tool rod per frame: +y along −a (a = R(q) â), origin at the tip."""

    axis = replay.tool_axis
    assert axis is not None
    robot = replay.robot
    model, data, fid = robot.model, robot.new_data(), robot.tip_id
    poses = []
    for q in replay.frame_q:
        pin.forwardKinematics(model, data, q)
        M = pin.updateFramePlacement(model, data, fid)
        poses.append(_homogeneous(_rotation_onto(1, -(M.rotation @ axis)), M.translation))
    return poses

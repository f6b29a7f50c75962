"""Registry of robot models known by name.

Maps a short name (``"rtr"``, ``"ur5"``, ``"panda"``, ...) to a URDF file, the package
directories Pinocchio needs to resolve its ``package://`` mesh URIs, and a sensible default
tip frame (the point of the tool that touches the surface).

Two sources:

* ``"bundled"``: URDFs shipped with hybrid_force (``robots/`` at the top of the repository,
  installed as ``hybrid_force/robots/`` inside the wheel). Only the paper's RTR arm.
* ``"example-robot-data"``: arms from the PyPI data-only wheel example-robot-data 6.x, found
  through :func:`importlib.metadata.files`; their mesh URIs are
  ``package://example-robot-data/robots/...`` so the package directory is
  ``site-packages/cmeel.prefix/share``.

This module imports no heavy dependency (no Pinocchio); it only finds files.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from hybrid_force.errors import RobotError, did_you_mean

__all__ = ["RobotEntry", "bundled_robots_dir", "known_robots", "resolve_robot"]

Source = Literal["bundled", "example-robot-data"]

_ERD_DIST = "example-robot-data"
_ERD_PREFIX = "cmeel.prefix/share/example-robot-data/robots/"


@dataclass(frozen=True)
class RobotEntry:
    """One robot model known by name.

    Attributes:
        name: short name used by ``load_robot(name)`` and the command line.
        urdf_path: absolute path of the URDF file.
        package_dirs: directories in which ``package://<pkg>/...`` URIs are resolved
            (empty for bundled models, which use only primitive shapes).
        default_tip: frame used as the tool tip when the caller names none.
        source: ``"bundled"`` or ``"example-robot-data"``.
        description: one line for humans.
        locked_joints: joints held at their neutral value (e.g. the Panda's fingers), so the
            model is the arm alone.
    """

    name: str
    urdf_path: Path
    package_dirs: tuple[str, ...]
    default_tip: str
    source: Source
    description: str
    locked_joints: tuple[str, ...] = ()


@dataclass(frozen=True)
class _ERDModel:
    """An example-robot-data model: its URDF relative to the robots folder, and its tip."""

    name: str
    relative_urdf: str
    default_tip: str
    description: str
    locked_joints: tuple[str, ...] = ()


# Default tips chosen after listing the frames of each model (tool flange or hand TCP).
_ERD_MODELS: tuple[_ERDModel, ...] = (
    _ERDModel(
        "ur3", "ur_description/urdf/ur3_robot.urdf", "tool0", "Universal Robots UR3, 6 joints"
    ),
    _ERDModel(
        "ur5", "ur_description/urdf/ur5_robot.urdf", "tool0", "Universal Robots UR5, 6 joints"
    ),
    _ERDModel(
        "ur10", "ur_description/urdf/ur10_robot.urdf", "tool0", "Universal Robots UR10, 6 joints"
    ),
    _ERDModel(
        "panda",
        "panda_description/urdf/panda.urdf",
        "panda_hand_tcp",
        "Franka Emika Panda, 7 joints (the 2 finger joints are locked)",
        ("panda_finger_joint1", "panda_finger_joint2"),
    ),
    _ERDModel(
        "z1",
        "z1_description/urdf/z1.urdf",
        "link06",
        "Unitree Z1, 6 arm joints + 1 gripper joint (tip: wrist flange)",
    ),
    _ERDModel("xarm7", "xarm_description/urdf/xarm7.urdf", "link_eef", "UFACTORY xArm7, 7 joints"),
    _ERDModel(
        "g1",
        "g1_description/urdf/g1_29dof_rev_1_0.urdf",
        "right_rubber_hand",
        "Unitree G1 humanoid, 29 joints, fixed pelvis (benchmarks; tip: right hand)",
    ),
)


def bundled_robots_dir() -> Path | None:
    """Directory holding the bundled URDFs, or None if neither candidate exists.

    Looks first inside the installed package (``hybrid_force/robots``, put there by the
    wheel's force-include), then at the top of a source checkout (``<repo>/robots``).
    """
    package = Path(__file__).resolve().parents[1]  # hybrid_force/
    candidates = (package / "robots", package.parent / "robots")
    for candidate in candidates:
        if (candidate / "rtr.urdf").is_file():
            return candidate.resolve()
    return None


def _bundled_entries() -> list[RobotEntry]:
    folder = bundled_robots_dir()
    if folder is None:
        return []
    return [
        RobotEntry(
            name="rtr",
            urdf_path=folder / "rtr.urdf",
            package_dirs=(),
            default_tip="tip",
            source="bundled",
            description=(
                "the paper's RTR arm (section 6): continuous revolute z, prismatic z, revolute"
            ),
        )
    ]


@functools.cache
def _erd_share_dir() -> Path | None:
    """``site-packages/cmeel.prefix/share`` of example-robot-data, or None if not installed."""
    import importlib.metadata  # here: a run of a bundled robot needs none of it (~0.02 s)

    try:
        files = importlib.metadata.files(_ERD_DIST)
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in files or ():
        text = str(f).replace("\\", "/")
        if text.startswith(_ERD_PREFIX) and text.endswith(".urdf"):
            # f is relative to site-packages: strip its parts from the located path.
            located = Path(str(f.locate())).resolve()
            site_packages = located.parents[len(Path(text).parts) - 1]
            return site_packages / "cmeel.prefix" / "share"
    return None


def _erd_entries() -> list[RobotEntry]:
    share = _erd_share_dir()
    if share is None:
        return []
    robots = share / "example-robot-data" / "robots"
    entries = []
    for model in _ERD_MODELS:
        path = robots / model.relative_urdf
        if path.is_file():
            entries.append(
                RobotEntry(
                    name=model.name,
                    urdf_path=path,
                    package_dirs=(str(share),),
                    default_tip=model.default_tip,
                    source="example-robot-data",
                    description=model.description,
                    locked_joints=model.locked_joints,
                )
            )
    return entries


def known_robots() -> list[RobotEntry]:
    """Every robot known by name: bundled first, then example-robot-data, in a fixed order."""
    return _bundled_entries() + _erd_entries()


def resolve_robot(name: str) -> RobotEntry:
    """Return the registry entry called ``name``.

    A name is never a file: :func:`hybrid_force.model.loading.load_robot` sends here every text that
    neither ends with ``.urdf`` nor holds a path separator, even if a file of that name exists
    in the working directory.

    Raises:
        RobotError: no robot has that name; the message lists the known names, the
            closest match, and how to use a file instead (a path such as ``./name``).
    """
    # the bundled robots first, as in known_robots(): a bundled name is found without reading
    # example-robot-data's installed-file list
    for entry in _bundled_entries():
        if entry.name == name:
            return entry
    entries = known_robots()
    for entry in entries:
        if entry.name == name:
            return entry
    names = [e.name for e in entries]
    hint = did_you_mean(name, names)
    raise RobotError(
        f"unknown robot {name!r}{hint}; known robots: {', '.join(names) or '(none)'} "
        f"(to use a file, give a path such as ./{name})"
    )

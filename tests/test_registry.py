"""hybrid_force.model.registry: every named robot loads, has its tip frame, its meshes resolve."""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hybrid_force.errors import BadInputError, RobotError
from hybrid_force.model.loading import load_robot
from hybrid_force.model.registry import RobotEntry, bundled_robots_dir, known_robots, resolve_robot
from hybrid_force.model.urdf_check import check_urdf

ENTRIES = known_robots()
NAMES = [e.name for e in ENTRIES]
# Loading every mesh of these takes about a second each; still run in CI.
_HEAVY_MESHES = {"ur3", "ur10", "z1", "g1"}


def _entry_params() -> list[object]:
    return [
        pytest.param(e, id=e.name, marks=[pytest.mark.slow] if e.name in _HEAVY_MESHES else [])
        for e in ENTRIES
    ]


def test_required_names_are_present() -> None:
    for name in ("rtr", "ur3", "ur5", "ur10", "panda", "z1"):
        assert name in NAMES
    assert len(NAMES) == len(set(NAMES))
    assert NAMES[0] == "rtr"


def test_entries_are_frozen_with_the_documented_fields() -> None:
    fields = [f.name for f in dataclasses.fields(RobotEntry)]
    assert fields == [
        "name",
        "urdf_path",
        "package_dirs",
        "default_tip",
        "source",
        "description",
        "locked_joints",
    ]
    entry = resolve_robot("rtr")
    with pytest.raises(dataclasses.FrozenInstanceError):
        entry.name = "other"  # type: ignore[misc]


def test_rtr_is_bundled_from_the_checkout(rtr_urdf: Path) -> None:
    entry = resolve_robot("rtr")
    assert entry.source == "bundled"
    assert entry.default_tip == "tip"
    assert entry.package_dirs == ()
    assert entry.urdf_path.resolve() == rtr_urdf.resolve()
    assert bundled_robots_dir() == rtr_urdf.resolve().parent


def test_example_robot_data_entries_use_the_cmeel_share_dir() -> None:
    for entry in ENTRIES:
        if entry.source != "example-robot-data":
            continue
        (share,) = entry.package_dirs
        assert Path(share).name == "share"
        assert Path(share).parent.name == "cmeel.prefix"
        assert entry.urdf_path.is_relative_to(Path(share) / "example-robot-data" / "robots")


@pytest.mark.parametrize("entry", [pytest.param(e, id=e.name) for e in ENTRIES])
def test_entry_loads_and_has_its_tip(entry: RobotEntry) -> None:
    assert entry.urdf_path.is_file()
    check_urdf(entry.urdf_path)
    robot = load_robot(entry.name)
    assert robot.source == entry.name  # a name re-loads from any working directory
    # One coordinate per moving joint (a continuous joint is an unbounded revolute one), and
    # as many as the URDF declares (counted from the XML) minus the locked ones.
    root = ET.parse(entry.urdf_path).getroot()
    moving = [
        j.get("name")
        for j in root.findall("joint")
        if j.get("type") in ("revolute", "continuous", "prismatic")
    ]
    assert robot.nq == robot.nv == len(moving) - len(entry.locked_joints)
    assert robot.euclidean is True
    assert robot.tip == entry.default_tip
    # The tip is carried by the arm: it moves when the joints move.
    rng = np.random.default_rng(5)
    q0 = robot.neutral()
    p0 = robot.tip_position(q0)
    assert np.linalg.norm(robot.tip_position(q0 + rng.uniform(-0.5, 0.5, robot.nq)) - p0) > 1e-3


def test_expected_joint_counts() -> None:
    counts = {
        e.name: pin.buildModelFromUrdf(str(e.urdf_path)).nv - len(e.locked_joints) for e in ENTRIES
    }
    assert counts["rtr"] == 3
    assert counts["ur5"] == counts["ur3"] == counts["ur10"] == 6
    assert counts["panda"] == 7  # 7 arm joints; the 2 finger joints are locked
    assert max(counts.values()) >= 25  # a big model for benchmarks


def _mesh_files(entry: RobotEntry) -> list[str]:
    root = ET.parse(entry.urdf_path).getroot()
    return [m.get("filename", "") for m in root.iter("mesh") if _in_visual(root, m)]


def _in_visual(root: ET.Element, mesh: ET.Element) -> bool:
    parents = {child: parent for parent in root.iter() for child in parent}
    node: ET.Element | None = mesh
    while node is not None:
        if node.tag == "visual":
            return True
        node = parents.get(node)
    return False


@pytest.mark.parametrize("entry", [pytest.param(e, id=e.name) for e in ENTRIES])
def test_visual_mesh_files_exist(entry: RobotEntry) -> None:
    """Resolve package:// URIs against package_dirs by hand (independent of Pinocchio)."""
    for uri in _mesh_files(entry):
        if uri.startswith("package://"):
            rel = uri.removeprefix("package://")
            assert any((Path(d) / rel).is_file() for d in entry.package_dirs), uri
        else:
            assert (entry.urdf_path.parent / uri).is_file(), uri


@pytest.mark.parametrize("entry", _entry_params())
def test_pinocchio_resolves_visual_meshes(entry: RobotEntry) -> None:
    model = pin.buildModelFromUrdf(str(entry.urdf_path))
    geom = pin.buildGeomFromUrdf(
        model, str(entry.urdf_path), pin.GeometryType.VISUAL, package_dirs=list(entry.package_dirs)
    )
    assert geom.ngeoms >= 1
    for obj in geom.geometryObjects:
        if obj.meshPath.startswith("/"):
            assert Path(obj.meshPath).is_file()


def test_wrong_package_dir_fails_mesh_resolution(tmp_path: Path) -> None:
    """Sanity check of the test above: without the right package dir Pinocchio refuses."""
    entry = resolve_robot("ur5")
    model = pin.buildModelFromUrdf(str(entry.urdf_path))
    with pytest.raises(ValueError, match="could not be found"):
        pin.buildGeomFromUrdf(
            model, str(entry.urdf_path), pin.GeometryType.VISUAL, package_dirs=[str(tmp_path)]
        )


def test_unknown_name_lists_known_names_and_suggests() -> None:
    with pytest.raises(RobotError) as info:
        resolve_robot("ur55")
    message = str(info.value)
    assert "'ur55'" in message
    assert "did you mean 'ur5'" in message
    for name in NAMES:
        assert name in message
    assert isinstance(info.value, BadInputError)


def test_unknown_name_without_close_match() -> None:
    with pytest.raises(RobotError, match=r"unknown robot 'zzzzzz'; known robots: rtr"):
        resolve_robot("zzzzzz")


def test_unknown_name_says_how_to_use_a_file() -> None:
    with pytest.raises(RobotError, match=r"to use a file, give a path such as \./my_arm\)"):
        resolve_robot("my_arm")


def test_rtr_base_joint_is_continuous_in_the_urdf(rtr_urdf: Path) -> None:
    """The paper's base joint turns freely: q1 is declared continuous, without a range."""
    joints = {j.get("name"): j for j in ET.parse(rtr_urdf).getroot().findall("joint")}
    assert joints["q1"].get("type") == "continuous"
    limit = joints["q1"].find("limit")
    assert limit is not None and limit.get("velocity") == "100"
    assert limit.get("lower") is None and limit.get("upper") is None
    assert "continuous" in resolve_robot("rtr").description

"""hybrid_force.model.report: what ``robots --check`` reports, against hand computations.

The RTR numbers come from robots/rtr.urdf by hand (l2 = 0.9 m, l3 = 1 m, m2 = m3 = 20 kg, q2 in
[-1, 16] m); the small URDFs here are written inline so their numbers follow from the text.
The reach is also checked as what it claims to be: a bound on ‖p(q) − o_1‖ over random
configurations within the limits.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import RTR_MJCF

from hybrid_force.errors import RobotError
from hybrid_force.model.loading import load_robot
from hybrid_force.model.report import format_report, model_report

# one triangle: an STL file coal (the replay's mesh loader) reads
_TRIANGLE_STL = (
    "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
    "endloop\nendfacet\nendsolid s\n"
)


def _body(mass: float, izz: float = 0.01, x: float = 0.0) -> str:
    return (
        f'<inertial><origin xyz="{x} 0 0"/><mass value="{mass}"/>'
        f'<inertia ixx="{izz}" ixy="0" ixz="0" iyy="{izz}" iyz="0" izz="{izz}"/></inertial>'
    )


def _mesh(uri: str) -> str:
    return f'<visual><geometry><mesh filename="{uri}"/></geometry></visual>'


def _write(tmp_path: Path, text: str, name: str = "arm.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --- the RTR arm, by hand --------------------------------------------------------------------
def test_rtr_report_by_hand() -> None:
    report = model_report("rtr")
    rows = [(j.name, j.urdf_type, j.lower, j.upper, j.effort) for j in report.joints]
    assert rows == [
        ("q1", "continuous", -math.inf, math.inf, math.inf),  # no range; effort="0": none
        ("q2", "prismatic", -1.0, 16.0, math.inf),
        ("q3", "revolute", -3.2, 3.2, math.inf),
    ]
    assert report.fixed_joints == ("tip_joint",)
    assert report.locked_joints == ()
    assert (report.tip, report.default_tip) == ("tip", "tip")
    assert report.tip_candidates == ("link3",)  # the other body frame on q3 (the leaf)
    assert report.total_mass == pytest.approx(40.0, abs=1e-12)  # 20 + 20 kg
    assert report.moving_mass == pytest.approx(40.0, abs=1e-12)
    # q1 -> q2: 0 m, q2 -> q3: 0.9 m, q3 -> tip: 1.0 m; q2 travels up to max(|-1|, 16) m
    assert report.reach.first_joint == "q1"
    assert report.reach.links == pytest.approx(1.9, abs=1e-12)
    assert report.reach.prismatic == 16.0
    assert report.reach.total == pytest.approx(17.9, abs=1e-12)
    assert report.meshes == ()
    assert report.model_warnings == ()
    assert report.notes == ()


def test_rtr_reach_bounds_the_tip(rng: np.random.Generator) -> None:
    """‖p(q) − o_1‖ ≤ 17.9 m for q within the limits; the horizontal distance from the q1
    axis is at most the links' 1.9 m, reached at q3 = 0 (p = (1.9 cos q1, 1.9 sin q1, q2))."""
    robot = load_robot("rtr")
    reach = model_report("rtr").reach
    q = np.column_stack(
        [rng.uniform(-10, 10, 500), rng.uniform(-1, 16, 500), rng.uniform(-3.2, 3.2, 500)]
    )
    tips = np.array([robot.tip_position(x) for x in q])
    assert np.all(np.linalg.norm(tips, axis=1) <= reach.total)  # o_1 = origin
    assert np.all(np.hypot(tips[:, 0], tips[:, 1]) <= reach.links + 1e-12)
    np.testing.assert_allclose(
        np.hypot(*robot.tip_position([0.3, 2.0, 0.0])[:2]), reach.links, rtol=1e-12
    )


def test_rtr_with_another_tip() -> None:
    """Tip on link3 (q3's origin): the links part loses l3 = 1 m."""
    report = model_report("rtr", tip="link3")
    assert (report.tip, report.default_tip) == ("link3", "tip")
    assert report.tip_candidates == ("tip",)
    assert report.reach.links == pytest.approx(0.9, abs=1e-12)
    assert report.reach.total == pytest.approx(16.9, abs=1e-12)
    assert "tip: link3 (given; default: tip)" in format_report(report)


def test_a_tip_that_is_no_frame_is_refused() -> None:
    with pytest.raises(RobotError, match="'nope' not found"):
        model_report("rtr", tip="nope")


# --- a small hand-written arm: offsets in 3D, a prismatic joint, a fixed branch -----------------
_ARM = (
    '<?xml version="1.0"?>\n<robot name="arm">'
    '<link name="world"/>'
    f'<link name="base">{_body(5.0)}</link>'
    f'<link name="upper">{_body(2.0, x=0.2)}</link>'
    f'<link name="slider">{_body(1.0)}</link>'
    '<link name="tool"/>'
    f'<link name="camera">{_body(0.5)}</link>'
    '<joint name="mount" type="fixed"><parent link="world"/><child link="base"/>'
    '<origin xyz="1 2 0"/></joint>'
    '<joint name="j1" type="revolute"><parent link="base"/><child link="upper"/>'
    '<origin xyz="0 0 0.5"/><axis xyz="0 0 1"/>'
    '<limit lower="-2" upper="2" effort="30" velocity="1"/></joint>'
    '<joint name="j2" type="prismatic"><parent link="upper"/><child link="slider"/>'
    '<origin xyz="0.3 0.4 0"/><axis xyz="1 0 0"/>'
    '<limit lower="-0.7" upper="0.25" effort="100" velocity="1"/></joint>'
    '<joint name="tool_joint" type="fixed"><parent link="slider"/><child link="tool"/>'
    '<origin xyz="0 0.12 0"/></joint>'
    '<joint name="cam" type="fixed"><parent link="upper"/><child link="camera"/>'
    '<origin xyz="0 0 0.1"/></joint>'
    "</robot>\n"
)


def test_hand_written_arm_by_hand(tmp_path: Path) -> None:
    """j1 -> j2: |(0.3, 0.4, 0)| = 0.5 m; j2 -> tool: 0.12 m; j2 travels max(0.7, 0.25) m.
    Masses 5 (welded to the world) + 2 + 1 + 0.5 kg. The end of the chain is j2: its body
    frames are slider and tool; camera is fixed to upper (on j1), not an end."""
    report = model_report(_write(tmp_path, _ARM), tip="tool")
    assert [(j.name, j.urdf_type, j.lower, j.upper, j.effort) for j in report.joints] == [
        ("j1", "revolute", -2.0, 2.0, 30.0),
        ("j2", "prismatic", -0.7, 0.25, 100.0),
    ]
    assert set(report.fixed_joints) == {"mount", "tool_joint", "cam"}
    assert report.total_mass == pytest.approx(8.5, abs=1e-12)
    assert report.moving_mass == pytest.approx(3.5, abs=1e-12)
    assert report.reach.first_joint == "j1"
    assert report.reach.links == pytest.approx(0.62, abs=1e-12)
    assert report.reach.prismatic == pytest.approx(0.7, abs=1e-12)
    assert report.tip_candidates == ("slider",)
    text = format_report(report)
    assert "  j2    prismatic  [-0.7, 0.25] m  100 N" in text
    assert "  j1    revolute   [-2, 2] rad     30 N·m" in text
    assert "reach: 1.32 m from the origin of joint j1 (joint-to-joint distances 0.62 m + " in text


def test_hand_written_reach_bounds_the_tip(tmp_path: Path, rng: np.random.Generator) -> None:
    """o_1 = j1's origin = (1, 2, 0.5) in the world. By hand the tip is at
    R_z(q1) (0.3 + q2, 0.52, 0) from o_1, so its farthest is hypot(0.55, 0.52) m at q2 = 0.25:
    below the bound 1.32 m (the segments never line up), which random samples respect."""
    path = _write(tmp_path, _ARM)
    robot = load_robot(path, tip="tool")
    reach = model_report(path, tip="tool").reach
    origin = np.array([1.0, 2.0, 0.5])
    far = np.linalg.norm(robot.tip_position([0.8, 0.25]) - origin)
    assert far == pytest.approx(math.hypot(0.55, 0.52), abs=1e-12)
    lower, upper = robot.position_limits
    for q in rng.uniform(lower, upper, size=(500, 2)):
        assert np.linalg.norm(robot.tip_position(q) - origin) <= reach.total


# --- meshes -----------------------------------------------------------------------------------
def test_meshes_found_and_missing(tmp_path: Path) -> None:
    """Relative to the URDF's folder, package:// against package_dirs (the URDF's folder for a
    plain file), an absolute path and file://; an http:// URI is never a file."""
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "base.stl").write_text(_TRIANGLE_STL)
    (tmp_path / "mypkg" / "meshes").mkdir(parents=True)
    (tmp_path / "mypkg" / "meshes" / "arm.stl").write_text(_TRIANGLE_STL)
    absolute = tmp_path / "elsewhere.stl"
    absolute.write_text(_TRIANGLE_STL)
    text = (
        '<robot name="m">'
        f'<link name="world">{_mesh("meshes/base.stl")}</link>'
        f'<link name="arm">{_body(2.0, x=0.3)}{_mesh("package://mypkg/meshes/arm.stl")}'
        f"{_mesh('meshes/gripper.stl')}{_mesh(str(absolute))}{_mesh('meshes/base.stl')}</link>"
        f'<link name="hand">{_mesh("file://" + str(absolute))}{_mesh("http://x.org/h.stl")}'
        f"{_mesh('package://otherpkg/h.stl')}</link>"
        '<joint name="j1" type="revolute"><parent link="world"/><child link="arm"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="5" velocity="1"/></joint>'
        '<joint name="j2" type="fixed"><parent link="arm"/><child link="hand"/></joint></robot>'
    )
    path = _write(tmp_path, text)
    report = model_report(path)
    status = {m.uri: (m.link, m.found) for m in report.meshes}
    assert status == {  # each URI once, with the first link that uses it
        "meshes/base.stl": ("world", tmp_path / "meshes" / "base.stl"),
        "package://mypkg/meshes/arm.stl": ("arm", tmp_path / "mypkg" / "meshes" / "arm.stl"),
        "meshes/gripper.stl": ("arm", None),
        str(absolute): ("arm", absolute),
        "file://" + str(absolute): ("hand", absolute),
        "http://x.org/h.stl": ("hand", None),
        "package://otherpkg/h.stl": ("hand", None),
    }
    missing = {m.uri: m.candidates for m in report.meshes if m.found is None}
    assert missing["meshes/gripper.stl"] == (tmp_path / "meshes" / "gripper.stl",)
    assert missing["http://x.org/h.stl"] == ()
    assert tmp_path / "otherpkg" / "h.stl" in missing["package://otherpkg/h.stl"]
    # the replay draws exactly the meshes reported found (its own resolution, same rule)
    from hybrid_force.viz.robot_visuals import _resolve_mesh

    robot = load_robot(path)
    dirs = [str(d) for d in robot.package_dirs]
    for m in report.meshes:
        assert _resolve_mesh(m.uri, tmp_path, dirs) == m.found, m.uri
    lines = format_report(report).splitlines()
    assert "meshes: 7 referenced, 4 found" in lines
    gripper = tmp_path / "meshes" / "gripper.stl"
    assert f"  missing  meshes/gripper.stl (link arm; looked for {gripper})" in lines
    assert "  missing  http://x.org/h.stl (link hand; not a file path)" in lines
    assert "  found    package://mypkg/meshes/arm.stl" in lines


# --- warnings, notes, refusals ------------------------------------------------------------------
def test_model_warnings_are_reported_not_issued(tmp_path: Path) -> None:
    """A massless end link with an inertia: the load's one ModelWarning is in the report (and
    nothing is issued: pytest's filterwarnings = error would fail the test)."""
    text = _ARM.replace('<link name="tool"/>', f'<link name="tool">{_body(0.0, izz=1e-4)}</link>')
    path = _write(tmp_path, text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        report = model_report(path, tip="tool")
    assert len(report.model_warnings) == 1
    assert report.model_warnings[0].startswith(f"{path}: link 'tool': <inertial> mass 0 kg")
    assert f"  warning: {path}: link 'tool'" in format_report(report)
    assert "warnings: 1" in format_report(report)


def test_a_root_inertial_only_urdfdom_complains_about(tmp_path: Path) -> None:
    """The root link is not checked; urdfdom drops its unreadable inertial (one ModelWarning
    from the loader) and yourdfpy cannot read the file at all: the report still gives the
    joints and masses from Pinocchio, and says what it could not read."""
    text = _ARM.replace('<link name="world"/>', '<link name="world">' + _body(1.0) + "</link>")
    text = text.replace('<mass value="1.0"/>', '<mass value="heavy"/>', 1)
    assert text.count("heavy") == 1 and text.index("heavy") < text.index('name="base"')
    report = model_report(_write(tmp_path, text), tip="tool")
    assert [j.name for j in report.joints] == ["j1", "j2"]
    assert report.joints[1].urdf_type == "prismatic"  # from Pinocchio's joint model
    assert report.total_mass == pytest.approx(8.5, abs=1e-12)  # the world's mass is dropped
    assert len(report.model_warnings) == 1 and "heavy" in report.model_warnings[0]
    assert len(report.notes) == 1 and report.notes[0].startswith("yourdfpy cannot read")
    assert report.meshes == ()


def test_a_model_that_cannot_be_simulated_is_refused(tmp_path: Path) -> None:
    text = _ARM.replace('name="j1" type="revolute"', 'name="j1" type="floating"')
    with pytest.raises(RobotError, match=r"arm\.urdf.*joint 'j1'.*floating joint"):
        model_report(_write(tmp_path, text))


# --- the registry's arms, read twice: by yourdfpy (URDF) and Pinocchio (the model) --------------
def test_panda_locked_fingers_and_masses_agree_with_yourdfpy() -> None:
    """The report's limits come from Pinocchio; yourdfpy reads the same URDF independently.
    Locking the fingers keeps their mass (the total is the URDF's sum of link masses)."""
    import yourdfpy

    from hybrid_force.model.registry import resolve_robot

    report = model_report("panda")
    urdf = yourdfpy.URDF.load(
        str(resolve_robot("panda").urdf_path), build_scene_graph=False, load_meshes=False
    )
    declared = {j.name: j.limit for j in urdf.robot.joints}
    assert report.locked_joints == ("panda_finger_joint1", "panda_finger_joint2")
    assert len(report.joints) == 7
    for joint in report.joints:
        limit = declared[joint.name]
        assert (joint.lower, joint.upper, joint.effort) == (limit.lower, limit.upper, limit.effort)
    urdf_mass = sum(link.inertial.mass for link in urdf.robot.links if link.inertial is not None)
    assert report.total_mass == pytest.approx(urdf_mass, rel=1e-12)
    assert report.tip == "panda_hand_tcp" and "panda_hand" in report.tip_candidates
    assert report.meshes and all(m.found is not None for m in report.meshes)
    assert report.model_warnings == () and report.notes == ()


def test_reach_of_a_planar_two_link_arm_is_reached_when_stretched(tmp_path: Path) -> None:
    """Two revolute joints about z, links 0.5 and 0.3 m: the bound 0.8 m is the true reach."""
    text = (
        '<robot name="two"><link name="world"/>'
        f'<link name="a">{_body(1.0, x=0.25)}</link><link name="b">{_body(1.0, x=0.15)}</link>'
        '<link name="tip"/>'
        '<joint name="j1" type="continuous"><parent link="world"/><child link="a"/>'
        '<axis xyz="0 0 1"/></joint>'
        '<joint name="j2" type="continuous"><parent link="a"/><child link="b"/>'
        '<origin xyz="0.5 0 0"/><axis xyz="0 0 1"/></joint>'
        '<joint name="t" type="fixed"><parent link="b"/><child link="tip"/>'
        '<origin xyz="0.3 0 0"/></joint></robot>'
    )
    path = _write(tmp_path, text)
    report = model_report(path)
    assert report.reach.total == pytest.approx(0.8, abs=1e-12)
    robot = load_robot(path)
    stretched = robot.tip_position([1.1, 0.0])
    assert np.linalg.norm(stretched) == pytest.approx(0.8, abs=1e-12)
    assert [j.urdf_type for j in report.joints] == ["continuous", "continuous"]
    assert "unbounded" in format_report(report)


# --- other model sources: the report reads what the model was built from -----------------------


def test_mjcf_rtr_has_the_urdf_rtr_numbers(tmp_path: Path) -> None:
    """The RTR written in MJCF: the same masses and reach by hand (1.9 m + 16 m); the joint
    types are Pinocchio's (MJCF has no 'continuous'), and a note says no URDF part is read."""
    path = tmp_path / "rtr.xml"
    path.write_text(RTR_MJCF)
    report = model_report(path, tip="tip")
    assert [(j.name, j.urdf_type) for j in report.joints] == [
        ("q1", "revolute"),
        ("q2", "prismatic"),
        ("q3", "revolute"),
    ]
    assert (report.joints[1].lower, report.joints[1].upper) == (-1.0, 16.0)
    assert report.total_mass == pytest.approx(40.0, abs=1e-12)
    assert report.reach.links == pytest.approx(1.9, abs=1e-12)
    assert report.reach.prismatic == 16.0
    assert report.meshes == () and report.fixed_joints == ()
    assert len(report.notes) == 1 and "is an MJCF model" in report.notes[0]


def test_xacro_is_reported_from_its_expansion(tmp_path: Path) -> None:
    """Lengths given as xacro properties (0.6 and 0.4 m) and a continuous joint: the report
    reads the expansion, so the type is 'continuous' and the reach 0.6 + 0.4 m."""
    path = tmp_path / "two.urdf.xacro"
    path.write_text(
        '<robot name="two" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<xacro:property name="l1" value="0.6"/><xacro:property name="l2" value="0.4"/>'
        f'<link name="world"/><link name="a">{_body(1.0, x=0.3)}</link>'
        f'<link name="b">{_body(1.0, x=0.2)}</link><link name="tip"/>'
        '<joint name="j1" type="continuous"><parent link="world"/><child link="a"/>'
        '<axis xyz="0 0 1"/></joint>'
        '<joint name="j2" type="revolute"><parent link="a"/><child link="b"/>'
        '<origin xyz="${l1} 0 0"/><axis xyz="0 0 1"/>'
        '<limit lower="-2" upper="2" effort="4" velocity="1"/></joint>'
        '<joint name="t" type="fixed"><parent link="b"/><child link="tip"/>'
        '<origin xyz="${l2} 0 0"/></joint></robot>'
    )
    report = model_report(path)
    assert [(j.name, j.urdf_type) for j in report.joints] == [
        ("j1", "continuous"),
        ("j2", "revolute"),
    ]
    assert report.fixed_joints == ("t",)
    assert report.reach.total == pytest.approx(1.0, abs=1e-12)
    assert report.total_mass == pytest.approx(2.0, abs=1e-12)
    assert report.notes == ()

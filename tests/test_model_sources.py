"""Bring your own robot: package folders and meshes, xacro files, MJCF files, and the joints
off the arm's chain (hybrid_force.model.loading.load_robot, the replay's visuals).

Every model here is a small file written by the test. References are independent of the
code under test: the closed-form kinematics and mass matrix of a planar two-link arm of thin
rods (p, M by hand), the bundled RTR URDF for an MJCF copy of it, and the mesh file's own
bytes for what the HTML replay must hold.
"""

from __future__ import annotations

import base64
import math
import os
import re
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import umsgpack
from conftest import ROD_MACRO, RTR_MJCF

from hybrid_force.errors import BadInputError, ModelWarning, RobotError, ScenarioError
from hybrid_force.geometry.builtin_surfaces import Plane
from hybrid_force.model.loading import load_robot
from hybrid_force.model.robot import Robot
from hybrid_force.model.xacro_files import expand_xacro
from hybrid_force.result import Result
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.viz import replay, robot_visuals

REPO = Path(__file__).resolve().parents[1]

# An ASCII STL of one triangle (coal reads it; meshcat embeds the file's bytes).
STL = """solid part
  facet normal 0 0 1
    outer loop
      vertex 0 0 0
      vertex 0.1 0 0
      vertex 0 0.1 0
    endloop
  endfacet
endsolid part
"""


# --- the reference arm: two thin rods turning about z ----------------------------------------
def _rod_link(name: str, length: float, mass: float, visual: str = "") -> str:
    """A thin rod along +x: mass at length/2, m l²/12 about y and z, none about x."""
    i = mass * length**2 / 12
    return (
        f'<link name="{name}"><inertial><origin xyz="{length / 2} 0 0"/>'
        f'<mass value="{mass}"/><inertia ixx="0" ixy="0" ixz="0" iyy="{i}" iyz="0" '
        f'izz="{i}"/></inertial>{visual}</link>'
    )


def _revolute(name: str, parent: str, child: str, x: float = 0.0, limits: str = "-3 3") -> str:
    lower, upper = limits.split()
    return (
        f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{x} 0 0"/><axis xyz="0 0 1"/>'
        f'<limit lower="{lower}" upper="{upper}" effort="10" velocity="2"/></joint>'
    )


def _planar_urdf(l1: float = 1.0, l2: float = 0.5, visuals: tuple[str, str] = ("", "")) -> str:
    """Links l1 (2 kg) and l2 (1 kg), joints j1, j2 about z, frame 'tip' at the end of l2."""
    return (
        '<?xml version="1.0"?><robot name="planar"><link name="base"/>'
        + _rod_link("l1", l1, 2.0, visuals[0])
        + _rod_link("l2", l2, 1.0, visuals[1])
        + '<link name="tip"/>'
        + _revolute("j1", "base", "l1")
        + _revolute("j2", "l1", "l2", x=l1)
        + f'<joint name="tip_joint" type="fixed"><parent link="l2"/><child link="tip"/>'
        f'<origin xyz="{l2} 0 0"/></joint></robot>'
    )


def _planar_p(q: np.ndarray, l1: float, l2: float) -> np.ndarray:
    """Tip position of the planar arm [m]."""
    a, b = q[0], q[0] + q[1]
    return np.array([l1 * math.cos(a) + l2 * math.cos(b), l1 * math.sin(a) + l2 * math.sin(b), 0])


def _planar_M(q: np.ndarray, l1: float, l2: float, m1: float = 2.0, m2: float = 1.0) -> np.ndarray:
    """Mass matrix of two thin rods about parallel z axes [kg m²]."""
    i1, i2 = m1 * l1**2 / 12, m2 * l2**2 / 12
    c2 = math.cos(q[1])
    m22 = i2 + m2 * (l2 / 2) ** 2
    m12 = m22 + m2 * l1 * (l2 / 2) * c2
    m11 = i1 + m1 * (l1 / 2) ** 2 + m22 + m2 * (l1**2 + 2 * l1 * (l2 / 2) * c2)
    return np.array([[m11, m12], [m12, m22]])


def _mesh_visual(uri: str, xyz: str = "0.2 0 0") -> str:
    return f'<visual><origin xyz="{xyz}"/><geometry><mesh filename="{uri}"/></geometry></visual>'


# --- replay helpers -------------------------------------------------------------------------------
def _result(robot: Robot, meta_robot: dict[str, Any] | None = None) -> Result:
    """A 0.2 s run of the arm (smooth q(t), p = p(q)), on the plane z = 0."""
    t = np.arange(21) * 0.01
    n = robot.nq
    q = np.column_stack([0.3 * np.sin(t + j) for j in range(n)])
    p = np.array([robot.tip_position(x) for x in q])
    meta = {
        "name": "own_robot",
        "robot": {**robot.reference, "nq": n} if meta_robot is None else meta_robot,
        "surfaces": [Plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]).to_dict()],
        "events": [],
        "status": "ok",
    }
    zeros = np.zeros_like(t)
    return Result(
        t=t, q=q, v=np.gradient(q, t, axis=0), q_d=q, u=np.zeros_like(q), p=p, p_d=p, f=zeros,
        f_d=zeros, phi=zeros, V=zeros, phase=np.zeros(t.size, dtype=np.int64), meta=meta,
    )  # fmt: skip


def _visual_objects(page: str) -> dict[str, dict[str, Any]]:
    """{robot visual's node path: its meshcat object} from the commands inlined in a page."""
    start = page.index("var commands = [")
    block = page[start : page.index("];", start)]
    commands = [
        umsgpack.unpackb(base64.b64decode(b)) for b in re.findall(r'"([A-Za-z0-9+/=]+)"', block)
    ]
    return {
        c["path"]: c["object"]
        for c in commands
        if c["type"] == "set_object" and "/robot/visuals/" in c["path"]
    }


def _html(result: Result, tmp_path: Path) -> tuple[str, list[warnings.WarningMessage]]:
    """The replay page of a result (written by write_html), and the ModelWarnings it gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ModelWarning)
        out = replay.write_html(result, tmp_path / "replay.html")
    return out.read_text(encoding="utf-8"), [w for w in caught if w.category is ModelWarning]


def _mesh_tree(tmp_path: Path) -> tuple[Path, Path]:
    """packages/mypkg/meshes/part.stl, and arm/arm.urdf using it (link l1) and a missing
    mesh of the same package (link l2). Returns (arm file, packages folder)."""
    packages = tmp_path / "packages"
    (packages / "mypkg" / "meshes").mkdir(parents=True)
    (packages / "mypkg" / "meshes" / "part.stl").write_text(STL)
    (tmp_path / "arm").mkdir()
    arm = tmp_path / "arm" / "arm.urdf"
    arm.write_text(
        _planar_urdf(
            visuals=(
                _mesh_visual("package://mypkg/meshes/part.stl"),
                _mesh_visual("package://mypkg/meshes/missing.stl", xyz="0.25 0 0"),
            )
        )
    )
    return arm, packages


# --- package folders and meshes -------------------------------------------------------------
def test_package_dirs_draw_the_found_mesh_and_one_warning_names_the_missing_one(
    tmp_path: Path,
) -> None:
    arm, packages = _mesh_tree(tmp_path)
    robot = load_robot(arm, package_dirs=[packages])  # meshes are not read to simulate
    assert robot.package_dirs[0] == str(packages)
    assert robot.package_dirs[-1] == str(arm.parent)  # the URDF's own folder, as before
    assert robot.reference["package_dirs"] == [str(packages)]
    page, caught = _html(_result(robot), tmp_path)
    assert len(caught) == 1, [str(w.message) for w in caught]
    message = str(caught[0].message)
    assert "package://mypkg/meshes/missing.stl" in message and "link 'l2'" in message
    objects = _visual_objects(page)
    # the found mesh: meshcat embeds the STL file's own bytes
    (geometry,) = objects["/meshcat/robot/visuals/l1_0"]["geometries"]
    assert geometry["format"] == "stl" and geometry["data"].data == STL.encode()
    # the missing one: a 5 cm cube
    (box,) = objects["/meshcat/robot/visuals/l2_0"]["geometries"]
    assert (box["type"], box["width"], box["height"], box["depth"]) == (
        "BoxGeometry", 0.05, 0.05, 0.05,
    )  # fmt: skip


def test_placeholder_stands_at_the_visual_origin(tmp_path: Path) -> None:
    """The cube of the missing mesh of link l2 sits at l2's visual origin (0.25, 0, 0)."""
    arm, packages = _mesh_tree(tmp_path)
    robot = load_robot(arm, package_dirs=[packages])
    with pytest.warns(ModelWarning, match="missing.stl"):
        visual = robot_visuals.visual_geometry(robot)
    (cube,) = [g for g in visual.geometryObjects if g.name == "l2_0"]
    np.testing.assert_allclose(cube.placement.translation, [0.25, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(cube.geometry.halfSide, [0.025] * 3, atol=1e-15)
    (part,) = [g for g in visual.geometryObjects if g.name == "l1_0"]
    assert part.meshPath == str(packages / "mypkg" / "meshes" / "part.stl")


def test_ros_package_path_resolves_package_uris(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    arm, packages = _mesh_tree(tmp_path)
    monkeypatch.setenv("ROS_PACKAGE_PATH", os.pathsep.join([str(tmp_path / "none"), str(packages)]))
    robot = load_robot(arm)
    assert robot.package_dirs == (str(tmp_path / "none"), str(packages), str(arm.parent))
    assert robot.reference["package_dirs"] == []  # the environment's folders are not stored
    with pytest.warns(ModelWarning) as record:
        visual = robot_visuals.visual_geometry(robot)
    assert len(record) == 1 and "missing.stl" in str(record[0].message)
    (part,) = [g for g in visual.geometryObjects if g.name == "l1_0"]
    assert part.meshPath == str(packages / "mypkg" / "meshes" / "part.stl")


def test_without_package_dirs_every_package_mesh_is_a_placeholder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    arm, _ = _mesh_tree(tmp_path)
    robot = load_robot(arm)
    page, caught = _html(_result(robot), tmp_path)
    assert sorted(str(w.message).split("mesh '")[1].split("'")[0] for w in caught) == [
        "package://mypkg/meshes/missing.stl",
        "package://mypkg/meshes/part.stl",
    ]
    objects = _visual_objects(page)
    assert objects["/meshcat/robot/visuals/l1_0"]["geometries"][0]["type"] == "BoxGeometry"


def test_relative_and_file_uris_resolve_against_the_urdf_folder(tmp_path: Path) -> None:
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "a.stl").write_text(STL)
    arm = tmp_path / "arm.urdf"
    arm.write_text(
        _planar_urdf(
            visuals=(
                _mesh_visual("meshes/a.stl"),
                _mesh_visual(f"file://{tmp_path / 'meshes' / 'a.stl'}"),
            )
        )
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no mesh is missing
        visual = robot_visuals.visual_geometry(load_robot(arm))
    paths = sorted(g.meshPath for g in visual.geometryObjects)
    assert paths == [str(tmp_path / "meshes" / "a.stl")] * 2


def test_an_unreadable_mesh_is_a_placeholder_with_one_warning(tmp_path: Path) -> None:
    """A file that exists but is no mesh: the other mesh is still drawn."""
    arm, packages = _mesh_tree(tmp_path)
    (packages / "mypkg" / "meshes" / "missing.stl").write_bytes(b"garbage\x00\x01")
    robot = load_robot(arm, package_dirs=[packages])
    with pytest.warns(ModelWarning) as record:
        visual = robot_visuals.visual_geometry(robot)
    assert len(record) == 1
    message = str(record[0].message)
    assert "mesh 'package://mypkg/meshes/missing.stl' of link 'l2' cannot be read" in message
    kinds = {g.name: type(g.geometry).__name__ for g in visual.geometryObjects}
    assert kinds["l2_0"] == "Box" and kinds["l1_0"].startswith("BVHModel")


def test_the_replay_reloads_package_dirs_from_meta(tmp_path: Path) -> None:
    arm, packages = _mesh_tree(tmp_path)
    robot = load_robot(arm, package_dirs=[packages])
    rep = replay.Replay(_result(robot))
    assert rep.robot.package_dirs[0] == str(packages)


def test_the_replay_finds_package_dirs_in_the_scenario_table(tmp_path: Path) -> None:
    """A result whose meta['robot'] has only model and tip (as simulate writes it today): the
    package folders come from meta['scenario']['robot'], relative to the scenario file."""
    arm, packages = _mesh_tree(tmp_path)
    robot = load_robot(arm, package_dirs=[packages])
    meta_robot = {"model": robot.source, "tip": robot.tip, "nq": 2}
    result = _result(robot, meta_robot).with_meta(
        scenario={"robot": {"model": "arm/arm.urdf", "package_dirs": ["packages"]}}
    )
    rep = replay.Replay(result)
    assert rep.robot.package_dirs[0] == str(packages)


# --- xacro ----------------------------------------------------------------------------------------

ARM_XACRO = """\
<?xml version="1.0"?>
<robot name="xarm" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="l1" default="1.0"/>
  <xacro:property name="l1" value="$(arg l1)"/>
  <xacro:property name="l2" value="0.5"/>
  <xacro:include filename="{include}"/>
  <link name="base"/>
  <xacro:rod name="l1" length="${{l1}}" mass="2"/>
  <xacro:rod name="l2" length="${{l2}}" mass="1"/>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="${{l1}} 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <joint name="tip_joint" type="fixed"><parent link="l2"/><child link="tip"/>
    <origin xyz="${{l2}} 0 0"/></joint>
</robot>
"""


NO_ARG = '<xacro:arg name="l1" default="1.0"/>'


def _xacro_arm(folder: Path, include: str = "parts/rod.xacro") -> Path:
    """folder/arm.urdf.xacro, its macro in folder/parts/rod.xacro (included as ``include``)."""
    (folder / "parts").mkdir(parents=True, exist_ok=True)
    (folder / "parts" / "rod.xacro").write_text(ROD_MACRO)
    path = folder / "arm.urdf.xacro"
    path.write_text(ARM_XACRO.format(include=include))
    return path


@pytest.mark.parametrize("l1", [0.7, 1.3])
def test_xacro_arm_matches_the_hand_formulas_for_its_argument(tmp_path: Path, l1: float) -> None:
    path = _xacro_arm(tmp_path)
    robot = load_robot(path, xacro_args={"l1": str(l1)})
    assert (robot.kind, robot.nv, robot.tip) == ("xacro", 2, "tip")
    assert robot.source == str(path.resolve())
    assert robot.reference["xacro_args"] == {"l1": str(l1)}
    rng = np.random.default_rng(3)
    for _ in range(4):
        q = rng.uniform(-2.5, 2.5, 2)
        np.testing.assert_allclose(robot.tip_position(q), _planar_p(q, l1, 0.5), atol=1e-14)
        np.testing.assert_allclose(robot.mass_matrix(q), _planar_M(q, l1, 0.5), atol=1e-13)


def test_xacro_default_argument_and_a_relative_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _xacro_arm(tmp_path / "arms")
    monkeypatch.chdir(tmp_path)
    robot = load_robot("arms/arm.urdf.xacro")  # a text ending .xacro: a path
    np.testing.assert_allclose(robot.tip_position([0.0, 0.0]), [1.5, 0.0, 0.0], atol=1e-15)
    assert robot.source == str((tmp_path / "arms" / "arm.urdf.xacro").resolve())
    monkeypatch.chdir(tmp_path / "arms")
    assert load_robot("arm.urdf.xacro").nv == 2  # a bare name ending .xacro is a file


def test_xacro_find_resolves_through_package_dirs(tmp_path: Path) -> None:
    """$(find armpkg) is packages/armpkg: the folder armpkg in a package folder."""
    _xacro_arm(tmp_path / "packages" / "armpkg")
    path = _xacro_arm(tmp_path / "robot", include="$(find armpkg)/parts/rod.xacro")
    (tmp_path / "robot" / "parts" / "rod.xacro").unlink()  # only the package's copy exists
    robot = load_robot(path, package_dirs=[tmp_path / "packages"], xacro_args={"l1": "0.8"})
    np.testing.assert_allclose(robot.tip_position([0.0, 0.0]), [1.3, 0.0, 0.0], atol=1e-15)
    with pytest.raises(RobotError) as info:
        load_robot(path)
    message = str(info.value)
    assert str(path) in message and "$(find armpkg)" in message
    assert "no folder 'armpkg' in the package folders" in message


def test_xacro_find_resolves_through_ros_package_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _xacro_arm(tmp_path / "packages" / "armpkg")
    path = _xacro_arm(tmp_path / "robot", include="$(find armpkg)/parts/rod.xacro")
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "packages"))
    text = expand_xacro(path, {}, ())
    assert 'name="l2"' in text and "xacro:" not in text


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda t: t.replace("</robot>", ""), "XML syntax error"),
        (lambda t: t.replace(NO_ARG, ""), "Undefined substitution argument l1"),
        (lambda t: t.replace('mass="1"/>', "/>"), "Undefined parameters [mass]"),
        (lambda t: t.replace("parts/rod.xacro", "parts/none.xacro"), "none.xacro"),
    ],
)  # fmt: skip
def test_xacro_errors_name_the_file_and_xacros_message(
    tmp_path: Path, edit: Any, expected: str
) -> None:
    path = _xacro_arm(tmp_path)
    path.write_text(edit(path.read_text()))
    with pytest.raises(RobotError) as info:
        load_robot(path)
    message = str(info.value)
    assert message.startswith(f"xacro cannot expand {path}")
    assert expected in message
    assert "\n" not in message


def test_xacro_expansion_is_checked_as_a_urdf(tmp_path: Path) -> None:
    """A expansion with an impossible inertia: the URDF check names the .xacro file."""
    path = _xacro_arm(tmp_path)
    path.write_text(path.read_text().replace('mass="2"', 'mass="-2"'))
    with pytest.raises(RobotError) as info:
        load_robot(path)
    message = str(info.value)
    assert f"{path} (as expanded by xacro)" in message and "link 'l1'" in message
    assert "hybrid_force_xacro_" not in message


def test_xacro_arguments_only_for_a_xacro_file(tmp_path: Path) -> None:
    arm = tmp_path / "arm.urdf"
    arm.write_text(_planar_urdf())
    with pytest.raises(RobotError, match=r"xacro arguments \(l1\) are given for .*arm.urdf"):
        load_robot(arm, xacro_args={"l1": "2"})
    with pytest.raises(RobotError, match="xacro_args must map argument names to texts"):
        load_robot(_xacro_arm(tmp_path), xacro_args={"l1": 2.0})  # type: ignore[dict-item]


def test_a_replay_rebuilds_a_xacro_arm_from_the_stored_expansion(tmp_path: Path) -> None:
    path = _xacro_arm(tmp_path)
    robot = load_robot(path, xacro_args={"l1": "0.6"})
    meta_robot = {**robot.reference, "nq": 2, "model_text": robot.urdf_xml, "model_format": "urdf"}
    result = _result(robot, meta_robot)
    assert result.meta["robot"]["xacro_args"] == {"l1": "0.6"}
    path.write_text("not xacro any more")  # the replay never reads (nor expands) the file
    rep = replay.Replay(result)
    np.testing.assert_allclose(rep.robot.tip_position([0.0, 0.0]), [1.1, 0.0, 0.0], atol=1e-15)
    # an older result, without the expansion: refused, the xacro file is not expanded
    old = _result(robot, {"model": robot.source, "tip": "tip", "nq": 2}).with_meta(
        scenario={"robot": {"model": "arm.urdf.xacro", "xacro_args": {"l1": 0.6}}}
    )
    with pytest.raises(BadInputError, match=r"arm\.urdf\.xacro' is a xacro file .* does not store"):
        replay.Replay(old)


# Paper section 6.3, shortened (tests/test_sweep.py): the RTR on the cylinder r = 0.4.
RTR_SCENARIO = """\
name = "own_rtr"
[robot]
{robot}
[surface]
type = "cylinder"
radius = 0.4
[trajectory]
type = "helix"
center = [0.0, 0.0, 10.0]
radius = 0.4
omega = 1.0
rise = 0.1
[initial]
tip = [0.4, 0.0, 7.0]
seed = {seed}
[control]
supervisor = false
[sim]
duration = 0.05
"""


def _rtr_scenario(path: Path, robot: str, seed: str = "[0.0, 6.0, 2.0]") -> Path:
    path.write_text(RTR_SCENARIO.format(robot=robot, seed=seed))
    return path


def test_rtr_xacro_is_the_bundled_rtr_at_the_default_length(
    tmp_path: Path, write_xacro_rtr: Callable[[Path], Path]
) -> None:
    path = write_xacro_rtr(tmp_path)
    xacro_rtr, rtr = load_robot(path), load_robot("rtr")
    short = load_robot(path, xacro_args={"l2": "0.7"})
    rng = np.random.default_rng(4)
    for _ in range(3):
        q = rng.uniform([-3, 0, -3], [3, 10, 3])
        np.testing.assert_allclose(xacro_rtr.mass_matrix(q), rtr.mass_matrix(q), atol=1e-12)
        reach = math.cos(q[2]) + 0.7
        p = [math.cos(q[0]) * reach, math.sin(q[0]) * reach, math.sin(q[2]) + q[1]]
        np.testing.assert_allclose(short.tip_position(q), p, atol=1e-14)


def test_scenario_with_a_xacro_model_and_arguments(
    tmp_path: Path, write_xacro_rtr: Callable[[Path], Path]
) -> None:
    write_xacro_rtr(tmp_path / "arms")
    scen = _rtr_scenario(
        tmp_path / "s.toml", 'model = "arms/rtr.urdf.xacro"\nxacro_args = {l2 = 0.7}'
    )
    sc = load_scenario(scen)  # a number is passed as its text, "0.7"
    assert sc.robot.reference["xacro_args"] == {"l2": "0.7"}
    np.testing.assert_allclose(sc.robot.tip_position([0.0, 0.0, 0.0]), [1.7, 0, 0], atol=1e-15)
    assert sc.source["robot"]["xacro_args"] == {"l2": 0.7}  # the file's data, as written
    # an undefined argument: exit 2 naming the file, robot.model and xacro's message
    xacro_file = tmp_path / "arms" / "rtr.urdf.xacro"
    xacro_file.write_text(
        xacro_file.read_text().replace('<xacro:arg name="l2" default="0.9"/>', "")
    )
    bad = _rtr_scenario(tmp_path / "bad.toml", 'model = "arms/rtr.urdf.xacro"')
    with pytest.raises(ScenarioError) as info:
        load_scenario(bad)
    message = str(info.value)
    assert message.startswith(f'{bad}: robot.model = "arms/rtr.urdf.xacro": xacro cannot expand')
    assert "Undefined substitution argument l2" in message


# --- MJCF -----------------------------------------------------------------------------------------
PLANAR_MJCF = """\
<mujoco model="planar">
  <compiler angle="radian"/>
  {assets}
  <worldbody>
    <body name="l1">
      <joint name="j1" type="hinge" axis="0 0 1" range="-3 3"/>
      <inertial pos="0.5 0 0" mass="2" diaginertia="0 0.16666666666666666 0.16666666666666666"/>
      <geom type="capsule" fromto="0 0 0 1 0 0" size="0.03"/>
      {geom1}
      <body name="l2" pos="1 0 0">
        <joint name="j2" type="hinge" axis="0 0 1" range="-3 3"/>
        <inertial pos="0.25 0 0" mass="1"
                  diaginertia="0 0.020833333333333332 0.020833333333333332"/>
        <geom type="box" pos="0.25 0 0" size="0.25 0.02 0.02"/>
        {geom2}
        <site name="tip" pos="0.5 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _mjcf(path: Path, assets: str = "", geom1: str = "", geom2: str = "") -> Path:
    path.write_text(PLANAR_MJCF.format(assets=assets, geom1=geom1, geom2=geom2))
    return path


def test_mjcf_arm_matches_the_hand_formulas(tmp_path: Path) -> None:
    """l1 = 1 m (2 kg), l2 = 0.5 m (1 kg) thin rods, as the URDF arm: the same p and M."""
    robot = load_robot(_mjcf(tmp_path / "arm.xml"), tip="tip")
    assert (robot.kind, robot.nv, robot.urdf_xml) == ("mjcf", 2, None)
    assert load_robot(tmp_path / "arm.xml").tip == "l2"  # default: the last body
    rng = np.random.default_rng(5)
    for _ in range(4):
        q = rng.uniform(-2.5, 2.5, 2)
        np.testing.assert_allclose(robot.tip_position(q), _planar_p(q, 1.0, 0.5), atol=1e-14)
        np.testing.assert_allclose(robot.mass_matrix(q), _planar_M(q, 1.0, 0.5), atol=1e-13)
    lower, upper = robot.position_limits
    np.testing.assert_array_equal(lower, [-3, -3])
    np.testing.assert_array_equal(upper, [3, 3])
    np.testing.assert_array_equal(robot.effort_limits, [np.inf, np.inf])  # MJCF gives none


def test_mjcf_rtr_is_the_bundled_urdf_rtr(tmp_path: Path) -> None:
    """The paper's RTR written in MJCF (hinge, slide, hinge): p, M and g equal the URDF's."""
    path = tmp_path / "rtr.xml"
    path.write_text(RTR_MJCF)
    mjcf, urdf = load_robot(path), load_robot("rtr")
    assert mjcf.tip == "tip" and mjcf.nv == 3
    rng = np.random.default_rng(9)
    for _ in range(5):
        q = rng.uniform([-3, 0, -3], [3, 10, 3])
        q3 = q[2]
        reach = math.cos(q3) + 0.9
        p = [math.cos(q[0]) * reach, math.sin(q[0]) * reach, math.sin(q3) + q[1]]
        np.testing.assert_allclose(mjcf.tip_position(q), p, atol=1e-14)
        np.testing.assert_allclose(mjcf.mass_matrix(q), urdf.mass_matrix(q), atol=1e-12)
        np.testing.assert_allclose(mjcf.gravity(q), urdf.gravity(q), atol=1e-12)


def test_a_contact_scenario_runs_on_an_mjcf_arm(tmp_path: Path) -> None:
    """tests/test_sweep.py's tiny paper 6.3 run (start on the cylinder, helix) on rtr.xml."""
    from hybrid_force.sim.loop import simulate

    (tmp_path / "arms").mkdir()
    (tmp_path / "arms" / "rtr.xml").write_text(RTR_MJCF)
    text = (REPO / "scenarios" / "paper_contact.toml").read_text()
    text = text.replace('model = "rtr"', 'model = "arms/rtr.xml"')
    scen = tmp_path / "rtr_mjcf.toml"
    scen.write_text(text)
    sc = load_scenario(scen, {"sim.duration": 0.3})
    assert sc.robot.kind == "mjcf"
    result = simulate(sc)
    assert result.meta["status"] == "ok"
    assert result.meta["robot"]["model"] == str((tmp_path / "arms" / "rtr.xml").resolve())
    # on the cylinder r = 0.4 all along, pressing with f_d = 10 N at the end
    assert np.max(np.abs(np.hypot(result.p[:, 0], result.p[:, 1]) - 0.4)) < 1e-9
    assert abs(result.f[-1] - 10.0) < 0.5


def test_mjcf_free_and_ball_joints_and_includes_are_refused(tmp_path: Path) -> None:
    free = tmp_path / "free.xml"
    free.write_text(
        RTR_MJCF.replace('<body name="link1">', '<body name="link1"><freejoint name="fly"/>')
    )
    with pytest.raises(RobotError) as info:
        load_robot(free)
    message = str(info.value)
    assert str(free) in message and "free joint 'fly'" in message and "fixed-base" in message
    ball = tmp_path / "ball.xml"
    ball.write_text(RTR_MJCF.replace('type="slide"', 'type="ball"'))
    with pytest.raises(RobotError, match=r"ball.xml: body 'link2' has a ball joint 'q2'"):
        load_robot(ball)
    inc = tmp_path / "inc.xml"
    inc.write_text(RTR_MJCF.replace("<worldbody>", '<include file="more.xml"/><worldbody>'))
    with pytest.raises(RobotError, match=r"inc.xml: <include file='more.xml'>: Pinocchio's MJCF"):
        load_robot(inc)
    broken = tmp_path / "broken.xml"
    broken.write_text(RTR_MJCF.replace('type="slide"', 'type="screw"'))
    with pytest.raises(
        RobotError, match=r"Pinocchio cannot parse MJCF .*broken.xml: Unknown joint"
    ):
        load_robot(broken)
    urdf_as_xml = tmp_path / "arm.xml"  # a URDF named .xml is a URDF
    urdf_as_xml.write_text(_planar_urdf())
    assert load_robot(urdf_as_xml).kind == "urdf"


def test_mjcf_mesh_inertia_is_warned(tmp_path: Path) -> None:
    """A body without <inertial> whose inertia would come from a mesh: Pinocchio does not
    compute it; a ModelWarning says so (the body's mass would be wrong)."""
    (tmp_path / "part.stl").write_text(STL)
    text = RTR_MJCF.replace(
        "<worldbody>", '<asset><mesh name="part" file="part.stl"/></asset><worldbody>'
    ).replace(
        '<body name="tip" pos="1 0 0"/>',
        '<body name="tip" pos="1 0 0"><geom type="mesh" mesh="part" mass="0.1"/></body>',
    )
    path = tmp_path / "m.xml"
    path.write_text(text)
    with pytest.warns(ModelWarning, match=r"body\(ies\) 'tip' have no <inertial> and a mesh geom"):
        load_robot(path)


def test_mjcf_replay_draws_its_mesh_and_warns_about_a_missing_one(tmp_path: Path) -> None:
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "part.stl").write_text(STL)
    path = _mjcf(
        tmp_path / "arm.xml",
        assets='<compiler meshdir="meshes"/><asset><mesh name="part" file="part.stl"/>'
        '<mesh name="gone" file="gone.stl"/></asset>',
        geom1='<geom type="mesh" mesh="part" mass="0"/>',
        geom2='<geom type="mesh" mesh="gone" mass="0"/>',
    )
    robot = load_robot(path, tip="tip")
    page, caught = _html(_result(robot), tmp_path)
    assert len(caught) == 1, [str(w.message) for w in caught]
    assert "mesh 'gone.stl' of body 'l2' not found" in str(caught[0].message)
    objects = _visual_objects(page)
    stl = [o for o in objects.values() if o["geometries"][0].get("format") == "stl"]
    assert len(stl) == 1 and stl[0]["geometries"][0]["data"].data == STL.encode()
    boxes = [
        o["geometries"][0] for o in objects.values() if o["geometries"][0]["type"] == "BoxGeometry"
    ]
    assert {(b["width"], b["height"], b["depth"]) for b in boxes} >= {
        (0.05, 0.05, 0.05),
        (0.5, 0.04, 0.04),
    }


# --- joints off the arm's chain -------------------------------------------------------------------
def _gripper_urdf(path: Path) -> Path:
    """The planar arm with a two-finger gripper on l2 (prismatic along y, 0.1 kg each):
    finger_a ranges over [0.01, 0.04] m (0 outside: held at 0.025), finger_b over
    [-0.02, 0.02] (held at 0), and a fixed frame 'flange' at the end of l2 (the tip)."""

    def finger(name: str, y: float, limits: tuple[float, float]) -> str:
        return (
            _rod_link(f"{name}_link", 0.05, 0.1)
            + f'<joint name="{name}" type="prismatic"><parent link="l2"/>'
            f'<child link="{name}_link"/><origin xyz="0.5 {y} 0"/><axis xyz="0 1 0"/>'
            f'<limit lower="{limits[0]}" upper="{limits[1]}" effort="5" velocity="1"/></joint>'
        )

    text = _planar_urdf().replace(
        "</robot>",
        finger("finger_a", 0.0, (0.01, 0.04))
        + finger("finger_b", 0.0, (-0.02, 0.02))
        + '<link name="flange"/><joint name="flange_joint" type="fixed"><parent link="l2"/>'
        '<child link="flange"/><origin xyz="0.5 0 0"/></joint></robot>',
    )
    path.write_text(text)
    return path


def test_joints_off_the_chain_are_locked_by_default_for_a_file(tmp_path: Path) -> None:
    path = _gripper_urdf(tmp_path / "gripper.urdf")
    robot = load_robot(path, tip="tip")
    assert [robot.model.names[j] for j in range(1, robot.model.njoints)] == ["j1", "j2"]
    data = robot.new_data()
    import pinocchio as pin

    q = np.array([0.4, -0.7])
    pin.framesForwardKinematics(robot.model, data, q)
    c, s = math.cos(q[0] + q[1]), math.sin(q[0] + q[1])
    end = _planar_p(q, 1.0, 0.5)
    for frame, y in (("finger_a_link", 0.025), ("finger_b_link", 0.0)):
        expected = end + np.array([-s * y, c * y, 0.0])  # y along l2's own y axis
        np.testing.assert_allclose(
            data.oMf[robot.model.getFrameId(frame)].translation, expected, atol=1e-15
        )
    # the locked fingers' masses ride on l2: M of an arm whose l2 carries 0.2 kg more
    total = sum(i.mass for i in robot.model.inertias)
    assert total == pytest.approx(3.2, abs=1e-12)
    free = load_robot(path, tip="tip", lock_off_chain=False)
    assert free.nv == 4 and free.reference["lock_off_chain"] is False
    np.testing.assert_allclose(free.tip_position([0.4, -0.7, 0, 0]), end, atol=1e-15)


def test_the_default_tip_of_a_gripper_file_decides_what_is_locked(tmp_path: Path) -> None:
    """The default tip is the last body frame of Pinocchio's model (unchanged); the joints
    kept are those the URDF's XML puts between the root and that link."""
    import pinocchio as pin

    path = _gripper_urdf(tmp_path / "g.urdf")
    full = pin.buildModelFromUrdf(str(path))
    last = [f.name for f in full.frames if f.type == pin.FrameType.BODY][-1]
    robot = load_robot(path)
    assert robot.tip == last
    assert list(robot.model.names)[1:] == _chain_joints(path, last)


def test_a_tip_on_the_base_cannot_lock_the_rest(tmp_path: Path) -> None:
    path = _gripper_urdf(tmp_path / "g.urdf")
    with pytest.raises(RobotError, match=r"tip frame 'base' .* is on the base"):
        load_robot(path, tip="base")


def _chain_joints(urdf: Path, tip_link: str) -> list[str]:
    """The moving joints from the root to a link, read from the URDF's XML by hand."""
    root = ET.parse(urdf).getroot()
    parent = {j.find("child").get("link"): j for j in root.findall("joint")}
    out, link = [], tip_link
    while link in parent:
        joint = parent[link]
        if joint.get("type") != "fixed":
            out.append(joint.get("name"))
        link = joint.find("parent").get("link")
    return out[::-1]


def test_registry_arms_keep_their_joints_unless_asked() -> None:
    """z1 keeps its gripper joint and g1 its 29 joints (hybrid-force robots); asked to lock,
    they keep only the joints on the chain to their tips."""
    z1, g1 = load_robot("z1"), load_robot("g1")
    assert (z1.nv, g1.nv) == (7, 29)
    z1_arm = load_robot("z1", lock_off_chain=True)
    g1_arm = load_robot("g1", lock_off_chain=True)
    for arm, full in ((z1_arm, z1), (g1_arm, g1)):
        expected = _chain_joints(full.urdf_path, "right_rubber_hand" if arm is g1_arm else "link06")
        assert list(arm.model.names)[1:] == expected
        # the kept joints move the tip as in the full model (the others at 0, inside range)
        q_full = np.zeros(full.nv)
        rng = np.random.default_rng(2)
        q = rng.uniform(-0.3, 0.3, arm.nv)
        for name, value in zip(expected, q, strict=True):
            q_full[full.model.idx_qs[full.model.getJointId(name)]] = value
        np.testing.assert_allclose(arm.tip_position(q), full.tip_position(q_full), atol=1e-12)
    assert load_robot("panda").nv == load_robot("panda", lock_off_chain=True).nv == 7


def test_scenario_lock_off_chain_key(tmp_path: Path) -> None:
    """The RTR with a finger on link 3: locked by default (3 joints), kept when asked."""
    text = (
        (REPO / "robots" / "rtr.urdf")
        .read_text()
        .replace(
            "</robot>",
            _rod_link("finger_link", 0.05, 0.1)
            + '<joint name="finger" type="prismatic"><parent link="link3"/>'
            '<child link="finger_link"/><origin xyz="0.5 0 0"/><axis xyz="0 1 0"/>'
            '<limit lower="0" upper="0.04" effort="5" velocity="1"/></joint></robot>',
        )
    )
    (tmp_path / "fingered.urdf").write_text(text)
    scen = _rtr_scenario(tmp_path / "s.toml", 'model = "fingered.urdf"\ntip = "tip"')
    assert load_scenario(scen).robot.nv == 3
    kept = _rtr_scenario(
        tmp_path / "k.toml", 'model = "fingered.urdf"\ntip = "tip"\nlock_off_chain = false'
    )
    with pytest.raises(ScenarioError, match=r"initial.seed = .*must have 4 numbers"):
        load_scenario(kept)


def test_robots_check_takes_the_load_options(tmp_path: Path, capsys) -> None:
    """``robots --check`` loads a xacro arm with its argument: the reported reach is the
    joint-to-joint distance l1 plus l2 (both revolute), and the total mass 2 + 1 kg."""
    from hybrid_force.cli import main

    path = _xacro_arm(tmp_path)
    assert main(["robots", "--check", str(path), "--xacro-arg", "l1=0.7"]) == 0
    out = capsys.readouterr().out
    assert "reach: 1.2 m" in out and "total mass: 3 kg" in out
    assert main(["robots", "--xacro-arg", "l1=0.7"]) == 2
    assert "--xacro-arg needs --check MODEL" in capsys.readouterr().err
    assert main(["robots", "--check", str(path), "--xacro-arg", "l1"]) == 2
    assert "must look like NAME=VALUE" in capsys.readouterr().err

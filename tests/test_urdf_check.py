"""hybrid_force.model.urdf_check: what breaks the simulation raises RobotError, implausible but
simulable inertial data is one ModelWarning per link, unsimulated links are not checked,
and extension tags (including undeclared namespace prefixes) do not stop a model; every
message names the file, the link and the values."""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hybrid_force.errors import BadInputError, ModelWarning, RobotError
from hybrid_force.model.urdf_check import check_urdf
from hybrid_force.model.urdf_text import urdf_text

_JOINT = (
    '<joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>'
    '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>'
)


def _inertial(mass: str, ixx: str, ixy: str, ixz: str, iyy: str, iyz: str, izz: str) -> str:
    return (
        f'<inertial><origin xyz="0 0 0"/><mass value="{mass}"/>'
        f'<inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/>'
        "</inertial>"
    )


def _urdf(arm_inertial: str = "", joint: str = _JOINT) -> str:
    return (
        f'<?xml version="1.0"?>\n<robot name="t"><link name="base"/>'
        f'<link name="arm">{arm_inertial}</link>{joint}</robot>\n'
    )


def _write(tmp_path: Path, text: str, name: str = "robot.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _rotated_inertia(moments: tuple[float, float, float], seed: int) -> tuple[str, ...]:
    """Six URDF inertia entries of diag(moments) in a random rotated frame."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    inertia = Q @ np.diag(moments) @ Q.T
    return tuple(
        repr(float(inertia[i, j])) for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
    )


# --- accepted -------------------------------------------------------------------------
def test_bundled_rtr_passes(rtr_urdf: Path) -> None:
    check_urdf(rtr_urdf)


@pytest.mark.parametrize(
    "inertial",
    [
        "",  # no <inertial>: massless frame
        _inertial("0", "0", "0", "0", "0", "0", "0"),  # documented massless exception
        _inertial("2", "0", "0", "0", "0", "0", "0"),  # point mass
        _inertial("2", "0", "0", "0", "0.5", "0", "0.5"),  # thin rod: 0 + I = I (equality)
        _inertial("2", "1", "0", "0", "2", "0", "3"),  # triangle equality with non-zero I1
        _inertial("2", *_rotated_inertia((1.0, 2.0, 2.5), seed=3)),  # rotated valid body
    ],
    ids=["no-inertial", "zero-mass-zero-inertia", "point-mass", "thin-rod", "flat", "rotated"],
)
def test_plausible_inertials_pass(tmp_path: Path, inertial: str) -> None:
    check_urdf(_write(tmp_path, _urdf(inertial)))


# --- files and XML --------------------------------------------------------------------
def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.urdf"
    with pytest.raises(RobotError, match=r"not found.*nope\.urdf"):
        check_urdf(path)


def test_directory_is_not_a_file(tmp_path: Path) -> None:
    with pytest.raises(RobotError, match="not a file"):
        check_urdf(tmp_path)


def test_malformed_xml_reports_parser_reason_and_position(tmp_path: Path) -> None:
    path = _write(tmp_path, '<robot name="t"><link name="a">\n</robot>\n', "bad.urdf")
    with pytest.raises(RobotError) as info:
        check_urdf(path)
    message = str(info.value)
    assert "bad.urdf" in message
    assert "mismatched tag" in message
    assert "line 2" in message


def test_empty_file(tmp_path: Path) -> None:
    with pytest.raises(RobotError, match=r"empty\.urdf.*no element found"):
        check_urdf(_write(tmp_path, "", "empty.urdf"))


def test_xml_that_is_not_a_urdf(tmp_path: Path) -> None:
    with pytest.raises(RobotError, match=r"not a URDF.*<sdf>.*expected <robot>"):
        check_urdf(_write(tmp_path, '<sdf version="1.6"><model name="m"/></sdf>'))


def test_robot_without_links(tmp_path: Path) -> None:
    with pytest.raises(RobotError, match="no <link>"):
        check_urdf(_write(tmp_path, '<robot name="t"></robot>'))


def test_urdf_error_is_bad_input() -> None:
    assert issubclass(RobotError, BadInputError)


@pytest.mark.parametrize(
    ("joint", "pattern"),
    [
        (_JOINT.replace('type="revolute"', 'type="hinge"'), r"'j1'.*'hinge'.*valid types"),
        (_JOINT.replace('child link="arm"', 'child link="elbow"'), r"'j1'.*child.*'elbow'"),
        (_JOINT.replace('<parent link="base"/>', ""), r"'j1' has no <parent"),
        (_JOINT.replace(' effort="10"', ""), r"revolute joint 'j1' lacks effort"),
        (
            _JOINT.replace('<limit lower="-1" upper="1" effort="10" velocity="1"/>', ""),
            r"revolute joint 'j1' lacks <limit>",
        ),
        ("", r"one root link.*'arm', 'base'"),
    ],
    ids=["joint-type", "unknown-child", "no-parent", "no-effort", "no-limit", "two-roots"],
)
def test_structural_errors(tmp_path: Path, joint: str, pattern: str) -> None:
    with pytest.raises(RobotError, match=pattern):
        check_urdf(_write(tmp_path, _urdf(joint=joint)))


def test_duplicate_link_name(tmp_path: Path) -> None:
    text = _urdf().replace('<link name="base"/>', '<link name="base"/><link name="base"/>')
    with pytest.raises(RobotError, match="duplicate link name 'base'"):
        check_urdf(_write(tmp_path, text))


def test_non_numeric_mass(tmp_path: Path) -> None:
    inertial = _inertial("heavy", "1", "0", "0", "1", "0", "1")
    with pytest.raises(RobotError, match=r"'arm'.*value='heavy' is not a number"):
        check_urdf(_write(tmp_path, _urdf(inertial)))


# --- refused: inertial data the simulation cannot take ----------------------------------
def test_negative_mass(tmp_path: Path) -> None:
    path = _write(tmp_path, _urdf(_inertial("-1.5", "1", "0", "0", "1", "0", "1")))
    with pytest.raises(RobotError) as info:
        check_urdf(path)
    message = str(info.value)
    assert str(path) in message
    assert "'arm'" in message
    assert "mass = -1.5 kg" in message


def test_negative_mass_with_zero_inertia_is_refused_too(tmp_path: Path) -> None:
    with pytest.raises(RobotError, match=r"'arm'.*mass = -2 kg"):
        check_urdf(_write(tmp_path, _urdf(_inertial("-2", "0", "0", "0", "0", "0", "0"))))


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_non_finite_values(tmp_path: Path, value: str) -> None:
    with pytest.raises(RobotError, match=rf"mass {value} is not finite"):
        check_urdf(_write(tmp_path, _urdf(_inertial(value, "1", "0", "0", "1", "0", "1"))))
    with pytest.raises(RobotError, match="non-finite"):
        check_urdf(_write(tmp_path, _urdf(_inertial("1", value, "0", "0", "1", "0", "1"))))


def test_negative_diagonal_is_not_psd(tmp_path: Path) -> None:
    path = _write(tmp_path, _urdf(_inertial("1", "-0.1", "0", "0", "1", "0", "1")))
    with pytest.raises(RobotError, match=r"'arm'.*not positive semi-definite.*ixx=-0\.1"):
        check_urdf(path)


def test_large_product_of_inertia_is_not_psd(tmp_path: Path) -> None:
    """diag(1, 1, 1) with ixy = 2: eigenvalues −1, 1, 3 (independent: det < 0)."""
    inertia = np.array([[1, 2, 0], [2, 1, 0], [0, 0, 1]], dtype=float)
    assert np.linalg.det(inertia) < 0
    path = _write(tmp_path, _urdf(_inertial("1", "1", "2", "0", "1", "0", "1")))
    with pytest.raises(RobotError, match=r"not positive semi-definite.*principal moments -1, 1, 3"):
        check_urdf(path)


def test_massless_link_with_a_non_psd_inertia_is_refused(tmp_path: Path) -> None:
    """Mass 0 is only a warning; an indefinite inertia on top of it is still refused."""
    with pytest.raises(RobotError, match=r"'arm'.*not positive semi-definite"):
        check_urdf(_write(tmp_path, _urdf(_inertial("0", "1", "2", "0", "1", "0", "1"))))


def test_psd_tolerance_is_round_off_of_six_digits(tmp_path: Path) -> None:
    """A thin rod (moments 0, 1, 1) whose zero moment was printed as -1e-6 passes (silently):
    1e-6 of the largest moment is 6-digit rounding. -1e-3 is no rounding: refused."""
    check_urdf(_write(tmp_path, _urdf(_inertial("1", "-1e-06", "0", "0", "1", "0", "1"))))
    with pytest.raises(RobotError, match=r"not positive semi-definite.*-0\.001"):
        check_urdf(_write(tmp_path, _urdf(_inertial("1", "-0.001", "0", "0", "1", "0", "1"))))


# --- warned about: implausible, but the dynamics are well defined ----------------------------
def _one_model_warning(path: Path) -> str:
    """The message of the single ModelWarning check_urdf(path) issues (it must not raise)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_urdf(path)
    assert [w.category for w in caught] == [ModelWarning], [str(w.message) for w in caught]
    message = str(caught[0].message)
    assert message.startswith(f"{path}: link 'arm': ")  # names the file and the link
    return message


def test_massless_link_with_inertia_warns(tmp_path: Path) -> None:
    """Mass 0, inertia diag(1, 1, 1) (a valid rotational inertia): one warning, not refused."""
    message = _one_model_warning(
        _write(tmp_path, _urdf(_inertial("0", "1", "0", "0", "1", "0", "1")))
    )
    assert "mass 0 kg" in message and "ixx=1" in message and "izz=1" in message
    assert "mass 0 with a non-zero inertia" in message
    assert "triangle" not in message  # 1 + 1 >= 1


def test_triangle_inequality_broken_warns(tmp_path: Path) -> None:
    """Principal moments 1, 1, 3: PSD, but 1 + 1 < 3 by 1 (33.3 % of I3, by hand)."""
    message = _one_model_warning(
        _write(tmp_path, _urdf(_inertial("1", "1", "0", "0", "1", "0", "3")))
    )
    assert "principal moments 1, 1, 3" in message
    assert "falls short of I3 by 1 kg m² (33.3 % of I3)" in message
    assert "triangle inequality" in message
    assert "mass 1 kg" in message and "mass 0 with" not in message


def test_triangle_inequality_broken_in_a_rotated_frame_warns(tmp_path: Path) -> None:
    """The check uses principal moments, so a rotation does not hide the violation:
    0.5 + 1 < 2 by 0.5 = 25 % of I3."""
    entries = _rotated_inertia((0.5, 1.0, 2.0), seed=11)
    message = _one_model_warning(_write(tmp_path, _urdf(_inertial("1", *entries))))
    assert "principal moments 0.5, 1, 2" in message
    assert "by 0.5 kg m² (25 % of I3)" in message


def test_one_warning_per_link_lists_every_finding(tmp_path: Path) -> None:
    message = _one_model_warning(
        _write(tmp_path, _urdf(_inertial("0", "1", "0", "0", "1", "0", "3")))
    )
    assert "mass 0 with a non-zero inertia" in message
    assert "falls short of I3 by 1 kg m²" in message


def test_a_few_percent_off_the_triangle_inequality_loads_with_one_warning(
    tmp_path: Path,
) -> None:
    """A published-URDF kind of error (moments 0.1, 0.2, 0.31: 3.2 % short) loads through
    load_robot with its one warning, and the arm simulates: M(q0) by hand is izz + m r² of
    the link about the joint's z axis = 0.31 + 1 · 0.5² = 0.56 kg m²."""
    from hybrid_force.model.loading import load_robot

    inertial = _inertial("1", "0.1", "0", "0", "0.2", "0", "0.31").replace(
        '<origin xyz="0 0 0"/>', '<origin xyz="0.5 0 0"/>'
    )
    path = _write(tmp_path, _urdf(inertial))
    with pytest.warns(ModelWarning, match=r"'arm'.*falls short of I3 by 0\.01 kg m² \(3\.23 %"):
        robot = load_robot(path)
    np.testing.assert_allclose(robot.mass_matrix(np.zeros(1)), [[0.56]], rtol=1e-12)


def test_triangle_tolerance_accepts_rounding_only(tmp_path: Path) -> None:
    """A thin rod rounded by 1e-9 or 1e-5 relative (6 significant digits) passes silently; a
    1e-3 relative violation warns."""
    for izz in ("1.000000001", "1.00001"):
        check_urdf(_write(tmp_path, _urdf(_inertial("1", "0", "0", "0", "1.0", "0", izz))))
    bad = _inertial("1", "0", "0", "0", "1.0", "0", "1.001")
    assert "triangle" in _one_model_warning(_write(tmp_path, _urdf(bad)))


def test_missing_inertia_element(tmp_path: Path) -> None:
    text = _urdf('<inertial><mass value="1"/></inertial>')
    with pytest.raises(RobotError, match=r"'arm'.*no <inertia>"):
        check_urdf(_write(tmp_path, text))


# --- outside the toolkit's scope (fixed-base arms with at least one moving joint) -------
@pytest.mark.parametrize("jtype", ["floating", "planar"])
def test_floating_and_planar_joints_are_refused(tmp_path: Path, jtype: str) -> None:
    joint = f'<joint name="free" type="{jtype}"><parent link="base"/><child link="arm"/></joint>'
    with pytest.raises(RobotError) as info:
        check_urdf(_write(tmp_path, _urdf(joint=joint)))
    message = str(info.value)
    assert "robot.urdf" in message
    assert f"joint 'free' (parent link 'base', child link 'arm') is a {jtype} joint" in message
    assert "fixed-base arms only" in message


def test_a_model_needs_a_moving_joint(tmp_path: Path) -> None:
    fixed = '<joint name="j1" type="fixed"><parent link="base"/><child link="arm"/></joint>'
    with pytest.raises(RobotError, match=r"no moving joint \(its only joint is fixed, so nv = 0\)"):
        check_urdf(_write(tmp_path, _urdf(joint=fixed)))
    check_urdf(_write(tmp_path, _urdf()))  # the same tree with j1 revolute passes


def test_a_single_link_without_joints_has_no_moving_joint(tmp_path: Path) -> None:
    with pytest.raises(RobotError, match=r"robot\.urdf.*no moving joint \(it has no joint"):
        check_urdf(_write(tmp_path, '<robot name="t"><link name="only"/></robot>'))


def test_mimic_attributes_are_checked(tmp_path: Path) -> None:
    two = _urdf(joint=_JOINT).replace(
        "</robot>",
        '<link name="hand"/><joint name="j2" type="revolute"><parent link="arm"/>'
        '<child link="hand"/><limit effort="1" velocity="1"/>MIMIC</joint></robot>',
    )
    check_urdf(_write(tmp_path, two.replace("MIMIC", '<mimic joint="j1" multiplier="2"/>')))
    with pytest.raises(RobotError, match=r"'j2': <mimic>.*multiplier='two' is not a number"):
        check_urdf(_write(tmp_path, two.replace("MIMIC", '<mimic joint="j1" multiplier="two"/>')))
    with pytest.raises(RobotError, match=r"'j2' has <mimic joint='nope'>"):
        check_urdf(_write(tmp_path, two.replace("MIMIC", '<mimic joint="nope"/>')))
    with pytest.raises(RobotError, match=r"'j2' has <mimic joint='j2'>"):
        check_urdf(_write(tmp_path, two.replace("MIMIC", '<mimic joint="j2"/>')))


# --- numbers urdfdom would choke on (several lines on stderr) or accept (NaN) ----------------
@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>', "has no direction"),
        ('<axis xyz="0 0 1"/>', '<axis xyz="nan 0 1"/>', "must be 3 finite numbers"),
        ('<axis xyz="0 0 1"/>', '<axis xyz="0 1"/>', "must be 3 finite numbers"),
        ('<origin xyz="0.9 0 0" rpy="0 0 0"/>', '<origin xyz="inf 0 0"/>', "3 finite numbers"),
        ('lower="-1" upper="16"', 'lower="16" upper="-1"', "lower is above upper"),
        ('lower="-1" upper="16"', 'lower="nan" upper="16"', "must be finite"),
        ('upper="16" effort="0"', 'upper="16" effort="-5"', "finite and >= 0"),
    ],
    ids=["zero-axis", "nan-axis", "short-axis", "inf-origin", "lower-above-upper",
         "nan-lower", "negative-effort"],
)  # fmt: skip
def test_joint_numbers_are_checked_before_pinocchio(
    tmp_path: Path, rtr_urdf: Path, old: str, new: str, words: str
) -> None:
    text = rtr_urdf.read_text()
    assert old in text
    path = tmp_path / "arm.urdf"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(RobotError, match=words) as info:
        check_urdf(path)
    assert str(path) in str(info.value)


def test_a_parser_complaint_on_a_model_that_loads_is_one_warning(
    tmp_path: Path, rtr_urdf: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """urdfdom skips a visual it cannot read and writes several lines on the C stderr: they
    become one ModelWarning naming the file, and nothing reaches stderr directly."""
    from hybrid_force.errors import ModelWarning
    from hybrid_force.model.loading import load_robot

    text = rtr_urdf.read_text().replace('<cylinder radius="0.03"', '<cylinder radius="abc"', 1)
    path = tmp_path / "arm.urdf"
    path.write_text(text)
    with pytest.warns(ModelWarning, match=r"arm.urdf: .*radius \[abc\]"):
        robot = load_robot(path)
    assert robot.nv == 3
    assert capfd.readouterr().err == ""


# --- links that are not simulated: the root and what is welded to it --------------------------
_BAD_INERTIALS = {
    "nan-mass": _inertial("nan", "1", "0", "0", "1", "0", "1"),
    "negative-mass": _inertial("-3", "1", "0", "0", "1", "0", "1"),
    "not-psd": _inertial("1", "1", "2", "0", "1", "0", "1"),
    "triangle": _inertial("1", "1", "0", "0", "1", "0", "3"),
    "massless-with-inertia": _inertial("0", "0.1", "0", "0", "0.1", "0", "0.1"),
    "no-mass": '<inertial><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>',
}
_ARM = _inertial("2", "0.01", "0", "0", "0.1", "0", "0.1").replace(
    '<origin xyz="0 0 0"/>', '<origin xyz="0.5 0 0"/>'
)


def _welded_arm(root: str = "", plate: str = "", flange: str = "") -> str:
    """world (root) -fixed-> plate -fixed-> mount -j1 (revolute z)-> arm -fixed-> flange.

    world, plate and mount are merged into Pinocchio's universe; arm and flange move with j1.
    """
    fixed = '<joint name="{0}" type="fixed"><parent link="{1}"/><child link="{2}"/></joint>'
    return (
        '<?xml version="1.0"?>\n<robot name="t">'
        f'<link name="world">{root}</link><link name="plate">{plate}</link>'
        f'<link name="mount"/><link name="arm">{_ARM}</link><link name="flange">{flange}</link>'
        + fixed.format("w1", "world", "plate")
        + fixed.format("w2", "plate", "mount")
        + '<joint name="j1" type="revolute"><parent link="mount"/><child link="arm"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>'
        + fixed.format("w3", "arm", "flange").replace(
            "/></joint>", '/><origin xyz="1 0 0"/></joint>'
        )
        + "</robot>\n"
    )


@pytest.mark.parametrize("case", _BAD_INERTIALS)
@pytest.mark.parametrize("where", ["root", "plate"])
def test_links_welded_to_the_root_are_not_checked(tmp_path: Path, case: str, where: str) -> None:
    """Whatever the root link or a link fixed to it (through two fixed joints) declares, the
    check says nothing (filterwarnings = error would turn a warning into a failure)."""
    check_urdf(_write(tmp_path, _welded_arm(**{where: _BAD_INERTIALS[case]})))


@pytest.mark.parametrize("case", ["negative-mass", "not-psd", "triangle", "massless-with-inertia"])
def test_a_bad_root_inertial_does_not_change_the_dynamics(tmp_path: Path, case: str) -> None:
    """The same arm with and without the root's inertial: the same M(q), loaded silently.
    By hand: M = izz + m r² = 0.1 + 2 · 0.5² = 0.6 kg m² about j1."""
    from hybrid_force.model.loading import load_robot

    plain = load_robot(_write(tmp_path, _welded_arm(), "plain.urdf"))
    odd = load_robot(_write(tmp_path, _welded_arm(root=_BAD_INERTIALS[case]), "odd.urdf"))
    for q in ([0.0], [0.7]):
        np.testing.assert_allclose(plain.mass_matrix(q), [[0.6]], rtol=1e-12)
        np.testing.assert_array_equal(odd.mass_matrix(q), plain.mass_matrix(q))


def test_a_massless_end_link_with_inertia_is_checked_and_warns(tmp_path: Path) -> None:
    """The flange is fixed to the moving arm, so it is simulated: mass 0 with izz = 0.05 warns
    once, names the flange, and adds 0.05 kg m² to M (0.6 + 0.05 by hand)."""
    from hybrid_force.model.loading import load_robot

    flange = _inertial("0", "0.05", "0", "0", "0.05", "0", "0.05")
    path = _write(tmp_path, _welded_arm(flange=flange))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_urdf(path)
    assert len(caught) == 1 and caught[0].category is ModelWarning
    assert str(caught[0].message).startswith(f"{path}: link 'flange': <inertial> mass 0 kg")
    with pytest.warns(ModelWarning, match="'flange'"):
        robot = load_robot(path)
    np.testing.assert_allclose(robot.mass_matrix([0.0]), [[0.65]], rtol=1e-12)


# --- extension tags and undeclared namespace prefixes ------------------------------------------
_EXTENSIONS = (
    '<gazebo reference="arm"><material>Gazebo/Orange</material><mu1>0.2</mu1></gazebo>'
    '<transmission name="t1"><type>transmission_interface/SimpleTransmission</type>'
    '<joint name="j1"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>'
    '<actuator name="m1"><mechanicalReduction>50</mechanicalReduction></actuator></transmission>'
    '<ros2_control name="hw" type="system"><joint name="j1"><command_interface name="effort"/>'
    "</joint></ros2_control>"
    '<drake:joint name="j9" type="planar"><drake:parent link="base"/></drake:joint>'
)


def _extended(arm: str = _ARM) -> tuple[str, str]:
    """(plain URDF, the same with extension tags and undeclared prefixes on link and joint)."""
    plain = _urdf(arm)
    extended = (
        plain.replace('<link name="arm">', '<link name="arm" drake:compliance="1e6">')
        .replace('<joint name="j1"', '<joint name="j1" gz:damping="0.1"')
        .replace("</robot>", _EXTENSIONS + "</robot>")
    )
    return plain, extended


def test_undeclared_prefix_is_refused_by_plain_xml_parsers(tmp_path: Path) -> None:
    """The problem being solved: ElementTree refuses the file ("unbound prefix")."""
    path = _write(tmp_path, _extended()[1])
    with pytest.raises(ET.ParseError, match="unbound prefix"):
        ET.parse(path)


def test_extension_tags_and_undeclared_prefixes_load(tmp_path: Path) -> None:
    """check_urdf accepts the file silently; urdf_text's result parses with ElementTree and
    Pinocchio builds from it (directly and after an ElementTree round trip, as the loader does)
    the same model as from the plain file: extensions change nothing."""
    plain, extended = _extended()
    path = _write(tmp_path, extended)
    check_urdf(path)
    text = urdf_text(path)
    root = ET.fromstring(text)
    assert root.get("name") == "t"
    drake = "{urn:hybrid-force:undeclared-prefix:drake}"
    assert root.find("link[@name='arm']").get(f"{drake}compliance") == "1e6"
    assert [j.get("name") for j in root.findall("joint")] == ["j1"]  # not the nested ones
    reference = pin.buildModelFromXML(plain)
    for xml in (text, ET.tostring(root, encoding="unicode")):
        model = pin.buildModelFromXML(xml)
        assert list(model.names) == list(reference.names) == ["universe", "j1"]
        assert model.inertias[1] == reference.inertias[1]
        assert model.jointPlacements[1] == reference.jointPlacements[1]
        np.testing.assert_array_equal(model.upperPositionLimit, [1.0])


def test_urdf_text_declares_undeclared_prefixes_on_the_root_only(tmp_path: Path) -> None:
    """Only the root start tag changes, so every line number stays the same; a prefix declared
    on one element does not cover its sibling, so it is declared on the root too; 'xml:' is
    always bound; a file without undeclared prefixes comes back unchanged."""
    text = (
        '<?xml version="1.0"?>\n<robot name="t">\n'
        '<link name="base" xmlns:a="urn:a" a:x="1" xml:lang="en"/>\n'
        '<link name="arm" a:y="2"/>\n' + _JOINT + "\n</robot>\n"
    )
    path = _write(tmp_path, text)
    out = urdf_text(path)
    assert out.splitlines()[1] == (
        '<robot xmlns:a="urn:hybrid-force:undeclared-prefix:a" name="t">'
    )
    assert out.splitlines()[2:] == text.splitlines()[2:]
    assert ET.fromstring(out).find("link[@name='base']").get("{urn:a}x") == "1"
    clean = _write(tmp_path, _urdf(_ARM), "clean.urdf")
    assert urdf_text(clean) == clean.read_text()


def test_urdf_text_decodes_the_declared_encoding(tmp_path: Path) -> None:
    """A Latin-1 file with a non-ASCII name: the text is decoded from Latin-1, its declaration
    then says UTF-8 (what the text is when encoded for Pinocchio and lxml)."""
    path = tmp_path / "latin.urdf"
    text = _urdf(_ARM).replace('version="1.0"', 'version="1.0" encoding="ISO-8859-1"')
    text = text.replace('name="arm"', 'name="bras_é"').replace('link="arm"', 'link="bras_é"')
    path.write_bytes(text.encode("latin-1"))
    out = urdf_text(path)
    assert out.startswith('<?xml version="1.0" encoding="UTF-8"?>')
    assert ET.fromstring(out.encode("utf-8")).find("link[2]").get("name") == "bras_é"
    model = pin.buildModelFromXML(out)
    assert model.frames[model.getFrameId("bras_é")].name == "bras_é"


def test_urdf_text_strips_a_utf8_byte_order_mark(tmp_path: Path) -> None:
    path = tmp_path / "bom.urdf"
    path.write_bytes(b"\xef\xbb\xbf" + _urdf(_ARM).encode())
    assert urdf_text(path) == _urdf(_ARM)
    check_urdf(path)


def test_urdf_text_reports_malformed_xml_like_the_check(tmp_path: Path) -> None:
    path = _write(tmp_path, '<robot name="t" a:b="1"><link name="a">\n</robot>\n', "bad.urdf")
    expected = r"malformed URDF .*bad\.urdf: XML parse error: mismatched tag: line 2"
    with pytest.raises(RobotError, match=expected):
        urdf_text(path)


def test_check_urdf_takes_the_text_it_is_given(tmp_path: Path) -> None:
    """check_urdf(path, text=...) checks the text (e.g. an expansion) and names the path."""
    path = tmp_path / "virtual.urdf"  # never written
    check_urdf(path, text=_urdf(_ARM))
    with pytest.raises(RobotError, match=r"virtual\.urdf.*mass = -1 kg"):
        check_urdf(path, text=_urdf(_inertial("-1", "1", "0", "0", "1", "0", "1")))


def test_load_robot_accepts_extension_tags_and_undeclared_prefixes(tmp_path: Path) -> None:
    """The loader builds from urdf_text: the extended file gives the plain file's dynamics
    (M = izz + m r² = 0.1 + 2 · 0.5² = 0.6 kg m² by hand), silently."""
    from hybrid_force.model.loading import load_robot

    plain, extended = _extended()
    robot = load_robot(_write(tmp_path, extended))
    reference = load_robot(_write(tmp_path, plain, "plain.urdf"))
    assert robot.nv == reference.nv == 1
    np.testing.assert_allclose(robot.mass_matrix([0.3]), [[0.6]], rtol=1e-12)
    np.testing.assert_array_equal(robot.mass_matrix([0.3]), reference.mass_matrix([0.3]))

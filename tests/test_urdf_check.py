"""hybrid_force.urdf_check: every broken-URDF case raises URDFError naming file, link, values."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hybrid_force.errors import BadInputError, URDFError
from hybrid_force.urdf_check import check_urdf

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
    with pytest.raises(URDFError, match=r"not found.*nope\.urdf"):
        check_urdf(path)


def test_directory_is_not_a_file(tmp_path: Path) -> None:
    with pytest.raises(URDFError, match="not a file"):
        check_urdf(tmp_path)


def test_malformed_xml_reports_parser_reason_and_position(tmp_path: Path) -> None:
    path = _write(tmp_path, '<robot name="t"><link name="a">\n</robot>\n', "bad.urdf")
    with pytest.raises(URDFError) as info:
        check_urdf(path)
    message = str(info.value)
    assert "bad.urdf" in message
    assert "mismatched tag" in message
    assert "line 2" in message


def test_empty_file(tmp_path: Path) -> None:
    with pytest.raises(URDFError, match=r"empty\.urdf.*no element found"):
        check_urdf(_write(tmp_path, "", "empty.urdf"))


def test_xml_that_is_not_a_urdf(tmp_path: Path) -> None:
    with pytest.raises(URDFError, match=r"not a URDF.*<sdf>.*expected <robot>"):
        check_urdf(_write(tmp_path, '<sdf version="1.6"><model name="m"/></sdf>'))


def test_robot_without_links(tmp_path: Path) -> None:
    with pytest.raises(URDFError, match="no <link>"):
        check_urdf(_write(tmp_path, '<robot name="t"></robot>'))


def test_urdf_error_is_bad_input() -> None:
    assert issubclass(URDFError, BadInputError)


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
    with pytest.raises(URDFError, match=pattern):
        check_urdf(_write(tmp_path, _urdf(joint=joint)))


def test_duplicate_link_name(tmp_path: Path) -> None:
    text = _urdf().replace('<link name="base"/>', '<link name="base"/><link name="base"/>')
    with pytest.raises(URDFError, match="duplicate link name 'base'"):
        check_urdf(_write(tmp_path, text))


def test_non_numeric_mass(tmp_path: Path) -> None:
    inertial = _inertial("heavy", "1", "0", "0", "1", "0", "1")
    with pytest.raises(URDFError, match=r"'arm'.*value='heavy' is not a number"):
        check_urdf(_write(tmp_path, _urdf(inertial)))


# --- physically impossible inertial data ----------------------------------------------
@pytest.mark.parametrize("mass", ["-1.5", "0"])
def test_non_positive_mass(tmp_path: Path, mass: str) -> None:
    path = _write(tmp_path, _urdf(_inertial(mass, "1", "0", "0", "1", "0", "1")))
    with pytest.raises(URDFError) as info:
        check_urdf(path)
    message = str(info.value)
    assert "robot.urdf" in message
    assert "'arm'" in message
    assert f"mass = {float(mass):g} kg" in message


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_non_finite_values(tmp_path: Path, value: str) -> None:
    with pytest.raises(URDFError, match=rf"mass {value} is not finite"):
        check_urdf(_write(tmp_path, _urdf(_inertial(value, "1", "0", "0", "1", "0", "1"))))
    with pytest.raises(URDFError, match="non-finite"):
        check_urdf(_write(tmp_path, _urdf(_inertial("1", value, "0", "0", "1", "0", "1"))))


def test_negative_diagonal_is_not_psd(tmp_path: Path) -> None:
    path = _write(tmp_path, _urdf(_inertial("1", "-0.1", "0", "0", "1", "0", "1")))
    with pytest.raises(URDFError, match=r"'arm'.*not positive semi-definite.*ixx=-0\.1"):
        check_urdf(path)


def test_large_product_of_inertia_is_not_psd(tmp_path: Path) -> None:
    """diag(1, 1, 1) with ixy = 2: eigenvalues −1, 1, 3 (independent: det < 0)."""
    inertia = np.array([[1, 2, 0], [2, 1, 0], [0, 0, 1]], dtype=float)
    assert np.linalg.det(inertia) < 0
    path = _write(tmp_path, _urdf(_inertial("1", "1", "2", "0", "1", "0", "1")))
    with pytest.raises(URDFError, match=r"not positive semi-definite.*principal moments -1, 1, 3"):
        check_urdf(path)


def test_triangle_inequality_broken(tmp_path: Path) -> None:
    """Principal moments 1, 1, 3: PSD, but 1 + 1 < 3 (no rigid body has them)."""
    path = _write(tmp_path, _urdf(_inertial("1", "1", "0", "0", "1", "0", "3")))
    with pytest.raises(URDFError) as info:
        check_urdf(path)
    message = str(info.value)
    assert "'arm'" in message
    assert "triangle inequality" in message
    assert "1, 1, 3" in message


def test_triangle_inequality_broken_in_a_rotated_frame(tmp_path: Path) -> None:
    """The check uses principal moments, so a rotation does not hide the violation."""
    entries = _rotated_inertia((0.5, 1.0, 2.0), seed=11)
    with pytest.raises(URDFError, match="triangle inequality"):
        check_urdf(_write(tmp_path, _urdf(_inertial("1", *entries))))


def test_triangle_tolerance_accepts_rounding_only(tmp_path: Path) -> None:
    """A thin rod rounded by 1e-9 relative passes; a 1e-3 relative violation does not."""
    ok = _inertial("1", "0", "0", "0", "1.0", "0", "1.000000001")
    check_urdf(_write(tmp_path, _urdf(ok)))
    bad = _inertial("1", "0", "0", "0", "1.0", "0", "1.001")
    with pytest.raises(URDFError, match="triangle inequality"):
        check_urdf(_write(tmp_path, _urdf(bad)))


def test_missing_inertia_element(tmp_path: Path) -> None:
    text = _urdf('<inertial><mass value="1"/></inertial>')
    with pytest.raises(URDFError, match=r"'arm'.*no <inertia>"):
        check_urdf(_write(tmp_path, text))


# --- outside the toolkit's scope (fixed-base arms with at least one moving joint) -------
@pytest.mark.parametrize("jtype", ["floating", "planar"])
def test_floating_and_planar_joints_are_refused(tmp_path: Path, jtype: str) -> None:
    joint = f'<joint name="free" type="{jtype}"><parent link="base"/><child link="arm"/></joint>'
    with pytest.raises(URDFError) as info:
        check_urdf(_write(tmp_path, _urdf(joint=joint)))
    message = str(info.value)
    assert "robot.urdf" in message
    assert f"joint 'free' (parent link 'base', child link 'arm') is a {jtype} joint" in message
    assert "fixed-base arms only" in message


def test_a_model_needs_a_moving_joint(tmp_path: Path) -> None:
    fixed = '<joint name="j1" type="fixed"><parent link="base"/><child link="arm"/></joint>'
    with pytest.raises(URDFError, match=r"no moving joint \(its only joint is fixed, so nv = 0\)"):
        check_urdf(_write(tmp_path, _urdf(joint=fixed)))
    check_urdf(_write(tmp_path, _urdf()))  # the same tree with j1 revolute passes


def test_a_single_link_without_joints_has_no_moving_joint(tmp_path: Path) -> None:
    with pytest.raises(URDFError, match=r"robot\.urdf.*no moving joint \(it has no joint"):
        check_urdf(_write(tmp_path, '<robot name="t"><link name="only"/></robot>'))


def test_mimic_attributes_are_checked(tmp_path: Path) -> None:
    two = _urdf(joint=_JOINT).replace(
        "</robot>",
        '<link name="hand"/><joint name="j2" type="revolute"><parent link="arm"/>'
        '<child link="hand"/><limit effort="1" velocity="1"/>MIMIC</joint></robot>',
    )
    check_urdf(_write(tmp_path, two.replace("MIMIC", '<mimic joint="j1" multiplier="2"/>')))
    with pytest.raises(URDFError, match=r"'j2': <mimic>.*multiplier='two' is not a number"):
        check_urdf(_write(tmp_path, two.replace("MIMIC", '<mimic joint="j1" multiplier="two"/>')))
    with pytest.raises(URDFError, match=r"'j2' has <mimic joint='nope'>"):
        check_urdf(_write(tmp_path, two.replace("MIMIC", '<mimic joint="nope"/>')))
    with pytest.raises(URDFError, match=r"'j2' has <mimic joint='j2'>"):
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
    with pytest.raises(URDFError, match=words) as info:
        check_urdf(path)
    assert str(path) in str(info.value)


def test_a_parser_complaint_on_a_model_that_loads_is_one_warning(
    tmp_path: Path, rtr_urdf: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """urdfdom skips a visual it cannot read and writes several lines on the C stderr: they
    become one ModelWarning naming the file, and nothing reaches stderr directly."""
    from hybrid_force.errors import ModelWarning
    from hybrid_force.robot import load_robot

    text = rtr_urdf.read_text().replace('<cylinder radius="0.03"', '<cylinder radius="abc"', 1)
    path = tmp_path / "arm.urdf"
    path.write_text(text)
    with pytest.warns(ModelWarning, match=r"arm.urdf: .*radius \[abc\]"):
        robot = load_robot(path)
    assert robot.nv == 3
    assert capfd.readouterr().err == ""

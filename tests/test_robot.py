"""Robot-model layer (hybrid_force.model.robot) beyond the RTR closed forms: any URDF arm.

References used here are independent of the code under test:
- J(q) against central finite differences of the tip position p(q);
- J̇(q, v) v against a central finite difference of J(q + v t) v in t;
- g(q) against finite differences of the potential energy, nle against RNEA at q̈ = 0;
- Ṁ − 2C skew-symmetric with Ṁ from finite differences of M along v;
- M symmetric positive definite; mass scaling is linear in M, C and g and leaves p and J alone.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hybrid_force.errors import BadInputError, RobotError
from hybrid_force.model.loading import load_robot
from hybrid_force.model.robot import Robot, RobotTerms

ARMS = ("rtr", "ur5", "panda")


@pytest.fixture(scope="module")
def arms() -> dict[str, Robot]:
    """The three arms of this file, loaded once."""
    return {name: load_robot(name) for name in ARMS}


def _random_state(robot: Robot, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random (q, v) within the joint limits (clipped to ±3 for wide/unbounded joints)."""
    lo = np.maximum(robot.model.lowerPositionLimit, -3.0)
    hi = np.minimum(robot.model.upperPositionLimit, 3.0)
    q = lo + (hi - lo) * rng.uniform(0.05, 0.95, robot.nq)
    v = rng.uniform(-1.5, 1.5, robot.nv)
    return q, v


def _fd_jacobian(robot: Robot, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """(3, n) central differences of the tip position."""
    cols = []
    for j in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[j] = h
        cols.append((robot.tip_position(q + dq) - robot.tip_position(q - dq)) / (2 * h))
    return np.column_stack(cols)


# --- loading -------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("name", "n", "tip"), [("rtr", 3, "tip"), ("ur5", 6, "tool0"), ("panda", 7, "panda_hand_tcp")]
)
def test_load_by_name(arms: dict[str, Robot], name: str, n: int, tip: str) -> None:
    robot = arms[name]
    assert robot.nq == robot.nv == n
    assert robot.tip == tip
    assert robot.model.frames[robot.tip_id].name == tip
    assert robot.urdf_path.is_file()
    assert robot.neutral().shape == (n,)


def test_load_rtr_by_path_and_tmp_copy(rtr_urdf: Path, tmp_path: Path) -> None:
    """The bundled file by path, and a copy elsewhere, give the same arm as the name."""
    rng = np.random.default_rng(1)
    ref = load_robot("rtr")
    copy = tmp_path / "my_arm.urdf"
    shutil.copy(rtr_urdf, copy)
    for source in (rtr_urdf, str(rtr_urdf), copy, str(copy)):
        robot = load_robot(source)
        assert robot.nv == 3
        # the default tip of a plain URDF is its last body frame: the "tip" link of rtr.urdf
        assert robot.tip == "tip"
        for _ in range(3):
            q, _v = _random_state(ref, rng)
            np.testing.assert_allclose(robot.tip_position(q), ref.tip_position(q), atol=1e-15)
            np.testing.assert_allclose(robot.mass_matrix(q), ref.mass_matrix(q), atol=1e-12)
    assert load_robot(copy).urdf_path == copy
    assert load_robot(str(copy)).source == str(copy.resolve())
    assert ref.source == "rtr"


def test_tip_keyword_picks_frame() -> None:
    """tip="link3" is the elbow end of link 3's frame: at the q3 joint, p = (c1 l2, s1 l2, q2)."""
    robot = load_robot("rtr", tip="link3")
    assert robot.tip == "link3"
    q = np.array([0.7, 3.0, 0.4])
    np.testing.assert_allclose(
        robot.tip_position(q), [0.9 * np.cos(0.7), 0.9 * np.sin(0.7), 3.0], atol=1e-14
    )
    ur5 = load_robot("ur5", tip="wrist_3_link")
    assert ur5.tip == "wrist_3_link"


# A one-joint arm: a 1 m rod turning about z (1 kg at its middle), tip at its end.
_ONE_JOINT = """<?xml version="1.0"?>
<robot name="one"><link name="base"/>
<link name="rod"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.09" iyz="0" izz="0.09"/></inertial></link>
<link name="end"/>
<joint name="spin" type="revolute"><parent link="base"/><child link="rod"/>
<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="5" velocity="2"/></joint>
<joint name="end_joint" type="fixed"><parent link="rod"/><child link="end"/>
<origin xyz="1 0 0"/></joint></robot>
"""


def test_a_bare_name_is_never_a_file_of_the_working_directory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, rtr_urdf: Path
) -> None:
    (tmp_path / "rtr").write_text(_ONE_JOINT)  # a file named like a registry arm
    (tmp_path / "myarm").write_text(_ONE_JOINT)
    monkeypatch.chdir(tmp_path)
    named = load_robot("rtr")  # the registry's arm, not ./rtr
    assert (named.nv, named.source) == (3, "rtr")
    assert named.urdf_path.resolve() == rtr_urdf.resolve()
    for path in ("./rtr", Path("rtr"), tmp_path / "rtr"):  # a separator, or a Path: a file
        one = load_robot(path)
        assert (one.nv, one.tip) == (1, "end")
        assert one.source == str((tmp_path / "rtr").resolve())
    with pytest.raises(RobotError) as info:
        load_robot("myarm")
    message = str(info.value)
    assert "unknown robot 'myarm'" in message
    assert "give a path such as ./myarm" in message
    assert "rtr" in message and "ur5" in message  # the known names
    assert load_robot("./myarm").nv == 1


def test_source_loads_the_same_arm_from_another_directory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "arms").mkdir()
    (tmp_path / "arms" / "one.urdf").write_text(_ONE_JOINT)
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path)
    robot = load_robot("arms/one.urdf")
    assert robot.name == "arms/one.urdf"  # as given
    assert robot.source == str(tmp_path.resolve() / "arms" / "one.urdf")
    assert Path(robot.source).is_absolute()
    assert robot.with_mass_factor(2.0).source == robot.source
    with pytest.raises(AttributeError):
        robot.source = "x"  # type: ignore[misc]
    monkeypatch.chdir(tmp_path / "elsewhere")
    again = load_robot(robot.source)
    q = np.array([0.3])
    np.testing.assert_allclose(again.tip_position(q), [np.cos(0.3), np.sin(0.3), 0], atol=1e-15)
    with pytest.raises(RobotError, match="not found"):
        load_robot(robot.name)  # the relative path no longer resolves from here


def test_joint_limits_from_the_urdf(tmp_path: Path) -> None:
    """Position limits as written (∓inf for a continuous joint); effort 0 or absent is +inf."""
    text = _ONE_JOINT.replace('effort="5"', 'effort="0"').replace(
        "</robot>",
        '<link name="slide_link"><inertial><mass value="0.5"/><inertia ixx="0.01" ixy="0" '
        'ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>'
        '<link name="wheel"><inertial><mass value="0.2"/><inertia ixx="0.001" ixy="0" '
        'ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>'
        '<joint name="slide" type="prismatic"><parent link="end"/><child link="slide_link"/>'
        '<axis xyz="1 0 0"/><limit lower="0" upper="0.4" effort="50" velocity="1"/></joint>'
        '<joint name="turn" type="continuous"><parent link="slide_link"/><child link="wheel"/>'
        '<axis xyz="0 1 0"/></joint></robot>',
    )
    path = tmp_path / "three.urdf"
    path.write_text(text)
    robot = load_robot(path, tip="wheel")
    assert robot.nq == robot.nv == 3
    lower, upper = robot.position_limits
    assert lower.shape == upper.shape == (3,)
    np.testing.assert_array_equal(lower, [-1.0, 0.0, -np.inf])
    np.testing.assert_array_equal(upper, [1.0, 0.4, np.inf])
    np.testing.assert_array_equal(robot.effort_limits, [np.inf, 50.0, np.inf])
    np.testing.assert_array_equal(robot.model.effortLimit[:2], [0.0, 50.0])  # model as parsed
    for array in (lower, upper, robot.effort_limits):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1.0
    with pytest.raises(AttributeError):
        robot.effort_limits = np.zeros(3)  # type: ignore[misc]


# --- kinematics ------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ARMS)
def test_jacobian_matches_finite_differences(arms: dict[str, Robot], name: str) -> None:
    robot = arms[name]
    rng = np.random.default_rng(11)
    worst = 0.0
    for _ in range(10):
        q, _ = _random_state(robot, rng)
        J = robot.jacobian(q)
        assert J.shape == (3, robot.nv)
        err = np.abs(J - _fd_jacobian(robot, q)).max()
        worst = max(worst, err)
    assert worst < 1e-8, worst


@pytest.mark.parametrize("name", ARMS)
def test_drift_matches_finite_difference_of_jacobian(arms: dict[str, Robot], name: str) -> None:
    """J̇ v = d/dt [J(q + v t)] v at t = 0 (central difference, h = 1e-5)."""
    robot = arms[name]
    rng = np.random.default_rng(12)
    h = 1e-5
    for _ in range(10):
        q, v = _random_state(robot, rng)
        fd = (robot.jacobian(q + h * v) - robot.jacobian(q - h * v)) / (2 * h) @ v
        drift = robot.drift(q, v)
        assert drift.shape == (3,)
        np.testing.assert_allclose(drift, fd, atol=1e-7 * (1 + np.abs(fd).max()))


@pytest.mark.parametrize("name", ARMS)
def test_drift_is_second_derivative_of_tip_at_zero_acceleration(
    arms: dict[str, Robot], name: str
) -> None:
    """p(q + v t) has second derivative J̇ v at t = 0 (second central difference)."""
    robot = arms[name]
    rng = np.random.default_rng(13)
    h = 1e-4
    for _ in range(5):
        q, v = _random_state(robot, rng)
        fd = (
            robot.tip_position(q + h * v)
            - 2 * robot.tip_position(q)
            + robot.tip_position(q - h * v)
        ) / h**2
        np.testing.assert_allclose(robot.drift(q, v), fd, atol=2e-5 * (1 + np.abs(fd).max()))


# --- dynamics ---------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ARMS)
def test_terms_agree_with_single_methods(arms: dict[str, Robot], name: str) -> None:
    robot = arms[name]
    rng = np.random.default_rng(14)
    for use_own_data in (True, False):
        q, v = _random_state(robot, rng)
        data = None if use_own_data else robot.new_data()
        t = robot.terms(q, v, data)
        assert isinstance(t, RobotTerms)
        np.testing.assert_allclose(t.M, robot.mass_matrix(q), atol=1e-12)
        np.testing.assert_allclose(t.C, robot.coriolis(q, v), atol=1e-12)
        np.testing.assert_allclose(t.g, robot.gravity(q), atol=1e-12)
        np.testing.assert_allclose(t.p, robot.tip_position(q), atol=1e-14)
        np.testing.assert_allclose(t.J, robot.jacobian(q), atol=1e-13)
        np.testing.assert_allclose(t.Jdot_v, robot.drift(q, v), atol=1e-11)
        np.testing.assert_allclose(t.Jdot @ v, t.Jdot_v, atol=1e-12)
        np.testing.assert_allclose(t.pdot, t.J @ v, atol=1e-13)
        np.testing.assert_allclose(t.nle, t.C @ v + t.g, atol=1e-11)
        # nle is the RNEA torque at zero acceleration (an independent algorithm)
        rnea = pin.rnea(robot.model, robot.new_data(), q, v, np.zeros(robot.nv))
        np.testing.assert_allclose(t.nle, rnea, atol=1e-9 * (1 + np.abs(rnea).max()))


@pytest.mark.parametrize("name", ARMS)
def test_mass_matrix_symmetric_positive_definite(arms: dict[str, Robot], name: str) -> None:
    robot = arms[name]
    rng = np.random.default_rng(15)
    for _ in range(10):
        q, v = _random_state(robot, rng)
        M = robot.mass_matrix(q)
        assert np.array_equal(M, M.T)
        assert np.linalg.eigvalsh(M).min() > 0
        # kinetic energy ½ vᵀMv equals Pinocchio's independent energy computation
        T = pin.computeKineticEnergy(robot.model, robot.new_data(), q, v)
        assert 0.5 * v @ M @ v == pytest.approx(T, rel=1e-12)


@pytest.mark.parametrize("name", ARMS)
def test_gravity_is_gradient_of_potential_energy(arms: dict[str, Robot], name: str) -> None:
    robot = arms[name]
    rng = np.random.default_rng(16)
    data = robot.new_data()
    h = 1e-6
    q, _ = _random_state(robot, rng)
    grad = np.empty(robot.nv)
    for j in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[j] = h
        up = pin.computePotentialEnergy(robot.model, data, q + dq)
        down = pin.computePotentialEnergy(robot.model, data, q - dq)
        grad[j] = (up - down) / (2 * h)
    np.testing.assert_allclose(robot.gravity(q), grad, atol=1e-6 * (1 + np.abs(grad).max()))


@pytest.mark.parametrize("name", ARMS)
def test_mdot_minus_2c_is_skew(arms: dict[str, Robot], name: str) -> None:
    robot = arms[name]
    rng = np.random.default_rng(17)
    h = 1e-6
    for _ in range(5):
        q, v = _random_state(robot, rng)
        Mdot = (robot.mass_matrix(q + h * v) - robot.mass_matrix(q - h * v)) / (2 * h)
        N = Mdot - 2 * robot.coriolis(q, v)
        assert np.abs(N + N.T).max() < 1e-6 * (1 + np.abs(Mdot).max())


@pytest.mark.parametrize("name", ARMS)
def test_with_mass_factor_scales_dynamics_not_kinematics(arms: dict[str, Robot], name: str) -> None:
    robot = arms[name]
    rng = np.random.default_rng(18)
    factor = 1.7
    heavy = robot.with_mass_factor(factor)
    assert heavy is not robot and heavy.tip == robot.tip and heavy.nv == robot.nv
    for _ in range(3):
        q, v = _random_state(robot, rng)
        M = robot.mass_matrix(q)
        np.testing.assert_allclose(heavy.mass_matrix(q), factor * M, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(
            heavy.coriolis(q, v), factor * robot.coriolis(q, v), rtol=1e-12, atol=1e-13
        )
        np.testing.assert_allclose(heavy.gravity(q), factor * robot.gravity(q), atol=1e-11)
        np.testing.assert_allclose(heavy.tip_position(q), robot.tip_position(q), atol=1e-15)
        np.testing.assert_allclose(heavy.jacobian(q), robot.jacobian(q), atol=1e-15)
        np.testing.assert_allclose(heavy.drift(q, v), robot.drift(q, v), atol=1e-13)
        # the original is untouched
        np.testing.assert_allclose(robot.mass_matrix(q), M, atol=0)
    total = sum(inertia.mass for inertia in robot.model.inertias)
    assert sum(i.mass for i in heavy.model.inertias) == pytest.approx(factor * total)


@pytest.mark.parametrize("factor", [0.0, -1.0, float("nan"), float("inf")])
def test_with_mass_factor_rejects_bad_factor(arms: dict[str, Robot], factor: float) -> None:
    with pytest.raises(BadInputError, match="mass factor"):
        arms["rtr"].with_mass_factor(factor)


# --- bad input ----------------------------------------------------------------------------------
def test_unknown_name_lists_known_robots() -> None:
    with pytest.raises(RobotError) as info:
        load_robot("nosuch_arm")
    message = str(info.value)
    assert "nosuch_arm" in message
    for name in ARMS:
        assert name in message


def test_unknown_tip_lists_frames(rtr_urdf: Path) -> None:
    for source in ("rtr", rtr_urdf):
        with pytest.raises(RobotError) as info:
            load_robot(source, tip="no_such_frame")
        message = str(info.value)
        assert "no_such_frame" in message
        for frame in ("tip", "link3", "link2"):
            assert frame in message


def test_missing_file_is_urdf_error(tmp_path: Path) -> None:
    missing = tmp_path / "absent.urdf"
    with pytest.raises(RobotError, match=r"absent\.urdf"):
        load_robot(missing)
    with pytest.raises(RobotError, match=r"absent\.urdf"):
        load_robot(str(missing))


@pytest.mark.parametrize(
    "bad", [np.zeros(2), np.zeros(4), np.zeros((3, 1)), [0.0, np.nan, 0.0], [np.inf, 0, 0]]
)
def test_bad_q_or_v_is_dimension_error(arms: dict[str, Robot], bad: object) -> None:
    robot = arms["rtr"]
    good = np.array([0.1, 2.0, 0.3])
    calls = [
        lambda: robot.mass_matrix(bad),
        lambda: robot.gravity(bad),
        lambda: robot.tip_position(bad),
        lambda: robot.jacobian(bad),
        lambda: robot.coriolis(bad, good),
        lambda: robot.coriolis(good, bad),
        lambda: robot.drift(bad, good),
        lambda: robot.drift(good, bad),
    ]
    for call in calls:
        with pytest.raises(BadInputError, match="rtr"):
            call()


def test_dimension_error_message_names_shape(arms: dict[str, Robot]) -> None:
    with pytest.raises(BadInputError, match=r"\(6,\).*\(5,\)"):
        arms["ur5"].jacobian(np.zeros(5))


def test_a_revolute_joint_without_lower_and_upper_has_no_range(tmp_path: Path) -> None:
    """URDF's default lower = upper = 0 means "no range given", not a joint that may not move:
    the run does not warn that it left its range."""
    text = (
        '<robot name="r"><link name="base"/>'
        '<link name="arm"><inertial><mass value="1"/><origin xyz="0.5 0 0"/>'
        '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>'
        '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/>'
        '<axis xyz="0 0 1"/><limit effort="5" velocity="1"/></joint></robot>'
    )
    path = tmp_path / "norange.urdf"
    path.write_text(text)
    robot = load_robot(path)
    lower, upper = robot.position_limits
    np.testing.assert_array_equal(lower, [-np.inf])
    np.testing.assert_array_equal(upper, [np.inf])
    np.testing.assert_array_equal(robot.effort_limits, [5.0])


def test_a_hand_built_model_without_moving_joint_is_refused_not_a_segfault() -> None:
    """Robot() itself refuses nv = 0 before any Pinocchio algorithm (crba on nv = 0 crashes
    the interpreter), so the Python API cannot reach a segfault either; in a subprocess so a
    regression fails this test instead of killing the suite."""
    import subprocess
    import sys

    code = (
        "import pinocchio as pin\n"
        "from hybrid_force.errors import RobotError\n"
        "from hybrid_force.model.robot import Robot\n"
        "m = pin.Model()\n"
        "m.addFrame(pin.Frame('tip', 0, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))\n"
        "try:\n"
        "    Robot(m, name='empty', urdf_path='none.urdf', tip='tip')\n"
        "except RobotError as exc:\n"
        "    print('refused:', exc)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "refused: robot 'empty': the model has no moving joint (nv = 0)" in proc.stdout


def test_a_hand_built_model_with_a_massless_joint_is_refused() -> None:
    import pinocchio as pin

    from hybrid_force.errors import RobotError

    model = pin.Model()
    j = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "massless")
    model.appendBodyToJoint(j, pin.Inertia.Zero(), pin.SE3.Identity())
    model.addFrame(pin.Frame("link", j, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    with pytest.raises(RobotError, match="'massless'"):
        Robot(model, name="hand", urdf_path=Path("none.urdf"), tip="link")


# --- model files other than .urdf: names vs paths, what reloads the arm ------------------------
def test_texts_ending_xacro_or_xml_are_paths_never_names(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """'arm.xml' and 'arm.urdf.xacro' are files of the working directory (a registry name has
    no such ending); a missing one says which kind of file is missing."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(RobotError, match=r"^MJCF file not found: arm.xml$"):
        load_robot("arm.xml")
    with pytest.raises(RobotError, match=r"^xacro file not found: arm.urdf.xacro$"):
        load_robot("arm.urdf.xacro")
    (tmp_path / "arm.xml").write_text(_ONE_JOINT)  # a URDF named .xml: read as a URDF
    robot = load_robot("arm.xml")
    assert (robot.kind, robot.nv, robot.source) == ("urdf", 1, str(tmp_path / "arm.xml"))


def test_reference_reloads_the_same_arm(tmp_path: Path) -> None:
    (tmp_path / "meshes").mkdir()
    path = tmp_path / "one.urdf"
    path.write_text(_ONE_JOINT)
    robot = load_robot(path, package_dirs=[tmp_path / "meshes"], lock_off_chain=False)
    assert robot.reference == {
        "model": str(path.resolve()),
        "tip": "end",
        "package_dirs": [str(tmp_path / "meshes")],
        "xacro_args": {},
        "lock_off_chain": False,
    }
    again = load_robot(**robot.reference)
    assert again.reference == robot.reference and again.package_dirs == robot.package_dirs
    heavy = robot.with_mass_factor(2.0)
    assert heavy.reference == robot.reference and heavy.kind == robot.kind == "urdf"
    assert heavy.urdf_xml == robot.urdf_xml and '<robot name="one">' in robot.urdf_xml
    named = load_robot("rtr")
    assert named.reference == {
        "model": "rtr", "tip": "tip", "package_dirs": [], "xacro_args": {},
        "lock_off_chain": None,
    }  # fmt: skip


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"package_dirs": "meshes"}, "package_dirs must be a list of folders"),
        ({"package_dirs": [3]}, "package_dirs must hold folder paths"),
        ({"xacro_args": ["l1"]}, "xacro_args must be a mapping"),
        ({"lock_off_chain": "yes"}, "lock_off_chain must be True, False or None"),
    ],
)
def test_bad_load_options_are_refused(kwargs: dict, match: str) -> None:
    with pytest.raises(RobotError, match=match):
        load_robot("rtr", **kwargs)

"""Issue 27, class 8: every failure is one clear line (no traceback, no signal death), it
names the file, key and value, and nothing is left half-written."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hybrid_force.errors import ScenarioError
from hybrid_force.scenario.loader import load_scenario

REPO_ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = REPO_ROOT / "scenarios"
CONTACT = SCENARIOS / "paper_contact.toml"


def _cli(*args: str | Path, cwd: Path = REPO_ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hybrid_force.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=120,
        check=False,
    )


def _one_line(proc: subprocess.CompletedProcess[str], status: int, *named: str) -> str:
    """Exit ``status``, one ``error:`` line on stderr naming each of ``named``."""
    assert proc.returncode == status, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    for word in named:
        assert word in lines[0], lines[0]
    return lines[0]


# --- a suggestion, copied, is accepted ---------------------------------------------------------
@pytest.mark.parametrize("rate", [300.0, 700.0, 450.0])
def test_the_rates_a_message_suggests_are_accepted_when_copied(rate: float) -> None:
    with pytest.raises(ScenarioError, match="rates that fit nearby") as info:
        load_scenario(CONTACT, {"control.rate": rate})
    shown = re.findall(r"([0-9.e+-]+) Hz", str(info.value).split("fit nearby:")[1])
    assert len(shown) == 2
    for text in shown:
        scenario = load_scenario(CONTACT, {"control.rate": float(text)})
        assert scenario.control.rate == float(text)


def test_the_stable_beta_a_message_gives_is_accepted_when_copied() -> None:
    sensing = {"sensor.force_delay": 3, "sensor.force_cutoff": 50.0, "sim.duration": 0.1}
    with pytest.raises(ScenarioError, match="any beta below is stable") as info:
        load_scenario(CONTACT, {**sensing, "control.beta": 100.0})
    example = re.search(r"e\.g\. ([0-9.e+-]+)\)", str(info.value))
    assert example is not None
    scenario = load_scenario(CONTACT, {**sensing, "control.beta": float(example.group(1))})
    assert scenario.control.beta == float(example.group(1))


# --- public API: a clear error of errors.py, not Boost.Python's or math's -------------------
@pytest.mark.parametrize("tip", [5, b"tip", ["tip"]])
def test_a_tip_that_is_not_a_text_is_a_frame_error_listing_the_frames(tip: object) -> None:
    from hybrid_force import load_robot
    from hybrid_force.errors import RobotError

    with pytest.raises(RobotError, match=r"tip must be a frame name \(a str\)") as info:
        load_robot("rtr", tip=tip)  # type: ignore[arg-type]
    assert info.value.key == "tip" and info.value.value == tip
    assert "frames of" in str(info.value) and "link3" in str(info.value)


@pytest.mark.parametrize("scenario", ["paper_contact", "ur5_sphere_normal"])
@pytest.mark.parametrize("t", [math.inf, -math.inf, math.nan, "1"])
def test_a_path_evaluated_at_a_non_finite_time_names_t(scenario: str, t: object) -> None:
    from hybrid_force.errors import PathError

    path = load_scenario(SCENARIOS / f"{scenario}.toml").path
    for method in (path.evaluate, path.position, path.direction_jet):
        with pytest.raises(PathError, match="the time t at which it is evaluated") as info:
            method(t)  # type: ignore[arg-type]
        assert info.value.key == "t"


def test_public_calls_with_wrong_types_raise_errors_of_the_package() -> None:
    """Each of these raised a raw TypeError, ValueError or AttributeError, or returned NaN."""
    from hybrid_force import load_robot, simulate
    from hybrid_force.errors import HybridForceError
    from hybrid_force.geometry.builtin_surfaces import Cylinder
    from hybrid_force.geometry.paths import Helix
    from hybrid_force.result import Result

    robot = load_robot("rtr")
    calls = {
        "package_dirs": lambda: load_robot("rtr", package_dirs=5),  # type: ignore[arg-type]
        "q for robot": lambda: robot.tip_position("abc"),
        "point p must be finite": lambda: Cylinder(0.4).distance([1e300, 0.0, 0.0]),
        "takes a hybrid_force Scenario": lambda: simulate(5),  # type: ignore[arg-type]
        "named by a path": lambda: Result.load(5),  # type: ignore[arg-type]
    }
    for named, call in calls.items():
        with pytest.raises(HybridForceError, match=named):
            call()
    # a direction of huge entries is a direction: its norm does not overflow to a zero axis
    helix = Helix(center=[0, 0, 0], radius=1.0, axis=[1e300, 0, 1e300], omega=1.0, rise=0.0)
    assert np.allclose(helix.frame[2], [math.sqrt(0.5), 0.0, math.sqrt(0.5)])


# --- values a run cannot use: refused by the loader, naming the file and the key --------------
@pytest.mark.parametrize(
    ("scenario", "override", "named"),
    [
        ("paper_contact", "initial.v=[1e300, 0, 0]", ["initial.v", "1e+300", "max_velocity"]),
        ("paper_contact", "surface.center=[1e300, 0, 0]", ["surface.center", "MAX_LENGTH"]),
        ("paper_contact", "surface.radius=1e7", ["surface.radius", "MAX_LENGTH"]),
        ("rtr_plane", "surface.point=[0, 0, 1e300]", ["surface.point", "MAX_LENGTH"]),
        ("paper_contact", "trajectory.center=[1e300, 0, 10]", ["trajectory.center", "1e+300"]),
        ("paper_contact", "trajectory.rise=1e300", ["trajectory.rise", "MAX_LENGTH"]),
        ("paper_contact", "trajectory.omega=1e300", ["trajectory.omega", "MAX_LENGTH"]),
        ("paper_contact", "trajectory.phase=1e300", ["trajectory.phase", "MAX_LENGTH"]),
        ("ur5_sphere_normal", "trajectory.origin=[1e300, 0]", ["trajectory.origin", "MAX_LENGTH"]),
        ("panda_pipe_tilt", "trajectory.points=[[1e300, 0], [0, 0]]", ["trajectory.points"]),
    ],
)
def test_an_absurd_value_is_refused_naming_file_and_key(
    tmp_path: Path, scenario: str, override: str, named: list[str]
) -> None:
    out = tmp_path / "out"
    proc = _cli("run", SCENARIOS / f"{scenario}.toml", "--set", override, "--out", out)
    _one_line(proc, 2, f"{scenario}.toml", *named)
    assert not out.exists()  # nothing half-written


# --- stacked surfaces whose rows are dependent at the start ------------------------------------
TWO_PARALLEL_PLANES = """\
name = "two_planes"
[robot]
model = "rtr"
[[surfaces]]
type = "plane"
point = [0.0, 0.0, 5.0]
normal = [0.0, 0.0, 1.0]
[[surfaces]]
type = "plane"
point = [0.0, 0.0, 5.0]
normal = [0.0, 0.0, -1.0]
[trajectory]
type = "circle"
center = [0.0, 0.0, 5.0]
radius = 0.6
normal = [0.0, 0.0, 1.0]
omega = 0.5
[initial]
tip = [0.6, 0.0, 5.0]
seed = [0.0, 4.0, 1.8]
[control]
supervisor = false
f_d = [10.0, 10.0]
[sim]
duration = 0.1
"""


def test_two_parallel_planes_are_refused_naming_both_surfaces(tmp_path: Path) -> None:
    scenario = tmp_path / "two_planes.toml"
    scenario.write_text(TWO_PARALLEL_PLANES)
    out = tmp_path / "out"
    proc = _cli("run", scenario, "--out", out)
    _one_line(proc, 2, str(scenario), "surfaces.0, surfaces.1", "linearly dependent")
    assert not out.exists()


def test_scenario_built_in_python_refuses_dependent_rows_too(tmp_path: Path) -> None:
    import dataclasses

    from hybrid_force.errors import ScenarioError
    from hybrid_force.geometry.builtin_surfaces import Plane

    # the tip stands still on the planes x = 0.4 and z = 5: independent rows, accepted
    text = TWO_PARALLEL_PLANES.replace("normal = [0.0, 0.0, -1.0]", "normal = [1.0, 0.0, 0.0]")
    text = text.replace(
        "point = [0.0, 0.0, 5.0]\nnormal = [1.0", "point = [0.6, 0.0, 5.0]\nnormal = [1.0"
    )
    text = text.replace("omega = 0.5", "omega = 0.0")
    scenario = tmp_path / "two.toml"
    scenario.write_text(text)
    base = load_scenario(scenario)
    flipped = Plane([0.6, 0.0, 5.0], [-1.0, 0.0, 0.0])  # the same plane, facing the other way
    with pytest.raises(ScenarioError, match=r"surfaces\[0\], surfaces\[1\] are linearly"):
        dataclasses.replace(base, surfaces=[base.surfaces[1], flipped])


# --- TOML nested deeply under an unknown key ----------------------------------------------------
@pytest.mark.parametrize("header", ["zz", "control.zz"])
def test_a_deeply_nested_unknown_table_is_one_line_naming_its_key(
    tmp_path: Path, header: str
) -> None:
    scenario = tmp_path / "deep.toml"
    deep = ".".join([header, *["zz"] * 5000])
    scenario.write_text(CONTACT.read_text() + f"\n[{deep}]\nx = 1\n")
    out = tmp_path / "out"
    proc = _cli("run", scenario, "--out", out)
    _one_line(proc, 2, str(scenario), f"{header}.zz.zz", "MAX_NESTING")
    assert not out.exists()


def test_a_deeply_nested_document_built_in_python_is_refused_without_recursion() -> None:
    from hybrid_force.scenario.loader import read_scenario_document, scenario_from_document

    doc = read_scenario_document(CONTACT)
    inner: dict[str, object] = {}
    doc["robot"]["extra"] = inner
    for _ in range(20000):  # deeper than Python's recursion limit
        inner["a"] = inner = {}
    with pytest.raises(ScenarioError, match=r"robot\.extra\.a\.a.*MAX_NESTING") as info:
        scenario_from_document(doc, origin="deep.toml")
    assert info.value.key == "robot.extra"


# --- robots --check: a mesh is found only if it can be read -----------------------------------
def test_a_corrupt_mesh_is_reported_unreadable_not_found(tmp_path: Path) -> None:
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "good.stl").write_text(
        "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
        "endloop\nendfacet\nendsolid s\n"
    )
    (tmp_path / "meshes" / "bad.stl").write_bytes(b"\x00garbage, not a mesh\xff" * 8)
    inertial = (
        '<inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" '
        'izz="0.1"/></inertial>'
    )

    def visual(name: str) -> str:
        return f'<visual><geometry><mesh filename="meshes/{name}"/></geometry></visual>'

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(
        f'<robot name="arm"><link name="base">{inertial}{visual("good.stl")}</link>'
        f'<link name="arm">{inertial}{visual("bad.stl")}</link>'
        '<joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>'
        '<origin xyz="0.3 0 0"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="5" velocity="1"/></joint></robot>'
    )
    proc = _cli("robots", "--check", urdf)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert "meshes: 2 referenced, 1 found, 1 unreadable" in lines
    assert "  found    meshes/good.stl" in lines
    bad = [line for line in lines if line.startswith("  unreadable meshes/bad.stl (link arm; ")]
    assert len(bad) == 1 and str(tmp_path / "meshes" / "bad.stl") in bad[0]


# --- hybrid-force plot on malformed sweep tables -----------------------------------------------
HEADER = "control.beta,final_position_error\n"


@pytest.mark.parametrize(
    ("content", "named"),
    [
        (b"", "is empty"),
        (HEADER.encode(), "no rows"),
        (b"a,b\n1,2\n", "not in"),
        ((HEADER + "x,y\n").encode(), "not numeric"),
        ((HEADER + "1,2,3\n4\n").encode(), "line 2: 3 fields"),
        ((HEADER + '"1,2\n').encode(), "cannot read"),
        (bytes(range(256)) * 8, "cannot read"),
        ((HEADER + "1," + "9" * 200_000 + "\n").encode(), "cannot read"),
    ],
    ids=["empty", "header-only", "wrong-columns", "text", "ragged", "quote", "binary", "huge"],
)
def test_a_malformed_sweep_table_is_one_line_and_writes_nothing(
    tmp_path: Path, content: bytes, named: str
) -> None:
    table = tmp_path / "sweep.csv"
    table.write_bytes(content)
    out = tmp_path / "figures"
    proc = _cli(
        "plot", table, "--x", "control.beta", "--metric", "final_position_error", "--out", out
    )
    _one_line(proc, 2, "sweep.csv", named)
    assert not out.exists()


# --- the command line's last resort: one line, never a traceback -------------------------------
@pytest.mark.parametrize(
    ("raised", "status", "named"),
    [
        (MemoryError(), 1, "out of memory"),
        (RecursionError("maximum recursion depth exceeded"), 1, "unexpected RecursionError"),
        (OverflowError("math range error"), 1, "unexpected OverflowError"),
        (ValueError("raw"), 1, "unexpected ValueError: raw"),
    ],
)
def test_an_unexpected_exception_is_one_line(
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    raised: BaseException,
    status: int,
    named: str,
) -> None:
    import numpy as np

    from hybrid_force import cli

    def fail(args: object) -> int:
        raise raised

    monkeypatch.delenv("HYBRID_FORCE_TRACEBACK", raising=False)
    monkeypatch.setattr(cli, "_cmd_laws", fail)
    assert cli.main(["laws"]) == status
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: laws: ") and named in err[0], err
    # numpy's LinAlgError as well (two parallel planes raised one before this session)
    monkeypatch.setattr(cli, "_cmd_laws", lambda args: np.linalg.inv(np.zeros((2, 2))))
    assert cli.main(["laws"]) == 1
    assert "unexpected LinAlgError: Singular matrix" in capsys.readouterr().err
    # for a developer, the traceback on request
    monkeypatch.setenv("HYBRID_FORCE_TRACEBACK", "1")
    monkeypatch.setattr(cli, "_cmd_laws", fail)
    if not isinstance(raised, MemoryError):
        with pytest.raises(type(raised)):
            cli.main(["laws"])


def test_a_sweep_table_beyond_the_byte_limit_is_refused_unread(tmp_path: Path) -> None:
    from hybrid_force.viz.sweep_plots import MAX_SWEEP_BYTES

    table = tmp_path / "sweep.csv"
    with table.open("wb") as fh:  # sparse: only the size is written
        fh.truncate(MAX_SWEEP_BYTES + 1)
    out = tmp_path / "figures"
    proc = _cli(
        "plot", table, "--x", "control.beta", "--metric", "final_position_error", "--out", out
    )
    _one_line(proc, 2, "sweep.csv", "MAX_SWEEP_BYTES")
    assert not out.exists()


def test_a_foreign_warning_is_one_line_too(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import warnings

    from hybrid_force import cli

    def warn(args: object) -> int:
        warnings.warn("overflow encountered in matmul", RuntimeWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(cli, "_cmd_laws", warn)
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # the test run's own filter turns warnings into errors
        assert cli.main(["laws"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("warning: RuntimeWarning: overflow encountered in matmul (")


def test_a_sweep_over_a_key_nested_thousands_deep_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    key = ".".join(["x"] * 3000)
    proc = _cli("sweep", CONTACT, "--grid", f"{key}=1", "--out", out)
    _one_line(proc, 2, "--grid", "3000 parts", "MAX_NESTING")
    assert not out.exists()


# --- MJCF numbers Pinocchio's parser would read as whatever memory held --------------------
@pytest.mark.parametrize(
    ("body", "named"),
    [
        ('<body name="b" pos="a b c">', "pos='a b c': must be finite numbers"),
        ('<body name="b" pos="0 0 nan">', "must be finite numbers"),
        ('<body name="b" pos="0 0 1e400">', "must be finite numbers"),
    ],
)
def test_an_mjcf_number_that_is_no_number_is_refused(tmp_path: Path, body: str, named: str) -> None:
    from hybrid_force import load_robot
    from hybrid_force.errors import RobotError

    mjcf = tmp_path / "arm.xml"
    mjcf.write_text(
        f'<mujoco><worldbody>{body}<joint name="j" type="hinge"/>'
        '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></worldbody></mujoco>'
    )
    with pytest.raises(RobotError, match=named) as info:
        load_robot(mjcf)
    assert str(mjcf) in str(info.value)


@pytest.mark.parametrize(
    ("joint", "inertial", "named"),
    [
        ('range="1 0"', 'mass="1" diaginertia="1 1 1"', "lower above upper"),
        ("", 'mass="-1" diaginertia="1 1 1"', "mass='-1': must not be negative"),
        ("", 'mass="1" diaginertia="1 -1 1"', "must not be negative"),
    ],
)
def test_an_impossible_mjcf_value_is_refused(
    tmp_path: Path, joint: str, inertial: str, named: str
) -> None:
    from hybrid_force import load_robot
    from hybrid_force.errors import RobotError

    mjcf = tmp_path / "arm.xml"
    mjcf.write_text(
        f'<mujoco><worldbody><body name="b"><joint name="j" type="hinge" {joint}/>'
        f'<inertial pos="0 0 0" {inertial}/></body></worldbody></mujoco>'
    )
    with pytest.raises(RobotError, match=named):
        load_robot(mjcf)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS is Linux's")
def test_memory_exhausted_in_a_real_run_is_one_line(tmp_path: Path) -> None:
    """An address-space limit of 1.5 GiB and a log of 2e7 samples: the allocation fails with
    MemoryError (or, on a machine with less memory, the loader refuses the log first)."""
    import resource

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (1536 * 2**20, 1536 * 2**20))

    out = tmp_path / "out"
    command = [sys.executable, "-m", "hybrid_force.cli", "run", str(CONTACT)]
    proc = subprocess.run(
        [*command, "--set", "sim.duration=20000", "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=REPO_ROOT,
        timeout=120,
        check=False,
        preexec_fn=limit,
    )
    assert proc.returncode in (1, 2), proc.stderr
    line = _one_line(proc, proc.returncode)
    assert "out of memory" in line or "sim.duration" in line
    assert not out.exists() or not any(out.iterdir())  # nothing half-written

"""``hybrid-force robots`` and the command line's error handling, in a subprocess."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from hybrid_force.cli import main

REPO_ROOT = Path(__file__).resolve().parents[1]

# one triangle: an STL file coal (the replay's mesh loader) reads
_TRIANGLE_STL = (
    "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
    "endloop\nendfacet\nendsolid s\n"
)


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hybrid_force.cli", *args],
        capture_output=True,
        text=True,
        cwd=REPO_ROOT,
        timeout=120,
        check=False,
    )


def test_robots_table() -> None:
    proc = _run("robots")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert lines[0].split() == ["name", "joints", "default", "tip", "source"]
    rows = {line.split()[0]: line.split() for line in lines[1:]}
    assert rows["rtr"][1:] == ["3", "tip", "bundled"]
    assert rows["ur5"][1:] == ["6", "tool0", "example-robot-data"]
    assert rows["panda"][1:] == ["7", "panda_hand_tcp", "example-robot-data"]  # fingers locked
    assert proc.stderr == ""


def test_help() -> None:
    proc = _run("--help")
    assert proc.returncode == 0
    assert "robots" in proc.stdout


@pytest.mark.parametrize(("args", "text"), [((), "required"), (("robts",), "invalid choice")])
def test_usage_errors_are_one_line(args: tuple[str, ...], text: str) -> None:
    proc = _run(*args)
    assert proc.returncode == 2
    assert proc.stdout == ""
    err_lines = proc.stderr.strip().splitlines()
    assert len(err_lines) == 1
    assert err_lines[0].startswith("error: ")
    assert text in err_lines[0]


def test_bad_input_error_is_one_line_exit_2(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A BadInputError raised inside a subcommand becomes ``error: ...`` and status 2."""
    import hybrid_force.cli
    from hybrid_force.errors import RobotError

    def broken(name: str, tip: str | None = None) -> None:
        raise RobotError(f"URDF file not found: /nowhere/{name}.urdf\n(second line)")

    monkeypatch.setattr(hybrid_force.cli, "load_robot", broken)
    assert main(["robots"]) == 2
    captured = capsys.readouterr()
    assert captured.err == "error: URDF file not found: /nowhere/rtr.urdf (second line)\n"


# --- robots --check MODEL [--tip FRAME] ------------------------------------------------------
def test_check_rtr_prints_the_hand_numbers(capsys: pytest.CaptureFixture[str]) -> None:
    """robots/rtr.urdf by hand: q1 continuous, q2 prismatic in [-1, 16] m, q3 revolute in
    [-3.2, 3.2] rad, no effort limit (effort="0"); 20 + 20 kg; reach from q1's origin:
    0.9 + 1.0 m of links (the tip's largest distance from the q1 axis) + 16 m of q2."""
    assert main(["robots", "--check", "rtr"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    lines = captured.out.splitlines()
    assert lines[0] == f"model: rtr ({REPO_ROOT / 'robots' / 'rtr.urdf'})"
    assert lines[1] == "joints: 3 moving"
    assert [line.split() for line in lines[2:6]] == [
        ["name", "type", "range", "effort"],
        ["q1", "continuous", "unbounded", "unspecified"],
        ["q2", "prismatic", "[-1,", "16]", "m", "unspecified"],
        ["q3", "revolute", "[-3.2,", "3.2]", "rad", "unspecified"],
    ]
    assert "fixed joints: tip_joint" in lines
    assert "tip: tip (default)" in lines
    assert "other tip frames: link3" in lines
    assert "total mass: 40 kg (40 kg on moving joints)" in lines
    assert (
        "reach: 17.9 m from the origin of joint q1 "
        "(joint-to-joint distances 1.9 m + prismatic travel 16 m)"
    ) in lines
    assert "meshes: 0 referenced, 0 found" in lines
    assert lines[-1] == "warnings: none"


def test_check_with_a_tip(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["robots", "--check", "rtr", "--tip", "link3"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "tip: link3 (given; default: tip)" in out
    assert any(line.startswith("reach: 16.9 m from the origin of joint q1") for line in out)


_MESHY = (
    '<robot name="m">'
    '<link name="world"><visual><geometry><mesh filename="meshes/base.stl"/></geometry>'
    "</visual></link>"
    '<link name="arm"><inertial><origin xyz="0.3 0 0"/><mass value="2"/>'
    '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>'
    '<visual><geometry><mesh filename="meshes/gripper.stl"/></geometry></visual></link>'
    '<link name="hand"/>'
    '<joint name="j1" type="revolute"><parent link="world"/><child link="arm"/>'
    '<origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>'
    '<limit lower="-1" upper="1" effort="5" velocity="1"/></joint>'
    '<joint name="j2" type="fixed"><parent link="arm"/><child link="hand"/>'
    '<origin xyz="0.3 0.4 0"/></joint></robot>'
)


def test_check_a_urdf_with_a_missing_mesh(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """meshes/base.stl exists next to the URDF, meshes/gripper.stl does not: reported, and
    the status stays 0 (meshes only matter to the viewer). Reach by hand: |(0.3, 0.4, 0)|."""
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "base.stl").write_text(_TRIANGLE_STL)
    path = tmp_path / "arm.urdf"
    path.write_text(_MESHY)
    assert main(["robots", "--check", str(path)]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    lines = captured.out.splitlines()
    assert lines[0] == f"model: {path}"
    assert "meshes: 2 referenced, 1 found" in lines
    assert "  found    meshes/base.stl" in lines
    missing = tmp_path / "meshes" / "gripper.stl"
    assert f"  missing  meshes/gripper.stl (link arm; looked for {missing})" in lines
    assert "total mass: 2 kg (2 kg on moving joints)" in lines
    reach = "reach: 0.5 m from the origin of joint j1 (the sum of the joint-to-joint distances"
    assert any(line.startswith(reach) for line in lines)
    assert "  j1    revolute  [-1, 1] rad  5 N·m" in lines


def test_check_lists_the_model_warnings(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A massless hand with an inertia: one warning line in the report, none on stderr."""
    path = tmp_path / "arm.urdf"
    path.write_text(
        _MESHY.replace(
            '<link name="hand"/>',
            '<link name="hand"><inertial><mass value="0"/><inertia ixx="1e-4" ixy="0" ixz="0" '
            'iyy="1e-4" iyz="0" izz="1e-4"/></inertial></link>',
        )
    )
    assert main(["robots", "--check", str(path)]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    lines = captured.out.splitlines()
    index = lines.index("warnings: 1")
    assert lines[index + 1].startswith(f"  warning: {path}: link 'hand': <inertial> mass 0 kg")


def test_check_a_refused_model_exits_2_with_one_error_line(tmp_path: Path) -> None:
    """A floating joint: the process exits 2 with one ``error:`` line naming file and joint."""
    path = tmp_path / "floating.urdf"
    path.write_text(_MESHY.replace('name="j1" type="revolute"', 'name="j1" type="floating"'))
    proc = _run("robots", "--check", str(path))
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: unsupported URDF ")
    assert str(path) in lines[0] and "joint 'j1'" in lines[0] and "floating joint" in lines[0]


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (["robots", "--check", "rtr", "--tip", "nope"], "tip frame 'nope' not found"),
        (["robots", "--check", "rtx"], "unknown robot 'rtx' (did you mean 'rtr'?)"),
        (["robots", "--tip", "tip"], "--tip needs --check MODEL"),
    ],
    ids=["bad-tip", "unknown-name", "tip-without-check"],
)
def test_check_bad_input_is_one_error_line(
    capsys: pytest.CaptureFixture[str], args: list[str], text: str
) -> None:
    assert main(args) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and text in lines[0]

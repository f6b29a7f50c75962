"""``hybrid-force robots`` and the command line's error handling, in a subprocess."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from hybrid_force.cli import main

REPO_ROOT = Path(__file__).resolve().parents[1]


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
    import hybrid_force.robot
    from hybrid_force.errors import URDFError

    def broken(name: str, tip: str | None = None) -> None:
        raise URDFError(f"URDF file not found: /nowhere/{name}.urdf\n(second line)")

    monkeypatch.setattr(hybrid_force.robot, "load_robot", broken)
    assert main(["robots"]) == 2
    captured = capsys.readouterr()
    assert captured.err == "error: URDF file not found: /nowhere/rtr.urdf (second line)\n"

"""Tests of hybrid_force.run_output and of the files ``hybrid-force run`` leaves on disk."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hybrid_force.cli import main
from hybrid_force.errors import BadInputError
from hybrid_force.result import Result
from hybrid_force.run_output import RunOutput
from hybrid_force.viz.figure_names import FIGURE_NAMES

REPO = Path(__file__).resolve().parents[1]
CONTACT = REPO / "scenarios" / "paper_contact.toml"


def _run(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _tiny(out: Path, *extra: object) -> list[object]:
    return ["run", CONTACT, "--set", "sim.duration=0.05", "--out", out, "--quiet", *extra]


# --- RunOutput alone -------------------------------------------------------------------------
def test_second_holder_of_a_folder_is_refused_and_the_lock_dies_with_the_first(
    tmp_path: Path,
) -> None:
    first = RunOutput(tmp_path / "out")
    with first:
        with pytest.raises(BadInputError, match="another run or sweep is writing into this folder"):
            RunOutput(tmp_path / "out").__enter__()
        # a different folder is independent
        with RunOutput(tmp_path / "other"):
            pass
    with RunOutput(tmp_path / "out"):  # released: a new run may write there
        pass
    assert sorted(os.listdir(tmp_path / "out")) == []  # the lock leaves no file behind


def test_lock_held_by_another_process_refuses_the_cli_run_before_simulating(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import fcntl, os, sys, time; fd = os.open(sys.argv[1], os.O_RDONLY); "
            "fcntl.flock(fd, fcntl.LOCK_EX); print('locked', flush=True); time.sleep(60)",
            str(out),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        code, stdout, err = _run(capsys, *_tiny(out))
    finally:
        holder.kill()
        holder.wait(10)
        assert holder.stdout is not None
        holder.stdout.close()
    assert code == 2 and stdout == ""
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: --out")
    assert "another run or sweep is writing into this folder" in lines[0]
    assert os.listdir(out) == []  # nothing written by the refused run


@pytest.mark.parametrize("name", ["result.npz", "summary.json", "force_error.png"])
def test_html_that_is_a_file_of_the_run_is_refused_before_running(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    out = tmp_path / "out"
    # also through another spelling of the same path
    html = out / "sub" / ".." / name
    code, stdout, err = _run(capsys, *_tiny(out, "--html", html))
    assert code == 2 and stdout == ""
    assert err.startswith("error: --html") and err.count("\n") == 1
    assert not (out / "result.npz").exists() and not (out / "summary.json").exists()


def test_html_that_is_the_scenario_file_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = tmp_path / "s.toml"
    scenario.write_text(CONTACT.read_text())
    before = scenario.read_bytes()
    code, _, err = _run(capsys, "run", scenario, "--out", tmp_path / "o", "--html", scenario)
    assert code == 2 and "an input of the run" in err
    assert scenario.read_bytes() == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_unwritable_output_folder_is_refused_before_simulating(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:  # pragma: no cover - CI runs as root; the root-proof variant follows
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o500)
    try:
        code, _, err = _run(capsys, *_tiny(out))
    finally:
        out.chmod(0o700)
    assert code == 2 and "cannot write into" in err


def test_output_path_that_is_a_file_is_refused_before_simulating(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    ran: list[object] = []
    monkeypatch.setattr(sys.modules["hybrid_force.cli"], "simulate", ran.append)
    code, _, err = _run(capsys, *_tiny(blocker / "out"))
    assert code == 2 and err.startswith("error: --out") and err.count("\n") == 1
    assert ran == [] and blocker.read_text() == "not a folder"


def test_folder_where_no_file_can_be_created_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The writability probe (root ignores permissions, so its failure is simulated)."""

    def refuse(*args: object, **kwargs: object) -> tuple[int, str]:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr("hybrid_force.run_output.tempfile.mkstemp", refuse)
    code, _, err = _run(capsys, *_tiny(tmp_path / "out"))
    assert code == 2 and "cannot write into" in err and "Permission denied" in err
    assert not (tmp_path / "out" / "result.npz").exists()


# --- what is on disk after a run -------------------------------------------------------------
def test_result_and_summary_carry_the_same_run_id_and_stale_figures_go(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    for name in FIGURE_NAMES:  # figures of an earlier run
        (out / f"{name}.png").write_bytes(b"old")
    (out / "notes.txt").write_text("mine")  # a file the toolkit did not write stays
    assert _run(capsys, *_tiny(out))[0] == 0
    first = json.loads((out / "summary.json").read_text())
    assert Result.load(out / "result.npz").meta["run_id"] == first["run_id"]
    assert not any((out / f"{name}.png").exists() for name in FIGURE_NAMES)
    assert (out / "notes.txt").read_text() == "mine"
    assert _run(capsys, *_tiny(out))[0] == 0
    second = json.loads((out / "summary.json").read_text())
    assert second["run_id"] != first["run_id"]
    assert Result.load(out / "result.npz").meta["run_id"] == second["run_id"]


def test_kill_between_result_and_summary_never_pairs_two_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A crash after the new result.npz is written and before its summary: the old summary
    is already gone, so no summary describes another run than the result beside it."""
    out = tmp_path / "out"
    assert _run(capsys, *_tiny(out))[0] == 0
    old_id = json.loads((out / "summary.json").read_text())["run_id"]

    def crash(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt  # as a kill would, between the two files

    monkeypatch.setattr("hybrid_force.run_output.atomic_file", crash)
    assert _run(capsys, *_tiny(out))[0] == 130
    new_id = Result.load(out / "result.npz").meta["run_id"]
    assert new_id != old_id
    assert not (out / "summary.json").exists()


def test_sigterm_saves_the_partial_result_and_exits_143(tmp_path: Path) -> None:
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "hybrid_force.cli", "run", str(CONTACT), "--out", str(out),
         "--set", "sim.duration=600", "--quiet"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120.0
        while not out.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)  # the folder is made (and locked) just before the simulation
        time.sleep(3.0)  # the kernels load, then some simulated seconds
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 143, err
    assert "run failed (interrupted)" in err and "SIGTERM" in err
    result = Result.load(out / "result.npz")
    summary = json.loads((out / "summary.json").read_text())
    assert result.status == "failed" and summary["reason"] == "interrupted"
    assert summary["run_id"] == result.meta["run_id"]
    assert 0.0 < result.t[-1] < 600.0 and summary["t_end"] == result.t[-1]
    assert np.all(np.isfinite(result.q))


@pytest.mark.parametrize("name", ["result.npz", "summary.json"])
def test_replay_html_never_replaces_the_result_it_replays(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    out = tmp_path / "out"
    assert _run(capsys, *_tiny(out))[0] == 0
    before = (out / name).read_bytes()
    code, _, err = _run(capsys, "replay", out / "result.npz", "--html", out / name)
    assert code == 2 and err.startswith("error: --html") and err.count("\n") == 1
    assert (out / name).read_bytes() == before


def test_output_files_that_would_replace_the_scenario_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = tmp_path / "summary.json"  # a TOML scenario under an unlucky name
    scenario.write_text(CONTACT.read_text())
    before = scenario.read_bytes()
    code, _, err = _run(capsys, "run", scenario, "--out", tmp_path, "--set", "sim.duration=0.05")
    assert code == 2 and "would replace its input" in err and err.count("\n") == 1
    assert scenario.read_bytes() == before and not (tmp_path / "result.npz").exists()

"""``hybrid-force run`` and ``hybrid-force plot`` end to end, in a subprocess."""

from __future__ import annotations

import dataclasses
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hybrid_force.cli import _import_feature, _Progress, main
from hybrid_force.errors import MissingExtraError
from hybrid_force.metrics import Metrics
from hybrid_force.result import Result

REPO_ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((REPO_ROOT / "scenarios").glob("*.toml"))
METRIC_KEYS = {f.name for f in dataclasses.fields(Metrics)}
FIGURES = {
    "path3d.png",
    "projection.png",
    "position_errors.png",
    "force_error.png",
    "desired_force.png",
    "lyapunov.png",
}


def _cli(*args: str | Path, cwd: Path = REPO_ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hybrid_force.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=300,
        check=False,
    )


def _assert_one_error_line(proc: subprocess.CompletedProcess[str], status: int) -> str:
    assert proc.returncode == status, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("error: ")
    return lines[0]


@pytest.fixture(scope="module")
def saved_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short paper_contact run saved by the command line (its output folder)."""
    out = tmp_path_factory.mktemp("saved") / "paper_contact"
    proc = _cli(
        "run", SHIPPED[0].parent / "paper_contact.toml", "--set", "sim.duration=0.2", "--out", out
    )
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.mark.parametrize("scenario", SHIPPED, ids=lambda p: p.stem)
def test_run_every_shipped_scenario(scenario: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = _cli("run", scenario, "--set", "sim.duration=0.2", "--out", out)
    assert proc.returncode == 0, proc.stderr
    # not a terminal: no progress bar; only the run's own warnings (e.g. the UR5's first
    # milliseconds beyond its effort limits), each also named in the summary
    warned = proc.stderr.splitlines()
    assert all(line.startswith("warning: run ") for line in warned), proc.stderr
    assert "position error" in proc.stdout and "steps/s" in proc.stdout
    result = Result.load(out / "result.npz")
    assert result.status == "ok"
    summary = json.loads((out / "summary.json").read_text())
    assert len(warned) == len(summary["warnings"])
    named = summary["effort_exceeded"] + summary["joint_range_exceeded"]
    assert all(any(f"joint {j} " in line for line in warned) for j in named)
    assert result.t[-1] == pytest.approx(0.2)
    assert result.n_samples == 201  # dt = 1 ms in every shipped file
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) >= METRIC_KEYS
    assert summary["status"] == "ok" and summary["name"] == scenario.stem
    # the summary agrees with the arrays: final position error = ‖p − p_d‖ at the end
    e_end = float(np.linalg.norm(result.p[-1] - result.p_d[-1]))
    assert summary["final_position_error"] == pytest.approx(e_end, rel=1e-12, abs=1e-300)
    # the scenario as loaded (with the override) is stored in the result
    assert result.meta["scenario"]["sim"]["duration"] == 0.2
    assert not list(out.glob("*.tmp")) and not list(out.glob(".*"))


def test_default_output_folder_is_runs_name(tmp_path: Path) -> None:
    proc = _cli(
        "run",
        REPO_ROOT / "scenarios" / "rtr_plane.toml",
        "--set",
        "sim.duration=0.05",
        "--quiet",
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == ""  # --quiet
    assert (tmp_path / "runs" / "rtr_plane" / "result.npz").is_file()
    assert (tmp_path / "runs" / "rtr_plane" / "summary.json").is_file()


def test_broken_scenario_exit_2(tmp_path: Path) -> None:
    text = (REPO_ROOT / "scenarios" / "paper_contact.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(
        text.replace(
            "radius = 0.4\ncenter = [0.0, 0.0, 0.0]", 'radius = "big"\ncenter = [0.0, 0.0, 0.0]'
        )
    )
    line = _assert_one_error_line(_cli("run", bad, "--out", tmp_path / "o"), 2)
    assert str(bad) in line and 'surface.radius = "big"' in line
    assert not (tmp_path / "o" / "result.npz").exists()


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("--set", "control.Kp=3"), "control.Kp = 3"),
        (("--set", "sim.duration=0"), "sim.duration = 0"),
        (("--set", "nokey"), "table.key=value"),
        (("--bogus",), "unrecognized arguments"),
    ],
)
def test_bad_options_exit_2(tmp_path: Path, args: tuple[str, ...], words: str) -> None:
    proc = _cli("run", REPO_ROOT / "scenarios" / "paper_contact.toml", *args, "--out", tmp_path)
    line = _assert_one_error_line(proc, 2)
    assert words in line


def test_missing_scenario_file_exit_2(tmp_path: Path) -> None:
    line = _assert_one_error_line(_cli("run", tmp_path / "nope.toml"), 2)
    assert "nope.toml" in line and "not found" in line


def test_diverging_run_exit_1_saves_failed_result(tmp_path: Path) -> None:
    # f_d = 1e9 N is beyond the simulator's runaway bound on |f| (1e7 N)
    out = tmp_path / "div"
    proc = _cli(
        "run",
        REPO_ROOT / "scenarios" / "paper_contact.toml",
        "--set",
        "control.f_d=1e9",
        "--set",
        "sim.duration=0.2",
        "--out",
        out,
    )
    line = _assert_one_error_line(proc, 1)
    assert line.startswith("error: run failed (diverged): ") and "runaway" in line
    result = Result.load(out / "result.npz")
    assert result.meta["status"] == "failed" and result.meta["error"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed"


def test_plot_saved_result(saved_run: Path, tmp_path: Path) -> None:
    proc = _cli("plot", saved_run / "result.npz", "--out", tmp_path / "figs")
    assert proc.returncode == 0, proc.stderr
    written = {p.name for p in (tmp_path / "figs").glob("*.png")}
    assert written == FIGURES
    for name in FIGURES:
        assert (tmp_path / "figs" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_run_with_plot_writes_figures(tmp_path: Path) -> None:
    out = tmp_path / "o"
    proc = _cli(
        "run",
        REPO_ROOT / "scenarios" / "paper_contact.toml",
        "--set",
        "sim.duration=0.02",
        "--plot",
        "--quiet",
        "--out",
        out,
    )
    assert proc.returncode == 0, proc.stderr
    assert {p.name for p in out.glob("*.png")} == FIGURES


@pytest.mark.parametrize(
    ("name", "args", "words"),
    [
        ("sweep.csv", (), "--x"),
        ("sweep.csv", ("--x", "control.Kd"), "--metric"),
        ("notes.txt", (), ".npz"),
        ("missing.npz", (), "missing.npz"),
    ],
)
def test_plot_bad_input_exit_2(
    tmp_path: Path, name: str, args: tuple[str, ...], words: str
) -> None:
    path = tmp_path / name
    if not name.startswith("missing"):
        path.write_text("control.Kd,final_position_error\n1,2\n")
    line = _assert_one_error_line(_cli("plot", path, *args), 2)
    assert words in line


def test_plot_npz_rejects_sweep_options(saved_run: Path) -> None:
    line = _assert_one_error_line(_cli("plot", saved_run / "result.npz", "--x", "sim.dt"), 2)
    assert "sweep" in line


@pytest.mark.parametrize("command", ["run", "plot", "replay", "robots"])
def test_help_of_every_command(command: str) -> None:
    proc = _cli(command, "--help")
    assert proc.returncode == 0
    assert proc.stdout.startswith("usage: hybrid-force " + command)


def test_missing_feature_module_is_a_clear_error() -> None:
    with pytest.raises(MissingExtraError, match="the thing is not available"):
        _import_feature("hybrid_force.no_such_module", "the thing")


def test_progress_bar_text() -> None:
    stream = io.StringIO()
    bar = _Progress(stream, "demo", delay=0.0)
    bar(0.5)
    text = stream.getvalue()
    assert text.startswith("\rdemo [") and "50%" in text and "ETA" in text
    assert text.count("#") == _Progress.WIDTH // 2
    bar.close()
    assert stream.getvalue().endswith("\r")
    # before the delay nothing is shown (runs shorter than a second stay quiet)
    quiet = io.StringIO()
    _Progress(quiet, "demo", delay=60.0)(0.5)
    assert quiet.getvalue() == ""


def test_lost_contact_exits_1_and_saves_the_run(tmp_path: Path, capsys) -> None:
    out = tmp_path / "lost"
    code = main([
        "run", str(SHIPPED[0].parent / "paper_contact.toml"), "--out", str(out), "--quiet",
        "--set", "initial.v=[0, 0, 3]", "--set", "control.f_d=0", "--set", "sim.duration=1",
    ])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 1
    assert "warning: run 'paper_contact': the tool left the surface" in err
    assert "error: run failed (lost contact)" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["reason"] == "lost contact"
    assert summary["lost_contact"] is True and summary["contact_at_end"] is False
    assert Result.load(out / "result.npz").meta["run_id"] == summary["run_id"]


def test_log_that_does_not_fit_in_memory_is_refused_before_the_run(
    tmp_path: Path, capsys, monkeypatch
) -> None:
    monkeypatch.setattr("hybrid_force.sim.run_checks.available_memory", lambda: 10**6)
    out = tmp_path / "big"
    code = main(["run", str(SHIPPED[0].parent / "paper_contact.toml"), "--out", str(out)])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1
    assert err[0].startswith("error: sim.duration = 20 s at sim.dt = 0.001 s")
    assert "GiB" in err[0] and not (out / "result.npz").exists()


def test_run_failing_at_its_first_sample_with_plot_keeps_exit_1(tmp_path: Path, capsys) -> None:
    """One sample cannot be drawn: the figures are skipped with a warning; the run's verdict
    (exit 1, its result and summary saved) stands."""
    out = tmp_path / "div"
    code = main([
        "run", str(REPO_ROOT / "scenarios" / "paper_contact.toml"), "--set", "control.f_d=1e9",
        "--set", "sim.duration=0.2", "--out", str(out), "--plot",
    ])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 1 and "warning: no figures:" in err and "run failed (diverged)" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_samples"] == 1 and summary["status"] == "failed"


def test_run_interrupted_before_its_first_sample_saves_an_empty_result(
    tmp_path: Path, capsys, monkeypatch
) -> None:
    from hybrid_force.model.robot import Robot

    def interrupt(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    # the first thing the loop does is ask the plant's terms (bound once, Robot.terms_into):
    # Ctrl-C lands there
    monkeypatch.setattr(Robot, "terms", interrupt)
    monkeypatch.setattr(Robot, "terms_into", lambda self, data, out: interrupt)
    out = tmp_path / "empty"
    code = main(["run", str(REPO_ROOT / "scenarios" / "paper_contact.toml"), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 130 and "run failed (interrupted)" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_samples"] == 0 and summary["t_end"] is None
    assert summary["reason"] == "interrupted" and summary["final_position_error"] is None
    assert Result.load(out / "result.npz").n_samples == 0


_CONSOLE = """
import atexit, os, sys, threading, time
from pathlib import Path
marks = Path(sys.argv[1])
atexit.register(lambda: (marks / "atexit").write_text("ran"))  # a library's clean-up
real_exit = os._exit
def fast_exit(status):  # the exit without the teardown, marked
    (marks / "fast").write_text(str(status))
    real_exit(status)
os._exit = fast_exit

def later():
    time.sleep(0.5)
    (marks / "thread").write_text("ran")

from hybrid_force import cli
command = cli.main
def command_then_thread():  # another thread alive when main returns (argv[2] "thread")
    import gc
    (marks / "frozen").write_text(f"{gc.get_freeze_count()} {len(gc.get_objects())}")
    status = command()
    if thread:
        threading.Thread(target=later).start()
    return status
thread = sys.argv[2] == "thread"
cli.main = command_then_thread
sys.argv = ["hybrid-force", *sys.argv[3:]]
sys.exit(cli.console())
"""


@pytest.mark.parametrize("thread", [False, True])
def test_the_console_script_runs_the_exit_handlers_and_waits_for_other_threads(
    tmp_path: Path, thread: bool
) -> None:
    # hybrid-force (cli.console): main starts with the imports' objects frozen (out of the
    # garbage collector's walks); the command's files and summary are out, the atexit handlers
    # ran, the exit status is main's, and the process ended by os._exit (no teardown); while
    # another thread is alive it exits as Python does, after that thread (which writes its
    # mark half a second after main returned)
    scenario = REPO_ROOT / "scenarios" / "paper_contact.toml"
    for argv, status in (
        (["run", str(scenario), "--set", "sim.duration=0.01", "--out", str(tmp_path / "o")], 0),
        (["run", str(tmp_path / "missing.toml")], 2),
    ):
        for mark in ("atexit", "thread", "fast"):
            (tmp_path / mark).unlink(missing_ok=True)
        done = subprocess.run(
            [sys.executable, "-c", _CONSOLE, str(tmp_path), "thread" if thread else "-", *argv],
            capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
        assert done.returncode == status, done.stderr
        assert (tmp_path / "atexit").read_text() == "ran"
        assert (tmp_path / "thread").exists() is thread
        assert (tmp_path / "fast").exists() is not thread
        frozen, tracked = map(int, (tmp_path / "frozen").read_text().split())
        assert frozen > 10_000 and tracked < frozen / 10  # the imports' objects: out of the walks
        if status == 0:
            assert done.stdout.rstrip().endswith(f"{tmp_path / 'o' / 'summary.json'}")
            assert Result.load(tmp_path / "o" / "result.npz").n_samples == 11
        else:
            assert done.stderr.startswith("error: ") and "missing.toml" in done.stderr


def test_the_console_script_is_cli_console() -> None:
    import tomllib

    project = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]
    assert project["scripts"]["hybrid-force"] == "hybrid_force.cli:console"

"""Sweeps and compare see exactly what ``run`` sees; a resumed sweep never mixes two worlds.

A scenario whose arm is a model file (URDF, xacro) or whose ``control.model`` is one runs
through ``hybrid-force run``, ``sweep`` (a grid of the scenario's own value) and ``compare``
(the scenario's own law) on the process pool (fork, spawn) and on Dask, with ``--out``
relative, absolute and default: every row is ok and its metrics are the run's, bit for bit.
Resuming reuses rows only when the scenario, every model file it reads and the hybrid_force
version are unchanged; otherwise it refuses with exit status 2 naming what changed.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hybrid_force.cli import main
from hybrid_force.studies.table import METRIC_COLUMNS, read_sweep_csv, read_table

REPO = Path(__file__).resolve().parents[1]

# Paper section 6.3 (RTR arm on the cylinder r = 0.4, starting in contact), 0.1 s long.
SCENARIO = """\
name = "parity"
[robot]
model = "{robot}"
[surface]
type = "cylinder"
radius = 0.4
center = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
[trajectory]
type = "helix"
center = [0.0, 0.0, 10.0]
radius = 0.4
axis = [0.0, 0.0, 1.0]
omega = 1.0
rise = 0.1
phase = 0.0
[initial]
tip = [0.4, 0.0, 7.0]
seed = [0.0, 6.0, 2.0]
[control]
supervisor = false
f_d = 10.0
{control}
[sim]
duration = 0.1
dt = 1e-3
settle_time = 0.05
"""

#: The scenario's own value of control.f_d, as a one-value grid: the sweep's run is the run.
OWN = ["--grid", "control.f_d=10.0"]
QUIET = ["--quiet", "--workers", "1"]


def _study(folder: Path, kind: str, write_xacro_rtr: Callable[[Path], Path]) -> Path:
    """folder/arms/ (a.urdf: the bundled RTR; rtr.urdf.xacro and parts/rod.xacro) and
    folder/s.toml naming them relatively: robot.model a URDF ("urdf") or a xacro file
    ("xacro"), control.model a URDF ("control"), or the arm a URDF and control.model the
    xacro file ("all")."""
    arms = folder / "arms"
    arms.mkdir(parents=True)
    shutil.copy(REPO / "robots" / "rtr.urdf", arms / "a.urdf")
    write_xacro_rtr(arms)
    robot, control = {
        "urdf": ("arms/a.urdf", ""),
        "xacro": ("arms/rtr.urdf.xacro", ""),
        "control": ("rtr", 'model = "arms/a.urdf"'),
        "all": ("arms/a.urdf", 'model = "arms/rtr.urdf.xacro"'),
    }[kind]
    path = folder / "s.toml"
    path.write_text(SCENARIO.format(robot=robot, control=control))
    return path


def _run_summary(scenario: Path, out: Path) -> dict[str, Any]:
    assert main(["run", str(scenario), "--out", str(out), "--quiet"]) == 0
    summary: dict[str, Any] = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok", summary
    return summary


def _assert_same_metrics(row: dict[str, str], summary: dict[str, Any]) -> None:
    """The row's metric cells are the run's summary's numbers (the CSV keeps every bit)."""
    assert row["status"] == "ok", row
    assert summary["position_error_max_settled"] is not None  # the numbers compared exist
    axis = summary["position_error_max_axis"]
    for name in METRIC_COLUMNS:
        if name.startswith("position_error_max_axis_"):
            expected = None if axis is None else axis["xyz".index(name[-1])]
        else:
            expected = summary[name]
        if expected is None:
            assert row[name] == "", name
        elif isinstance(expected, bool):  # the run's flags (touched, chatter, ...)
            assert row[name] == json.dumps(expected), name
        else:
            assert float(row[name]) == pytest.approx(expected, rel=1e-12, abs=1e-12), name


def _out_option(how: str, tmp_path: Path, name: str) -> tuple[list[str], Path]:
    """The --out option of a command run in tmp_path (the cwd), and the folder it names."""
    if how == "relative":
        return ["--out", name], tmp_path / name
    if how == "absolute":
        return ["--out", str(tmp_path / name)], tmp_path / name
    return [], tmp_path / "runs" / f"s_{name}"  # the default: runs/<scenario stem>_<command>


@pytest.mark.parametrize("how", ["relative", "absolute", "default"])
@pytest.mark.parametrize("kind", ["urdf", "xacro", "control"])
def test_sweep_and_compare_rows_are_the_run_on_the_pool(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    write_xacro_rtr: Callable[[Path], Path],
    kind: str,
    how: str,
) -> None:
    scenario = _study(tmp_path / "study", kind, write_xacro_rtr)
    monkeypatch.chdir(tmp_path)  # a relative --out is relative to here, not the scenario
    summary = _run_summary(scenario, tmp_path / "run")
    option, out = _out_option(how, tmp_path, "sweep")
    assert main(["sweep", str(scenario), *OWN, *option, *QUIET, "--start-method", "fork"]) == 0
    (row,) = read_sweep_csv(out / "sweep.csv")[1]
    _assert_same_metrics(row, summary)
    option, out = _out_option(how, tmp_path, "compare")
    argv = ["compare", str(scenario), "--laws", "arimoto", *option, *QUIET]
    assert main([*argv, "--start-method", "fork"]) == 0
    (law,) = read_sweep_csv(out / "runs" / "sweep.csv")[1]
    _assert_same_metrics(law, summary)
    assert read_table(out / "compare.csv")[1][0]["status"] == "ok"


@pytest.mark.parametrize(
    ("engine", "how"),
    [(["--start-method", "spawn"], "relative"), (["--scheduler", "local"], "default")],
    ids=["spawn", "dask"],
)
def test_sweep_and_compare_rows_are_the_run_on_spawned_and_dask_workers(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    write_xacro_rtr: Callable[[Path], Path],
    engine: list[str],
    how: str,
) -> None:
    """The arm a URDF file and control.model a xacro file, both relative to the scenario."""
    scenario = _study(tmp_path / "study", "all", write_xacro_rtr)
    monkeypatch.chdir(tmp_path)
    summary = _run_summary(scenario, tmp_path / "run")
    option, out = _out_option(how, tmp_path, "sweep")
    grid = ["--grid", "control.f_d=10.0,12.0"]
    assert main(["sweep", str(scenario), *grid, *option, *QUIET, *engine]) == 0
    rows = read_sweep_csv(out / "sweep.csv")[1]
    assert [r["status"] for r in rows] == ["ok", "ok"], rows
    _assert_same_metrics(rows[0], summary)
    if "spawn" in engine:  # one Dask case only: its cluster is slow to start
        option, out = _out_option(how, tmp_path, "compare")
        argv = ["compare", str(scenario), "--laws", "arimoto", *option, *QUIET, *engine]
        assert main(argv) == 0
        _assert_same_metrics(read_sweep_csv(out / "runs" / "sweep.csv")[1][0], summary)


# ----------------------------------------------------------------------------- resuming
def _sweep(scenario: Path, out: Path, values: str = "5,6") -> list[str]:
    return ["sweep", str(scenario), "--grid", f"control.Lambda={values}", "--out", str(out)]


def _edit(path: Path, old: str, new: str) -> str:
    """Replace the first ``old`` in the file by ``new``; return the former text."""
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    return text


def test_resume_refuses_rows_of_another_arm_and_reuses_those_of_the_same(
    tmp_path: Path,
    write_xacro_rtr: Callable[[Path], Path],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    scenario = _study(tmp_path / "study", "all", write_xacro_rtr)
    out = tmp_path / "out"
    argv = [*_sweep(scenario, out), *QUIET, "--start-method", "fork"]
    assert main(argv) == 0
    table = (out / "sweep.csv").read_text()
    recorded = json.loads((out / "sweep.json").read_text())["inputs"]
    arms = (tmp_path / "study" / "arms").resolve()
    assert {Path(name).name: entry["key"] for name, entry in recorded.items()} == {
        "a.urdf": "robot.model",
        "rtr.urdf.xacro": "control.model",
        "rod.xacro": "control.model",  # included by the xacro file
    }
    capsys.readouterr()
    # another content of the arm's URDF, of the controller's xacro file or of a file it
    # includes: refused (exit 2) naming it, and the table is left as it was
    for changed, key, old, new in (
        (arms / "a.urdf", "robot.model", '<mass value="20"/>', '<mass value="21"/>'),
        (arms / "rtr.urdf.xacro", "control.model", "<robot", "<!-- a comment -->\n<robot"),
        (arms / "parts" / "rod.xacro", "control.model", "<robot", "<!-- a comment -->\n<robot"),
    ):
        before = _edit(changed, old, new)
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"'{changed}' ({key} of the scenario)" in err and "another content" in err, err
        assert (out / "sweep.csv").read_text() == table
        changed.write_text(before)
    # the file removed: refused too
    (arms / "a.urdf").rename(arms / "b.urdf")
    assert main(argv) == 2
    assert "is missing now" in capsys.readouterr().err
    (arms / "b.urdf").rename(arms / "a.urdf")
    # every input as it was: the rows are reused, and a new variant only is run
    assert main([*_sweep(scenario, out, "5,6,7"), *QUIET, "--start-method", "fork"]) == 0
    assert "1 new" in capsys.readouterr().out
    rows = read_sweep_csv(out / "sweep.csv")[1]
    assert [r["control.Lambda"] for r in rows] == ["5", "6", "7"]
    assert all(r["status"] == "ok" for r in rows)
    # another hybrid_force version: refused
    monkeypatch.setattr("hybrid_force.studies.resume._version", lambda: "99.0")
    assert main(argv) == 2
    assert "hybrid_force_version" in capsys.readouterr().err


def test_compare_with_no_law_that_ran_exits_1(
    tmp_path: Path, write_xacro_rtr: Callable[[Path], Path], capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = _study(tmp_path / "study", "urdf", write_xacro_rtr)
    out = tmp_path / "cmp"
    argv = ["compare", str(scenario), "--laws", "arimoto", "--set", "sensor.velocity_noise=1e3"]
    assert main([*argv, "--out", str(out), *QUIET, "--start-method", "fork"]) == 1
    err = capsys.readouterr().err
    assert "error: no law ran (1 diverged)" in err, err
    assert read_table(out / "compare.csv")[1][0]["status"] == "diverged"

"""hybrid_force.studies.sweep: variants, engines (process pool, Dask), failures, resuming."""

from __future__ import annotations

import argparse
import contextlib
import csv
import hashlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from hybrid_force.errors import BadInputError
from hybrid_force.studies.sweep import add_sweep_arguments, run_sweep, sweep_command
from hybrid_force.studies.table import METRIC_COLUMNS, TIMING_COLUMNS, read_sweep_csv
from hybrid_force.studies.tasks import run_one
from hybrid_force.studies.variants import MAX_RUNS, expand, run_id, split_values

REPO = Path(__file__).resolve().parents[1]

# Paper section 6.3 (RTR arm on the cylinder r = 0.4, starting in contact), shortened.
SCENARIO = """\
name = "tiny_contact"
[robot]
model = "rtr"
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
[sim]
duration = {duration}
dt = 1e-3
"""


@pytest.fixture()
def scenario(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(SCENARIO.format(duration=0.15))
    return path


def _deterministic(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]


# ----------------------------------------------------------------------------- variants
def test_expand_grid_is_the_cartesian_product_in_order() -> None:
    variants = expand({"a.x": [1, 2], "b.y": ["u", "v", "w"]}, {}, 0, 0)
    expected = [
        {"a.x": 1, "b.y": "u"},
        {"a.x": 1, "b.y": "v"},
        {"a.x": 1, "b.y": "w"},
        {"a.x": 2, "b.y": "u"},
        {"a.x": 2, "b.y": "v"},
        {"a.x": 2, "b.y": "w"},
    ]
    assert variants == expected
    assert expand({}, {}, 0, 0) == [{}]


def test_expand_random_samples_are_shared_by_grid_points_and_in_range() -> None:
    variants = expand({"a.x": [1, 2, 3]}, {"s.m": (0.8, 1.2), "c.k": (-5.0, 5.0)}, 50, 7)
    assert len(variants) == 150
    per_point = [[(v["s.m"], v["c.k"]) for v in variants if v["a.x"] == g] for g in (1, 2, 3)]
    assert per_point[0] == per_point[1] == per_point[2]  # common random numbers
    m = np.array([p[0] for p in per_point[0]])
    k = np.array([p[1] for p in per_point[0]])
    assert np.all((m >= 0.8) & (m < 1.2)) and np.all((k >= -5) & (k < 5))
    assert len(set(m.tolist())) == 50  # distinct draws
    # same seed: same samples whatever the option order; another seed: other samples
    again = expand({"a.x": [1, 2, 3]}, {"c.k": (-5.0, 5.0), "s.m": (0.8, 1.2)}, 50, 7)
    assert [(v["s.m"], v["c.k"]) for v in again] == [(v["s.m"], v["c.k"]) for v in variants]
    other = expand({}, {"s.m": (0.8, 1.2), "c.k": (-5.0, 5.0)}, 50, 8)
    assert other[0]["s.m"] != per_point[0][0][0]
    # uniform: the mean of 2000 draws on [0.8, 1.2) is 1.0 within 4 standard errors
    big = np.array([v["s.m"] for v in expand({}, {"s.m": (0.8, 1.2)}, 2000, 1)])
    assert abs(big.mean() - 1.0) < 4 * (0.4 / np.sqrt(12)) / np.sqrt(2000)


@pytest.mark.parametrize(
    ("grid", "random", "samples", "match"),
    [
        ({"Lambda": [1]}, {}, 0, "table.key"),
        ({"c.L": []}, {}, 0, "no values"),
        ({"c.L": [1, 2, 1]}, {}, 0, "twice"),
        ({"c.L": [1]}, {"c.L": (0, 1)}, 3, "both"),
        ({}, {"c.L": (2.0, 1.0)}, 3, "lo <= hi"),
        ({}, {"c.L": (0.0, float("inf"))}, 3, "finite"),
        ({}, {"c.L": (0.0, 1.0)}, 0, "samples"),
    ],
)
def test_expand_rejects_bad_specs(grid, random, samples, match) -> None:
    with pytest.raises(BadInputError, match=match):
        expand(grid, random, samples, 0)


def test_run_id_is_sha1_of_sorted_json_and_order_independent() -> None:
    params = {"control.Lambda": 5.0, "sim.duration": 0.2}
    text = '{"control.Lambda":5.0,"sim.duration":0.2}'
    assert run_id(params) == hashlib.sha1(text.encode()).hexdigest()[:16]
    assert run_id({"sim.duration": 0.2, "control.Lambda": 5.0}) == run_id(params)
    assert run_id({"control.Lambda": np.float64(5.0), "sim.duration": 0.2}) == run_id(params)
    assert run_id({"control.Lambda": 5.1, "sim.duration": 0.2}) != run_id(params)


def test_split_values_keeps_lists_and_quoted_commas() -> None:
    assert split_values("1, 2.5,3e-2") == ["1", "2.5", "3e-2"]
    assert split_values('[0.4, 0, 7],[1,2,3],"a,b"') == ["[0.4, 0, 7]", "[1,2,3]", '"a,b"']


# ----------------------------------------------------------------------------- runs
def test_run_one_never_raises(tmp_path: Path, scenario: Path) -> None:
    ok = run_one(str(scenario), {"control.Lambda": 5.0}, str(tmp_path / "keep"))
    assert ok["status"] == "ok" and ok["error"] is None
    assert ok["t_end"] == pytest.approx(0.15)
    # starts on the surface and stays on it (post-stabilised): violation at round-off
    assert ok["worst_constraint_violation"] < 1e-12
    from hybrid_force.result import Result

    kept = Result.load(tmp_path / "keep" / f"{run_id({'control.Lambda': 5.0})}.npz")
    e = np.linalg.norm(kept.p[-1] - kept.p_d[-1])
    assert ok["final_position_error"] == pytest.approx(e, rel=1e-12)
    bad = run_one(str(scenario), {"control.Lambda": -1.0}, None)
    assert bad["status"] == "bad input" and "control.Lambda" in bad["error"]
    # Λ = 1e4 is refused before the run now (its sampled velocity loop, issue 27)
    fast = run_one(str(scenario), {"control.Lambda": 1e4}, None)
    assert fast["status"] == "bad input" and "control.Lambda = 10000.0" in fast["error"]
    wild = run_one(str(scenario), {"sensor.velocity_noise": 1e3}, None)
    assert wild["status"] == "diverged" and "runaway" in wild["error"]
    assert wild["t_end"] is not None and wild["t_end"] < 0.15
    missing = run_one(str(tmp_path / "nope.toml"), {}, None)
    assert missing["status"] in ("bad input", "error") and "nope.toml" in missing["error"]
    assert set(METRIC_COLUMNS) <= set(ok) and set(TIMING_COLUMNS) <= set(ok)


def test_pool_and_dask_give_identical_rows(tmp_path: Path, scenario: Path) -> None:
    variants = expand({"control.Lambda": [5.0, 1e4, -1.0, 20.0]}, {}, 0, 0)
    pool_csv = run_sweep(scenario, variants, workers=2, out_dir=tmp_path / "pool", progress=False)
    dask_csv = run_sweep(
        scenario, variants, workers=2, scheduler="local", out_dir=tmp_path / "dask", progress=False
    )
    cols_p, rows_p = read_sweep_csv(pool_csv)
    cols_d, rows_d = read_sweep_csv(dask_csv)
    assert cols_p == cols_d
    assert cols_p[:2] == ["run_id", "control.Lambda"]
    assert _deterministic(rows_p) == _deterministic(rows_d)
    assert [r["run_id"] for r in rows_p] == [run_id(v) for v in variants]  # variant order
    # Λ = 1e4: refused by the law's velocity-loop check (issue 27), no longer run to diverge
    assert [r["status"] for r in rows_p] == ["ok", "bad input", "bad input", "ok"]
    assert float(rows_p[0]["final_position_error"]) > 0
    info = json.loads((tmp_path / "pool" / "sweep.json").read_text())
    assert info["n_variants"] == 4 and info["columns"] == cols_p
    assert not [p for p in (tmp_path / "pool").iterdir() if p.name.endswith(".tmp")]
    # a heat map / line plot of the CSV
    from hybrid_force.viz.sweep_plots import plot_sweep

    png = plot_sweep(pool_csv, tmp_path / "line.png", x="control.Lambda", metric="t_end")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000


_KILL_SCRIPT = """
import sys
from hybrid_force.studies.sweep import run_sweep
if __name__ == "__main__":
    variants = [{{"control.Lambda": float(x)}} for x in {lambdas}]
    run_sweep(sys.argv[1], variants, workers=1, out_dir=sys.argv[2], progress=False)
"""


def test_killed_sweep_resumes_without_redoing_finished_runs(tmp_path: Path) -> None:
    scenario = tmp_path / "slow.toml"
    scenario.write_text(SCENARIO.format(duration=0.4))
    lambdas = [2.0, 3.0, 5.0, 8.0, 10.0, 15.0, 20.0, 30.0]
    script = tmp_path / "sweep_script.py"
    script.write_text(textwrap.dedent(_KILL_SCRIPT.format(lambdas=lambdas)))
    out = tmp_path / "out"
    csv_path = out / "sweep.csv"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    log = tmp_path / "stderr.txt"
    with log.open("wb") as err:
        proc = subprocess.Popen(
            [sys.executable, str(script), str(scenario), str(out)],
            env=env,
            start_new_session=True,
            stderr=err,
        )
    seen = 0
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            if csv_path.exists():
                _, rows = read_sweep_csv(csv_path)  # always parseable, even mid-sweep
                seen = len(rows)
                if seen >= 2:
                    break
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the script and its worker process
        proc.wait()
    assert 2 <= seen < len(lambdas), log.read_text()
    with csv_path.open(newline="") as fh:
        before = list(csv.DictReader(fh))
    assert before and all(r["status"] == "ok" for r in before)
    assert len(list(out.glob(".scratch-*"))) == 1  # the killed sweep could not remove it
    new_rows: list[dict] = []
    variants = [{"control.Lambda": x} for x in lambdas]
    run_sweep(scenario, variants, workers=2, out_dir=out, progress=False, on_row=new_rows.append)
    _, after = read_sweep_csv(csv_path)
    assert not list(out.glob(".scratch-*"))  # the next sweep removed it
    assert [r["run_id"] for r in after] == [run_id(v) for v in variants]
    assert len(new_rows) == len(lambdas) - len(before)  # only the missing runs ran
    assert {r["run_id"] for r in new_rows}.isdisjoint({r["run_id"] for r in before})
    by_id = {r["run_id"]: r for r in after}
    for r in before:  # finished rows kept verbatim (wall_time included: not rerun)
        assert by_id[r["run_id"]] == r
    # a third run has nothing left to do
    again: list[dict] = []
    run_sweep(scenario, variants, workers=1, out_dir=out, progress=False, on_row=again.append)
    assert again == []
    assert read_sweep_csv(csv_path)[1] == after


def test_resume_refuses_another_scenario(tmp_path: Path, scenario: Path) -> None:
    run_sweep(
        scenario, [{"control.Lambda": -1.0}], workers=1, out_dir=tmp_path / "o", progress=False
    )
    scenario.write_text(SCENARIO.format(duration=0.25))
    with pytest.raises(BadInputError, match="different version"):
        run_sweep(scenario, [{"control.Lambda": -1.0}], out_dir=tmp_path / "o", progress=False)
    (tmp_path / "x.csv").write_text("a,b\n1,2\n")
    with pytest.raises(BadInputError, match="not a sweep CSV"):
        read_sweep_csv(tmp_path / "x.csv")


# ----------------------------------------------------------------------------- command
def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_sweep_arguments(parser)
    return parser.parse_args(list(argv))


def test_sweep_command(tmp_path: Path, scenario: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "cmd"
    args = _args(
        str(scenario),
        "--grid",
        "control.Lambda=5,-1",
        "--random",
        "sim.model_mass_factor=0.9:1.1",
        "--samples",
        "2",
        "--seed",
        "3",
        "--workers",
        "2",
        "--out",
        str(out),
        "--keep-results",
        "--quiet",
    )
    assert sweep_command(args) == 0
    text = capsys.readouterr().out
    assert "4 runs (2 ok, 2 bad input)" in text
    _, rows = read_sweep_csv(out / "sweep.csv")
    assert [r["control.Lambda"] for r in rows] == ["5", "5", "-1", "-1"]
    masses = [float(r["sim.model_mass_factor"]) for r in rows]
    assert masses[0] == masses[2] and masses[1] == masses[3] and min(masses) >= 0.9
    assert len(list((out / "results").glob("*.npz"))) == 2  # bad input: no result
    info = json.loads((out / "sweep.json").read_text())
    assert info["arguments"]["grid"] == {"control.Lambda": [5, -1]}
    for bad, match in [
        (("--random", "sim.model_mass_factor=0.9:1.1"), "--samples"),
        (("--samples", "3"), "--random"),
        (("--grid", "control.Lambda"), "table.key=v1"),
        (("--random", "sim.model_mass_factor=0.9"), "lo:hi"),
        (("--grid", "Lambda=1,2"), "table.key"),
    ]:
        with pytest.raises(BadInputError, match=match):
            sweep_command(_args(str(scenario), *bad, "--out", str(out)))
    with pytest.raises(BadInputError, match="does not exist"):
        sweep_command(_args(str(tmp_path / "missing.toml")))


def test_rows_of_other_sweeps_are_kept_and_error_rows_retried(
    tmp_path: Path, scenario: Path
) -> None:
    out = tmp_path / "o"
    first = [{"control.Lambda": -1.0}, {"control.Lambda": -2.0}]
    run_sweep(scenario, first, workers=1, out_dir=out, progress=False)
    columns, rows = read_sweep_csv(out / "sweep.csv")
    rows[0]["status"] = "error"  # as if the run had hit a bug: retried on resume
    with (out / "sweep.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    second = [{"control.Lambda": -3.0}, {"control.Lambda": -1.0}]
    new: list[dict] = []
    run_sweep(scenario, second, workers=1, out_dir=out, progress=False, on_row=new.append)
    assert sorted(r["control.Lambda"] for r in new) == [-3.0, -1.0]
    _, after = read_sweep_csv(out / "sweep.csv")
    # this sweep's variants in its order, then the row of the earlier sweep
    assert [r["control.Lambda"] for r in after] == ["-3.0", "-1.0", "-2.0"]
    assert [r["status"] for r in after] == ["bad input"] * 3


# ----------------------------------------------------------------------------- trust
def _alive(procs: list) -> list[int]:
    """Pids of the psutil processes that still run (a zombie waiting to be reaped is dead)."""
    import psutil

    out = []
    for p in procs:
        try:
            if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p.pid)
        except psutil.NoSuchProcess:
            pass
    return out


def _stop(proc: subprocess.Popen) -> None:
    """Kill a process group started by a test (start_new_session=True) and reap its leader."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=10)


@pytest.fixture()
def dask_cluster(tmp_path: Path) -> Iterator[tuple[str, Path]]:
    """A Dask scheduler and one worker (1 process, 1 thread) started as commands in their own
    folder, with their own TMPDIR: (scheduler address, that folder). Killed at teardown."""
    home = tmp_path / "cluster" / "home"  # not a sibling of the caller's folder
    (home / "tmp").mkdir(parents=True)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(REPO)  # the same hybrid_force as the sweep's, not the caller's folder
    env["TMPDIR"] = str(home / "tmp")
    bin_dir = Path(sys.executable).parent
    dask_cmd = str(bin_dir / "dask") if (bin_dir / "dask").exists() else "dask"
    sched_file = home / "scheduler.json"
    procs: list[subprocess.Popen] = []
    logs = [(home / "scheduler.log").open("wb"), (home / "worker.log").open("wb")]
    try:
        procs.append(
            subprocess.Popen(
                [dask_cmd, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                 "--scheduler-file", str(sched_file)],
                cwd=home, env=env, stdout=logs[0], stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        )  # fmt: skip
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            assert procs[0].poll() is None, (home / "scheduler.log").read_text()
            time.sleep(0.1)
        time.sleep(0.2)  # the file is written in one go, but let it land
        address = json.loads(sched_file.read_text())["address"]
        procs.append(
            subprocess.Popen(
                [dask_cmd, "worker", address, "--nworkers", "1", "--nthreads", "1",
                 "--no-dashboard", "--local-directory", str(home)],
                cwd=home, env=env, stdout=logs[1], stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        )  # fmt: skip
        from dask.distributed import Client

        with Client(address, timeout=30) as client:
            client.wait_for_workers(1, timeout=60)
        yield address, home
    finally:
        for proc in procs:
            _stop(proc)
        for log in logs:
            log.close()


@pytest.mark.slow
def test_sweep_on_a_cluster_whose_workers_cannot_see_the_scenario(
    tmp_path: Path,
    dask_cluster: tuple[str, Path],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture,
) -> None:
    """The workers run in another folder: a scenario path relative to the caller's folder and a
    URDF path relative to the scenario mean nothing to them; they get data, not paths."""
    from hybrid_force.cli import main
    from hybrid_force.result import Result

    address, home = dask_cluster
    scen_dir = tmp_path / "study"
    scen_dir.mkdir()
    # the bundled URDF, with meshes that exist nowhere: simulating needs none
    urdf = (REPO / "robots" / "rtr.urdf").read_text()
    mesh = '<visual><geometry><mesh filename="package://nowhere/arm.stl"/></geometry></visual>'
    urdf = urdf.replace('<link name="tip">', f'<link name="tip">{mesh}', 1)
    assert "package://nowhere" in urdf
    (scen_dir / "my_rtr.urdf").write_text(urdf)
    text = SCENARIO.format(duration=0.1).replace('model = "rtr"', 'model = "my_rtr.urdf"')
    (scen_dir / "tiny.toml").write_text(text)
    caller = tmp_path / "caller"
    caller.mkdir()
    monkeypatch.chdir(caller)
    assert (caller / "../study/tiny.toml").is_file()
    assert not (home / "../study/tiny.toml").exists()  # the caller's path, seen by the worker
    status = main(
        ["sweep", "../study/tiny.toml", "--grid", "control.Lambda=5,20,-1",
         "--scheduler", address, "--out", "out", "--keep-results", "--quiet"]
    )  # fmt: skip
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert "warning: 1 of 3 runs are not ok (1 bad input)" in captured.err
    _, rows = read_sweep_csv(caller / "out" / "sweep.csv")
    assert [r["status"] for r in rows] == ["ok", "ok", "bad input"], rows
    assert float(rows[0]["t_end"]) == pytest.approx(0.1)
    # the message names the scenario as the caller gave it, not a worker's temporary copy
    assert rows[2]["error"].startswith("../study/tiny.toml: control.Lambda")
    assert "hybrid_force_run_" not in rows[2]["error"]
    # results kept by the caller (never written by a worker), naming the caller's URDF
    kept = sorted((caller / "out" / "results").glob("*.npz"))
    assert [p.stem for p in kept] == sorted(r["run_id"] for r in rows[:2])
    result = Result.load(kept[0])
    assert result.meta["robot"]["model"] == str((scen_dir / "my_rtr.urdf").resolve())
    assert result.meta["scenario"]["robot"]["model"] == "my_rtr.urdf"
    # the worker made its temporary folders in its TMPDIR and removed them; nothing of the
    # sweep's was written in the worker's folder
    from dask.distributed import Client

    with Client(address, timeout=30) as client:
        assert list(client.run(tempfile.gettempdir).values()) == [str(home / "tmp")]
    assert not list((home / "tmp").rglob("hybrid_force_run_*"))
    assert not list(home.rglob("*.npz")) and not list(home.rglob("*.urdf"))


def test_run_one_sends_a_relative_urdf_and_names_the_original(tmp_path: Path) -> None:
    from hybrid_force.result import Result

    (tmp_path / "arms").mkdir()
    (tmp_path / "arms" / "a.urdf").write_text((REPO / "robots" / "rtr.urdf").read_text())
    scen = tmp_path / "s.toml"
    scen.write_text(SCENARIO.format(duration=0.05).replace('"rtr"', '"arms/a.urdf"'))
    keep = tmp_path / "keep"
    row = run_one(str(scen), {"control.Lambda": 5.0}, str(keep))
    assert row["status"] == "ok", row
    kept = Result.load(keep / f"{row['run_id']}.npz")
    assert kept.meta["robot"]["model"] == str((tmp_path / "arms" / "a.urdf").resolve())
    assert kept.meta["scenario"]["robot"]["model"] == "arms/a.urdf"
    missing = run_one(str(scen), {"robot.model": "arms/none.urdf"}, None)
    assert missing["status"] == "bad input"
    assert "URDF file not found" in missing["error"] and "none.urdf" in missing["error"]
    named = run_one(str(scen), {"robot.model": "rtr"}, str(keep))
    assert named["status"] == "ok"
    assert Result.load(keep / f"{named['run_id']}.npz").meta["robot"]["model"] == "rtr"


def test_exit_status_when_runs_fail(
    tmp_path: Path, scenario: Path, capsys: pytest.CaptureFixture
) -> None:
    """Every run failed: 1. Some failed: 0 and a warning on stderr. (--help says so.)"""
    out = tmp_path / "all_bad"
    args = _args(str(scenario), "--grid", "control.Lambda=-1,-2", "--out", str(out), "--quiet")
    assert sweep_command(args) == 1
    err = capsys.readouterr().err
    assert "error: no run is ok (2 bad input)" in err
    assert [r["status"] for r in read_sweep_csv(out / "sweep.csv")[1]] == ["bad input"] * 2
    assert sweep_command(args) == 1  # resumed: nothing to run, still no run ok
    from hybrid_force.cli import main

    assert main(["sweep", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "exit status:" in text and "1 no run is ok" in text and "143 SIGTERM" in text
    assert f"more than {MAX_RUNS} runs" in text


def test_huge_sweeps_are_refused_before_expanding(tmp_path: Path, scenario: Path) -> None:
    assert MAX_RUNS == 100_000
    t0 = time.perf_counter()
    big = {f"t.k{i}": list(range(10)) for i in range(12)}  # 10**12 variants
    with pytest.raises(BadInputError, match=r"would have 1000000000000 runs .*--grid t\.k0: 10"):
        expand(big, {}, 0, 0)
    with pytest.raises(BadInputError, match=r"--grid a\.x: 1000 values × --samples 101"):
        expand({"a.x": list(range(1000))}, {"s.m": (0.0, 1.0)}, 101, 0)
    with pytest.raises(BadInputError, match="--samples 1000000000"):
        expand({}, {"s.m": (0.0, 1.0)}, 10**9, 0)  # not drawn: 8 GB of samples
    with pytest.raises(BadInputError, match=r"lists 100001 values"):
        expand({"a.x": range(MAX_RUNS + 1)}, {}, 0, 0)
    assert time.perf_counter() - t0 < 2.0
    assert len(expand({"a.x": list(range(1000)), "b.y": list(range(100))}, {}, 0, 0)) == MAX_RUNS
    values = ",".join(str(i) for i in range(MAX_RUNS + 1))
    with pytest.raises(BadInputError, match=r"--grid control\.Lambda lists 100001 values"):
        sweep_command(_args(str(scenario), "--grid", f"control.Lambda={values}"))
    with pytest.raises(BadInputError, match="at most 100000"):
        run_sweep(scenario, [{"a.x": i} for i in range(MAX_RUNS + 1)], out_dir=tmp_path / "o")
    assert not (tmp_path / "o").exists()


def _descendants(pid: int) -> list:
    import psutil

    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["pool", "local"])
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["TERM", "KILL"])
def test_killing_the_sweep_leaves_no_worker(tmp_path: Path, engine: str, sig: int) -> None:
    """A sweep of long runs is killed while its workers run: none of the processes it
    started (workers, Dask nannies' workers, resource tracker) outlives it by more than 10 s."""
    scen = tmp_path / "long.toml"
    scen.write_text(SCENARIO.format(duration=0.15))
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "hybrid_force.cli", "sweep", str(scen), "--grid",
           "control.Lambda=2,3,5", "--grid", "sim.duration=60.0", "--workers", "1",
           "--out", str(out), "--quiet"]  # fmt: skip
    if engine == "local":
        cmd += ["--scheduler", "local"]
    log = tmp_path / "stderr.txt"
    with log.open("wb") as err:
        proc = subprocess.Popen(cmd, cwd=tmp_path, stderr=err, start_new_session=True)
    try:
        # a run has started when its private folder exists (in DIR/.scratch-<pid>-*/); the
        # first starts while the sweep checks the scenario, before it writes sweep.csv
        deadline = time.monotonic() + 90
        while not (
            list(out.glob(".scratch-*/hybrid_force_run_*")) and (out / "sweep.csv").exists()
        ):
            assert proc.poll() is None, log.read_text()
            assert time.monotonic() < deadline, "no run started"
            time.sleep(0.05)
        started = _descendants(proc.pid)
        assert started, "the sweep has no child process"
        os.kill(proc.pid, sig)
        status = proc.wait(timeout=30)
        t_killed = time.monotonic()
        while _alive(started) and time.monotonic() - t_killed < 10:
            time.sleep(0.05)
        assert _alive(started) == [], log.read_text()
    finally:
        _stop(proc)
        for p in _descendants(proc.pid):
            with contextlib.suppress(Exception):
                p.kill()
    if sig == signal.SIGTERM:
        assert status == 143, log.read_text()
        assert "terminated (SIGTERM) after 0 new run(s)" in log.read_text()
        _, rows = read_sweep_csv(out / "sweep.csv")  # written, parseable, nothing finished
        assert rows == []
        assert not list(out.glob(".scratch-*"))  # the workers' temporary folders are gone
    else:
        assert status == -signal.SIGKILL


def test_a_scenario_file_changed_during_the_sweep_stops_it(tmp_path: Path, scenario: Path) -> None:
    """Rows of two versions of a scenario never share a table: the change is found when the
    next task is made (the first runs, one per worker, were made before it, of the old one)."""
    variants = [
        {"robot.model": "nowhere/arm.urdf"},
        {"control.Lambda": 5.0},  # sent ahead to the one worker before any row
        {"control.Lambda": 6.0},  # made after the change: refused
    ]
    seen: list[dict] = []

    def edit(row: dict) -> None:  # the first row is made here (the URDF is missing)
        seen.append(row)
        scenario.write_text(SCENARIO.format(duration=0.2))

    with pytest.raises(BadInputError, match="changed or removed during the sweep"):
        run_sweep(
            scenario, variants, workers=1, out_dir=tmp_path / "o", progress=False, on_row=edit
        )
    assert [r["status"] for r in seen] == ["bad input"]
    assert "URDF file not found" in seen[0]["error"]
    _, rows = read_sweep_csv(tmp_path / "o" / "sweep.csv")
    assert [r["run_id"] for r in rows] == [run_id(variants[0])]  # the finished row is kept


_WATCHED_CHILD = """
import os, sys, threading, time
if sys.argv[1] == "fallback":
    sys.platform = "darwin"  # no prctl: the polling thread must do it
from hybrid_force.studies.sweep import _watch_parent
_watch_parent(os.getppid())
names = [t.name for t in threading.enumerate()]
print("watched", "hybrid_force parent watch" in names, flush=True)
time.sleep(60)
"""
_PARENT = """
import subprocess, sys, time
child = subprocess.Popen([sys.executable, "-c", sys.argv[1], sys.argv[2]])
print(child.pid, flush=True)
time.sleep(60)
"""


@pytest.mark.parametrize("how", ["prctl", "fallback"])
def test_a_watched_worker_dies_with_its_parent(how: str) -> None:
    """_watch_parent (the pool workers' initialiser): SIGKILL of the parent kills the child,
    through PR_SET_PDEATHSIG on Linux or the os.getppid() polling thread elsewhere."""
    import psutil

    parent = subprocess.Popen(
        [sys.executable, "-c", _PARENT, _WATCHED_CHILD, how],
        stdout=subprocess.PIPE,  # the child inherits it: its line comes after the pid
        text=True,
        start_new_session=True,
    )
    try:
        assert parent.stdout is not None
        child = psutil.Process(int(parent.stdout.readline()))
        thread = "True" if how == "fallback" or not sys.platform.startswith("linux") else "False"
        assert parent.stdout.readline().split() == ["watched", thread]
        assert _alive([child]) == [child.pid]
        parent.kill()
        parent.wait(timeout=10)
        t0 = time.monotonic()
        while _alive([child]) and time.monotonic() - t0 < 5:
            time.sleep(0.05)
        assert _alive([child]) == []
    finally:
        _stop(parent)
        if parent.stdout is not None:
            parent.stdout.close()


def test_a_run_that_loses_contact_is_a_failed_row_with_its_metrics(tmp_path: Path) -> None:
    """Kicked off the surface with nothing to bring it back (f_d = 0, no supervisor): the run
    fails with reason 'lost contact'; its row keeps the metrics of the whole run."""
    scenario = tmp_path / "tiny.toml"
    scenario.write_text(SCENARIO.format(duration=0.3))
    row = run_one(
        str(scenario),
        {"initial.v": [0.0, 0.0, 3.0], "control.f_d": 0.0},
        None,
    )
    assert row["status"] == "failed" and row["error"].startswith("lost contact: ")
    assert row["t_end"] == pytest.approx(0.3)


def test_a_sweep_into_a_folder_another_command_writes_into_is_refused(
    tmp_path: Path, scenario: Path, capsys: pytest.CaptureFixture
) -> None:
    """Two writers of one sweep.csv would each rewrite it from their own rows: the second is
    refused before it runs anything, and the first one's files are untouched."""
    from hybrid_force.run_output import locked_folder

    out = tmp_path / "busy"
    with locked_folder(out):
        (out / "sweep.csv").write_text("run_id,status\nabc,ok\n")
        from hybrid_force.cli import main

        argv = ["sweep", str(scenario), "--grid", "control.Lambda=5,10", "--out", str(out)]
        assert main(argv) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "another run or sweep is writing into this folder" in err[0]
    assert (out / "sweep.csv").read_text() == "run_id,status\nabc,ok\n"


# ----------------------------------------------------------------------------- own model files
# The RTR arm as a xacro file (conftest.py's write_xacro_rtr): link 2's length is the argument
# l2, its links made by a macro of an included file (parts/rod.xacro).


def _xacro_study(tmp_path: Path, write_xacro_rtr: Callable[[Path], Path]) -> Path:
    """study/arms/rtr.urdf.xacro (+ parts/rod.xacro) and study/s.toml using it with l2 = 0.8."""
    write_xacro_rtr(tmp_path / "study" / "arms")
    scen = tmp_path / "study" / "s.toml"
    robot = 'model = "arms/rtr.urdf.xacro"\nxacro_args = {l2 = "0.8"}'
    scen.write_text(SCENARIO.format(duration=0.05).replace('model = "rtr"', robot))
    return scen


def test_a_xacro_model_is_expanded_by_the_sweep_and_sent_as_urdf(
    tmp_path: Path, write_xacro_rtr: Callable[[Path], Path]
) -> None:
    """The worker gets the expanded URDF text: it runs with the xacro files gone."""
    from hybrid_force.studies.tasks import _execute, _Source

    scen = _xacro_study(tmp_path, write_xacro_rtr)
    task = _Source(scen).job("r1", {"control.Lambda": 5.0}, keep=True)
    assert not isinstance(task, dict), task
    assert task.urdf is not None and task.urdf.expanded and task.urdf.name == "rtr.urdf"
    text = task.urdf.data.decode()
    assert "xacro" not in text.split("-->")[-1] and '<origin xyz="0.8 0 0"/>' in text
    for f in sorted((tmp_path / "study" / "arms").rglob("*.xacro")):
        f.unlink()
    row, blob = _execute(task)
    assert row["status"] == "ok", row
    assert blob is not None


def test_run_one_on_a_relative_xacro_model_names_it_and_its_arguments(
    tmp_path: Path, write_xacro_rtr: Callable[[Path], Path]
) -> None:
    from hybrid_force.result import Result
    from hybrid_force.viz.scene import Replay

    scen = _xacro_study(tmp_path, write_xacro_rtr)
    keep = tmp_path / "keep"
    row = run_one(str(scen), {"control.Lambda": 5.0}, str(keep))
    assert row["status"] == "ok", row
    kept = Result.load(keep / f"{row['run_id']}.npz")
    xacro_file = str((tmp_path / "study" / "arms" / "rtr.urdf.xacro").resolve())
    assert kept.meta["robot"]["model"] == xacro_file
    assert kept.meta["robot"]["xacro_args"] == {"l2": "0.8"}
    assert kept.meta["scenario"]["robot"] == {
        "model": "arms/rtr.urdf.xacro",
        "xacro_args": {"l2": "0.8"},
    }
    # the replay expands the file again with l2 = 0.8: the tip at q = 0 is l2 + l3 away
    robot = Replay(kept).robot
    np.testing.assert_allclose(robot.tip_position([0.0, 0.0, 0.0]), [1.8, 0.0, 0.0], atol=1e-15)
    # the argument swept as a number is passed as its text
    swept = run_one(str(scen), {"robot.xacro_args.l2": 0.7}, str(keep))
    assert swept["status"] == "ok", swept
    kept = Result.load(keep / f"{swept['run_id']}.npz")
    assert kept.meta["robot"]["xacro_args"] == {"l2": "0.7"}
    # a value xacro cannot compute with: bad input naming robot.model and xacro's message
    bad = run_one(str(scen), {"robot.xacro_args.l2": "abc"}, None)
    assert bad["status"] == "bad input"
    assert 'robot.model = "arms/rtr.urdf.xacro": xacro cannot expand' in bad["error"]
    assert "when evaluating expression 'length / 2'" in bad["error"]
    # one that expands into a URDF that cannot be simulated: refused here as the loader does
    broken = run_one(str(scen), {"robot.xacro_args.l2": "inf"}, None)
    assert broken["status"] == "bad input"
    assert broken["error"].startswith(f'{scen}: robot.model = "arms/rtr.urdf.xacro": ')
    assert "rtr.urdf.xacro (as expanded by xacro)" in broken["error"]
    assert "xyz='inf 0 0' must be 3 finite numbers" in broken["error"]


def test_run_one_on_an_mjcf_model(tmp_path: Path) -> None:
    """The RTR in MJCF (hinge, slide, hinge) is sent as the .xml file's bytes."""
    from hybrid_force.result import Result

    mjcf = """\
<mujoco model="rtr"><compiler angle="radian"/><worldbody>
  <body name="link1"><joint name="q1" type="hinge" axis="0 0 1"/>
    <body name="link2"><joint name="q2" type="slide" axis="0 0 1" range="-1 16"/>
      <inertial pos="0.45 0 0" mass="20" diaginertia="0 1.35 1.35"/>
      <body name="link3" pos="0.9 0 0"><joint name="q3" type="hinge" axis="0 -1 0"/>
        <inertial pos="0.5 0 0" mass="20" diaginertia="0 1.6666666666666667 1.6666666666666667"/>
        <body name="tip" pos="1 0 0"/>
</body></body></body></worldbody></mujoco>
"""
    (tmp_path / "arms").mkdir()
    (tmp_path / "arms" / "rtr.xml").write_text(mjcf)
    scen = tmp_path / "s.toml"
    scen.write_text(SCENARIO.format(duration=0.05).replace('"rtr"', '"arms/rtr.xml"'))
    keep = tmp_path / "keep"
    row = run_one(str(scen), {}, str(keep))
    assert row["status"] == "ok", row
    kept = Result.load(keep / f"{row['run_id']}.npz")
    assert kept.meta["robot"]["model"] == str((tmp_path / "arms" / "rtr.xml").resolve())
    # the same run as the bundled URDF arm's (same model, same numbers)
    named = run_one(str(scen), {"robot.model": "rtr"}, None)
    assert row["final_position_error"] == pytest.approx(named["final_position_error"], rel=1e-9)


def _thread_settings() -> dict[str, str | None]:
    import os

    from hybrid_force.studies.engines import THREAD_VARIABLES

    return {name: os.environ.get(name) for name in THREAD_VARIABLES}


def test_workers_start_single_threaded_and_the_environment_is_restored(monkeypatch) -> None:
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor

    from hybrid_force.studies.engines import THREAD_VARIABLES, single_threaded_workers

    for name in THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")  # the user's own choice is kept
    before = dict(os.environ)
    with single_threaded_workers():
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
            seen = pool.submit(_thread_settings).result(timeout=60)
    expected = {name: "1" for name in THREAD_VARIABLES}
    expected["MKL_NUM_THREADS"] = "3"
    assert seen == expected
    assert dict(os.environ) == before

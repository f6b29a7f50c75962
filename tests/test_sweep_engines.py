"""hybrid_force.studies engines: rows identical whatever the workers, start method, chunks or
engine; chunk sizes; warm-up; the scenario checked as the variants see it; module layout."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from hybrid_force.errors import BadInputError
from hybrid_force.studies import engines, sweep, table, tasks, variants
from hybrid_force.studies.engines import CHUNK_SECONDS, _ChunkSize
from hybrid_force.studies.sweep import run_sweep
from hybrid_force.studies.table import TIMING_COLUMNS, _cell, read_sweep_csv
from hybrid_force.studies.tasks import run_one
from hybrid_force.studies.variants import expand, run_id

REPO = Path(__file__).resolve().parents[1]

PAPER = REPO / "scenarios" / "paper_contact.toml"  # section 6.3, 20 s: shortened per variant


@pytest.fixture()
def scenario(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(PAPER.read_text().replace("duration = 20.0", "duration = 0.1"))
    return path


def _results(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]


def test_rows_are_identical_whatever_the_workers_start_method_chunks_or_engine(
    tmp_path: Path, scenario: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each row equals the one its variant gives when run alone in this process (run_one: no
    pool, no warm-up, no chunk), on 1 to 3 forked or spawned workers and on Dask."""
    lambdas = [2.0, 3.0, 5.0, 8.0, 10.0, 15.0, 20.0, 30.0, 1e4, -1.0]
    todo = expand({"control.Lambda": lambdas}, {}, 0, 0)
    alone = [run_one(str(scenario), v, None) for v in todo]
    reference = [{k: _cell(v) for k, v in r.items() if k not in TIMING_COLUMNS} for r in alone]
    # Λ = 1e4 is refused by the law's velocity-loop check (issue 27) before it could diverge
    assert [r["status"] for r in reference][-2:] == ["bad input", "bad input"]
    sizes: list[int] = []
    next_size = _ChunkSize.next

    def spy(self: _ChunkSize) -> int:
        sizes.append(next_size(self))
        return sizes[-1]

    monkeypatch.setattr(_ChunkSize, "next", spy)
    setups: list[dict] = [
        {"workers": 1, "start_method": "spawn"},
        {"workers": 3, "start_method": "spawn"},
        {"workers": 2, "scheduler": "local"},
    ]
    paths = [
        run_sweep(scenario, todo, out_dir=tmp_path / f"s{i}", progress=False, **setup)
        for i, setup in enumerate(setups)
    ]
    if sys.platform.startswith("linux"):
        # forked workers, from a process with no other thread (a Dask client leaves some here)
        code = (
            "import sys, json\n"
            "from hybrid_force.studies.sweep import run_sweep\n"
            "run_sweep(sys.argv[1], json.loads(sys.argv[2]), workers=2, out_dir=sys.argv[3],\n"
            "          progress=False, start_method='fork')\n"
        )
        env = dict(os.environ, PYTHONPATH=str(REPO))
        argv = [sys.executable, "-c", code, str(scenario), json.dumps(todo), str(tmp_path / "f")]
        subprocess.run(argv, env=env, check=True, capture_output=True)
        setups.append({"workers": 2, "start_method": "fork"})
        paths.append(tmp_path / "f" / "sweep.csv")
    for setup, path in zip(setups, paths, strict=True):
        _, rows = read_sweep_csv(path)
        assert [r["run_id"] for r in rows] == [run_id(v) for v in todo], setup
        assert _results(rows) == reference, setup
    assert max(sizes) > 1  # short runs were sent in chunks of several


def test_chunk_sizes_fill_the_target_time_and_keep_the_work_shared() -> None:
    sizes = _ChunkSize(n_jobs=1000, workers=4)
    assert sizes.next() == 1  # nothing measured yet
    for wall in (0.01, 0.02, 0.01, 5.0, 0.01):  # median 0.01 s
        sizes.observe({"wall_time": wall, "status": "ok"})
    sizes.observe({"wall_time": 0.0, "status": "bad input"})  # not a run: ignored
    assert sizes.next() == int(CHUNK_SECONDS / 0.01)
    sizes.left = 40  # fair share: 40 left over 2 × 4 workers
    assert sizes.next() == 5
    sizes.left = 3
    assert sizes.next() == 1
    slow = _ChunkSize(n_jobs=100, workers=2)
    slow.observe({"wall_time": 3.0, "status": "ok"})
    assert slow.next() == 1  # long runs go one by one


def test_warm_up_never_raises_and_changes_no_row(tmp_path: Path, scenario: Path) -> None:
    source = tasks._Source(scenario)
    good = source.job(run_id({}), {}, keep=False)
    assert isinstance(good, tasks._Task)
    before, _ = tasks._execute(good)
    tasks.warm_up(good)
    after, _ = tasks._execute(good)
    drop = set(TIMING_COLUMNS)
    assert {k: v for k, v in before.items() if k not in drop} == {
        k: v for k, v in after.items() if k not in drop
    }
    broken = tasks._Task("x", {}, {"robot": {"model": "no-such-arm"}}, "b.toml", None, False)
    tasks.warm_up(broken)  # a variant that cannot run: nothing raised


@pytest.mark.parametrize("enabled", [True, False])
def test_warm_up_pauses_the_garbage_collector_and_leaves_it_as_it_was(
    scenario: Path, monkeypatch: pytest.MonkeyPatch, enabled: bool
) -> None:
    import gc

    task = tasks._Source(scenario).job(run_id({}), {}, keep=False)
    assert isinstance(task, tasks._Task)
    seen: list[bool] = []
    execute = tasks._execute

    def spy(t: tasks._Task) -> tasks._Outcome:
        seen.append(gc.isenabled())
        if enabled:
            raise RuntimeError("a warm-up that fails still gives the collector back")
        return execute(t)

    monkeypatch.setattr(tasks, "_execute", spy)
    was = gc.isenabled()
    try:
        (gc.enable if enabled else gc.disable)()
        tasks.warm_up(task)
        assert seen == [False] and gc.isenabled() is enabled
    finally:
        (gc.enable if was else gc.disable)()


def test_the_scenario_is_checked_as_every_variant_sees_it(tmp_path: Path) -> None:
    """A key the grid fixes to one value is part of the scenario the command checks; a file
    broken elsewhere is refused before anything is written, and its workers are stopped."""
    import argparse

    from hybrid_force.errors import BadInputError
    from hybrid_force.studies.sweep import add_sweep_arguments, sweep_command

    def args(*argv: str) -> argparse.Namespace:
        parser = argparse.ArgumentParser()
        add_sweep_arguments(parser)
        return parser.parse_args(list(argv))

    broken = tmp_path / "broken.toml"
    broken.write_text(PAPER.read_text().replace("duration = 20.0", "duration = -1.0"))
    out = tmp_path / "fixed"
    code = sweep_command(
        args(str(broken), "--grid", "sim.duration=0.05", "--workers", "1", "--out", str(out))
    )
    assert code == 0
    _, rows = read_sweep_csv(out / "sweep.csv")
    assert [r["status"] for r in rows] == ["ok"] and float(rows[0]["t_end"]) == 0.05
    refused = tmp_path / "refused"
    with pytest.raises(BadInputError, match=r"sim\.duration"):
        sweep_command(
            args(
                str(broken), "--grid", "control.Lambda=2,3", "--workers", "2", "--out", str(refused)
            )
        )
    assert not refused.exists()  # nothing written, not even the folder
    import multiprocessing

    assert multiprocessing.active_children() == []  # the pool's workers were stopped


def test_tasks_sent_ahead_are_run_once_and_their_rows_kept_only_if_still_to_do(
    scenario: Path,
) -> None:
    source = tasks._Source(scenario)
    a, b, c = (
        source.job(run_id(v), v, keep=False)
        for v in expand({"control.Lambda": [2.0, 3.0, 5.0]}, {}, 0, 0)
    )
    assert all(isinstance(t, tasks._Task) for t in (a, b, c))
    engine = engines.PoolEngine(1, 3, "spawn")
    try:
        engine.start(None)
        engine.send_ahead(iter([a, b]))  # one worker: only the first is sent
        assert engine.sent_ahead == {a.run_id}
        rows: list[dict] = []
        lost: list[str] = []
        # a's variant is no longer to do (say, finished by another sweep): its row is dropped
        assert engine.keep_ahead({b.run_id, c.run_id}) == frozenset()
        engine.run(iter([(c.run_id, c)]), 1, lambda row, blob: rows.append(row), lost)
        assert [r["run_id"] for r in rows] == [c.run_id] and lost == []
    finally:
        engine.close()
    engine = engines.PoolEngine(1, 3, "spawn")
    try:
        engine.start(None)
        engine.send_ahead(iter([a]))
        assert engine.keep_ahead({a.run_id, b.run_id}) == {a.run_id}
        rows = []
        engine.run(iter([(b.run_id, b)]), 1, lambda row, blob: rows.append(row), lost)
    finally:
        engine.close()
    # each once, with the row it gives when run alone
    assert sorted(r["run_id"] for r in rows) == sorted([a.run_id, b.run_id])
    alone = tasks._execute(a)[0]
    drop = set(TIMING_COLUMNS)
    kept = next(r for r in rows if r["run_id"] == a.run_id)
    assert {k: v for k, v in kept.items() if k not in drop} == {
        k: v for k, v in alone.items() if k not in drop
    }


def test_a_sweep_runs_each_variant_once_with_the_first_sent_ahead(
    tmp_path: Path, scenario: Path
) -> None:
    todo = expand({"control.Lambda": [2.0, 3.0, 5.0, 8.0]}, {}, 0, 0)
    seen: list[str] = []
    path = run_sweep(
        scenario, todo, workers=2, out_dir=tmp_path / "o", progress=False,
        start_method="spawn", on_row=lambda row: seen.append(row["run_id"]),
    )  # fmt: skip
    assert sorted(seen) == sorted(run_id(v) for v in todo)  # every row once, none twice
    _, rows = read_sweep_csv(path)
    assert [r["run_id"] for r in rows] == [run_id(v) for v in todo]
    assert not list((tmp_path / "o").glob(".scratch-*"))  # the runs' folders removed


def test_a_bad_start_method_is_refused(tmp_path: Path, scenario: Path) -> None:
    with pytest.raises(BadInputError, match="start_method"):
        run_sweep(scenario, [{}], out_dir=tmp_path / "o", start_method="thread")  # type: ignore[arg-type]


def test_forked_workers_run_openblas_on_one_thread() -> None:
    """The thread variables do not reach a library loaded before the fork: a forked worker
    sets every loaded OpenBLAS to one thread itself (read back through OpenBLAS's getter)."""
    code = (
        "import ctypes, numpy\n"
        "from hybrid_force.studies.engines import _one_blas_thread\n"
        "paths = {l.split()[-1] for l in open('/proc/self/maps') if 'openblas' in l.lower()}\n"
        "getters = []\n"
        "for p in paths:\n"
        "    lib = ctypes.CDLL(p)\n"
        "    for n in ('scipy_openblas_get_num_threads64_', 'scipy_openblas_get_num_threads',\n"
        "              'openblas_get_num_threads64_', 'openblas_get_num_threads'):\n"
        "        if hasattr(lib, n):\n"
        "            getters.append(getattr(lib, n)); break\n"
        "_one_blas_thread()\n"
        "print(len(getters), [g() for g in getters])\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    env["PYTHONPATH"] = str(REPO)
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    ).stdout.split(maxsplit=1)
    if out[0] == "0" or not sys.platform.startswith("linux"):
        pytest.skip("no OpenBLAS with the usual entry points here")
    assert out[1].strip() == str([1] * int(out[0]))


def test_the_parts_of_a_sweep_live_in_their_own_modules_of_at_most_600_lines() -> None:
    for name in sweep.__all__:
        assert getattr(sweep, name) is not None, name
    for module in (engines, sweep, table, tasks, variants):
        assert module.__file__ is not None
        assert len(Path(module.__file__).read_text().splitlines()) <= 600, module.__name__


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_run_stopped_by_a_signal_stops_the_sweep_with_that_signal(
    scenario: Path, monkeypatch: pytest.MonkeyPatch, sig: str
) -> None:
    """In the sweep's own process (the warm-up before a fork, run_one), a run interrupted by
    SIGTERM raises Terminated (exit status 143), by Ctrl-C a KeyboardInterrupt (130)."""
    from hybrid_force._signals import Terminated
    from hybrid_force.errors import RunFailedError

    def interrupted(*args: object, **kwargs: object) -> None:
        raise RunFailedError("stopped", signal=sig, reason="interrupted")

    monkeypatch.setattr("hybrid_force.studies.tasks.simulate", interrupted)
    task = tasks._Source(scenario).job(run_id({}), {}, keep=False)
    assert isinstance(task, tasks._Task)
    with pytest.raises(KeyboardInterrupt) as caught:
        tasks.warm_up(task)
    assert isinstance(caught.value, Terminated) == (sig == "SIGTERM")

"""Parameter sweeps and Monte-Carlo studies of a scenario, resumable, on a process pool or Dask.

A sweep runs one scenario file many times with different overrides (``"table.key"`` → value,
the same keys as ``hybrid-force run --set``) and writes one row per run to ``DIR/sweep.csv``.

* :func:`expand` turns a grid (Cartesian product) and uniform random samples into variants,
  each a dict of overrides with a stable run id (a hash of its sorted parameters).
* :func:`run_one` runs one variant and returns a flat row; it never raises.
* :func:`run_sweep` runs the variants that ``DIR/sweep.csv`` does not hold yet, on local worker
  processes (forked from this process once it has loaded the compiled kernels, or spawned) or
  on a Dask distributed cluster, and rewrites ``sweep.csv`` atomically as rows come back.
* :func:`add_sweep_arguments` / :func:`sweep_command`: the ``hybrid-force sweep`` command.

The parts live in their own modules, and their names stay importable from this one:
:mod:`~hybrid_force.studies.variants` (grid, samples, run ids),
:mod:`~hybrid_force.studies.table` (columns, ``sweep.csv``), :mod:`~hybrid_force.studies.tasks`
(one run in a worker), :mod:`~hybrid_force.studies.engines` (process pool, Dask; warm-up,
chunks), :mod:`~hybrid_force.studies.progress` (the progress line),
:mod:`~hybrid_force.studies.command_line` (the engine options, a command stopped by a signal;
shared with ``hybrid-force compare``).

Row statuses: ``"ok"``; ``"diverged"`` (the simulation failed at run time; the metrics are those
of the partial run); ``"failed"`` (the run failed otherwise: it lost contact, or its desired
path became singular; the error column starts with the reason); ``"bad input"`` (the variant
is not a valid scenario, e.g. a negative gain); ``"error"`` (an unexpected exception: a bug,
not a verdict on the variant). Rows with status ``"error"`` are run again when the sweep is
resumed; all others are final.

Resuming: run again with the same arguments and ``--out DIR``. Rows already in
``DIR/sweep.csv`` (matched by run id) are kept and not run again; ``DIR/sweep.json`` records
the arguments, the hybrid_force version and the sha256 of the scenario file and of every file
its rows read (model files of ``robot.model`` and ``control.model``, xacro includes). A sweep
refuses to resume (BadInputError, exit status 2, naming the file) in a DIR whose rows were made
from another content of any of them or by another version
(:mod:`~hybrid_force.studies.resume`): a table never mixes two worlds.

Workers get data, never paths: this process reads the scenario file (with each variant's
overrides) and the model files its ``robot.model`` and ``control.model`` name (resolved
against the scenario's folder, as ``hybrid-force run`` does, whatever the working directory
and ``--out``), and sends them with the task: a URDF's or an MJCF file's bytes, or for a
xacro file the URDF text it expands to here (with ``robot.xacro_args`` and
``robot.package_dirs``), so workers need neither xacro nor the files it includes. Meshes
are never sent: simulating reads none (the package folders are checked here and recorded in
the kept results' meta for the replay). A worker writes the model files into a private
temporary folder (an absolute path), builds the scenario from the data, and sends back
the row and, with ``keep_results``, the saved result's bytes, which this process writes
into ``DIR/results/``. So a Dask worker on another machine or in another folder needs only
hybrid_force installed. Local workers die with the sweep (even on ``kill -9``), and SIGTERM
stops them, keeps the finished rows and exits 143. At most :data:`MAX_RUNS` variants.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from hybrid_force._extras import require as require_extra
from hybrid_force.errors import BadInputError, RunFailedError
from hybrid_force.run_output import locked_folder
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.studies.command_line import add_engine_arguments, run_stoppable

# The parts of a sweep live in their own modules; their public names (and the private ones
# earlier versions of this module held) stay importable from here.
from hybrid_force.studies.engines import (
    DaskEngine,
    PoolEngine,
    StartMethod,
)
from hybrid_force.studies.engines import (
    _watch_parent as _watch_parent,
)
from hybrid_force.studies.progress import Progress, ProgressReporter, format_duration
from hybrid_force.studies.resume import _check_same_inputs, _version
from hybrid_force.studies.resume import _check_same_scenario as _check_same_scenario
from hybrid_force.studies.table import (
    _CSV_NAME,
    _JSON_NAME,
    STATUSES,
    _file_sha256,
    _Table,
    _write_atomic,
    read_sweep_csv,
)
from hybrid_force.studies.tasks import _execute as _execute
from hybrid_force.studies.tasks import _one_line as _one_line
from hybrid_force.studies.tasks import _save_blob, _Source, _Task
from hybrid_force.studies.variants import (
    MAX_RUNS,
    expand,
    parse_grid,
    parse_random,
    run_id,
)

__all__ = ["add_sweep_arguments", "add_trust_xacro_argument", "run_sweep", "sweep_command"]


def run_sweep(
    scenario_path: str | os.PathLike[str],
    variants: Sequence[Mapping[str, Any]],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    out_dir: str | os.PathLike[str],
    keep_results: bool = False,
    progress: Progress = True,
    arguments: Mapping[str, Any] | None = None,
    on_row: Callable[[dict[str, Any]], None] | None = None,
    check: Callable[[], None] | None = None,
    start_method: StartMethod = "auto",
    label: str = "sweep",
    trust_xacro: bool = False,
) -> Path:
    """Run every variant not yet in ``out_dir/sweep.csv``; return the CSV path.

    Args:
        scenario_path: the scenario TOML file, read by this process only (workers, which
            need hybrid_force installed, get its data and the content of the model files
            its robot.model and control.model name, resolved against its folder).
        variants: dicts of overrides, e.g. from :func:`expand`; run ids must be distinct.
        workers: local worker processes (default ``os.cpu_count()``), or the number of workers
            of a ``"local"`` Dask cluster (default 2).
        scheduler: None: a local process pool (see ``start_method``);
            ``"local"``: a Dask LocalCluster (processes, one thread each) started and closed
            here; anything else: the address of a running Dask scheduler ("tcp://host:8786").
        out_dir: output directory (created). Holds sweep.csv, sweep.json, with keep_results
            results/<run_id>.npz and, while the sweep runs, .scratch-<pid>-*/ (the local
            workers' temporary folders).
        keep_results: save every run's Result (written here, by this process, atomically).
        progress: text progress bar with ETA on stderr, when stderr is a terminal (True), never
            (False) or always ("force").
        arguments: extra JSON-able description of the sweep stored in sweep.json.
        on_row: called in this process with every new row (after it is written).
        check: called once the workers are starting (they load their kernels and start the
            first variants meanwhile, one each), before sweep.json and sweep.csv are written:
            an exception it raises stops the sweep and its workers, and no row is written
            (e.g. the command's validation of the scenario file, which is bad input).
        start_method: how the process pool's workers start: "fork" (this process loads the
            kernels once and forks ready workers), "spawn" (fresh interpreters, each loading
            them), or "auto": fork on Linux when this process runs no other Python thread,
            else spawn. The rows are the same either way.
        label: the word before the progress line (e.g. "compare" for a comparison of laws).
        trust_xacro: let xacro evaluate a xacro model's expressions as Python, as
            ``robot.xacro_trust = true`` does (``--trust-xacro``); the model is expanded by
            this process only.

    Returns:
        ``out_dir/sweep.csv``: one row per variant in variant order (plus rows of earlier
        sweeps in the same directory whose run ids are not among the variants, at the end).

    The CSV is rewritten atomically (temp file + os.replace) after every finished run (when the
    sweep has so many rows that rewriting costs more than 10 % of the time, at most that often,
    and always at the end), so an interruption never leaves it half-written; a rerun skips the
    run ids it holds (except rows with status "error").

    Raises:
        MissingExtraError: a ``scheduler`` without dask installed (the ``dask`` extra).
        BadInputError: duplicate variants, more than :data:`MAX_RUNS` of them, a bad out_dir, a
            DIR made from another scenario file, model file or hybrid_force version, a
            scenario or model file changed during the sweep, a result that cannot be saved.
        ScenarioError: the scenario file cannot be read or is not TOML.
        RunFailedError: runs were lost (a worker process died); the finished rows are saved
            and rerunning the same sweep runs the missing ones.

    Any exception (Ctrl-C included) kills the local workers before it propagates, and
    ``sweep.csv`` holds every row finished until then.
    """
    scenario = Path(scenario_path)
    if not scenario.is_file():
        raise BadInputError(f"scenario file '{scenario}' does not exist")
    if hasattr(variants, "__len__") and len(variants) > MAX_RUNS:
        raise BadInputError(
            f"the sweep has {len(variants)} variants; at most {MAX_RUNS} (MAX_RUNS) are allowed: "
            "split it into several sweeps, each with its own --out"
        )
    variants = [dict(v) for v in variants]
    ids = [run_id(v) for v in variants]
    if len(set(ids)) != len(ids):
        dup = next(v for v, rid in zip(variants, ids, strict=True) if ids.count(rid) > 1)
        raise BadInputError(f"the variant {dup!r} appears more than once")
    if workers is not None and (isinstance(workers, bool) or int(workers) < 1):
        raise BadInputError(f"--workers must be a positive integer, got {workers!r}")
    if scheduler is not None:  # before anything is written
        require_extra("dask", "the Dask engine (--scheduler)")
    # read here, never by a worker; ScenarioError if unreadable
    source = _Source(scenario, trust_xacro=trust_xacro)
    out = Path(out_dir)
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInputError(f"cannot create output directory '{out}': {exc}") from exc
    keep_dir = (out / "results").resolve() if keep_results else None
    # The workers start first, and load their kernels while this process goes on; before the
    # folder is locked, so that no forked worker holds a copy of the lock. Which variants are
    # left is read here without the lock (it only sizes the pool) and again under it.
    guess = [(rid, v) for rid, v in zip(ids, variants, strict=True)]
    with contextlib.suppress(BadInputError):
        if (out / _CSV_NAME).exists():
            done = _Table(out / _CSV_NAME, variants)
            guess = [(rid, v) for rid, v in guess if not done.finished(rid)]
    engine: PoolEngine | DaskEngine | None = None
    failed = True
    scratch: str | None = None
    try:
        # the local workers' temporary folders go in DIR/.scratch-<pid>-*: removed at the end,
        # even when the sweep is interrupted (SIGTERM, Ctrl-C); after a kill -9, by the next one
        if scheduler in (None, "local"):
            scratch = source.scratch = _scratch_dir(out)
        if guess:
            engine = PoolEngine(workers, len(guess), start_method) if scheduler is None else (
                DaskEngine(workers, scheduler)
            )  # fmt: skip
            engine.start(_warm_task(source, guess, keep=keep_dir is not None))
            # the first runs start while the scenario is checked below (their rows wait)
            engine.send_ahead(_first_tasks(source, guess, keep=keep_dir is not None))
        # one command at a time writes into a folder: a second sweep (or a run) is refused
        with locked_folder(out, "--out"):
            sha = _file_sha256(scenario)
            source.check_unchanged()  # the tasks made so far are of the version hashed
            _check_same_scenario(out, scenario, sha)
            kept_inputs = _check_same_inputs(out, source)
            table = _Table(out / _CSV_NAME, variants)
            if check is not None:
                check()
            todo = [
                (rid, v) for rid, v in zip(ids, variants, strict=True) if not table.finished(rid)
            ]
            info = {
                "scenario": str(scenario.resolve()),
                "scenario_sha256": sha,
                "hybrid_force_version": _version(),
                "inputs": {},
                "n_variants": len(variants),
                "workers": workers,
                "scheduler": scheduler,
                "keep_results": keep_results,
                "columns": table.columns,
                "arguments": dict(arguments or {}),
                "variants": [{"run_id": rid, **v} for rid, v in zip(ids, variants, strict=True)],
            }

            def write_info() -> None:
                # every file a row in the table read, its sha256 (those of earlier sweeps in
                # this folder kept): written before the rows that read them
                info["inputs"] = {**kept_inputs, **source.inputs}
                _write_atomic(out / _JSON_NAME, json.dumps(info, indent=1, default=str) + "\n")

            write_info()
            table.write()
            if todo and engine is None:
                # the folder changed since the guess: workers now, spawned (a fork would copy
                # the lock)
                engine = PoolEngine(workers, len(todo), "spawn") if scheduler is None else (
                    DaskEngine(workers, scheduler)
                )  # fmt: skip
                engine.start(None)
            lost = _run_todo(
                engine, source, todo, table, keep_dir, progress, on_row, label, write_info
            )
            failed = False
    finally:
        if engine is not None:
            engine.close(failed)
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)
        if failed and created:  # refused before anything was written: leave no empty folder
            with contextlib.suppress(OSError):
                out.rmdir()
    if lost:
        missing = sum(1 for rid in ids if rid not in table.rows)
        raise RunFailedError(
            f"{len(lost)} run(s) were lost ({lost[0]}); {missing} variant(s) have no row; the "
            f"{len(table.rows)} finished rows are in '{table.path}'; run the same sweep again "
            "to run the missing ones"
        )
    return table.path


def _run_todo(
    engine: PoolEngine | DaskEngine | None,
    source: _Source,
    todo: Sequence[tuple[str, Mapping[str, Any]]],
    table: _Table,
    keep_dir: Path | None,
    progress: Progress,
    on_row: Callable[[dict[str, Any]], None] | None,
    label: str = "sweep",
    write_info: Callable[[], None] | None = None,
) -> list[str]:
    """Run the variants left on the engine, each row written as it comes back; the lost runs.

    The CSV is rewritten at the end, even after an exception (then the engine is stopped by
    the caller). ``write_info`` rewrites sweep.json: called before a row is added when the
    tasks made since read new files, so that sweep.json names every file a row read.
    """
    recorded = len(source.inputs)
    report = ProgressReporter(
        len(table.ids), done=len(table.ids) - len(todo), progress=progress, label=label
    )
    lost: list[str] = []

    def finish(row: dict[str, Any], blob: bytes | None) -> None:
        nonlocal recorded
        if write_info is not None and len(source.inputs) != recorded:
            recorded = len(source.inputs)
            write_info()
        if blob is not None and keep_dir is not None:
            try:
                _save_blob(keep_dir, str(row["run_id"]), blob)
            except OSError as exc:
                raise BadInputError(f"cannot save a result into '{keep_dir}': {exc}") from exc
        table.add(row)
        table.write(force=False)
        report.advance(ok=row.get("status") == "ok")
        if on_row is not None:
            on_row(row)

    if engine is None or not todo:
        report.draw()
        report.close()
        return lost
    ahead = engine.keep_ahead({rid for rid, _ in todo})
    rest = [(rid, v) for rid, v in todo if rid not in ahead]
    try:
        with report:
            engine.run(_jobs(source, rest, keep_dir), len(rest), finish, lost)
    finally:
        table.write()
    return lost


def _warm_task(
    source: _Source, todo: Sequence[tuple[str, Mapping[str, Any]]], *, keep: bool
) -> _Task | None:
    """The task the workers warm up on: the first of the first few variants that is one."""
    return next(_first_tasks(source, todo, keep=keep), None)


def _first_tasks(
    source: _Source, todo: Sequence[tuple[str, Mapping[str, Any]]], *, keep: bool
) -> Iterator[_Task]:
    """The tasks of the first few variants (8 at most; bad input left out), made as asked."""
    for rid, params in todo[:8]:
        job = source.job(rid, params, keep=keep)
        if isinstance(job, _Task):
            yield job


def _jobs(
    source: _Source, todo: Sequence[tuple[str, Mapping[str, Any]]], keep_dir: Path | None
) -> Iterator[tuple[str, _Task | dict[str, Any]]]:
    """The variants' tasks (or bad-input rows), each made when the engine asks for it."""
    for rid, params in todo:
        yield rid, source.job(rid, params, keep=keep_dir is not None)


def _scratch_dir(out: Path) -> str:
    """A new folder ``out/.scratch-<pid>-<random>``, after removing those of dead sweeps."""
    for old in out.glob(".scratch-*-*"):
        pid_text = old.name.split("-")[1]
        if not pid_text.isdigit() or int(pid_text) == os.getpid():
            continue
        try:
            os.kill(int(pid_text), 0)
        except ProcessLookupError:
            shutil.rmtree(old, ignore_errors=True)  # its sweep was killed
        except OSError:
            pass  # alive (another user's process): leave it
    # absolute: a worker's model paths are written into its scenario, whatever its cwd
    return tempfile.mkdtemp(prefix=f".scratch-{os.getpid()}-", dir=out.resolve())


# ----------------------------------------------------------------------------- command line
def add_sweep_arguments(parser: argparse.ArgumentParser) -> None:
    """Define the options of ``hybrid-force sweep`` on the given (sub)parser."""
    parser.epilog = _EXIT_STATUS_HELP
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.add_argument("scenario", help="scenario TOML file")
    parser.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="TABLE.KEY=V1,V2,...",
        help="swept values of a scenario key (TOML values; repeat for a Cartesian product)",
    )
    parser.add_argument(
        "--random",
        action="append",
        default=[],
        metavar="TABLE.KEY=LO:HI",
        help="uniform random values in [LO, HI) (repeatable; needs --samples)",
    )
    parser.add_argument(
        "--samples", type=int, default=None, metavar="N", help="random samples per grid point"
    )
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="random seed (0)")
    parser.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="output directory (default runs/<scenario stem>_sweep); rerun to resume",
    )
    parser.add_argument(
        "--keep-results",
        action="store_true",
        help="save every run's result to DIR/results/<run_id>.npz",
    )
    add_trust_xacro_argument(parser)
    add_engine_arguments(parser)


def add_trust_xacro_argument(parser: argparse.ArgumentParser) -> None:
    """Define ``--trust-xacro`` (as ``robot.xacro_trust = true`` for every run): shared by
    ``sweep`` and ``compare``."""
    parser.add_argument(
        "--trust-xacro",
        action="store_true",
        help="let xacro run the .xacro model's Python expressions (as robot.xacro_trust = "
        "true; trusted files only, docs/robots.md)",
    )


_EXIT_STATUS_HELP = f"""\
exit status:
  0    every variant has a row and at least one run is ok; runs that diverged or are
       bad input are reported on stderr ("warning: N of M runs are not ok ...")
  1    no run is ok (all diverged or bad input), or some runs hit an unexpected error
       (status "error", run again on resume), or runs were lost (a worker died)
  2    bad input: the scenario file, an option, or more than {MAX_RUNS} runs
  130  Ctrl-C;  143  SIGTERM (the workers are stopped, the finished rows are kept)
With 1 (lost or error runs), 130 and 143, running the same command again resumes the sweep.
"""


def sweep_command(args: argparse.Namespace) -> int:
    """``hybrid-force sweep``; returns the exit status.

    0: every variant has a row and at least one is ok (rows not ok are counted in a warning on
    stderr); 1: no run is ok, or rows with status "error", or lost runs (a worker died);
    2: bad input (raised as :class:`BadInputError` / BadInputError, e.g. more than
    :data:`MAX_RUNS` variants); 130: Ctrl-C; 143: SIGTERM. With 1, 130 and 143 the finished
    rows are saved and rerunning the same command completes the sweep.
    """

    scenario = Path(args.scenario)
    if not scenario.is_file():
        raise BadInputError(f"scenario file '{scenario}' does not exist")
    grid = parse_grid(args.grid)
    random = parse_random(args.random)
    if random and args.samples is None:
        raise BadInputError("--random needs --samples N (random samples per grid point)")
    if args.samples is not None and not random:
        raise BadInputError("--samples needs at least one --random table.key=lo:hi")
    if args.workers is not None and args.workers < 1:
        raise BadInputError(f"--workers must be a positive integer, got {args.workers}")
    variants = expand(grid, random, args.samples or 0, args.seed)
    fixed = {key: values[0] for key, values in grid.items() if len(values) == 1}
    if args.trust_xacro:
        fixed["robot.xacro_trust"] = True  # for the check; the runs get it from trust_xacro
    out = Path(args.out) if args.out else Path("runs") / f"{scenario.stem}_sweep"
    arguments = {
        "grid": grid,
        "random": {k: list(v) for k, v in random.items()},
        "samples": args.samples,
        "seed": args.seed,
    }
    t0 = time.monotonic()
    outcome, n_new = run_stoppable(
        lambda on_row: run_sweep(
            scenario,
            variants,
            workers=args.workers,
            scheduler=args.scheduler,
            out_dir=out,
            keep_results=args.keep_results,
            progress=args.progress,
            start_method=args.start_method,
            arguments=arguments,
            on_row=on_row,
            # a broken scenario file is bad input, before any run; checked as every variant
            # sees it (with the keys the grid fixes to one value, e.g. sim.duration), while
            # the workers start
            check=lambda: load_scenario(scenario, fixed),
            trust_xacro=args.trust_xacro,
        ),
        out / _CSV_NAME,
    )
    if isinstance(outcome, int):
        return outcome
    path = outcome
    counts = _print_summary(path, variants, n_new, time.monotonic() - t0)
    total = sum(counts.values())
    not_ok = total - counts["ok"]
    detail = ", ".join(f"{n} {s}" for s, n in counts.items() if n and s != "ok")
    if counts["error"]:
        print(
            f"error: {counts['error']} of {total} runs hit an unexpected error (status "
            f"'error': a bug, not a verdict on the variant); see the error column of '{path}'; "
            "running the same command again retries them",
            file=sys.stderr,
        )
        return 1
    if counts["ok"] == 0:
        print(f"error: no run is ok ({detail}); see the error column of '{path}'", file=sys.stderr)
        return 1
    if not_ok:
        print(
            f"warning: {not_ok} of {total} runs are not ok ({detail}); see the status and error "
            f"columns of '{path}'",
            file=sys.stderr,
        )
    return 0


def _print_summary(
    path: Path, variants: Sequence[Mapping[str, Any]], n_new: int, wall: float
) -> dict[str, int]:
    """Print the sweep's summary on stdout; return the number of its rows of each status."""
    _, rows = read_sweep_csv(path)
    ids = {run_id(v) for v in variants}
    mine = [r for r in rows if r["run_id"] in ids]
    counts = {s: sum(r["status"] == s for r in mine) for s in STATUSES}
    parts = ", ".join(f"{n} {s}" for s, n in counts.items() if n)
    print(
        f"sweep: {len(mine)} runs ({parts}); {n_new} new in {format_duration(wall)}, "
        f"{len(mine) - n_new} kept from before"
    )
    failed = [r for r in mine if r["status"] != "ok"]
    if failed:
        print(f"first failure: {failed[0]['run_id']} {failed[0]['status']}: {failed[0]['error']}")
    ok = [r for r in mine if r["status"] == "ok" and r["final_position_error"]]
    if ok:
        best = min(ok, key=lambda r: float(r["final_position_error"]))
        params = ", ".join(f"{k}={best[k]}" for k in variants[0] if k in best)
        print(
            f"best final position error: {float(best['final_position_error']):.3g} m "
            f"at {params or 'the scenario as is'}"
        )
    print(f"wrote {path}")
    return counts

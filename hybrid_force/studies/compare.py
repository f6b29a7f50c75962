"""Control laws compared on one scenario: ``hybrid-force compare``.

The scenario runs once per law, with the same plant, sensor, path and seed: only
``control.law`` differs. The runs go through the sweep's runner (:func:`~hybrid_force.studies.
sweep.run_sweep`: a sweep over ``control.law``, on the same process pool or Dask engines, warm
workers, atomic writes and progress line), into ``DIR/runs/`` (its ``sweep.csv``,
``sweep.json`` and each law's result ``results/<run_id>.npz``). From the results, this module
writes

* ``DIR/compare.csv``: one row per law (:data:`COMPARE_COLUMNS`; the numbers are
  :class:`~hybrid_force.metrics.TrackingMetrics`, defined in docs/compare.md), atomically;
* ``DIR/compare_force_error.png`` and ``DIR/compare_path_error.png``: every law's force error
  and path error against time, one plot each (:mod:`hybrid_force.viz.compare_plots`).

A law whose run fails (diverges, loses contact, is bad input) is a row saying so (its status and
error), with empty metric cells: a partial run's numbers are not comparable with full ones. Its
curves up to the failure are drawn. Running the same command again reuses the finished runs
(the sweep's resume) and rewrites the table and the figures.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from hybrid_force._extras import available as extra_available
from hybrid_force._extras import require as require_extra
from hybrid_force.control.laws.base import law_names, law_spec
from hybrid_force.errors import BadInputError, did_you_mean
from hybrid_force.metrics import compute_tracking_metrics, force_error, path_error
from hybrid_force.result import Result
from hybrid_force.result_summary import REMOVAL_KEYS
from hybrid_force.run_output import locked_folder
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.scenario.overrides import parse_override
from hybrid_force.studies.command_line import add_engine_arguments, run_stoppable
from hybrid_force.studies.engines import StartMethod
from hybrid_force.studies.progress import Progress, format_duration
from hybrid_force.studies.sweep import add_trust_xacro_argument, run_sweep
from hybrid_force.studies.table import (
    _CSV_NAME,
    _cell,
    _csv_text,
    _write_atomic,
    read_sweep_csv,
    read_table,
)
from hybrid_force.studies.variants import run_id

__all__ = [
    "COMPARE_COLUMNS",
    "METRIC_UNITS",
    "add_compare_arguments",
    "check_laws",
    "compare_command",
    "compare_row",
    "run_compare",
]

#: The file of the table, in DIR.
COMPARE_CSV = "compare.csv"
#: The sweep's folder inside DIR (its table, its arguments, the laws' results).
RUNS_DIR = "runs"

#: The metric columns of ``compare.csv`` (attributes of TrackingMetrics) with their units.
METRIC_UNITS: dict[str, str] = {
    "force_error_rms_settled": "N",
    "force_error_max_settled": "N",
    "impact_force_peak": "N",
    "path_error_rms_settled": "m",
    "path_error_max_settled": "m",
    "out_of_contact_fraction": "1",
    "time_to_settle": "s",
    "torque_max": "N·m",
}

COMPARE_COLUMNS: tuple[str, ...] = (
    "law",
    "status",
    "error",
    *METRIC_UNITS,
    *REMOVAL_KEYS,
    "wall_time",
    "result",
)
"""Columns of ``compare.csv``: the law, the run's status (the sweep's: ok, diverged, failed,
bad input, error) and error message, the metrics (:data:`METRIC_UNITS`; empty unless the status
is ok), the removal metrics of a scenario with ``[removal]``
(:data:`~hybrid_force.result_summary.REMOVAL_KEYS`, docs/removal.md; empty without it), the
run's wall time [s] and its result file (relative to DIR)."""


def check_laws(laws: Sequence[str] | None) -> tuple[str, ...]:
    """The laws to compare: ``laws`` checked against the registry, or every registered law.

    Raises:
        BadInputError: (key ``--laws``) no law, or a law that is unknown or given twice, naming
            it and the valid names.
    """

    valid = law_names()
    if laws is None:
        return valid
    names = tuple(laws)
    if not names:
        raise BadInputError(
            f"--laws lists no law; valid: {', '.join(valid)}", key="--laws", value=names
        )
    seen: set[str] = set()
    for name in names:
        if name not in valid:
            raise BadInputError(
                f"--laws: {name!r} is not a known law{did_you_mean(name, valid)}; valid: "
                f"{', '.join(valid)}",
                key="--laws",
                value=name,
            )
        if name in seen:
            raise BadInputError(
                f"--laws lists {name!r} twice; valid: {', '.join(valid)}",
                key="--laws",
                value=name,
            )
        seen.add(name)
    return names


def _variants(laws: Sequence[str], overrides: Mapping[str, Any]) -> list[dict[str, Any]]:
    """One variant per law: ``control.law`` and the overrides that act with that law.

    A law's own settings (``control.<law>.<key>``) go to that law's run only, and the
    paper's gains (``control.Kd``, ``kd_rate``, ``Lambda``, ``beta``, ``gamma``) to the laws
    that read them (``LawSpec.gains``; Λ also to every supervised run, as the approach rate's
    default): the loader refuses a key without effect (issue 27), and ``--set`` is for
    every law.
    """

    if "control.law" in overrides:
        raise BadInputError(
            "--set control.law is not allowed: the laws are chosen with --laws",
            key="control.law",
            value=overrides["control.law"],
        )
    tables = set(law_names())
    paper = ("Kd", "kd_rate", "Lambda", "beta", "gamma")

    def acts(law: str, key: str) -> bool:
        parts = key.split(".")
        if len(parts) >= 2 and parts[0] == "control" and parts[1] in tables:
            return parts[1] == law
        if len(parts) == 2 and parts[0] == "control" and parts[1] in paper:
            return parts[1] in law_spec(law).gains or parts[1] == "Lambda"
        return True

    return [
        {"control.law": law, **{k: v for k, v in overrides.items() if acts(law, k)}} for law in laws
    ]


def compare_row(
    law: str,
    run: Mapping[str, str],
    result: Any,
    surfaces: Sequence[Any],
    path_errors: Any = None,
) -> dict[str, Any]:
    """The ``compare.csv`` row of one law.

    Args:
        law: the law's name.
        run: its row of the sweep's table (strings; status, error, wall_time).
        result: its :class:`~hybrid_force.result.Result`, or None when the run left none.
        surfaces: the scenario's surfaces (their normals define the path error).
        path_errors: (N,) the result's path error [m] if already computed
            (:func:`~hybrid_force.metrics.path_error`).

    Returns:
        A dict with the keys of :data:`COMPARE_COLUMNS` but ``result``; metric values are
        None unless the status is "ok".
    """

    row: dict[str, Any] = {"law": law, "status": run["status"], "error": run["error"] or None}
    row.update(dict.fromkeys(METRIC_UNITS))
    row.update(dict.fromkeys(REMOVAL_KEYS))
    wall = run.get("wall_time") or ""
    row["wall_time"] = float(wall) if wall else None
    if row["status"] == "ok":
        if result is None:
            row["status"] = "error"
            row["error"] = "its result file is missing; delete DIR/runs to run it again"
        else:
            metrics = compute_tracking_metrics(result, surfaces, path_errors=path_errors).to_dict()
            row.update({name: metrics[name] for name in METRIC_UNITS})
            removal = result.meta.get("removal")
            if isinstance(removal, dict):  # a scenario with [removal]
                row.update({name: removal.get(name) for name in REMOVAL_KEYS})
    return row


def run_compare(
    scenario_path: str | os.PathLike[str],
    laws: Sequence[str] | None = None,
    *,
    out_dir: str | os.PathLike[str],
    overrides: Mapping[str, Any] | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Progress = True,
    start_method: StartMethod = "auto",
    on_row: Callable[[dict[str, Any]], None] | None = None,
    figures: bool = True,
    trust_xacro: bool = False,
) -> Path:
    """Run the scenario once per law and write ``out_dir/compare.csv`` (and the figures).

    Args:
        scenario_path: the scenario TOML file.
        laws: names of registered laws (default: all, in registry order); the rows follow
            this order.
        out_dir: the output folder (DIR; the runs go into DIR/runs).
        overrides: ``"table.key"`` → value applied to every run (not ``control.law``).
        workers, scheduler, progress, start_method: as for
            :func:`~hybrid_force.studies.sweep.run_sweep`.
        on_row: called with every new row of the sweep's table (a finished run).
        figures: also draw the overlay figures (needs matplotlib, the ``plots`` extra).
        trust_xacro: as for :func:`~hybrid_force.studies.sweep.run_sweep`.

    Returns:
        The path of ``compare.csv``.

    Raises:
        MissingExtraError: ``figures`` without matplotlib (checked before any run).
        BadInputError: a bad law list, ``control.law`` among the overrides, or anything
            :func:`~hybrid_force.studies.sweep.run_sweep` refuses; ScenarioError: the scenario
            file (checked as every run sees it, before any run).
        RunFailedError: runs were lost (a worker died); rerunning resumes.
    """
    from hybrid_force.viz.compare_plots import LawCurve, plot_comparison

    if figures:
        require_extra("plots", "the overlay figures")
    names = check_laws(laws)
    fixed = dict(overrides or {})
    variants = _variants(names, fixed)
    checked = {**variants[0], **({"robot.xacro_trust": True} if trust_xacro else {})}
    scenario = Path(scenario_path)
    out = Path(out_dir)
    created = not out.exists()
    loaded: list[Any] = []
    try:
        table = run_sweep(
            scenario,
            variants,
            workers=workers,
            scheduler=scheduler,
            out_dir=out / RUNS_DIR,
            keep_results=True,
            progress=progress,
            arguments={"compare": {"laws": list(names), "set": fixed}},
            on_row=on_row,
            # bad input before any run, as the runs see it (the first law stands for all:
            # the surfaces, path and plant do not depend on the law)
            check=lambda: loaded.append(load_scenario(scenario, checked)),
            start_method=start_method,
            label="compare",
            trust_xacro=trust_xacro,
        )
    except BaseException:
        if created:  # refused before anything was written: leave no empty folder
            with contextlib.suppress(OSError):
                out.rmdir()
        raise
    surfaces = list(loaded[0].tool_surfaces)  # the tool centre p follows these: their normals at p
    _, runs = read_sweep_csv(table)
    by_id = {r["run_id"]: r for r in runs}
    rows: list[dict[str, Any]] = []
    curves: list[LawCurve] = []
    with locked_folder(out, "--out"):
        for law, variant in zip(names, variants, strict=True):
            rid = run_id(variant)
            relative = Path(RUNS_DIR, "results", f"{rid}.npz")
            result = Result.load(out / relative) if (out / relative).is_file() else None
            e_t = None if result is None else path_error(result, surfaces)
            row = compare_row(law, by_id[rid], result, surfaces, e_t)
            row["result"] = relative.as_posix() if result is not None else None
            rows.append(row)
            if figures and result is not None and e_t is not None and result.n_samples >= 2:
                curves.append(LawCurve(law, row["status"], result.t, force_error(result), e_t))
        cells = [{k: _cell(row.get(k)) for k in COMPARE_COLUMNS} for row in rows]
        _write_atomic(out / COMPARE_CSV, _csv_text(COMPARE_COLUMNS, cells))
        if curves:
            plot_comparison(curves, out, settle_time=loaded[0].sim.settle_time)
    return out / COMPARE_CSV


# ----------------------------------------------------------------------------- command line
def add_compare_arguments(parser: argparse.ArgumentParser) -> None:
    """Define the options of ``hybrid-force compare`` on the given (sub)parser."""
    parser.epilog = _EXIT_STATUS_HELP
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.add_argument("scenario", metavar="FILE", help="scenario TOML file")
    parser.add_argument(
        "--laws",
        default=None,
        metavar="LAW,LAW,...",
        help="the laws to compare, comma-separated (default: every law of 'hybrid-force laws')",
    )
    parser.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="output directory (default runs/<scenario stem>_compare); rerun to resume",
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="TABLE.KEY=VALUE",
        help="override a key of the file for every law (TOML value), e.g. --set "
        "sim.duration=5; repeatable; not control.law",
    )
    add_trust_xacro_argument(parser)
    add_engine_arguments(parser)


_EXIT_STATUS_HELP = """\
output: DIR/compare.csv (one row per law; columns and units in docs/compare.md),
  DIR/compare_force_error.png, DIR/compare_path_error.png, and DIR/runs/ (the runs: the
  sweep's table and each law's result, runs/results/<run_id>.npz).
exit status:
  0    every law has a row and at least one law's run is ok; laws whose run failed
       (diverged, lost contact, bad input) are rows saying so, listed on stderr ("warning: ...")
  1    no law's run is ok ("error: no law ran ..."), some runs hit an unexpected error
       (status "error"), or runs were lost (a worker died)
  2    bad input: the scenario file, an option, an unknown or repeated law, or DIR holds
       runs made from another version of the scenario, of a model file or of hybrid_force
  130  Ctrl-C;  143  SIGTERM (the workers are stopped, the finished runs are kept)
With 1, 130 and 143, running the same command again resumes.
"""


def compare_command(args: argparse.Namespace) -> int:
    """``hybrid-force compare``; returns the exit status (see ``_EXIT_STATUS_HELP``)."""

    scenario = Path(args.scenario)
    if not scenario.is_file():
        raise BadInputError(
            f"scenario file '{scenario}' does not exist", key="FILE", value=str(scenario)
        )
    laws = check_laws(None if args.laws is None else [s.strip() for s in args.laws.split(",")])
    overrides = dict(parse_override(text) for text in args.set)
    if args.workers is not None and args.workers < 1:
        raise BadInputError(
            f"--workers must be a positive integer, got {args.workers}",
            key="--workers",
            value=args.workers,
        )
    out = Path(args.out) if args.out else Path("runs") / f"{scenario.stem}_compare"
    # the table does not need matplotlib: without it the figures are skipped, said once
    figures = extra_available("plots")
    if not figures:
        print(
            'note: no figures: matplotlib is not installed (pip install "hybrid_force[plots]")',
            file=sys.stderr,
        )
    t0 = time.monotonic()
    outcome, n_new = run_stoppable(
        lambda on_row: run_compare(
            scenario,
            laws,
            out_dir=out,
            overrides=overrides,
            workers=args.workers,
            scheduler=args.scheduler,
            progress=args.progress,
            start_method=args.start_method,
            on_row=on_row,
            figures=figures,
            trust_xacro=args.trust_xacro,
        ),
        out / RUNS_DIR / _CSV_NAME,
    )
    if isinstance(outcome, int):
        return outcome
    _, rows = read_table(outcome, "compare")
    _print_table(rows, sys.stdout)
    wall = format_duration(time.monotonic() - t0)
    beside = " and the figures beside it" if figures else ""
    print(f"compare: {len(rows)} law(s), {n_new} new run(s) in {wall}; wrote {outcome}{beside}")
    bad = [r for r in rows if r["status"] != "ok"]
    for r in bad:
        # a run's error starts with its reason ("diverged: ..."); bad input's does not
        why = r["error"] if r["error"].startswith(r["status"]) else f"{r['status']}: {r['error']}"
        print(f"warning: law {r['law']}: {why}", file=sys.stderr)
    errors = [r["law"] for r in bad if r["status"] == "error"]
    if errors:
        print(
            f"error: the run of {', '.join(errors)} hit an unexpected error (a bug, not a "
            "verdict on the law); running the same command again retries it",
            file=sys.stderr,
        )
        return 1
    if len(bad) == len(rows):  # as a sweep with no run ok: nothing was compared
        counts = Counter(r["status"] for r in rows)
        detail = ", ".join(f"{n} {s}" for s, n in counts.items())
        print(f"error: no law ran ({detail}); see the error column of '{outcome}'", file=sys.stderr)
        return 1
    return 0


#: Short headers of the table printed on stdout.
_SHORT = {
    "force_error_rms_settled": "|e_f| rms [N]",
    "force_error_max_settled": "|e_f| max [N]",
    "impact_force_peak": "f peak [N]",
    "path_error_rms_settled": "|e_t| rms [m]",
    "path_error_max_settled": "|e_t| max [m]",
    "out_of_contact_fraction": "off contact",
    "time_to_settle": "settled at [s]",
    "torque_max": "|u| max",
    "wall_time": "wall [s]",
}


def _print_table(rows: Sequence[Mapping[str, str]], stream: Any) -> None:
    """The table for humans: one line per law, numbers with 3 significant digits."""
    lines = [["law", "status", *_SHORT.values()]]
    for r in rows:
        cells = [f"{float(r[name]):.3g}" if r[name] else "-" for name in _SHORT]
        lines.append([r["law"], r["status"], *cells])
    widths = [max(len(line[i]) for line in lines) for i in range(len(lines[0]))]
    for line in lines:
        text = "  ".join(c.ljust(w) for c, w in zip(line, widths, strict=True))
        print(text.rstrip(), file=stream)

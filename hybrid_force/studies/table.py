"""The table of a sweep: its columns, and ``sweep.csv`` read and rewritten atomically.

Rows are kept as strings (floats as ``repr``, so they read back exactly) in variant order; rows
of other sweeps in the same folder are kept at the end.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from hybrid_force._atomic import atomic_file
from hybrid_force.errors import BadInputError
from hybrid_force.result_summary import REMOVAL_KEYS
from hybrid_force.studies.variants import _canonical, run_id

__all__ = ["METRIC_COLUMNS", "STATUSES", "TIMING_COLUMNS", "read_sweep_csv", "read_table"]

STATUSES = ("ok", "diverged", "failed", "bad input", "error")
"""Possible values of the ``status`` column (see the module docstring)."""

METRIC_COLUMNS: tuple[str, ...] = (
    "t_end",
    "final_position_error",
    "position_error_max",
    "position_error_max_settled",
    "position_error_rms_settled",
    "position_error_max_axis_x",
    "position_error_max_axis_y",
    "position_error_max_axis_z",
    "final_force_error",
    "force_error_max_settled",
    "force_error_rms_settled",
    "worst_constraint_violation",
    "contact_time",
    "impact_speed",
    "impact_impulse",
    "n_impacts",
    "time_to_converge",
    "n_events",
    "n_warnings",
    "touched",
    "chatter",
    "force_settled",
    *REMOVAL_KEYS,
)
"""Deterministic metric columns: identical for the same variant on any engine.

t_end [s] is the last simulated time (the failure time of a diverged run); position errors
[m] (``*_settled``: over t ≥ sim.settle_time), force errors [N] over contact samples,
worst_constraint_violation [m], contact_time [s], impact_speed [m/s], impact_impulse [N·s],
time_to_converge [s] (first time after which ‖e‖ < 1 mm for good), n_warnings (lines in
the run's summary.json warnings: filter on ``n_warnings == 0`` for the runs that did what
they were asked), touched, chatter (releases and re-touches after the force settled) and
force_settled (the final force error within tolerance), as
:func:`hybrid_force.sim.run_checks.run_behaviour` measures them; for a scenario with
``[removal]``, the removal metrics (:data:`~hybrid_force.result_summary.REMOVAL_KEYS`:
removal_volume [m³], removal_depth_mean, _std, _min, _max [m], removal_uniformity,
removal_coverage; docs/removal.md), empty without it. Empty cell: not defined
(e.g. no contact, or the run did not start).
"""

TIMING_COLUMNS: tuple[str, ...] = ("steps_per_second", "wall_time")
"""Machine-dependent columns (steps/s of the control loop, wall time [s] of the whole run)."""

_FIXED_HEAD = ("run_id",)
_STATUS_COLUMNS = ("status", "error", "warnings")
_CSV_NAME = "sweep.csv"
_JSON_NAME = "sweep.json"


def _cell(value: Any) -> str:
    """CSV text of a value: '' for None, repr for floats (round-trips exactly), JSON for lists."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (int, str)):
        return str(value)
    return json.dumps(_canonical(value), separators=(", ", ": "))


def read_table(
    path: str | os.PathLike[str], what: str = "sweep"
) -> tuple[list[str], list[dict[str, str]]]:
    """Read a CSV table: (columns, rows as dicts of strings).

    Raises BadInputError naming ``what`` file if it is unreadable or a row has the wrong number
    of cells.
    """
    src = Path(path)
    try:
        with src.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            rows = [dict(r) for r in reader]
            columns = list(reader.fieldnames or [])
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise BadInputError(f"cannot read {what} file '{src}': {exc}") from exc
    for i, r in enumerate(rows):
        if None in r or any(v is None for v in r.values()):
            raise BadInputError(f"'{src}' row {i + 2} has the wrong number of cells")
    return columns, rows


def read_sweep_csv(path: str | os.PathLike[str]) -> tuple[list[str], list[dict[str, str]]]:
    """Read a sweep CSV: (columns, rows as dicts of strings). Raises BadInputError if unreadable."""
    columns, rows = read_table(path)
    if columns and "run_id" not in columns:
        raise BadInputError(
            f"'{path}' is not a sweep CSV (no run_id column; columns: {', '.join(columns)}); "
            "choose another --out"
        )
    return columns, rows


def _write_atomic(path: Path, text: str) -> None:
    """Write text to path atomically: temp file in the same directory, fsync, os.replace."""
    with atomic_file(path, "w", encoding="utf-8", newline="") as fh:
        fh.write(text)


def _csv_text(columns: Sequence[str], rows: Sequence[Mapping[str, str]]) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({c: r.get(c, "") for c in columns})
    return buf.getvalue()


def _file_sha256(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError as exc:
        raise BadInputError(f"cannot read scenario file '{path}': {exc}") from exc


class _Table:
    """The rows of a sweep, kept as strings, written atomically in variant order."""

    def __init__(self, path: Path, variants: Sequence[Mapping[str, Any]]) -> None:
        self.path = path
        self.ids = [run_id(v) for v in variants]
        self.index = {rid: i for i, rid in enumerate(self.ids)}
        params: list[str] = []
        for v in variants:
            params.extend(k for k in v if k not in params)
        fixed = {*_FIXED_HEAD, *_STATUS_COLUMNS, *METRIC_COLUMNS, *TIMING_COLUMNS}
        clash = [k for k in params if k in fixed]
        if clash:
            raise BadInputError(f"parameter name(s) {', '.join(clash)} clash with sweep columns")
        self.rows: dict[str, dict[str, str]] = {}
        self.foreign: list[dict[str, str]] = []  # rows of run ids not in this sweep: kept
        if path.exists():
            columns, old = read_sweep_csv(path)
            params.extend(c for c in columns if c not in fixed and c not in params)
            for r in old:
                if r["run_id"] in self.index:
                    self.rows[r["run_id"]] = r
                else:
                    self.foreign.append(r)
        self.columns = [
            *_FIXED_HEAD,
            *params,
            *_STATUS_COLUMNS,
            *METRIC_COLUMNS,
            *TIMING_COLUMNS,
        ]
        self.last_write = 0.0
        self.write_cost = 0.0

    def finished(self, rid: str) -> bool:
        row = self.rows.get(rid)
        return row is not None and row.get("status") != "error"

    def add(self, row: Mapping[str, Any]) -> None:
        self.rows[str(row["run_id"])] = {k: _cell(v) for k, v in row.items()}

    def write(self, force: bool = True) -> None:
        """Rewrite the CSV; unless forced, skip when writing would cost > 10 % of the time."""
        now = time.monotonic()
        if not force and (now - self.last_write) < 10.0 * self.write_cost:
            return
        ordered = [self.rows[rid] for rid in self.ids if rid in self.rows]
        t0 = time.monotonic()
        _write_atomic(self.path, _csv_text(self.columns, ordered + self.foreign))
        self.last_write = time.monotonic()
        self.write_cost = self.last_write - t0

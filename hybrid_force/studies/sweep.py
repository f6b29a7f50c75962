"""Parameter sweeps and Monte-Carlo studies of a scenario, resumable, on a process pool or Dask.

A sweep runs one scenario file many times with different overrides (``"table.key"`` → value,
the same keys as ``hybrid-force run --set``) and writes one row per run to ``DIR/sweep.csv``.

* :func:`expand` turns a grid (Cartesian product) and uniform random samples into variants,
  each a dict of overrides with a stable run id (a hash of its sorted parameters).
* :func:`run_one` runs one variant and returns a flat row; it never raises.
* :func:`run_sweep` runs the variants that ``DIR/sweep.csv`` does not hold yet, on local worker
  processes (:class:`concurrent.futures.ProcessPoolExecutor`, "spawn" start method) or on a
  Dask distributed cluster, and rewrites ``sweep.csv`` atomically after every finished run.
* :func:`add_sweep_arguments` / :func:`sweep_command`: the ``hybrid-force sweep`` command.

Row statuses: ``"ok"``; ``"diverged"`` (the simulation failed at run time; the metrics are those
of the partial run); ``"failed"`` (the run failed otherwise: it lost contact, or its desired
path became singular; the error column starts with the reason); ``"bad input"`` (the variant
is not a valid scenario, e.g. a negative gain); ``"error"`` (an unexpected exception: a bug,
not a verdict on the variant). Rows with status ``"error"`` are run again when the sweep is
resumed; all others are final.

Resuming: run again with the same arguments and ``--out DIR``. Rows already in
``DIR/sweep.csv`` (matched by run id) are kept and not run again; ``DIR/sweep.json`` records
the arguments and a hash of the scenario file, and a sweep refuses to resume in a DIR made
from a different scenario file content.

Workers get data, never paths: this process reads the scenario file (with each variant's
overrides) and the model file its ``robot.model`` names, and sends both with the task: a
URDF's or an MJCF file's bytes, or for a xacro file the URDF text it expands to here (with
``robot.xacro_args`` and ``robot.package_dirs``), so workers need neither xacro nor the
files it includes. Meshes are never sent: simulating reads none (the package folders are
checked here and recorded in the kept results' meta for the replay). A worker writes the
model into a private temporary folder, builds the scenario from the data, and sends back
the row and, with ``keep_results``, the saved result's bytes, which this process writes
into ``DIR/results/``. So a Dask worker on another machine or in another folder needs only
hybrid_force installed. Local workers die with the sweep (even on ``kill -9``), and SIGTERM
stops them, keeps the finished rows and exits 143. At most :data:`MAX_RUNS` variants.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import ctypes
import hashlib
import io
import itertools
import json
import math
import multiprocessing
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import wait as _futures_wait
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from hybrid_force._atomic import atomic_file
from hybrid_force._signals import Terminated, sigterm_raises
from hybrid_force.errors import BadInputError, ScenarioError, SimulationError, SweepError
from hybrid_force.run_output import locked_folder

__all__ = [
    "MAX_RUNS",
    "METRIC_COLUMNS",
    "STATUSES",
    "THREAD_VARIABLES",
    "TIMING_COLUMNS",
    "SweepError",
    "add_sweep_arguments",
    "expand",
    "read_sweep_csv",
    "run_id",
    "run_one",
    "run_sweep",
    "single_threaded_workers",
    "split_values",
    "sweep_command",
]

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
)
"""Deterministic metric columns: identical for the same variant on any engine.

t_end [s] is the last simulated time (the failure time of a diverged run); position errors
[m] (``*_settled``: over t ≥ sim.settle_time), force errors [N] over contact samples,
worst_constraint_violation [m], contact_time [s], impact_speed [m/s], impact_impulse [N·s],
time_to_converge [s] (first time after which ‖e‖ < 1 mm for good). Empty cell: not defined
(e.g. no contact, or the run did not start).
"""

TIMING_COLUMNS: tuple[str, ...] = ("steps_per_second", "wall_time")
"""Machine-dependent columns (steps/s of the control loop, wall time [s] of the whole run)."""

MAX_RUNS = 100_000
"""Most variants one sweep may have (the grid sizes' product × samples; values of one --grid).

Larger sweeps are refused before anything is expanded or run: split them into several sweeps.
"""

_FIXED_HEAD = ("run_id",)
_STATUS_COLUMNS = ("status", "error", "warnings")
_CSV_NAME = "sweep.csv"
_JSON_NAME = "sweep.json"

Progress = bool | Literal["force"]


# ----------------------------------------------------------------------------- variants
def _canonical(value: Any) -> Any:
    """A JSON-able canonical form of a parameter value (numpy scalars → Python numbers)."""
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (bool, int, str)) or value is None:
        return value
    if isinstance(value, float):
        return value
    return str(value)


def run_id(params: Mapping[str, Any]) -> str:
    """Stable id of a variant: the first 16 hex digits of the SHA-1 of its sorted-key JSON.

    Independent of the order of the keys, of the process and of the machine; numpy scalars
    hash like the equal Python numbers. (1 and 1.0 differ: ``{"a": 1}`` ≠ ``{"a": 1.0}``.)
    """
    text = json.dumps(
        {str(k): _canonical(v) for k, v in params.items()},
        sort_keys=True,
        separators=(",", ":"),
        allow_nan=True,
    )
    return hashlib.sha1(text.encode("utf-8")).hexdigest()[:16]


def _check_key(key: str, option: str) -> None:
    table, dot, name = key.partition(".")
    if not (dot and table and name):
        raise SweepError(
            f"{option} key {key!r} must be of the form table.key (e.g. control.Lambda)"
        )


def expand(
    grid: Mapping[str, Sequence[Any]],
    random: Mapping[str, tuple[float, float]],
    samples: int,
    seed: int,
) -> list[dict[str, Any]]:
    """Expand a grid and random ranges into the list of variants (dicts of overrides).

    Args:
        grid: ``"table.key"`` → list of values. Variants are the Cartesian product, in the order
            of the keys as given, the last key varying fastest.
        random: ``"table.key"`` → (lo, hi): uniform samples in [lo, hi). Drawn with
            ``numpy.random.default_rng(seed)``, a (samples, m) matrix of the keys in sorted
            order (so the draws do not depend on the order of the options); the SAME samples are
            combined with every grid point (common random numbers: the grid effect is not
            confounded with sampling noise). Ignored when empty.
        samples: number of random samples per grid point (≥ 1 when ``random`` is given; not used
            otherwise).
        seed: seed of the random generator.

    Returns:
        ``len(product) × samples`` dicts (grid keys first, then random keys), grid-major.
        An empty grid and no random ranges give one variant, ``{}`` (the scenario as is).

    Raises:
        SweepError: a key not of the form table.key, a key both in grid and random, an empty
            value list, a value listed twice, a range with lo > hi or not finite, samples < 1,
            more than :data:`MAX_RUNS` variants (checked before anything is expanded).
    """
    import numpy as np

    for key, values in grid.items():
        _check_key(key, "--grid")
        if len(values) == 0:
            raise SweepError(f"--grid {key} has no values")
        if len(values) > MAX_RUNS:
            raise SweepError(
                f"--grid {key} lists {len(values)} values; at most {MAX_RUNS} (MAX_RUNS) are "
                "allowed"
            )
    if random and (isinstance(samples, bool) or not isinstance(samples, int) or samples < 1):
        raise SweepError(f"--samples must be a positive integer with --random, got {samples!r}")
    n_runs = math.prod(len(values) for values in grid.values()) * (samples if random else 1)
    if n_runs > MAX_RUNS:
        sizes = [f"--grid {key}: {len(values)} values" for key, values in grid.items()]
        if random:
            sizes.append(f"--samples {samples}")
        raise SweepError(
            f"the sweep would have {n_runs} runs ({' × '.join(sizes)}); at most {MAX_RUNS} "
            "(MAX_RUNS) are allowed: split it into several sweeps, each with its own --out"
        )
    for key, values in grid.items():
        seen: set[str] = set()
        for v in values:
            text = json.dumps(_canonical(v), sort_keys=True)
            if text in seen:
                raise SweepError(f"--grid {key} lists the value {v!r} twice")
            seen.add(text)
    both = sorted(set(grid) & set(random))
    if both:
        raise SweepError(f"{', '.join(both)} is given both as --grid and as --random")
    for key, rng_range in random.items():
        _check_key(key, "--random")
        try:
            lo, hi = (float(x) for x in rng_range)
        except (TypeError, ValueError) as exc:
            raise SweepError(f"--random {key} must be a pair lo:hi, got {rng_range!r}") from exc
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise SweepError(f"--random {key}={lo}:{hi} needs finite lo <= hi")
    points = [dict(zip(grid, combo, strict=True)) for combo in itertools.product(*grid.values())]
    if not random:
        return [{k: _canonical(v) for k, v in p.items()} for p in points]
    keys = sorted(random)
    gen = np.random.default_rng(seed)
    unit = gen.random((samples, len(keys)))  # (samples, m) in [0, 1)
    lows = np.array([float(random[k][0]) for k in keys])
    highs = np.array([float(random[k][1]) for k in keys])
    draws = lows + unit * (highs - lows)
    order = [k for k in random]  # column order of the rows: as given
    out: list[dict[str, Any]] = []
    for p in points:
        for row in draws:
            sample = {k: float(row[keys.index(k)]) for k in order}
            out.append({**{k: _canonical(v) for k, v in p.items()}, **sample})
    return out


def split_values(text: str) -> list[str]:
    """Split ``"v1,v2,[1,2],'a,b'"`` at the commas that are not inside brackets or quotes."""
    parts: list[str] = []
    depth = 0
    quote: str | None = None
    current: list[str] = []
    for ch in text:
        if quote is not None:
            current.append(ch)
            if ch == quote:
                quote = None
            continue
        if ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append("".join(current).strip())
            current = []
            continue
        current.append(ch)
    parts.append("".join(current).strip())
    return parts


# ----------------------------------------------------------------------------- one run
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


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _metrics_row(result: Any) -> dict[str, Any]:
    """The metric and timing columns of a (possibly partial) Result."""
    summary = result.summary()
    row: dict[str, Any] = {name: summary.get(name) for name in METRIC_COLUMNS}
    axis = summary.get("position_error_max_axis")
    for i, suffix in enumerate("xyz"):
        row[f"position_error_max_axis_{suffix}"] = None if axis is None else float(axis[i])
    row["t_end"] = float(result.t[-1]) if result.n_samples else None
    row["steps_per_second"] = result.meta.get("steps_per_second")
    return row


def _new_row(rid: str, params: Mapping[str, Any]) -> dict[str, Any]:
    """A row with status "ok", no error, no warnings and every metric/timing column None."""
    row: dict[str, Any] = {"run_id": rid, **params, "status": "ok", "error": None}
    row["warnings"] = None
    for name in (*METRIC_COLUMNS, *TIMING_COLUMNS):
        row[name] = None
    return row


@dataclass(frozen=True)
class _Urdf:
    """A model file of the sweep's machine, sent with a task (a worker may not see the file).

    ``model`` is ``robot.model`` as the scenario writes it (e.g. ``"rtr.urdf"``), ``path`` the
    file's absolute path on the sweep's machine (what the kept result's meta names), ``data``
    the bytes the worker writes as ``name`` in its folder: a URDF's or MJCF file's own bytes,
    or the URDF text a xacro file expands to (``expanded``: the worker then drops
    ``robot.xacro_args``). Kinematics and inertias only are used: meshes are never read.
    """

    model: str
    path: str
    data: bytes
    name: str = "robot.urdf"
    expanded: bool = False


@dataclass(frozen=True)
class _Task:
    """Everything one run needs, and nothing a worker might not see: sent to a worker.

    ``doc`` is the scenario's data with the variant's overrides applied; ``origin`` names the
    scenario file in messages; ``keep``: return the result (the bytes of its .npz) to the
    sweep; ``scratch``: a folder of the sweep's machine for the run's temporary folder (only
    for workers on that machine; None: the worker's own temporary directory);
    ``robot_meta``: what the kept result's ``meta["robot"]`` records besides the model
    (``package_dirs`` absolute on the sweep's machine, ``xacro_args``, ``lock_off_chain``),
    so that its replay loads the same arm.
    """

    run_id: str
    params: dict[str, Any]
    doc: dict[str, Any]
    origin: str
    urdf: _Urdf | None
    keep: bool
    scratch: str | None = None
    robot_meta: dict[str, Any] | None = None


_Outcome = tuple[dict[str, Any], bytes | None]
"""What a worker returns: the row, and the saved .npz of the run's Result (or None)."""


def _signature(path: Path) -> tuple[int, int, int]:
    """(inode, size [B], mtime [ns]) of a file: changes when the file is rewritten."""
    st = path.stat()
    return st.st_ino, st.st_size, st.st_mtime_ns


class _Source:
    """The scenario file on the sweep's machine: it turns variants into :class:`_Task` s.

    The file is read here (never by a worker). Raises ScenarioError (bad input) at
    construction if it cannot be read or is not TOML.
    """

    def __init__(self, path: Path, *, scratch: str | None = None) -> None:
        from hybrid_force.scenario.loader import read_scenario_document

        self.path = path
        self.origin = str(path)
        self.scratch = scratch
        read_scenario_document(path)  # unreadable file or bad TOML: ScenarioError now
        try:
            self.signature = _signature(path)
        except OSError as exc:
            raise SweepError(f"cannot read scenario file '{path}': {exc}") from exc
        self._urdfs: dict[str, _Urdf | str] = {}  # model and options → file, or why not

    def job(self, rid: str, params: Mapping[str, Any], keep: bool) -> _Task | dict[str, Any]:
        """The task of one variant, or its finished row when it is bad input already here.

        Raises:
            SweepError: the scenario file was changed since the sweep started (its rows would
                mix two versions of the scenario).
        """
        from hybrid_force.scenario.loader import read_scenario_document

        try:
            unchanged = _signature(self.path) == self.signature
        except OSError:
            unchanged = False
        if not unchanged:
            raise SweepError(
                f"the scenario file '{self.path}' was changed or removed during the sweep; "
                "the finished rows are kept, but a new version of the file needs another --out"
            )
        try:
            doc = read_scenario_document(self.path, dict(params))
            urdf, robot_meta = self._urdf(doc)
        except BadInputError as exc:
            row = _new_row(rid, params)
            row["status"] = "bad input"
            row["error"] = _one_line(str(exc))
            row["wall_time"] = 0.0
            return row
        return _Task(rid, dict(params), doc, self.origin, urdf, keep, self.scratch, robot_meta)

    def _urdf(self, doc: Mapping[str, Any]) -> tuple[_Urdf | None, dict[str, Any]]:
        """The model file ``robot.model`` names (relative to the scenario's folder; None for a
        registry arm), and the options the result's ``meta["robot"]`` records.

        A xacro file is expanded here, once per set of arguments and package folders; its
        failure is bad input naming ``robot.model``, as the scenario loader says it.
        """
        from hybrid_force.errors import ModelWarning, RobotError
        from hybrid_force.model.robot import expand_xacro
        from hybrid_force.scenario.loader import resolve_robot_table

        table = resolve_robot_table(doc, self.path, origin=self.origin)
        lock = table.values.get("lock_off_chain")
        robot_meta = {
            "package_dirs": list(table.package_dirs),
            "xacro_args": dict(table.xacro_args),
            "lock_off_chain": lock if isinstance(lock, bool) else None,
        }
        if table.kind == "name":
            return None, robot_meta
        target = Path(table.target)
        key = json.dumps([str(target), table.xacro_args, table.package_dirs], sort_keys=True)
        if key not in self._urdfs:
            try:
                if table.kind == "xacro":
                    with warnings.catch_warnings():  # the worker's load warns, in the row
                        warnings.simplefilter("ignore", ModelWarning)
                        text = expand_xacro(
                            target, table.xacro_args, table.package_dirs, check=True
                        )
                    name = target.name.removesuffix(".xacro")
                    name = name if name.endswith(".urdf") else f"{name or 'robot'}.urdf"
                    found = _Urdf(
                        table.model, str(target.resolve()), text.encode("utf-8"), name, True
                    )
                else:
                    data = target.read_bytes()
                    found = _Urdf(table.model, str(target.resolve()), data, target.name)
                self._urdfs[key] = found
            except RobotError as exc:
                self._urdfs[key] = _one_line(str(exc))
            except FileNotFoundError:
                self._urdfs[key] = (
                    f"model file not found (paths are relative to the scenario file): {target}"
                )
            except OSError as exc:
                self._urdfs[key] = f"cannot read the model file {target}: {exc}"
        found_or_why = self._urdfs[key]
        if isinstance(found_or_why, str):
            raise ScenarioError(
                f"{self.origin}: robot.model = {json.dumps(table.model)}: {found_or_why}"
            )
        return found_or_why, robot_meta


def run_one(scenario_path: str, params: dict[str, Any], keep_dir: str | None) -> dict[str, Any]:
    """Run one variant of a scenario in this process; never raises (failures become the status).

    Args:
        scenario_path: the scenario TOML file.
        params: overrides ``"table.key"`` → value (as for ``hybrid-force run --set``).
        keep_dir: if given, the run's Result (partial for a diverged run) is saved atomically to
            ``keep_dir/<run_id>.npz``.

    Returns:
        A flat dict: ``run_id``, the params (keys ``"table.key"``), ``status`` (see
        :data:`STATUSES`), ``error`` (one-line message or None), ``warnings`` (the distinct
        warnings the run raised, joined by " | ", or None), the :data:`METRIC_COLUMNS`
        (None when undefined) and the :data:`TIMING_COLUMNS` (wall_time [s]).

    The run goes through the same steps as a sweep's: the scenario's data and its URDF file
    are read here, then built and simulated from a private temporary folder.
    """
    rid = run_id(params)
    try:
        job = _Source(Path(scenario_path)).job(rid, params, keep=keep_dir is not None)
    except BadInputError as exc:
        row = _new_row(rid, params)
        row.update(status="bad input", error=_one_line(str(exc)), wall_time=0.0)
        return row
    if isinstance(job, dict):
        return job
    row, blob = _execute(job)
    if blob is not None and keep_dir is not None:
        try:
            _save_blob(Path(keep_dir), rid, blob)
        except OSError as exc:
            row["status"] = "error"
            row["error"] = _one_line(f"cannot save the result: {exc}")
    return row


def _execute(task: _Task) -> _Outcome:
    """Run one task (in a worker); never raises: failures become the row's status.

    The URDF (if any) is written to a private temporary folder, removed afterwards. Top-level,
    so it pickles for a process pool or a Dask worker.
    """
    row = _new_row(task.run_id, task.params)
    blob: bytes | None = None
    renames: list[tuple[str, str]] = []  # worker paths → what the sweep's machine calls them
    wall0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            scratch = task.scratch if task.scratch and os.path.isdir(task.scratch) else None
            with tempfile.TemporaryDirectory(
                prefix="hybrid_force_run_", dir=scratch, ignore_cleanup_errors=True
            ) as tmp:
                blob = _simulate_into(row, task, Path(tmp), renames)
        except Exception as exc:
            row["status"] = "error"
            row["error"] = _one_line(f"{type(exc).__name__}: {exc}")
    messages = list(dict.fromkeys(_one_line(str(w.message)) for w in caught))
    row["warnings"] = " | ".join(messages) if messages else None
    for key in ("error", "warnings"):
        for local, original in renames:
            if row[key]:
                row[key] = row[key].replace(local, original)
    row["wall_time"] = time.perf_counter() - wall0
    return row, blob


def _simulate_into(
    row: dict[str, Any], task: _Task, tmp: Path, renames: list[tuple[str, str]]
) -> bytes | None:
    """Build and simulate the task in the folder ``tmp``; fill ``row`` (status, error, metrics).

    Returns the bytes of the saved Result when the task keeps it, else None. Raises only on an
    unexpected exception (the caller makes it status "error").
    """
    from hybrid_force.errors import DivergenceError, RunFailedError, RunInterruptedError
    from hybrid_force.scenario.loader import scenario_from_document
    from hybrid_force.sim.loop import simulate

    doc = dict(task.doc)
    robot = doc.get("robot")
    if isinstance(robot, dict):
        # the package folders were checked by the sweep: simulating reads no mesh
        robot = {k: v for k, v in robot.items() if k != "package_dirs"}
        if task.urdf is not None:
            local = tmp / (task.urdf.name or "robot.urdf")
            local.write_bytes(task.urdf.data)
            robot["model"] = str(local)
            if task.urdf.expanded:
                robot.pop("xacro_args", None)
            renames.append((str(local), task.urdf.path))
        doc["robot"] = robot
    result: Any = None
    try:
        scenario = scenario_from_document(doc, origin=task.origin, base_dir=tmp)
        result = simulate(scenario)
    except RunInterruptedError as exc:
        raise KeyboardInterrupt from exc  # the sweep is being stopped: not a verdict on the run
    except RunFailedError as exc:
        # "error": an unexpected exception inside the run, retried on resume like any other
        row["status"] = (
            "diverged" if isinstance(exc, DivergenceError)
            else "error" if exc.reason == "error" else "failed"
        )  # fmt: skip
        row["error"] = _one_line(f"{exc.reason}: {exc}")
        result = exc.result
    except SimulationError as exc:
        row["status"] = "diverged"
        row["error"] = _one_line(f"{type(exc).__name__}: {exc}")
    except BadInputError as exc:
        row["status"] = "bad input"
        row["error"] = _one_line(str(exc))
    if result is None:
        return None
    result = _with_original_model(result, task)
    row.update(_metrics_row(result))
    if not task.keep:
        return None
    return result.save(tmp / "result.npz").read_bytes()


def _with_original_model(result: Any, task: _Task) -> Any:
    """The Result with its meta naming the robot as the sweep's machine does, not the worker.

    ``meta["robot"]``: ``model`` the registry name, or the model file's absolute path on the
    sweep's machine, and the task's ``robot_meta`` (package folders, xacro arguments,
    locking: what the replay passes to ``load_robot``); ``meta["scenario"]["robot"]``: the
    ``[robot]`` table as the scenario file (with the variant's overrides) writes it.
    """
    robot = dict(result.meta.get("robot") or {})
    if task.urdf is not None:
        robot["model"] = task.urdf.path
    robot.update(task.robot_meta or {})
    source = result.meta.get("scenario")
    original = task.doc.get("robot")
    if isinstance(source, dict) and isinstance(original, dict):
        source = {**source, "robot": dict(original)}
    return result.with_meta(robot=robot, scenario=source)


def _save_blob(keep_dir: Path, rid: str, blob: bytes) -> Path:
    """Write a run's .npz bytes atomically to ``keep_dir/<rid>.npz`` (directory fsync'ed)."""
    keep_dir.mkdir(parents=True, exist_ok=True)
    target = keep_dir / f"{rid}.npz"
    with atomic_file(target) as fh:
        fh.write(blob)
    with contextlib.suppress(OSError):
        fd = os.open(keep_dir, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    return target


# ----------------------------------------------------------------------------- worker processes
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def _watch_parent(parent_pid: int) -> None:
    """Make this worker process die (SIGKILL) as soon as its parent, ``parent_pid``, dies.

    The initialiser of the sweep's local worker processes, so that even a ``kill -9`` of the
    sweep leaves none behind. On Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` (the kernel kills
    us when the parent's thread that started us exits: the sweep's main thread); elsewhere, or
    if prctl fails, a daemon thread polls ``os.getppid()`` every 0.2 s. A parent that died
    before the watch was armed is caught by comparing ``os.getppid()`` with ``parent_pid``.
    """
    armed = False
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent_pid:
        os._exit(1)  # orphaned already

    if not armed:

        def poll() -> None:
            while os.getppid() == parent_pid:
                time.sleep(0.2)
            os._exit(1)

        threading.Thread(target=poll, name="hybrid_force parent watch", daemon=True).start()


# ----------------------------------------------------------------------------- CSV files
def read_sweep_csv(path: str | os.PathLike[str]) -> tuple[list[str], list[dict[str, str]]]:
    """Read a sweep CSV: (columns, rows as dicts of strings). Raises SweepError if unreadable."""
    src = Path(path)
    try:
        with src.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            rows = [dict(r) for r in reader]
            columns = list(reader.fieldnames or [])
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise SweepError(f"cannot read sweep file '{src}': {exc}") from exc
    if columns and "run_id" not in columns:
        raise SweepError(
            f"'{src}' is not a sweep CSV (no run_id column; columns: {', '.join(columns)}); "
            "choose another --out"
        )
    for i, r in enumerate(rows):
        if None in r or any(v is None for v in r.values()):
            raise SweepError(f"'{src}' row {i + 2} has the wrong number of cells")
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
        raise SweepError(f"cannot read scenario file '{path}': {exc}") from exc


# ----------------------------------------------------------------------------- progress
class _Bar:
    """A one-line text progress bar with ETA on stderr."""

    def __init__(self, total: int, done: int, enabled: bool) -> None:
        self.total, self.done0, self.done = total, done, done
        self.enabled = enabled
        self.t0 = time.monotonic()
        self.failed = 0

    def update(self, status: str) -> None:
        self.done += 1
        if status != "ok":
            self.failed += 1
        self.draw()

    def draw(self) -> None:
        if not self.enabled:
            return
        width = 30
        frac = self.done / self.total if self.total else 1.0
        filled = round(frac * width)
        elapsed = time.monotonic() - self.t0
        new = self.done - self.done0
        if new > 0 and self.done < self.total:
            eta = _hms(elapsed / new * (self.total - self.done))
        elif self.done >= self.total:
            eta = "done"
        else:
            eta = "--:--"
        text = (
            f"\r[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} "
            f"{100 * frac:3.0f}%  elapsed {_hms(elapsed)}  ETA {eta}  not ok: {self.failed} "
        )
        sys.stderr.write(text)
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


def _hms(seconds: float) -> str:
    s = round(seconds)
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m:02d}:{s:02d}"


# ----------------------------------------------------------------------------- the sweep
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
            raise SweepError(f"parameter name(s) {', '.join(clash)} clash with sweep columns")
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
) -> Path:
    """Run every variant not yet in ``out_dir/sweep.csv``; return the CSV path.

    Args:
        scenario_path: the scenario TOML file, read by this process only (workers, which
            need hybrid_force installed, get its data and its URDF file's content).
        variants: dicts of overrides, e.g. from :func:`expand`; run ids must be distinct.
        workers: local worker processes (default ``os.cpu_count()``), or the number of workers
            of a ``"local"`` Dask cluster (default 2).
        scheduler: None: a process pool ("spawn" start method, safe with Pinocchio);
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

    Returns:
        ``out_dir/sweep.csv``: one row per variant in variant order (plus rows of earlier
        sweeps in the same directory whose run ids are not among the variants, at the end).

    The CSV is rewritten atomically (temp file + os.replace) after every finished run (when the
    sweep has so many rows that rewriting costs more than 10 % of the time, at most that often,
    and always at the end), so an interruption never leaves it half-written; a rerun skips the
    run ids it holds (except rows with status "error").

    Raises:
        SweepError: duplicate variants, more than :data:`MAX_RUNS` of them, a bad out_dir, a
            DIR made from another scenario file, a scenario file changed during the sweep, a
            result that cannot be saved.
        ScenarioError: the scenario file cannot be read or is not TOML.
        SimulationError: runs were lost (a worker process died); the finished rows are saved
            and rerunning the same sweep runs the missing ones.

    Any exception (Ctrl-C included) kills the local workers before it propagates, and
    ``sweep.csv`` holds every row finished until then.
    """
    scenario = Path(scenario_path)
    if not scenario.is_file():
        raise SweepError(f"scenario file '{scenario}' does not exist")
    if hasattr(variants, "__len__") and len(variants) > MAX_RUNS:
        raise SweepError(
            f"the sweep has {len(variants)} variants; at most {MAX_RUNS} (MAX_RUNS) are allowed: "
            "split it into several sweeps, each with its own --out"
        )
    variants = [dict(v) for v in variants]
    ids = [run_id(v) for v in variants]
    if len(set(ids)) != len(ids):
        dup = next(v for v, rid in zip(variants, ids, strict=True) if ids.count(rid) > 1)
        raise SweepError(f"the variant {dup!r} appears more than once")
    if workers is not None and (isinstance(workers, bool) or int(workers) < 1):
        raise SweepError(f"--workers must be a positive integer, got {workers!r}")
    source = _Source(scenario)  # read here, never by a worker; ScenarioError if unreadable
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SweepError(f"cannot create output directory '{out}': {exc}") from exc
    # one command at a time writes into a folder: a second sweep (or a run) is refused
    with locked_folder(out, "--out"):
        sha = _file_sha256(scenario)
        info_path = out / _JSON_NAME
        if info_path.exists() and (out / _CSV_NAME).exists():
            try:
                old = json.loads(info_path.read_text(encoding="utf-8"))
            except (OSError, json.JSONDecodeError):
                old = {}
            if old.get("scenario_sha256") not in (None, sha):
                raise SweepError(
                    f"'{out}' holds a sweep of a different version of the scenario "
                    f"(sha256 {old.get('scenario_sha256')}, now {sha} for '{scenario}'); "
                    "use another --out or delete that directory"
                )
        table = _Table(out / _CSV_NAME, variants)
        keep_dir = (out / "results").resolve() if keep_results else None
        info = {
            "scenario": str(scenario.resolve()),
            "scenario_sha256": sha,
            "n_variants": len(variants),
            "workers": workers,
            "scheduler": scheduler,
            "keep_results": keep_results,
            "columns": table.columns,
            "arguments": dict(arguments or {}),
            "variants": [{"run_id": rid, **v} for rid, v in zip(ids, variants, strict=True)],
        }
        _write_atomic(info_path, json.dumps(info, indent=1, default=str) + "\n")
        todo = [(rid, v) for rid, v in zip(ids, variants, strict=True) if not table.finished(rid)]
        table.write()
        enabled = progress == "force" or (bool(progress) and sys.stderr.isatty())
        bar = _Bar(len(variants), len(variants) - len(todo), enabled)
        if not todo:
            bar.draw()
            bar.close()
            return table.path
        bar.draw()
        lost: list[str] = []

        def finish(row: dict[str, Any], blob: bytes | None) -> None:
            if blob is not None and keep_dir is not None:
                try:
                    _save_blob(keep_dir, str(row["run_id"]), blob)
                except OSError as exc:
                    raise SweepError(f"cannot save a result into '{keep_dir}': {exc}") from exc
            table.add(row)
            table.write(force=False)
            bar.update(str(row.get("status")))
            if on_row is not None:
                on_row(row)

        remote = scheduler not in (None, "local")
        # the local workers' temporary folders go in DIR/.scratch-<pid>-*: removed at the end,
        # even when the sweep is interrupted (SIGTERM, Ctrl-C); after a kill -9, by the next sweep
        scratch = None if remote else _scratch_dir(out)
        source.scratch = scratch

        def jobs() -> Iterator[tuple[str, _Task | dict[str, Any]]]:
            for rid, params in todo:
                yield rid, source.job(rid, params, keep=keep_dir is not None)

        try:
            if scheduler is None:
                _run_pool(jobs(), len(todo), workers, finish, lost)
            else:
                _run_dask(jobs(), workers, scheduler, finish, lost)
        finally:
            table.write()
            bar.close()
            if scratch is not None:
                shutil.rmtree(scratch, ignore_errors=True)
        if lost:
            missing = sum(1 for rid in ids if rid not in table.rows)
            raise SimulationError(
                f"{len(lost)} run(s) were lost ({lost[0]}); {missing} variant(s) have no row; the "
                f"{len(table.rows)} finished rows are in '{table.path}'; run the same sweep again "
                "to run the missing ones"
            )
        return table.path


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
    return tempfile.mkdtemp(prefix=f".scratch-{os.getpid()}-", dir=out)


def _pump(
    jobs: Iterator[tuple[str, _Task | dict[str, Any]]],
    submit: Callable[[_Task], Any],
    wait_first: Callable[[list[Any]], Iterable[Any]],
    limit: int,
    finish: Callable[[dict[str, Any], bytes | None], None],
    lost: list[str],
    *,
    stop_on_loss: bool,
) -> None:
    """Keep at most ``limit`` tasks in flight and hand each finished one to ``finish``.

    Tasks are made (their scenario data read) only when submitted, so a long sweep holds a few
    of them in memory, not all. A future that raised (a lost worker, not a failed run:
    :func:`_execute` never raises) is recorded in ``lost`` with its run id; with
    ``stop_on_loss`` (a broken process pool takes no more work) nothing more is submitted.
    """
    pending: dict[Any, str] = {}
    more = True

    def refill() -> None:
        nonlocal more
        while more and len(pending) < limit:
            job = next(jobs, None)
            if job is None:
                more = False
                return
            rid, item = job
            if isinstance(item, _Task):
                try:
                    pending[submit(item)] = rid
                except Exception as exc:  # e.g. BrokenProcessPool: a worker died
                    lost.append(f"{rid}: {type(exc).__name__}: {_one_line(str(exc))}")
                    more = False
            else:
                finish(item, None)  # bad input found here: no worker needed

    refill()
    while pending:
        for fut in wait_first(list(pending)):
            rid = pending.pop(fut)
            try:
                row, blob = fut.result()
            except Exception as exc:
                lost.append(f"{rid}: {type(exc).__name__}: {_one_line(str(exc))}")
                more = more and not stop_on_loss
                continue
            finish(row, blob)
        refill()


def _first_done(futures: list[Future[_Outcome]]) -> Iterable[Future[_Outcome]]:
    return _futures_wait(futures, return_when=FIRST_COMPLETED).done


#: Thread-pool sizes of the numeric libraries, set to 1 in the workers a sweep starts: each
#: run is one small serial loop, and n workers × the machine's cores threads would only fight
#: over the cores (oversubscription).
THREAD_VARIABLES = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "NUMBA_NUM_THREADS",
)


@contextlib.contextmanager
def single_threaded_workers() -> Iterator[None]:
    """While open, processes started from this one run their numeric libraries on one thread.

    Sets each of :data:`THREAD_VARIABLES` that is not already set to "1" (a value the user set
    is kept), and restores the environment on exit. The workers read them when they start
    (a "spawn" pool, a LocalCluster's worker processes).
    """
    added = [name for name in THREAD_VARIABLES if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


def _run_pool(
    jobs: Iterator[tuple[str, _Task | dict[str, Any]]],
    n_jobs: int,
    workers: int | None,
    finish: Callable[[dict[str, Any], bytes | None], None],
    lost: list[str],
) -> None:
    """Run on a local process pool ("spawn": no fork of a process holding Pinocchio state).

    The workers die with this process (:func:`_watch_parent`); on any exception (SIGTERM,
    Ctrl-C, a failed write) they are killed before it propagates, so none is left running.
    """
    n = min(int(workers or os.cpu_count() or 1), n_jobs)
    ctx = multiprocessing.get_context("spawn")
    # the pool starts its workers on demand, while jobs are submitted: keep the variables set
    with single_threaded_workers():
        pool = ProcessPoolExecutor(
            max_workers=n, mp_context=ctx, initializer=_watch_parent, initargs=(os.getpid(),)
        )
        try:
            _pump(
                jobs,
                lambda task: pool.submit(_execute, task),
                _first_done,
                max(4 * n, 32),
                finish,
                lost,
                stop_on_loss=True,
            )
        except BaseException:
            _kill_pool(pool)
            raise
        pool.shutdown(wait=True)


def _kill_pool(pool: ProcessPoolExecutor) -> None:
    """Stop a process pool now: cancel what is queued, kill (SIGKILL) and reap its workers."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        with contextlib.suppress(Exception):
            proc.kill()
    for proc in processes:
        with contextlib.suppress(Exception):
            proc.join(timeout=5.0)
    if isinstance(manager, threading.Thread):
        manager.join(timeout=5.0)  # it sees the pool broken and releases its queues


def _run_dask(
    jobs: Iterator[tuple[str, _Task | dict[str, Any]]],
    workers: int | None,
    scheduler: str,
    finish: Callable[[dict[str, Any], bytes | None], None],
    lost: list[str],
) -> None:
    """Run on a Dask cluster: a LocalCluster for "local", else the scheduler at that address.

    A LocalCluster's worker processes are children of this process and exit when it dies
    (Dask's nanny pipe); on any exception the cluster is closed before it propagates. Tasks
    carry the scenario's data and URDF, so remote workers need no shared file system.
    """
    try:
        from dask.distributed import Client, LocalCluster
        from dask.distributed import wait as dask_wait
    except ImportError as exc:  # pragma: no cover - dask is a dependency
        raise SweepError(f"--scheduler needs dask.distributed: {exc}") from exc
    cluster: Any = None
    with contextlib.ExitStack() as stack:
        if scheduler == "local":
            stack.enter_context(single_threaded_workers())
            cluster = stack.enter_context(
                LocalCluster(
                    n_workers=int(workers or 2),
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                )
            )
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(scheduler, timeout=30))
            except (OSError, TimeoutError, ValueError) as exc:
                raise SweepError(
                    f"cannot connect to the Dask scheduler at {scheduler!r}: {exc} "
                    "(give tcp://host:port of a running scheduler, or 'local')"
                ) from exc
        threads = sum(client.nthreads().values())
        submitted: list[Any] = []

        def submit(task: _Task) -> Any:
            fut = client.submit(_execute, task, key=f"run-{task.run_id}", pure=False)
            submitted.append(fut)
            return fut

        def wait_first(futures: list[Any]) -> Iterable[Any]:
            return dask_wait(futures, return_when="FIRST_COMPLETED").done

        try:
            _pump(jobs, submit, wait_first, max(4 * threads, 32), finish, lost, stop_on_loss=False)
        except BaseException:
            if cluster is not None:
                _stop_local_workers(cluster)
            else:  # someone else's cluster: only take our tasks off it
                with contextlib.suppress(Exception):
                    client.cancel([f for f in submitted if not f.done()])
            raise


def _stop_local_workers(cluster: Any) -> None:
    """Close a LocalCluster's workers now: a busy worker is killed after 0.4 s, not 4 s.

    (Closing the cluster would ask each worker to finish its task for 4 s first.) Dask's
    warnings about the cancelled and killed tasks are silenced: they are expected here.
    """
    import asyncio
    import logging

    async def close_all() -> None:
        nannies = list(cluster.workers.values())
        await asyncio.gather(*(n.close(timeout=0.5) for n in nannies), return_exceptions=True)

    log = logging.getLogger("distributed")
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        cluster.sync(close_all)
    except Exception:  # the cluster's own close still follows
        pass
    finally:
        log.setLevel(level)


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
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes (default: one per core; 2 for --scheduler local)",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS|local",
        help="run on a Dask cluster: a scheduler address (tcp://host:8786) or 'local' "
        "(a LocalCluster on this machine); default: a local process pool",
    )
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
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def _parse_grid(items: Sequence[str]) -> dict[str, list[Any]]:
    from hybrid_force.scenario.loader import parse_override

    grid: dict[str, list[Any]] = {}
    for item in items:
        key, sep, values = item.partition("=")
        key = key.strip()
        if not sep or not key or not values.strip():
            raise SweepError(f"--grid {item!r} must be table.key=v1,v2,...")
        if key in grid:
            raise SweepError(f"--grid {key} is given twice; list all its values in one option")
        texts = split_values(values)
        if len(texts) > MAX_RUNS:
            raise SweepError(
                f"--grid {key} lists {len(texts)} values; at most {MAX_RUNS} (MAX_RUNS) are allowed"
            )
        parsed = []
        for text in texts:
            if not text:
                raise SweepError(f"--grid {item!r} has an empty value")
            parsed.append(parse_override(f"{key}={text}")[1])
        grid[key] = parsed
    return grid


def _parse_random(items: Sequence[str]) -> dict[str, tuple[float, float]]:
    out: dict[str, tuple[float, float]] = {}
    for item in items:
        key, sep, rng = item.partition("=")
        key = key.strip()
        lo_text, colon, hi_text = rng.partition(":")
        try:
            if not (sep and key and colon):
                raise ValueError
            lo, hi = float(lo_text), float(hi_text)
        except ValueError:
            raise SweepError(f"--random {item!r} must be table.key=lo:hi (two numbers)") from None
        if key in out:
            raise SweepError(f"--random {key} is given twice")
        out[key] = (lo, hi)
    return out


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
    2: bad input (raised as :class:`SweepError` / BadInputError, e.g. more than
    :data:`MAX_RUNS` variants); 130: Ctrl-C; 143: SIGTERM. With 1, 130 and 143 the finished
    rows are saved and rerunning the same command completes the sweep.
    """
    from hybrid_force.scenario.loader import load_scenario

    scenario = Path(args.scenario)
    if not scenario.is_file():
        raise SweepError(f"scenario file '{scenario}' does not exist")
    grid = _parse_grid(args.grid)
    random = _parse_random(args.random)
    if random and args.samples is None:
        raise SweepError("--random needs --samples N (random samples per grid point)")
    if args.samples is not None and not random:
        raise SweepError("--samples needs at least one --random table.key=lo:hi")
    if args.workers is not None and args.workers < 1:
        raise SweepError(f"--workers must be a positive integer, got {args.workers}")
    variants = expand(grid, random, args.samples or 0, args.seed)
    out = Path(args.out) if args.out else Path("runs") / f"{scenario.stem}_sweep"
    arguments = {
        "grid": grid,
        "random": {k: list(v) for k, v in random.items()},
        "samples": args.samples,
        "seed": args.seed,
    }
    t0 = time.monotonic()
    n_new = 0

    def count(_row: dict[str, Any]) -> None:
        nonlocal n_new
        n_new += 1

    def stopped(how: str) -> None:
        print(
            f"{how} after {n_new} new run(s); the finished rows are in "
            f"'{out / _CSV_NAME}'; run the same command again to resume",
            file=sys.stderr,
        )

    try:
        with sigterm_raises():
            load_scenario(scenario)  # a broken scenario file is bad input, before any run
            path = run_sweep(
                scenario,
                variants,
                workers=args.workers,
                scheduler=args.scheduler,
                out_dir=out,
                keep_results=args.keep_results,
                progress=not args.quiet,
                arguments=arguments,
                on_row=count,
            )
    except Terminated:  # before KeyboardInterrupt, which it is
        stopped("terminated (SIGTERM)")
        return 128 + signal.SIGTERM
    except KeyboardInterrupt:
        stopped("interrupted")
        return 130
    except SimulationError as exc:
        print(f"error: {_one_line(str(exc))}", file=sys.stderr)
        return 1
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
        f"sweep: {len(mine)} runs ({parts}); {n_new} new in {_hms(wall)}, "
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

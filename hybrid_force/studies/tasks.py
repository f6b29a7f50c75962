"""One run of a sweep: a variant turned into a task (data, not paths), run in a worker.

:class:`_Source` reads the scenario file and the model files it names (``robot.model``,
``control.model``) on the sweep's machine, resolved against the scenario's folder as
``hybrid-force run`` resolves them, and makes each variant's :class:`_Task`; it records the
sha256 of every file it read (:attr:`_Source.inputs`), so that a resumed sweep knows whether
its rows saw the same files. :func:`_execute` runs a task in any process (a pool worker, a
Dask worker, or this one) and returns its row, never raising; :func:`warm_up` loads the
compiled kernels a task's runs use, once per process.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import gc
import hashlib
import json
import os
import tempfile
import time
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hybrid_force._atomic import atomic_file
from hybrid_force._signals import Terminated
from hybrid_force.errors import (
    BadInputError,
    ModelWarning,
    RobotError,
    RunFailedError,
    ScenarioError,
)
from hybrid_force.geometry.surface_base import prebuilt_surfaces
from hybrid_force.model.loading import _is_path
from hybrid_force.model.scenario_robot import resolve_control_model
from hybrid_force.model.xacro_files import expand_xacro
from hybrid_force.scenario._builders import file_surfaces, resolve_robot_table
from hybrid_force.scenario.loader import read_scenario_document, scenario_from_document
from hybrid_force.sim.loop import simulate
from hybrid_force.studies.table import METRIC_COLUMNS, TIMING_COLUMNS
from hybrid_force.studies.variants import run_id

__all__ = ["run_one"]


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

    ``model`` is the key's value as the scenario writes it (e.g. ``"rtr.urdf"``), ``path`` the
    file's absolute path on the sweep's machine (what the kept result's meta names), ``data``
    the bytes the worker writes as ``name`` in its folder: a URDF's or MJCF file's own bytes,
    or the URDF text a xacro file expands to (``expanded``: the worker then drops
    ``robot.xacro_args``). ``key`` is the scenario key that names it (``robot.model`` or
    ``control.model``). Kinematics and inertias only are used: meshes are never read.
    """

    model: str
    path: str
    data: bytes
    name: str = "robot.urdf"
    expanded: bool = False
    key: str = "robot.model"


@dataclass(frozen=True)
class _Task:
    """Everything one run needs, and nothing a worker might not see: sent to a worker.

    ``doc`` is the scenario's data with the variant's overrides applied; ``origin`` names the
    scenario file in messages; ``keep``: return the result (the bytes of its .npz) to the
    sweep; ``scratch``: a folder of the sweep's machine for the run's temporary folder (only
    for workers on that machine; None: the worker's own temporary directory);
    ``robot_meta``: what the kept result's ``meta["robot"]`` records besides the model
    (``package_dirs`` absolute on the sweep's machine, ``xacro_args``, ``lock_off_chain``),
    so that its replay loads the same arm; ``control``: the file ``control.model`` names
    (None: no such key, or a registry arm, which every worker has).
    """

    run_id: str
    params: dict[str, Any]
    doc: dict[str, Any]
    origin: str
    urdf: _Urdf | None
    keep: bool
    scratch: str | None = None
    robot_meta: dict[str, Any] | None = None
    control: _Urdf | None = None
    surfaces: dict[str, tuple[dict[str, Any], Any]] | None = None


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

    def __init__(
        self, path: Path, *, scratch: str | None = None, trust_xacro: bool = False
    ) -> None:

        self.path = path
        self.trust_xacro = trust_xacro  # --trust-xacro: as robot.xacro_trust = true
        self.origin = str(path)
        self.scratch = scratch
        read_scenario_document(path)  # unreadable file or bad TOML: ScenarioError now
        try:
            self.signature = _signature(path)
        except OSError as exc:
            raise BadInputError(f"cannot read scenario file '{path}': {exc}") from exc
        self._urdfs: dict[str, _Urdf | str] = {}  # model and options → file, or why not
        self._built: dict[str, dict[str, tuple[dict[str, Any], Any]]] = {}  # surface tables
        # every file the tasks made so far read, absolute path → {"key", "sha256"} (None: the
        # file was missing): a resumed sweep reuses rows only if each is unchanged
        self.inputs: dict[str, dict[str, str | None]] = {}
        self._changed: list[str] = []  # the variant's files changed since read (messages)

    def job(self, rid: str, params: Mapping[str, Any], keep: bool) -> _Task | dict[str, Any]:
        """The task of one variant, or its finished row when it is bad input already here.

        Raises:
            BadInputError: the scenario file was changed since the sweep started, or a model file
                the variant reads was read before with another content (its rows would mix two
                versions of the scenario or of the arm).
        """

        self.check_unchanged()
        self._changed.clear()
        try:
            doc = read_scenario_document(self.path, dict(params))
            self._note_missing(doc)  # a bad-input row depends on a missing file too
            urdf, robot_meta = self._urdf(doc)
            control = self._control(doc)
            surfaces = self._file_surfaces(doc)
        except BadInputError as exc:
            self._check_inputs()  # a file changed during the sweep: no verdict on the variant
            row = _new_row(rid, params)
            row["status"] = "bad input"
            row["error"] = _one_line(str(exc))
            row["wall_time"] = 0.0
            return row
        self._check_inputs()
        return _Task(
            rid, dict(params), doc, self.origin, urdf, keep, self.scratch, robot_meta, control,
            surfaces or None,
        )  # fmt: skip

    def _file_surfaces(self, doc: Mapping[str, Any]) -> dict[str, tuple[dict[str, Any], Any]]:
        """The variant's surfaces built from files (mesh parts), built here once per set of
        table values (variants that share them share the surface); each file read is recorded
        in :attr:`inputs` (key ``<table>.file``)."""
        tables = {k: doc[k] for k in ("surface", "surfaces") if k in doc}
        cache = json.dumps(tables, sort_keys=True, default=str)
        if cache not in self._built:
            built = file_surfaces(doc, self.path, origin=self.origin)
            for name, (_, surface) in built.items():
                source = Path(str(getattr(surface, "file", "")))
                self._record(f"{name}.file", str(source), _sha256_or_none(source))
            self._built[cache] = built
        return self._built[cache]

    def _record(self, key: str, path: str, digest: str | None) -> None:
        """Note that a task read the file ``path`` (for ``key``) with this sha256; a file read
        before with another content during this sweep is kept for :meth:`_check_inputs`."""
        path = os.path.abspath(path)
        seen = self.inputs.get(path)
        if seen is not None and seen["sha256"] != digest:
            self._changed.append(
                f"the file '{path}' ({key} of '{self.path}') was changed during the sweep "
                f"(sha256 {seen['sha256']}, now {digest}); the finished rows are kept, but a "
                "new version of the file needs another --out"
            )
            return
        self.inputs[path] = {"key": key, "sha256": digest}

    def _check_inputs(self) -> None:
        """BadInputError naming the first file the variant read that was read before with another
        content during this sweep (its rows would mix two versions of it)."""
        if self._changed:
            raise BadInputError(self._changed[0], file=str(self.path))

    def _note_missing(self, doc: Mapping[str, Any]) -> None:
        """Record the model files the variant names that do not exist (their sha256 None)."""

        for name in ("robot", "control"):
            table = doc.get(name)
            key = f"{name}.model"
            model = table.get("model") if isinstance(table, dict) else None
            if isinstance(model, str) and _is_path(model):
                target = Path(model) if Path(model).is_absolute() else self.path.parent / model
                if not target.is_file():
                    self._record(key, str(target), None)

    def _read_model(
        self,
        key: str,
        model: str,
        target: Path,
        kind: str,
        xacro_args: Mapping[str, str],
        package_dirs: tuple[str, ...],
        *,
        trust: bool = False,
    ) -> _Urdf:
        """The model file ``target`` (the value ``model`` of ``key``) as a task sends it, read
        or expanded once per set of options (a xacro file's expressions as data unless
        ``trust``); the files read are recorded in :attr:`inputs`.

        Raises:
            ScenarioError: it cannot be read or expanded, naming the file and key as the
                scenario loader does.
        """

        cache = json.dumps([key, str(target), xacro_args, package_dirs, trust], sort_keys=True)
        if cache not in self._urdfs:
            includes: list[str] = []
            try:
                if kind == "xacro":
                    with warnings.catch_warnings():  # the worker's load warns, in the row
                        warnings.simplefilter("ignore", ModelWarning)
                        try:
                            text = expand_xacro(
                                target,
                                xacro_args,
                                package_dirs,
                                check=True,
                                includes=includes,
                                trust=trust,
                            )
                        finally:  # the files xacro read, also when it failed
                            for name in (str(target), *includes):
                                self._record(key, name, _sha256_or_none(Path(name)))
                    name = target.name.removesuffix(".xacro")
                    name = name if name.endswith(".urdf") else f"{name or 'robot'}.urdf"
                    found = _Urdf(
                        model, str(target.resolve()), text.encode("utf-8"), name, True, key
                    )
                else:
                    data = target.read_bytes()
                    self._record(key, str(target), hashlib.sha256(data).hexdigest())
                    found = _Urdf(model, str(target.resolve()), data, target.name, key=key)
                self._urdfs[cache] = found
            except RobotError as exc:
                self._urdfs[cache] = _one_line(str(exc))
            except FileNotFoundError:
                self._urdfs[cache] = (
                    f"model file not found (paths are relative to the scenario file): {target}"
                )
            except OSError as exc:
                self._urdfs[cache] = f"cannot read the model file {target}: {exc}"
        found_or_why = self._urdfs[cache]
        if isinstance(found_or_why, str):
            raise ScenarioError(f"{self.origin}: {key} = {json.dumps(model)}: {found_or_why}")
        return found_or_why

    def _control(self, doc: Mapping[str, Any]) -> _Urdf | None:
        """The file ``control.model`` names (relative to the scenario's folder), as
        ``hybrid-force run`` loads it (a xacro file without arguments); None for none or a
        registry arm."""

        found = resolve_control_model(doc, self.path, origin=self.origin)
        if found is None:
            return None
        model, target, kind = found
        robot = doc.get("robot")  # robot.xacro_trust covers a xacro control.model too
        trust = self.trust_xacro or (isinstance(robot, dict) and robot.get("xacro_trust") is True)
        return self._read_model("control.model", model, target, kind, {}, (), trust=trust)

    def check_unchanged(self) -> None:
        """BadInputError if the file was changed or removed since it was first read (the rows of
        two versions of a scenario would share a table)."""
        try:
            unchanged = _signature(self.path) == self.signature
        except OSError:
            unchanged = False
        if not unchanged:
            raise BadInputError(
                f"the scenario file '{self.path}' was changed or removed during the sweep; "
                "the finished rows are kept, but a new version of the file needs another --out"
            )

    def _urdf(self, doc: Mapping[str, Any]) -> tuple[_Urdf | None, dict[str, Any]]:
        """The model file ``robot.model`` names (relative to the scenario's folder; None for a
        registry arm), and the options the result's ``meta["robot"]`` records.

        A xacro file is expanded here, once per set of arguments and package folders, its
        expressions as data unless ``robot.xacro_trust`` (or ``--trust-xacro``); its failure
        is bad input naming ``robot.model``, as the scenario loader says it.
        """

        table = resolve_robot_table(doc, self.path, origin=self.origin)
        lock = table.values.get("lock_off_chain")
        robot_meta = {
            "package_dirs": list(table.package_dirs),
            "xacro_args": dict(table.xacro_args),
            "lock_off_chain": lock if isinstance(lock, bool) else None,
        }
        if table.kind == "name":
            return None, robot_meta
        found = self._read_model(
            "robot.model",
            table.model,
            Path(table.target),
            table.kind,
            table.xacro_args,
            table.package_dirs,
            trust=self.trust_xacro or table.values.get("xacro_trust") is True,
        )
        return found, robot_meta


def _sha256_or_none(path: Path) -> str | None:
    """The sha256 of a file's bytes, or None when it cannot be read (missing)."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


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

    The run goes through the same steps as a sweep's: the scenario's data and its model files
    (``robot.model``, ``control.model``) are read here, then built and simulated from a
    private temporary folder.
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
                # absolute: the model paths written into the scenario must not be joined to
                # the folder again (a relative scratch, e.g. a relative --out, did that)
                blob = _simulate_into(row, task, Path(os.path.abspath(tmp)), renames)
        except Exception as exc:
            row["status"] = "error"
            row["error"] = _one_line(f"{type(exc).__name__}: {exc}")
    messages = list(dict.fromkeys(_one_line(str(w.message)) for w in caught))
    row["warnings"] = " | ".join(messages) if messages else None
    if row.get("status") == "ok" or messages:  # the row's count is of the row's warnings
        row["n_warnings"] = len(messages)
    for key in ("error", "warnings"):
        for local, original in renames:
            if row[key]:
                row[key] = row[key].replace(local, original)
    row["wall_time"] = time.perf_counter() - wall0
    return row, blob


def warm_up(task: _Task) -> None:
    """Load, in this process, the compiled kernels that the runs of ``task`` use: run a copy of
    it a few steps long and drop its row. Never raises (a variant that cannot run still warms
    the imports); called once per worker, before its first task.

    Later runs are unchanged by it: a run's result depends only on its task (the kernels are
    the same compiled code, loaded sooner).

    The garbage collector is paused meanwhile: loading Numba and the kernels makes some 10⁵
    objects that live as long as the process and no garbage worth collecting, and the full
    collections their number triggers would cost a tenth of the warm-up.
    """

    doc = copy.deepcopy(task.doc)
    sim = doc.get("sim")
    sim = dict(sim) if isinstance(sim, dict) else {}
    dt = sim.get("dt", 1e-3)
    if isinstance(dt, (int, float)) and not isinstance(dt, bool) and dt > 0:
        sim["duration"] = 5.0 * float(dt)
    doc["sim"] = sim
    with contextlib.suppress(Exception), _collector_paused():
        _execute(dataclasses.replace(task, doc=doc, keep=False, scratch=None))


@contextlib.contextmanager
def _collector_paused() -> Iterator[None]:
    """While open, Python's cyclic garbage collector does not run (then as it was before)."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def _simulate_into(
    row: dict[str, Any], task: _Task, tmp: Path, renames: list[tuple[str, str]]
) -> bytes | None:
    """Build and simulate the task in the folder ``tmp``; fill ``row`` (status, error, metrics).

    Returns the bytes of the saved Result when the task keeps it, else None. Raises only on an
    unexpected exception (the caller makes it status "error").
    """

    doc = dict(task.doc)
    robot = doc.get("robot")
    if isinstance(robot, dict):
        # the package folders were checked by the sweep: simulating reads no mesh
        robot = {k: v for k, v in robot.items() if k != "package_dirs"}
        if task.urdf is not None:
            robot["model"] = _write_model(tmp / "robot", task.urdf, renames)
            if task.urdf.expanded:
                robot.pop("xacro_args", None)
        doc["robot"] = robot
    control = doc.get("control")
    if isinstance(control, dict) and task.control is not None:
        # its own folder: it may have the robot's file name and another content
        doc["control"] = {**control, "model": _write_model(tmp / "control", task.control, renames)}
    result: Any = None
    try:
        with prebuilt_surfaces(task.surfaces or {}):
            scenario = scenario_from_document(doc, origin=task.origin, base_dir=tmp)
        result = simulate(scenario)
    except RunFailedError as exc:
        if exc.reason == "interrupted":
            # the sweep is being stopped (e.g. in the warm-up of its own process): not a verdict
            stop = Terminated if exc.signal == "SIGTERM" else KeyboardInterrupt
            raise stop from exc
        # "error": an unexpected exception inside the run, retried on resume like any other
        row["status"] = (
            "diverged" if exc.reason == "diverged"
            else "error" if exc.reason == "error" else "failed"
        )  # fmt: skip
        row["error"] = _one_line(f"{exc.reason}: {exc}")
        result = exc.result
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


def _write_model(folder: Path, model: _Urdf, renames: list[tuple[str, str]]) -> str:
    """Write a sent model file into ``folder``; its absolute path (what the worker's scenario
    names), noted in ``renames`` as the sweep's machine calls it."""
    folder.mkdir(parents=True, exist_ok=True)
    local = folder / (model.name or "robot.urdf")
    local.write_bytes(model.data)
    # "key = value" in the loader's messages: the value as the scenario writes it, as in run's
    quoted = (
        json.dumps(str(local), ensure_ascii=False),
        json.dumps(model.model, ensure_ascii=False),
    )
    renames.extend([quoted, (str(local), model.path)])
    return str(local)


def _with_original_model(result: Any, task: _Task) -> Any:
    """The Result with its meta naming the robot as the sweep's machine does, not the worker.

    ``meta["robot"]``: ``model`` the registry name, or the model file's absolute path on the
    sweep's machine, and the task's ``robot_meta`` (package folders, xacro arguments,
    locking: what the replay passes to ``load_robot``); ``meta["scenario"]["robot"]`` and
    ``["control"]``: the tables as the scenario file (with the variant's overrides) writes
    them, not naming the worker's copies of the model files.
    """
    robot = dict(result.meta.get("robot") or {})
    if task.urdf is not None:
        robot["model"] = task.urdf.path
    robot.update(task.robot_meta or {})
    source = result.meta.get("scenario")
    if isinstance(source, dict):
        source = dict(source)
        for name in ("robot", "control"):
            original = task.doc.get(name)
            if isinstance(original, dict):
                source[name] = dict(original)
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

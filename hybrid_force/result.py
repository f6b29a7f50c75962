"""One simulation run on disk and in memory: the :class:`Result` object and its metrics.

A :class:`Result` holds the time series of one closed-loop run (issue 5 item 4)
and a JSON-able ``meta`` dict (scenario, robot, surfaces, path, gains, settings, events, status,
software versions, speed).  It is saved to, and loaded from, a single ``.npz`` file with exactly
the arrays ``t q v q_d u p p_d f f_d phi V phase`` plus ``meta`` (the JSON text as a 0-d numpy
unicode array); no pickle is involved, so ``np.load(path, allow_pickle=False)`` reads it.

Saving is atomic: the archive is written to a temporary file in the target's directory, flushed
and fsync'ed, then moved onto the target with :func:`os.replace`.  A crash or Ctrl-C during the
write leaves any earlier file at the target untouched and removes the temporary file.

:meth:`Result.metrics` computes the numbers the paper (section 6) and issue 5 report (position
and force errors, constraint drift, contact, impacts, convergence) with
:func:`hybrid_force.metrics.compute_metrics`.

Units: SI throughout (s, m, rad, N, N·m, J, N·s).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import zipfile
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.lib.npyio import NpzFile

from hybrid_force._atomic import atomic_file
from hybrid_force.errors import BadInputError, DimensionError, ResultFileError
from hybrid_force.events import EVENT_KINDS  # re-exported: the kinds a run records
from hybrid_force.law_log import check_law_log
from hybrid_force.metrics import (  # re-exported: the metrics of a result, computed there
    CONVERGE_TOLERANCE,
    DEFAULT_SETTLE_TIME,
    Metrics,
    compute_metrics,
)
from hybrid_force.phases import Phase

__all__ = [
    "ARRAY_NAMES",
    "CONVERGE_TOLERANCE",
    "DEFAULT_SETTLE_TIME",
    "EVENT_KINDS",
    "OPTIONAL_ARRAYS",
    "PHASE_CONTACT",
    "PHASE_FREE",
    "PHASE_NEAR",
    "Metrics",
    "Result",
    "load_result",
]

#: The arrays of a result file, in schema order (``meta`` is stored beside them).
ARRAY_NAMES: tuple[str, ...] = (
    "t",
    "q",
    "v",
    "q_d",
    "u",
    "p",
    "p_d",
    "f",
    "f_d",
    "phi",
    "V",
    "phase",
)
#: Arrays a result file may hold beyond :data:`ARRAY_NAMES` (older files lack them; see
#: :class:`Result` for the value then).
OPTIONAL_ARRAYS: tuple[str, ...] = ("f_meas", "u_cmd", "law_log", "tool_angle")
#: Phase codes of the ``phase`` array.
PHASE_FREE, PHASE_NEAR, PHASE_CONTACT = Phase.FREE, Phase.NEAR, Phase.CONTACT
_PHASES = tuple(int(p) for p in Phase)
_STATUSES = ("ok", "failed")
_META_KEY = "meta"
#: Deepest nesting of lists and objects accepted in a loaded result's meta.
MAX_META_DEPTH = 64
#: Most members an archive may hold (a result has 13).
_MAX_MEMBERS = 64


# --------------------------------------------------------------------------- helpers
def _json_default(obj: Any) -> Any:
    """Turn numpy scalars/arrays and paths into plain JSON values (used by ``json.dumps``)."""
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, (tuple, set, frozenset)):
        return list(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON-able")


def _meta_to_json(meta: Mapping[str, Any]) -> str:
    """Serialise ``meta`` to strict JSON text (no NaN/inf); BadInputError if impossible."""
    try:
        return json.dumps(meta, default=_json_default, allow_nan=False, sort_keys=False)
    except (TypeError, ValueError) as exc:
        raise BadInputError(
            f"Result meta must be JSON-able without NaN/inf (use None): {exc}"
        ) from exc


def _as_float_array(name: str, value: Any) -> np.ndarray:
    """Return ``value`` as a new read-only float64 array; BadInputError for non-real data."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        raise BadInputError(
            f"Result array '{name}' must hold real numbers (float64), got dtype {arr.dtype}"
        )
    out = np.array(arr, dtype=np.float64, copy=True)
    out.setflags(write=False)
    return out


def _as_phase_array(value: Any) -> np.ndarray:
    """Return ``value`` as a new read-only int64 array of phase codes 0/1/2."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "iu":
        raise BadInputError(
            f"Result array 'phase' must hold integers (int64: 0 free, 1 near, 2 contact), "
            f"got dtype {arr.dtype}"
        )
    out = np.array(arr, dtype=np.int64, copy=True)
    bad = ~np.isin(out, _PHASES)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise BadInputError(
            f"Result array 'phase' has value {int(out.flat[i])} at sample {i}; "
            f"valid phases are 0 (free), 1 (near), 2 (contact)"
        )
    out.setflags(write=False)
    return out


def _check_shape(name: str, arr: np.ndarray, expected: tuple[int, ...]) -> None:
    """Raise DimensionError naming ``name`` unless ``arr.shape == expected``."""
    if arr.shape != expected:
        raise DimensionError(
            f"Result array '{name}' must have shape {expected}, got shape {tuple(arr.shape)}"
        )


def _json_depth(value: Any) -> int:
    """Nesting depth of JSON data (0 for a scalar), without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, dict):
            node = list(node.values())
        if isinstance(node, list):
            deepest = max(deepest, depth + 1)
            if deepest > MAX_META_DEPTH:
                return deepest
            stack.extend((child, depth + 1) for child in node)
    return deepest


def _check_archive(fh: Any, src: Path) -> None:
    """Refuse, before anything is decompressed or allocated, an archive whose arrays would not
    fit in memory or whose .npy headers claim more data than their member holds.

    The sizes checked are the zip directory's uncompressed sizes, which ``zipfile`` enforces
    while reading, and each array header's shape × item size against its member's size (numpy
    allocates the claimed shape before reading). Zip and header errors propagate to
    :meth:`Result.load`, which reports them as an unreadable archive.
    """
    from numpy.lib import format as npy_format

    from hybrid_force.sim.run_checks import available_memory

    if fh.read(6) == b"\x93NUMPY":
        raise ResultFileError(
            f"result file '{src}' holds a single numpy array, not an .npz result archive"
        )
    fh.seek(0)
    with zipfile.ZipFile(fh) as archive:
        members = archive.infolist()
        if len(members) > _MAX_MEMBERS:
            raise ResultFileError(
                f"result file '{src}' has {len(members)} members; a result has "
                f"{len(ARRAY_NAMES) + 1}"
            )
        total = sum(m.file_size for m in members)
        free = available_memory()
        if free is not None and 2 * total > free:
            raise ResultFileError(
                f"result file '{src}' would take {total / 2**30:.3g} GiB once decompressed "
                f"(twice that while loading); {free / 2**30:.3g} GiB of memory is available"
            )
        for member in members:
            # numpy serves "t" as well as "t.npy" as array "t": check every member that
            # holds an array, whatever its name
            with archive.open(member) as npy:
                if npy.read(6) != b"\x93NUMPY":
                    continue
                npy.seek(0)
                version = npy_format.read_magic(npy)
                if version == (1, 0):
                    shape, _, dtype = npy_format.read_array_header_1_0(npy)
                else:
                    shape, _, dtype = npy_format.read_array_header_2_0(npy)
            claimed = math.prod(shape) * dtype.itemsize
            if claimed > member.file_size:
                name = member.filename.removesuffix(".npy")
                raise ResultFileError(
                    f"result file '{src}': array '{name}' claims shape "
                    f"{shape} ({claimed} bytes) but its member holds {member.file_size} bytes"
                )


def _fsync_directory(directory: Path) -> None:
    """Best-effort fsync of a directory so a completed rename survives a power cut (POSIX)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


# --------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False, repr=False)
class Result:
    """Time series and metadata of one run (the result schema of issue 5 item 4).

    N samples, n joints, k constraints (k = 1 in the paper).  Arrays are copied on
    construction, converted to float64 (``phase``: int64) and made read-only.

    Attributes:
        t: (N,) time [s], strictly increasing.
        q: (N, nq) joint configuration [rad or m].
        v: (N, n) joint velocity [rad/s or m/s].
        q_d: (N, nq) desired configuration [rad or m].
        u: (N, n) joint torque/force applied to the arm [N·m or N] (the command, saturated
            at the effort limits when the plant enforces them, ``sim.torque_limits``).
        p, p_d: (N, 3) actual / desired tip position [m].
        f, f_d: (N,) (or (N, k) for k > 1) contact force along the unit surface normal pointing to
            the free side, > 0 when the tool presses on the surface, 0 out of contact [N].
        phi: (N,) (or (N, k)) signed metric distance of the tip to the surface, > 0 free side [m].
        V: (N,) Lyapunov function ½ sᵀ M s + ½ β e_F² of paper section 5.1 [J].
        phase: (N,) int64 phase code: 2 (contact) exactly when the tool is on the surface
            (the plant's contact state); otherwise the supervisor's approach phase, 0 free or
            1 near (a sample off the surface is never 2, whatever the controller assumed).
        f_meas: (N,) or (N, k) the contact force the controller measured and used at each
            sample (held between control ticks) [N]; with ideal sensing at the plant's rate it
            is f itself (also the value for files written before it existed).
        u_cmd: (N, n) the torque the controller commanded [N·m or N]; u itself where no
            effort limit acted (also the value for files written before it existed).
        law_log: (N, m) the control law's own signals at each sample (e.g. its parameter
            estimates), named by ``meta["law_log_names"]`` (:mod:`hybrid_force.law_log`);
            (N, 0) when the law logs nothing (also the value for older files).
        tool_angle: (N,) the angle [rad] between the actual tool axis and its desired direction
            a_d(t) (``[tool] orientation = "normal"``); None, and absent from the file, when
            the run did not control the tool's direction (``orientation = "free"``).
        meta: JSON-able dict (name, scenario, robot, surfaces, path, gains, settings, events,
            status, error, versions, steps_per_second, wall_time); stored as a normalised copy.
            steps_per_second counts the loop from its second step on (the first steps load
            or, after installation, compile the kernels); wall_time is the whole loop [s].

    For all-revolute/prismatic arms nq = n.  For arms with continuous or spherical joints
    (Pinocchio's nq > nv) ``q`` and ``q_d`` may have nq columns and ``v``, ``u`` n = nv columns.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    q_d: np.ndarray
    u: np.ndarray
    p: np.ndarray
    p_d: np.ndarray
    f: np.ndarray
    f_d: np.ndarray
    phi: np.ndarray
    V: np.ndarray
    phase: np.ndarray
    meta: dict[str, Any] = field(default_factory=dict)
    f_meas: np.ndarray | None = None
    u_cmd: np.ndarray | None = None
    law_log: np.ndarray | None = None
    tool_angle: np.ndarray | None = None

    # ------------------------------------------------------------------ validation
    def __post_init__(self) -> None:
        """Copy, convert and validate every array and ``meta`` (DimensionError/BadInputError)."""
        arrays = {
            name: _as_phase_array(getattr(self, name))
            if name == "phase"
            else _as_float_array(name, getattr(self, name))
            for name in ARRAY_NAMES
        }
        t = arrays["t"]
        if t.ndim != 1:
            raise DimensionError(
                f"Result array 't' must have shape (N,), got shape {tuple(t.shape)}"
            )
        n_samples = t.shape[0]
        q = arrays["q"]
        if q.ndim != 2 or q.shape[0] != n_samples or q.shape[1] < 1:
            raise DimensionError(
                f"Result array 'q' must have shape (N, nq) = ({n_samples}, nq ≥ 1), "
                f"got shape {tuple(q.shape)}"
            )
        nq = q.shape[1]
        v = arrays["v"]
        if v.ndim != 2 or v.shape[0] != n_samples or not 1 <= v.shape[1] <= nq:
            raise DimensionError(
                f"Result array 'v' must have shape (N, n) = ({n_samples}, {nq}) "
                f"(n ≤ nq = {nq} for continuous/spherical joints), got shape {tuple(v.shape)}"
            )
        n = v.shape[1]
        _check_shape("q_d", arrays["q_d"], (n_samples, nq))
        _check_shape("u", arrays["u"], (n_samples, n))
        _check_shape("p", arrays["p"], (n_samples, 3))
        _check_shape("p_d", arrays["p_d"], (n_samples, 3))
        _check_shape("V", arrays["V"], (n_samples,))
        _check_shape("phase", arrays["phase"], (n_samples,))
        f = arrays["f"]
        if f.ndim == 2 and f.shape[0] == n_samples and f.shape[1] >= 2:
            constraint_shape: tuple[int, ...] = (n_samples, f.shape[1])
        else:
            constraint_shape = (n_samples,)
        for name in ("f", "f_d", "phi"):
            arr = arrays[name]
            if arr.shape != constraint_shape:
                raise DimensionError(
                    f"Result array '{name}' must have shape {constraint_shape} like 'f' "
                    f"((N,) for one constraint, (N, k) for k ≥ 2), got shape {tuple(arr.shape)}"
                )
        if not np.all(np.isfinite(t)):
            raise BadInputError("Result array 't' must be finite")
        if n_samples > 1 and not np.all(np.diff(t) > 0.0):
            i = int(np.flatnonzero(np.diff(t) <= 0.0)[0])
            raise BadInputError(
                f"Result array 't' must be strictly increasing; t[{i}] = {t[i]!r} and "
                f"t[{i + 1}] = {t[i + 1]!r}"
            )
        f_meas = arrays["f"] if self.f_meas is None else _as_float_array("f_meas", self.f_meas)
        if f_meas.shape != constraint_shape:
            raise DimensionError(
                f"Result array 'f_meas' must have shape {constraint_shape} like 'f', got shape "
                f"{tuple(f_meas.shape)}"
            )
        u_cmd = arrays["u"] if self.u_cmd is None else _as_float_array("u_cmd", self.u_cmd)
        _check_shape("u_cmd", u_cmd, (n_samples, n))
        if self.tool_angle is not None:
            tool_angle = _as_float_array("tool_angle", self.tool_angle)
            _check_shape("tool_angle", tool_angle, (n_samples,))
            object.__setattr__(self, "tool_angle", tool_angle)
        meta = self._normalise_meta(self.meta)
        law_log = check_law_log(self.law_log, n_samples, meta)
        for name, arr in arrays.items():
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "f_meas", f_meas)
        object.__setattr__(self, "u_cmd", u_cmd)
        object.__setattr__(self, "law_log", law_log)
        object.__setattr__(self, "meta", meta)

    @staticmethod
    def _normalise_meta(meta: Any) -> dict[str, Any]:
        """Return a JSON round-tripped copy of ``meta`` after checking status and events."""
        if not isinstance(meta, Mapping):
            raise BadInputError(f"Result meta must be a dict, got {type(meta).__name__}")
        out = json.loads(_meta_to_json(meta))
        status = out.get("status", "ok")
        if status not in _STATUSES:
            raise BadInputError(
                f"Result meta 'status' is {status!r}; valid values are {', '.join(_STATUSES)}"
            )
        events = out.get("events", [])
        if not isinstance(events, list):
            raise BadInputError(f"Result meta 'events' must be a list, got {type(events).__name__}")
        for i, ev in enumerate(events):
            if not isinstance(ev, dict):
                raise BadInputError(f"Result meta events[{i}] must be a dict, got {ev!r}")
            if not isinstance(ev.get("kind"), str):
                raise BadInputError(
                    f"Result meta events[{i}] needs a string 'kind' (one of "
                    f"{', '.join(EVENT_KINDS)}), got {ev!r}"
                )
            t_ev = ev.get("t")
            if isinstance(t_ev, bool) or not isinstance(t_ev, (int, float)):
                raise BadInputError(f"Result meta events[{i}] needs a numeric 't' [s], got {ev!r}")
        return out

    def __repr__(self) -> str:
        return (
            f"Result(name={self.meta.get('name')!r}, status={self.status!r}, "
            f"n_samples={self.n_samples}, n_joints={self.n_joints}, "
            f"n_constraints={self.n_constraints}, events={len(self.events)})"
        )

    # ------------------------------------------------------------------ properties
    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.t.shape[0])

    @property
    def n_joints(self) -> int:
        """Number of joints n (columns of ``v`` and ``u``; equals nq for revolute/prismatic)."""
        return int(self.v.shape[1])

    @property
    def nq(self) -> int:
        """Number of configuration coordinates (columns of ``q`` and ``q_d``)."""
        return int(self.q.shape[1])

    @property
    def n_constraints(self) -> int:
        """Number of stacked surface constraints k (1 when ``f`` is (N,))."""
        return 1 if self.f.ndim == 1 else int(self.f.shape[1])

    @property
    def events(self) -> list[dict[str, Any]]:
        """Copies of the events of ``meta["events"]`` (dicts with at least "t" and "kind")."""
        return [dict(ev) for ev in self.meta.get("events", [])]

    @property
    def status(self) -> str:
        """``"ok"`` or ``"failed"`` (``meta["status"]``, ``"ok"`` if absent)."""
        return str(self.meta.get("status", "ok"))

    @property
    def failed(self) -> bool:
        """True if the run failed (it then holds the samples up to the failure)."""
        return self.status == "failed"

    # ------------------------------------------------------------------ derived results
    def truncated(self, n: int) -> Result:
        """Return a new Result with the first ``n`` samples (0 ≤ n ≤ N); meta is kept as is."""
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
            raise BadInputError(f"truncated(n): n must be an int, got {n!r}")
        if not 0 <= n <= self.n_samples:
            raise BadInputError(
                f"truncated(n): n must be in [0, {self.n_samples}] (the number of samples), got {n}"
            )
        stop = int(n)
        arrays: dict[str, Any] = {
            name: getattr(self, name)[:stop]
            for name in (*ARRAY_NAMES, *OPTIONAL_ARRAYS)
            if getattr(self, name) is not None
        }
        return Result(**arrays, meta=self.meta)

    def slice(self, stop: int) -> Result:
        """Return a new Result with the first ``stop`` samples (same as :meth:`truncated`)."""
        return self.truncated(stop)

    def with_meta(self, **updates: Any) -> Result:
        """Return a copy whose meta has the given top-level keys replaced (e.g. ``status``)."""
        meta = dict(self.meta)
        meta.update(updates)
        return dataclasses.replace(self, meta=meta)

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write this result atomically to ``path`` (one uncompressed ``.npz``); return the path.

        The archive is written to a temporary file in the same directory, flushed and
        fsync'ed, then moved onto ``path`` with :func:`os.replace`.  On any exception,
        including KeyboardInterrupt, the temporary file is removed and the exception re-raised;
        an existing file at ``path`` is untouched until the final replace.  The parent
        directory is created if missing.  The file name is used as given (no suffix added).
        """
        target = Path(path)
        if target.is_dir():
            raise ResultFileError(f"cannot save result to '{target}': it is a directory")
        meta_text = _meta_to_json(self.meta)
        payload: dict[str, Any] = {
            name: getattr(self, name)
            for name in (*ARRAY_NAMES, *OPTIONAL_ARRAYS)
            if getattr(self, name) is not None  # tool_angle: only when the run has one
        }
        payload[_META_KEY] = np.array(meta_text, dtype=np.str_)
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ResultFileError(
                f"cannot save result to '{target}': cannot create directory "
                f"'{target.parent}': {exc}"
            ) from exc
        with atomic_file(target) as fh:
            np.savez(fh, **payload)
        _fsync_directory(target.parent)
        return target

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Result:
        """Read a result saved by :meth:`save`.

        Raises:
            ResultFileError: naming the file, if it is missing, not an npz archive (truncated or
                garbage), lacks arrays (listed), has no or bad ``meta`` JSON, or holds arrays of
                inconsistent shapes or dtypes.
        """
        src = Path(path)
        if not src.exists():
            raise ResultFileError(f"result file '{src}' does not exist")
        if not src.is_file():
            raise ResultFileError(f"result file '{src}' is not a regular file")
        data: dict[str, np.ndarray] = {}
        try:
            # open the file ourselves: np.load leaks its handle when the zip is corrupt
            with src.open("rb") as fh:
                _check_archive(fh, src)
                fh.seek(0)
                loaded = np.load(fh, allow_pickle=False)
                if not isinstance(loaded, NpzFile):
                    raise ResultFileError(
                        f"result file '{src}' holds a single numpy array, not an .npz result "
                        f"archive"
                    )
                with loaded as npz:
                    names = set(npz.files)
                    missing = [n for n in (*ARRAY_NAMES, _META_KEY) if n not in names]
                    if missing:
                        found = ", ".join(sorted(names)) or "none"
                        raise ResultFileError(
                            f"result file '{src}' is not a complete hybrid_force result: "
                            f"missing array(s) {', '.join(missing)} (found: {found})"
                        )
                    for name in (*ARRAY_NAMES, *OPTIONAL_ARRAYS, _META_KEY):
                        if name in names:
                            data[name] = npz[name]
        except ResultFileError:
            raise
        except (
            OSError,
            ValueError,
            EOFError,
            zipfile.BadZipFile,
            zlib.error,
            KeyError,
            RuntimeError,
        ) as exc:  # RuntimeError: an encrypted member; NotImplementedError: unknown compression
            raise ResultFileError(
                f"result file '{src}' is not a readable .npz archive (truncated or not a "
                f"hybrid_force result): {type(exc).__name__}: {exc}"
            ) from exc
        meta_arr = data.pop(_META_KEY)
        if meta_arr.shape != () or meta_arr.dtype.kind != "U":
            raise ResultFileError(
                f"result file '{src}': 'meta' must be a 0-d unicode string array of JSON text, "
                f"got dtype {meta_arr.dtype} shape {meta_arr.shape}"
            )
        try:
            meta = json.loads(str(meta_arr))
        except json.JSONDecodeError as exc:
            raise ResultFileError(f"result file '{src}': 'meta' is not valid JSON: {exc}") from exc
        except RecursionError:
            meta = None  # nested beyond Python's recursion limit: refused just below
        depth = _json_depth(meta) if meta is not None else MAX_META_DEPTH + 1
        if depth > MAX_META_DEPTH:
            raise ResultFileError(
                f"result file '{src}': 'meta' is nested more than {MAX_META_DEPTH} levels deep "
                "(a result's meta needs about 5)"
            )
        if not isinstance(meta, dict):
            raise ResultFileError(
                f"result file '{src}': 'meta' must be a JSON object, got {type(meta).__name__}"
            )
        try:
            return cls(**data, meta=meta)
        except BadInputError as exc:
            raise ResultFileError(f"result file '{src}' is inconsistent: {exc}") from exc

    # ------------------------------------------------------------------ metrics
    def metrics(
        self,
        settle_time: float | None = None,
        converge_tolerance: float = CONVERGE_TOLERANCE,
    ) -> Metrics:
        """Compute the run's :class:`Metrics`.

        Args:
            settle_time: start [s] of the "settled" window; defaults to
                ``meta["settings"]["settle_time"]``, else 5.0 s.
            converge_tolerance: position error norm [m] for ``time_to_converge`` (1e-3 m).
        """
        return compute_metrics(self, settle_time, converge_tolerance)

    def summary(self, settle_time: float | None = None) -> dict[str, Any]:
        """JSON-able dict: what the run was and how it ended, then its :class:`Metrics`.

        Keys: name, run_id (the same in result.npz's meta: a summary and a result with the same
        run_id describe the same run), status ("ok" or "failed"), reason (None, "diverged",
        "lost contact", "interrupted", "path", "error"), error, warnings (lines), steps_per_second,
        n_samples, t_end [s] (the last sample: earlier than the duration for a failed run),
        n_events, contact_at_end, lost_contact, left_contact_at [s], joint_range_exceeded,
        velocity_exceeded and effort_exceeded (joint names; details in meta["limits"]),
        saturated_time ({joint: seconds} the applied torque was held at an effort limit),
        friction_energy and damping_energy [J] (dissipated by the contact's friction and
        compliant damping, docs/contact.md), then the metrics. Keys whose
        value the run did not record (older results) are None or empty.
        """
        meta = self.meta
        limits = meta.get("limits") or {}
        out: dict[str, Any] = {
            "name": meta.get("name"),
            "run_id": meta.get("run_id"),
            "status": self.status,
            "reason": meta.get("reason"),
            "error": meta.get("error"),
            "warnings": list(meta.get("warnings") or []),
            "steps_per_second": meta.get("steps_per_second"),
            "n_samples": self.n_samples,
            "t_end": float(self.t[-1]) if self.n_samples else None,
            "n_events": len(self.events),
            "contact_at_end": meta.get("contact_at_end"),
            "lost_contact": meta.get("lost_contact"),
            "left_contact_at": meta.get("left_at"),
            "joint_range_exceeded": [v["joint"] for v in limits.get("position", [])],
            "velocity_exceeded": [v["joint"] for v in limits.get("velocity", [])],
            "effort_exceeded": [v["joint"] for v in limits.get("effort", [])],
            "saturated_time": dict(meta.get("saturated_time") or {}),
            "friction_energy": meta.get("friction_energy"),
            "damping_energy": meta.get("damping_energy"),
        }
        out.update(self.metrics(settle_time).to_dict())
        return out


def load_result(path: str | os.PathLike[str]) -> Result:
    """Read a result file; same as :meth:`Result.load` (ResultFileError naming the file)."""
    return Result.load(path)

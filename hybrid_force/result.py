"""One simulation run in memory: the :class:`Result` dataclass, its checks and its metrics.

A :class:`Result` holds the time series of one closed-loop run and a JSON-able ``meta`` dict
(scenario, robot, surfaces, path, gains, settings, events, status, software versions, speed).
Its arrays are checked on construction (shapes, dtypes, phase codes, increasing time).
Saving and loading the single ``.npz`` file are in :mod:`hybrid_force.result_file` (atomic
write, checked read), the summary in :mod:`hybrid_force.result_summary`, the metrics in
:mod:`hybrid_force.metrics`; :class:`Result` calls them.

Units: SI throughout (s, m, rad, N, N·m, J, N·s).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hybrid_force.errors import BadInputError
from hybrid_force.events import EVENT_KINDS
from hybrid_force.law_log import check_law_log
from hybrid_force.metrics import (
    CONVERGE_TOLERANCE,
    Metrics,
    compute_metrics,
)
from hybrid_force.phases import Phase
from hybrid_force.result_file import (
    ARRAY_NAMES,
    OPTIONAL_ARRAYS,
    REMOVAL_ARRAYS,
    meta_to_json,
    read_arrays,
    write_arrays,
)
from hybrid_force.result_summary import summarise

__all__ = ["PHASE_CONTACT", "PHASE_FREE", "PHASE_NEAR", "Result", "load_result"]

#: Phase codes of the ``phase`` array.
PHASE_FREE, PHASE_NEAR, PHASE_CONTACT = Phase.FREE, Phase.NEAR, Phase.CONTACT
_PHASES = tuple(int(p) for p in Phase)
_STATUSES = ("ok", "failed")


# --------------------------------------------------------------------------- helpers
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
    """Raise BadInputError naming ``name`` unless ``arr.shape == expected``."""
    if arr.shape != expected:
        raise BadInputError(
            f"Result array '{name}' must have shape {expected}, got shape {tuple(arr.shape)}"
        )


# --------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False, repr=False)
class Result:
    """Time series and metadata of one run.

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
        phi: (N,) (or (N, k)) signed metric distance of the tip to the surface, > 0 free side [m]
            (for a ball-end tool, of its centre to the offset surface: the ball's gap to the part).
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
        contact_point: (N, 3) (or (N, k, 3) for k > 1) where a ball-end tool touches the part
            [m]: p − r n̂, r = ``tool.radius``, n̂ the unit normal at the tool centre p (the
            ball's point nearest the part when it is off it; NaN where n̂ is undefined); None,
            and absent from the file, for a point tool (``tool.radius = 0``).
        removal_points, removal_depth, removal_target: the removal grid of a run with
            ``[removal]`` (docs/removal.md): the cells' centres (M, 3) [m] on the surface, the
            depth removed (M,) [m], and (M,) 1.0 for a cell of the target region, else 0.0
            (the metrics' region, ``meta["removal"]``); None, and absent from the file,
            without removal. Per cell, not per sample: :meth:`truncated` keeps them whole.
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
    contact_point: np.ndarray | None = None
    removal_points: np.ndarray | None = None
    removal_depth: np.ndarray | None = None
    removal_target: np.ndarray | None = None

    # ------------------------------------------------------------------ validation
    def __post_init__(self) -> None:
        """Copy, convert and validate every array and ``meta`` (BadInputError/BadInputError)."""
        arrays = {
            name: _as_phase_array(getattr(self, name))
            if name == "phase"
            else _as_float_array(name, getattr(self, name))
            for name in ARRAY_NAMES
        }
        t = arrays["t"]
        if t.ndim != 1:
            raise BadInputError(
                f"Result array 't' must have shape (N,), got shape {tuple(t.shape)}"
            )
        n_samples = t.shape[0]
        q = arrays["q"]
        if q.ndim != 2 or q.shape[0] != n_samples or q.shape[1] < 1:
            raise BadInputError(
                f"Result array 'q' must have shape (N, nq) = ({n_samples}, nq ≥ 1), "
                f"got shape {tuple(q.shape)}"
            )
        nq = q.shape[1]
        v = arrays["v"]
        if v.ndim != 2 or v.shape[0] != n_samples or not 1 <= v.shape[1] <= nq:
            raise BadInputError(
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
                raise BadInputError(
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
            raise BadInputError(
                f"Result array 'f_meas' must have shape {constraint_shape} like 'f', got shape "
                f"{tuple(f_meas.shape)}"
            )
        u_cmd = arrays["u"] if self.u_cmd is None else _as_float_array("u_cmd", self.u_cmd)
        _check_shape("u_cmd", u_cmd, (n_samples, n))
        if self.tool_angle is not None:
            tool_angle = _as_float_array("tool_angle", self.tool_angle)
            _check_shape("tool_angle", tool_angle, (n_samples,))
            object.__setattr__(self, "tool_angle", tool_angle)
        if self.contact_point is not None:
            contact = _as_float_array("contact_point", self.contact_point)
            k = 1 if len(constraint_shape) == 1 else constraint_shape[1]
            _check_shape("contact_point", contact, (n_samples, 3) if k == 1 else (n_samples, k, 3))
            object.__setattr__(self, "contact_point", contact)
        self._check_removal()
        meta = self._normalise_meta(self.meta)
        law_log = check_law_log(self.law_log, n_samples, meta)
        for name, arr in arrays.items():
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "f_meas", f_meas)
        object.__setattr__(self, "u_cmd", u_cmd)
        object.__setattr__(self, "law_log", law_log)
        object.__setattr__(self, "meta", meta)

    def _check_removal(self) -> None:
        """The removal arrays: all three or none, (M, 3), (M,), (M,) of one M."""
        given = [getattr(self, name) is not None for name in REMOVAL_ARRAYS]
        if not any(given):
            return
        if not all(given):
            only = [n for n in REMOVAL_ARRAYS if getattr(self, n) is not None]
            raise BadInputError(
                f"Result arrays {', '.join(REMOVAL_ARRAYS)} come together (a run with "
                f"[removal]); got only {', '.join(only)}"
            )
        points = _as_float_array("removal_points", self.removal_points)
        if points.ndim != 2 or points.shape[1] != 3:
            raise BadInputError(
                f"Result array 'removal_points' must have shape (M, 3), got {points.shape}"
            )
        m = points.shape[0]
        object.__setattr__(self, "removal_points", points)
        for name in REMOVAL_ARRAYS[1:]:
            arr = _as_float_array(name, getattr(self, name))
            _check_shape(name, arr, (m,))
            object.__setattr__(self, name, arr)

    @staticmethod
    def _normalise_meta(meta: Any) -> dict[str, Any]:
        """Return a JSON round-tripped copy of ``meta`` after checking status and events."""
        if not isinstance(meta, Mapping):
            raise BadInputError(f"Result meta must be a dict, got {type(meta).__name__}")
        out = json.loads(meta_to_json(meta))
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
        whole = {name: getattr(self, name) for name in REMOVAL_ARRAYS}  # per cell: kept
        return Result(**arrays, **whole, meta=self.meta)

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
        arrays = {
            name: getattr(self, name)
            for name in (*ARRAY_NAMES, *OPTIONAL_ARRAYS, *REMOVAL_ARRAYS)
            if getattr(self, name) is not None  # tool_angle, contact_point: when the run has one
        }
        write_arrays(target, arrays, meta_to_json(self.meta))
        return target

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Result:
        """Read a result saved by :meth:`save`.

        Raises:
            BadInputError: naming the file, if it is missing, not an npz archive (truncated or
                garbage), lacks arrays (listed), has no or bad ``meta`` JSON, or holds arrays of
                inconsistent shapes or dtypes.
        """
        if not isinstance(path, str | os.PathLike):
            raise BadInputError(f"a result file is named by a path, got {path!r:.80}")
        src = Path(path)
        data, meta = read_arrays(src)
        try:
            return cls(**data, meta=meta)
        except BadInputError as exc:
            raise BadInputError(f"result file '{src}' is inconsistent: {exc}") from exc

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
        """JSON-able dict: what the run was and how it ended, then its :class:`Metrics`
        (the keys: :func:`~hybrid_force.result_summary.summarise`)."""
        return summarise(self, settle_time)


def load_result(path: str | os.PathLike[str]) -> Result:
    """Read a result file; same as :meth:`Result.load` (BadInputError naming the file)."""
    return Result.load(path)

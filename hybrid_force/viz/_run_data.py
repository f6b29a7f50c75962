"""The arrays of one run that the figures need, checked, and the times they mark.

:func:`_load_run` reads a :class:`hybrid_force.result.Result` (or anything with the same
attributes, or the path of a saved ``.npz``) into a :class:`_Run` with its shapes checked; the
helpers below find the phase switches, the contact intervals and the zoom windows in its time axis.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid_force.errors import BadInputError
from hybrid_force.law_log import check_law_log, law_log_names
from hybrid_force.phases import CONTACT, NEAR
from hybrid_force.result import Result

_ZOOM_S = 10.0  # [s] zoom window of force_error.png and window of desired_force.png
_SWITCH_KINDS = ("near", "contact", "impact", "release")


# --------------------------------------------------------------------------------------------
# The run, checked
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Run:
    """The arrays of one run that the figures need, with shapes checked.

    t: (N,) [s]; p, p_d: (N, 3) [m]; f, f_d, phi: (N, k) [N, N, m]; f_meas: (N, k) the force
    the controller measured [N], or None when it is f (ideal sensing); V: (N,) [J];
    phase: (N,) int (0 free, 1 near, 2 contact); surfaces: surface dicts of the schema;
    events: (t [s], kind) pairs of meta["events"], sorted by time; law_log: (N, m) the law's
    own signals named by law_log_names (m = 0 when it logged none); tool_angle: (N,) [rad] the
    tool axis' angle from its desired direction, or None (a run that did not control it);
    settle_time: meta["settings"]["settle_time"] [s], or None.
    """

    name: str
    t: np.ndarray
    p: np.ndarray
    p_d: np.ndarray
    f: np.ndarray
    f_d: np.ndarray
    V: np.ndarray
    phase: np.ndarray
    surfaces: tuple[Mapping[str, Any], ...]
    events: tuple[tuple[float, str], ...]
    f_meas: np.ndarray | None = None
    law_log: np.ndarray | None = None
    law_log_names: tuple[str, ...] = ()
    tool_angle: np.ndarray | None = None
    settle_time: float | None = None

    @property
    def k(self) -> int:
        """Number of constraints (columns of f)."""
        return int(self.f.shape[1])

    @property
    def contact(self) -> np.ndarray:
        """(N,) bool: samples in the contact phase."""
        return self.phase == CONTACT


def _array(result: object, attr: str) -> np.ndarray:
    if not hasattr(result, attr):
        raise BadInputError(
            f"cannot plot {type(result).__name__}: it has no attribute {attr!r} "
            "(expected a hybrid_force Result with t, p, p_d, f, f_d, V, phase, meta)"
        )
    try:
        return np.asarray(getattr(result, attr), dtype=float)
    except (TypeError, ValueError) as exc:
        raise BadInputError(f"result.{attr} is not a numeric array: {exc}") from exc


def _as_columns(a: np.ndarray, attr: str, n: int) -> np.ndarray:
    """(N,) or (N, k) → (N, k)."""
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] != n or a.shape[1] < 1:
        raise BadInputError(f"result.{attr} has shape {a.shape}; expected ({n},) or ({n}, k)")
    return a


def _read_events(meta: Mapping[str, Any]) -> tuple[tuple[float, str], ...]:
    raw = meta.get("events") or []
    if not isinstance(raw, Sequence) or isinstance(raw, str):
        raise BadInputError(
            f"result meta['events'] must be a list of dicts, got {type(raw).__name__}"
        )
    events: list[tuple[float, str]] = []
    for i, ev in enumerate(raw):
        if not isinstance(ev, Mapping) or "t" not in ev or "kind" not in ev:
            raise BadInputError(
                f"result meta['events'][{i}] = {ev!r} lacks the keys 't' and 'kind'"
            )
        try:
            te = float(ev["t"])
        except (TypeError, ValueError) as exc:
            raise BadInputError(
                f"result meta['events'][{i}]['t'] = {ev['t']!r} is not a number"
            ) from exc
        if not math.isfinite(te):
            raise BadInputError(f"result meta['events'][{i}]['t'] = {te} is not finite")
        events.append((te, str(ev["kind"])))
    return tuple(sorted(events))


def _read_surfaces(meta: Mapping[str, Any]) -> tuple[Mapping[str, Any], ...]:
    raw = meta.get("surfaces") or []
    if not isinstance(raw, Sequence) or isinstance(raw, str):
        raw = [raw]
    out: list[Mapping[str, Any]] = []
    for i, s in enumerate(raw):
        if hasattr(s, "to_dict"):
            s = s.to_dict()
        if not isinstance(s, Mapping):
            raise BadInputError(f"result meta['surfaces'][{i}] = {s!r} is not a surface dict")
        out.append(s)
    return tuple(out)


def _load_run(result: object) -> _Run:
    """Check a Result (or a path to a saved one) and gather what the figures need."""
    if isinstance(result, str | os.PathLike):
        result = Result.load(result)
    t = _array(result, "t")
    if t.ndim != 1 or t.shape[0] < 2:
        raise BadInputError(
            f"result.t has shape {t.shape}; need a 1-D time vector of at least 2 samples"
        )
    if not np.all(np.isfinite(t)):
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise BadInputError(f"result.t[{bad}] = {t[bad]} is not finite")
    n = t.shape[0]
    p, p_d = _array(result, "p"), _array(result, "p_d")
    for attr, a in (("p", p), ("p_d", p_d)):
        if a.shape != (n, 3):
            raise BadInputError(f"result.{attr} has shape {a.shape}; expected ({n}, 3)")
    f = _as_columns(_array(result, "f"), "f", n)
    f_d = _as_columns(_array(result, "f_d"), "f_d", n)
    if f_d.shape != f.shape:
        raise BadInputError(f"result.f_d has shape {f_d.shape} but result.f has shape {f.shape}")
    v = _array(result, "V")
    if v.shape != (n,):
        raise BadInputError(f"result.V has shape {v.shape}; expected ({n},)")
    phase = np.asarray(getattr(result, "phase", np.zeros(n)))
    if phase.shape != (n,):
        raise BadInputError(f"result.phase has shape {phase.shape}; expected ({n},)")
    meta = getattr(result, "meta", None) or {}
    if not isinstance(meta, Mapping):
        raise BadInputError(f"result.meta must be a dict, got {type(meta).__name__}")
    name = str(meta.get("name") or "unnamed run")
    f_meas = getattr(result, "f_meas", None)
    if f_meas is not None:
        f_meas = _as_columns(np.asarray(f_meas, dtype=float), "f_meas", n)
        if f_meas.shape != f.shape or np.array_equal(f_meas, f):
            f_meas = None  # ideal sensing: nothing more to draw
    law_log, law_names = _read_law_log(result, meta, n)
    tool_angle = getattr(result, "tool_angle", None)
    if tool_angle is not None:
        tool_angle = np.asarray(tool_angle, dtype=float)
        if tool_angle.shape != (n,):
            raise BadInputError(f"result.tool_angle has shape {tool_angle.shape}; expected ({n},)")
    settle = (meta.get("settings") or {}).get("settle_time")
    return _Run(
        name=name,
        t=t,
        p=p,
        p_d=p_d,
        f=f,
        f_d=f_d,
        V=v,
        phase=phase.astype(np.int64),
        surfaces=_read_surfaces(meta),
        events=_read_events(meta),
        f_meas=f_meas,
        law_log=law_log,
        law_log_names=law_names,
        tool_angle=tool_angle,
        settle_time=float(settle) if isinstance(settle, int | float) else None,
    )


def _read_law_log(
    result: object, meta: Mapping[str, Any], n: int
) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """The law's own signals (N, m) and their names, or (None, ()) when it logged none."""

    value = getattr(result, "law_log", None)
    try:
        names = law_log_names(meta)
        if value is None or not names:
            return None, ()
        return check_law_log(np.asarray(value, dtype=float), n, meta), names
    except (ValueError, TypeError) as exc:  # the checks' BadInputError is a ValueError
        raise BadInputError(f"result.law_log: {exc}") from exc


# --------------------------------------------------------------------------------------------
# Time helpers
# --------------------------------------------------------------------------------------------
def _zoom_end(t: np.ndarray) -> float:
    """End [s] of the force-error zoom: 10 s after the start, or half the run if it is shorter."""
    duration = float(t[-1] - t[0])
    return float(t[0] + (_ZOOM_S if duration > _ZOOM_S else 0.5 * duration))


def _window_end(t: np.ndarray) -> float:
    """End [s] of the desired-force window: the first 10 s, or the whole run if shorter."""
    return float(min(t[-1], t[0] + _ZOOM_S))


def _phase_switches(t: np.ndarray, phase: np.ndarray) -> list[tuple[float, str]]:
    """(time [s], kind) at each change of `phase`: → near, → contact, contact → release, → free."""
    out: list[tuple[float, str]] = []
    for i in np.flatnonzero(np.diff(phase) != 0) + 1:
        old, new = int(phase[i - 1]), int(phase[i])
        if new == CONTACT:
            kind = "contact"
        elif old == CONTACT:
            kind = "release"
        elif new == NEAR:
            kind = "near"
        else:
            kind = "free"
        out.append((float(t[i]), kind))
    return out


def _switches(run: _Run) -> list[tuple[float, str]]:
    """Switches to mark: meta events of kind near/contact/impact/release, else phase changes."""
    marked = [(te, kind) for te, kind in run.events if kind in _SWITCH_KINDS]
    return marked if marked else _phase_switches(run.t, run.phase)


def _intervals(t: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """(start [s], width [s]) of each run of true samples of mask (N,) over time t (N,).

    A run of samples i..j covers [t[i], t[j + 1]) (up to t[-1] for a run reaching the end).
    """
    m = np.concatenate([[False], mask.astype(bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    starts, stops = edges[0::2], edges[1::2]  # stops: one past the last true sample
    ends = t[np.minimum(stops, t.size - 1)]
    return [(float(t[a]), float(e - t[a])) for a, e in zip(starts, ends, strict=True)]

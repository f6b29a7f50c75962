"""The numbers that say how well one run went: :class:`Metrics` and :func:`compute_metrics`.

Position error per axis and its norm, force error ``|f - f_d|`` while in contact, worst
constraint drift, contact time, impact impulse and speed, and the time to converge: what the
paper (section 6) and issue 5 report. :meth:`hybrid_force.result.Result.metrics` calls
:func:`compute_metrics`.

Units: SI throughout (s, m, N, N·s).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from hybrid_force.errors import BadInputError
from hybrid_force.phases import Phase

if TYPE_CHECKING:  # annotations only: result imports this module
    from hybrid_force.result import Result

__all__ = ["CONVERGE_TOLERANCE", "DEFAULT_SETTLE_TIME", "Metrics", "compute_metrics"]

#: Settling time [s] used by :func:`compute_metrics` when ``meta["settings"]`` has none.
DEFAULT_SETTLE_TIME = 5.0
#: ``time_to_converge`` is the first time after which ``||p - p_d||`` stays below this [m].
CONVERGE_TOLERANCE = 1e-3


def _finite_rows(*arrays: np.ndarray) -> np.ndarray:
    """Boolean mask (N,) of samples where every given array is finite."""
    mask = np.ones(arrays[0].shape[0], dtype=bool)
    for a in arrays:
        fin = np.isfinite(a)
        mask &= np.all(fin, axis=tuple(range(1, fin.ndim)))  # also for N = 0
    return mask


def _max_or_none(x: np.ndarray) -> float | None:
    return float(np.max(x)) if x.size else None


def _rms_or_none(x: np.ndarray) -> float | None:
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else None


@dataclass(frozen=True)
class Metrics:
    """Error and contact metrics of one run (issue 5 item 4; paper section 6).

    Position error ``e = p - p_d`` [m]; force error ``|f - f_d|`` [N] over contact samples
    (phase 2) only (with k > 1 constraints, the Euclidean norm over the k components).
    "Settled" values use the samples with ``t >= settle_time``.  A value that does not apply
    (no samples after ``settle_time``, never in contact, no impact, never converged) is ``None``,
    never NaN.  Samples with non-finite values (e.g. the last sample of a diverged run) are
    skipped; the run's ``status`` says it failed.

    Attributes:
        settle_time: time [s] from which the "settled" metrics are taken.
        position_error_max_axis: (3,) max ``|e_x|, |e_y|, |e_z|`` for t ≥ settle_time [m].
        position_error_rms_axis: (3,) RMS of ``e_x, e_y, e_z`` for t ≥ settle_time [m].
        position_error_max: max ``||e||`` over the whole run [m].
        position_error_max_settled: max ``||e||`` for t ≥ settle_time [m].
        position_error_rms_settled: RMS of ``||e||`` for t ≥ settle_time [m].
        final_position_error: ``||e||`` at the last sample [m].
        force_error_max_settled: max ``|f - f_d|`` over contact samples with t ≥ settle_time [N].
        force_error_rms_settled: RMS of ``|f - f_d|`` over the same samples [N].
        final_force_error: ``|f - f_d|`` at the last sample if it is in contact, else None [N].
        worst_constraint_violation: max ``|phi|`` over all contact samples [m].
        contact_time: time of the first "contact" event, else of the first phase-2 sample [s].
        impact_impulse: sum of ``|impulse|`` of the "impact" events (0.0 if none) [N·s].
        impact_speed: max ``speed`` of the "impact" events (None if none) [m/s].
        n_impacts: number of "impact" events.
        time_to_converge: first time after which ``||e||`` stays below ``converge_tolerance``
            until the end of the run [s].
        converge_tolerance: the tolerance used for ``time_to_converge`` [m].
        tool_angle_final: the angle between the tool axis and its desired direction at the
            last sample [rad]; None when the run did not control it (``[tool] orientation =
            "free"``: the result has no ``tool_angle``).
        tool_angle_max_settled: its maximum for t ≥ settle_time [rad] (None likewise).
    """

    settle_time: float
    position_error_max_axis: tuple[float, float, float] | None
    position_error_rms_axis: tuple[float, float, float] | None
    position_error_max: float | None
    position_error_max_settled: float | None
    position_error_rms_settled: float | None
    final_position_error: float | None
    force_error_max_settled: float | None
    force_error_rms_settled: float | None
    final_force_error: float | None
    worst_constraint_violation: float | None
    contact_time: float | None
    impact_impulse: float
    impact_speed: float | None
    n_impacts: int
    time_to_converge: float | None
    converge_tolerance: float = CONVERGE_TOLERANCE
    tool_angle_final: float | None = None
    tool_angle_max_settled: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able dict (floats, ints, lists, None) with the attribute names as keys."""
        out: dict[str, Any] = {}
        for fld in dataclasses.fields(self):
            value = getattr(self, fld.name)
            out[fld.name] = list(value) if isinstance(value, tuple) else value
        return out


def compute_metrics(
    result: Result,
    settle_time: float | None = None,
    converge_tolerance: float = CONVERGE_TOLERANCE,
) -> Metrics:
    """Compute the :class:`Metrics` of one run.

    Args:
        result: the run (its arrays t (N,) [s], p, p_d (N, 3) [m], f, f_d, phi (N,) or (N, k),
            phase (N,), and meta's events and settings).
        settle_time: start [s] of the "settled" window; defaults to
            ``meta["settings"]["settle_time"]``, else :data:`DEFAULT_SETTLE_TIME`.
        converge_tolerance: position error norm [m] for ``time_to_converge`` (1e-3 m).
    """
    if settle_time is None:
        settings = result.meta.get("settings") or {}
        settle_time = settings.get("settle_time", DEFAULT_SETTLE_TIME)
    if isinstance(settle_time, bool) or not isinstance(settle_time, (int, float)):
        raise BadInputError(f"metrics: settle_time must be a number [s], got {settle_time!r}")
    settle = float(settle_time)
    if not math.isfinite(settle):
        raise BadInputError(f"metrics: settle_time must be finite, got {settle_time!r}")
    tol = float(converge_tolerance)
    if not (math.isfinite(tol) and tol > 0.0):
        raise BadInputError(
            f"metrics: converge_tolerance must be a positive number [m], got {converge_tolerance!r}"
        )

    t = result.t
    e = result.p - result.p_d  # (N, 3) [m]
    e_ok = _finite_rows(e)
    e_norm = np.linalg.norm(e, axis=1)  # (N,) [m]
    settled = t >= settle
    pos_win = e_ok & settled
    e_set = e[pos_win]
    max_axis: tuple[float, ...] | None
    rms_axis: tuple[float, ...] | None
    if e_set.shape[0]:
        max_axis = tuple(float(x) for x in np.max(np.abs(e_set), axis=0))
        rms_axis = tuple(float(x) for x in np.sqrt(np.mean(np.square(e_set), axis=0)))
    else:
        max_axis = rms_axis = None
    final_pos = float(e_norm[-1]) if result.n_samples and e_ok[-1] else None

    # force error over contact samples; k > 1: Euclidean norm over the k constraints
    df = result.f - result.f_d
    ef = np.abs(df) if df.ndim == 1 else np.linalg.norm(df, axis=1)  # (N,) [N]
    contact = result.phase == Phase.CONTACT
    f_ok = _finite_rows(ef)
    f_win = contact & settled & f_ok
    last_contact = result.n_samples > 0 and bool(contact[-1]) and bool(f_ok[-1])
    final_force = float(ef[-1]) if last_contact else None

    phi_abs = np.abs(result.phi) if result.phi.ndim == 1 else np.max(np.abs(result.phi), axis=1)
    viol = phi_abs[contact & _finite_rows(phi_abs)]

    events = result.events
    contact_events = [float(ev["t"]) for ev in events if ev["kind"] == "contact"]
    if contact_events:
        contact_time: float | None = min(contact_events)
    elif np.any(contact):
        contact_time = float(t[int(np.argmax(contact))])
    else:
        contact_time = None
    impacts = [ev for ev in events if ev["kind"] == "impact"]
    impulse = 0.0
    speeds: list[float] = []
    for ev in impacts:
        if ev.get("impulse") is not None:
            impulse += float(np.linalg.norm(np.atleast_1d(np.asarray(ev["impulse"], float))))
        if ev.get("speed") is not None:
            speeds.append(abs(float(ev["speed"])))

    # first time after which ||e|| < tol until the end (non-finite counts as "not below")
    above = ~(e_ok & (e_norm < tol))
    if result.n_samples == 0 or above[-1]:
        converge: float | None = None
    elif not np.any(above):
        converge = float(t[0])
    else:
        converge = float(t[int(np.flatnonzero(above)[-1]) + 1])

    tool_final: float | None = None
    tool_max: float | None = None
    tool_angle = getattr(result, "tool_angle", None)
    if tool_angle is not None and result.n_samples:
        tool_ok = np.isfinite(tool_angle)
        tool_final = float(tool_angle[-1]) if tool_ok[-1] else None
        tool_max = _max_or_none(tool_angle[tool_ok & settled])

    return Metrics(
        settle_time=settle,
        position_error_max_axis=max_axis,  # type: ignore[arg-type]
        position_error_rms_axis=rms_axis,  # type: ignore[arg-type]
        position_error_max=_max_or_none(e_norm[e_ok]),
        position_error_max_settled=_max_or_none(e_norm[pos_win]),
        position_error_rms_settled=_rms_or_none(e_norm[pos_win]),
        final_position_error=final_pos,
        force_error_max_settled=_max_or_none(ef[f_win]),
        force_error_rms_settled=_rms_or_none(ef[f_win]),
        final_force_error=final_force,
        worst_constraint_violation=_max_or_none(viol),
        contact_time=contact_time,
        impact_impulse=impulse,
        impact_speed=max(speeds) if speeds else None,
        n_impacts=len(impacts),
        time_to_converge=converge,
        converge_tolerance=tol,
        tool_angle_final=tool_final,
        tool_angle_max_settled=tool_max,
    )

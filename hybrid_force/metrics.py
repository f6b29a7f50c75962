"""The numbers that say how well one run went: :class:`Metrics` and :func:`compute_metrics`.

Position error per axis and its norm, force error ``|f - f_d|`` while in contact, worst
constraint drift, contact time, impact impulse and speed, and the time to converge: what the
paper (section 6) and issue 5 report. :meth:`hybrid_force.result.Result.metrics` calls
:func:`compute_metrics`.

:class:`TrackingMetrics` (:func:`compute_tracking_metrics`) adds what a comparison of control
laws needs (``hybrid-force compare``): the path error along the surface
(:func:`tangential_component` of the position error, the normals from
:func:`surface_normals`), the force peak after the first contact (:func:`impact_force_peak`),
the share of time off the surface after it (:func:`out_of_contact_fraction`), the time after
which both errors stay small (:func:`time_staying_within`) and the largest joint torque.

Units: SI throughout (s, m, N, N·s).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from hybrid_force.errors import BadInputError
from hybrid_force.phases import CONTACT, Phase

if TYPE_CHECKING:
    from hybrid_force.geometry.surface_base import Surface

__all__ = [
    "CONVERGE_TOLERANCE",
    "DEFAULT_SETTLE_TIME",
    "FORCE_TOLERANCE",
    "IMPACT_WINDOW",
    "Metrics",
    "TrackingMetrics",
    "compute_metrics",
    "compute_tracking_metrics",
    "force_error",
    "impact_force_peak",
    "out_of_contact_fraction",
    "path_error",
    "surface_normals",
    "tangential_component",
    "time_staying_within",
]


class RunRecord(Protocol):
    """What every reader of a run finds in it (:class:`RunArrays`,
    :class:`~hybrid_force.result_summary.SummarisedRun`): the sample times t (N,) [s], the
    run's meta, its sample count N and its events."""

    @property
    def t(self) -> np.ndarray: ...
    @property
    def meta(self) -> dict[str, Any]: ...
    @property
    def n_samples(self) -> int: ...
    @property
    def events(self) -> list[dict[str, Any]]: ...


class RunArrays(RunRecord, Protocol):
    """What the metrics read of a run: a :class:`~hybrid_force.result.Result` (whose module
    imports this one), or anything with the same arrays."""

    @property
    def p(self) -> np.ndarray: ...
    @property
    def p_d(self) -> np.ndarray: ...
    @property
    def f(self) -> np.ndarray: ...
    @property
    def f_d(self) -> np.ndarray: ...
    @property
    def phi(self) -> np.ndarray: ...
    @property
    def phase(self) -> np.ndarray: ...
    @property
    def u(self) -> np.ndarray: ...


#: Settling time [s] used by :func:`compute_metrics` when ``meta["settings"]`` has none.
DEFAULT_SETTLE_TIME = 5.0
#: ``time_to_converge`` is the first time after which ``||p - p_d||`` stays below this [m]
#: (and the path tolerance of :attr:`TrackingMetrics.time_to_settle`).
CONVERGE_TOLERANCE = 1e-3
#: The force tolerance [N] of :attr:`TrackingMetrics.time_to_settle`.
FORCE_TOLERANCE = 1.0
#: :func:`impact_force_peak` looks this long [s] after the first contact.
IMPACT_WINDOW = 0.5


def _settle_time(result: RunArrays, settle_time: float | None) -> float:
    """The settling time [s]: ``settle_time``, else the run's ``sim.settle_time``, else 5 s."""
    if settle_time is None:
        settings = result.meta.get("settings") or {}
        settle_time = settings.get("settle_time", DEFAULT_SETTLE_TIME)
    if isinstance(settle_time, bool) or not isinstance(settle_time, (int, float)):
        raise BadInputError(
            f"metrics: settle_time must be a number [s], got {settle_time!r}",
            key="settle_time",
            value=settle_time,
        )
    settle = float(settle_time)
    if not math.isfinite(settle):
        raise BadInputError(
            f"metrics: settle_time must be finite, got {settle_time!r}",
            key="settle_time",
            value=settle_time,
        )
    return settle


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
    result: RunArrays,
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
    settle = _settle_time(result, settle_time)
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

    ef = force_error(result)  # (N,) [N]
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

    # non-finite counts as "not below"
    converge = time_staying_within(t, e_ok & (e_norm < tol))

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


# ----------------------------------------------------------------------------- tracking
def force_error(result: RunArrays) -> np.ndarray:
    """(N,) force error ``|f - f_d|`` [N] at every sample (k > 1: the Euclidean norm over the k
    constraints); off the surface f = 0, so it is ``|f_d|`` there."""
    df = result.f - result.f_d
    return np.abs(df) if df.ndim == 1 else np.linalg.norm(df, axis=1)


def time_staying_within(t: np.ndarray, within: np.ndarray) -> float | None:
    """The first time [s] from which ``within`` holds at every sample until the end.

    Args:
        t: (N,) sample times [s], increasing.
        within: (N,) bool: the sample is within its tolerance.

    Returns:
        ``t[i]`` for the smallest i with ``within[i:]`` all true (``t[0]`` when every sample
        is within); None when the last sample is not, or N = 0.
    """
    inside = np.asarray(within, dtype=bool)
    if inside.shape[0] == 0 or not inside[-1]:
        return None
    outside = np.flatnonzero(~inside)
    return float(t[0] if outside.size == 0 else t[int(outside[-1]) + 1])


def tangential_component(e: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """The part of each vector e orthogonal to its sample's surface normals.

    ``e_t = e − P e``, with P the orthogonal projector onto the span of the sample's normals
    (``P = G⁺ G`` for the (k, 3) matrix G of its normals; for one unit normal n,
    ``e_t = e − (e·n) n``). So ``e_t · n = 0`` for every normal n and
    ``‖e‖² = ‖e_t‖² + ‖P e‖²``. The normals need not be unit or orthogonal; a zero normal
    spans nothing (nothing is removed along it).

    Args:
        e: (N, 3) vectors, e.g. the position error p − p_d [m].
        normals: (N, 3) one normal per sample, or (N, k, 3) k per sample.

    Returns:
        (N, 3) e_t; NaN rows where e or a normal is not finite.

    Raises:
        BadInputError: e not (N, 3), or normals neither (N, 3) nor (N, k, 3).
    """
    e = np.asarray(e, dtype=float)
    g = np.asarray(normals, dtype=float)
    if g.ndim == 2:
        g = g[:, None, :]
    if e.ndim != 2 or e.shape[1] != 3:
        raise BadInputError(
            f"tangential_component: e must have shape (N, 3), got {e.shape}", key="e", value=e.shape
        )
    if g.ndim != 3 or g.shape[0] != e.shape[0] or g.shape[2] != 3:
        raise BadInputError(
            f"tangential_component: normals must have shape ({e.shape[0]}, 3) or "
            f"({e.shape[0]}, k, 3), got {np.shape(normals)}",
            key="normals",
            value=np.shape(normals),
        )
    ok = _finite_rows(e, g)
    out = np.full(e.shape, np.nan)
    if np.any(ok):
        gk = g[ok]  # (M, k, 3)
        projector = np.linalg.pinv(gk) @ gk  # (M, 3, 3)
        out[ok] = e[ok] - np.einsum("mij,mj->mi", projector, e[ok])
    return out


def surface_normals(surfaces: Sequence[Surface], points: np.ndarray) -> np.ndarray:
    """(N, k, 3) unit normals ∇Φ_j/‖∇Φ_j‖ of the k surfaces at each of the points (N, 3) [m].

    A zero vector where a gradient vanishes (e.g. on a cylinder's axis), NaN rows where a
    point is not finite. Evaluated one point at a time (about 10 µs per point and surface).
    """
    pts = np.asarray(points, dtype=float)
    out = np.full((pts.shape[0], len(surfaces), 3), np.nan)
    ok = _finite_rows(pts)
    for i in np.flatnonzero(ok):
        for j, surface in enumerate(surfaces):
            g = surface.gradient(pts[i])
            norm = float(np.linalg.norm(g))
            out[i, j] = g / norm if norm > 0.0 else 0.0
    return out


def impact_force_peak(
    t: np.ndarray, f: np.ndarray, phase: np.ndarray, window: float = IMPACT_WINDOW
) -> float | None:
    """The largest contact force ``|f|`` [N] (k > 1: ‖f‖) within ``window`` [s] of the first
    contact: over the contact samples with ``t_c ≤ t ≤ t_c + window``, t_c the time of the first
    sample in phase 2 (contact). None if the run never touches. Non-finite samples are skipped.

    Args:
        t: (N,) [s]; f: (N,) or (N, k) contact force [N]; phase: (N,) phase codes.
    """
    contact = np.asarray(phase) == CONTACT
    if not np.any(contact):
        return None
    t0 = float(t[int(np.argmax(contact))])
    f = np.asarray(f, dtype=float)
    mag = np.abs(f) if f.ndim == 1 else np.linalg.norm(f, axis=1)
    win = contact & (t >= t0) & (t <= t0 + window) & np.isfinite(mag)
    return _max_or_none(mag[win])


def out_of_contact_fraction(t: np.ndarray, phase: np.ndarray) -> float | None:
    """The fraction of the time after the first contact spent off the surface, in [0, 1].

    Each sample i holds until the next one (a duration ``t[i+1] − t[i]``); the fraction is the
    summed duration of the samples not in phase 2 (contact) from the first contact sample
    on, over the time from that sample to the last one. None if the run never touches, or
    touches only at its last sample.

    Args:
        t: (N,) [s]; phase: (N,) phase codes.
    """
    contact = np.asarray(phase) == CONTACT
    if not np.any(contact):
        return None
    c = int(np.argmax(contact))
    durations = np.diff(np.asarray(t, dtype=float)[c:])  # samples c .. N-2
    total = float(np.sum(durations))
    if total <= 0.0:
        return None
    return float(np.sum(durations[~contact[c:-1]]) / total)


@dataclass(frozen=True)
class TrackingMetrics:
    """How well one run tracked the path along the surface and the force across it.

    What ``hybrid-force compare`` reports for each control law (docs/compare.md). The path
    error is the tangential part of the position error, ``e_t`` = :func:`tangential_component`
    of ``e = p − p_d`` with the surfaces' unit normals at the actual tip p: the error along
    the surface, the normal direction being the force loop's. "Settled": t ≥ settle_time.

    Attributes:
        settle_time: start [s] of the settled window.
        force_error_rms_settled, force_error_max_settled: RMS and max of ``|f − f_d|`` over
            the contact samples with t ≥ settle_time [N] (as :class:`Metrics`).
        impact_force_peak: :func:`impact_force_peak` with ``impact_window`` [N].
        path_error_rms_settled, path_error_max_settled: RMS and max of ``‖e_t‖`` over the
            samples with t ≥ settle_time [m].
        out_of_contact_fraction: :func:`out_of_contact_fraction` (dimensionless).
        time_to_settle: the first time [s] after which every sample is in contact with
            ``|f − f_d| < force_tolerance`` and ``‖e_t‖ < path_tolerance``
            (:func:`time_staying_within`).
        torque_max: max ``|u_j|`` over every joint and sample of the applied torque
            [N·m, N for a prismatic joint].
        path_tolerance [m], force_tolerance [N], impact_window [s]: the settings used.

    A value that does not apply (no sample in its window, never in contact, never settled)
    is None; samples with non-finite values are skipped.
    """

    settle_time: float
    force_error_rms_settled: float | None
    force_error_max_settled: float | None
    impact_force_peak: float | None
    path_error_rms_settled: float | None
    path_error_max_settled: float | None
    out_of_contact_fraction: float | None
    time_to_settle: float | None
    torque_max: float | None
    path_tolerance: float = CONVERGE_TOLERANCE
    force_tolerance: float = FORCE_TOLERANCE
    impact_window: float = IMPACT_WINDOW

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able dict with the attribute names as keys."""
        return dataclasses.asdict(self)


def path_error(result: RunArrays, surfaces: Sequence[Surface]) -> np.ndarray:
    """(N,) ``‖e_t‖`` [m]: the norm of the tangential part of ``p − p_d``, the normals of
    ``surfaces`` taken at p (:func:`tangential_component`, :func:`surface_normals`)."""
    e_t = tangential_component(result.p - result.p_d, surface_normals(surfaces, result.p))
    return np.linalg.norm(e_t, axis=1)


def compute_tracking_metrics(
    result: RunArrays,
    surfaces: Sequence[Surface],
    settle_time: float | None = None,
    *,
    path_tolerance: float = CONVERGE_TOLERANCE,
    force_tolerance: float = FORCE_TOLERANCE,
    impact_window: float = IMPACT_WINDOW,
    path_errors: np.ndarray | None = None,
) -> TrackingMetrics:
    """Compute the :class:`TrackingMetrics` of one run.

    Args:
        result: the run (t, p, p_d, f, f_d, phase, u and meta's settings).
        surfaces: the k surfaces of the run, in the order of the columns of f (their normals
            define the tangential path error).
        settle_time: start [s] of the settled window; default ``meta["settings"]
            ["settle_time"]``, else :data:`DEFAULT_SETTLE_TIME`.
        path_tolerance [m], force_tolerance [N]: the tolerances of ``time_to_settle``.
        impact_window: [s] see :func:`impact_force_peak`.
        path_errors: (N,) ``‖e_t‖`` [m] when the caller has it already
            (:func:`path_error` of the same result and surfaces); computed here if None.
    """
    settle = _settle_time(result, settle_time)
    for name, value in (
        ("path_tolerance", path_tolerance),
        ("force_tolerance", force_tolerance),
        ("impact_window", impact_window),
    ):
        if isinstance(value, bool) or not (isinstance(value, (int, float)) and value > 0.0):
            raise BadInputError(
                f"metrics: {name} must be a positive number, got {value!r}", key=name, value=value
            )
    k = 1 if result.f.ndim == 1 else result.f.shape[1]
    if len(surfaces) != k:
        raise BadInputError(
            f"metrics: the run has {k} constraint(s) but {len(surfaces)} surface(s) were given",
            key="surfaces",
            value=len(surfaces),
        )
    base = compute_metrics(result, settle)
    t = result.t
    e_t = path_error(result, surfaces) if path_errors is None else np.asarray(path_errors, float)
    if e_t.shape != t.shape:
        raise BadInputError(
            f"metrics: path_errors must have shape {t.shape}, got {e_t.shape}",
            key="path_errors",
            value=e_t.shape,
        )
    settled = (t >= settle) & np.isfinite(e_t)
    ef = force_error(result)
    contact = result.phase == CONTACT
    within = contact & (ef < force_tolerance) & (e_t < path_tolerance)  # NaN compares False
    u = np.abs(result.u)
    return TrackingMetrics(
        settle_time=settle,
        force_error_rms_settled=base.force_error_rms_settled,
        force_error_max_settled=base.force_error_max_settled,
        impact_force_peak=impact_force_peak(t, result.f, result.phase, impact_window),
        path_error_rms_settled=_rms_or_none(e_t[settled]),
        path_error_max_settled=_max_or_none(e_t[settled]),
        out_of_contact_fraction=out_of_contact_fraction(t, result.phase),
        time_to_settle=time_staying_within(t, within),
        torque_max=_max_or_none(u[np.isfinite(u)]),
        path_tolerance=float(path_tolerance),
        force_tolerance=float(force_tolerance),
        impact_window=float(impact_window),
    )

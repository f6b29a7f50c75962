"""The summary of a run: what it was, how it ended, and its metrics, as one JSON-able dict.

:func:`summarise` is what :meth:`hybrid_force.result.Result.summary` returns and what
``hybrid-force run`` writes as ``summary.json`` beside ``result.npz``; the sweep's table rows
are built from it too.
"""

from __future__ import annotations

from typing import Any, Protocol

from hybrid_force.metrics import Metrics, RunRecord

__all__ = ["REMOVAL_KEYS", "SummarisedRun", "summarise"]

REMOVAL_KEYS: tuple[str, ...] = (
    "removal_volume",
    "removal_depth_mean",
    "removal_depth_std",
    "removal_depth_min",
    "removal_depth_max",
    "removal_uniformity",
    "removal_coverage",
)
"""The removal metrics of a run with ``[removal]`` (docs/removal.md): the volume removed
[m³] (the whole grid), over the target region the area-weighted depth mean, std, min, max [m],
the uniformity 1 − std/mean and the coverage (area fraction with depth ≥ mean / 2)."""


class SummarisedRun(RunRecord, Protocol):
    """What the summary reads of a run: a :class:`~hybrid_force.result.Result` (whose module
    imports this one)."""

    @property
    def status(self) -> str: ...
    def metrics(self, settle_time: float | None = None) -> Metrics: ...


def summarise(result: SummarisedRun, settle_time: float | None = None) -> dict[str, Any]:
    """JSON-able dict: what the run was and how it ended, then its metrics.

    Keys: name, run_id (the same in result.npz's meta: a summary and a result with the same
    run_id describe the same run), status ("ok" or "failed"), reason (None, "diverged",
    "lost contact", "interrupted", "path", "error"), error, warnings (lines), steps_per_second,
    n_samples, t_end [s] (the last sample: earlier than the duration for a failed run),
    n_events, contact_at_end, lost_contact, left_contact_at [s], joint_range_exceeded,
    velocity_exceeded and effort_exceeded (joint names; details in meta["limits"]),
    saturated_time ({joint: seconds} the applied torque was held at an effort limit),
    friction_energy and damping_energy [J] (dissipated by the contact's friction and
    compliant damping, docs/contact.md), joint_damping_energy and joint_friction_energy [J]
    (dissipated by the joints' own damping and friction, the model's ``<dynamics>``),
    n_warnings (the number of lines in warnings: a sweep filters on it), touched (the tool was
    on the surface at some time), chatter (its releases each followed by a touch after the
    force first settled), force_settled (RMS |f − f_d| over the final part of the run within
    tolerance; None without contact or f_d; :func:`hybrid_force.sim.run_checks.run_behaviour`),
    then the metrics
    (:class:`~hybrid_force.metrics.Metrics`, with ``settle_time`` [s] as in
    :meth:`~hybrid_force.result.Result.metrics`), then the :data:`REMOVAL_KEYS` (None without
    ``[removal]``). Keys whose value the run did not record (older results) are None or
    empty.
    """
    meta = result.meta
    limits = meta.get("limits") or {}
    behaviour = meta.get("behaviour") or {}
    out: dict[str, Any] = {
        "name": meta.get("name"),
        "run_id": meta.get("run_id"),
        "status": result.status,
        "reason": meta.get("reason"),
        "error": meta.get("error"),
        "warnings": list(meta.get("warnings") or []),
        "n_warnings": len(meta.get("warnings") or []),
        "steps_per_second": meta.get("steps_per_second"),
        "n_samples": result.n_samples,
        "t_end": float(result.t[-1]) if result.n_samples else None,
        "n_events": len(result.events),
        "contact_at_end": meta.get("contact_at_end"),
        "lost_contact": meta.get("lost_contact"),
        "left_contact_at": meta.get("left_at"),
        "joint_range_exceeded": [v["joint"] for v in limits.get("position", [])],
        "velocity_exceeded": [v["joint"] for v in limits.get("velocity", [])],
        "effort_exceeded": [v["joint"] for v in limits.get("effort", [])],
        "saturated_time": dict(meta.get("saturated_time") or {}),
        "friction_energy": meta.get("friction_energy"),
        "damping_energy": meta.get("damping_energy"),
        "joint_damping_energy": meta.get("joint_damping_energy"),
        "joint_friction_energy": meta.get("joint_friction_energy"),
        "touched": behaviour.get("touched"),
        "chatter": behaviour.get("chatter"),
        "force_settled": behaviour.get("force_settled"),
    }
    out.update(result.metrics(settle_time).to_dict())
    removal = meta.get("removal")
    removal = removal if isinstance(removal, dict) else {}  # None without [removal]
    out.update({key: removal.get(key) for key in REMOVAL_KEYS})
    return out

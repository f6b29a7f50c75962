"""What a run must say about itself: memory it needs, limits it broke, contact it lost.

Checks made around :func:`hybrid_force.sim.loop.simulate`, none of which changes the physics:

* :func:`check_log_memory`: the run's log (one float64 row per sample) and the copies the
  result makes must fit in the memory available, or the run is refused before it starts;
* :func:`limit_violations`: joint positions outside the URDF's range, velocities beyond its
  velocity limits and commanded torques beyond its effort limits (the plant saturates the
  applied torque there when ``sim.torque_limits`` is on; :func:`saturated_time` says how long);
* :func:`contact_outcome`: whether the tool was on the surface at the end, and when it left.

Each returns plain JSON-able data stored in the result's ``meta`` and shown in the summary.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from hybrid_force.errors import BadInputError
from hybrid_force.events import LimitCrossed

__all__ = [
    "LOG_COPIES",
    "available_memory",
    "check_log_memory",
    "contact_outcome",
    "describe",
    "limit_events",
    "limit_slack",
    "limit_violations",
    "saturated_time",
]

#: Peak copies of the log held at the end of a run: the table, the trimmed arrays handed to
#: the Result and the Result's own read-only copies.
LOG_COPIES = 3
_LIMIT_TOL = 1e-9  # relative slack on a limit [−], so round-off on the bound is not a violation


def available_memory() -> int | None:
    """Memory [bytes] the system can give without swapping (MemAvailable), None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def check_log_memory(n_samples: int, width: int, duration: float, dt: float) -> int:
    """Refuse a run whose log would not fit in memory; return the bytes it needs.

    Args:
        n_samples: N, samples of the run (duration / dt + 1). width: float64 numbers per sample.
        duration, dt: sim.duration and sim.dt [s], named in the message.

    Raises:
        BadInputError: LOG_COPIES × N × width × 8 bytes exceed :func:`available_memory`.
    """
    needed = LOG_COPIES * n_samples * width * 8
    free = available_memory()
    if free is not None and needed > free:
        raise BadInputError(
            f"sim.duration = {duration:g} s at sim.dt = {dt:g} s records {n_samples} samples of "
            f"{width} numbers: the run needs {needed / 2**30:.3g} GiB of memory for its log "
            f"({LOG_COPIES} copies of {n_samples * width * 8 / 2**30:.3g} GiB) and "
            f"{free / 2**30:.3g} GiB is available; shorten sim.duration or raise sim.dt"
        )
    return needed


def _first_and_worst(
    t: np.ndarray, excess: np.ndarray, values: np.ndarray, limit: float
) -> dict[str, Any]:
    bad = np.flatnonzero(excess > 0.0)
    worst = int(bad[np.argmax(excess[bad])])
    return {
        "first_t": float(t[bad[0]]),
        "worst": float(values[worst]),
        "worst_t": float(t[worst]),
        "limit": float(limit),
        "samples": int(bad.size),
    }


def limit_slack(bound: np.ndarray | float, relative: bool = False) -> np.ndarray:
    """How far beyond a limit a value may lie before it counts as a crossing (round-off on the
    bound is not one): ``_LIMIT_TOL`` × max(1, |bound|), or × |bound| with ``relative`` (for
    magnitudes: velocity and effort). Infinite for an infinite bound."""
    size = np.abs(np.asarray(bound, dtype=float))
    return _LIMIT_TOL * (size if relative else np.maximum(1.0, size))


def limit_violations(
    joint_names: Sequence[str],
    lower: np.ndarray,
    upper: np.ndarray,
    effort: np.ndarray,
    t: np.ndarray,
    q: np.ndarray,
    u: np.ndarray,
    velocity: np.ndarray | None = None,
    v: np.ndarray | None = None,
) -> dict[str, list[dict[str, Any]]]:
    """Joints that left their range or velocity limit, and joints whose command exceeded the
    effort limit.

    Args:
        joint_names: (n,) names of the arm's joints, one per column of q and u (nq = nv).
        lower, upper: (n,) joint range [rad or m]; ±inf where there is none.
        effort: (n,) effort limits [N·m or N]; +inf where there is none.
        t: (N,) time [s]. q: (N, n) positions. u: (N, n) commanded torques.
        velocity: (n,) velocity limits [rad/s or m/s] (+inf: none); v: (N, n) velocities.

    Returns:
        ``{"position": [...], "velocity": [...], "effort": [...]}``, one dict per offending
        joint: ``joint``, ``first_t`` [s], ``worst`` (the value furthest beyond), ``worst_t``,
        ``limit`` (the bound it crossed) and ``samples`` (how many samples were beyond).
    """
    out: dict[str, list[dict[str, Any]]] = {"position": [], "velocity": [], "effort": []}
    if t.size == 0:
        return out
    if v is None or velocity is None:
        v, velocity = np.zeros_like(u), np.full(u.shape[1], np.inf)
    finite_rows = (
        np.all(np.isfinite(q), axis=1)
        & np.all(np.isfinite(u), axis=1)
        & np.all(np.isfinite(v), axis=1)
    )
    t, q, u, v = t[finite_rows], q[finite_rows], u[finite_rows], v[finite_rows]
    if t.size == 0:
        return out
    for j, name in enumerate(joint_names):
        for bound, sign in ((upper[j], 1.0), (lower[j], -1.0)):
            if np.isfinite(bound):
                excess = sign * (q[:, j] - bound) - limit_slack(bound)
                if np.any(excess > 0.0):
                    out["position"].append(
                        {"joint": name, **_first_and_worst(t, excess, q[:, j], bound)}
                    )
        for key, limit, values in (
            ("velocity", velocity[j], v[:, j]),
            ("effort", effort[j], u[:, j]),
        ):
            if np.isfinite(limit):
                excess = np.abs(values) - (limit + limit_slack(limit, relative=True))
                if np.any(excess > 0.0):
                    out[key].append({"joint": name, **_first_and_worst(t, excess, values, limit)})
    return out


def limit_events(limits: dict[str, list[dict[str, Any]]]) -> list[LimitCrossed]:
    """One event per joint that crossed a position or velocity limit, at the first crossing
    (kind ``"joint_limit"`` or ``"velocity_limit"``)."""
    return [
        LimitCrossed(item["first_t"], item["joint"], item["limit"], kind)
        for key, kind in (("position", "joint_limit"), ("velocity", "velocity_limit"))
        for item in limits.get(key, [])
    ]


def saturated_time(
    joint_names: Sequence[str], effort: np.ndarray, u_cmd: np.ndarray, dt: float
) -> dict[str, float]:
    """{joint: time [s]} during which the commanded torque u_cmd (N, n) was beyond the effort
    limit (n,) and the applied torque was held at it: samples × dt; joints never saturated are
    left out."""
    out: dict[str, float] = {}
    for j, name in enumerate(joint_names):
        if np.isfinite(effort[j]):
            beyond = np.abs(u_cmd[:, j]) > effort[j] + limit_slack(effort[j], relative=True)
            count = int(np.count_nonzero(beyond))
            if count:
                out[name] = count * dt
    return out


def contact_outcome(
    ever_in_contact: bool, in_contact_at_end: bool, events: Sequence[dict[str, Any]]
) -> dict[str, Any]:
    """Where the tool ended: ``contact_at_end``, ``lost_contact`` and ``left_at`` [s].

    ``lost_contact`` is True when the tool was on the surface at some time (at the start, or
    after a touch) and is off it at the end; ``left_at`` is then the time of the last release.
    """
    releases = [float(e["t"]) for e in events if e.get("kind") == "release"]
    lost = ever_in_contact and not in_contact_at_end
    return {
        "contact_at_end": bool(in_contact_at_end),
        "lost_contact": bool(lost),
        "left_at": (releases[-1] if releases else None) if lost else None,
    }


def describe(
    limits: dict[str, list[dict[str, Any]]],
    outcome: dict[str, Any],
    saturated: dict[str, float] | None = None,
) -> list[str]:
    """One line per problem of :func:`limit_violations` and :func:`contact_outcome`;
    ``saturated`` ({joint: s}, :func:`saturated_time`) when the plant enforced the limits."""
    notes: list[str] = []
    for item in limits["position"]:
        notes.append(
            f"joint {item['joint']} left its range (limit {item['limit']:.6g}) at "
            f"t = {item['first_t']:.6g} s, reaching {item['worst']:.6g} "
            f"at t = {item['worst_t']:.6g} s"
        )
    for item in limits.get("velocity", []):
        notes.append(
            f"joint {item['joint']} exceeded its velocity limit {item['limit']:.6g} at "
            f"t = {item['first_t']:.6g} s, reaching {item['worst']:.6g} "
            f"at t = {item['worst_t']:.6g} s"
        )
    for item in limits["effort"]:
        if saturated is None:
            applied = "the plant applied it unsaturated"
        else:
            held = saturated.get(item["joint"], 0.0)
            applied = f"the applied torque was held at the limit for {held:.6g} s"
        notes.append(
            f"joint {item['joint']} was commanded {item['worst']:.6g} "
            f"at t = {item['worst_t']:.6g} s, beyond its effort limit {item['limit']:.6g} "
            f"(first at t = {item['first_t']:.6g} s; {applied})"
        )
    if outcome["lost_contact"]:
        left = outcome["left_at"]
        when = f" at t = {left:.6g} s" if left is not None else ""
        notes.append(f"the tool left the surface{when} and was not on it at the end")
    return notes

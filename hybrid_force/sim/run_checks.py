"""What a run must say about itself: memory it needs, limits it broke, contact it lost.

Checks made around :func:`hybrid_force.sim.loop.simulate`, none of which changes the physics:

* :func:`check_log_memory`: the run's log (one float64 row per sample) and the copies the
  result makes must fit in the memory available, or the run is refused before it starts;
* :func:`limit_violations`: joint positions outside the URDF's range, velocities beyond its
  velocity limits and commanded torques beyond its effort limits (the plant saturates the
  applied torque there when ``sim.torque_limits`` is on; :func:`saturated_time` says how long);
* :func:`contact_outcome`: whether the tool was on the surface at the end, and when it left.

Each returns plain JSON-able data stored in the result's ``meta`` and shown in the summary.
Three more stop a run: :func:`check_contact_step` refuses a time step too long for the
contact model before it starts, :func:`check_finite` (a non-finite or runaway state) and
:class:`JointLimits` (``sim.joint_limits = "stop"``) raise at the sample that breaks them;
:class:`SampleChecks` makes both at every sample and times the Python warnings raised.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from hybrid_force._memory import available_memory
from hybrid_force.errors import OWN_WARNINGS, BadInputError, RunFailedError, ScenarioError
from hybrid_force.events import LimitCrossed
from hybrid_force.metrics import FORCE_TOLERANCE
from hybrid_force.sim.contact import largest_stable_dt, step_text

if TYPE_CHECKING:  # annotations only: the loop's settings import this module's callers
    from hybrid_force.model.robot import Robot
    from hybrid_force.sim.settings import Scenario, SimSettings

__all__ = [
    "LOG_COPIES",
    "JointLimits",
    "SampleChecks",
    "check_contact_step",
    "check_finite",
    "check_log_memory",
    "contact_outcome",
    "describe",
    "joint_names",
    "limit_events",
    "limit_slack",
    "limit_violations",
    "saturated_time",
]

#: Peak copies of the log held at the end of a run: the table, the trimmed arrays handed to
#: the Result and the Result's own read-only copies.
LOG_COPIES = 3
_LIMIT_TOL = 1e-9  # relative slack on a limit [−], so round-off on the bound is not a violation


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
    joint_names: Sequence[str],
    effort: np.ndarray,
    u: np.ndarray,
    u_cmd: np.ndarray,
    dt: float,
) -> dict[str, float]:
    """{joint: time [s]} during which a limit was applied: the applied torque u (N, n) held at
    the effort limit (n,), ±effort exactly, while the command u_cmd (N, n) differed from it;
    samples × dt; joints never held are left out.

    A command beyond the limit that the plant did not hold there (the limits off,
    ``sim.torque_limits = false``) is not counted: :func:`limit_violations` reports it.
    """
    out: dict[str, float] = {}
    for j, name in enumerate(joint_names):
        if np.isfinite(effort[j]):
            held = (np.abs(u[:, j]) == effort[j]) & (u_cmd[:, j] != u[:, j])
            count = int(np.count_nonzero(held))
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


class JointLimits:
    """The position and velocity limits a run with ``sim.joint_limits = "stop"`` stops at."""

    def __init__(self, robot: Robot) -> None:
        # the slack of run_checks.limit_violations: round-off on a bound is no crossing
        lower, upper = robot.position_limits
        self.lower, self.upper = lower - limit_slack(lower), upper + limit_slack(upper)
        velocity = robot.velocity_limits
        self.velocity = velocity + limit_slack(velocity, relative=True)
        self.names = joint_names(robot)
        self.any = bool(np.isfinite(lower).any() or np.isfinite(upper).any())
        self.any |= bool(np.isfinite(velocity).any())

    def check(self, t: float, q: np.ndarray, v: np.ndarray) -> None:
        """Raise RunFailedError naming the first joint beyond a limit at time t [s]."""
        if (
            np.all(q >= self.lower)
            and np.all(q <= self.upper)
            and np.all(np.abs(v) <= self.velocity)
        ):
            return
        for j, name in enumerate(self.names):
            if not self.lower[j] <= q[j] <= self.upper[j]:
                raise RunFailedError(
                    f"joint {name} left its range [{self.lower[j]:.6g}, {self.upper[j]:.6g}] at "
                    f't = {t:.6g} s (q = {q[j]:.6g}; sim.joint_limits = "stop")',
                    reason="joint limit",
                )
            if j < v.shape[0] and not abs(v[j]) <= self.velocity[j]:
                raise RunFailedError(
                    f"joint {name} exceeded its velocity limit {self.velocity[j]:.6g} at "
                    f't = {t:.6g} s (v = {v[j]:.6g}; sim.joint_limits = "stop")',
                    reason="joint limit",
                )


class SampleChecks:
    """The checks of every sample of a run, and the times of the Python warnings it raises.

    Args:
        sc: the run (its ``sim`` bounds and ``sim.joint_limits``, its arm's limits).
        caught: the list ``warnings.catch_warnings(record=True)`` fills during the run.
    """

    def __init__(self, sc: Scenario, caught: list[Any]) -> None:
        self.sim, self.caught = sc.sim, caught
        #: [s] the simulated time at which each caught warning was raised
        self.caught_at: list[float] = []
        # sim.joint_limits = "stop": position and velocity limits checked at every sample
        stop_at = JointLimits(sc.robot) if sc.sim.joint_limits == "stop" else None
        self.stop_at = stop_at if stop_at is not None and stop_at.any else None

    def check(self, t: float, ok: bool, q: np.ndarray, v: np.ndarray, f: np.ndarray) -> None:
        """After the sample at t [s] (``ok``: what the record found, q, v, f its state): time
        the warnings raised since the last one; raise RunFailedError (:func:`check_finite`)
        when not ok, RunFailedError (:class:`JointLimits`) beyond a limit it stops at."""
        if len(self.caught) > len(self.caught_at):  # a Python warning at this step: its time
            self.caught_at.extend([t] * (len(self.caught) - len(self.caught_at)))
        if not ok:
            check_finite(t, q, v, f, self.sim)  # raises RunFailedError with the details
        if self.stop_at is not None:
            self.stop_at.check(t, q, v)

    def notes(self, t: float) -> list[str]:
        """The caught warnings, one line each (:func:`warning_notes`); those not timed yet were
        raised at t [s], the run's last time."""
        return warning_notes(self.caught, [*self.caught_at, *[t] * len(self.caught)])


def joint_names(robot: Robot) -> list[str]:
    """Names of the joints, one per column of q (nq = nv for every arm the loader builds)."""
    model = robot.model
    names = [""] * robot.nq
    for j in range(1, model.njoints):
        joint = model.joints[j]
        for c in range(joint.nq):
            names[joint.idx_q + c] = model.names[j] if joint.nq == 1 else f"{model.names[j]}[{c}]"
    return names


def check_finite(t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray, sim: SimSettings) -> None:
    """Raise RunFailedError, with the state, if q (nq,), v (nv,) or f (k,) at time t [s] is
    not finite or |q̇| or |f| exceeds ``sim.max_velocity`` or ``sim.max_force``."""
    vmax = float(np.abs(v).max())
    fmax = float(np.abs(f).max()) if f.size else 0.0
    if vmax <= sim.max_velocity and fmax <= sim.max_force and np.isfinite(q @ q):
        return
    if not (np.isfinite(vmax) and np.isfinite(fmax) and np.all(np.isfinite(q))):
        raise RunFailedError(
            f"non-finite state at t = {t:.6g} s: q = {q.tolist()}, v = {v.tolist()}",
            reason="diverged",
        )
    if vmax > sim.max_velocity:
        raise RunFailedError(
            f"runaway at t = {t:.6g} s: |q̇| = {vmax:.3g} > {sim.max_velocity:.3g} "
            f"(q = {np.round(q, 6).tolist()}, v = {np.round(v, 6).tolist()})",
            reason="diverged",
        )
    raise RunFailedError(
        f"runaway at t = {t:.6g} s: |f| = {fmax:.3g} N > {sim.max_force:.3g} N "
        f"(q = {np.round(q, 6).tolist()})",
        reason="diverged",
    )


def check_contact_step(sc: Scenario, q0: np.ndarray, f0: float) -> None:
    """Refuse a time step too long for the contact model (compliant stiffness, friction's
    regularisation) at the start configuration q0 (nq,); f0 [N]: the task's force."""

    dt_max = largest_stable_dt(sc.contact, sc.robot, sc.tool_surfaces, [q0], f0)
    if sc.sim.dt > dt_max:
        raise ScenarioError(
            f"sim.dt = {sc.sim.dt:g} s is too long for the contact "
            f"({_contact_text(sc.contact.to_dict())}): the largest stable step at the start "
            f"is {step_text(dt_max)} s (docs/contact.md, time step)",
            key="sim.dt",
            value=sc.sim.dt,
        )


def _contact_text(contact: dict) -> str:
    """The contact settings as the ``[contact]`` keys that matter for the time step."""
    keys: tuple[str, ...] = ()
    if contact["model"] == "compliant":
        keys = ("stiffness", "damping", "exponent")
    keys += ("friction", "friction_velocity") if contact["friction"] > 0 else ()
    return ", ".join(f"contact.{k} = {contact[k]:g}" for k in keys)


CHATTER_PAIRS = 3
"""A run whose tool leaves the surface and touches it again this many times after the force
first settled is reported as chattering (:func:`run_behaviour`)."""
FINAL_FRACTION = 0.2
"""The final part of a run [fraction of its time] over which the force error must have
settled (:func:`run_behaviour`)."""


def force_tolerance(f_d: float) -> float:
    """The force error [N] a settled run stays within: 1 N or 10 % of f_d, the larger."""
    return max(FORCE_TOLERANCE, 0.1 * f_d)


def run_behaviour(
    t: np.ndarray,
    f: np.ndarray,
    f_d: np.ndarray,
    distance: np.ndarray,
    in_contact: np.ndarray,
) -> tuple[dict[str, Any], list[str]]:
    """What the run did at the surface, from its recorded trajectory: the flags a sweep can
    filter on and one line per thing the run did not do as its summary would suggest.

    The notes: the tool never touched (f_d > 0 and never on the surface), with its closest
    approach; it chattered (at least :data:`CHATTER_PAIRS` releases each followed by a touch
    after the force first settled within :func:`force_tolerance`, else after the first
    touch), with their count and times; the force error never settled (its RMS over the
    last :data:`FINAL_FRACTION` of the run above :func:`force_tolerance`).

    Args:
        t: (N,) [s].
        f: (N, k) the plant's contact force [N].
        f_d: (k,) the task's desired force [N] (``control.f_d``).
        distance: (N, k) the tip's distance to each surface [m].
        in_contact: (N,) the plant's contact state at each sample.

    Returns:
        ``{"touched": bool, "chatter": int, "force_settled": bool | None}`` (None without
        contact or f_d) and the notes, one line each.
    """
    notes: list[str] = []
    n = t.shape[0]
    wanted = float(f_d.max()) if f_d.size else 0.0
    tol = force_tolerance(wanted)
    touched = bool(in_contact.any())
    flags: dict[str, Any] = {"touched": touched, "chatter": 0, "force_settled": None}
    if n == 0:
        return flags, notes
    if not touched:
        if wanted > 0:
            closest = distance.max(axis=1) if distance.ndim == 2 else distance
            i = int(np.argmin(closest))
            notes.append(
                f"the tool never touched the surface: its closest approach was "
                f"{float(closest[i]):.3g} m at t = {float(t[i]):.4g} s, so f_d = {wanted:g} N "
                f"was never applied"
            )
        return flags, notes
    error = np.abs(f - f_d[None, :]).max(axis=1) if f.ndim == 2 else np.abs(f - wanted)
    settled_at = np.flatnonzero(in_contact & (error <= tol))
    start = int(settled_at[0]) if settled_at.size else int(np.flatnonzero(in_contact)[0])
    after = in_contact[start:]
    releases = np.flatnonzero(after[:-1] & ~after[1:]) + start + 1
    touches = np.flatnonzero(~after[:-1] & after[1:]) + start + 1
    pairs = int(sum(1 for r in releases if (touches > r).any()))
    flags["chatter"] = pairs
    if pairs >= CHATTER_PAIRS:
        what = "the force first settled" if settled_at.size else "the first touch"
        notes.append(
            f"the tool chattered on the surface: {pairs} releases and re-touches between "
            f"t = {float(t[releases[0]]):.4g} s and t = {float(t[touches[-1]]):.4g} s, after "
            f"{what} at t = {float(t[start]):.4g} s"
        )
    if wanted > 0:
        t0 = float(t[-1]) * (1.0 - FINAL_FRACTION)
        window = t >= t0
        rms = float(np.sqrt(np.mean(error[window] ** 2)))
        flags["force_settled"] = rms <= tol
        if not rms <= tol:
            notes.append(
                f"the force error did not settle: RMS |f − f_d| = {rms:.3g} N (max "
                f"{float(error[window].max()):.3g} N) over the last {float(t[-1]) - t0:.3g} s "
                f"(t >= {t0:.4g} s), above the tolerance {tol:g} N"
            )
    return flags, notes


def warning_notes(caught: Sequence[Any], times: Sequence[float]) -> list[str]:
    """The Python warnings a run raised, one line each: ``at t = … s: <Category>: <message>``
    (no source line), identical ones once with their count and first time.

    Args:
        caught: ``warnings.WarningMessage`` records, in order. times: the simulated time [s]
            at which each was raised (as long as ``caught``).
    """

    seen: dict[str, list[float]] = {}
    for w, when in zip(caught, times, strict=False):
        text = " ".join(str(w.message).split())
        if not issubclass(w.category, OWN_WARNINGS):
            text = f"{w.category.__name__}: {text}"
        seen.setdefault(text, []).append(float(when))
    out = []
    for text, stamps in seen.items():
        count = f" ({len(stamps)} times)" if len(stamps) > 1 else ""
        if text.startswith("at t = "):  # says its own time
            out.append(f"{text}{count}")
        else:
            out.append(f"at t = {stamps[0]:.4g} s{count}: {text}")
    return out

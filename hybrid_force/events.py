"""The events of a run: what happened at one instant, one small frozen dataclass per kind.

The supervisor reports its phase changes and a wrong inverse-kinematics branch, the plant its
touches, impacts and releases, the run's checks a joint beyond a limit, and the loop what
stopped a failed run. In a :class:`~hybrid_force.result.Result` (and its files) an event is
stored as its :meth:`Event.to_dict` form, ``{"t": s, "kind": ..., <its fields>}``;
:func:`event_from_dict` reads one back.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from hybrid_force.errors import BadInputError
from hybrid_force.phases import Phase

__all__ = [
    "EVENT_KINDS",
    "Branch",
    "Event",
    "Impact",
    "LimitCrossed",
    "PhaseChange",
    "Release",
    "RunStopped",
    "Touch",
    "event_from_dict",
]


@dataclass(frozen=True)
class Event:
    """Something that happened at time ``t`` [s]; ``kind`` names it in a result's meta."""

    t: float
    KIND: ClassVar[str] = ""

    @property
    def kind(self) -> str:
        """The event's name in ``meta["events"]`` (e.g. ``"impact"``)."""
        return self.KIND

    def to_dict(self) -> dict[str, Any]:
        """``{"t": s, "kind": ..., <fields>}``: the form stored in a result (JSON-able)."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        fields.pop("t")
        return {"t": float(self.t), "kind": self.kind, **self._stored(fields)}

    def _stored(self, fields: dict[str, Any]) -> dict[str, Any]:
        return fields


@dataclass(frozen=True)
class PhaseChange(Event):
    """The supervisor entered ``phase`` (section 6.4); its kind is the phase's name."""

    phase: Phase = Phase.FREE

    @property
    def kind(self) -> str:
        return Phase(self.phase).label

    def _stored(self, fields: dict[str, Any]) -> dict[str, Any]:
        return {}  # the phase is the kind


@dataclass(frozen=True)
class Touch(Event):
    """A compliant contact began; ``speed`` [m/s] is the normal approach rate."""

    speed: float = 0.0
    KIND: ClassVar[str] = "touch"


@dataclass(frozen=True)
class Impact(Event):
    """A rigid touch: a plastic impact with ``impulse`` [N·s] (sum of |rows|) at ``speed`` [m/s]."""

    impulse: float = 0.0
    speed: float = 0.0
    KIND: ClassVar[str] = "impact"


@dataclass(frozen=True)
class Release(Event):
    """The tool left the surface; ``force`` [N] is the (smallest) contact force that asked to."""

    force: float = 0.0
    KIND: ClassVar[str] = "release"


@dataclass(frozen=True)
class Branch(Event):
    """The task error ``error`` [m] persists along the constraint normal: another IK branch."""

    error: float = 0.0
    KIND: ClassVar[str] = "branch"


@dataclass(frozen=True)
class LimitCrossed(Event):
    """Joint ``joint`` first crossed its position (``which = "joint_limit"``) or velocity
    (``"velocity_limit"``) limit ``limit`` [rad, m, rad/s or m/s]; its kind is ``which``."""

    joint: str = ""
    limit: float = 0.0
    which: str = "joint_limit"

    @property
    def kind(self) -> str:
        return self.which

    def _stored(self, fields: dict[str, Any]) -> dict[str, Any]:
        fields.pop("which")
        return fields


@dataclass(frozen=True)
class RunStopped(Event):
    """A failed run stopped here; its kind is the failure's ``reason``
    (:attr:`hybrid_force.errors.RunFailedError.reason`: "diverged", "path", …)."""

    reason: str = "error"

    @property
    def kind(self) -> str:
        return self.reason

    def _stored(self, fields: dict[str, Any]) -> dict[str, Any]:
        return {}


_BY_KIND: dict[str, type[Event]] = {
    **{p.label: PhaseChange for p in Phase},
    "touch": Touch,
    "impact": Impact,
    "release": Release,
    "branch": Branch,
    "joint_limit": LimitCrossed,
    "velocity_limit": LimitCrossed,
    **{r: RunStopped for r in ("diverged", "joint limit", "lost contact", "interrupted", "path")},
    "error": RunStopped,
}

#: Every kind of event a run records.
EVENT_KINDS: tuple[str, ...] = tuple(_BY_KIND)


def event_from_dict(d: Mapping[str, Any]) -> Event:
    """The event of a stored ``{"t": s, "kind": ..., ...}`` (inverse of :meth:`Event.to_dict`).

    Raises:
        BadInputError: an unknown kind (listing the valid ones) or fields the kind has not.
    """
    kind = d.get("kind")
    if not isinstance(kind, str) or kind not in _BY_KIND:
        raise BadInputError(
            f"event kind {kind!r} is not one of {', '.join(EVENT_KINDS)}", key="kind", value=kind
        )
    cls = _BY_KIND[kind]
    fields = {k: v for k, v in d.items() if k != "kind"}
    if cls is PhaseChange:
        fields["phase"] = next(p for p in Phase if p.label == kind)
    elif cls is LimitCrossed:
        fields["which"] = kind
    elif cls is RunStopped:
        fields["reason"] = kind
    try:
        return cls(**fields)
    except TypeError as exc:
        raise BadInputError(f"event {dict(d)!r}: {exc}", key="events", value=dict(d)) from None

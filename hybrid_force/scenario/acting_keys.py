"""The keys of a scenario file that act only in some configurations of a run (a compliant
contact's stiffness, a pointed tool's tilt, a law's own gains, ...): each with the rule that
says when it has an effect; the loader refuses one given where it has none
(:func:`_check_acting`), and warns about and drops a key no configuration reads
(:func:`_drop_never_acting`)."""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from hybrid_force._file_errors import _Context, _fmt
from hybrid_force.control.laws.base import LAWS, law_names, law_spec
from hybrid_force.errors import RunWarning


def _parent(doc: Mapping[str, Any], dotted: str) -> tuple[Mapping[str, Any] | None, str]:
    """The table holding the last key of ``"table.key"`` or ``"table.sub.key"`` (None when a
    table on the way is absent or not a table), and that key."""
    *tables, key = dotted.split(".")
    node: object = doc
    for name in tables:
        node = node.get(name) if isinstance(node, Mapping) else None
    return (node if isinstance(node, Mapping) else None), key


def _value(doc: Mapping[str, Any], dotted: str, default: object = None) -> object:
    """``doc[table][key]`` of a ``"table.key"`` (the default when a table or the key is
    absent)."""
    node, key = _parent(doc, dotted)
    return node.get(key, default) if node is not None else default


def _law(doc: Mapping[str, Any]) -> str:
    law = _value(doc, "control.law", "arimoto")
    return law if isinstance(law, str) and law in law_names() else "arimoto"


def _supervised(doc: Mapping[str, Any]) -> bool:
    return _value(doc, "control.supervisor", True) is not False


def _law_is(name: str, doc: Mapping[str, Any]) -> bool:
    return _law(doc) == name


def _law_reads(gain: str, doc: Mapping[str, Any]) -> bool:
    """The chosen law reads ``control.<gain>`` (its registry entry's ``gains``, not replaced by
    a key of its table or of [control]); Λ is also the approach rate's default (supervised
    runs without ``control.approach_rate``)."""

    law = _law(doc)
    spec = law_spec(law)
    options = _value(doc, f"control.{law}", {})
    given = {
        *(options if isinstance(options, Mapping) else {}),
        *(doc.get("control", {}) if isinstance(doc.get("control"), Mapping) else {}),
    }
    if gain == "Lambda" and _supervised(doc) and "approach_rate" not in given:
        return True
    return gain in spec.gains and (spec.gains[gain] is None or spec.gains[gain] not in given)


def _gain_needs(gain: str) -> str:

    readers = [name for name, spec in LAWS.items() if gain in spec.gains]
    replaced = {str(spec.gains[gain]) for spec in LAWS.values() if spec.gains.get(gain)}
    text = f"control.law = one of {readers}" if readers else "no law (none reads it)"
    if replaced:
        text += f", without the key that replaces it ({', '.join(sorted(replaced))})"
    if gain == "Lambda":
        text += ", or the supervisor's approach (control.supervisor = true, no approach_rate)"
    return text


@dataclass(frozen=True)
class _ActsWhen:
    """A key that has an effect only in some configurations of the run.

    Attributes:
        key: ``"table.key"`` (a law's table ``"control.<law>"`` as a whole).
        acts: the document → True when the key has an effect.
        needs: what would make it act, in words (for the message).
    """

    key: str
    acts: Callable[[Mapping[str, Any]], bool]
    needs: str


def _compliant(doc: Mapping[str, Any]) -> bool:
    return _value(doc, "contact.model", "rigid") == "compliant"


def _rigid(doc: Mapping[str, Any]) -> bool:
    return not _compliant(doc)


def _force_tracking(doc: Mapping[str, Any]) -> bool:
    return _value(doc, "control.impedance.force_tracking", True) is not False


def _friction(doc: Mapping[str, Any]) -> bool:
    mu = _value(doc, "contact.friction", 0.0)
    return not isinstance(mu, (int, float)) or isinstance(mu, bool) or mu != 0


def _oriented(doc: Mapping[str, Any]) -> bool:
    return _value(doc, "tool.orientation", "free") == "normal"


def _world_waypoints(doc: Mapping[str, Any]) -> bool:
    return _value(doc, "trajectory.frame", "world") == "world"


_ACTS_WHEN: tuple[_ActsWhen, ...] = (
    *(
        _ActsWhen(f"contact.{key}", _compliant, 'contact.model = "compliant"')
        for key in ("stiffness", "damping", "exponent")
    ),
    _ActsWhen("contact.friction_velocity", _friction, "contact.friction > 0"),
    *(
        _ActsWhen(f"tool.{key}", _oriented, 'tool.orientation = "normal"')
        for key in ("axis", "tilt", "tilt_axis", "roll")
    ),
    _ActsWhen("tool.pad", lambda doc: "removal" in doc, "a [removal] table (Preston's removal)"),
    _ActsWhen("trajectory.projection_tol", _world_waypoints, 'trajectory.frame = "world"'),
    *(
        _ActsWhen(f"sim.{key}", _rigid, 'contact.model = "rigid" (the default)')
        for key in ("baumgarte_alpha", "baumgarte_beta", "unilateral")
    ),
    _ActsWhen(
        "control.impedance.force_rate", _force_tracking, "control.impedance.force_tracking = true"
    ),
    *(
        _ActsWhen(f"control.{key}", _supervised, "control.supervisor = true")
        for key in ("approach_rate", "max_dist")
    ),
    *(
        _ActsWhen(f"control.{name}", functools.partial(_law_is, name), f'control.law = "{name}"')
        for name in law_names()
    ),
    *(
        _ActsWhen(f"control.{gain}", functools.partial(_law_reads, gain), _gain_needs(gain))
        for gain in ("Kd", "kd_rate", "Lambda", "beta", "gamma")
    ),
)
"""Every key that acts only in some configurations, and when (issue 27, class 6): the
loader refuses one given where it has no effect (:func:`_check_acting`)."""

_NEVER_ACTS: dict[str, str] = {
    "control.P": (
        "eq. 31's f_d = P·f is 0 before contact, where the measured force is 0: the near phase "
        "uses the approach term instead (docs/scenarios.md, [control])"
    ),
}
"""Keys the format keeps but no configuration reads: warned about and left out of the run."""


def _check_acting(doc: Mapping[str, Any], ctx: _Context) -> None:
    """Refuse a key of :data:`_ACTS_WHEN` given where it has no effect (naming the file, the
    key, its value and what would make it act)."""
    for rule in _ACTS_WHEN:
        node, key = _parent(doc, rule.key)
        if node is not None and key in node and not rule.acts(doc):
            raise ctx.error(
                rule.key,
                node[key],
                f"has no effect in this configuration; it acts only with {rule.needs}: remove "
                "it, or set what makes it act",
            )


def _drop_never_acting(doc: dict[str, Any], ctx: _Context) -> None:
    """Warn about a key of :data:`_NEVER_ACTS` (its value already checked) and drop it from
    ``doc`` (in place): the run's recorded scenario then does not list it."""

    for dotted, why in _NEVER_ACTS.items():
        table, _, key = dotted.partition(".")
        node = doc.get(table)
        if isinstance(node, dict) and key in node:
            value = node.pop(key)
            warnings.warn(
                RunWarning(
                    f"{ctx.file}: {dotted} = {_fmt(value)} has no effect in any configuration "
                    f"({why}); it is left out of the run's settings"
                ),
                stacklevel=3,
            )

"""The dataclass is the schema: a settings field carries its unit, range, choices and doc.

A settings dataclass declares each field once, with :func:`param`::

    @dataclass(frozen=True)
    class SimSettings:
        dt: float = param(1e-3, unit="s", minimum=0.0, strict=True, doc="time step")

The TOML reader (:mod:`hybrid_force.settings_reader`), the ``__post_init__`` checks, the key
tables of docs/scenarios.md and the JSON Schema (:mod:`hybrid_force.schema_docs`) all read it
(:func:`spec_of`, :func:`specs`): a default, unit or range is written here and nowhere else.
"""

from __future__ import annotations

import dataclasses
import functools
import types
import typing
from collections.abc import Callable, Iterator
from dataclasses import MISSING, dataclass
from typing import TYPE_CHECKING, Any, Literal

from hybrid_force import _checks as checks

if TYPE_CHECKING:
    from hybrid_force.errors import BadInputError

__all__ = [
    "MISSING_VALUE",
    "Param",
    "check_fields",
    "declared",
    "default_of",
    "param",
    "spec_of",
    "specs",
    "value_kind",
]


class _Required:
    """The default of a field that has none (it is required)."""

    def __repr__(self) -> str:
        return "<required>"


MISSING_VALUE: Any = _Required()
"""What :func:`default_of` returns for a required field (no default)."""

_KEY = "hybrid_force"


@dataclass(frozen=True)
class Param:
    """What a field accepts, beside its type and default.

    Attributes:
        doc: one line: what it is (no unit, no default: both are shown from here).
        unit: its unit ("s", "N", "m", "rad", "rad/s or m/s"; "" when dimensionless).
        minimum, maximum: the range of a number (None: unbounded on that side).
        strict: the range's ends are excluded.
        choices: the values a text may take (empty: any).
        key: the TOML key, when it differs from the field name (e.g. ``baumgarte_alpha``).
        toml: False: the field is set from Python only (no TOML key).
        acts_when: the key has an effect only when another key has a value: ``(key, value)``
            or ``(key, ">", value)`` or ``(key, "in", values)``; the other key is of the same
            table, or ``table.key`` (``("contact.model", "rigid")``); absent keys have their
            defaults.
            A key given where its rule does not hold is refused by the reader.
        inert: why no configuration reads the key (the reader warns and leaves it out).
    """

    doc: str = ""
    unit: str = ""
    minimum: float | None = None
    maximum: float | None = None
    strict: bool = False
    choices: tuple[Any, ...] = ()
    key: str | None = None
    toml: bool = True
    acts_when: tuple[Any, ...] = ()
    inert: str = ""


def param(
    default: Any = MISSING,
    *,
    default_factory: Callable[[], Any] | Any = MISSING,
    doc: str = "",
    unit: str = "",
    minimum: float | None = None,
    maximum: float | None = None,
    strict: bool = False,
    choices: tuple[Any, ...] = (),
    key: str | None = None,
    toml: bool = True,
    acts_when: tuple[Any, ...] = (),
    inert: str = "",
) -> Any:
    """A dataclass field with its :class:`Param` metadata (``dataclasses.field`` otherwise)."""
    spec = Param(doc, unit, minimum, maximum, strict, tuple(choices), key, toml, acts_when, inert)
    meta = {_KEY: spec}
    if default_factory is not MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def spec_of(f: dataclasses.Field[Any]) -> Param:
    """The :class:`Param` of a field (an empty one when it was declared without :func:`param`)."""
    found = f.metadata.get(_KEY)
    return found if isinstance(found, Param) else Param()


def declared(f: dataclasses.Field[Any]) -> bool:
    """The field was declared with :func:`param`."""
    return isinstance(f.metadata.get(_KEY), Param)


def default_of(f: dataclasses.Field[Any]) -> Any:
    """A field's default (its factory called), or :data:`MISSING_VALUE` when it has none."""
    if f.default is not MISSING:
        return f.default
    if f.default_factory is not MISSING:
        return f.default_factory()
    return MISSING_VALUE


def specs(cls: type) -> Iterator[tuple[dataclasses.Field[Any], Param]]:
    """The fields of a dataclass with their :class:`Param`, in declaration order."""
    for f in dataclasses.fields(cls):
        yield f, spec_of(f)


@functools.cache
def _kinds(cls: type) -> dict[str, tuple[str, tuple[Any, ...]]]:
    hints = typing.get_type_hints(cls)  # once per class: it evaluates every annotation
    return {f.name: _kind(hints[f.name]) for f in dataclasses.fields(cls)}


def value_kind(cls: type, f: dataclasses.Field[Any]) -> tuple[str, tuple[Any, ...]]:
    """(kind, choices) of a field's TOML value, from its type: "bool", "integer", "number",
    "str", "choice" (a ``Literal``: its values), "vec3" (3 floats), "vector" (floats),
    "points" (a list of vectors),
    "number_or_vector" (``float | tuple[float, ...]``), "matrix" (``float | np.ndarray``: a
    number, a vector or a matrix), "table" (a nested settings dataclass, whose fields are keys
    of the same table), "typed_table" (a union of settings dataclasses each with a ``kind``: a
    subtable ``[table.key]`` whose ``type`` is one of the kinds; the choices are the classes)
    or "any" (the table's own code reads it). ``X | None`` is read as X."""
    return _kinds(cls)[f.name]


def _kinded(hint: Any) -> bool:
    """A settings dataclass with a ``kind`` (the ``type`` of its subtable)."""
    return dataclasses.is_dataclass(hint) and isinstance(getattr(hint, "kind", None), str)


def _kind(hint: Any) -> tuple[str, tuple[Any, ...]]:
    args = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        rest = tuple(a for a in args if a is not type(None))
        if len(rest) == 1:
            return _kind(rest[0])
        if float in rest and tuple[float, ...] in rest:
            return "number_or_vector", ()
        if float in rest and any(getattr(a, "__name__", "") == "ndarray" for a in rest):
            return "matrix", ()
        if all(_kinded(a) for a in rest):
            return "typed_table", rest  # a subtable [table.key] whose ``type`` picks the class
        return "any", ()
    if typing.get_origin(hint) is Literal:
        return "choice", args
    if typing.get_origin(hint) is tuple:
        if args == (float, float, float):
            return "vec3", ()
        if args == (float, ...):
            return "vector", ()
        if args == (tuple[float, ...], ...):
            return "points", ()
    if dataclasses.is_dataclass(hint):
        return "table", ()
    simple = {bool: "bool", int: "integer", float: "number", str: "str"}
    return simple.get(hint, "any"), ()


def check_fields(obj: Any, error: type[BadInputError], prefix: str) -> None:
    """The generic check of a settings dataclass, from its fields' :class:`Param`: each
    number finite and within its range (stored as a float), each integer whole and within
    its range, each flag a bool, each text one of its choices. A field whose default is None
    may be None. Other kinds are left to the class. Raises ``error`` naming the field as
    ``prefix`` + its key (``"sim.dt"``), with its value and what is valid."""

    cls = type(obj)
    for f, spec in specs(cls):
        value = getattr(obj, f.name)
        if not declared(f) or (value is None and default_of(f) is None):
            continue
        kind, choices = value_kind(cls, f)
        what = f"{prefix}{spec.key or f.name}"
        try:
            value = _check_one(kind, choices, spec, value, what, error)
        except error as exc:
            raise error(str(exc), key=what, value=value) from None
        object.__setattr__(obj, f.name, value)


def _check_one(
    kind: str,
    choices: tuple[Any, ...],
    spec: Param,
    value: Any,
    what: str,
    error: type[BadInputError],
) -> Any:
    """One field's value checked by its kind and :class:`Param` (:func:`check_fields`)."""
    low, high = spec.minimum, spec.maximum
    if kind == "number":
        return checks.number(
            value, what, error, minimum=low, strict=spec.strict, maximum=high, unit=spec.unit
        )
    if kind == "integer":
        low = int(low if low is not None else -(2**63))
        return checks.integer(
            value, what, error, minimum=low, maximum=None if high is None else int(high)
        )
    if kind == "bool":
        return checks.flag(value, what, error)
    if kind == "choice" or spec.choices:
        return checks.one_of(value, what, error, [str(c) for c in spec.choices or choices])
    return value

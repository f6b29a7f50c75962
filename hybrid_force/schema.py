"""The dataclass is the schema: a settings field carries its unit, range, choices and doc.

A settings dataclass declares each field once, with :func:`param`::

    @dataclass(frozen=True)
    class SimSettings:
        dt: float = param(1e-3, unit="s", minimum=0.0, strict=True, doc="time step")

The TOML reader (:mod:`hybrid_force.scenario`), the ``__post_init__`` checks, the key tables
of docs/scenarios.md and the JSON Schema (``hybrid-force schema``) all read this metadata
(:func:`spec_of`, :func:`specs`): a default, unit or range is written here and nowhere else.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Callable, Iterator
from dataclasses import MISSING, dataclass
from typing import Any, Literal

__all__ = [
    "MISSING_VALUE",
    "Param",
    "declared",
    "default_of",
    "param",
    "spec_of",
    "specs",
    "value_kind",
]

MISSING_VALUE: Any = MISSING
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
    """

    doc: str = ""
    unit: str = ""
    minimum: float | None = None
    maximum: float | None = None
    strict: bool = False
    choices: tuple[Any, ...] = ()
    key: str | None = None
    toml: bool = True


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
) -> Any:
    """A dataclass field with its :class:`Param` metadata (``dataclasses.field`` otherwise)."""
    meta = {_KEY: Param(doc, unit, minimum, maximum, strict, tuple(choices), key, toml)}
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


def value_kind(cls: type, f: dataclasses.Field[Any]) -> tuple[str, tuple[Any, ...]]:
    """(kind, choices) of a field's TOML value, from its type: "bool", "integer", "number",
    "str", "choice" (a ``Literal``: its values), "vec3" (3 floats), "vector" (floats), or
    "any" (a type the reader does not know: the table's own code reads it). ``X | None``
    is read as X (None is no TOML value)."""
    hint = typing.get_type_hints(cls)[f.name]
    args = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        rest = [a for a in args if a is not type(None)]
        hint = rest[0] if len(rest) == 1 else hint
        args = typing.get_args(hint)
    if typing.get_origin(hint) is Literal:
        return "choice", args
    if typing.get_origin(hint) is tuple:
        if args == (float, float, float):
            return "vec3", ()
        if args == (float, ...):
            return "vector", ()
    simple = {bool: "bool", int: "integer", float: "number", str: "str"}
    return simple.get(hint, "any"), ()

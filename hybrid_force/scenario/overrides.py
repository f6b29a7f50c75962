"""The ``--set table.key=value`` overrides of a run's scenario: a text parsed as a TOML value
(:func:`parse_override`, nothing evaluated) and set into the scenario's data before it is
checked (:func:`_apply_overrides`)."""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from typing import Any

from hybrid_force._file_errors import _Context
from hybrid_force.errors import ScenarioError


def parse_override(text: str) -> tuple[str, object]:
    """Split ``"table.key=value"`` into ``("table.key", value)``, the value parsed as a TOML
    value (``0.5``, ``true``, ``[1, 2, 3]``, ``"text"``); anything that is not valid TOML
    (``rk4``, ``__import__('os')``) stays the raw string: nothing is evaluated. ScenarioError
    when there is no ``=`` or the key is empty."""
    if not isinstance(text, str) or "=" not in text:
        raise ScenarioError(f"override {text!r} must look like table.key=value (e.g. sim.dt=1e-3)")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise ScenarioError(f"override {text!r} has an empty key; use table.key=value")
    raw = raw.strip()
    try:
        value: object = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    except RecursionError:
        raise ScenarioError(f"override {key!r}: its value is nested too deeply") from None
    return key, value


def _apply_overrides(doc: dict[str, Any], overrides: Mapping[str, object], ctx: _Context) -> None:
    """Set ``doc[table][key] = value`` for each ``"table.key"`` (in place).

    ``"name"`` sets a top-level key; ``"surfaces.<i>.key"`` a key of the i-th [[surfaces]].
    A missing table is created (validation then reports it if it is unknown).
    """
    for dotted, value in overrides.items():
        parts = str(dotted).split(".")
        node: Any = doc
        where: list[str] = []
        for part in parts[:-1]:
            where.append(part)
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise ctx.table_error(
                        ".".join(where),
                        f"override {dotted!r}: index {part!r} is not one of "
                        f"0..{len(node) - 1} of this array of tables",
                    )
                node = node[int(part)]
                continue
            if not isinstance(node, dict):
                raise ctx.table_error(
                    ".".join(where[:-1]), f"override {dotted!r}: this is not a table"
                )
            node = node.setdefault(part, {})
        if not isinstance(node, dict):
            raise ctx.table_error(".".join(where), f"override {dotted!r}: this is not a table")
        node[parts[-1]] = value

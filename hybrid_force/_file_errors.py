"""The errors of a scenario file: ``<file>: <table.key> = <value>: <problem>``, one format
for every layer that checks a part of the file (the reader, the arm, the start, the pre-run
checks)."""

from __future__ import annotations

import json
import re
from collections.abc import Mapping

from hybrid_force.errors import ScenarioError


def _fmt(value: object) -> str:
    """A value as it would be written in TOML (JSON is close enough), shortened."""
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError, RecursionError):
        text = repr(value) if not isinstance(value, dict | list) else "[...]"
    return text if len(text) <= 100 else text[:97] + "..."


class _Context:
    """Builds error messages for one file: ``<file>: <table.key> = <value>: <problem>``."""

    def __init__(self, file: str) -> None:
        self.file = file

    def error(self, key: str, value: object, problem: str) -> ScenarioError:
        return ScenarioError(
            f"{self.file}: {key} = {_fmt(value)}: {problem}", key=key, value=value, file=self.file
        )

    def table_error(self, key: str, problem: str) -> ScenarioError:
        return ScenarioError(f"{self.file}: {key}: {problem}", key=key, file=self.file)


def _wrap(
    ctx: _Context, table: str, values: Mapping[str, object], exc: BaseException
) -> ScenarioError:
    """Re-raise a constructor's BadInputError naming the file and the key it is about."""
    message = " ".join(str(exc).split())
    for key in sorted(values, key=len, reverse=True):
        if re.search(rf"(?<![A-Za-z_]){re.escape(key)}(?![A-Za-z_])", message):
            return ctx.error(f"{table}.{key}", values[key], message)
    shown = ", ".join(f"{table}.{k} = {_fmt(v)}" for k, v in values.items())
    return ScenarioError(f"{ctx.file}: {shown or table}: {message}")

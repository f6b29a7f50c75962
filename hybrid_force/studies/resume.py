"""Whether the rows in a sweep's folder may be reused: the sweep of the same inputs.

A sweep's ``sweep.json`` records the sha256 of its scenario file, of every file its tasks read
(model files, xacro includes: ``inputs``) and the hybrid_force version. A resumed sweep reuses
the rows of its folder only when all of them are unchanged, compared by content; otherwise it
refuses (BadInputError, exit status 2) naming what changed, so that one table never mixes rows of
two scenarios, two arms or two versions of the toolkit.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import hybrid_force
from hybrid_force.errors import BadInputError
from hybrid_force.studies.table import _CSV_NAME, _JSON_NAME
from hybrid_force.studies.tasks import _sha256_or_none

if TYPE_CHECKING:
    from hybrid_force.studies.tasks import _Source

__all__: list[str] = []


def _version() -> str:
    """The installed hybrid_force's version: rows of another version are not reused."""

    return str(hybrid_force.__version__)


def _check_same_scenario(out: Path, scenario: Path, sha: str) -> None:
    """BadInputError if ``out`` holds a sweep of another version of the scenario file."""
    info_path = out / _JSON_NAME
    if info_path.exists() and (out / _CSV_NAME).exists():
        try:
            old = json.loads(info_path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError):
            old = {}
        if old.get("scenario_sha256") not in (None, sha):
            raise BadInputError(
                f"'{out}' holds a sweep of a different version of the scenario "
                f"(sha256 {old.get('scenario_sha256')}, now {sha} for '{scenario}'); "
                "use another --out or delete that directory"
            )


def _check_same_inputs(out: Path, source: _Source) -> dict[str, dict[str, str | None]]:
    """The files the rows of ``out`` read (from its sweep.json), each checked unchanged.

    Every file is compared by content (sha256) with what this sweep's tasks read of it, or
    else with the file as it is now; so is the hybrid_force version.

    Raises:
        BadInputError: the rows in ``out`` were made by another hybrid_force version, or from a
            file that has another content now (or was added or removed), naming the file,
            the scenario key that reads it and both sha256.
    """
    info_path = out / _JSON_NAME
    if not (info_path.exists() and (out / _CSV_NAME).exists()):
        return {}
    try:
        old = json.loads(info_path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        old = {}
    old = old if isinstance(old, dict) else {}
    made_by = old.get("hybrid_force_version")
    if made_by != _version():
        raise BadInputError(
            f"'{out}' holds rows made by hybrid_force {made_by or '(an earlier version)'} "
            f"(hybrid_force_version in '{info_path}'), now {_version()}: they are not reused; "
            "use another --out or delete that directory",
            key="hybrid_force_version",
            value=made_by,
        )
    inputs = old.get("inputs")
    kept: dict[str, dict[str, str | None]] = {}
    for name, entry in (inputs if isinstance(inputs, dict) else {}).items():
        entry = entry if isinstance(entry, dict) else {}
        was = entry.get("sha256")
        key = str(entry.get("key") or "a model")
        seen = source.inputs.get(name)
        now = seen["sha256"] if seen is not None else _sha256_or_none(Path(name))
        if now != was:
            what = (
                "was missing and exists now" if was is None
                else "is missing now" if now is None
                else f"has another content now (sha256 {was}, now {now})"
            )  # fmt: skip
            raise BadInputError(
                f"'{out}' holds rows made from another version of '{name}' ({key} of the "
                f"scenario): the file {what}; they are not reused, so as not to mix two "
                "versions in one table: use another --out or delete that directory",
                key=key,
                value=name,
            )
        kept[name] = {"key": key, "sha256": was}
    return kept

"""A run's result on disk: the ``.npz`` schema, the atomic write and the checked read.

A result file is one uncompressed ``.npz`` archive with exactly the arrays of
:data:`ARRAY_NAMES` (and those of :data:`OPTIONAL_ARRAYS` the run has) plus ``meta``, the
run's metadata as JSON text in a 0-d numpy unicode array; no pickle is involved, so
``np.load(path, allow_pickle=False)`` reads it.

:func:`write_arrays` writes atomically: to a temporary file in the target's directory, flushed
and fsync'ed, then moved onto the target with :func:`os.replace`; a crash or Ctrl-C during the
write leaves any earlier file at the target untouched. :func:`read_arrays` refuses, before
numpy allocates anything, an archive that would not fit in memory or whose headers claim more
data than they hold, and names the file in every error. Building the
:class:`~hybrid_force.result.Result` from what it read (shapes, dtypes, phases) is the
dataclass's own check.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from numpy.lib import format as npy_format
from numpy.lib.npyio import NpzFile

from hybrid_force._atomic import atomic_file, prepare_target
from hybrid_force._memory import available_memory
from hybrid_force.errors import BadInputError

__all__ = [
    "ARRAY_NAMES",
    "MAX_META_DEPTH",
    "META_KEY",
    "OPTIONAL_ARRAYS",
    "REMOVAL_ARRAYS",
    "meta_to_json",
    "read_arrays",
    "write_arrays",
]

#: The arrays of a result file, in schema order (``meta`` is stored beside them).
ARRAY_NAMES: tuple[str, ...] = (
    "t",
    "q",
    "v",
    "q_d",
    "u",
    "p",
    "p_d",
    "f",
    "f_d",
    "phi",
    "V",
    "phase",
)
#: Arrays a result file may hold beyond :data:`ARRAY_NAMES` (older files lack them; see
#: :class:`~hybrid_force.result.Result` for the value then).
OPTIONAL_ARRAYS: tuple[str, ...] = ("f_meas", "u_cmd", "law_log", "tool_angle", "contact_point")
#: The removal grid's arrays of a run with ``[removal]`` (per cell, not per sample: a
#: truncated result keeps them whole): removal_points (M, 3) [m], removal_depth (M,) [m],
#: removal_target (M,) 1 for a cell of the target region, else 0 (docs/removal.md).
REMOVAL_ARRAYS: tuple[str, ...] = ("removal_points", "removal_depth", "removal_target")
#: Name of the member holding the metadata's JSON text.
META_KEY = "meta"
#: Deepest nesting of lists and objects accepted in a loaded result's meta.
MAX_META_DEPTH = 64
#: Most members an archive may hold (a result has 13).
_MAX_MEMBERS = 64


def _json_default(obj: Any) -> Any:
    """Turn numpy scalars/arrays and paths into plain JSON values (used by ``json.dumps``)."""
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, (tuple, set, frozenset)):
        return list(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON-able")


def meta_to_json(meta: Mapping[str, Any]) -> str:
    """Serialise ``meta`` to strict JSON text (no NaN/inf).

    Raises:
        BadInputError: a value is not JSON-able or is NaN/inf.
    """
    try:
        return json.dumps(meta, default=_json_default, allow_nan=False, sort_keys=False)
    except (TypeError, ValueError) as exc:
        raise BadInputError(
            f"Result meta must be JSON-able without NaN/inf (use None): {exc}"
        ) from exc


def _json_depth(value: Any) -> int:
    """Nesting depth of JSON data (0 for a scalar), without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, dict):
            node = list(node.values())
        if isinstance(node, list):
            deepest = max(deepest, depth + 1)
            if deepest > MAX_META_DEPTH:
                return deepest
            stack.extend((child, depth + 1) for child in node)
    return deepest


def _check_archive(fh: BinaryIO, src: Path) -> None:
    """Refuse, before anything is decompressed or allocated, an archive whose arrays would not
    fit in memory or whose .npy headers claim more data than their member holds.

    The sizes checked are the zip directory's uncompressed sizes, which ``zipfile`` enforces
    while reading, and each array header's shape × item size against its member's size (numpy
    allocates the claimed shape before reading). Zip and header errors propagate to
    :func:`read_arrays`, which reports them as an unreadable archive.
    """
    if fh.read(6) == b"\x93NUMPY":
        raise BadInputError(
            f"result file '{src}' holds a single numpy array, not an .npz result archive"
        )
    fh.seek(0)
    with zipfile.ZipFile(fh) as archive:
        members = archive.infolist()
        if len(members) > _MAX_MEMBERS:
            raise BadInputError(
                f"result file '{src}' has {len(members)} members; a result has "
                f"{len(ARRAY_NAMES) + 1}"
            )
        total = sum(m.file_size for m in members)
        free = available_memory()
        if free is not None and 2 * total > free:
            raise BadInputError(
                f"result file '{src}' would take {total / 2**30:.3g} GiB once decompressed "
                f"(twice that while loading); {free / 2**30:.3g} GiB of memory is available"
            )
        for member in members:
            # numpy serves "t" as well as "t.npy" as array "t": check every member that
            # holds an array, whatever its name
            with archive.open(member) as npy:
                if npy.read(6) != b"\x93NUMPY":
                    continue
                npy.seek(0)
                version = npy_format.read_magic(npy)
                if version == (1, 0):
                    shape, _, dtype = npy_format.read_array_header_1_0(npy)
                else:
                    shape, _, dtype = npy_format.read_array_header_2_0(npy)
            claimed = math.prod(shape) * dtype.itemsize
            if claimed > member.file_size:
                name = member.filename.removesuffix(".npy")
                raise BadInputError(
                    f"result file '{src}': array '{name}' claims shape "
                    f"{shape} ({claimed} bytes) but its member holds {member.file_size} bytes"
                )


def _fsync_directory(directory: Path) -> None:
    """Best-effort fsync of a directory so a completed rename survives a power cut (POSIX)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def write_arrays(target: Path, arrays: Mapping[str, np.ndarray], meta_text: str) -> None:
    """Write ``arrays`` and the JSON text ``meta_text`` atomically to ``target`` (one
    uncompressed ``.npz``), creating its parent directory if missing.

    On any exception, including KeyboardInterrupt, the temporary file is removed and the
    exception re-raised; an existing file at ``target`` is untouched until the final replace.

    Raises:
        BadInputError: ``target`` is a directory, or its parent cannot be created.
    """
    prepare_target(target, BadInputError, "save result")
    payload: dict[str, Any] = dict(arrays)
    payload[META_KEY] = np.array(meta_text, dtype=np.str_)
    with atomic_file(target) as fh:
        np.savez(fh, **payload)
    _fsync_directory(target.parent)


def read_arrays(src: Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays (every one of :data:`ARRAY_NAMES` and those of :data:`OPTIONAL_ARRAYS` the
    file holds) and the decoded meta dict of the result file ``src``.

    Raises:
        BadInputError: naming the file, if it is missing, not an npz archive (truncated or
            garbage), too large for memory, lacks arrays (listed), or has no or bad ``meta``
            JSON (not an object, nested more than :data:`MAX_META_DEPTH` levels).
    """
    if not src.exists():
        raise BadInputError(f"result file '{src}' does not exist")
    if not src.is_file():
        raise BadInputError(f"result file '{src}' is not a regular file")
    data: dict[str, np.ndarray] = {}
    try:
        # open the file ourselves: np.load leaks its handle when the zip is corrupt
        with src.open("rb") as fh:
            _check_archive(fh, src)
            fh.seek(0)
            loaded = np.load(fh, allow_pickle=False)
            if not isinstance(loaded, NpzFile):
                raise BadInputError(
                    f"result file '{src}' holds a single numpy array, not an .npz result archive"
                )
            with loaded as npz:
                names = set(npz.files)
                missing = [n for n in (*ARRAY_NAMES, META_KEY) if n not in names]
                if missing:
                    found = ", ".join(sorted(names)) or "none"
                    raise BadInputError(
                        f"result file '{src}' is not a complete hybrid_force result: "
                        f"missing array(s) {', '.join(missing)} (found: {found})"
                    )
                for name in (*ARRAY_NAMES, *OPTIONAL_ARRAYS, *REMOVAL_ARRAYS, META_KEY):
                    if name in names:
                        data[name] = npz[name]
    except BadInputError:
        raise
    except (
        OSError,
        ValueError,
        EOFError,
        zipfile.BadZipFile,
        zlib.error,
        KeyError,
        RuntimeError,
    ) as exc:  # RuntimeError: an encrypted member; NotImplementedError: unknown compression
        raise BadInputError(
            f"result file '{src}' is not a readable .npz archive (truncated or not a "
            f"hybrid_force result): {type(exc).__name__}: {exc}"
        ) from exc
    meta_arr = data.pop(META_KEY)
    if meta_arr.shape != () or meta_arr.dtype.kind != "U":
        raise BadInputError(
            f"result file '{src}': 'meta' must be a 0-d unicode string array of JSON text, "
            f"got dtype {meta_arr.dtype} shape {meta_arr.shape}"
        )
    try:
        meta = json.loads(str(meta_arr))
    except json.JSONDecodeError as exc:
        raise BadInputError(f"result file '{src}': 'meta' is not valid JSON: {exc}") from exc
    except RecursionError:
        meta = None  # nested beyond Python's recursion limit: refused just below
    depth = _json_depth(meta) if meta is not None else MAX_META_DEPTH + 1
    if depth > MAX_META_DEPTH:
        raise BadInputError(
            f"result file '{src}': 'meta' is nested more than {MAX_META_DEPTH} levels deep "
            "(a result's meta needs about 5)"
        )
    if not isinstance(meta, dict):
        raise BadInputError(
            f"result file '{src}': 'meta' must be a JSON object, got {type(meta).__name__}"
        )
    return data, meta

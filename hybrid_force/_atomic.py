"""Atomic file writes: a file on disk is either the old one or the complete new one.

Every writer of the toolkit (results, summaries, figures, HTML replays, sweep tables) goes
through :func:`atomic_file`: it writes a temporary file in the target's own directory,
flushes and fsyncs it, gives it the usual permissions (0666 minus the umask; ``mkstemp``
creates 0600) and ``os.replace``-s it onto the target. Any exception, KeyboardInterrupt
included, removes the temporary file and leaves an earlier target untouched.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from hybrid_force.errors import BadInputError

__all__ = ["atomic_file", "prepare_target"]


def _umask() -> int:
    mask = os.umask(0)  # the only portable way to read it; restored at once
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike[str], mode: str = "wb", **open_kwargs: Any) -> Iterator[IO]:
    """Open a temporary file for writing that replaces ``path`` when the block succeeds.

    Args:
        path: the target file; its directory must exist.
        mode: "wb" or "w" (text: pass ``encoding=`` and ``newline=`` as for :func:`open`).
    """
    target = Path(path)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, mode, **open_kwargs) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def prepare_target(
    target: Path, error: type[BadInputError], action: str, key: str | None = None
) -> None:
    """Refuse a ``target`` that is a directory, and create its folder, before
    :func:`atomic_file` writes it.

    Raises:
        error: with the message ``cannot <action> to '<target>': ...`` (action: "save result",
            "write HTML", ...) saying which of the two failed; ``key`` (e.g. the option that
            named the file) and the target as the error's key and value.
    """
    if target.is_dir():
        raise error(f"cannot {action} to '{target}': it is a directory", key=key, value=target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise error(
            f"cannot {action} to '{target}': cannot create directory '{target.parent}': {exc}",
            key=key,
            value=target,
        ) from exc

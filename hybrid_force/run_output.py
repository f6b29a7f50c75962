"""The output folder of one run: checked before the run, locked during it, consistent after.

``hybrid-force run`` writes ``DIR/result.npz`` and ``DIR/summary.json`` (and with ``--plot``
the figures). :class:`RunOutput` makes these promises:

* the folder is created and proven writable before the simulation starts (a run of minutes
  is never lost to an unwritable folder);
* one run at a time writes into a folder: an exclusive ``flock`` on the folder itself is held
  from the check to the last file; a second run into the same folder is refused at once (the
  lock dies with its process, so a killed run leaves no stale lock, and no lock file);
* an extra output path (``--html``) that is the run's own result, summary, a figure the run
  writes, or the scenario file itself is refused before the run;
* result.npz and summary.json never describe different runs: the old summary and the old
  figures are removed first, then the result is written atomically, then the summary
  (atomically, carrying the same ``run_id``). A kill at any moment leaves either the old
  pair, the old result alone, the new result alone, or the new pair.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from types import TracebackType
from typing import Any

from hybrid_force._atomic import atomic_file, prepare_target
from hybrid_force.errors import BadInputError
from hybrid_force.viz.figure_names import FIGURE_NAMES, OPTIONAL_FIGURE_NAMES

__all__ = ["RESULT_NAME", "SUMMARY_NAME", "RunOutput", "locked_folder"]

RESULT_NAME = "result.npz"
SUMMARY_NAME = "summary.json"


class RunOutput:
    """The output folder of one run (a context manager holding its lock).

    Args:
        folder: the output folder (created if missing).
        inputs: files the run reads (the scenario): no output may replace one.
    """

    def __init__(self, folder: str | os.PathLike[str], inputs: Iterable[Path] = ()) -> None:
        self.folder = Path(folder)
        self.result = self.folder / RESULT_NAME
        self.summary = self.folder / SUMMARY_NAME
        names = (*FIGURE_NAMES, *OPTIONAL_FIGURE_NAMES)
        self.figures = tuple(self.folder / f"{name}.png" for name in names)
        self._inputs = tuple(Path(p) for p in inputs)
        self._stack = contextlib.ExitStack()

    # ------------------------------------------------------------------ before the run
    def check_extra(self, option: str, path: str | os.PathLike[str]) -> Path:
        """Refuse an extra output (e.g. ``--html FILE``) that would replace another file of
        this run or one of its inputs, or whose folder cannot be written; return it."""
        target = Path(path)
        mine = {
            **{_key(p): "an input of the run" for p in self._inputs},
            _key(self.result): "the run's result",
            _key(self.summary): "the run's summary",
            **{_key(f): "a figure of the run" for f in self.figures},
        }
        what = mine.get(_key(target))
        if what is not None:
            raise BadInputError(f"{option} {str(path)!r} is {what}: choose another file")
        prepare_target(target, BadInputError, f"write {option}", key=option)
        _probe(target.parent, option)
        return target

    def __enter__(self) -> RunOutput:
        """Create the folder, prove it writable and take its lock (BadInputError if held).

        Also refused: a folder where the run's own files would replace one of its inputs
        (a scenario file called summary.json in the output folder, say).
        """
        ours = {_key(f) for f in (self.result, self.summary, *self.figures)}
        for given in self._inputs:
            if _key(given) in ours:
                raise BadInputError(
                    f"--out {str(self.folder)!r}: the run would replace its input {str(given)!r}"
                )
        self._stack.enter_context(locked_folder(self.folder))
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._stack.close()

    # ------------------------------------------------------------------ after the run
    def save(self, result: Any) -> dict[str, Any]:
        """Write result.npz then summary.json (see the module docstring); return the summary."""
        summary = result.summary()
        text = json.dumps(summary, indent=2, allow_nan=False) + "\n"
        try:
            for stale in (self.summary, *self.figures):
                with contextlib.suppress(FileNotFoundError):
                    stale.unlink()
            result.save(self.result)
            with atomic_file(self.summary, "w", encoding="utf-8") as fh:
                fh.write(text)
        except OSError as exc:
            raise BadInputError(
                f"cannot write the results into {str(self.folder)!r}: {exc}"
            ) from None
        return summary


@contextlib.contextmanager
def locked_folder(folder: Path, option: str = "--out") -> Iterator[Path]:
    """Within the block, ``folder`` exists, is writable and is ours alone.

    Creates the folder, proves a file can be made in it, and holds an exclusive ``flock`` on
    it (the folder itself, so no lock file is left behind, and the lock dies with the
    process). Runs and sweeps both take it: two commands never write into one folder at once.

    Raises:
        BadInputError: naming ``option`` and the folder: cannot be created or written, not a
            folder, or another command holds its lock.
    """
    where = f"{option} {str(folder)!r}"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInputError(f"{where}: cannot create the output folder: {exc.strerror}") from None
    if not folder.is_dir():
        raise BadInputError(f"{where} is not a folder")
    _probe(folder, option)
    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    except OSError as exc:
        raise BadInputError(f"{where}: cannot open it: {exc.strerror}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno in (errno.EWOULDBLOCK, errno.EACCES, errno.EAGAIN):
                raise BadInputError(
                    f"{where}: another run or sweep is writing into this folder (it holds the "
                    f"folder's lock); wait for it or choose another {option}"
                ) from None
            raise BadInputError(f"{where}: cannot lock it: {exc}") from None
        yield folder
    finally:
        os.close(fd)  # closing the descriptor releases the lock


def _key(path: Path) -> str:
    """A path compared by where it points (resolved, also for a file that does not exist)."""
    return os.path.normcase(str(path.resolve()))


def _probe(folder: Path, option: str) -> None:
    """BadInputError unless a file can be created (and removed) in ``folder``."""
    if not folder.is_dir():
        raise BadInputError(f"{option}: the folder {str(folder)!r} does not exist")
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=".hybrid-force-probe.")
    except OSError as exc:
        raise BadInputError(
            f"{option}: cannot write into {str(folder)!r}: {exc.strerror or exc}"
        ) from None
    os.close(fd)
    os.unlink(name)

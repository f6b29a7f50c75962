"""A one-line progress report with an estimate of the time left, for commands that run many runs.

:class:`ProgressReporter` counts finished items (runs) of a known total and redraws one line on
a stream (stderr), only when that stream is a terminal unless asked otherwise, so the
machine-readable output on stdout is never touched. Used by ``hybrid-force sweep``; written so
any command that runs a list of runs (e.g. a comparison of laws) can use it as is.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Literal, TextIO

__all__ = ["Progress", "ProgressReporter", "format_duration", "progress_enabled"]

Progress = bool | Literal["force"]
"""When to draw: True on a terminal only, False never, "force" always (e.g. into a log)."""


def progress_enabled(progress: Progress, stream: TextIO) -> bool:
    """Whether a report is drawn on ``stream`` for the choice ``progress``."""
    if progress == "force":
        return True
    if not progress:
        return False
    isatty = getattr(stream, "isatty", None)
    return bool(isatty is not None and isatty())


def format_duration(seconds: float) -> str:
    """``m:ss`` below an hour, ``h:mm:ss`` above (rounded to the second)."""
    s = max(0, round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m:02d}:{s:02d}"


class ProgressReporter:
    """Finished items of ``total``, elapsed time and time left, redrawn in place on ``stream``.

    The estimate of the time left is the remaining count times the mean interval between
    finished items since the first one of this session (the start-up before the first item,
    workers starting and loading their kernels, is not spread over the items); items that were
    done before (``done``, e.g. rows kept by a resumed sweep) do not count in the rate.

    Args:
        total: number of items (≥ 0).
        done: items already finished when the report starts.
        stream: where to draw (default ``sys.stderr``).
        progress: see :data:`Progress`.
        label: a short word before the bar (e.g. ``"sweep"``).
        min_interval: least time [s] between two redraws (the last item always redraws).
        clock: the clock [s] (monotonic; a test may pass its own).
    """

    WIDTH = 30

    def __init__(
        self,
        total: int,
        *,
        done: int = 0,
        stream: TextIO | None = None,
        progress: Progress = True,
        label: str = "",
        min_interval: float = 0.1,
        clock: Callable[[], float] | None = None,
    ) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = progress_enabled(progress, self.stream)
        self.total = int(total)
        self.done = self.done0 = int(done)
        self.not_ok = 0
        self.label = label
        self.min_interval = float(min_interval)
        self._clock = clock or time.monotonic
        self.start = self._clock()
        self._first: float | None = None  # when the first item of this session finished
        self._last: float | None = None  # when the latest one finished
        self._drawn_at = -float("inf")
        self._width = 0

    def advance(self, ok: bool = True, n: int = 1) -> None:
        """Count ``n`` more finished items (``ok`` False: they are counted as not ok)."""
        now = self._clock()
        if self._first is None:
            self._first = now
        self._last = now
        self.done += n
        if not ok:
            self.not_ok += n
        self.draw(force=self.done >= self.total)

    def remaining_time(self) -> float | None:
        """Estimated seconds until every item is done; None before there is a rate; 0 done."""
        left = self.total - self.done
        if left <= 0:
            return 0.0
        new = self.done - self.done0
        if self._first is None or self._last is None or new < 2 or self._last <= self._first:
            return None
        return left * (self._last - self._first) / (new - 1)

    def line(self) -> str:
        """The text of the report (no carriage return)."""
        frac = self.done / self.total if self.total else 1.0
        filled = round(min(max(frac, 0.0), 1.0) * self.WIDTH)
        left = self.remaining_time()
        eta = "done" if left == 0.0 else "--:--" if left is None else format_duration(left)
        head = f"{self.label} " if self.label else ""
        text = (
            f"{head}[{'#' * filled}{'.' * (self.WIDTH - filled)}] {self.done}/{self.total} "
            f"{100 * frac:3.0f}%  elapsed {format_duration(self._clock() - self.start)}  "
            f"left {eta}"
        )
        return text + (f"  not ok: {self.not_ok}" if self.not_ok else "")

    def draw(self, force: bool = True) -> None:
        """Redraw the line (unless disabled, or drawn less than ``min_interval`` ago)."""
        if not self.enabled:
            return
        now = self._clock()
        if not force and now - self._drawn_at < self.min_interval:
            return
        self._drawn_at = now
        text = self.line()
        pad = " " * max(0, self._width - len(text))  # wipe a longer previous line
        self._width = len(text)
        self.stream.write(f"\r{text}{pad}")
        self.stream.flush()

    def close(self) -> None:
        """End the line (what follows on the terminal starts on a new line)."""
        if self.enabled and self._width:
            self.stream.write("\n")
            self.stream.flush()
            self._width = 0

    def __enter__(self) -> ProgressReporter:
        self.draw()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

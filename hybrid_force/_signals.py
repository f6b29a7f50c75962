"""SIGTERM as an exception, so a command stops like Ctrl-C and keeps what it computed.

``hybrid-force run`` and ``hybrid-force sweep`` are stopped by schedulers and service managers
with SIGTERM. Python's default for SIGTERM ends the process at once, losing a run's samples
or a sweep's finished rows. Inside :func:`sigterm_raises`, SIGTERM raises :class:`Terminated`,
a KeyboardInterrupt, in the main thread: every clean-up written for Ctrl-C runs, and the
command exits with 128 + 15 = 143 instead of 130.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

__all__ = ["Terminated", "sigterm_raises"]


class Terminated(KeyboardInterrupt):
    """SIGTERM reached the command (``signal`` names it, as RunFailedError does)."""

    signal = "SIGTERM"


@contextlib.contextmanager
def sigterm_raises() -> Iterator[None]:
    """While in the block, the first SIGTERM raises :class:`Terminated` in the main thread.

    A second SIGTERM during the clean-up the first one started is ignored (the clean-up takes
    well under a second). Outside the main thread handlers cannot be set, and SIGTERM keeps
    its previous meaning.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired = False

    def handler(signum: int, frame: object) -> None:
        nonlocal fired
        if not fired:
            fired = True
            raise Terminated()

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)

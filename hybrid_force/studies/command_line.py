"""What the commands that run many runs share on the command line: where the runs go, and a
command stopped by a signal.

:func:`add_engine_arguments` defines ``--workers``, ``--scheduler``, ``--start-method`` and the
progress options; :func:`run_stoppable` runs the command's runs so that SIGTERM and Ctrl-C stop
it with their exit status (143, 130), the finished rows kept. Used by ``hybrid-force sweep``
and ``hybrid-force compare``.
"""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hybrid_force._signals import Terminated, sigterm_raises
from hybrid_force.errors import RunFailedError
from hybrid_force.studies.tasks import _one_line

__all__ = ["add_engine_arguments", "run_stoppable"]


def add_engine_arguments(parser: argparse.ArgumentParser) -> None:
    """Define the options of where and how visibly the runs go (``--workers``, ``--scheduler``,
    ``--start-method``, ``--progress``/``--no-progress``): shared by ``sweep`` and ``compare``."""
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes (default: one per core; 2 for --scheduler local)",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS|local",
        help="run on a Dask cluster: a scheduler address (tcp://host:8786) or 'local' "
        "(a LocalCluster on this machine); default: a local process pool",
    )
    parser.add_argument(
        "--start-method",
        choices=("auto", "fork", "spawn"),
        default="auto",
        help="how local workers start: fork (from this process, its kernels loaded once), "
        "spawn (fresh interpreters); default auto: fork on Linux, else spawn",
    )
    parser.add_argument(
        "--progress",
        dest="progress",
        action="store_const",
        const="force",
        default=True,
        help="draw the progress line on stderr even when it is not a terminal "
        "(default: only on a terminal)",
    )
    parser.add_argument(
        "--no-progress",
        "--quiet",
        dest="progress",
        action="store_const",
        const=False,
        help="no progress line",
    )


def run_stoppable(
    run: Callable[[Callable[[dict[str, Any]], None]], Path], table: Path
) -> tuple[Path | int, int]:
    """Call ``run(on_row)`` (a :func:`run_sweep` passing ``on_row`` on) with SIGTERM raising.

    Returns:
        What ``run`` returns, or the exit status of a command it stopped (with one line on
        stderr): 143 SIGTERM, 130 Ctrl-C (the finished rows are in ``table``), 1 runs were
        lost (a RunFailedError); and the number of new rows. Bad input propagates.
    """
    n_new = 0

    def count(_row: dict[str, Any]) -> None:
        nonlocal n_new
        n_new += 1

    def stopped(how: str) -> None:
        print(
            f"{how} after {n_new} new run(s); the finished rows are in '{table}'; run the "
            "same command again to resume",
            file=sys.stderr,
        )

    try:
        with sigterm_raises():
            return run(count), n_new
    except Terminated:  # before KeyboardInterrupt, which it is
        stopped("terminated (SIGTERM)")
        return 128 + signal.SIGTERM, n_new
    except KeyboardInterrupt:
        stopped("interrupted")
        return 130, n_new
    except RunFailedError as exc:
        print(f"error: {_one_line(str(exc))}", file=sys.stderr)
        return 1, n_new

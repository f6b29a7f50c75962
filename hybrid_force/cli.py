"""Command line of hybrid_force: ``hybrid-force <subcommand> ...``.

Subcommands:

* ``robots``: list the robot models known by name, with joint count, default tip frame and
  source.

Bad input (any :class:`~hybrid_force.errors.BadInputError`) prints one line
``error: <message>`` on stderr and exits with status 2, never a traceback; a run-time
failure (:class:`~hybrid_force.errors.SimulationError`) exits with status 1.
Heavy modules (Pinocchio, numpy, matplotlib, meshcat) are imported inside the subcommand
functions, so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import NoReturn

from hybrid_force.errors import BadInputError, SimulationError

__all__ = ["build_parser", "main"]

Handler = Callable[[argparse.Namespace], int]


def _cmd_robots(args: argparse.Namespace) -> int:
    """Print a table of the named robots: name, joints, default tip, source."""
    from hybrid_force._registry import known_robots
    from hybrid_force.robot import load_robot

    rows: list[tuple[str, str, str, str]] = []
    for entry in known_robots():
        robot = load_robot(entry.name)  # checks the URDF and that the default tip exists
        rows.append((entry.name, str(robot.nv), robot.tip, entry.source))
    header = ("name", "joints", "default tip", "source")
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip())
    return 0


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line ``error: ...`` (exit status 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand (each sets ``handler``)."""
    parser = _Parser(
        prog="hybrid-force",
        description="Hybrid position-force control of robot arms on known rigid surfaces.",
    )
    sub = parser.add_subparsers(dest="command", metavar="<command>")
    sub.required = True
    robots = sub.add_parser(
        "robots",
        help="list the robot models known by name",
        description="List the robot models known by name (joint count, default tip, source).",
    )
    robots.set_defaults(handler=_cmd_robots)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status (0 ok, 1 run-time failure, 2 bad input)."""
    parser = build_parser()
    try:
        args = parser.parse_args(None if argv is None else list(argv))
    except SystemExit as exc:  # --help (0) or a usage error (2, already printed)
        return exc.code if isinstance(exc.code, int) else 0
    handler: Handler = args.handler
    try:
        return handler(args)
    except BadInputError as exc:
        print(f"error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"error: {_one_line(exc)}", file=sys.stderr)
        return 1


def _one_line(exc: BaseException) -> str:
    """The exception message on one line."""
    return " ".join(str(exc).split())


if __name__ == "__main__":
    sys.exit(main())

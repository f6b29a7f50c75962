"""Command line of hybrid_force: ``hybrid-force <subcommand> ...``.

Subcommands:

* ``run SCENARIO``: load a scenario file (with ``--set table.key=value`` overrides), simulate
  it, print a short summary, write ``DIR/result.npz`` and ``DIR/summary.json`` (and with
  ``--plot`` the figures, ``--html`` a 3D replay, ``--view`` a live viewer: these need the
  ``plots`` and ``replay`` extras, checked before the run).
* ``plot FILE``: the figures of a saved run (``.npz``) or a plot of a sweep (``.csv``).
* ``replay RESULT.npz``: the 3D replay of a saved run (hybrid_force.viz.replay).
* ``sweep SCENARIO ...``: a parameter sweep (hybrid_force.studies.sweep defines its options).
* ``compare SCENARIO --laws A,B,...``: the scenario once per control law, a table and overlay
  figures of how each did (hybrid_force.studies.compare defines its options).
* ``laws``: the control laws a scenario's ``control.law`` may name.
* ``robots``: list the robot models known by name, with joint count, default tip frame and
  source; ``robots --check MODEL [--tip FRAME]``: what loading one model finds
  (hybrid_force.model.report).

Exit status (the contract README.md documents):

* 0: the run finished as asked (warnings, e.g. a joint beyond its URDF range, are printed as
  ``warning: ...`` lines and stored in summary.json);
* 2: bad input, refused before anything runs (any :class:`~hybrid_force.errors.BadInputError`:
  scenario, model, an output folder that is not writable or is locked by another run, an
  output path that would replace the run's own files, an option whose extra is not installed,
  :class:`~hybrid_force.errors.MissingExtraError`): one line ``error: <message>``;
* 1: a run that started and failed (:class:`~hybrid_force.errors.RunFailedError`: diverged,
  lost contact, path singular on the way, an unexpected exception); its partial result and
  summary are saved with ``status = "failed"`` and ``reason``;
* 130 / 143: interrupted by Ctrl-C (SIGINT) / SIGTERM; the partial result is saved as well.

Anything else that escapes a command (out of memory, an unexpected exception from a library)
is one line ``error: <command>: ...`` with exit status 1, never a traceback; the environment
variable ``HYBRID_FORCE_TRACEBACK=1`` shows the traceback instead.

The edges of the optional extras (figures, the replay, sweeps and comparisons: matplotlib,
meshcat, dask) and the model report are imported inside the subcommand functions that need
them, so ``--help`` and ``run`` do not load them.
"""

from __future__ import annotations

import argparse
import atexit
import gc
import importlib
import json
import os
import sys
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn, TextIO

from hybrid_force._extras import require as require_extra
from hybrid_force._jit import own_kernels_only
from hybrid_force._signals import sigterm_raises
from hybrid_force.control.laws.base import LAWS
from hybrid_force.errors import (
    OWN_WARNINGS,
    BadInputError,
    MissingExtraError,
    RunFailedError,
    RunWarning,
)
from hybrid_force.geometry.mesh_field import CREASE_ANGLE, FACETS
from hybrid_force.geometry.mesh_surface import check_part
from hybrid_force.model.loading import load_robot
from hybrid_force.model.registry import known_robots
from hybrid_force.result import Result
from hybrid_force.run_output import RunOutput
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.scenario.overrides import parse_override
from hybrid_force.schema_docs import json_schema, markdown_tables, with_generated_tables
from hybrid_force.sim.loop import simulate

__all__ = ["build_parser", "console", "main"]

Handler = Callable[[argparse.Namespace], int]


def _cmd_laws(args: argparse.Namespace) -> int:
    """Print the control laws a scenario's ``control.law`` may name, one line each; with
    ``--options`` also each law's ``[control.<law>]`` keys."""

    width = max(len(name) for name in LAWS)
    for name, spec in LAWS.items():
        print(f"{name:<{width}}  {spec.summary}")
        for key, doc in spec.describe() if args.options else ():
            print(f"{'':<{width}}    control.{name}.{key}: {doc}")
    return 0


def _cmd_schema(args: argparse.Namespace) -> int:
    """Print the JSON Schema of a scenario file; ``--markdown``: the key tables of
    docs/scenarios.md; ``--update-docs FILE``: rewrite FILE's generated tables in place."""

    if args.update_docs:
        path = Path(args.update_docs)
        path.write_text(with_generated_tables(path.read_text(encoding="utf-8")), encoding="utf-8")
    elif args.markdown:
        for name, table in markdown_tables().items():
            print(f"<!-- generated: {name} -->\n{table}\n<!-- end generated -->\n")
    else:
        print(json.dumps(json_schema(), indent=2, ensure_ascii=False))
    return 0


def _cmd_part(args: argparse.Namespace) -> int:
    """``part --check FILE``: read and fit a mesh part as ``[surface] type = "mesh"`` would
    and print what :func:`~hybrid_force.geometry.mesh_surface.check_part` measures."""
    report = check_part(
        args.check,
        resolution=args.resolution,
        scale=args.scale,
        facets=args.facets,
        crease_angle=args.crease_angle,
    )
    for line in report.lines():
        print(line)
    return 0


def _cmd_robots(args: argparse.Namespace) -> int:
    """Print a table of the named robots (name, joints, default tip, source), or with
    ``--check MODEL`` what loading that model finds (hybrid_force.model.report)."""
    if args.check is not None:
        from hybrid_force.model.report import format_report, model_report

        xacro_args: dict[str, str] = {}
        for text in args.xacro_arg:
            name, sep, value = text.partition("=")
            if not sep or not name.strip():
                raise BadInputError(f"robots: --xacro-arg {text!r} must look like NAME=VALUE")
            xacro_args[name.strip()] = value
        report = model_report(
            args.check,
            tip=args.tip,
            package_dirs=args.package_dir,
            xacro_args=xacro_args or None,
            lock_off_chain=False if args.keep_off_chain else None,
            xacro_trust=args.trust_xacro,
        )
        sys.stdout.write(format_report(report))
        return 0
    given = [
        o
        for o, v in (
            ("--tip", args.tip is not None),
            ("--package-dir", args.package_dir),
            ("--xacro-arg", args.xacro_arg),
            ("--keep-off-chain", args.keep_off_chain),
            ("--trust-xacro", args.trust_xacro),
        )
        if v
    ]
    if given:
        raise BadInputError(f"robots: {', '.join(given)} needs --check MODEL")

    rows: list[tuple[str, str, str, str]] = []
    for entry in known_robots():
        robot = load_robot(entry.name)  # checks the URDF and that the default tip exists
        rows.append((entry.name, str(robot.nv), robot.tip, entry.source))
    header = ("name", "joints", "default tip", "source")
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip())
    return 0


def _import_feature(module: str, feature: str) -> Any:
    """Import ``module`` for ``feature``; MissingExtraError (exit status 2) if it is missing."""

    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name == module:
            raise MissingExtraError(
                f"{feature} is not available: the module {module} is missing from this install",
                module=module,
            ) from None
        raise


class _Progress:
    """A one-line text progress bar with ETA on a terminal stream (shown after 1 s)."""

    WIDTH = 30

    def __init__(self, stream: TextIO, label: str, delay: float = 1.0) -> None:
        self.stream = stream
        self.label = label
        self.delay = delay
        self.start = time.perf_counter()
        self.shown = False
        self.length = 0

    def __call__(self, fraction: float) -> None:
        elapsed = time.perf_counter() - self.start
        if elapsed < self.delay:
            return
        fraction = min(max(float(fraction), 0.0), 1.0)
        filled = round(self.WIDTH * fraction)
        eta = elapsed * (1.0 - fraction) / fraction if fraction > 0 else float("nan")
        eta_text = f"ETA {eta:5.0f} s" if eta == eta else "ETA     ? s"
        line = (
            f"\r{self.label} [{'#' * filled}{'.' * (self.WIDTH - filled)}] "
            f"{100 * fraction:3.0f}%  {eta_text}"
        )
        self.length = max(self.length, len(line))
        self.stream.write(line)
        self.stream.flush()
        self.shown = True

    def close(self) -> None:
        """Erase the bar (the summary follows on stdout)."""
        if self.shown:
            self.stream.write("\r" + " " * self.length + "\r")
            self.stream.flush()
            self.shown = False


def _output_dir(text: str | os.PathLike[str]) -> Path:
    out = Path(text)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInputError(f"cannot create output directory {str(out)!r}: {exc}") from None
    return out


def _num(x: object, unit: str, fmt: str = ".3g") -> str:
    return "-" if x is None else f"{format(float(x), fmt)} {unit}"  # type: ignore[arg-type]


def _print_summary(summary: dict[str, Any], out: Path, stream: TextIO) -> None:
    """A few lines for humans: errors, contact, impact, speed, where the files are."""
    settle = summary.get("settle_time")
    sps = summary.get("steps_per_second")
    lines = [
        f"{summary.get('name')}: {summary.get('status')}, {summary.get('n_samples')} samples, "
        f"{_num(sps, 'steps/s', '.0f')}",
        f"  position error: final {_num(summary.get('final_position_error'), 'm')}, "
        f"worst {_num(summary.get('position_error_max'), 'm')}, "
        f"worst after t = {settle:g} s {_num(summary.get('position_error_max_settled'), 'm')}",
        f"  force error |f - f_d|: final {_num(summary.get('final_force_error'), 'N')}, "
        f"worst after t = {settle:g} s {_num(summary.get('force_error_max_settled'), 'N')}",
        f"  contact at t = {_num(summary.get('contact_time'), 's', '.4g')}, "
        f"impact speed {_num(summary.get('impact_speed'), 'm/s')}, "
        f"worst distance in contact {_num(summary.get('worst_constraint_violation'), 'm')}",
    ]
    if summary.get("tool_angle_final") is not None:  # [tool] orientation = "normal"
        lines.append(
            f"  tool axis from its desired direction: final "
            f"{_num(summary.get('tool_angle_final'), 'rad')}, worst after t = {settle:g} s "
            f"{_num(summary.get('tool_angle_max_settled'), 'rad')}"
        )
    lines.append(f"  wrote {out / 'result.npz'} and {out / 'summary.json'}")
    print("\n".join(lines), file=stream)


#: Exit status of a run stopped by a signal: 128 + the signal's number, as shells report it.
_SIGNAL_STATUS = {"SIGINT": 130, "SIGTERM": 143}


def _cmd_run(args: argparse.Namespace) -> int:
    """Load, run, summarise and save a scenario (see the module docstring)."""

    # what the options ask for beyond the core, before anything runs (MissingExtraError, exit 2)
    if args.plot:
        require_extra("plots", "--plot (the figures)")
    if args.html is not None or args.view:
        require_extra("replay", "--html and --view (the 3D replay)")
    overrides: dict[str, object] = {}
    for text in args.set or []:
        key, value = parse_override(text)
        overrides[key] = value
    if args.trust_xacro:
        overrides["robot.xacro_trust"] = True
    with warnings.catch_warnings(record=True) as loaded:  # shown now, kept in the summary
        for category in OWN_WARNINGS:
            warnings.simplefilter("always", category)
        scenario = load_scenario(args.scenario, overrides)
    _show_warnings(loaded)
    load_notes = [_one_line(w.message) for w in loaded if issubclass(w.category, OWN_WARNINGS)]
    output = RunOutput(
        args.out if args.out is not None else Path("runs") / scenario.name,
        inputs=[Path(args.scenario)],
    )
    html = output.check_extra("--html", args.html) if args.html is not None else None
    with output, sigterm_raises():
        show = not args.quiet and sys.stderr.isatty()
        progress = _Progress(sys.stderr, scenario.name) if show else None
        caught: list[warnings.WarningMessage] = []
        failure: RunFailedError | None = None
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", RunWarning)
                result = simulate(scenario, progress=progress)
        except RunFailedError as exc:
            failure = exc
        finally:
            if progress is not None:
                progress.close()
        _show_warnings(caught)
        if failure is not None:
            if failure.result is not None and load_notes:
                failure.result = _with_notes(failure.result, load_notes)
            return _run_failed(failure, output, args)
        summary = output.save(_with_notes(result, load_notes))
        if not args.quiet:
            _print_summary(summary, output.folder, sys.stdout)
        if args.plot:
            _plot_result(result, output.folder, quiet=args.quiet)
        if html is not None:
            replay = _import_feature("hybrid_force.viz.replay", "the 3D replay (--html)")
            replay.write_html(result, html)
            if not args.quiet:
                print(f"  wrote {html}")
    if args.view:
        replay = _import_feature("hybrid_force.viz.replay", "the 3D viewer (--view)")
        replay.serve(result)
    return 0


def _with_notes(result: Any, notes: Sequence[str]) -> Any:
    """The result with the scenario's load warnings first in its one list of warnings
    (summary.json ``warnings``, ``n_warnings``)."""
    if not notes:
        return result
    return result.with_meta(warnings=[*notes, *(result.meta.get("warnings") or [])])


def _show_warnings(caught: Sequence[warnings.WarningMessage]) -> None:
    """Show the warnings a run recorded (after its progress bar is gone)."""
    for w in caught:
        warnings.showwarning(w.message, w.category, w.filename, w.lineno)


def _run_failed(exc: RunFailedError, output: Any, args: argparse.Namespace) -> int:
    """Save the partial result of a failed run, say where; return the exit status."""
    status = _SIGNAL_STATUS.get(exc.signal or "SIGINT", 130) if exc.reason == "interrupted" else 1
    where = ""
    if exc.result is not None:
        # a second interrupt while saving must not leave half a pair: the writes are atomic
        output.save(exc.result)
        if args.plot and status == 1:
            try:
                _plot_result(exc.result, output.folder, quiet=True)
            except BadInputError as plot_exc:  # e.g. fewer than 2 samples: the run's verdict stands
                print(f"warning: no figures: {_one_line(plot_exc)}", file=sys.stderr)
        t_end = float(exc.result.t[-1]) if exc.result.n_samples else 0.0
        where = (
            f" (its result up to t = {t_end:.6g} s saved in {output.result} and {output.summary})"
        )
    print(f"error: run failed ({exc.reason}): {_one_line(exc)}{where}", file=sys.stderr)
    return status


def _plot_result(result: Any, out: Path, *, quiet: bool) -> list[Path]:
    from hybrid_force.viz.run_figures import plot_result

    files = plot_result(result, out)
    if not quiet:
        print(f"  wrote {len(files)} figures: {', '.join(str(f) for f in files)}")
    return files


def _cmd_plot(args: argparse.Namespace) -> int:
    """Figures of a saved run (.npz) or a sweep plot (.csv)."""
    require_extra("plots", "figures")  # before the output folder is made
    path = Path(args.file)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        if args.x is not None or args.y is not None or args.metric is not None:
            raise BadInputError(
                f"--x, --y and --metric apply to a sweep CSV, not to a run result ({path})"
            )

        result = Result.load(path)
        out = _output_dir(args.out if args.out is not None else path.parent)
        _plot_result(result, out, quiet=False)
        return 0
    if suffix == ".csv":
        if args.x is None or args.metric is None:
            raise BadInputError(
                f"plotting the sweep {path} needs --x <table.key> and --metric <name> "
                "(and optionally --y <table.key> for a heat map)"
            )
        from hybrid_force.viz.sweep_plots import plot_sweep

        # not made here: plot_sweep makes it once the table has been read (nothing left behind)
        out = Path(args.out) if args.out is not None else path.parent
        ys = f"_{args.y}" if args.y is not None else ""
        png = out / f"{path.stem}_{args.metric}_vs_{args.x}{ys}.png"
        written = plot_sweep(path, png, x=args.x, y=args.y, metric=args.metric)
        print(f"wrote {written}")
        return 0
    raise BadInputError(
        f"cannot plot {str(path)!r}: expected a run result (.npz) or a sweep table (.csv)"
    )


def _cmd_replay(args: argparse.Namespace) -> int:
    """3D replay of a saved run (delegated to hybrid_force.viz.replay)."""
    replay = _import_feature("hybrid_force.viz.replay", "the 3D replay")
    return int(replay.replay_command(args))


def _cmd_study_missing(args: argparse.Namespace) -> int:
    _import_feature(f"hybrid_force.studies.{args.command}", f"the {args.command} command")
    raise MissingExtraError(  # pragma: no cover
        f"the {args.command} command is not available",
        module=f"hybrid_force.studies.{args.command}",
    )


def _cmd_study(args: argparse.Namespace) -> int:
    """A sweep or a comparison of laws (delegated to hybrid_force.studies.<command>)."""
    module = _import_feature(f"hybrid_force.studies.{args.command}", f"the {args.command} command")
    return int(getattr(module, f"{args.command}_command")(args))


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line ``error: ...`` (exit status 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"error: {message} (see '{self.prog} --help')\n")


def build_parser(
    *, sweep_options: bool = True, compare_options: bool = True
) -> argparse.ArgumentParser:
    """The argument parser with every subcommand (each sets ``handler``).

    sweep_options, compare_options: let hybrid_force.studies.sweep (compare) add the options of
    ``sweep`` (``compare``) (imports that module; :func:`main` does so only when the command
    is that one, so ``--help`` stays fast).
    """
    parser = _Parser(
        prog="hybrid-force",
        description="Hybrid position-force control of robot arms on known rigid surfaces.",
    )
    sub = parser.add_subparsers(dest="command", metavar="<command>")
    sub.required = True
    robots = sub.add_parser(
        "robots",
        help="list the robot models known by name, or check one model",
        description=(
            "List the robot models known by name (joint count, default tip, source). With "
            "--check MODEL: load MODEL (a name or a URDF path) as a scenario would and print "
            "its joints and limits, the tip and other tip frames, the total mass, the reach, "
            "the meshes its visuals reference (found or missing) and the model's warnings; "
            "exit status 2 with one error line if it cannot be simulated (docs/robots.md)."
        ),
    )
    robots.add_argument(
        "--check", metavar="MODEL", default=None, help="report on one model (name or URDF path)"
    )
    robots.add_argument(
        "--tip", metavar="FRAME", default=None, help="with --check: the tip frame to load with"
    )
    _repeatable(
        robots,
        "--package-dir",
        "DIR",
        "with --check: a folder holding package://NAME/... as NAME/... (repeatable)",
    )
    _repeatable(
        robots,
        "--xacro-arg",
        "NAME=VALUE",
        "with --check: an argument of a .xacro model (repeatable)",
    )
    robots.add_argument(
        "--keep-off-chain",
        action="store_true",
        help="with --check: keep the joints off the chain to the tip free (not locked)",
    )
    robots.add_argument(
        "--trust-xacro",
        action="store_true",
        help="with --check: let xacro run the .xacro model's Python expressions (trusted "
        "files only; by default they are evaluated as data, docs/robots.md)",
    )
    robots.set_defaults(handler=_cmd_robots)
    laws = sub.add_parser(
        "laws",
        help="list the control laws a scenario can name (control.law)",
        description="List the control laws a scenario's control.law can name, one line each "
        "with its source; --options also lists the keys of each law's [control.<law>] table.",
    )
    laws.add_argument("--options", action="store_true", help="also list each law's settings")
    laws.set_defaults(handler=_cmd_laws)
    schema = sub.add_parser(
        "schema",
        help="the JSON Schema of a scenario file (for editors), or the docs' key tables",
        description="Print the JSON Schema (draft 2020-12) of a scenario file, generated from "
        "the settings dataclasses the loader reads; --markdown prints the key tables of "
        "docs/scenarios.md, --update-docs FILE rewrites them in FILE.",
    )
    schema.add_argument("--markdown", action="store_true", help="print the docs' key tables")
    schema.add_argument("--update-docs", metavar="FILE", default=None, help="rewrite its tables")
    schema.set_defaults(handler=_cmd_schema)
    part = sub.add_parser(
        "part",
        help="check a mesh part (STL, OBJ, PLY) and its smooth distance field",
        description='Read a mesh part as [surface] type = "mesh" does, fit (or read from the '
        "cache) its smooth signed-distance field and print: faces, watertight or not, the "
        "bounding box, how far the curved patches bend off the faces, the grid and its memory, "
        "the fit error max |Φ − d| at the "
        "vertices, the face centres and over the band, the smallest concave radius of "
        "curvature, the build time and the cache file (docs/mesh_parts.md); exit status 2 "
        "with one error line for a file that cannot be used.",
    )
    part.add_argument("--check", metavar="FILE", required=True, help="the mesh file")
    part.add_argument(
        "--resolution",
        metavar="R",
        type=float,
        default=None,
        help="grid spacing [m] (default: twice the facets' size, clamped)",
    )
    part.add_argument(
        "--scale", metavar="S", type=float, default=1.0, help="the file's units in metres"
    )
    part.add_argument(
        "--facets",
        choices=FACETS,
        default="curved",
        help="curved: the patches through the vertices (default); flat: the faces themselves",
    )
    part.add_argument(
        "--crease-angle",
        metavar="DEG",
        type=float,
        default=CREASE_ANGLE,
        help=f"faces meeting at more than this keep a sharp edge (default {CREASE_ANGLE:g})",
    )
    part.set_defaults(handler=_cmd_part)
    _add_run(sub)
    _add_plot(sub)
    _add_replay(sub)
    _add_study(
        sub,
        "sweep",
        "run a scenario over a grid of parameter values",
        "Run a scenario over a grid of parameter values and write a CSV table.",
        sweep_options,
    )
    _add_study(
        sub,
        "compare",
        "run a scenario once per control law and compare them",
        "Run a scenario once per control law (same plant, sensor and seed: only control.law "
        "differs), on the sweep's workers, and write a CSV table of the laws' force and path "
        "errors, impact peak, time off the surface, settling time, peak torque and wall time, "
        "with overlay figures of the force and path errors (docs/compare.md).",
        compare_options,
    )
    return parser


def _repeatable(parser: argparse.ArgumentParser, flag: str, metavar: str, help: str) -> None:
    """A repeatable option of ``parser``: each use appends its value to a list, empty if unused."""
    parser.add_argument(flag, metavar=metavar, action="append", default=[], help=help)


def _add_run(sub: Any) -> None:
    run = sub.add_parser(
        "run",
        help="run a scenario file and save its result",
        description=(
            "Load a scenario file (TOML, see docs/scenarios.md), simulate it, print a short "
            "summary and write DIR/result.npz and DIR/summary.json. Exit status: 0 ok, "
            "1 the run failed (its partial result is saved), 2 bad input, 130/143 "
            "interrupted by SIGINT/SIGTERM (partial result saved)."
        ),
    )
    run.add_argument("scenario", metavar="SCENARIO", help="scenario file (.toml)")
    run.add_argument(
        "--out", metavar="DIR", default=None, help="output folder (default: runs/<name>/)"
    )
    _repeatable(
        run,
        "--set",
        "TABLE.KEY=VALUE",
        "override a key of the file (TOML value), e.g. --set sim.duration=2; repeatable",
    )
    run.add_argument("--plot", action="store_true", help="also write the figures (PNG) into DIR")
    run.add_argument("--html", metavar="FILE", default=None, help="write a 3D replay (HTML)")
    run.add_argument("--view", action="store_true", help="open the 3D viewer after the run")
    run.add_argument("--quiet", action="store_true", help="no progress bar and no summary")
    run.add_argument(
        "--trust-xacro",
        action="store_true",
        help="let xacro run the .xacro model's Python expressions (as robot.xacro_trust = "
        "true; trusted files only, docs/robots.md)",
    )
    run.set_defaults(handler=_cmd_run)


def _add_plot(sub: Any) -> None:
    plot = sub.add_parser(
        "plot",
        help="figures of a saved run (.npz) or of a sweep (.csv)",
        description=(
            "FILE.npz (a run): the paper's figures as PNGs. FILE.csv (a sweep): a metric "
            "against one swept parameter (--x), or a heat map over two (--x and --y)."
        ),
    )
    plot.add_argument("file", metavar="FILE", help="result.npz of a run, or a sweep .csv")
    plot.add_argument(
        "--out", metavar="DIR", default=None, help="output folder (default: FILE's folder)"
    )
    plot.add_argument("--x", metavar="TABLE.KEY", default=None, help="sweep: x parameter")
    plot.add_argument("--y", metavar="TABLE.KEY", default=None, help="sweep: y parameter")
    plot.add_argument("--metric", metavar="NAME", default=None, help="sweep: metric column")
    plot.set_defaults(handler=_cmd_plot)


def _add_replay(sub: Any) -> None:
    replay = sub.add_parser(
        "replay",
        help="3D replay of a saved run",
        description="Replay a saved run in 3D: in the browser, or as a self-contained HTML file.",
    )
    replay.add_argument("result", metavar="RESULT.npz", help="result file of a run")
    replay.add_argument("--html", metavar="FILE", default=None, help="write an HTML file")
    replay.add_argument("--port", metavar="N", type=int, default=None, help="viewer port")
    replay.set_defaults(handler=_cmd_replay)


def _add_study(sub: Any, name: str, summary: str, description: str, with_options: bool) -> None:
    """The subcommand ``name`` of hybrid_force.studies.<name>, whose ``add_<name>_arguments``
    defines its options (only when ``with_options``: importing the module costs time)."""
    parser = sub.add_parser(name, help=summary, description=description)
    if not with_options:
        parser.set_defaults(handler=_cmd_study)
        return
    try:
        module = _import_feature(f"hybrid_force.studies.{name}", f"the {name} command")
    except MissingExtraError:
        parser.add_argument("args", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
        parser.set_defaults(handler=_cmd_study_missing)
        return
    getattr(module, f"add_{name}_arguments")(parser)
    parser.set_defaults(handler=_cmd_study)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status (0 ok, 1 run-time failure, 2 bad input)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    command = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(sweep_options=command == "sweep", compare_options=command == "compare")
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2, already printed)
        return exc.code if isinstance(exc.code, int) else 0
    handler: Handler = args.handler
    # When the process exits, Python's last garbage collection walks every object the loaded
    # kernels left (about 0.2 s of a short run's or sweep's wall time); frozen, they are skipped.
    atexit.register(gc.freeze)
    try:
        # a command compiles no code but the kernels: Numba can skip SciPy (see _jit)
        with warnings.catch_warnings(), own_kernels_only():
            warnings.showwarning = _show_warning
            return handler(args)
    except BadInputError as exc:
        print(f"error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except RunFailedError as exc:
        print(f"error: {_one_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:  # outside a run (Terminated: SIGTERM in a run's clean-up)
        print("error: interrupted", file=sys.stderr)
        return _SIGNAL_STATUS.get(getattr(exc, "signal", "SIGINT"), 130)
    except MemoryError:
        gc.collect()  # what the failed allocation left, so that printing has room
        print(
            f"error: {command or 'hybrid-force'}: out of memory (MemoryError); the input asks "
            "for more than this machine has (see the documented maximums in docs/)",
            file=sys.stderr,
        )
        return 1
    except Exception as exc:  # the command line's last resort: one line, never a traceback
        if os.environ.get(_TRACEBACK_ENV):
            raise
        print(
            f"error: {command or 'hybrid-force'}: unexpected {type(exc).__name__}: "
            f"{_one_line(exc) or '(no message)'} (set {_TRACEBACK_ENV}=1 for the traceback; "
            "please report it)",
            file=sys.stderr,
        )
        return 1


#: Set (to anything) to see the traceback of an unexpected exception instead of one line.
_TRACEBACK_ENV = "HYBRID_FORCE_TRACEBACK"


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """The toolkit's own warnings as one line ``warning: <message>``; others (numpy's
    RuntimeWarning of an overflow, a library's DeprecationWarning) as one line too, with their
    category and where they come from, not Python's two lines with the source."""
    if issubclass(category, OWN_WARNINGS):
        print(f"warning: {_one_line(message)}", file=sys.stderr)
    else:
        where = f"{Path(filename).name}:{lineno}"
        print(f"warning: {category.__name__}: {_one_line(message)} ({where})", file=sys.stderr)


def _one_line(exc: object) -> str:
    """The exception message on one line."""
    return " ".join(str(exc).split())


def console() -> int:
    """The ``hybrid-force`` console script (and ``python -m hybrid_force.cli``): :func:`main`,
    then, when nothing else runs in the process, an exit without Python's teardown.

    Before :func:`main`, the objects the imports made (numpy's, Pinocchio's, the package's) are
    frozen (:func:`gc.freeze`): the garbage collections of the command (many while Numba is
    imported and the kernels load, one of them a full one) no longer walk them, about 0.03 to
    0.06 s of a short command; they live as long as the process anyway.

    A command's files are closed and in place when :func:`main` returns; what is left is the
    exit handlers (``atexit``: the libraries' clean-ups, temporary folders), which are run here,
    stdout and stderr, which are flushed, and the interpreter's teardown, which frees every
    module's objects one at a time (Numba's and LLVM's: 0.05 to 0.1 s of a short command,
    ``benchmarks/bench_fixed_cost.py --phases``), which ``os._exit`` skips. While another
    thread is alive (a viewer, a pool of workers) the process exits as usual, after it.
    Returns the exit status in that case only.
    """
    gc.freeze()
    status = main()
    if threading.active_count() > 1:
        return status
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: as Python's exit, status 120
            status = status or 120
    os._exit(status)


if __name__ == "__main__":
    sys.exit(console())

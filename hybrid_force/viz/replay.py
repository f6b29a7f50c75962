"""Browser 3D replay of a run with meshcat: a self-contained HTML recording or a live viewer.

A :class:`Replay` turns a :class:`~hybrid_force.result.Result` (or a saved ``result.npz``) into a
meshcat scene:

* the arm with its URDF *visual* geometry (primitives or meshes, no collision geometry), loaded
  through :class:`pinocchio.visualize.MeshcatVisualizer`, under ``/meshcat/robot/visuals/<name>``;
* every surface of the constraint, translucent, sized around the motion (a cylinder segment
  spanning the motion along its axis, a sphere, a square plate for a plane), under
  ``/meshcat/replay/surfaces/surface_<i>``;
* the desired tip path ``p_d`` (dashed colour, ``/meshcat/replay/paths/desired``) and the actual
  tip path ``p`` (``/meshcat/replay/paths/actual``) as polylines, thinned to a bounded number of
  points;
* the tip marker ``/meshcat/replay/tip`` whose visible child shows the phase
  (``free`` grey, ``near`` orange, ``contact`` green; a ball-end tool's is its ball);
* one force arrow per surface, ``/meshcat/replay/force/arrow_<i>``: it ends at the tip and points
  along −n̂ (n̂ = unit surface normal to the free side), i.e. it shows the force the tool applies on
  the surface; its length is ``force_scale · |f|`` [m] capped at ``force_cap``; it is hidden when
  f = 0;
* for a run with ``[tool] orientation = "normal"``, the tool axis ``/meshcat/replay/tool_axis``:
  a rod of ``tool_length`` from the tip back along the actual tool axis a = R(q) â (the tool's
  shaft, its tip on the surface);
* for a run with ``[removal]``, the depth removed by the end of the run,
  ``/meshcat/replay/removal``: a point at each cell of the removal grid coloured by its depth
  (viridis, the colormap of ``removal.png``, from the least depth to the greatest; at most
  ``max_removal_points`` points, a larger grid averaged into voxels), with its colour scale in
  µm in the page's legend (printed by :func:`serve`); see :mod:`.scene_removal`.

Time runs at real speed: the run is resampled at ``fps`` frames per second (linear interpolation
of q, p and f between samples; the phase of the latest sample) into a
:class:`meshcat.animation.Animation`; meshcat's own play / pause / reset / time controls drive it.
Animation time τ [s] = t − t[0].

Outputs:

* :func:`write_html`: one self-contained HTML file (meshcat's JavaScript inlined, the scene as
  inline base64 msgpack commands decoded synchronously) that makes no network request;
* :func:`serve`: a live meshcat server bound to 127.0.0.1 only; prints its URL, plays the run once
  a browser connects and always shuts the server process down (also on Ctrl-C, SIGTERM, or if
  this process dies);
* :func:`show`: an ``IPython.display.HTML`` iframe of the static recording for notebooks
  (``from hybrid_force import replay; replay.show(result)``);
* :func:`replay_command`: the ``hybrid-force replay`` subcommand.

The page exposes ``window.viewer`` (meshcat's viewer; ``viewer.animator`` seeks and plays) and
``window.hybridForceReplay`` (``fps``, ``t0``, ``duration``, ``n_frames``, ``nodes``: the scene
paths above) for scripts and tests.

The scene is built in :mod:`hybrid_force.viz.scene` (the robot's visuals in
:mod:`.robot_visuals`), the page in :mod:`.html_page`, the live server in :mod:`.live_server`;
this module gathers the public names and the functions above.
"""

from __future__ import annotations

import html as html_lib
import os
import sys
from pathlib import Path
from typing import Any

from hybrid_force.result import Result
from hybrid_force.run_output import RunOutput
from hybrid_force.viz.live_server import _serve_replay
from hybrid_force.viz.replay_view import ReplaySettings
from hybrid_force.viz.scene import Replay
from hybrid_force.viz.scene_removal import legend

__all__ = ["html", "replay_command", "serve", "show", "write_html"]


def html(result_or_path: Result | str | os.PathLike[str], *, fps: float = 30.0) -> str:
    """The self-contained HTML replay of a run as a string (see :meth:`Replay.html`)."""
    return Replay(result_or_path, ReplaySettings(fps=fps)).html()


def write_html(
    result_or_path: Result | str | os.PathLike[str],
    path: str | os.PathLike[str],
    *,
    fps: float = 30.0,
) -> Path:
    """Write the self-contained HTML replay of a run to ``path`` atomically; return the path.

    The page has meshcat's viewer JavaScript inlined and makes no network request; it plays the
    run at real speed, resampled at ``fps`` frames per second.

    Raises:
        BadInputError: ``result_or_path`` is a missing, truncated or non-result file.
        BadInputError: the result's robot cannot be found, or ``path`` cannot be written.
    """
    return Replay(result_or_path, ReplaySettings(fps=fps)).write_html(path)


def serve(
    result_or_path: Result | str | os.PathLike[str],
    *,
    port: int | None = None,
    loop: bool = False,
    fps: float = 30.0,
    browser_timeout: float | None = None,
) -> None:
    """Replay a run in a live meshcat viewer served on 127.0.0.1 only.

    Starts a meshcat server subprocess (web port ``port``, or the first free one from 7000),
    prints its URL, waits until a browser connects, plays the run in real time (forever with
    ``loop=True``) and returns; the server process is terminated in every case, including
    Ctrl-C (KeyboardInterrupt is re-raised after the shutdown), SIGTERM/SIGHUP (turned into
    KeyboardInterrupt) and the death of this process (the server watches its parent).

    Args:
        browser_timeout: stop waiting for a browser after this many seconds [s] (None: wait).

    Raises:
        BadInputError, BadInputError: as :func:`write_html`; BadInputError also when ``port``
            is already in use.
    """
    replay = Replay(result_or_path, ReplaySettings(fps=fps))
    if replay.removal is not None:  # the live viewer has no legend: the scale is printed
        scale = legend(replay.removal)
        print(
            f"removal colours: {scale['title']}, viridis from {scale['low_um']:.4g} (dark "
            f"violet) to {scale['high_um']:.4g} (yellow)",
            flush=True,
        )
    _serve_replay(replay, port=port, loop=loop, browser_timeout=browser_timeout)


def show(
    result_or_path: Result | str | os.PathLike[str], *, fps: float = 30.0, height: int = 480
) -> Any:
    """Notebook display: an ``IPython.display.HTML`` iframe holding the static replay.

    Works offline and without a server (the recording is inlined with ``srcdoc``)::

        from hybrid_force import replay
        replay.show(result)
    """
    from IPython.display import HTML

    page = Replay(result_or_path, ReplaySettings(fps=fps)).html()
    return HTML(
        f'<div style="height: {int(height)}px; width: 100%; resize: both; overflow: hidden">'
        f'<iframe srcdoc="{html_lib.escape(page, quote=True)}" '
        'style="width: 100%; height: 100%; border: none"></iframe></div>'
    )


def replay_command(args: Any) -> int:
    """The ``hybrid-force replay RESULT.npz [--html FILE] [--port N]`` subcommand.

    ``args.result``: path of a result.npz; ``args.html``: write the HTML there instead of serving
    (None to serve); ``args.port``: web port of the live server (None: pick a free one).
    Returns 0 on success, 130 after Ctrl-C; bad input raises BadInputError (exit 2 in the CLI).
    """
    html_path = getattr(args, "html", None)
    if html_path is not None:
        # never write the page over the result it replays, or over its summary or figures
        source = Path(args.result)
        html_path = RunOutput(source.parent, inputs=[source]).check_extra("--html", html_path)
        out = write_html(args.result, html_path)
        size = out.stat().st_size
        print(f"wrote {out} ({size / 1e6:.2f} MB)")
        return 0
    try:
        serve(args.result, port=getattr(args, "port", None))
    except KeyboardInterrupt:
        print("interrupted; meshcat server stopped", file=sys.stderr)
        return 130
    return 0

"""The figure of a law's own signals (``law_log.png``): each against time, relative to its start.

Drawn by :func:`~hybrid_force.viz.run_figures.plot_result` when the run's law logged signals
(``Result.law_log``, :mod:`hybrid_force.law_log`), e.g. the parameter estimates θ̂ of
``arimoto_adaptive``, whose start value is the controller's model: the top panel shows each
signal divided by its value at the start (θ̂/θ_model: 1 = the model, 0.9 = 10 % below it); the
signals that start at 0 cannot be divided and are drawn as they are in the bottom panel.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybrid_force.viz._run_data import _Run
from hybrid_force.viz._style import _new_figure, _note

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["law_log_figure"]

_MAX_LEGEND = 16  # more lines than this: no legend (it would hide the plot), a note instead


def law_log_figure(run: _Run) -> Figure | None:
    """The figure of ``run.law_log`` (N, m) against ``run.t`` [s]; None when m = 0."""
    log = run.law_log
    if log is None or log.shape[1] == 0:
        return None
    start = log[0]
    scaled = np.isfinite(start) & (start != 0.0)
    fig = _new_figure(9.5, 7.5)
    top, bottom = fig.subplots(2, 1, sharex=True)
    names = np.array(run.law_log_names, dtype=object)
    _lines(top, run.t, log[:, scaled] / start[scaled], list(names[scaled]))
    top.axhline(1.0, color="0.5", lw=0.8, ls="--")
    top.set_ylabel("signal / its value at the start")
    _lines(bottom, run.t, log[:, ~scaled], list(names[~scaled]))
    bottom.set_ylabel("signals starting at 0 [their units]")
    bottom.set_xlabel("t [s]")
    bottom.set_xlim(run.t[0], run.t[-1])
    fig.suptitle(f"{run.name}: the law's own signals ({log.shape[1]})")
    return fig


def _lines(ax: Axes, t: np.ndarray, y: np.ndarray, names: list[str]) -> None:
    """One line per column of y (N, c), with a legend on the right when c is small."""
    ax.grid(True, alpha=0.3)
    if y.shape[1] == 0:
        _note(ax, "none")
        return
    for j, name in enumerate(names):
        ax.plot(t, y[:, j], lw=1.0, label=name)
    if len(names) <= _MAX_LEGEND:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=7)
    else:
        _note(ax, f"{len(names)} signals (too many to label)")

"""The names of a run's figure files, apart from the code that draws them.

A run's output folder (:class:`hybrid_force.run_output.RunOutput`) needs the names before the
run, to refuse an output path that would replace a figure; importing them from here keeps the
figure code (and its imports) out of a run that draws none.
"""

from __future__ import annotations

__all__ = ["FIGURE_NAMES", "LAW_LOG_FIGURE", "OPTIONAL_FIGURE_NAMES"]

#: The law's own signals over time (:mod:`hybrid_force.viz.law_log_figure`).
LAW_LOG_FIGURE = "law_log"

#: Base names of the files :func:`hybrid_force.viz.run_figures.plot_result` writes, in order
#: (each gets ``prefix`` and ``.png``).
FIGURE_NAMES: tuple[str, ...] = (
    "path3d",
    "projection",
    "position_errors",
    "force_error",
    "desired_force",
    "lyapunov",
)
#: Files ``plot_result`` writes after those only when the run has what they show (the law's
#: own signals; ``tool_angle``: a run that controlled the tool's direction; ``removal``: a run
#: with ``[removal]``, :mod:`hybrid_force.viz.removal_figure`).
OPTIONAL_FIGURE_NAMES: tuple[str, ...] = (LAW_LOG_FIGURE, "tool_angle", "removal")

"""The paper's figures (Fig. 2, 3, 4) as matplotlib PNGs for any run, and sweep plots.

:func:`plot_result` draws one run (a :class:`hybrid_force.result.Result`, or anything with the
same attributes, or the path of a saved ``.npz``) as the six PNGs of :data:`FIGURE_NAMES`, listed
with their paper figures in :mod:`hybrid_force.viz.run_figures`, and those of
:data:`OPTIONAL_FIGURE_NAMES` when the run has what they show (the law's own signals, the tool
angle).

:func:`plot_sweep` draws one metric of a sweep CSV against one swept parameter (line plot) or two
(heat map).

matplotlib is imported only inside the functions (``import hybrid_force`` stays fast) and every
figure is drawn on its own Agg canvas (no pyplot, no global backend change, usable from threads and
on machines without a display). Each PNG is written atomically: to a temporary file in the same
directory, then ``os.replace``.

The figures of a run live in :mod:`hybrid_force.viz.run_figures`, the sweep plots in
:mod:`hybrid_force.viz.sweep_plots`; this module gathers their public names.
"""

from __future__ import annotations

from hybrid_force.errors import PlotError
from hybrid_force.viz.run_figures import FIGURE_NAMES, OPTIONAL_FIGURE_NAMES, plot_result
from hybrid_force.viz.sweep_plots import plot_sweep

__all__ = ["FIGURE_NAMES", "OPTIONAL_FIGURE_NAMES", "PlotError", "plot_result", "plot_sweep"]

"""The paper's figures (Fig. 2, 3, 4) as matplotlib PNGs for any run, and sweep plots.

:func:`plot_result` draws one run (a :class:`hybrid_force.result.Result`, or anything with the
same attributes, or the path of a saved ``.npz``):

===================== ===========================================================================
file                  content (paper figure)
===================== ===========================================================================
``path3d.png``        desired (dashed) and actual tip path in 3D, surfaces as wireframes (2a, 3a)
``projection.png``    the path projected on the plane normal to a cylinder's axis, on a plane's
                      own coordinates, or on xy (sphere), with the surface trace (3b)
``position_errors``   e_x, e_y, e_z against time and ‖e‖ on a log scale (2c–e, 3c–e)
``force_error.png``   e_f = f − f_d over the run, zoomed on the start, and |e_f| on a log scale;
                      samples out of contact greyed (2b, 4b, 4c)
``desired_force.png`` f_d and f over the first 10 s with the phase switches marked (4a)
``lyapunov.png``      V = ½sᵀMs + ½βe_F² (section 5.1) with the contact phase shaded
===================== ===========================================================================

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
from hybrid_force.viz.run_figures import FIGURE_NAMES, plot_result
from hybrid_force.viz.sweep_plots import plot_sweep

__all__ = ["FIGURE_NAMES", "PlotError", "plot_result", "plot_sweep"]

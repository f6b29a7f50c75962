"""Overlay figures of a comparison of control laws: every law's force error on one plot, and
every law's path error on another (``hybrid-force compare``).

=========================== =====================================================================
file                        content
=========================== =====================================================================
``compare_force_error.png`` ``|f − f_d|`` [N] against time, every law: linear, then a log scale
``compare_path_error.png``  ``‖e_t‖`` [m] (the position error along the surface) against time,
                            every law: linear, then a log scale
=========================== =====================================================================

The settling time is marked. A law whose run failed is drawn up to its failure, its status in
the legend; when other laws are ok, the y-axes are scaled to those, so that a diverging curve
leaves the plot rather than flattening the others. Each figure is drawn on its own Agg canvas
and written atomically (see :mod:`._style`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hybrid_force._extras import require as require_extra
from hybrid_force.errors import BadInputError
from hybrid_force.viz._style import _legend_right, _new_figure, _note, _out_dir, _save_atomic

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["COMPARE_FIGURES", "LawCurve", "plot_comparison"]

#: Base names of the files :func:`plot_comparison` writes, in order (each gets ``.png``).
COMPARE_FIGURES: tuple[str, ...] = ("compare_force_error", "compare_path_error")


@dataclass(frozen=True)
class LawCurve:
    """One law's curves.

    Attributes:
        law: the law's name (the legend).
        status: its run's status ("ok", or why not: shown in the legend).
        t: (N,) time [s].
        force_error: (N,) ``|f − f_d|`` [N].
        path_error: (N,) ``‖e_t‖`` [m].
    """

    law: str
    status: str
    t: np.ndarray
    force_error: np.ndarray
    path_error: np.ndarray

    def __post_init__(self) -> None:
        n = np.shape(self.t)
        for name in ("force_error", "path_error"):
            if np.shape(getattr(self, name)) != n or len(n) != 1:
                raise BadInputError(
                    f"LawCurve {self.law!r}: t and {name} must have the same shape (N,), got "
                    f"{n} and {np.shape(getattr(self, name))}"
                )


def _finite(y: np.ndarray) -> np.ndarray:
    """y as floats with non-finite entries NaN (matplotlib leaves a gap there)."""
    y = np.asarray(y, dtype=float)
    return np.where(np.isfinite(y), y, np.nan)


def _limits(values: Sequence[np.ndarray], log: bool) -> tuple[float, float] | None:
    """y-limits that hold every finite (positive, for log) value, with a margin; None if none."""
    kept = [v[np.isfinite(v) & (v > 0.0 if log else True)] for v in values]
    data = np.concatenate(kept) if kept else np.zeros(0)
    if data.size == 0:
        return None
    low, high = float(data.min()), float(data.max())
    if log:
        return low / 2.0, high * 2.0
    pad = 0.05 * (high - low) if high > low else max(abs(high), 1.0) * 0.05
    return min(low, 0.0) - pad, high + pad


def _panel(
    ax: Axes,
    curves: Sequence[LawCurve],
    field: str,
    *,
    log: bool,
    settle_time: float | None,
) -> None:
    """One axes: ``field`` of every curve against time."""
    ok = [c for c in curves if c.status == "ok"]
    drawn = []
    for curve in curves:
        y = _finite(getattr(curve, field))
        if log:
            y = np.where(y > 0.0, y, np.nan)
        if not np.any(np.isfinite(y)):
            continue
        if curve.status == "ok":
            ax.plot(curve.t, y, lw=1.2, label=curve.law)
        else:  # dashed, and a cross where it stops
            (line,) = ax.plot(curve.t, y, lw=1.2, ls="--", label=f"{curve.law} ({curve.status})")
            last = int(np.flatnonzero(np.isfinite(y))[-1])
            ax.plot(curve.t[last], y[last], "x", color=line.get_color(), ms=7, clip_on=True)
        drawn.append(y)
    if not drawn:
        _note(ax, "no finite values" + (" above 0" if log else ""))
        return
    if log:
        ax.set_yscale("log")
    # scaled to the ok laws when some failed: a diverging curve must not hide the others
    scale = [_finite(getattr(c, field)) for c in ok] if ok and len(ok) < len(curves) else drawn
    limits = _limits(scale, log)
    if limits is not None and limits[0] < limits[1]:
        ax.set_ylim(*limits)
    if settle_time is not None:
        ax.axvline(settle_time, color="0.4", ls=":", lw=1.0, label=f"settle time {settle_time:g} s")
    ax.grid(True, alpha=0.3)


def plot_comparison(
    curves: Sequence[LawCurve],
    out_dir: str | os.PathLike[str],
    *,
    settle_time: float | None = None,
) -> list[Path]:
    """Draw the two overlay figures of :data:`COMPARE_FIGURES` into ``out_dir``.

    Args:
        curves: one :class:`LawCurve` per law (at least one).
        out_dir: output folder (created).
        settle_time: [s] marked by a dotted line (None: not marked).

    Returns:
        The paths written, in the order of :data:`COMPARE_FIGURES`.

    Raises:
        BadInputError: no curve, or an output folder that cannot be made.
        MissingExtraError: matplotlib cannot be imported (the ``plots`` extra).
    """
    require_extra("plots", "figures")
    if not curves:
        raise BadInputError("plot_comparison: no law to draw")
    out = _out_dir(out_dir)
    written: list[Path] = []
    specs = (
        ("force_error", "|f − f_d| [N]", "Force error of each law"),
        ("path_error", "‖e_t‖ [m]", "Path error along the surface of each law"),
    )
    for name, (field, ylabel, title) in zip(COMPARE_FIGURES, specs, strict=True):
        fig = _new_figure(8.0, 6.0)
        top, bottom = fig.subplots(2, 1, sharex=True)
        _panel(top, curves, field, log=False, settle_time=settle_time)
        _panel(bottom, curves, field, log=True, settle_time=settle_time)
        top.set_title(title)
        top.set_ylabel(ylabel)
        bottom.set_ylabel(f"{ylabel}, log scale")
        bottom.set_xlabel("t [s]")
        if top.get_legend_handles_labels()[0]:
            _legend_right(top)
        path = out / f"{name}.png"
        _save_atomic(fig, path)
        written.append(path)
    return written

"""The paper's figures (Fig. 2, 3, 4) of one run as matplotlib PNGs.

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
``law_log.png``       only when the law logged signals of its own (``Result.law_log``): each
                      relative to its start, e.g. θ̂/θ_model (:mod:`.law_log_figure`)
``tool_angle.png``    only for a run with ``[tool] orientation = "normal"``: the angle between the
                      tool axis and its desired direction, on a log scale, settling time marked
``removal.png``       only for a run with ``[removal]``: the depth removed [µm] on the unrolled
                      surface, the tip's path and the target region drawn over it
                      (:mod:`.removal_figure`)
===================== ===========================================================================

Each figure is drawn on its own Agg canvas and written atomically (see :mod:`._style`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hybrid_force._extras import require as require_extra
from hybrid_force.errors import BadInputError
from hybrid_force.phases import NEAR
from hybrid_force.result import Result
from hybrid_force.viz._run_data import (
    _intervals,
    _load_run,
    _Run,
    _switches,
    _window_end,
    _zoom_end,
)
from hybrid_force.viz._style import _legend_right, _new_figure, _note, _out_dir, _save_atomic
from hybrid_force.viz._wireframes import (
    _finite_points,
    _projection,
    _surface_mesh,
    _surface_triangles,
)
from hybrid_force.viz.figure_names import FIGURE_NAMES, LAW_LOG_FIGURE
from hybrid_force.viz.law_log_figure import law_log_figure
from hybrid_force.viz.removal_figure import REMOVAL_FIGURE, removal_figure

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["plot_result"]

_MAX_3D_POINTS = 4000  # 3D/2D path lines are decimated to at most this many points
_KIND_COLOURS = {
    "near": "tab:orange",
    "contact": "tab:green",
    "impact": "tab:red",
    "release": "tab:purple",
    "free": "tab:gray",
}


def _decimate(n: int, limit: int = _MAX_3D_POINTS) -> slice:
    """A stride keeping at most about `limit` of n samples (the last one is appended by callers)."""
    return slice(None, None, max(1, math.ceil(n / limit)))


def _thin(a: np.ndarray) -> np.ndarray:
    """Rows of a decimated for line drawing, always keeping the last row."""
    idx = np.arange(a.shape[0])[_decimate(a.shape[0])]
    if idx[-1] != a.shape[0] - 1:
        idx = np.append(idx, a.shape[0] - 1)
    return a[idx]


def _shade(ax: Axes, t: np.ndarray, mask: np.ndarray, colour: str, label: str) -> None:
    """Shade the time intervals where mask (N,) is true over the full height of ax."""
    spans = _intervals(t, mask)
    if spans:
        ax.broken_barh(
            spans,
            (0.0, 1.0),
            transform=ax.get_xaxis_transform(),
            facecolors=colour,
            alpha=0.15,
            linewidth=0,
            label=label,
        )


def _positive(a: np.ndarray) -> np.ndarray:
    """a with non-positive and non-finite entries replaced by NaN (for log axes)."""
    return np.where(np.isfinite(a) & (a > 0), a, np.nan)


def _semilog(ax: Axes, t: np.ndarray, y: np.ndarray, **kw: Any) -> bool:
    """Plot y (N,) on a log y-axis when it has positive values; returns whether it did."""
    yp = _positive(y)
    if not np.any(np.isfinite(yp)):
        return False
    ax.plot(t, yp, **kw)
    ax.set_yscale("log")
    return True


def _mark_nonfinite(axes: Sequence[Axes], t: np.ndarray, a: np.ndarray, what: str) -> None:
    """A red dotted line on every axes at the first sample where a (N, ...) is not finite."""
    bad = ~np.all(np.isfinite(a.reshape(a.shape[0], -1)), axis=1)
    if not np.any(bad):
        return
    t_bad = float(t[int(np.argmax(bad))])
    for ax in axes:
        ax.axvline(t_bad, color="red", ls=":", lw=1.2)
    axes[-1].text(
        t_bad,
        0.9,
        f"{what} not finite from t = {t_bad:.4g} s ",
        color="red",
        transform=axes[-1].get_xaxis_transform(),
        ha="right",
        va="center",
        fontsize=8,
    )


def _column_label(base: str, j: int, k: int) -> str:
    return base if k == 1 else f"{base}, constraint {j + 1}"


# --------------------------------------------------------------------------------------------


# --------------------------------------------------------------------------------------------
# Figures
# --------------------------------------------------------------------------------------------
def _fig_path3d(run: _Run) -> Figure:
    """Fig. 2a / 3a: desired and actual tip paths in 3D with the surfaces as wireframes."""
    fig = _new_figure(7.5, 6.5)
    # the paths drawn over the surfaces: matplotlib's depth sort of a part's many triangles
    # against a few long lines hides a path lying on the part
    ax = fig.add_subplot(projection="3d", computed_zorder=False)
    pts = _finite_points(run.p, run.p_d)
    skipped: list[str] = []
    for i, s in enumerate(run.surfaces):
        triangles = _surface_triangles(s, i, pts)
        if triangles is not None:  # a mesh part: its own triangles
            (x, y, z), faces = triangles[0].T, triangles[1]
            ax.plot_trisurf(
                x, y, z, triangles=faces, color="0.7", linewidth=0.2, edgecolor="0.45",
                alpha=0.35, label="surface" if i == 0 else None,
            )  # fmt: skip
            continue
        mesh = _surface_mesh(s, i, pts)
        if mesh is None:
            skipped.append(str(s.get("type")))
            continue
        ax.plot_wireframe(
            *mesh, color="0.55", linewidth=0.5, alpha=0.55, label="surface" if i == 0 else None
        )
    pd, p = _thin(run.p_d), _thin(run.p)
    ax.plot(pd[:, 0], pd[:, 1], pd[:, 2], "--", color="tab:blue", lw=1.4, label="desired $p_d$")
    ax.plot(p[:, 0], p[:, 1], p[:, 2], "-", color="tab:red", lw=1.2, label="actual $p$")
    first = run.p[np.all(np.isfinite(run.p), axis=1)]
    if first.size:
        ax.scatter(*first[0], color="k", marker="o", s=30, label="start")
        ax.scatter(*first[-1], color="k", marker="s", s=30, label="end")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    _box_aspect(ax)
    title = f"{run.name}: tip path (desired dashed, actual solid)"
    if skipped:
        title += f"\nsurface type(s) {', '.join(skipped)} not drawn"
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=8)
    return fig


def _box_aspect(ax: Any) -> None:
    """Box proportional to the data ranges (true shape); no side below 0.4 of the largest."""
    lims = np.array([ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d()])
    spans = lims[:, 1] - lims[:, 0]
    if np.all(np.isfinite(spans)) and spans.max() > 0:
        ax.set_box_aspect(tuple(np.clip(spans / spans.max(), 0.4, 1.0)), zoom=0.9)
    from matplotlib.ticker import MaxNLocator

    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(nbins=5))


def _fig_projection(run: _Run) -> Figure:
    """Fig. 3b: the paths projected on the plane normal to the cylinder axis (or plane / xy)."""
    proj = _projection(run.surfaces)
    fig = _new_figure(6.5, 6.5)
    ax = fig.add_subplot()
    th = np.linspace(0.0, 2.0 * np.pi, 361)
    for cu, cw, r, label in proj.circles:
        ax.plot(
            cu + r * np.cos(th),
            cw + r * np.sin(th),
            color="0.45",
            lw=2.5,
            alpha=0.6,
            label=f"surface trace ({label})",
        )
    pd, p = _thin(run.p_d), _thin(run.p)
    ax.plot(pd @ proj.u, pd @ proj.w, "--", color="tab:blue", lw=1.4, label="desired $p_d$")
    ax.plot(p @ proj.u, p @ proj.w, "-", color="tab:red", lw=1.0, label="actual $p$")
    ok = np.all(np.isfinite(run.p), axis=1)
    if np.any(ok):
        q0, q1 = run.p[ok][0], run.p[ok][-1]
        ax.plot(q0 @ proj.u, q0 @ proj.w, "ko", ms=6, label="start")
        ax.plot(q1 @ proj.u, q1 @ proj.w, "ks", ms=6, label="end")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(proj.xlabel)
    ax.set_ylabel(proj.ylabel)
    ax.set_title(f"{run.name}: {proj.title}")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return fig


def _fig_position_errors(run: _Run) -> Figure:
    """Fig. 2c–e / 3c–e: e = p − p_d per axis [m] and ‖e‖ [m] on a log scale."""
    fig = _new_figure(8.0, 9.0)
    axes = fig.subplots(4, 1, sharex=True)
    e = run.p - run.p_d
    for i, name in enumerate("xyz"):
        ax = axes[i]
        ax.plot(run.t, e[:, i], color="tab:blue", lw=1.0)
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.set_ylabel(f"$e_{name} = {name} - {name}_d$ [m]")
        ax.grid(True, alpha=0.3)
    ax = axes[3]
    norm = np.linalg.norm(e, axis=1)
    if _semilog(ax, run.t, norm, color="k", lw=1.0, label=r"$\|e\|$"):
        ax.axhline(1e-6, color="tab:green", ls=":", lw=1.0)
        ax.text(
            0.005,
            1e-6,
            "1 µm",
            transform=ax.get_yaxis_transform(),
            ha="left",
            va="bottom",
            fontsize=8,
            color="tab:green",
        )
    else:
        _note(ax, "‖e‖ has no positive finite value")
    _mark_nonfinite(axes, run.t, e, "e")
    ax.set_ylabel(r"$\|p - p_d\|$ [m]")
    ax.set_xlabel("t [s]")
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"{run.name}: position tracking errors")
    return fig


def _fig_force_error(run: _Run) -> Figure:
    """Fig. 2b, 4b, 4c: e_f = f − f_d [N] over the run, zoomed on the start, and log |e_f|."""
    fig = _new_figure(8.0, 8.5)
    axes = fig.subplots(3, 1)
    contact = run.contact
    ef = run.f - run.f_d
    t_zoom = _zoom_end(run.t)
    zoom = run.t <= t_zoom
    for ax, sel in ((axes[0], slice(None)), (axes[1], zoom)):
        t = run.t[sel]
        for j in range(run.k):
            ej = ef[sel, j]
            c = contact[sel]
            ax.plot(
                t,
                np.where(c, ej, np.nan),
                color=f"C{j}",
                lw=1.0,
                label=_column_label("$e_f$ in contact", j, run.k),
            )
            ax.plot(
                t,
                np.where(c, np.nan, ej),
                color="0.7",
                lw=1.0,
                label="not in contact (e_f not meaningful)" if j == 0 else None,
            )
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_ylabel("$e_f = f - f_d$ [N]")
        ax.set_xlabel("t [s]")
        ax.grid(True, alpha=0.3)
    axes[0].set_title("whole run")
    # one legend for the three panels, outside them (a legend inside could hide a divergence)
    fig.legend(
        handles=axes[0].get_legend_handles_labels()[0],
        loc="outside lower center",
        ncol=min(3, run.k + 1),
        fontsize=8,
    )
    axes[1].set_title(f"first {t_zoom - run.t[0]:.3g} s")
    ax = axes[2]
    drawn = False
    for j in range(run.k):
        drawn |= _semilog(
            ax,
            run.t,
            np.where(contact, np.abs(ef[:, j]), np.nan),
            color=f"C{j}",
            lw=1.0,
            label=_column_label("$|e_f|$ in contact", j, run.k),
        )
    if not drawn:
        _note(ax, "never in contact, or |e_f| = 0 throughout contact")
    _mark_nonfinite([axes[0], axes[2]], run.t, ef, "e_f")
    ax.set_ylabel("$|e_f|$ [N]")
    ax.set_xlabel("t [s]")
    ax.set_xlim(run.t[0], run.t[-1])
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"{run.name}: force tracking error")
    return fig


def _group_switches(
    switches: Sequence[tuple[float, str]], tol: float
) -> list[tuple[float, list[str]]]:
    """Merge switches closer than tol [s] into one label (e.g. contact and impact at once)."""
    groups: list[tuple[float, list[str]]] = []
    for te, kind in switches:
        if groups and te - groups[-1][0] <= tol:
            if kind not in groups[-1][1]:
                groups[-1][1].append(kind)
        else:
            groups.append((te, [kind]))
    return groups


def _fig_desired_force(run: _Run) -> Figure:
    """Fig. 4a: f_d and f [N] over the first 10 s with the phase switches as vertical lines."""
    fig = _new_figure(8.5, 4.8)
    ax = fig.add_subplot()
    t_end = _window_end(run.t)
    sel = run.t <= t_end

    def column(y: np.ndarray, j: int, label: str, **style: Any) -> None:
        """Column j of y (N, k) [N] over the window, its label naming the surface if k > 1."""
        ax.plot(run.t[sel], y[sel, j], label=_column_label(label, j, run.k), **style)

    true = "true $f$" if run.f_meas is not None else "$f$"
    for j in range(run.k):
        column(run.f, j, true, color=f"C{j}", lw=1.0, alpha=0.8)
        if run.f_meas is not None:
            column(run.f_meas, j, "measured $\\tilde f$", color=f"C{j + 3}", lw=0.8, alpha=0.7)
        column(run.f_d, j, "desired $f_d$", color="k" if run.k == 1 else f"C{j}", lw=1.6, ls="--")
    switches = [(te, kind) for te, kind in _switches(run) if run.t[0] <= te <= t_end]
    seen: set[str] = set()
    for te, kind in switches[:200]:
        ax.axvline(
            te,
            color=_KIND_COLOURS.get(kind, "tab:gray"),
            lw=1.0,
            ls="-.",
            label=f"switch: {kind}" if kind not in seen else None,
        )
        seen.add(kind)
    groups = _group_switches(switches, 0.01 * (t_end - run.t[0]))
    if len(groups) <= 8:
        for te, kinds in groups:
            # labels left of their line, except near the left edge where they would leave the axes
            left_edge = te - run.t[0] < 0.08 * (t_end - run.t[0])
            ax.text(
                te,
                0.97,
                f" {', '.join(kinds)} {te:.3g} s",
                transform=ax.get_xaxis_transform(),
                rotation=90,
                ha="left" if left_edge else "right",
                va="top",
                fontsize=8,
                color=_KIND_COLOURS.get(kinds[0], "tab:gray"),
                bbox={"facecolor": "white", "alpha": 0.75, "edgecolor": "none", "pad": 1.0},
            )
    title = f"desired force, first {t_end - run.t[0]:.3g} s"
    return _finish_time_axes(fig, ax, run, t_end, "force along the surface normal [N]", title)


def _fig_lyapunov(run: _Run) -> Figure:
    """V = ½sᵀMs + ½βe_F² [J] (section 5.1) against time, contact phase shaded."""
    fig = _new_figure(8.5, 4.5)
    ax = fig.add_subplot()
    _semilog_or_linear(ax, run.t, run.V, "V", "V")
    _shade(ax, run.t, run.phase == NEAR, "tab:orange", "near phase")
    ylabel = r"$V = \frac{1}{2}s^T M s + \frac{1}{2}\beta e_F^2$ [J]"
    return _time_panel(fig, ax, run, ylabel, "Lyapunov function")


def _semilog_or_linear(ax: Axes, t: np.ndarray, y: np.ndarray, label: str, what: str) -> None:
    """y (N,) against t (N,) [s] as a black line on a log scale, or on a linear one with a note
    naming ``what`` when y has no positive finite value (a log axis could not show it)."""
    if not _semilog(ax, t, y, color="k", lw=1.0, label=label):
        ax.plot(t, y, color="k", lw=1.0, label=label)
        _note(ax, f"{what} has no positive finite value: linear scale")


def _time_panel(fig: Figure, ax: Axes, run: _Run, ylabel: str, title: str) -> Figure:
    """Finish a one-panel figure over the run's time: contact shaded, labels, legend, title."""
    _shade(ax, run.t, run.contact, "tab:green", "contact phase")
    return _finish_time_axes(fig, ax, run, run.t[-1], ylabel, title)


def _finish_time_axes(
    fig: Figure, ax: Axes, run: _Run, t_end: float, ylabel: str, title: str
) -> Figure:
    """Finish a one-panel figure over the run's time from its start to t_end [s]: labels,
    grid (its minor lines too on a log axis; a linear one has none), legend, title."""
    ax.set_xlim(run.t[0], t_end)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    _legend_right(ax)
    ax.set_title(f"{run.name}: {title}")
    return fig


def _fig_tool_angle(run: _Run) -> Figure:
    """The angle [rad] between the tool axis and its desired direction, log scale."""
    fig = _new_figure(8.5, 4.5)
    ax = fig.add_subplot()
    angle = run.tool_angle
    if angle is None:
        _note(ax, 'no tool angle: the run did not control the tool\'s direction ("free")')
    else:
        _semilog_or_linear(ax, run.t, angle, "tool angle", "the angle")
    if run.settle_time is not None and run.t[0] <= run.settle_time <= run.t[-1]:
        ax.axvline(run.settle_time, color="tab:blue", ls="--", lw=1.0, label="settle time")
    if angle is not None:
        _mark_nonfinite([ax], run.t, angle, "tool angle")
    ylabel = r"$\angle(a, a_d)$ [rad]"
    return _time_panel(fig, ax, run, ylabel, "tool axis from its desired direction")


_BUILDERS = {
    "path3d": _fig_path3d,
    "projection": _fig_projection,
    "position_errors": _fig_position_errors,
    "force_error": _fig_force_error,
    "desired_force": _fig_desired_force,
    "lyapunov": _fig_lyapunov,
    "tool_angle": _fig_tool_angle,
}


def plot_result(result: object, out_dir: str | os.PathLike[str], *, prefix: str = "") -> list[Path]:
    """Draw the paper's figures of one run as PNGs in out_dir and return the files written.

    result: a :class:`hybrid_force.result.Result` (or an object with its attributes t (N,) [s],
    p and p_d (N, 3) [m], f and f_d (N,) or (N, k) [N], V (N,) [J], phase (N,) and meta), or the
    path of a saved result. out_dir is created if needed. Files, in order:
    ``{prefix}path3d.png``, ``projection.png``, ``position_errors.png``, ``force_error.png``,
    ``desired_force.png``, ``lyapunov.png``, then ``law_log.png`` when the law logged signals
    of its own, ``tool_angle.png`` for a run with a ``tool_angle`` and ``removal.png`` for a
    run with removal arrays (see the module docstring). Existing files are replaced
    atomically. Raises :class:`BadInputError` on a missing attribute or wrong shape,
    :class:`~hybrid_force.errors.MissingExtraError` without matplotlib (the ``plots`` extra).
    """
    require_extra("plots", "figures")
    if os.sep in prefix or (os.altsep and os.altsep in prefix):
        raise BadInputError(
            f"prefix {prefix!r} must be a file-name prefix, not contain a path separator"
        )
    if isinstance(result, str | os.PathLike):  # loaded once: the removal map reads it too
        result = Result.load(result)
    run = _load_run(result)
    out = _out_dir(out_dir)
    written: list[Path] = []
    names = FIGURE_NAMES + (("tool_angle",) if run.tool_angle is not None else ())
    for name in names:
        fig = _BUILDERS[name](run)
        path = out / f"{prefix}{name}.png"
        _save_atomic(fig, path)
        written.append(path)
    law_fig = law_log_figure(run)
    if law_fig is not None:
        path = out / f"{prefix}{LAW_LOG_FIGURE}.png"
        _save_atomic(law_fig, path)
        written.append(path)
    removal_fig = removal_figure(result, run.name)
    if removal_fig is not None:
        path = out / f"{prefix}{REMOVAL_FIGURE}.png"
        _save_atomic(removal_fig, path)
        written.append(path)
    return written

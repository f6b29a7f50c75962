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
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hybrid_force._atomic import atomic_file
from hybrid_force.errors import PlotError, did_you_mean
from hybrid_force.phases import CONTACT, NEAR

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["FIGURE_NAMES", "PlotError", "plot_result", "plot_sweep"]

#: Base names of the files :func:`plot_result` writes, in order (each gets ``prefix`` and ``.png``).
FIGURE_NAMES: tuple[str, ...] = (
    "path3d",
    "projection",
    "position_errors",
    "force_error",
    "desired_force",
    "lyapunov",
)

_DPI = 110
_MAX_3D_POINTS = 4000  # 3D/2D path lines are decimated to at most this many points
_ZOOM_S = 10.0  # [s] zoom window of force_error.png and window of desired_force.png
_SWITCH_KINDS = ("near", "contact", "impact", "release")
_KIND_COLOURS = {
    "near": "tab:orange",
    "contact": "tab:green",
    "impact": "tab:red",
    "release": "tab:purple",
    "free": "tab:gray",
}
_SURFACE_TYPES = ("cylinder", "sphere", "plane")


# --------------------------------------------------------------------------------------------
# The run, checked
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Run:
    """The arrays of one run that the figures need, with shapes checked.

    t: (N,) [s]; p, p_d: (N, 3) [m]; f, f_d, phi: (N, k) [N, N, m]; f_meas: (N, k) the force
    the controller measured [N], or None when it is f (ideal sensing); V: (N,) [J];
    phase: (N,) int (0 free, 1 near, 2 contact); surfaces: surface dicts of the schema;
    events: (t [s], kind) pairs of meta["events"], sorted by time.
    """

    name: str
    t: np.ndarray
    p: np.ndarray
    p_d: np.ndarray
    f: np.ndarray
    f_d: np.ndarray
    V: np.ndarray
    phase: np.ndarray
    surfaces: tuple[Mapping[str, Any], ...]
    events: tuple[tuple[float, str], ...]
    f_meas: np.ndarray | None = None

    @property
    def k(self) -> int:
        """Number of constraints (columns of f)."""
        return int(self.f.shape[1])

    @property
    def contact(self) -> np.ndarray:
        """(N,) bool: samples in the contact phase."""
        return self.phase == CONTACT


def _array(result: object, attr: str) -> np.ndarray:
    if not hasattr(result, attr):
        raise PlotError(
            f"cannot plot {type(result).__name__}: it has no attribute {attr!r} "
            "(expected a hybrid_force Result with t, p, p_d, f, f_d, V, phase, meta)"
        )
    try:
        return np.asarray(getattr(result, attr), dtype=float)
    except (TypeError, ValueError) as exc:
        raise PlotError(f"result.{attr} is not a numeric array: {exc}") from exc


def _as_columns(a: np.ndarray, attr: str, n: int) -> np.ndarray:
    """(N,) or (N, k) → (N, k)."""
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] != n or a.shape[1] < 1:
        raise PlotError(f"result.{attr} has shape {a.shape}; expected ({n},) or ({n}, k)")
    return a


def _read_events(meta: Mapping[str, Any]) -> tuple[tuple[float, str], ...]:
    raw = meta.get("events") or []
    if not isinstance(raw, Sequence) or isinstance(raw, str):
        raise PlotError(f"result meta['events'] must be a list of dicts, got {type(raw).__name__}")
    events: list[tuple[float, str]] = []
    for i, ev in enumerate(raw):
        if not isinstance(ev, Mapping) or "t" not in ev or "kind" not in ev:
            raise PlotError(f"result meta['events'][{i}] = {ev!r} lacks the keys 't' and 'kind'")
        try:
            te = float(ev["t"])
        except (TypeError, ValueError) as exc:
            raise PlotError(
                f"result meta['events'][{i}]['t'] = {ev['t']!r} is not a number"
            ) from exc
        if not math.isfinite(te):
            raise PlotError(f"result meta['events'][{i}]['t'] = {te} is not finite")
        events.append((te, str(ev["kind"])))
    return tuple(sorted(events))


def _read_surfaces(meta: Mapping[str, Any]) -> tuple[Mapping[str, Any], ...]:
    raw = meta.get("surfaces") or []
    if not isinstance(raw, Sequence) or isinstance(raw, str):
        raw = [raw]
    out: list[Mapping[str, Any]] = []
    for i, s in enumerate(raw):
        if hasattr(s, "to_dict"):
            s = s.to_dict()
        if not isinstance(s, Mapping):
            raise PlotError(f"result meta['surfaces'][{i}] = {s!r} is not a surface dict")
        out.append(s)
    return tuple(out)


def _load_run(result: object) -> _Run:
    """Check a Result (or a path to a saved one) and gather what the figures need."""
    if isinstance(result, str | os.PathLike):
        from hybrid_force.result import Result  # lazy: plots is an edge module

        result = Result.load(result)
    t = _array(result, "t")
    if t.ndim != 1 or t.shape[0] < 2:
        raise PlotError(
            f"result.t has shape {t.shape}; need a 1-D time vector of at least 2 samples"
        )
    if not np.all(np.isfinite(t)):
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise PlotError(f"result.t[{bad}] = {t[bad]} is not finite")
    n = t.shape[0]
    p, p_d = _array(result, "p"), _array(result, "p_d")
    for attr, a in (("p", p), ("p_d", p_d)):
        if a.shape != (n, 3):
            raise PlotError(f"result.{attr} has shape {a.shape}; expected ({n}, 3)")
    f = _as_columns(_array(result, "f"), "f", n)
    f_d = _as_columns(_array(result, "f_d"), "f_d", n)
    if f_d.shape != f.shape:
        raise PlotError(f"result.f_d has shape {f_d.shape} but result.f has shape {f.shape}")
    v = _array(result, "V")
    if v.shape != (n,):
        raise PlotError(f"result.V has shape {v.shape}; expected ({n},)")
    phase = np.asarray(getattr(result, "phase", np.zeros(n)))
    if phase.shape != (n,):
        raise PlotError(f"result.phase has shape {phase.shape}; expected ({n},)")
    meta = getattr(result, "meta", None) or {}
    if not isinstance(meta, Mapping):
        raise PlotError(f"result.meta must be a dict, got {type(meta).__name__}")
    name = str(meta.get("name") or "unnamed run")
    f_meas = getattr(result, "f_meas", None)
    if f_meas is not None:
        f_meas = _as_columns(np.asarray(f_meas, dtype=float), "f_meas", n)
        if f_meas.shape != f.shape or np.array_equal(f_meas, f):
            f_meas = None  # ideal sensing: nothing more to draw
    return _Run(
        name=name,
        t=t,
        p=p,
        p_d=p_d,
        f=f,
        f_d=f_d,
        V=v,
        phase=phase.astype(np.int64),
        surfaces=_read_surfaces(meta),
        events=_read_events(meta),
        f_meas=f_meas,
    )


# --------------------------------------------------------------------------------------------
# Geometry helpers (pure numpy)
# --------------------------------------------------------------------------------------------
_DEFAULT_VECTORS = {"center": (0.0, 0.0, 0.0), "axis": (0.0, 0.0, 1.0)}  # as in surfaces.py


def _vec(d: Mapping[str, Any], key: str, where: str) -> np.ndarray:
    """The 3-vector d[key] [m]; a cylinder's/sphere's center and axis default as in surfaces.py."""
    if key not in d:
        if key in _DEFAULT_VECTORS and d.get("type") in ("cylinder", "sphere"):
            return np.array(_DEFAULT_VECTORS[key])
        raise PlotError(f"{where} lacks the key {key!r} (has {sorted(d)})")
    try:
        v = np.asarray(d[key], dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise PlotError(f"{where}[{key!r}] = {d[key]!r} is not a 3-vector") from exc
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise PlotError(f"{where}[{key!r}] = {d[key]!r} is not a finite 3-vector")
    return v


def _unit(d: Mapping[str, Any], key: str, where: str) -> np.ndarray:
    v = _vec(d, key, where)
    norm = float(np.linalg.norm(v))
    if norm < 1e-12:
        raise PlotError(f"{where}[{key!r}] = {d[key]!r} has zero length")
    return v / norm


def _radius(d: Mapping[str, Any], where: str) -> float:
    if "radius" not in d:
        raise PlotError(f"{where} lacks the key 'radius' (has {sorted(d)})")
    try:
        r = float(d["radius"])
    except (TypeError, ValueError) as exc:
        raise PlotError(f"{where}['radius'] = {d['radius']!r} is not a number") from exc
    if not (math.isfinite(r) and r > 0):
        raise PlotError(f"{where}['radius'] = {r} must be a positive finite length [m]")
    return r


def _plane_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (u, w) with (u, w, n) a right-handed orthonormal frame.

    u is the world axis least aligned with n, projected on the plane normal to n, so that for
    n = ±z the pair is (x, ±y) and a cylinder of axis z projects on the paper's xy plane.
    n: (3,) unit. Returns u, w: (3,), (3,).
    """
    e = np.eye(3)[int(np.argmin(np.abs(n)))]
    u = e - (e @ n) * n
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def _finite_points(*arrays: np.ndarray) -> np.ndarray:
    pts = np.concatenate([a for a in arrays], axis=0)
    return pts[np.all(np.isfinite(pts), axis=1)]


def _cylinder_mesh(
    center: np.ndarray, axis: np.ndarray, radius: float, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wireframe grid (X, Y, Z: (n_s, n_theta) [m]) of a cylinder over the axial range of pts.

    pts: (M, 3) [m] the motion; the segment covers its projection on the axis, padded.
    """
    u, w = _plane_basis(axis)
    if pts.size:
        s = (pts - center) @ axis
        lo, hi = float(s.min()), float(s.max())
    else:
        lo = hi = 0.0
    pad = max(0.08 * (hi - lo), 0.25 * radius if hi - lo < 1e-9 else 0.0)
    ss = np.linspace(lo - pad, hi + pad, 9)
    th = np.linspace(0.0, 2.0 * np.pi, 37)
    ring = radius * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * w)  # (37, 3)
    grid = center + ss[:, None, None] * axis + ring[None, :, :]  # (9, 37, 3)
    return grid[..., 0], grid[..., 1], grid[..., 2]


def _sphere_mesh(
    center: np.ndarray, radius: float, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wireframe (X, Y, Z: (n_polar, n_azimuth) [m]) of the spherical cap around the motion.

    The cap is centred on the mean direction of pts from the centre and covers every point of
    pts with a margin; when it would exceed 150° the whole sphere is drawn.
    """
    amax = np.pi
    m = np.array([0.0, 0.0, 1.0])
    if pts.size:
        rel = pts - center
        mean = rel.mean(axis=0)
        if np.linalg.norm(mean) > 1e-9 * max(radius, 1.0):
            m = mean / np.linalg.norm(mean)
            norms = np.linalg.norm(rel, axis=1)
            ok = norms > 1e-12
            cosang = np.clip((rel[ok] @ m) / norms[ok], -1.0, 1.0)
            reach = float(np.arccos(cosang).max()) if cosang.size else 0.0
            amax = reach * 1.15 + np.radians(8.0)
            if amax > np.radians(150.0):
                amax = np.pi
    u, w = _plane_basis(m)
    th = np.linspace(0.0, amax, 13)
    ps = np.linspace(0.0, 2.0 * np.pi, 37)
    dirs = np.cos(th)[:, None, None] * m + np.sin(th)[:, None, None] * (
        np.cos(ps)[None, :, None] * u + np.sin(ps)[None, :, None] * w
    )
    grid = center + radius * dirs
    return grid[..., 0], grid[..., 1], grid[..., 2]


def _plane_mesh(
    point: np.ndarray, normal: np.ndarray, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wireframe (X, Y, Z: (11, 11) [m]) of the plane patch under the motion pts (M, 3), padded."""
    u, w = _plane_basis(normal)
    if pts.size:
        a, b = (pts - point) @ u, (pts - point) @ w
        a0, a1, b0, b1 = float(a.min()), float(a.max()), float(b.min()), float(b.max())
    else:
        a0 = a1 = b0 = b1 = 0.0
    span = max(a1 - a0, b1 - b0, 0.1)
    pad = 0.1 * span
    aa = np.linspace(a0 - pad, a1 + pad, 11)
    bb = np.linspace(b0 - pad, b1 + pad, 11)
    grid = point + aa[:, None, None] * u + bb[None, :, None] * w
    return grid[..., 0], grid[..., 1], grid[..., 2]


def _surface_mesh(
    s: Mapping[str, Any], i: int, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The wireframe of surface dict s (None for a type this module cannot draw)."""
    where = f"result meta['surfaces'][{i}]"
    kind = s.get("type")
    if kind == "cylinder":
        return _cylinder_mesh(
            _vec(s, "center", where), _unit(s, "axis", where), _radius(s, where), pts
        )
    if kind == "sphere":
        return _sphere_mesh(_vec(s, "center", where), _radius(s, where), pts)
    if kind == "plane":
        return _plane_mesh(_vec(s, "point", where), _unit(s, "normal", where), pts)
    return None


@dataclass(frozen=True)
class _Projection:
    """A 2-D view: coordinates (x·u, x·w) [m] with labels, and the circles to draw there."""

    u: np.ndarray
    w: np.ndarray
    xlabel: str
    ylabel: str
    title: str
    circles: tuple[tuple[float, float, float, str], ...]  # (centre u, centre w, radius, label)


def _axis_name(v: np.ndarray, fallback: str) -> str:
    for i, name in enumerate("xyz"):
        if abs(abs(v[i]) - 1.0) < 1e-12:
            return name if v[i] > 0 else f"−{name}"
    return f"{fallback} = ({v[0]:.2f}, {v[1]:.2f}, {v[2]:.2f})·p"


def _projection(surfaces: Sequence[Mapping[str, Any]]) -> _Projection:
    """Choose the 2-D view of Fig. 3b: first cylinder, else first plane, else the xy plane.

    Circles drawn: cylinders whose axis is parallel to the view normal, and every sphere (its
    outline in any orthographic view).
    """
    normal, what = np.array([0.0, 0.0, 1.0]), "xy plane"
    for kind in ("cylinder", "plane"):
        found = [(i, s) for i, s in enumerate(surfaces) if s.get("type") == kind]
        if found:
            i, s = found[0]
            key = "axis" if kind == "cylinder" else "normal"
            normal = _unit(s, key, f"result meta['surfaces'][{i}]")
            what = "plane normal to the cylinder axis" if kind == "cylinder" else "the plane"
            break
    u, w = _plane_basis(normal)
    if what == "xy plane":
        u, w = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    circles: list[tuple[float, float, float, str]] = []
    for i, s in enumerate(surfaces):
        where = f"result meta['surfaces'][{i}]"
        if s.get("type") == "cylinder":
            a = _unit(s, "axis", where)
            if abs(abs(a @ normal) - 1.0) < 1e-9:
                c = _vec(s, "center", where)
                circles.append((float(c @ u), float(c @ w), _radius(s, where), f"cylinder {i}"))
        elif s.get("type") == "sphere":
            c = _vec(s, "center", where)
            circles.append((float(c @ u), float(c @ w), _radius(s, where), f"sphere {i} outline"))
    return _Projection(
        u=u,
        w=w,
        xlabel=f"{_axis_name(u, 'u')} [m]",
        ylabel=f"{_axis_name(w, 'w')} [m]",
        title=f"projection on {what}",
        circles=tuple(circles),
    )


def _decimate(n: int, limit: int = _MAX_3D_POINTS) -> slice:
    """A stride keeping at most about `limit` of n samples (the last one is appended by callers)."""
    return slice(None, None, max(1, math.ceil(n / limit)))


def _thin(a: np.ndarray) -> np.ndarray:
    """Rows of a decimated for line drawing, always keeping the last row."""
    idx = np.arange(a.shape[0])[_decimate(a.shape[0])]
    if idx[-1] != a.shape[0] - 1:
        idx = np.append(idx, a.shape[0] - 1)
    return a[idx]


# --------------------------------------------------------------------------------------------
# Time helpers
# --------------------------------------------------------------------------------------------
def _zoom_end(t: np.ndarray) -> float:
    """End [s] of the force-error zoom: 10 s after the start, or half the run if it is shorter."""
    duration = float(t[-1] - t[0])
    return float(t[0] + (_ZOOM_S if duration > _ZOOM_S else 0.5 * duration))


def _window_end(t: np.ndarray) -> float:
    """End [s] of the desired-force window: the first 10 s, or the whole run if shorter."""
    return float(min(t[-1], t[0] + _ZOOM_S))


def _phase_switches(t: np.ndarray, phase: np.ndarray) -> list[tuple[float, str]]:
    """(time [s], kind) at each change of `phase`: → near, → contact, contact → release, → free."""
    out: list[tuple[float, str]] = []
    for i in np.flatnonzero(np.diff(phase) != 0) + 1:
        old, new = int(phase[i - 1]), int(phase[i])
        if new == CONTACT:
            kind = "contact"
        elif old == CONTACT:
            kind = "release"
        elif new == NEAR:
            kind = "near"
        else:
            kind = "free"
        out.append((float(t[i]), kind))
    return out


def _switches(run: _Run) -> list[tuple[float, str]]:
    """Switches to mark: meta events of kind near/contact/impact/release, else phase changes."""
    marked = [(te, kind) for te, kind in run.events if kind in _SWITCH_KINDS]
    return marked if marked else _phase_switches(run.t, run.phase)


def _intervals(t: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """(start [s], width [s]) of each run of true samples of mask (N,) over time t (N,).

    A run of samples i..j covers [t[i], t[j + 1]) (up to t[-1] for a run reaching the end).
    """
    m = np.concatenate([[False], mask.astype(bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    starts, stops = edges[0::2], edges[1::2]  # stops: one past the last true sample
    ends = t[np.minimum(stops, t.size - 1)]
    return [(float(t[a]), float(e - t[a])) for a, e in zip(starts, ends, strict=True)]


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


def _legend_right(ax: Axes) -> None:
    """A legend outside ax on its right (inside, it could hide data such as a divergence)."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8)


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


def _note(ax: Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", color="0.35")


def _column_label(base: str, j: int, k: int) -> str:
    return base if k == 1 else f"{base}, constraint {j + 1}"


# --------------------------------------------------------------------------------------------
# Figures
# --------------------------------------------------------------------------------------------
def _new_figure(width: float, height: float) -> Figure:
    """A Figure on its own Agg canvas (no pyplot state, no display needed)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _fig_path3d(run: _Run) -> Figure:
    """Fig. 2a / 3a: desired and actual tip paths in 3D with the surfaces as wireframes."""
    fig = _new_figure(7.5, 6.5)
    ax = fig.add_subplot(projection="3d")
    pts = _finite_points(run.p, run.p_d)
    skipped: list[str] = []
    for i, s in enumerate(run.surfaces):
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
    for j in range(run.k):
        ax.plot(
            run.t[sel],
            run.f[sel, j],
            color=f"C{j}",
            lw=1.0,
            alpha=0.8,
            label=_column_label("true $f$" if run.f_meas is not None else "$f$", j, run.k),
        )
        if run.f_meas is not None:
            ax.plot(
                run.t[sel],
                run.f_meas[sel, j],
                color=f"C{j + 3}",
                lw=0.8,
                alpha=0.7,
                label=_column_label("measured $\\tilde f$", j, run.k),
            )
        ax.plot(
            run.t[sel],
            run.f_d[sel, j],
            color="k" if run.k == 1 else f"C{j}",
            lw=1.6,
            ls="--",
            label=_column_label("desired $f_d$", j, run.k),
        )
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
    ax.set_xlim(run.t[0], t_end)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("force along the surface normal [N]")
    ax.grid(True, alpha=0.3)
    _legend_right(ax)
    ax.set_title(f"{run.name}: desired force, first {t_end - run.t[0]:.3g} s")
    return fig


def _fig_lyapunov(run: _Run) -> Figure:
    """V = ½sᵀMs + ½βe_F² [J] (section 5.1) against time, contact phase shaded."""
    fig = _new_figure(8.5, 4.5)
    ax = fig.add_subplot()
    if not _semilog(ax, run.t, run.V, color="k", lw=1.0, label="V"):
        ax.plot(run.t, run.V, color="k", lw=1.0, label="V")
        _note(ax, "V has no positive finite value: linear scale")
    _shade(ax, run.t, run.phase == NEAR, "tab:orange", "near phase")
    _shade(ax, run.t, run.contact, "tab:green", "contact phase")
    ax.set_xlim(run.t[0], run.t[-1])
    ax.set_xlabel("t [s]")
    ax.set_ylabel(r"$V = \frac{1}{2}s^T M s + \frac{1}{2}\beta e_F^2$ [J]")
    ax.grid(True, which="both", alpha=0.3)
    _legend_right(ax)
    ax.set_title(f"{run.name}: Lyapunov function")
    return fig


_BUILDERS = {
    "path3d": _fig_path3d,
    "projection": _fig_projection,
    "position_errors": _fig_position_errors,
    "force_error": _fig_force_error,
    "desired_force": _fig_desired_force,
    "lyapunov": _fig_lyapunov,
}


def _save_atomic(fig: Figure, path: Path) -> None:
    """Write fig as PNG to path via a temporary file in the same directory and os.replace."""
    with atomic_file(path) as fh:
        fig.savefig(fh, format="png", dpi=_DPI)


def _out_dir(out_dir: str | os.PathLike[str]) -> Path:
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise PlotError(f"output directory {str(out)!r} exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PlotError(f"cannot create output directory {str(out)!r}: {exc}") from exc
    return out


def plot_result(result: object, out_dir: str | os.PathLike[str], *, prefix: str = "") -> list[Path]:
    """Draw the paper's figures of one run as PNGs in out_dir and return the files written.

    result: a :class:`hybrid_force.result.Result` (or an object with its attributes t (N,) [s],
    p and p_d (N, 3) [m], f and f_d (N,) or (N, k) [N], V (N,) [J], phase (N,) and meta), or the
    path of a saved result. out_dir is created if needed. Files, in order:
    ``{prefix}path3d.png``, ``projection.png``, ``position_errors.png``, ``force_error.png``,
    ``desired_force.png``, ``lyapunov.png`` (see the module docstring). Existing files are
    replaced atomically. Raises :class:`PlotError` on a missing attribute or wrong shape.
    """
    if os.sep in prefix or (os.altsep and os.altsep in prefix):
        raise PlotError(
            f"prefix {prefix!r} must be a file-name prefix, not contain a path separator"
        )
    run = _load_run(result)
    out = _out_dir(out_dir)
    written: list[Path] = []
    for name in FIGURE_NAMES:
        fig = _BUILDERS[name](run)
        path = out / f"{prefix}{name}.png"
        _save_atomic(fig, path)
        written.append(path)
    return written


# --------------------------------------------------------------------------------------------
# Sweeps
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Sweep:
    """A sweep CSV: column names and rows (dicts of strings)."""

    path: Path
    columns: tuple[str, ...]
    rows: tuple[dict[str, str], ...]

    def require(self, column: str, role: str) -> None:
        if column not in self.columns:
            raise PlotError(
                f"{role} column {column!r} is not in {str(self.path)!r}"
                f"{did_you_mean(column, self.columns)}; available columns: "
                + ", ".join(self.columns)
            )

    def ok(self) -> np.ndarray:
        """(R,) bool: rows whose status is "ok" (all rows when there is no status column)."""
        if "status" not in self.columns:
            return np.ones(len(self.rows), dtype=bool)
        return np.array([r.get("status", "").strip() == "ok" for r in self.rows], dtype=bool)

    def numbers(self, column: str) -> np.ndarray:
        """(R,) float: column parsed as numbers; empty or non-numeric cells become NaN."""
        return np.array([_to_float(r.get(column)) for r in self.rows], dtype=float)


def _is_number(s: str) -> bool:
    """Whether s parses as a float ("nan" and "inf" included: a run may report them)."""
    try:
        float(s)
    except ValueError:
        return False
    return True


def _to_float(s: str | None) -> float:
    try:
        return float(s) if s is not None else math.nan
    except ValueError:
        return math.nan


def _read_sweep(csv_path: str | os.PathLike[str]) -> _Sweep:
    path = Path(csv_path)
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            rows = tuple(dict(r) for r in reader)
            columns = tuple(reader.fieldnames or ())
    except FileNotFoundError as exc:
        raise PlotError(f"sweep file {str(path)!r} does not exist") from exc
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise PlotError(f"cannot read sweep file {str(path)!r}: {exc}") from exc
    if not columns:
        raise PlotError(f"sweep file {str(path)!r} is empty (no header row)")
    if not rows:
        raise PlotError(f"sweep file {str(path)!r} has a header but no rows")
    return _Sweep(path=path, columns=columns, rows=rows)


def _levels(sweep: _Sweep, column: str) -> tuple[np.ndarray, list[str]]:
    """Index (R,) of each row's value of a swept parameter among its sorted distinct values.

    Numeric columns are sorted numerically, others in order of first appearance. Returns the
    index array and the tick labels of the distinct values.
    """
    raw = [r.get(column, "") or "" for r in sweep.rows]
    nums = sweep.numbers(column)
    if np.all(np.isfinite(nums)):
        values = np.unique(nums)
        return np.searchsorted(values, nums), [f"{v:.4g}" for v in values]
    distinct = list(dict.fromkeys(raw))
    lookup = {v: i for i, v in enumerate(distinct)}
    return np.array([lookup[v] for v in raw]), distinct


def _use_log(values: np.ndarray, *, at_least: bool = False) -> bool:
    """Log scale when every finite value is positive and they span more than 2 decades.

    at_least: also when they span exactly 2 decades (used for swept parameters such as
    K_d ∈ {1, 10, 100}, which are usually chosen on a log grid).
    """
    v = values[np.isfinite(values)]
    if not (v.size >= 2 and np.all(v > 0)):
        return False
    ratio = v.max() / v.min()
    return bool(ratio >= 100.0 if at_least else ratio > 100.0)


def _sweep_line(sweep: _Sweep, x: str, metric: str) -> Figure:
    """The metric against one swept parameter; failed rows as grey crosses along the bottom."""
    fig = _new_figure(7.0, 4.8)
    ax = fig.add_subplot()
    ok = sweep.ok()
    m = sweep.numbers(metric)
    xs = sweep.numbers(x)
    numeric = bool(np.all(np.isfinite(xs)))
    if not numeric:
        idx, labels = _levels(sweep, x)
        xs = idx.astype(float)
        ax.set_xticks(range(len(labels)), labels)
    good = ok & np.isfinite(m)
    order = np.argsort(xs[good], kind="stable")
    gx, gm = xs[good][order], m[good][order]
    if gx.size:
        ux = np.unique(gx)
        if ux.size < gx.size:  # other parameters vary too: show every run and their median
            med = np.array([np.median(gm[gx == v]) for v in ux])
            ax.plot(gx, gm, "o", color="tab:blue", alpha=0.4, ms=4, label="runs")
            ax.plot(ux, med, "-", color="tab:blue", lw=1.5, label="median over other parameters")
        else:
            ax.plot(gx, gm, "o-", color="tab:blue", lw=1.5, ms=5, label=metric)
    else:
        _note(ax, f"no run with status ok and a finite {metric}")
    bad = ~good
    if np.any(bad):
        ax.plot(
            xs[bad],
            np.zeros(int(bad.sum())),
            "x",
            color="0.5",
            ms=8,
            mew=2,
            transform=ax.get_xaxis_transform(),
            clip_on=False,
            label=f"failed or missing ({int(bad.sum())})",
        )
    if _use_log(gm):
        ax.set_yscale("log")
    if numeric and _use_log(xs, at_least=True):
        ax.set_xscale("log")
    ax.set_xlabel(x)
    ax.set_ylabel(metric)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{sweep.path.name}: {metric} against {x}")
    return fig


def _sweep_grid(sweep: _Sweep, x: str, y: str, metric: str) -> tuple[np.ndarray, np.ndarray]:
    """Heat-map cells: (values (ny, nx), failed (ny, nx) bool).

    A cell's value is the median metric of its ok rows with a finite metric (NaN if none);
    a cell is failed when it has rows but none of them gives a value.
    """
    ix, xl = _levels(sweep, x)
    iy, yl = _levels(sweep, y)
    m = sweep.numbers(metric)
    ok = sweep.ok() & np.isfinite(m)
    values = np.full((len(yl), len(xl)), np.nan)
    failed = np.zeros_like(values, dtype=bool)
    for r in range(len(yl)):
        for c in range(len(xl)):
            here = (iy == r) & (ix == c)
            if np.any(here & ok):
                values[r, c] = float(np.median(m[here & ok]))
            elif np.any(here):
                failed[r, c] = True
    return values, failed


def _sweep_heatmap(sweep: _Sweep, x: str, y: str, metric: str) -> Figure:
    """The metric over two swept parameters as a heat map; failed cells grey and hatched."""
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.patches import Patch, Rectangle

    values, failed = _sweep_grid(sweep, x, y, metric)
    _, xl = _levels(sweep, x)
    _, yl = _levels(sweep, y)
    fig = _new_figure(7.5, 6.0)
    ax = fig.add_subplot()
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        norm: Normalize = Normalize(0.0, 1.0)
    elif _use_log(finite):
        norm = LogNorm(float(finite.min()), float(finite.max()))
    elif finite.min() == finite.max():
        norm = Normalize(float(finite.min()) - 0.5, float(finite.max()) + 0.5)
    else:
        norm = Normalize(float(finite.min()), float(finite.max()))
    from matplotlib import colormaps

    cmap = colormaps["viridis"].with_extremes(bad="0.85")
    image = ax.imshow(
        np.ma.masked_invalid(values),
        origin="lower",
        cmap=cmap,
        norm=norm,
        aspect="auto",
        interpolation="nearest",
    )
    fig.colorbar(image, ax=ax, label=metric + (" (log scale)" if isinstance(norm, LogNorm) else ""))
    for r, c in zip(*np.nonzero(failed), strict=True):
        ax.add_patch(
            Rectangle(
                (c - 0.5, r - 0.5),
                1.0,
                1.0,
                facecolor="0.85",
                edgecolor="0.4",
                hatch="//",
                linewidth=0.0,
            )
        )
    if values.size <= 144:
        for r in range(values.shape[0]):
            for c in range(values.shape[1]):
                v = values[r, c]
                if np.isfinite(v):
                    light = norm(v) < 0.5
                    ax.text(
                        c,
                        r,
                        f"{v:.3g}",
                        ha="center",
                        va="center",
                        fontsize=8,
                        color="white" if light else "black",
                    )
    ax.set_xticks(range(len(xl)), xl)
    ax.set_yticks(range(len(yl)), yl)
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    handles = []
    if np.any(failed):
        handles.append(Patch(facecolor="0.85", edgecolor="0.4", hatch="//", label="failed run"))
    if np.any(~np.isfinite(values) & ~failed):
        handles.append(Patch(facecolor="0.85", label="no run"))
    if handles:
        ax.legend(
            handles=handles,
            loc="upper left",
            bbox_to_anchor=(0.0, -0.12),
            fontsize=8,
            ncol=2,
            frameon=False,
        )
    ax.set_title(f"{sweep.path.name}: {metric} over {x} and {y}")
    return fig


def plot_sweep(
    csv_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    x: str,
    metric: str,
    y: str | None = None,
) -> Path:
    """Plot a metric of a sweep CSV against one swept parameter (line) or two (heat map).

    csv_path: a CSV with one row per run; parameter columns are named like "control.Kd", metric
    columns plainly (e.g. "final_position_error"), and an optional "status" column: rows whose
    status is not "ok" are shown as missing (grey crosses on a line plot, grey hatched cells on a
    heat map). Several rows with the same parameter values are summarised by their median. The
    colour (or y) scale is logarithmic when the positive metric spans more than 2 decades.
    Writes a PNG to out_path atomically (parent directories created) and returns out_path.
    Raises :class:`PlotError` naming the file and listing the columns when x, y or metric is not
    a column, when the metric holds text in an ok row, and when the file is missing or empty.
    """
    sweep = _read_sweep(csv_path)
    sweep.require(x, "x")
    sweep.require(metric, "metric")
    if y is not None:
        sweep.require(y, "y")
        if y == x:
            raise PlotError(f"x and y are both {x!r}; a heat map needs two different parameters")
    if metric in (x, y):
        raise PlotError(f"metric {metric!r} is also a swept parameter; choose another column")
    ok = sweep.ok()
    for i, row in enumerate(sweep.rows):
        cell = (row.get(metric) or "").strip()
        if ok[i] and cell and not _is_number(cell):
            raise PlotError(
                f"metric column {metric!r} of {str(sweep.path)!r} is not numeric (data row "
                f"{i + 1} has {cell!r}); available columns: " + ", ".join(sweep.columns)
            )
    fig = _sweep_line(sweep, x, metric) if y is None else _sweep_heatmap(sweep, x, y, metric)
    out = Path(out_path)
    _out_dir(out.parent)
    _save_atomic(fig, out)
    return out

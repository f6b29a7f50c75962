"""Sweep plots: one metric of a sweep CSV against one swept parameter (line plot) or two (heat
map), failed runs shown as missing.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hybrid_force._extras import require as require_extra
from hybrid_force.errors import BadInputError, did_you_mean
from hybrid_force.viz._style import _new_figure, _note, _out_dir, _save_atomic

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["MAX_SWEEP_BYTES", "plot_sweep"]

MAX_SWEEP_BYTES = 256 * 2**20
"""The largest sweep CSV read (256 MiB): a sweep has at most 100 000 runs (MAX_RUNS), a few
hundred bytes each; the table is held in memory to be plotted."""


@dataclass(frozen=True)
class _Sweep:
    """A sweep CSV: column names and rows (dicts of strings)."""

    path: Path
    columns: tuple[str, ...]
    rows: tuple[dict[str, str], ...]

    def require(self, column: str, role: str) -> None:
        if column not in self.columns:
            raise BadInputError(
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
        size = path.stat().st_size
        if size > MAX_SWEEP_BYTES:
            raise BadInputError(
                f"sweep file {str(path)!r} is {size} bytes, more than the {MAX_SWEEP_BYTES} a "
                "sweep table may have (MAX_SWEEP_BYTES)"
            )
        with path.open(newline="", encoding="utf-8") as fh:
            reader = csv.reader(fh, strict=True)  # strict: an unclosed quote is an error
            columns = tuple(next(reader, ()))
            rows_list: list[dict[str, str]] = []
            for cells in reader:
                if not cells:
                    continue  # a blank line, as DictReader skips it
                if len(cells) != len(columns):  # a ragged row: not a table this plot can read
                    raise BadInputError(
                        f"sweep file {str(path)!r}, line {reader.line_num}: {len(cells)} fields "
                        f"where the header has {len(columns)}"
                    )
                rows_list.append(dict(zip(columns, cells, strict=True)))
            rows = tuple(rows_list)
    except FileNotFoundError as exc:
        raise BadInputError(f"sweep file {str(path)!r} does not exist") from exc
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise BadInputError(f"cannot read sweep file {str(path)!r}: {exc}") from exc
    if not columns:
        raise BadInputError(f"sweep file {str(path)!r} is empty (no header row)")
    if not rows:
        raise BadInputError(f"sweep file {str(path)!r} has a header but no rows")
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
    Raises :class:`BadInputError` naming the file and listing the columns when x, y or metric is not
    a column, when the metric holds text in an ok row, and when the file is missing or empty;
    :class:`~hybrid_force.errors.MissingExtraError` without matplotlib (the ``plots`` extra).
    """
    require_extra("plots", "figures")
    sweep = _read_sweep(csv_path)
    sweep.require(x, "x")
    sweep.require(metric, "metric")
    if y is not None:
        sweep.require(y, "y")
        if y == x:
            raise BadInputError(
                f"x and y are both {x!r}; a heat map needs two different parameters"
            )
    if metric in (x, y):
        raise BadInputError(f"metric {metric!r} is also a swept parameter; choose another column")
    ok = sweep.ok()
    for i, row in enumerate(sweep.rows):
        cell = (row.get(metric) or "").strip()
        if ok[i] and cell and not _is_number(cell):
            raise BadInputError(
                f"metric column {metric!r} of {str(sweep.path)!r} is not numeric (data row "
                f"{i + 1} has {cell!r}); available columns: " + ", ".join(sweep.columns)
            )
    fig = _sweep_line(sweep, x, metric) if y is None else _sweep_heatmap(sweep, x, y, metric)
    out = Path(out_path)
    _out_dir(out.parent)
    _save_atomic(fig, out)
    return out

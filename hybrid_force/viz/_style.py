"""What the run figures and the sweep plots share: a figure on its own Agg canvas, the output
folder, and atomic PNG writes.

matplotlib is imported only inside the functions (``import hybrid_force`` stays fast) and every
figure is drawn on its own Agg canvas (no pyplot, no global backend change, usable from threads and
on machines without a display). Each PNG is written atomically: to a temporary file in the same
directory, then ``os.replace``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from hybrid_force._atomic import atomic_file
from hybrid_force.errors import BadInputError

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

_DPI = 110


def _new_figure(width: float, height: float) -> Figure:
    """A Figure on its own Agg canvas (no pyplot state, no display needed)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _note(ax: Axes, text: str) -> None:
    """A grey message in the middle of ax (for an empty panel)."""
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", color="0.35")


def _legend_right(ax: Axes) -> None:
    """A legend outside ax on its right (inside, it could hide data such as a divergence)."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8)


def _save_atomic(fig: Figure, path: Path) -> None:
    """Write fig as PNG to path via a temporary file in the same directory and os.replace."""
    with atomic_file(path) as fh:
        fig.savefig(fh, format="png", dpi=_DPI)


def _out_dir(out_dir: str | os.PathLike[str]) -> Path:
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise BadInputError(f"output directory {str(out)!r} exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInputError(f"cannot create output directory {str(out)!r}: {exc}") from exc
    return out

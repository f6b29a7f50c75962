"""Tests of hybrid_force.viz.sweep_plots: a metric of a sweep CSV as a line plot or a heat map.

The CSVs are written by the tests (known values and failed rows), so every expectation comes
from how the test built its data, not from the plotting code.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import png_size

from hybrid_force.errors import BadInputError
from hybrid_force.viz import sweep_plots
from hybrid_force.viz.sweep_plots import plot_sweep


def test_log_scale_rule() -> None:
    assert sweep_plots._use_log(np.array([1e-3, 1.0, np.nan]))  # 3 decades
    assert not sweep_plots._use_log(np.array([1.0, 100.0]))  # exactly 2: not more than 2
    assert sweep_plots._use_log(np.array([1.0, 100.0]), at_least=True)
    assert not sweep_plots._use_log(np.array([-1.0, 1e3]))  # not all positive
    assert not sweep_plots._use_log(np.array([5.0]))


def _write_csv(path: Path, rows: list[dict[str, Any]]) -> Path:
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


@pytest.fixture
def sweep_csv(tmp_path: Path) -> Path:
    rows = []
    for kd in (1.0, 10.0, 100.0):
        for lam in (0.5, 1.0, 2.0, 4.0):
            failed = kd == 100.0 and lam == 4.0
            rows.append(
                {
                    "control.Kd": kd,
                    "control.Lambda": lam,
                    "status": "failed" if failed else "ok",
                    "final_position_error": "" if failed else 1e-2 / (kd * kd * lam),
                }
            )
    return _write_csv(tmp_path / "sweep.csv", rows)


def test_plot_sweep_line_and_heatmap(sweep_csv: Path, tmp_path: Path) -> None:
    line = plot_sweep(
        sweep_csv, tmp_path / "out" / "line.png", x="control.Kd", metric="final_position_error"
    )
    heat = plot_sweep(
        sweep_csv,
        tmp_path / "heat.png",
        x="control.Kd",
        y="control.Lambda",
        metric="final_position_error",
    )
    for path in (line, heat):
        png_size(path)
        assert path.stat().st_size > 10_000
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_file()) == ["heat.png", "sweep.csv"]


def test_sweep_grid_places_values_and_failures(sweep_csv: Path) -> None:
    sweep = sweep_plots._read_sweep(sweep_csv)
    values, failed = sweep_plots._sweep_grid(
        sweep, "control.Kd", "control.Lambda", "final_position_error"
    )
    assert values.shape == (4, 3)  # rows: Lambda levels, columns: Kd levels
    for r, lam in enumerate((0.5, 1.0, 2.0, 4.0)):
        for c, kd in enumerate((1.0, 10.0, 100.0)):
            if kd == 100.0 and lam == 4.0:
                assert failed[r, c] and np.isnan(values[r, c])
            else:
                assert not failed[r, c]
                assert values[r, c] == pytest.approx(1e-2 / (kd * kd * lam))
    fig = sweep_plots._sweep_heatmap(sweep, "control.Kd", "control.Lambda", "final_position_error")
    from matplotlib.colors import LogNorm

    assert isinstance(fig.axes[0].images[0].norm, LogNorm)  # spans 5+ decades
    fig = sweep_plots._sweep_line(sweep, "control.Kd", "final_position_error")
    assert fig.axes[0].get_yscale() == "log" and fig.axes[0].get_xscale() == "log"


def test_sweep_linear_scale_when_narrow(tmp_path: Path) -> None:
    rows = [{"sim.dt": dt, "rms": 1.0 + dt} for dt in (0.001, 0.002, 0.004)]
    sweep = sweep_plots._read_sweep(_write_csv(tmp_path / "s.csv", rows))
    fig = sweep_plots._sweep_line(sweep, "sim.dt", "rms")
    assert fig.axes[0].get_yscale() == "linear"
    np.testing.assert_allclose(fig.axes[0].get_lines()[0].get_ydata(), [1.001, 1.002, 1.004])


def test_sweep_where_every_run_failed_still_draws(tmp_path: Path) -> None:
    rows = [
        {"control.Kd": kd, "sim.integrator": integ, "status": "failed", "rms": ""}
        for kd in (1, 2)
        for integ in ("euler", "rk4")
    ]
    sweep = sweep_plots._read_sweep(_write_csv(tmp_path / "s.csv", rows))
    values, failed = sweep_plots._sweep_grid(sweep, "sim.integrator", "control.Kd", "rms")
    assert failed.all() and np.isnan(values).all() and values.shape == (2, 2)
    fig = sweep_plots._sweep_heatmap(sweep, "sim.integrator", "control.Kd", "rms")
    fig.canvas.draw()
    assert [t.get_text() for t in fig.axes[0].get_xticklabels()] == ["euler", "rk4"]
    assert len(fig.axes[0].patches) == 4  # four hatched cells


def test_plot_sweep_wrong_column_lists_columns(sweep_csv: Path, tmp_path: Path) -> None:
    with pytest.raises(BadInputError) as info:
        plot_sweep(sweep_csv, tmp_path / "x.png", x="control.kd", metric="final_position_error")
    msg = str(info.value)
    assert "sweep.csv" in msg and "'control.kd'" in msg
    for col in ("control.Kd", "control.Lambda", "status", "final_position_error"):
        assert col in msg
    assert "did you mean 'control.Kd'" in msg
    with pytest.raises(BadInputError, match="available columns"):
        plot_sweep(sweep_csv, tmp_path / "x.png", x="control.Kd", y="nope", metric="status")
    with pytest.raises(BadInputError, match=r"not numeric \(data row 1 has 'ok'\)"):
        plot_sweep(sweep_csv, tmp_path / "x.png", x="control.Kd", metric="status")
    with pytest.raises(BadInputError, match="does not exist"):
        plot_sweep(tmp_path / "missing.csv", tmp_path / "x.png", x="a", metric="b")
    assert not (tmp_path / "x.png").exists()

"""hybrid-force compare: the tracking metrics by hand, and the command (laws, rows, failures)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hybrid_force.control.laws import base
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane
from hybrid_force.metrics import (
    compute_tracking_metrics,
    impact_force_peak,
    out_of_contact_fraction,
    path_error,
    surface_normals,
    tangential_component,
    time_staying_within,
)
from hybrid_force.result import Result
from hybrid_force.studies.compare import COMPARE_COLUMNS, METRIC_UNITS, check_laws, run_compare
from hybrid_force.studies.table import read_table

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
DT = 1.0 / 64.0  # exact binary step: t = 0.5, 1.0, 2.5 fall on samples


def _result(
    t: np.ndarray,
    *,
    p: np.ndarray | None = None,
    p_d: np.ndarray | None = None,
    f: np.ndarray | None = None,
    f_d: np.ndarray | None = None,
    phase: np.ndarray | None = None,
    u: np.ndarray | None = None,
    settle_time: float = 1.0,
) -> Result:
    """A hand-built run of a 3-joint arm: zeros wherever the test gives nothing."""
    n = t.shape[0]
    zeros3 = np.zeros((n, 3))
    return Result(
        t=t,
        q=zeros3,
        v=zeros3,
        q_d=zeros3,
        u=zeros3 if u is None else u,
        p=zeros3 if p is None else p,
        p_d=zeros3 if p_d is None else p_d,
        f=np.zeros(n) if f is None else f,
        f_d=np.zeros(n) if f_d is None else f_d,
        phi=np.zeros(n),
        V=np.zeros(n),
        phase=np.full(n, 2) if phase is None else phase,
        meta={"settings": {"settle_time": settle_time}},
    )


# ----------------------------------------------------------------------------- the metrics
def test_tangential_component_removes_exactly_the_normal_component(
    rng: np.random.Generator,
) -> None:
    e = rng.normal(size=(200, 3))
    n = rng.normal(size=(200, 3)) * rng.uniform(0.1, 10.0, size=(200, 1))  # not unit
    e_t = tangential_component(e, n)
    unit = n / np.linalg.norm(n, axis=1, keepdims=True)
    along = np.sum(e * unit, axis=1)
    # orthogonal to the normal, and Pythagoras: ‖e‖² = ‖e_t‖² + (e·n̂)²
    assert np.max(np.abs(np.sum(e_t * unit, axis=1))) < 1e-12
    np.testing.assert_allclose(np.sum(e_t**2, axis=1) + along**2, np.sum(e**2, axis=1), rtol=1e-12)
    # the classic formula e − (e·n̂) n̂
    np.testing.assert_allclose(e_t, e - along[:, None] * unit, atol=1e-12)
    # a vector along the normal leaves nothing, one in the tangent plane is kept whole
    np.testing.assert_allclose(tangential_component(3.0 * unit, n), 0.0, atol=1e-12)
    np.testing.assert_allclose(tangential_component(e_t, n), e_t, atol=1e-12)
    # by hand: the normal z removes the z part
    np.testing.assert_allclose(
        tangential_component(np.array([[1.0, 2.0, 3.0]]), np.array([[0.0, 0.0, 5.0]])),
        [[1.0, 2.0, 0.0]],
        atol=1e-15,
    )


def test_tangential_component_with_two_normals_keeps_the_line_they_leave(
    rng: np.random.Generator,
) -> None:
    e = rng.normal(size=(50, 3))
    a, b = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))  # neither unit nor orthogonal
    e_t = tangential_component(e, np.stack([a, b], axis=1))
    axis = np.cross(a, b)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)  # the one direction normal to both
    np.testing.assert_allclose(e_t, np.sum(e * axis, axis=1)[:, None] * axis, atol=1e-12)


def test_tangential_component_marks_non_finite_samples_and_checks_shapes() -> None:
    e = np.array([[1.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])
    n = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    e_t = tangential_component(e, n)
    assert e_t[0].tolist() == [1.0, 0.0, 0.0] and np.all(np.isnan(e_t[1]))
    from hybrid_force.errors import BadInputError

    with pytest.raises(BadInputError, match="normals"):
        tangential_component(e, np.zeros((3, 3)))


def test_surface_normals_and_path_error_on_a_cylinder_by_hand() -> None:
    cylinder = Cylinder(0.4)  # axis z: the outward normal at (x, y, z) is (x, y, 0) / 0.4
    points = np.array([[0.4, 0.0, 7.0], [0.0, -0.4, 1.0], [0.0, 0.0, 3.0]])
    normals = surface_normals([cylinder], points)
    np.testing.assert_allclose(normals[:, 0], [[1, 0, 0], [0, -1, 0], [0, 0, 0]], atol=1e-15)
    # tip on the surface at (0.4, 0, z); desired 1 cm further out and 2 mm higher: only the
    # 2 mm along the surface count
    t = np.arange(3) * DT
    p = np.array([[0.4, 0.0, 7.0]] * 3)
    p_d = p + np.array([0.01, 0.0, 0.002])
    np.testing.assert_allclose(path_error(_result(t, p=p, p_d=p_d), [cylinder]), 0.002, rtol=1e-12)


def test_time_staying_within_by_hand() -> None:
    t = np.arange(6) * 0.5
    assert time_staying_within(t, np.array([0, 1, 0, 1, 1, 1], bool)) == 1.5
    assert time_staying_within(t, np.ones(6, bool)) == 0.0
    assert time_staying_within(t, np.array([1, 1, 1, 1, 1, 0], bool)) is None
    assert time_staying_within(t[:0], np.zeros(0, bool)) is None


def test_impact_force_peak_looks_half_a_second_after_the_first_contact() -> None:
    t = np.arange(193) * DT  # 0 .. 3 s
    phase = np.where(t >= 0.5, 2, 0)
    f = np.where(phase == 2, 10.0, 0.0)
    f[t == 0.75] = 25.0
    f[t == 1.25] = 40.0  # 0.75 s after the contact: not the impact
    assert impact_force_peak(t, f, phase) == 25.0
    f[t == 1.0] = 30.0  # exactly 0.5 s after: still in the window
    assert impact_force_peak(t, f, phase) == 30.0
    assert impact_force_peak(t, f, phase, window=1.0) == 40.0
    assert impact_force_peak(t, f, np.zeros_like(phase)) is None


def test_out_of_contact_fraction_weights_each_sample_by_its_duration() -> None:
    t = np.array([0.0, 1.0, 2.0, 4.0, 5.0, 9.0])
    phase = np.array([0, 2, 2, 0, 2, 2])
    # from t = 1 (first contact) to 9: 8 s, of which [4, 5) off the surface
    assert out_of_contact_fraction(t, phase) == 1.0 / 8.0
    assert out_of_contact_fraction(t, np.zeros(6, int)) is None
    assert out_of_contact_fraction(t, np.array([0, 0, 0, 0, 0, 2])) is None


def test_tracking_metrics_of_a_hand_built_run() -> None:
    """Known force and path errors before and after settling (t = 1 s), an impact, a release,
    and an exponential settling whose crossing times are solved by hand."""
    t = np.arange(193) * DT  # 0 .. 3 s
    n = t.shape[0]
    plane = Plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])  # normal z
    phase = np.where(t >= 0.25, 2, 1)
    f_d = np.full(n, 10.0)
    # force error: decays as 8 e^(−4t) N in contact, with an impact peak of 30 N at 0.5 s
    f = np.where(phase == 2, 10.0 + 8.0 * np.exp(-4.0 * t), 0.0)
    f[t == 0.5] = 30.0
    # path error: 5 cm e^(−3t) along x, and a normal offset along z that must not count
    e = np.zeros((n, 3))
    e[:, 0] = 0.05 * np.exp(-3.0 * t)
    e[:, 2] = 0.3
    p_d = np.stack([t, np.zeros(n), np.zeros(n)], axis=1)
    u = np.zeros((n, 3))
    u[10, 1] = -7.5
    u[50, 2] = 4.0
    res = _result(t, p=p_d + e, p_d=p_d, f=f, f_d=f_d, phase=phase, u=u)
    m = compute_tracking_metrics(res, [plane])

    settled = t >= 1.0
    ef = 8.0 * np.exp(-4.0 * t[settled])
    assert m.force_error_max_settled == pytest.approx(8.0 * math.exp(-4.0), rel=1e-12)
    assert m.force_error_rms_settled == pytest.approx(math.sqrt(np.mean(ef**2)), rel=1e-12)
    et = 0.05 * np.exp(-3.0 * t[settled])
    assert m.path_error_max_settled == pytest.approx(0.05 * math.exp(-3.0), rel=1e-12)
    assert m.path_error_rms_settled == pytest.approx(math.sqrt(np.mean(et**2)), rel=1e-12)
    assert m.impact_force_peak == 30.0
    assert m.out_of_contact_fraction == 0.0
    assert m.torque_max == 7.5
    # settled: the first sample after both 8 e^(−4t) < 1 (t > ln 8 / 4) and 0.05 e^(−3t) < 1e-3
    # (t > ln 50 / 3 = 1.304 s)
    t_star = max(math.log(8.0) / 4.0, math.log(50.0) / 3.0)
    assert m.time_to_settle == math.ceil(t_star / DT) * DT

    # a late release (off the surface for 3 samples) delays the settling past it, and counts
    # in the time off the surface; the force metrics skip the samples off the surface
    phase2 = phase.copy()
    phase2[160:163] = 0
    f2 = np.where(phase2 == 2, f, 0.0)
    m2 = compute_tracking_metrics(
        _result(t, p=p_d + e, p_d=p_d, f=f2, f_d=f_d, phase=phase2, u=u), [plane]
    )
    assert m2.time_to_settle == t[163]
    first = int(np.argmax(phase2 == 2))
    assert m2.out_of_contact_fraction == pytest.approx(3 * DT / (t[-1] - t[first]), rel=1e-12)
    assert m2.force_error_max_settled == m.force_error_max_settled
    # never settled when the last sample is out of tolerance
    f3 = f.copy()
    f3[-1] = 12.0
    m3 = compute_tracking_metrics(
        _result(t, p=p_d + e, p_d=p_d, f=f3, f_d=f_d, phase=phase), [plane]
    )
    assert m3.time_to_settle is None


def test_tracking_metrics_refuse_the_wrong_number_of_surfaces() -> None:
    from hybrid_force.errors import BadInputError

    t = np.arange(4) * DT
    with pytest.raises(BadInputError, match="2 surface"):
        compute_tracking_metrics(_result(t), [Cylinder(0.4), Cylinder(0.5)])
    with pytest.raises(BadInputError, match="path_errors"):
        compute_tracking_metrics(_result(t), [Cylinder(0.4)], path_errors=np.zeros(3))


# ----------------------------------------------------------------------------- the command
# Paper section 6.3 (RTR arm on the cylinder, starting in contact), shortened.
SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "paper_contact.toml"
SHORT = {"sim.duration": 0.3, "sim.settle_time": 0.1}
SHORT_ARGS = ["--set", "sim.duration=0.3", "--set", "sim.settle_time=0.1"]


def _stiff_arimoto(context: base.LawContext) -> Any:
    """A second law for the tests: the paper's law with twice its Λ."""
    from hybrid_force.control.laws import arimoto

    gains = dataclasses.replace(context.gains, Lambda=2.0 * context.gains.Lambda)
    return arimoto.build(dataclasses.replace(context, gains=gains))


class _Runaway:
    """A law that pushes every joint with 1e9 from its 50th step: the run diverges."""

    V = math.nan

    def __init__(self, context: base.LawContext) -> None:
        self.inner = base.law_spec("arimoto").factory(context)
        self.steps = 0

    def _push(self, command: Any) -> Any:
        if self.steps < 50:
            return command
        return dataclasses.replace(command, u0=np.full(command.u0.shape, 1e9))

    def free_space(self, *args: Any) -> Any:
        return self._push(self.inner.free_space(*args))

    def hybrid(self, *args: Any) -> Any:
        return self._push(self.inner.hybrid(*args))

    def update(self, dt: float, f: np.ndarray) -> None:
        self.steps += 1
        self.inner.update(dt, f)

    def trace(self, *args: Any) -> Any:
        return self.inner.trace(*args)

    def info(self) -> dict[str, Any]:
        return {"law": "runaway"}


@pytest.fixture()
def two_laws(monkeypatch: pytest.MonkeyPatch) -> tuple[str, ...]:
    """Registers "arimoto_stiff" and "runaway" for this test (the forked workers inherit it)."""
    for name, factory in (("arimoto_stiff", _stiff_arimoto), ("runaway", _Runaway)):
        spec = base.LawSpec(name, "a law of the tests", factory)
        monkeypatch.setitem(base.LAWS, name, spec)
    return base.law_names()


def _rows(path: Path) -> list[dict[str, str]]:
    columns, rows = read_table(path)
    assert tuple(columns) == COMPARE_COLUMNS
    return rows


def test_laws_default_to_the_registry_and_unknown_or_repeated_are_refused(
    two_laws: tuple[str, ...], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from hybrid_force.cli import main

    assert check_laws(None) == two_laws and "runaway" in two_laws
    for laws, named in (("arimoto,nope", "'nope'"), ("arimoto,arimoto", "'arimoto' twice")):
        assert main(["compare", str(SCENARIO), "--laws", laws, "--out", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err
        assert named in err and "valid: " + ", ".join(two_laws) in err, err
    assert main(["compare", str(SCENARIO), "--set", "control.law=arimoto"]) == 2
    assert "--laws" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # refused before anything was written
    assert main(["compare", "--help"]) == 0
    assert "--laws" in (text := capsys.readouterr().out) and "exit status" in text


def test_rows_match_separate_runs_of_each_law_on_one_or_two_workers(
    two_laws: tuple[str, ...], tmp_path: Path
) -> None:
    from hybrid_force.scenario.loader import load_scenario
    from hybrid_force.sim.loop import simulate

    laws = ("arimoto", "arimoto_stiff")
    tables = []
    for workers in (1, 2):
        csv_path = run_compare(
            SCENARIO,
            laws,
            out_dir=tmp_path / f"w{workers}",
            overrides=SHORT,
            workers=workers,
            progress=False,
            start_method="fork",
        )
        tables.append(_rows(csv_path))
    one, two = tables
    for a, b in zip(one, two, strict=True):  # identical but for the wall time
        assert {**a, "wall_time": ""} == {**b, "wall_time": ""}
    assert [r["law"] for r in one] == list(laws)
    for law, row in zip(laws, one, strict=True):
        sc = load_scenario(SCENARIO, {"control.law": law, **SHORT})
        expected = compute_tracking_metrics(simulate(sc), sc.surfaces).to_dict()
        assert row["status"] == "ok" and row["error"] == ""
        for name in METRIC_UNITS:
            value = expected[name]
            assert row[name] == ("" if value is None else repr(value)), name
            if value is not None:
                assert float(row[name]) == value  # bit for bit
        assert float(row["wall_time"]) > 0.0
        assert (tmp_path / "w1" / row["result"]).is_file()
    # the two laws differ (else the test could not tell them apart)
    assert one[0]["path_error_max_settled"] != one[1]["path_error_max_settled"]
    for name in ("compare_force_error.png", "compare_path_error.png"):
        assert (tmp_path / "w1" / name).read_bytes()[:8] == PNG_MAGIC


def test_a_law_that_diverges_is_a_row_saying_so(
    two_laws: tuple[str, ...],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    from hybrid_force.cli import main

    out = tmp_path / "out"
    argv = ["compare", str(SCENARIO), "--laws", "runaway,arimoto", "--out", str(out), *SHORT_ARGS]
    assert main([*argv, "--workers", "1", "--start-method", "fork", "--no-progress"]) == 0
    captured = capsys.readouterr()
    assert "warning: law runaway: diverged" in captured.err
    runaway, arimoto = _rows(out / "compare.csv")
    assert runaway["law"] == "runaway" and runaway["status"] == "diverged"
    assert "runaway at t = " in runaway["error"]
    assert all(runaway[name] == "" for name in METRIC_UNITS)  # no number for a failed run
    assert runaway["result"]  # its partial run is kept (and drawn)
    assert arimoto["status"] == "ok" and arimoto["impact_force_peak"] != ""
    assert captured.out.splitlines()[1].split()[:2] == ["runaway", "diverged"]
    # the same command again runs nothing and writes the same table
    before = (out / "compare.csv").read_text()
    assert main([*argv, "--no-progress"]) == 0
    assert "0 new run(s)" in capsys.readouterr().out
    assert (out / "compare.csv").read_text() == before


def test_plot_comparison_refuses_no_law_and_mismatched_curves(tmp_path: Path) -> None:
    from hybrid_force.errors import BadInputError
    from hybrid_force.viz.compare_plots import COMPARE_FIGURES, LawCurve, plot_comparison

    with pytest.raises(BadInputError, match="no law"):
        plot_comparison([], tmp_path)
    t = np.arange(5) * DT
    with pytest.raises(BadInputError, match="path_error"):
        LawCurve("a", "ok", t, np.ones(5), np.ones(4))
    # a failed law whose values are all non-finite is left out, the others drawn
    curves = [
        LawCurve("a", "ok", t, np.exp(-t), np.exp(-2 * t)),
        LawCurve("b", "diverged", t, np.full(5, np.nan), np.full(5, np.inf)),
    ]
    written = plot_comparison(curves, tmp_path / "figs", settle_time=0.02)
    assert [p.name for p in written] == [f"{name}.png" for name in COMPARE_FIGURES]
    assert all(p.read_bytes()[:8] == PNG_MAGIC for p in written)

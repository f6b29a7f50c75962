"""Tests of hybrid_force.viz.run_figures: the paper's figures of one run.

The runs are synthetic (known shapes, hand-written phases and events), so every expectation
here comes from how the test built its data, not from the plotting code.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import png_size

from hybrid_force.errors import BadInputError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.surface_base import plane_basis
from hybrid_force.result import Result
from hybrid_force.viz import _run_data, _wireframes, run_figures
from hybrid_force.viz.figure_names import FIGURE_NAMES
from hybrid_force.viz.run_figures import plot_result

EXPECTED = (
    "path3d.png",
    "projection.png",
    "position_errors.png",
    "force_error.png",
    "desired_force.png",
    "lyapunov.png",
)

# The synthetic approach run: free until T_NEAR, near until T_CONTACT, then in contact.
T_NEAR, T_CONTACT, DURATION, DT = 2.0, 3.0, 14.0, 0.01
RADIUS, RISE, OMEGA = 0.4, 0.05, 1.0


def _synthetic(k: int = 1, *, events: bool = True, seed: int = 7) -> Result:
    """A run tracking a helix on the cylinder r = 0.4 about z, errors decaying like e^{-t}."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, DURATION + DT / 2, DT)
    n_samples, n = t.size, 3
    p_d = np.column_stack([RADIUS * np.cos(OMEGA * t), RADIUS * np.sin(OMEGA * t), 1.0 + RISE * t])
    e0 = np.array([-0.3, -0.3, 0.5])
    p = p_d + np.exp(-t)[:, None] * e0
    phase = np.where(t < T_NEAR, 0, np.where(t < T_CONTACT, 1, 2)).astype(np.int64)
    contact = phase == 2
    f_d1 = np.where(contact, 10.0, np.where(phase == 1, 5.0 * (T_CONTACT - t), 0.0))
    f1 = np.where(contact, 10.0 + 4.0 * np.exp(-(t - T_CONTACT) / 0.5), 0.0)
    phi1 = np.where(contact, 0.0, np.linalg.norm(p[:, :2], axis=1) - RADIUS)
    cols = [(f1, f_d1, phi1)] + [(0.5 * f1, 0.5 * f_d1, phi1) for _ in range(k - 1)]
    f, f_d, phi = (np.column_stack(c) if k > 1 else c[0] for c in zip(*cols, strict=True))
    surfaces: list[dict[str, Any]] = [
        {
            "type": "cylinder",
            "radius": RADIUS,
            "center": [0, 0, 0],
            "axis": [0, 0, 1],
            "inside": False,
        }
    ]
    if k > 1:
        surfaces.append({"type": "plane", "point": [0, 0, 0.5], "normal": [0, 0, 1]})
    meta: dict[str, Any] = {
        "name": "synthetic_approach",
        "surfaces": surfaces,
        "status": "ok",
        "events": (
            [
                {"t": T_NEAR, "kind": "near"},
                {"t": T_CONTACT, "kind": "contact"},
                {"t": T_CONTACT, "kind": "impact", "impulse": 0.2, "speed": 0.1},
            ]
            if events
            else []
        ),
    }
    q = rng.normal(size=(n_samples, n))
    return Result(
        t=t,
        q=q,
        v=rng.normal(size=(n_samples, n)),
        q_d=q,
        u=rng.normal(size=(n_samples, n)),
        p=p,
        p_d=p_d,
        f=f,
        f_d=f_d,
        phi=phi,
        V=2.0 * np.exp(-2.0 * t),
        phase=phase,
        meta=meta,
    )


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path]]:
    out = tmp_path_factory.mktemp("plots") / "nested" / "run"
    return out, plot_result(_synthetic(), out)


# ------------------------------------------------------------------------------- plot_result
def test_plot_result_writes_exactly_the_six_pngs(written: tuple[Path, list[Path]]) -> None:
    out, paths = written
    assert [p.name for p in paths] == list(EXPECTED)
    assert tuple(f"{n}.png" for n in FIGURE_NAMES) == EXPECTED
    # nothing else (no temporary files left behind)
    assert sorted(p.name for p in out.iterdir()) == sorted(EXPECTED)
    for path in paths:
        width, height = png_size(path)
        assert width >= 400 and height >= 400, (path.name, width, height)
        assert path.stat().st_size > 15_000, path.name


def test_plot_result_k2_and_prefix_and_fallback_events(tmp_path: Path) -> None:
    run = _synthetic(k=2, events=False)
    assert run.f.shape == (run.t.size, 2)
    paths = plot_result(run, tmp_path, prefix="k2_")
    assert [p.name for p in paths] == [f"k2_{n}" for n in EXPECTED]
    for path in paths:
        png_size(path)


def test_a_saved_result_loads_for_plotting(tmp_path: Path) -> None:
    result = _synthetic()
    saved = result.save(tmp_path / "result.npz")
    run = _run_data._load_run(saved)  # what plot_result does with a path
    assert run.name == "synthetic_approach"
    np.testing.assert_array_equal(run.p, result.p)
    np.testing.assert_array_equal(run.f[:, 0], result.f)
    assert run.events == ((T_NEAR, "near"), (T_CONTACT, "contact"), (T_CONTACT, "impact"))


def test_figures_carry_scenario_name_and_units() -> None:
    run = _run_data._load_run(_synthetic())
    for name, build in run_figures._BUILDERS.items():
        fig = build(run)
        titles = [ax.get_title() for ax in fig.axes]
        suptitle = fig.get_suptitle()
        assert any("synthetic_approach" in s for s in [*titles, suptitle]), name
        for ax in fig.axes:
            if ax.get_label() == "<colorbar>":
                continue
            for label in (ax.get_xlabel(), ax.get_ylabel()):
                if label:
                    assert "[" in label and "]" in label, (name, label)


def test_path3d_lines_are_the_paths() -> None:
    result = _synthetic()
    fig = run_figures._fig_path3d(_run_data._load_run(result))
    ax = fig.axes[0]
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    xs, _ys, zs = lines["actual $p$"].get_data_3d()
    np.testing.assert_allclose(xs[[0, -1]], result.p[[0, -1], 0])
    np.testing.assert_allclose(zs[[0, -1]], result.p[[0, -1], 2])
    assert lines["desired $p_d$"].get_linestyle() == "--"


def test_position_error_panels_hold_p_minus_pd() -> None:
    result = _synthetic()
    fig = run_figures._fig_position_errors(_run_data._load_run(result))
    e_hand = np.exp(-result.t)[:, None] * np.array([-0.3, -0.3, 0.5])
    for i in range(3):
        y = fig.axes[i].get_lines()[0].get_ydata()
        np.testing.assert_allclose(y, e_hand[:, i], atol=1e-12)
    assert fig.axes[3].get_yscale() == "log"


def test_force_error_masks_samples_out_of_contact() -> None:
    result = _synthetic()
    fig = run_figures._fig_force_error(_run_data._load_run(result))
    whole = fig.axes[0]
    in_contact = whole.get_lines()[0].get_ydata()
    free = whole.get_lines()[1].get_ydata()
    contact = result.t >= T_CONTACT
    assert np.all(np.isnan(in_contact[~contact])) and np.all(np.isfinite(in_contact[contact]))
    assert np.all(np.isnan(free[contact])) and np.all(np.isfinite(free[~contact]))
    # e_f = 4 e^{-(t - 3)/0.5} in contact, by construction
    hand = 4.0 * np.exp(-(result.t[contact] - T_CONTACT) / 0.5)
    np.testing.assert_allclose(in_contact[contact], hand, rtol=0, atol=1e-12)
    # zoom: first 10 s of a 14 s run
    tz = fig.axes[1].get_lines()[0].get_xdata()
    assert tz.max() <= 10.0 + 1e-12 and tz.max() > 10.0 - DT
    assert fig.axes[2].get_yscale() == "log"


def test_desired_force_marks_the_switches() -> None:
    fig = run_figures._fig_desired_force(_run_data._load_run(_synthetic()))
    ax = fig.axes[0]
    vlines = sorted(
        float(ln.get_xdata()[0])
        for ln in ax.get_lines()
        if len(ln.get_xdata()) == 2 and ln.get_xdata()[0] == ln.get_xdata()[1]
    )
    assert vlines == [T_NEAR, T_CONTACT, T_CONTACT]
    texts = [txt.get_text() for txt in ax.texts]
    assert any("near" in s for s in texts)
    assert any("contact" in s and "impact" in s for s in texts)  # same instant, one label
    assert ax.get_xlim() == (0.0, 10.0)


def test_lyapunov_is_log_scale() -> None:
    fig = run_figures._fig_lyapunov(_run_data._load_run(_synthetic()))
    assert fig.axes[0].get_yscale() == "log"


# ---------------------------------------------------------------------- geometry and events
def test_phase_switches_fallback() -> None:
    t = np.arange(10.0)
    phase = np.array([0, 0, 1, 1, 2, 2, 1, 0, 2, 2])
    got = _run_data._phase_switches(t, phase)
    assert got == [
        (2.0, "near"),
        (4.0, "contact"),
        (6.0, "release"),
        (7.0, "free"),
        (8.0, "contact"),
    ]


def test_intervals_of_a_mask() -> None:
    t = np.arange(8.0) * 0.5
    mask = np.array([1, 1, 0, 0, 1, 0, 1, 1], dtype=bool)
    # runs 0..1 -> [0, 1.0), 4..4 -> [2.0, 2.5), 6..7 reaches the end -> [3.0, 3.5]
    assert _run_data._intervals(t, mask) == [(0.0, 1.0), (2.0, 0.5), (3.0, 0.5)]
    assert _run_data._intervals(t, np.zeros(8, dtype=bool)) == []
    assert _run_data._intervals(t, np.ones(8, dtype=bool)) == [(0.0, 3.5)]


def test_diverged_run_marks_first_non_finite_sample() -> None:
    result = _synthetic()
    p = result.p.copy()
    f = result.f.copy()
    i_bad = 1200
    p[i_bad:] = np.nan
    f[i_bad + 5 :] = np.inf
    bad = dataclasses.replace(result, p=p, f=f, meta=dict(result.meta, status="failed"))
    run = _run_data._load_run(bad)
    for build, t_expected in (
        (run_figures._fig_position_errors, result.t[i_bad]),
        (run_figures._fig_force_error, result.t[i_bad + 5]),
    ):
        fig = build(run)
        fig.canvas.draw()  # rendering must not warn (pytest turns warnings into errors)
        red = [
            ln.get_xdata()[0]
            for ln in fig.axes[0].get_lines()
            if ln.get_color() == "red" and ln.get_linestyle() == ":"
        ]
        assert red == [pytest.approx(t_expected)]


def test_zoom_windows() -> None:
    assert _run_data._zoom_end(np.linspace(1.0, 21.0, 5)) == pytest.approx(11.0)
    assert _run_data._zoom_end(np.linspace(0.0, 6.0, 5)) == pytest.approx(3.0)
    assert _run_data._window_end(np.linspace(0.0, 6.0, 5)) == pytest.approx(6.0)
    assert _run_data._window_end(np.linspace(0.0, 60.0, 5)) == pytest.approx(10.0)


def test_plane_basis_is_right_handed_orthonormal() -> None:
    rng = np.random.default_rng(3)
    for n in [np.array([0.0, 0.0, 1.0]), *rng.normal(size=(20, 3))]:
        n = n / np.linalg.norm(n)
        u, w = plane_basis(n)
        frame = np.column_stack([u, w, n])
        np.testing.assert_allclose(frame.T @ frame, np.eye(3), atol=1e-12)
        assert np.linalg.det(frame) == pytest.approx(1.0)
    u, w = plane_basis(np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose([u, w], [[1, 0, 0], [0, 1, 0]], atol=1e-15)


def test_surface_meshes_lie_on_their_surfaces() -> None:
    rng = np.random.default_rng(11)
    pts = rng.normal(size=(50, 3))
    c, a = np.array([0.1, -0.2, 0.3]), np.array([1.0, 2.0, 2.0]) / 3.0
    g = Cylinder(0.7, c, a).patch(pts) - c
    radial = g - (g @ a)[..., None] * a
    np.testing.assert_allclose(np.linalg.norm(radial, axis=-1), 0.7, rtol=1e-12)
    s = g @ a
    s_pts = (pts - c) @ a
    assert s.min() <= s_pts.min() and s.max() >= s_pts.max()  # covers the motion's axial range
    cap = Sphere(0.7, c).patch(c + 0.7 * np.array([[1.0, 0, 0], [0.9, 0.3, 0]]))
    np.testing.assert_allclose(np.linalg.norm(cap - c, axis=-1), 0.7)
    normal = np.array([0.0, 0.6, 0.8])
    np.testing.assert_allclose((Plane(c, normal).patch(pts) - c) @ normal, 0.0, atol=1e-12)


def test_projection_choice() -> None:
    cyl = {"type": "cylinder", "radius": 0.4, "center": [1, 2, 3], "axis": [0, 0, 1]}
    proj = _wireframes._projection([cyl])
    assert proj.xlabel == "x [m]" and proj.ylabel == "y [m]"
    assert proj.circles == ((1.0, 2.0, 0.4, "cylinder 0"),)
    plane = {"type": "plane", "point": [0, 0, 0], "normal": [1, 0, 0]}
    proj = _wireframes._projection([plane])
    assert abs(proj.u @ [1, 0, 0]) < 1e-12 and abs(proj.w @ [1, 0, 0]) < 1e-12
    assert proj.circles == ()
    sphere = {"type": "sphere", "radius": 0.5, "center": [0.1, 0.2, 0.3]}
    proj = _wireframes._projection([sphere])
    assert proj.xlabel == "x [m]" and proj.circles == ((0.1, 0.2, 0.5, "sphere 0 outline"),)


def test_bad_results_raise_plot_error(tmp_path: Path) -> None:
    class Partial:
        t = np.linspace(0, 1, 5)

    with pytest.raises(BadInputError, match="'p'"):
        plot_result(Partial(), tmp_path)
    with pytest.raises(BadInputError, match="path separator"):
        plot_result(_synthetic(), tmp_path, prefix="a/b")
    assert issubclass(BadInputError, BadInputError)


def test_surface_dicts_are_read_by_the_surface_parser(tmp_path: Path) -> None:
    """A bad surface dict is refused as surface_from_dict refuses it, naming its index; a
    function surface (not rebuildable) is skipped, not an error."""
    base = _synthetic()
    bad = {"type": "cylinder", "radius": -0.4}
    broken = dataclasses.replace(base, meta=dict(base.meta, surfaces=[{"type": "function"}, bad]))
    with pytest.raises(BadInputError, match=r"meta\['surfaces'\]\[1\] cannot be drawn.*radius"):
        plot_result(broken, tmp_path)
    skipped = dataclasses.replace(base, meta=dict(base.meta, surfaces=[{"type": "function"}]))
    assert len(plot_result(skipped, tmp_path)) == len(FIGURE_NAMES)


def test_desired_force_shows_the_measured_force_when_it_is_not_the_true_one() -> None:
    import dataclasses

    base = _synthetic()
    ideal = run_figures._fig_desired_force(_run_data._load_run(base)).axes[0]
    assert not any("measured" in ln.get_label() for ln in ideal.get_lines())
    f_meas = base.f + 0.25  # a biased sensor
    sampled = dataclasses.replace(base, f_meas=f_meas)
    ax = run_figures._fig_desired_force(_run_data._load_run(sampled)).axes[0]
    measured = [ln for ln in ax.get_lines() if "measured" in ln.get_label()]
    true = [ln for ln in ax.get_lines() if "true" in ln.get_label()]
    assert len(measured) == 1 and len(true) == 1
    n = len(measured[0].get_ydata())
    np.testing.assert_allclose(measured[0].get_ydata(), f_meas[:n])

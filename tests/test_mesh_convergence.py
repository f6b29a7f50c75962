"""The paper's section 6.3 run (scenarios/paper_contact.toml) on its cylinder given as a mesh
of N sections: what the settled error is made of, and what converges as ``resolution`` is
refined (docs/mesh_parts.md, "Convergence on a faceted part"; the larger study:
benchmarks/study_mesh_convergence.py, which imports the helpers below).

**Curved facets (the default).** Φ = 0 lies on the patches through the vertices
(geometry/mesh_patches), which are the cylinder to R φ⁴/8 (φ = π/N; 7e-11 m at N = 512), and
the field's samples are their distance to O(d² φ² / R): no faceting floor is left, and what
remains is the spline's fit of the cylinder's distance, which shrinks with h (measured in the
study: orders 0.6 to 2.9 between h = 40 and 2.45 mm; not a clean power, the narrow band's
coarse nodes beyond 4 h enter it too).

**Flat facets.** The tip stays on Φ = 0 (rigid contact), the desired helix lies on the true
cylinder of radius R (on the mesh's vertices), so at the tip p the radial error splits exactly
into

    d_true(p) = d_mesh(p) + (d_true(p) − d_mesh(p))
                 (a) the field vs the mesh   (b) the mesh vs the true cylinder

(d: signed distances, positive outside; d_mesh the mesh's exact distance, libigl). (b) is
geometry: the mesh lies between the cylinders of radii R cos(π/N) and R, so (b) ∈ [−s, 0] with
s = R (1 − cos(π/N)) the sagitta, reached at the middle of each facet; it does not depend on
the resolution. (a) is the fit: with h coarser than the facet width w = 2πR/N the spline cannot
see the facets (|a| ~ s); finer, it follows them, rounding each edge (a kink of the distance
whose normal turns by 2π/N) over about h: |a| ≈ c (2π/N) h at the edges, over a fraction
~ h/w of the path, so max |a| = O(h) and mean |a| = O(h²), self-similar in h/w with amplitude
s (measured on 64, 128 and 512 sections in the study).

References: the analytic distance to a regular prism (for libigl's), the sagitta identity,
the built-in paper_contact run (exact cylinder).
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

from hybrid_force.geometry.mesh_surface import MeshSurface
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

REPO = Path(__file__).resolve().parents[1]
RADIUS = 0.4  # [m] the paper's cylinder (eq. 26)
START = (0.4, 0.0, 10.0)  # the helix of eq. 25 at t = 0
OMEGA, RISE = 1.0, 0.1  # [rad/s], [m/rad] the helix's angular rate and rise (eq. 25)
F_D = 10.0  # [N]

pytestmark = pytest.mark.usefixtures("field_cache")  # tests/conftest.py


def sagitta(sections: int, radius: float = RADIUS) -> float:
    """s = R (1 − cos(π/N)) [m]: how far a face of an N-section cylinder dips below its
    vertices' circle, at its middle."""
    return radius * (1.0 - math.cos(math.pi / sections))


def facet_width(sections: int, radius: float = RADIUS) -> float:
    """w = 2πR/N [m], the facets' width (the chord, to O(N⁻³))."""
    return 2.0 * math.pi * radius / sections


def cylinder_mesh(sections: int, duration: float, margin: float, wedge: bool) -> trimesh.Trimesh:
    """The N-section cylinder of radius R about the z axis, vertices at the angles 2πk/N (as
    trimesh.creation.cylinder), covering the helix of a run of ``duration`` [s] from START
    with ``margin`` [m] beyond it along the axis.

    ``wedge``: only the pie slice (the axis, two radial faces and caps) whose outer faces are
    those of the cylinder over the helix's angles ± margin / R: the same facets where the tool
    runs, on a grid a fraction of the full cylinder's (a finer resolution within MAX_NODES).
    Its medial axis (between the outer face and the radial faces) is 0.18 m or more inside,
    so use it only where that is ≥ 10 h: a kink of the distance within a few h of the
    surface pollutes the interpolating spline there (measured: 2e-5 m at h = 0.04)."""
    z0, z1 = START[2] - margin, START[2] + RISE * OMEGA * duration + margin
    if not wedge:
        mesh = trimesh.creation.cylinder(radius=RADIUS, height=z1 - z0, sections=sections)
        mesh.apply_translation([0.0, 0.0, 0.5 * (z0 + z1)])
        return mesh
    step = 2.0 * math.pi / sections
    first = math.floor(-margin / RADIUS / step)
    last = math.ceil((OMEGA * duration + margin / RADIUS) / step)
    angles = step * np.arange(first, last + 1)
    m = len(angles)
    ring = RADIUS * np.column_stack([np.cos(angles), np.sin(angles)])
    vertices = np.vstack(
        [np.column_stack([ring, np.full(m, z)]) for z in (z0, z1)] + [[[0, 0, z0], [0, 0, z1]]]
    )
    b, t, cb, ct = 0, m, 2 * m, 2 * m + 1
    faces = []
    for i in range(m - 1):
        faces += [[b + i, b + i + 1, t + i + 1], [b + i, t + i + 1, t + i]]  # outer
        faces += [[cb, b + i + 1, b + i], [ct, t + i, t + i + 1]]  # caps
    faces += [[cb, b, t], [cb, t, ct], [cb, ct, t + m - 1], [cb, t + m - 1, b + m - 1]]
    mesh = trimesh.Trimesh(vertices, np.array(faces), process=True)
    mesh.fix_normals()
    assert mesh.is_watertight and mesh.volume > 0
    return mesh


def paper_contact_on(
    folder: Path, mesh_file: str, resolution: float, duration: float, facets: str
) -> Path:
    """scenarios/paper_contact.toml with its cylinder replaced by the mesh ``folder /
    mesh_file`` at ``resolution`` [m] with ``facets``, ``duration`` [s], started at the field's
    closest point to START (a mesh of few sections is up to its sagitta off the helix's
    start)."""
    surface = MeshSurface.from_file(folder / mesh_file, resolution=resolution, facets=facets)
    tip = surface.closest_point(np.array(START)).tolist()
    text = (REPO / "scenarios" / "paper_contact.toml").read_text()
    cylinder = (
        'type = "cylinder"\nradius = 0.4\ncenter = [0.0, 0.0, 0.0]\naxis = [0.0, 0.0, 1.0]\n'
        "inside = false          # the tool works outside the cylinder"
    )
    replaced = text.replace(
        cylinder,
        f'type = "mesh"\nfile = "{mesh_file}"\nresolution = {resolution}\nfacets = "{facets}"',
    )
    replaced = replaced.replace("tip = [0.4, 0.0, 7.0]", f"tip = {tip!r}")
    replaced = replaced.replace("duration = 20.0", f"duration = {duration}")
    assert replaced.count('type = "mesh"') == 1 and f"duration = {duration}" in replaced
    path = folder / f"{Path(mesh_file).stem}_{resolution:g}_{facets}.toml"
    path.write_text(replaced)
    return path


def prism_distance(points: np.ndarray, sections: int) -> np.ndarray:
    """The exact signed distance [m] (> 0 outside) of points (M, 3) to the infinite regular
    N-gon prism inscribed in the cylinder of radius R about z (vertices at 2πk/N): the
    distance to the nearest of the two edges' segments around each point's angle, in the
    xy plane; (M,). The reference for libigl's distance to the mesh away from its caps."""
    xy = points[:, :2]
    step = 2.0 * math.pi / sections
    k = np.floor(np.arctan2(xy[:, 1], xy[:, 0]) / step)
    best = np.full(len(xy), np.inf)
    for shift in (-1.0, 0.0, 1.0):  # the facet of the point's angle and its neighbours
        a0, a1 = (k + shift) * step, (k + shift + 1.0) * step
        p0 = RADIUS * np.column_stack([np.cos(a0), np.sin(a0)])
        p1 = RADIUS * np.column_stack([np.cos(a1), np.sin(a1)])
        edge = p1 - p0
        u = np.clip(np.sum((xy - p0) * edge, axis=1) / np.sum(edge * edge, axis=1), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(xy - p0 - u[:, None] * edge, axis=1))
    apothem = RADIUS * math.cos(math.pi / sections)
    centre = (k + 0.5) * step
    inside = np.hypot(xy[:, 0], xy[:, 1]) * np.cos(np.arctan2(xy[:, 1], xy[:, 0]) - centre)
    return np.where(inside < apothem, -best, best)


def settled_parts(result: Any, mesh: trimesh.Trimesh, since: float) -> dict[str, float]:
    """The settled errors of a run from ``since`` [s] on, split as in the module docstring:
    ``position`` max ‖p − p_d‖, ``radial`` max |d_true(p)|, ``fit_max`` / ``fit_mean`` max and
    mean |d_mesh(p)| (a), ``facet`` max |d_true(p) − d_mesh(p)| (b), ``force`` max |f − f_d|
    [N]; lengths [m]. ``d_mesh`` is libigl's exact distance of ``mesh`` at the tip."""
    import igl

    last = result.t >= since
    p = np.ascontiguousarray(result.p[last])
    d_mesh = np.asarray(igl.signed_distance(p, mesh.vertices, mesh.faces)[0])
    d_true = np.hypot(p[:, 0], p[:, 1]) - RADIUS
    return {
        "position": float(np.linalg.norm(p - result.p_d[last], axis=1).max()),
        "radial": float(np.abs(d_true).max()),
        "fit_max": float(np.abs(d_mesh).max()),
        "fit_mean": float(np.abs(d_mesh).mean()),
        "facet": float(np.abs(d_true - d_mesh).max()),
        "force": float(np.abs(result.f[last] - F_D).max()),
    }


def run_on(
    folder: Path,
    sections: int,
    resolution: float,
    duration: float,
    wedge: bool,
    facets: str = "flat",
) -> tuple[Any, trimesh.Trimesh]:
    """paper_contact on the N-section mesh (:func:`cylinder_mesh`, margin max(0.06 m, 10 h)
    so that caps and radial faces are out of the field's reach of the path): its result and
    the mesh."""
    margin = max(0.06, 10.0 * resolution)
    mesh = cylinder_mesh(sections, duration, margin, wedge)
    name = f"{'wedge' if wedge else 'cylinder'}{sections}_{resolution:g}.stl"
    mesh.export(folder / name)
    scenario = paper_contact_on(folder, name, resolution, duration, facets)
    return simulate(load_scenario(scenario)), mesh


#: the run's length [s] and the start of its settled window: the analytic run's error decays
#: by 10x every 0.25 s to 1e-9 m at 1.5 s (test below), far below the µm errors measured here
DURATION, SETTLED = 2.0, 1.5


def test_the_analytic_run_settles_to_round_off() -> None:
    exact = simulate(
        load_scenario(
            REPO / "scenarios" / "paper_contact.toml",
            {"initial.tip": list(START), "sim.duration": DURATION},
        )
    )
    last = exact.t >= SETTLED
    assert np.linalg.norm(exact.p - exact.p_d, axis=1)[last].max() <= 2e-9
    assert np.abs(exact.f[last] - F_D).max() <= 1e-9


def test_paper_contact_on_a_512_section_curved_mesh_converges_to_the_cylinder(
    tmp_path: Path,
) -> None:
    """The issue's target on the 512-section mesh with curved facets (the default): settled
    position error ≤ 1e-5 m and |f − f_d| ≤ 1e-3 N, and the error shrinks as h is refined:
    far below the faces' sagitta s (module docstring; measured 9.4e-7, 4.1e-7, 2.8e-7 m at
    h = 40, 20, 10 mm; the study goes on to 2.45 mm, 1.7e-8 m). The asserted overall order is
    0.5 (measured 0.89 from 40 to 10 mm). The force error stays at the rigid contact's
    round-off (~1e-10 N) throughout."""
    sections = 512
    s = sagitta(sections)
    errors = []
    for resolution in (0.04, 0.02, 0.01):
        result, mesh = run_on(tmp_path, sections, resolution, DURATION, False, "curved")
        parts = settled_parts(result, mesh, SETTLED)
        assert parts["position"] <= 1e-5, parts
        assert parts["force"] <= 1e-3, parts
        errors.append(parts["radial"])
    assert errors[0] > errors[1] > errors[2], errors
    assert errors[-1] <= s / 10
    assert math.log2(errors[0] / errors[2]) / 2 >= 0.5, errors


def test_paper_contact_on_a_512_section_flat_mesh(tmp_path: Path) -> None:
    """With flat facets, the issue's target on the 512-section mesh: settled position error
    ≤ 1e-5 m and |f − f_d| ≤ 1e-3 N; the faceting part (b) is the sagitta identity (libigl's
    distance checked against the prism's). At this h = 4 w the field cannot see the facets: (a)
    does not shrink with h here (the study: the same ≈ s from h = 40 mm to 5 mm)."""
    sections, resolution = 512, 0.02
    result, mesh = run_on(tmp_path, sections, resolution, DURATION, wedge=False)
    parts = settled_parts(result, mesh, SETTLED)
    assert parts["position"] <= 1e-5, parts
    assert parts["force"] <= 1e-3, parts
    # (b): libigl's distance at the tip is the prism's (to its float error, ~1e-16 m)
    last = result.t >= SETTLED
    tips = np.ascontiguousarray(result.p[last])
    import igl

    d_mesh = np.asarray(igl.signed_distance(tips, mesh.vertices, mesh.faces)[0])
    np.testing.assert_allclose(d_mesh, prism_distance(tips, sections), atol=1e-12)
    d_true = np.hypot(tips[:, 0], tips[:, 1]) - RADIUS
    s = sagitta(sections)
    # the mesh lies between the cylinders of radii R − s and R: (b) ∈ [−s, 0] ...
    assert np.all(d_true - d_mesh <= 1e-12) and np.all(d_true - d_mesh >= -s - 1e-12)
    # ... and reaches −s at the facets' middles: the tip passes within ω dt / 2 of each, where
    # (b) = −s + ρ φ² / 2 (φ the angle from the facet's middle)
    assert parts["facet"] >= s - RADIUS * (OMEGA * 1e-3 / 2) ** 2 / 2 - 1e-9, (parts, s)


def test_the_field_converges_to_the_mesh_at_the_tip(tmp_path: Path) -> None:
    """(a) shrinks as h is refined below the facet width: halving h from w/2 to w/8 on a
    64-section mesh (w = 39 mm: the regime h < w within the grid bound and seconds; (a) is
    self-similar in h/w, so 512 sections behave the same at h/8, the study). The asserted
    orders are the predicted ones (1 for the max, 2 for the mean, module docstring) less
    0.5: each log2 ratio must be nearer the predicted order than the next lower one."""
    sections = 64
    w = facet_width(sections)
    fits = []
    for fraction in (2, 4, 8):
        result, mesh = run_on(tmp_path, sections, w / fraction, 3.0, wedge=True)
        # the tip is on Φ = 0 from the start (rigid contact): (a) is the fit wherever it is,
        # so the whole run past the first 0.5 s counts (24 facets' edges, not the 5 the
        # settled window crosses)
        assert np.abs(result.phi[result.t >= 0.5]).max() <= 1e-9
        parts = settled_parts(result, mesh, 0.5)
        assert parts["facet"] <= sagitta(sections) + 1e-12
        fits.append((parts["fit_max"], parts["fit_mean"]))
    for (max0, mean0), (max1, mean1) in itertools.pairwise(fits):
        assert math.log2(max0 / max1) >= 1.0 - 0.5, fits
        assert math.log2(mean0 / mean1) >= 2.0 - 0.5, fits

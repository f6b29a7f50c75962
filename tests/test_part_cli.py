"""``hybrid-force part --check FILE``: its report against independent numbers (trimesh's own
counts and bounds, the exact sphere), and its refusals (exit status 2)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

from hybrid_force.cli import main

pytestmark = pytest.mark.usefixtures("field_cache")  # tests/conftest.py


def _number(text: str, pattern: str) -> float:
    found = re.search(pattern, text)
    assert found, (pattern, text)
    return float(found.group(1).replace(",", ""))


def test_part_check_reports_the_mesh_and_its_fit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=0.2)  # 5,120 faces
    mesh.apply_translation([0.1, -0.2, 0.3])
    path = tmp_path / "ball.ply"
    mesh.export(path)
    assert main(["part", "--check", str(path), "--resolution", "0.01"]) == 0
    out = capsys.readouterr().out
    assert f"faces: {len(mesh.faces):,} ({len(mesh.vertices):,} vertices), watertight" in out
    low, high = mesh.bounds
    box = re.search(r"bounding box \[m\]: \[(.*?)\] to \[(.*?)\]", out)
    assert box
    np.testing.assert_allclose([float(x) for x in box.group(1).split(",")], low, atol=1e-6)
    np.testing.assert_allclose([float(x) for x in box.group(2).split(",")], high, atol=1e-6)
    assert "resolution: 0.01 m" in out
    # the grid: the box padded by max(8 h, diagonal / 10) on each side, one node per h
    diagonal = float(np.linalg.norm(high - low))
    pad = max(0.08, diagonal / 10)
    expected = (high - low + 2 * pad) / 0.01 + 1  # nodes per axis, up to the rounding up
    grid = re.search(r"grid: (\d+) x (\d+) x (\d+) = ([0-9,]+) nodes", out)
    assert grid
    counts = np.array([int(x) for x in grid.groups()[:3]])
    assert np.all(counts >= expected - 1e-6) and np.all(counts <= expected + 1 + 1e-6), counts
    assert int(grid.group(4).replace(",", "")) == int(np.prod(counts))
    megabytes = _number(out, r"nodes, ([0-9.]+) MB")
    assert megabytes == pytest.approx(np.prod(counts + 2) * 8 / 1e6, rel=2e-3)
    # fit errors: the field smooths the facets, whose depth below the vertices' sphere is
    # at most rc² / (2R) (rc a face's circumradius)
    tri = mesh.vertices[mesh.faces]
    sides = [np.linalg.norm(tri[:, i] - tri[:, (i + 1) % 3], axis=1) for i in range(3)]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    depth = float(((sides[0] * sides[1] * sides[2] / (4 * area)) ** 2 / (2 * 0.2)).max())
    for what in ("vertices", "face centres"):
        assert _number(out, rf"{what} ([0-9.e-]+)") <= 2 * depth + 5e-5
    assert _number(out, r"points\) ([0-9.e-]+)") <= 2 * depth + 5e-5
    low_norm, high_norm = (float(x) for x in re.findall(r"band: ([0-9.]+) to ([0-9.]+)", out)[0])
    assert 0.98 <= low_norm <= high_norm <= 1.02
    assert "smallest concave radius of curvature: none" in out  # a sphere is convex
    assert _number(out, r"build time: ([0-9.]+) s") > 0
    cache = re.search(r"cache file: (\S+)", out)
    assert cache and Path(cache.group(1)).is_file()
    # a second check reads the field from the cache
    assert main(["part", "--check", str(path), "--resolution", "0.01"]) == 0
    assert "(read from the cache)" in capsys.readouterr().out


def test_part_check_default_resolution_scale_and_concave_radius(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # a torus in millimetres (R = 200, r = 50): scale 1e-3; its hole is concave, radius
    # R − r = 0.15 m along the ring on the inner equator (a lower estimate, as documented)
    mesh = trimesh.creation.torus(
        major_radius=200.0, minor_radius=50.0, major_sections=96, minor_sections=32
    )
    path = tmp_path / "ring.stl"
    mesh.export(path)
    assert main(["part", "--check", str(path), "--scale", "0.001"]) == 0
    out = capsys.readouterr().out
    assert "(default: twice the facets' size, clamped)" in out
    size = re.search(r"\(([0-9.]+) x ([0-9.]+) x ([0-9.]+)\)", out)
    assert size
    assert [float(x) for x in size.groups()] == pytest.approx([0.5, 0.5, 0.1], abs=2e-3)
    concave = _number(out, r"concave radius of curvature: ([0-9.]+) m")
    assert 0.6 * 0.15 <= concave <= 1.02 * 0.15


def test_part_check_refuses_bad_files_with_exit_status_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["part", "--check", str(tmp_path / "missing.stl")]) == 2
    assert "cannot read the file" in capsys.readouterr().err
    box = tmp_path / "box.stl"
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(box)
    assert main(["part", "--check", str(box), "--resolution", "0.0005"]) == 2
    err = capsys.readouterr().err
    assert "surface.resolution = 0.0005 m" in err and "above the bound" in err
    assert main(["part", "--check", str(box), "--scale", "-2"]) == 2
    assert "scale must be a finite number > 0" in capsys.readouterr().err
    assert main(["part"]) == 2  # --check is required


@pytest.mark.filterwarnings("ignore::hybrid_force.errors.ModelWarning")  # not watertight
def test_part_check_of_an_open_sheet_reports_its_open_edges_and_the_fit_away_from_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A flat square sheet (z = 0, 10 × 10 quads over 0.4 m): 40 open edges, trimesh's count
    of edges used by one face; Φ is not trusted within 8 h of them; away from them the field
    is the plane z = 0 (within 2 h of it, |Φ − |z|| below 1e-5 m, where over the whole band
    the border's jump makes it over 1 mm); no hollow is reported for the flat sheet."""
    x = np.linspace(-0.2, 0.2, 11)
    gx, gy = np.meshgrid(x, x, indexing="ij")
    vertices = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    faces = [
        f
        for i in range(10)
        for j in range(10)
        for a in [i * 11 + j]
        for f in ([a, a + 11, a + 1], [a + 1, a + 11, a + 12])
    ]
    mesh = trimesh.Trimesh(vertices, np.array(faces), process=False)
    path = tmp_path / "sheet.obj"
    mesh.export(path)
    assert main(["part", "--check", str(path), "--resolution", "0.01"]) == 0
    out = capsys.readouterr().out
    single = int((np.bincount(mesh.edges_unique_inverse) == 1).sum())
    assert single == 40
    assert f"open edges: {single:,}; Φ is not trusted within 0.08 m (8 grid spacings)" in out
    whole = _number(out, r"fit error max \|Φ − d\| \[m\]: .* points\) ([0-9.e+-]+)")
    away = _number(out, r"fit error away from the open edges \[m\]: .*band ([0-9.e+-]+)")
    assert away < 1e-5 and whole > 1e-3
    assert "smallest concave radius of curvature (away from the open edges): none" in out

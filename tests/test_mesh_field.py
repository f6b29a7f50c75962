"""The smooth field of a mesh part against exact surfaces, the mesh's own exact distance
(trimesh, independent of libigl which builds the field) and finite differences."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh
from conftest import point_segment_distances

from hybrid_force.errors import ModelWarning, SurfaceError
from hybrid_force.geometry.mesh_field import (
    MAX_NODES,
    _grid,
    build_field,
    default_resolution,
    load_field,
    read_mesh,
    rpy_matrix,
)
from hybrid_force.geometry.mesh_surface import MeshSurface

RADIUS = 0.3


pytestmark = pytest.mark.usefixtures("field_cache")  # tests/conftest.py


@pytest.fixture(scope="module")
def sphere_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("mesh") / "sphere.stl"
    mesh = trimesh.creation.icosphere(subdivisions=5, radius=RADIUS)  # 20,480 faces
    assert len(mesh.faces) == 20480
    mesh.export(path)
    return path


@pytest.fixture(scope="module")
def sphere(sphere_file: Path) -> MeshSurface:
    """The icosphere with curved facets (the default): Φ = 0 on the patches through its
    vertices, which lie on the true sphere."""
    return MeshSurface.from_file(sphere_file, resolution=0.0105, cache=False)


@pytest.fixture(scope="module")
def flat_sphere(sphere_file: Path) -> MeshSurface:
    """The icosphere with flat facets: Φ = 0 on its faces."""
    return MeshSurface.from_file(sphere_file, resolution=0.0105, facets="flat", cache=False)


def _near_surface(rng: np.random.Generator, count: int, band: float) -> tuple[np.ndarray, ...]:
    """Points within ``band`` of the sphere: (points, unit directions, radii)."""
    d = rng.normal(size=(count, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    r = RADIUS + rng.uniform(-band, band, count)
    return d * r[:, None], d, r


def _sagitta(part_file: Path) -> float:
    """Largest depth of a face's circumcentre below the true sphere: rc² / (2R) to first order."""
    mesh = trimesh.load(part_file)
    tri = mesh.vertices[mesh.faces]
    a = np.linalg.norm(tri[:, 1] - tri[:, 2], axis=1)
    b = np.linalg.norm(tri[:, 0] - tri[:, 2], axis=1)
    c = np.linalg.norm(tri[:, 0] - tri[:, 1], axis=1)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    rc = a * b * c / (4 * area)
    return float(RADIUS - np.sqrt(RADIUS**2 - rc.max() ** 2))


def test_flat_sphere_field_is_the_mesh_distance_within_a_tenth_of_a_millimetre(
    flat_sphere: MeshSurface, sphere_file: Path
) -> None:
    rng = np.random.default_rng(1)
    points, _, r = _near_surface(rng, 1500, 0.005)
    exact = -trimesh.proximity.signed_distance(trimesh.load(sphere_file), points)  # >0 outside
    phi = flat_sphere.field.values(points)
    assert np.abs(phi - exact).max() <= 1e-4
    # against the true sphere: the fit plus the mesh's own faceting (its inscribed faces)
    assert np.abs(phi - (r - RADIUS)).max() <= 1e-4 + _sagitta(sphere_file)


def test_curved_sphere_field_is_the_true_sphere_far_below_the_sagitta(
    sphere: MeshSurface, sphere_file: Path
) -> None:
    """The patches through the vertices are the sphere to the accuracy of the corner normals
    (angle-weighted face normals, off the radial by O(L²/R²) on the icosphere's uneven
    faces): measured 2.3e-6 m max within 5 mm, 0.3 µm mean near the surface, against the
    faces' sagitta of 8.9e-5 m."""
    rng = np.random.default_rng(1)
    points, _, r = _near_surface(rng, 1500, 0.005)
    error = np.abs(sphere.field.values(points) - (r - RADIUS))
    assert error.max() <= _sagitta(sphere_file) / 20
    near, _, r_near = _near_surface(rng, 1500, 1e-4)
    assert (
        np.abs(sphere.field.values(near) - (r_near - RADIUS)).mean() <= _sagitta(sphere_file) / 100
    )


@pytest.mark.parametrize("facets", ["flat", "curved"])
def test_sphere_field_normal_gradient_norm_and_smoothness(
    facets: str, sphere: MeshSurface, flat_sphere: MeshSurface
) -> None:
    surface = sphere if facets == "curved" else flat_sphere
    rng = np.random.default_rng(2)
    points, directions, _ = _near_surface(rng, 1500, 0.005)
    worst_angle = worst_turn = 0.0
    norms = []
    for p, n in zip(points, directions, strict=True):
        _, g, _ = surface.evaluate(p)
        norms.append(np.linalg.norm(g))
        worst_angle = max(worst_angle, math.degrees(math.acos(min(1.0, g @ n / norms[-1]))))
        tangent = np.cross(n, rng.normal(size=3))
        tangent /= np.linalg.norm(tangent)
        _, g2, _ = surface.evaluate(p + 1e-4 * tangent)  # 0.1 mm along the surface
        cos = g @ g2 / (np.linalg.norm(g) * np.linalg.norm(g2))
        worst_turn = max(worst_turn, math.degrees(math.acos(min(1.0, cos))))
    # the issue's targets; the curved facets' normal is the sphere's to ~0.03°, and turns by
    # the true 0.1 mm / 0.3 m = 0.0191° plus 0.0005° (measured)
    assert worst_angle <= (0.5 if facets == "flat" else 0.05)
    assert worst_turn <= (0.05 if facets == "flat" else 0.021)
    assert min(norms) >= 0.98 and max(norms) <= 1.02
    if facets == "curved":
        assert min(norms) >= 0.999 and max(norms) <= 1.001


def test_gradient_and_hessian_are_central_differences(sphere: MeshSurface) -> None:
    rng = np.random.default_rng(3)
    points, _, _ = _near_surface(rng, 20, 0.02)
    step = 1e-6
    for p in points:
        _, g, hess = sphere.evaluate(p)
        for k in range(3):
            e = np.zeros(3)
            e[k] = step
            plus, g_plus, _ = sphere.evaluate(p + e)
            minus, g_minus, _ = sphere.evaluate(p - e)
            assert (plus - minus) / (2 * step) == pytest.approx(g[k], abs=1e-8)
            np.testing.assert_allclose((g_plus - g_minus) / (2 * step), hess[:, k], atol=1e-6)
        np.testing.assert_array_equal(hess, hess.T)


def test_field_interpolates_its_samples_and_is_continuous_out_of_its_box(
    flat_sphere: MeshSurface,
) -> None:
    import igl

    sphere = flat_sphere
    field = sphere.field
    rng = np.random.default_rng(4)
    idx = rng.integers(0, np.array(field.shape), size=(20000, 3))
    nodes = field.origin + field.spacing * idx
    # the nodes near the surface hold exact distances (the band); the field goes through them
    nodes = nodes[np.abs(np.linalg.norm(nodes, axis=1) - RADIUS) < 2 * field.spacing][:50]
    assert len(nodes) == 50
    part = sphere.part
    exact, *_ = igl.signed_distance(nodes, part.vertices, part.faces)
    np.testing.assert_allclose(field.values(nodes), exact, atol=1e-12)
    # across the box's face: the value and the gradient along the outward axis are continuous
    top = field.origin + field.spacing * (np.array(field.shape) - 1)
    p = np.array([top[0], 0.01, -0.02])
    inside, g_in, _ = field.evaluate(p - np.array([1e-9, 0, 0]))
    outside, g_out, _ = field.evaluate(p + np.array([1e-9, 0, 0]))
    assert outside == pytest.approx(inside, abs=1e-8)
    assert g_out[0] == pytest.approx(g_in[0], abs=1e-6)
    far, _, _ = field.evaluate(p + np.array([1.0, 0, 0]))
    assert far == pytest.approx(inside + g_in[0] * 1.0, abs=1e-8)


@pytest.mark.parametrize("facets", ["flat", "curved"])
def test_cylinder_mesh_matches_the_exact_cylinder(facets: str, tmp_path: Path) -> None:
    """Flat facets lie up to the sagitta inside the cylinder; the curved patches are the
    cylinder itself (its corner normals are radial by symmetry, its caps kept flat by the
    crease), so the field's own fit error alone remains."""
    radius, sections = 0.4, 512
    mesh = trimesh.creation.cylinder(radius=radius, height=0.2, sections=sections)
    path = tmp_path / "cyl.obj"
    mesh.export(path)
    surface = MeshSurface.from_file(path, facets=facets, cache=False)
    rng = np.random.default_rng(5)
    angle = rng.uniform(0, 2 * np.pi, 500)
    rho = radius + rng.uniform(-0.005, 0.005, 500)
    points = np.column_stack(
        [rho * np.cos(angle), rho * np.sin(angle), rng.uniform(-0.05, 0.05, 500)]
    )
    sagitta = radius * (1 - math.cos(math.pi / sections))  # faces inside the vertices' circle
    if facets == "curved":
        sagitta = 0.0
    phi = surface.field.values(points)
    assert np.abs(phi - (rho - radius)).max() <= sagitta + 2e-5
    for p, a in zip(points[:40], angle[:40], strict=True):
        n = surface.normal(p)
        assert n @ np.array([math.cos(a), math.sin(a), 0.0]) >= math.cos(math.radians(0.1))
        foot = surface.closest_point(p)
        assert abs(surface.phi(foot)) <= 1e-12
        assert math.hypot(foot[0], foot[1]) == pytest.approx(radius, abs=sagitta + 2e-5)


def test_inside_flips_the_sign_and_placement_moves_the_part(sphere_file: Path) -> None:
    rpy, position = (0.3, -0.2, 1.1), (0.5, -0.1, 0.2)
    placed = MeshSurface.from_file(
        sphere_file, position=position, rpy=rpy, scale=0.5, inside=True, resolution=0.01
    )
    centre = np.array(position)
    rot = rpy_matrix(rpy)
    # free inside: Φ > 0 there; 0.1 m from the centre (away from its medial point) Φ = 0.05 m
    probe = centre + rot @ np.array([0.0, 0.1, 0.0])
    assert placed.phi(probe) == pytest.approx(0.5 * RADIUS - 0.1, abs=2e-4)
    assert placed.phi(centre + np.array([0.3, 0, 0])) < 0
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-15)
    # Rz(y) Ry(p) Rx(r), each written out
    r, p, y = rpy
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    np.testing.assert_allclose(rot, rz @ ry @ rx, atol=1e-15)


def test_cache_reload_is_bit_identical_and_a_corrupt_cache_is_rebuilt(sphere_file: Path) -> None:
    part = read_mesh(sphere_file)
    first = build_field(part, 0.03)
    assert first.cache_file and Path(first.cache_file).is_file()
    again = build_field(part, 0.03)
    np.testing.assert_array_equal(again.coefficients, first.coefficients)
    assert again.build_seconds == 0.0  # read, not built
    Path(first.cache_file).write_bytes(b"not a field")
    assert load_field(first.cache_file) is None
    rebuilt = build_field(part, 0.03)
    np.testing.assert_array_equal(rebuilt.coefficients, first.coefficients)
    other = build_field(part, 0.031)  # other settings: another file
    assert other.cache_file != first.cache_file


def test_default_resolution_follows_the_facets(sphere_file: Path, tmp_path: Path) -> None:
    part = read_mesh(sphere_file)
    shortest = np.median(part.shortest_edges())
    assert default_resolution(part) == pytest.approx(2 * shortest)
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))  # 12 faces: h bounded by diagonal / 16
    box.export(tmp_path / "box.ply")
    coarse = read_mesh(tmp_path / "box.ply")
    assert default_resolution(coarse) == pytest.approx(math.sqrt(3) / 16)


def test_bad_mesh_files_are_refused_naming_key_and_file(tmp_path: Path) -> None:
    with pytest.raises(SurfaceError, match=r"surface\.file = '.*missing\.stl'.*read"):
        read_mesh(tmp_path / "missing.stl")
    garbage = tmp_path / "garbage.stl"
    garbage.write_bytes(b"\x00\x01binary garbage" * 7)
    with pytest.raises(SurfaceError, match=r"surface\.file = '.*garbage\.stl'"):
        read_mesh(garbage)
    empty = tmp_path / "empty.obj"
    empty.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(SurfaceError, match="no triangle faces"):
        read_mesh(empty)
    nan = tmp_path / "nan.obj"
    nan.write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(SurfaceError, match=r"non-finite|no triangle"):
        read_mesh(nan)
    other = tmp_path / "part.step"
    other.write_text("ISO-10303-21;")
    with pytest.raises(SurfaceError, match=r"valid: \.stl, \.obj, \.ply"):
        read_mesh(other)
    # one face wound against its neighbours: its three edges are traversed twice alike
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    faces = sphere.faces.copy()
    faces[5] = faces[5, ::-1]
    flipped = tmp_path / "flipped.obj"
    trimesh.Trimesh(sphere.vertices, faces, process=False).export(flipped)
    with pytest.raises(SurfaceError, match=r"flipped\.obj.*not consistently wound: 3 edges.*face"):
        read_mesh(flipped)
    box = tmp_path / "box.stl"
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(box)
    with pytest.raises(SurfaceError, match="scale must be"):
        read_mesh(box, scale=-1.0)
    with pytest.raises(SurfaceError, match=r"1e-6 to 1e3 m"):
        read_mesh(box, scale=1e6)


def test_bad_facet_settings_are_refused_naming_the_key(sphere_file: Path) -> None:
    part = read_mesh(sphere_file)
    with pytest.raises(SurfaceError, match=r"surface\.facets: must be one of curved, flat"):
        build_field(part, 0.05, facets="round", cache=False)
    for bad in (-1.0, 181.0, float("nan"), "30", True):
        with pytest.raises(SurfaceError, match=r"surface\.crease_angle: must be a number in"):
            build_field(part, 0.05, crease_angle=bad, cache=False)  # type: ignore[arg-type]


def test_a_grid_above_the_memory_bound_is_refused_with_the_finest_valid_spacing(
    tmp_path: Path,
) -> None:
    box = tmp_path / "box.stl"
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(box)
    part = read_mesh(box)
    with pytest.raises(SurfaceError, match=r"surface\.resolution = 0\.001 m") as info:
        build_field(part, 0.001, cache=False)
    finest = float(str(info.value).rsplit(">= ", 1)[1].split(" m")[0])
    assert f"{MAX_NODES:,}" in str(info.value)
    _grid(part, finest * 1.05, "surface.resolution")  # the suggestion, rounded up, is accepted
    with pytest.raises(SurfaceError):
        _grid(part, finest * 0.95, "surface.resolution")
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(SurfaceError, match="finite number > 0"):
            build_field(part, bad, cache=False)


def test_open_mesh_loads_with_a_warning_about_the_sign(tmp_path: Path) -> None:
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    mesh.update_faces(np.arange(len(mesh.faces)) != 0)  # one face removed: a hole
    path = tmp_path / "open.stl"
    mesh.export(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        surface = MeshSurface.from_file(path, resolution=0.02, cache=False)
    messages = [str(w.message) for w in caught if issubclass(w.category, ModelWarning)]
    assert any("not watertight" in m and "near the surface" in m for m in messages)
    assert surface.phi(np.array([0.0, 0.0, 0.25])) > 0  # outside, near the surface


def _sphere(folder: Path) -> Path:
    path = folder / "small_sphere.stl"
    trimesh.creation.icosphere(subdivisions=3, radius=0.1).export(path)
    return path


def test_concave_radius_of_a_torus_hole(tmp_path: Path) -> None:
    # a torus (R = 0.2, r = 0.05): on its inner equator, the curvature across the tube is
    # convex (1/r) and along the ring concave, of radius R − r = 0.15 m
    mesh = trimesh.creation.torus(
        major_radius=0.2, minor_radius=0.05, major_sections=128, minor_sections=48
    )
    path = tmp_path / "torus.stl"
    mesh.export(path)
    surface = MeshSurface.from_file(path, cache=False)  # h = 2 x the facets
    # a lower estimate: the fit's ripple at the vertices lowers it (by 8 % here; 25 % with
    # flat facets)
    assert 0.85 * 0.15 <= surface.smallest_concave_radius() <= 1.02 * 0.15
    flat = MeshSurface.from_file(path, facets="flat", cache=False)
    assert 0.7 * 0.15 <= flat.smallest_concave_radius() <= 1.02 * 0.15
    convex = MeshSurface.from_file(_sphere(path.parent), cache=False)
    assert convex.smallest_concave_radius() == math.inf


def test_a_ball_larger_than_a_mesh_tube_warns_where_and_by_how_much(tmp_path: Path) -> None:
    """The inside of a torus's tube (``inside = true``; ring radius 0.2 m, tube radius
    a = 0.05 m) is concave across the tube everywhere, of radius a: a ball of r = 0.06 m cannot
    reach its wall. The warning names the radius (a lower estimate of a, as the torus hole's
    above), a point of the tube's wall in the world (the part placed by ``position``) and the
    excess r − radius."""
    from hybrid_force.errors import RunWarning
    from hybrid_force.geometry.offset import tool_surfaces

    ring, a, r = 0.2, 0.05, 0.06
    mesh = trimesh.creation.torus(
        major_radius=ring, minor_radius=a, major_sections=128, minor_sections=48
    )
    path = tmp_path / "torus.stl"
    mesh.export(path)
    centre = np.array([0.4, -0.1, 0.3])
    tube = MeshSurface.from_file(path, position=(0.4, -0.1, 0.3), inside=True, cache=False)
    smallest, where = tube.concave_radius()
    assert where is not None
    assert 0.7 * a <= smallest <= 1.02 * a
    # on the tube's wall: at the distance a (to the vertices' polygon: 2 % here) from its
    # centre circle, of radius 0.2 m about the z axis through the part's position
    local = where - centre
    wall = math.hypot(math.hypot(local[0], local[1]) - ring, local[2])
    stl = 4 * float(np.finfo(np.float32).eps) * (ring + a)  # an STL's vertices are float32
    assert a * math.cos(math.pi / 48) - stl <= wall <= a + stl
    # with the tool centre's path, the warning also gives its nearest approach to that point
    # and its time (a circle along the tube's centre line, at 1 rad/s: the gap by hand)
    times = np.linspace(0.0, 6.0, 601)
    circle = centre + ring * np.column_stack([np.cos(times), np.sin(times), 0 * times])
    gaps = np.linalg.norm(circle - where, axis=1)
    j = int(np.argmin(gaps))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tool_surfaces([tube], r, along=(times, circle))
    (warning,) = [w for w in caught if issubclass(w.category, RunWarning)]
    message = str(warning.message)
    assert f"tool.radius = {r:g} m exceeds the smallest concave radius" in message
    assert f"{smallest:.6g} m at {np.round(where, 6).tolist()} m" in message
    assert f"by {r - smallest:.3g} m" in message
    assert (
        f"(the tool centre's path passes {gaps[j]:.3g} m from it, nearest at t = {times[j]:.4g} s)"
        in message
    )
    assert a * math.cos(math.pi / 48) - 0.01 <= gaps[j] <= a + 0.01
    # a ball that fits: no warning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tool_surfaces([tube], 0.5 * smallest)
    assert not [w for w in caught if issubclass(w.category, RunWarning)]


def test_orientation_terms_match_the_hessian_difference(sphere: MeshSurface) -> None:
    """MeshSurface.orientation_terms (one compiled call) against its definition through the
    checked methods it replaces in the tool's orientation: ∇Φ, ∇²Φ at p (the same bits) and
    (∇²Φ(p + δṗ) − ∇²Φ(p − δṗ)) / 2δ · ṗ, δ = step/‖ṗ‖ (to round-off)."""
    rng = np.random.default_rng(5)
    step = 1e-4
    for _ in range(20):
        d = rng.normal(size=3)
        p = d / np.linalg.norm(d) * 0.3
        sample = np.array([p, rng.normal(size=3) * 0.2, rng.normal(size=3)])
        terms = sphere.orientation_terms(sample, step)
        assert terms is not None
        g, H, third = terms
        _, g0, H0 = sphere.evaluate(p)
        assert np.array_equal(g, g0) and np.array_equal(H, H0)
        pd = sample[1]
        delta = step / np.linalg.norm(pd)
        difference = (sphere.hessian(p + delta * pd) - sphere.hessian(p - delta * pd)) / (2 * delta)
        np.testing.assert_allclose(third, difference @ pd, rtol=1e-9, atol=1e-12)
    still = np.array([[0.3, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    terms = sphere.orientation_terms(still, step)
    assert terms is not None and not terms[2].any()  # at rest: no rate of ∇²Φ
    assert sphere.orientation_terms(np.full((3, 3), np.nan), step) is None
    assert sphere.orientation_terms([[0.3, 0.0, 0.0]] * 3, step) is None  # type: ignore[arg-type]


def _sine_sheet(folder: Path, n: int = 40, half: float = 0.2, amplitude: float = 0.02) -> Path:
    """An open sheet z = A sin(k x), k = 10 /m, over [−half, half]² as an n × n grid of
    quads (two faces each, their normals along +z): its boundary is 4 n edges; its curvature
    across the waves is z'' / (1 + z'²)^(3/2) = −A k² sin(kx) / (1 + (A k cos kx)²)^(3/2),
    concave seen from +z where sin(kx) < 0, of smallest radius 1 / (A k²) = 0.5 m at the
    valley's bottom x = −π / (2k) = −0.157 m."""
    x = np.linspace(-half, half, n + 1)
    gx, gy = np.meshgrid(x, x, indexing="ij")
    vertices = np.column_stack([gx.ravel(), gy.ravel(), amplitude * np.sin(10.0 * gx.ravel())])
    faces = []
    for i in range(n):
        for j in range(n):
            a = i * (n + 1) + j
            faces += [[a, a + n + 1, a + 1], [a + 1, a + n + 1, a + n + 2]]
    path = folder / "sheet.stl"
    trimesh.Trimesh(vertices, np.array(faces), process=False).export(path)
    return path


def test_open_edges_are_the_boundary_and_the_fit_is_trusted_away_from_them(
    tmp_path: Path,
) -> None:
    """An open sheet: its open edges are its boundary (4 n edges, every end on the square's
    border); a closed sphere has none. Away from the open edges (8 h) the field is the sheet
    (|Φ| at its vertices below 1e-4 m, the level of a closed part) while near them it is not;
    the smallest concave radius, found away from the edges, is the valley's 1/(A k²) to 10 %
    (the border's fit jump, a few h across, would otherwise give a spurious hollow there)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        sheet = MeshSurface.from_file(_sine_sheet(tmp_path), resolution=0.01, cache=False)
    edges = sheet.part.open_edges
    assert edges.shape == (4 * 40, 2)
    ends = sheet.part.vertices[edges.ravel()]
    assert np.all(np.isclose(np.abs(ends[:, :2]).max(axis=1), 0.2, atol=1e-7))
    assert len(MeshSurface.from_file(_sphere(tmp_path), cache=False).part.open_edges) == 0
    assert sheet.untrusted_width == pytest.approx(8 * 0.01)
    vertices = sheet.part.vertices
    far = sheet.open_edge_distance(vertices) >= sheet.untrusted_width
    a, b = vertices[edges[:, 0]], vertices[edges[:, 1]]
    by_hand = point_segment_distances(vertices, a, b)
    np.testing.assert_allclose(sheet.open_edge_distance(vertices), by_hand, atol=1e-12)
    error = np.abs(sheet.field.values(vertices))
    assert error[far].max() < 1e-4
    assert error[~far].max() > 10 * error[far].max()
    smallest, where = sheet.concave_radius()
    assert where is not None
    assert sheet.open_edge_distance(where[None, :])[0] >= sheet.untrusted_width - 1e-6
    assert 0.9 / (0.02 * 10.0**2) <= smallest <= 1.1 / (0.02 * 10.0**2)
    assert math.sin(10.0 * where[0]) < -0.9  # in the valley

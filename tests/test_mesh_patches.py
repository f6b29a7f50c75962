"""The curved patches through a mesh's vertices (hybrid_force.geometry.mesh_patches) against
the exact surfaces the meshes sample: a cylinder (a circle's arc per face), a sphere, a cube
(creases everywhere), and libigl's exact distance to the faces."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from hybrid_force.geometry.mesh_patches import corner_normals, curved_patches

RADIUS = 0.4


def _cylinder(sections: int) -> trimesh.Trimesh:
    return trimesh.creation.cylinder(radius=RADIUS, height=0.6, sections=sections)


def _side_faces(mesh: trimesh.Trimesh) -> np.ndarray:
    return np.nonzero(np.abs(mesh.face_normals[:, 2]) < 1e-9)[0]


def test_corner_normals_of_a_prism_are_radial_and_its_caps_stay_flat() -> None:
    mesh = _cylinder(24)
    normals, face_normals, smooth = corner_normals(mesh.vertices, mesh.faces, 30.0)
    # every vertex of trimesh's prism but the caps' centres is on a rim (a crease)
    centre = np.hypot(mesh.vertices[:, 0], mesh.vertices[:, 1]) < 1e-12
    np.testing.assert_array_equal(smooth, centre[mesh.faces])
    side = _side_faces(mesh)
    corners = mesh.vertices[mesh.faces[side]]  # (S, 3, 3)
    radial = corners.copy()
    radial[..., 2] = 0.0
    radial /= np.linalg.norm(radial, axis=2)[..., None]
    # a side vertex's faces: its two side neighbours' triangles, 90° of angle on either side
    np.testing.assert_allclose(normals[side], radial, atol=1e-12)
    caps = np.setdiff1d(np.arange(len(mesh.faces)), side)
    np.testing.assert_allclose(normals[caps], np.repeat(face_normals[caps, None], 3, 1), atol=1e-12)


@pytest.mark.parametrize("sections", [16, 64, 512])
def test_cylinder_patches_are_its_arcs(sections: int) -> None:
    """On a side face the patch's height is the parabola 4 c x (1 − x) across the facet, x
    the fraction of its width w; c = w tan(φ)/4 (φ = π/N, the corner normals' tilt) is the
    arc's sagitta s to s φ²/4, and the parabola is the arc to (w/2)⁴ / (8 R³): both R φ⁴/8.
    The caps' patches are flat."""
    mesh = _cylinder(sections)
    patches = curved_patches(mesh.vertices, mesh.faces, 30.0)
    side = _side_faces(mesh)
    rng = np.random.default_rng(7)
    face = rng.choice(side, 400)
    bary = rng.dirichlet(np.ones(3), 400)
    points = patches.points(face, bary)
    phi = math.pi / sections
    rho = np.hypot(points[:, 0], points[:, 1])
    assert np.abs(rho - RADIUS).max() <= RADIUS * phi**4 / 4 + 1e-15
    # the flat faces' own distance to the circle is the sagitta, 4e5 times more at N = 512
    flat = np.einsum("mk,mkj->mj", bary, mesh.vertices[mesh.faces[face]])
    sagitta = RADIUS * (1 - math.cos(phi))
    assert np.abs(np.hypot(flat[:, 0], flat[:, 1]) - RADIUS).max() >= 0.5 * sagitta
    heights = np.linalg.norm(points - flat, axis=1)
    assert heights.max() <= patches.largest
    caps = np.setdiff1d(np.arange(len(mesh.faces)), side)
    np.testing.assert_array_equal(patches.edges[caps], 0.0)


def test_the_patches_distance_is_the_cylinder_distance_to_second_order() -> None:
    """Φ from libigl's feet on the faces against the cylinder's |p| − R: off by O(d² φ² / R)
    plus the patches' own R φ⁴/8 (the module docstring), where d − h, the first-order term,
    is off by up to |d| φ²/2."""
    import igl

    sections = 128
    mesh = _cylinder(sections)
    patches = curved_patches(mesh.vertices, mesh.faces, 30.0)
    rng = np.random.default_rng(8)
    theta = rng.uniform(0, 2 * math.pi, 3000)
    offset = rng.uniform(-0.01, 0.01, 3000)
    rho = RADIUS + offset
    z = rng.uniform(-0.2, 0.2, 3000)
    points = np.column_stack([rho * np.cos(theta), rho * np.sin(theta), z])
    d, face, foot, _ = igl.signed_distance(points, mesh.vertices, mesh.faces)
    face = np.asarray(face, dtype=np.int64)
    phi_part = patches.signed_distance(face, np.asarray(foot), points, np.asarray(d))
    phi = math.pi / sections
    bound = offset**2 * phi**2 / RADIUS + RADIUS * phi**4 / 4
    assert np.all(np.abs(phi_part - offset) <= bound)
    # the first-order term alone reaches a sizeable part of |d| φ²/2
    height = np.linalg.norm(patches.points(face, patches.barycentric(face, foot)) - foot, axis=1)
    first = np.abs(np.asarray(d) - height - offset)
    assert first.max() >= 10 * np.abs(phi_part - offset).max()


def test_a_box_edge_keeps_its_exact_distance() -> None:
    """Outside a box's edge (a crease) the distance is to the edge itself; the projection on
    a face normal would shorten it by the cosine of the angle."""
    import igl

    half = 0.1
    box = trimesh.creation.box(extents=(2 * half, 2 * half, 2 * half))
    patches = curved_patches(box.vertices, box.faces, 30.0)
    assert not patches.smooth.any()
    rng = np.random.default_rng(10)
    angle = rng.uniform(0.05, math.pi / 2 - 0.05, 500)  # round the edge x = y = half
    r = rng.uniform(1e-4, 0.05, 500)
    points = np.column_stack(
        [half + r * np.cos(angle), half + r * np.sin(angle), rng.uniform(-0.08, 0.08, 500)]
    )
    d, face, foot, _ = igl.signed_distance(points, box.vertices, box.faces)
    face = np.asarray(face, dtype=np.int64)
    np.testing.assert_allclose(
        patches.signed_distance(face, np.asarray(foot), points, np.asarray(d)), r, atol=1e-12
    )


def test_sphere_patches_are_far_closer_to_the_sphere_than_its_faces() -> None:
    radius = 0.3
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    patches = curved_patches(mesh.vertices, mesh.faces, 30.0)
    rng = np.random.default_rng(9)
    face = rng.integers(0, len(mesh.faces), 2000)
    bary = rng.dirichlet(np.ones(3), 2000)
    flat = np.einsum("mk,mkj->mj", bary, mesh.vertices[mesh.faces[face]])
    curved = patches.points(face, bary)
    flat_error = np.abs(np.linalg.norm(flat, axis=1) - radius).max()
    curved_error = np.abs(np.linalg.norm(curved, axis=1) - radius).max()
    assert curved_error <= flat_error / 10, (curved_error, flat_error)
    # the patches meet the vertices: zero height at the corners
    corners = patches.points(
        np.arange(len(mesh.faces)), np.tile(np.eye(3)[0], (len(mesh.faces), 1))
    )
    np.testing.assert_allclose(corners, mesh.vertices[mesh.faces[:, 0]], atol=1e-15)


def test_neighbouring_patches_meet_on_their_shared_edges() -> None:
    """The two faces of an edge give it heights that agree to second order in the faces'
    turn θ; measured along their own normals, the two curves part by at most h θ."""
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    patches = curved_patches(mesh.vertices, mesh.faces, 30.0)
    for (f, g), turn in zip(mesh.face_adjacency, mesh.face_adjacency_angles, strict=True):
        shared = np.intersect1d(mesh.faces[f], mesh.faces[g])
        points, heights = [], []
        for face in (f, g):
            bary = np.array([0.5 if v in shared else 0.0 for v in mesh.faces[face]])
            flat = bary @ mesh.vertices[mesh.faces[face]]
            points.append(patches.points(np.array([face]), bary[None])[0])
            heights.append(float(np.linalg.norm(points[-1] - flat)))
        assert heights[0] == pytest.approx(heights[1], rel=turn**2)
        assert np.linalg.norm(points[0] - points[1]) <= max(heights) * turn * 1.01


def test_smooth_edges_are_the_faces_within_the_crease_angle() -> None:
    mesh = _cylinder(24)
    patches = curved_patches(mesh.vertices, mesh.faces, 30.0)
    tri = mesh.vertices[mesh.faces]
    nxt = np.roll(tri, -1, axis=1)
    on_circle = (np.abs(np.hypot(tri[..., 0], tri[..., 1]) - RADIUS) < 1e-12) & (
        np.abs(np.hypot(nxt[..., 0], nxt[..., 1]) - RADIUS) < 1e-12
    )
    rim = on_circle & (np.abs(tri[..., 2] - nxt[..., 2]) < 1e-12)  # edge k → k+1 on a rim
    assert rim.sum() == 2 * 2 * 24  # each rim edge seen from its side face and its cap face
    np.testing.assert_array_equal(patches.smooth_edges, ~rim)
    side = np.abs(patches.normals[:, 2]) < 1e-9
    open_part = trimesh.Trimesh(mesh.vertices, mesh.faces[side], process=False)  # no caps
    open_edges = curved_patches(open_part.vertices, open_part.faces, 30.0).smooth_edges
    np.testing.assert_array_equal(open_edges, ~rim[side])  # an open rim is a crease too


def test_a_cube_keeps_its_edges_and_the_crease_angle_acts() -> None:
    cube = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    np.testing.assert_array_equal(curved_patches(cube.vertices, cube.faces, 30.0).edges, 0.0)
    # above 90° the faces at an edge are averaged: the cube bulges (its corners stay put)
    bent = curved_patches(cube.vertices, cube.faces, 100.0)
    assert bent.largest > 0.01

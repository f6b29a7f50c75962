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
    normals, face_normals = corner_normals(mesh.vertices, mesh.faces, 30.0)
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


def test_distance_less_the_height_is_the_cylinder_distance_to_first_order() -> None:
    """d − h(foot), d libigl's exact distance to the faces, against the cylinder's |p| − R:
    off by at most |d| φ² / 2 with φ = π/N the facets' half-turn (the module docstring)."""
    import igl

    sections = 128
    mesh = _cylinder(sections)
    patches = curved_patches(mesh.vertices, mesh.faces, 30.0)
    rng = np.random.default_rng(8)
    theta = rng.uniform(0, 2 * math.pi, 3000)
    offset = rng.uniform(-0.01, 0.01, 3000)
    rho = RADIUS + offset
    points = np.column_stack(
        [rho * np.cos(theta), rho * np.sin(theta), rng.uniform(-0.2, 0.2, 3000)]
    )
    d, face, foot, _ = igl.signed_distance(points, mesh.vertices, mesh.faces)
    curved = np.asarray(d) - patches.height(np.asarray(face, dtype=np.int64), np.asarray(foot))
    phi = math.pi / sections
    # plus the patch's own R φ⁴/8 (above), at the surface
    bound = np.abs(offset) * phi**2 / 2 * 1.05 + RADIUS * phi**4 / 4
    assert np.all(np.abs(curved - offset) <= bound)
    # the flat faces are up to the sagitta off
    assert np.abs(np.asarray(d) - offset).max() >= 0.9 * RADIUS * (1 - math.cos(phi))


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


def test_a_cube_keeps_its_edges_and_the_crease_angle_acts() -> None:
    cube = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    np.testing.assert_array_equal(curved_patches(cube.vertices, cube.faces, 30.0).edges, 0.0)
    # above 90° the faces at an edge are averaged: the cube bulges (its corners stay put)
    bent = curved_patches(cube.vertices, cube.faces, 100.0)
    assert bent.largest > 0.01

"""Curved patches through a mesh's vertices: the smooth part its facets were cut from.

A CAD export or a scan samples a smooth surface at its vertices and joins them by flat
triangles, whose chords lie up to the sagitta s off it (a cylinder of N sections: s = R(1 − cos
π/N), 7.5 µm at R = 0.4 m, N = 512). A distance field of the facets converges to the facets, not
to the part. Here each face carries a height field over its plane that bends it back towards the
surface its vertex normals describe:

    h(b) = 4 Σ_{edges ij} c_ij b_i b_j,    c_ij = L_ij (σ_i + σ_j) / 8,

b the barycentric coordinates of the foot point, L_ij the edge's length and σ_i = −(m_i · e)/(m_i
· n_f) the slope along e = (p_j − p_i)/L_ij of the plane normal to the corner normal m_i, seen
from the face plane (normal n_f); σ_j likewise along −e. On each edge h is the parabola whose
mean end slope is that of the two corner planes, so two faces sharing an edge agree on it to
second order, and on a circle of radius R through the vertices it is the arc to O(L⁴/R³): 1e-10
m on the cylinder above. It is the height part of Vlachos et al.'s PN triangles (2001) reduced
to a quadratic, as in Nagata's patch (2005); a departure from both: only the height along n_f is
used, the patch is never tessellated.

The corner normal m_i of face f at vertex i: the angle-weighted mean (Thürmer & Wüthrich 1998)
of the normals of the faces at i whose normal is within ``crease_angle`` of n_f. A sharp edge
(a cylinder's rim, a box's edges) is kept sharp: its faces do not bend towards each other.

The signed distance to the curved part is taken as d − h(foot), d the distance to the facets:
the first-order term of the distance to a surface tilted by at most the facets' turn φ from
them, off by at most |d| φ²/2 (2e-8 m at 1 mm from the 512-section cylinder).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["CurvedPatches", "corner_normals", "curved_patches"]


@dataclass(frozen=True, eq=False)
class CurvedPatches:
    """Each face's height coefficients ``edges`` (F, 3) [m] (c of edges 01, 12, 20) and its
    unit normal ``normals`` (F, 3), for the mesh ``vertices`` (V, 3) [m], ``faces`` (F, 3)."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    edges: np.ndarray

    @property
    def largest(self) -> float:
        """The largest height a patch can reach [m] (|h| ≤ Σ|c_ij|)."""
        return float(np.abs(self.edges).sum(axis=1).max()) if len(self.edges) else 0.0

    def barycentric(self, face: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Barycentric coordinates (m, 3) of ``points`` (m, 3) [m] projected on the planes of
        the faces with indices ``face`` (m,)."""
        tri = self.vertices[self.faces[face]]
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        w = points - tri[:, 0]
        d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
        w1, w2 = (w * e1).sum(1), (w * e2).sum(1)
        det = d11 * d22 - d12 * d12
        b1 = (d22 * w1 - d12 * w2) / det
        b2 = (d11 * w2 - d12 * w1) / det
        return np.column_stack([1.0 - b1 - b2, b1, b2])

    def height(self, face: np.ndarray, points: np.ndarray) -> np.ndarray:
        """h (m,) [m] of the patches of ``face`` (m,) at the feet ``points`` (m, 3) [m] on them,
        along each face's normal (> 0: the patch lies on the side the normal points to)."""
        if len(face) == 0:
            return np.zeros(0)
        return self._height(face, np.clip(self.barycentric(face, points), 0.0, 1.0))

    def _height(self, face: np.ndarray, b: np.ndarray) -> np.ndarray:
        """h = 4 Σ c_ij b_i b_j (m,) [m] at barycentric coordinates b (m, 3) of ``face``."""
        c = self.edges[face]
        pairs = b * np.roll(b, -1, axis=1)  # b0 b1, b1 b2, b2 b0: the edges 01, 12, 20
        return 4.0 * (c * pairs).sum(axis=1)

    def points(self, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """The patch points (m, 3) [m] over the barycentric coordinates ``bary`` (m, 3) of
        the faces ``face`` (m,)."""
        flat = np.einsum("mk,mkj->mj", bary, self.vertices[self.faces[face]])
        return flat + self._height(face, bary)[:, None] * self.normals[face]


def _face_geometry(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (F, 3) and corner angles (F, 3) [rad] of the faces."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    normals = cross / np.where(norm > 0, norm, 1.0)[:, None]
    angles = np.empty((len(faces), 3))
    for k in range(3):
        a = tri[:, (k + 1) % 3] - tri[:, k]
        b = tri[:, (k + 2) % 3] - tri[:, k]
        angles[:, k] = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), (a * b).sum(1))
    return normals, angles


def corner_normals(
    vertices: np.ndarray, faces: np.ndarray, crease_angle: float
) -> tuple[np.ndarray, np.ndarray]:
    """(corner normals (F, 3, 3): face f's normal at its k-th vertex, face normals (F, 3)).

    m = the angle-weighted mean of the normals of the faces at the vertex within
    ``crease_angle`` [deg] of face f's own (module docstring), unit length.
    """
    normals, angles = _face_geometry(vertices, faces)
    corners = faces.ravel()  # corner a = 3 f + k
    order = np.argsort(corners, kind="stable")
    counts = np.bincount(corners, minlength=len(vertices))
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    # every pair (a, b) of corners at the same vertex, a and b in sorted order
    size = counts[corners[order]]  # each sorted corner's group size
    first = starts[corners[order]]
    a = np.repeat(np.arange(len(order)), size)
    offsets = np.arange(len(a)) - np.repeat(np.cumsum(size) - size, size)
    b = np.repeat(first, size) + offsets
    fa, fb = order[a] // 3, order[b] // 3
    cos_crease = math.cos(math.radians(crease_angle))
    alike = (normals[fa] * normals[fb]).sum(1) >= cos_crease
    weight = np.where(alike, angles.ravel()[order[b]], 0.0)
    sums = np.empty((faces.size, 3))
    for j in range(3):
        sums[:, j] = np.bincount(order[a], weights=weight * normals[fb, j], minlength=faces.size)
    length = np.linalg.norm(sums, axis=1)
    own = np.repeat(normals, 3, axis=0)
    unit = np.where(length[:, None] > 0, sums / np.where(length > 0, length, 1.0)[:, None], own)
    return unit.reshape(-1, 3, 3), normals


def curved_patches(vertices: np.ndarray, faces: np.ndarray, crease_angle: float) -> CurvedPatches:
    """The patches of the mesh (module docstring), corners bent within ``crease_angle`` [deg]."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    m, n = corner_normals(vertices, faces, crease_angle)
    tri = vertices[faces]
    edges = np.empty((len(faces), 3))
    for k in range(3):
        i, j = k, (k + 1) % 3
        vec = tri[:, j] - tri[:, i]
        length = np.linalg.norm(vec, axis=1)
        e = vec / np.where(length > 0, length, 1.0)[:, None]
        # a corner normal at most 90° from n_f (the crease test keeps it far closer)
        mi_n = np.maximum((m[:, i] * n).sum(1), 1e-3)
        mj_n = np.maximum((m[:, j] * n).sum(1), 1e-3)
        slope_i = -(m[:, i] * e).sum(1) / mi_n
        slope_j = (m[:, j] * e).sum(1) / mj_n
        edges[:, k] = length * (slope_i + slope_j) / 8.0
    return CurvedPatches(vertices=vertices, faces=faces, normals=n, edges=edges)

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

The signed distance to the curved part at p (:meth:`CurvedPatches.signed_distance`), from
libigl's foot x on the facets: q = x + h(b) n_f the patch point over it, m̂ the corner normals
interpolated at b and normalised, and

    Φ = (p − q) · m̂          where the corners around x are smooth,
    Φ = sign(d − h) ‖p − q‖   where x lies on a crease: an edge whose faces turn by more
                              than the crease angle, or a vertex with such an edge (a box's
                              edge: the distance to the edge, which projection would shorten).

On a smooth part m̂ is the patch's normal to O(φ²) and q is the true foot's neighbour to O(|d|
φ), so the first is off by O(d² φ² / R) (R the radius of curvature): 2e-11 m at 1 mm from the
512-section cylinder. (d − h alone, the first-order term, is off by |d| φ²/2: the spline then
carries the nodes' error at a few h from the surface onto Φ = 0, O(h φ²).)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["CurvedPatches", "corner_normals", "curved_patches"]


#: A barycentric coordinate below this puts the foot on the opposite edge (libigl's feet on an
#: edge or vertex are exact to round-off).
_ON_EDGE = 1e-9


@dataclass(frozen=True, eq=False)
class CurvedPatches:
    """Each face's height coefficients ``edges`` (F, 3) [m] (c of edges 01, 12, 20), its unit
    normal ``normals`` (F, 3), its corner normals ``corners`` (F, 3, 3), ``smooth`` (F, 3): no
    crease at the corner's vertex, and ``smooth_edges`` (F, 3): the edges 01, 12, 20 are
    shared with a face within the crease angle, for the mesh ``vertices`` (V, 3) [m],
    ``faces`` (F, 3)."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    edges: np.ndarray
    corners: np.ndarray
    smooth: np.ndarray
    smooth_edges: np.ndarray

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

    def _height(self, face: np.ndarray, b: np.ndarray) -> np.ndarray:
        """h = 4 Σ c_ij b_i b_j (m,) [m] at barycentric coordinates b (m, 3) of ``face``."""
        c = self.edges[face]
        pairs = b * np.roll(b, -1, axis=1)  # b0 b1, b1 b2, b2 b0: the edges 01, 12, 20
        return 4.0 * (c * pairs).sum(axis=1)

    def signed_distance(
        self, face: np.ndarray, foot: np.ndarray, points: np.ndarray, signed: np.ndarray
    ) -> np.ndarray:
        """Φ (m,) [m] at ``points`` (m, 3) [m] of the curved part, > 0 on the side the face
        normals point to, from their feet (m, 3) [m] on the faces of indices ``face`` (m,) and
        their signed distances ``signed`` (m,) [m] to the faces (the module docstring)."""
        if len(face) == 0:
            return np.zeros(0)
        b = np.clip(self.barycentric(face, foot), 0.0, 1.0)
        q = self.points(face, b)
        m = np.einsum("mk,mkj->mj", b, self.corners[face])
        m /= np.linalg.norm(m, axis=1)[:, None]
        offset = points - q
        along = (offset * m).sum(axis=1)
        # a foot on an edge (one b is 0: the edge opposite) or at a vertex (two are) of a crease
        zero = b <= _ON_EDGE
        count = zero.sum(axis=1)
        opposite = np.argmax(zero, axis=1)
        on_crease_edge = (count == 1) & ~self.smooth_edges[face, (opposite + 1) % 3]
        vertex = np.argmax(~zero, axis=1)
        at_crease_vertex = (count == 2) & ~self.smooth[face, vertex]
        sharp = on_crease_edge | at_crease_vertex

        if not sharp.any():
            return along
        height = self._height(face[sharp], b[sharp])
        direct = np.sign(signed[sharp] - height) * np.linalg.norm(offset[sharp], axis=1)
        out = along.copy()
        out[sharp] = direct
        return out

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
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(corner normals (F, 3, 3): face f's normal at its k-th vertex, face normals (F, 3),
    smooth (F, 3): every two faces at the corner's vertex are within the crease angle).

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
    creased = np.bincount(corners[order[a]], weights=~alike, minlength=len(vertices)) > 0
    return unit.reshape(-1, 3, 3), normals, ~creased[faces]


def curved_patches(vertices: np.ndarray, faces: np.ndarray, crease_angle: float) -> CurvedPatches:
    """The patches of the mesh (module docstring), corners bent within ``crease_angle`` [deg]."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    m, n, smooth = corner_normals(vertices, faces, crease_angle)
    smooth_edges = _smooth_edges(faces, n, crease_angle)
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
    return CurvedPatches(vertices, faces, n, edges, m, smooth, smooth_edges)


def _smooth_edges(faces: np.ndarray, normals: np.ndarray, crease_angle: float) -> np.ndarray:
    """(F, 3): edge k → k+1 of each face is shared with exactly one other face whose normal
    is within ``crease_angle`` [deg] of its own (an open or non-manifold edge is a crease)."""
    pairs = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    _, group, counts = np.unique(pairs, axis=0, return_inverse=True, return_counts=True)
    group = group.ravel()
    order = np.argsort(group, kind="stable")
    shared = counts[group] == 2
    # the two half-edges of a shared edge are adjacent in ``order``
    partner = np.full(len(group), -1)
    first = order[np.concatenate([[True], group[order][1:] != group[order][:-1]])]
    for_pairs = shared[first]
    a = first[for_pairs]
    b = order[np.searchsorted(group[order], group[a]) + 1]
    partner[a], partner[b] = b, a
    cos_crease = math.cos(math.radians(crease_angle))
    own = normals[np.arange(len(group)) // 3]
    other = normals[np.maximum(partner, 0) // 3]
    alike = shared & ((own * other).sum(axis=1) >= cos_crease)
    return alike.reshape(-1, 3)

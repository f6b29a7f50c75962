"""A smooth signed-distance field Φ of a triangle mesh: a tricubic B-spline on a grid.

Why not the mesh's exact distance: its normal jumps at every edge (2.65° between samples
0.12 mm apart on a 20,480-face sphere), while the laws use ∇Φ and ∇²Φ. The field here is the
signed distance d of the mesh at the nodes of a regular grid (libigl's exact point-triangle
distance, signed by the pseudonormal on a watertight mesh and by the generalised winding number
on an open one; exact within a band of the surface, :func:`_signed_samples`), interpolated
by the tricubic B-spline through those values: C² everywhere, with ∇Φ and ∇²Φ in closed
form (:mod:`._field_kernels`).

With ``facets = "curved"`` (the default) d is the distance to the curved patches through the
mesh's vertices (:mod:`.mesh_patches`), not to its flat facets: the field then converges to the
smooth part the mesh was cut from as h is refined, not to its chords (on a cylinder of N
sections, the facets are up to R(1 − cos π/N) inside it). ``facets = "flat"``: the facets
themselves (a part that is faceted by design).

The grid spacing h smooths the facets: a spline interpolating d on a grid finer than the
facets follows their ripple, and the normal with it. The default h is therefore twice the
median of each face's shortest edge (the faceting scale: the chord of a cylinder's sections,
not its long sides), and at least the part's bounding-box diagonal / 256 and at most the
diagonal / 16; the grid covers the box padded by max(8 h, diagonal / 10) on every side.

The field is built once per mesh content and settings and cached on disk (an ``.npz`` named by
a hash of both; folder ``$HYBRID_FORCE_CACHE`` or ``~/.cache/hybrid_force/fields``).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import math
import os
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hybrid_force._atomic import atomic_file
from hybrid_force.errors import ModelWarning, SurfaceError
from hybrid_force.geometry.mesh_patches import CurvedPatches, curved_patches

__all__ = [
    "CREASE_ANGLE",
    "FACETS",
    "MAX_NODES",
    "DistanceField",
    "MeshPart",
    "build_field",
    "default_resolution",
    "load_field",
    "read_mesh",
]

#: How a mesh's faces are read: bent into patches through the vertices, or flat.
FACETS = ("curved", "flat")
#: Faces meeting at more than this [deg] keep the sharp edge between them (curved facets).
CREASE_ANGLE = 30.0
#: Largest grid the field may have [nodes]: 8 bytes each, 3 arrays of it at most while
#: building (about 400 MB at this bound); a finer ``resolution`` is refused naming it.
MAX_NODES = 16_000_000
_FORMAT = 2  # version of the cached file's layout: a change invalidates old caches


@dataclass(frozen=True, eq=False)
class MeshPart:
    """A triangle mesh placed in the world: vertices (V, 3) [m], faces (F, 3) vertex indices.

    ``digest``: sha256 of the file's bytes and the placement (scale, position, rpy), the cache's
    key. ``watertight``: every edge is shared by exactly two faces (trimesh's test).
    """

    vertices: np.ndarray
    faces: np.ndarray
    digest: str
    watertight: bool
    source: str

    @property
    def diagonal(self) -> float:
        """Length of the bounding box's diagonal [m]."""
        return float(np.linalg.norm(self.vertices.max(axis=0) - self.vertices.min(axis=0)))

    @functools.cached_property
    def open_edges(self) -> np.ndarray:
        """The edges (E, 2) vertex indices not shared by exactly two faces: the boundary of an
        open mesh (one face) and its non-manifold edges (three or more); empty when the part
        is watertight. Near them the signed distance jumps (its sign, from the winding
        number, flips across the surface's extension past the edge) and Φ does not follow the
        part (:meth:`.MeshSurface.open_edge_distance`)."""
        f = np.asarray(self.faces, dtype=np.int64)
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        unique, counts = np.unique(edges, axis=0, return_counts=True)
        return np.ascontiguousarray(unique[counts != 2], dtype=np.int64)

    def shortest_edges(self) -> np.ndarray:
        """Each face's shortest edge (F,) [m]."""
        tri = self.vertices[self.faces]
        lengths = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2)
        return np.asarray(lengths.min(axis=1))


def rpy_matrix(rpy: tuple[float, float, float]) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll): (3, 3), the URDF convention for ``rpy`` [rad]."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def read_mesh(
    file: str | os.PathLike[str],
    *,
    scale: float = 1.0,
    position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0),
    key: str = "surface.file",
) -> MeshPart:
    """Read an STL, OBJ or PLY file with trimesh and place it: p = R(rpy) · scale · x + position.

    Raises:
        SurfaceError: naming ``key`` and the file: unreadable, not a triangle mesh,
            no faces, non-finite vertices, faces not consistently wound (two faces traverse
            an edge in the same direction: which side is free is then undefined), a scale that
            is not a finite number > 0, or a part whose size is not between 1e-6 m and 1e3 m.
    """
    import trimesh

    path = Path(file)
    if not (isinstance(scale, (int, float)) and not isinstance(scale, bool)) or not (
        math.isfinite(scale) and scale > 0
    ):
        raise SurfaceError(f"{key}: scale must be a finite number > 0, got {scale!r}")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SurfaceError(f"{key} = '{file}': cannot read the file ({exc.strerror})") from None
    kind = path.suffix.lower().lstrip(".")
    if kind not in ("stl", "obj", "ply"):
        raise SurfaceError(
            f"{key} = '{file}': unknown mesh format '{path.suffix}'; valid: .stl, .obj, .ply"
        )
    try:
        # unprocessed first: trimesh's processing drops non-finite vertices and their faces
        # silently (a hole), which is refused here instead
        loaded = trimesh.load(io.BytesIO(data), file_type=kind, force="mesh", process=False)
        raw = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
        if raw.size and not np.isfinite(raw).all():
            first = int(np.nonzero(~np.isfinite(raw).all(axis=1))[0][0])
            raise SurfaceError(
                f"{key} = '{file}': the mesh has non-finite vertices (the first: vertex "
                f"{first} = {raw[first].tolist()})"
            )
        if hasattr(loaded, "process"):
            loaded.process()
    except SurfaceError:
        raise
    except Exception as exc:  # trimesh raises many types on a corrupt file
        why = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise SurfaceError(
            f"{key} = '{file}': not a readable {kind.upper()} mesh ({why})"
        ) from None
    vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64)
    if faces.ndim != 2 or faces.shape[0] == 0 or faces.shape[1] != 3:
        raise SurfaceError(f"{key} = '{file}': the mesh has no triangle faces")
    tri = vertices[faces]
    flat = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) == 0
    if flat.all():
        raise SurfaceError(f"{key} = '{file}': all {len(faces)} faces have zero area")
    if flat.any():
        warnings.warn(
            f"{key} = '{file}': {int(flat.sum())} of its {len(faces)} faces have zero area "
            f"(the first: face {int(np.nonzero(flat)[0][0])}); they are left out",
            ModelWarning,
            stacklevel=2,
        )
        kept = trimesh.Trimesh(vertices, faces[~flat], process=False)
        kept.remove_unreferenced_vertices()
        loaded = kept  # its watertight test below is the kept faces'
        vertices = np.asarray(kept.vertices, dtype=np.float64)
        faces = np.asarray(kept.faces, dtype=np.int64)
    if not bool(getattr(loaded, "is_winding_consistent", True)):
        raise SurfaceError(f"{key} = '{file}': {_winding_report(faces)}")
    placed = vertices * float(scale) @ rpy_matrix(rpy).T + np.asarray(position, dtype=np.float64)
    size = float(np.linalg.norm(placed.max(axis=0) - placed.min(axis=0)))
    if not 1e-6 <= size <= 1e3:
        raise SurfaceError(
            f"{key} = '{file}': the placed part is {size:.3g} m across; valid: 1e-6 to 1e3 m "
            "(is surface.scale right? it converts the file's units to metres)"
        )
    digest = hashlib.sha256(data)
    digest.update(np.asarray([scale, *position, *rpy], dtype=np.float64).tobytes())
    return MeshPart(
        vertices=placed,
        faces=faces,
        digest=digest.hexdigest(),
        watertight=bool(getattr(loaded, "is_watertight", False)),
        source=str(file),
    )


def _winding_report(faces: np.ndarray) -> str:
    """Why a mesh's faces are not consistently wound: how many edges two faces traverse in
    the same direction, and the first such pair of faces."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)  # half-edge 3 f + k of face f
    _, inverse, counts = np.unique(directed, axis=0, return_inverse=True, return_counts=True)
    group = inverse.ravel()
    twice = np.nonzero(counts[group] > 1)[0]
    pair = sorted(int(i) // 3 for i in twice[group[twice] == group[twice[0]]])
    return (
        f"its faces are not consistently wound: {len(twice) // 2} edges are traversed in the "
        f"same direction by two faces (the first: faces {pair[0]} and {pair[-1]}), so the side "
        "their normals point to is not defined; orient them coherently first (e.g. trimesh's "
        "repair.fix_winding, MeshLab's Re-Orient all faces coherently)"
    )


def default_resolution(part: MeshPart) -> float:
    """The default grid spacing h [m] (module docstring: twice the faceting scale, clamped)."""
    diagonal = part.diagonal
    facet = 2.0 * float(np.median(part.shortest_edges()))
    return min(max(facet, diagonal / 256.0), diagonal / 16.0)


@dataclass(frozen=True, eq=False)
class DistanceField:
    """A tricubic B-spline Φ: coefficients (nx + 2, ny + 2, nz + 2) of nodes origin + i·h.

    Φ is the mesh's signed distance, positive on the side the face normals point to, or
    on the other for ``inside`` (the tool works inside a closed part).
    """

    coefficients: np.ndarray
    origin: np.ndarray
    spacing: float
    build_seconds: float = 0.0
    cache_file: str = ""
    #: max |Φ| at the part's vertices plus max |Φ| at its faces' centres and edges' middles
    #: (on the curved patches, or the flat faces): how far Φ = 0 may lie from the part [m]
    tolerance: float = 0.0

    @property
    def shape(self) -> tuple[int, int, int]:
        """Nodes per axis."""
        nx, ny, nz = (n - 2 for n in self.coefficients.shape)
        return (nx, ny, nz)

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(Φ [m], ∇Φ: (3,), ∇²Φ: (3, 3) [1/m]) at p: (3,) float64 [m]; fresh arrays.

        No memory of the last point: in a run the contact, the constraint and the tool's
        orientation ask at three different points a step (measured: 1 % hits on
        panda_pipe_tilt's mesh twin, ur5_mesh_forearm, panda_mesh_wrap), so keeping it cost
        more than it saved."""
        grad = np.empty(3)
        hess = np.empty((3, 3))
        value = _kernel()(self.coefficients, self.origin, self.spacing, p, grad, hess)
        return value, grad, hess

    def hessian(self, p: np.ndarray) -> np.ndarray | None:
        """∇²Φ at p: (3,) float64 [m], a fresh (3, 3) [1/m] (the same bits as ``evaluate(p)[2]``),
        or None when a coordinate of p is not finite or exceeds 1e150 m.

        ∇Φ goes to a scratch array shared by all fields: it is never read, so nothing can
        race on it."""
        hess = np.empty((3, 3))
        if _hessian_kernel()(self.coefficients, self.origin, self.spacing, p, _UNREAD, hess):
            return hess
        return None

    def orientation_terms(
        self, sample: np.ndarray, step: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """(∇Φ (3,), ∇²Φ (3, 3) [1/m], (d/dt ∇²Φ) ṗ_d (3,) [1/s]) at a path sample (3, 3) rows
        p_d [m], ṗ_d [m/s], p̈_d, the last by a central difference of ∇²Φ over ±``step`` [m]
        along ṗ_d (:func:`._field_kernels.orientation_terms`); None when p_d or ṗ_d is not
        finite. Views of one fresh (5, 3) array."""
        out = np.empty((5, 3))
        if _orientation_kernel()(self.coefficients, self.origin, self.spacing, step, sample, out):
            return out[0], out[1:4], out[4]
        return None

    def values(self, points: np.ndarray) -> np.ndarray:
        """Φ at points (m, 3) [m]: (m,)."""
        from hybrid_force.geometry import _field_kernels

        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.empty(pts.shape[0])
        _field_kernels.field_eval_many(self.coefficients, self.origin, self.spacing, pts, out)
        return out


_FIELD_EVAL = None


def _kernel():  # type: ignore[no-untyped-def]
    """The compiled field_eval, imported on first use (Numba is not imported before)."""
    global _FIELD_EVAL
    if _FIELD_EVAL is None:
        from hybrid_force.geometry import _field_kernels

        _FIELD_EVAL = _field_kernels.field_eval
    return _FIELD_EVAL


_FIELD_HESSIAN = None
_ORIENTATION = None
_UNREAD = np.empty(3)  # the ∇Φ DistanceField.hessian does not return


def _hessian_kernel():  # type: ignore[no-untyped-def]
    """The compiled field_hessian, imported on first use (as :func:`_kernel`)."""
    global _FIELD_HESSIAN
    if _FIELD_HESSIAN is None:
        from hybrid_force.geometry import _field_kernels

        _FIELD_HESSIAN = _field_kernels.field_hessian
    return _FIELD_HESSIAN


def _orientation_kernel():  # type: ignore[no-untyped-def]
    """The compiled orientation_terms, imported on first use (as :func:`_kernel`)."""
    global _ORIENTATION
    if _ORIENTATION is None:
        from hybrid_force.geometry import _field_kernels

        _ORIENTATION = _field_kernels.orientation_terms
    return _ORIENTATION


def _grid(part: MeshPart, h: float, key: str) -> tuple[np.ndarray, tuple[int, int, int]]:
    """The grid's origin (3,) [m] and node counts: the box padded by max(8 h, diagonal/10)."""
    low, high = part.vertices.min(axis=0), part.vertices.max(axis=0)
    pad = max(8.0 * h, part.diagonal / 10.0)
    counts = np.ceil((high - low + 2.0 * pad) / h).astype(np.int64) + 1
    nodes = int(np.prod(counts.astype(np.float64)))
    if nodes > MAX_NODES:
        finest = h * (nodes / MAX_NODES) ** (1.0 / 3.0)
        raise SurfaceError(
            f"{key} = {h:g} m: the grid would have {counts[0]} x {counts[1]} x {counts[2]} = "
            f"{nodes:,} nodes, above the bound of {MAX_NODES:,} (about "
            f"{MAX_NODES * 24 / 1e6:.0f} MB while building); valid for this part: >= {finest:.3g} m"
        )
    nx, ny, nz = (int(n) for n in counts)
    return low - pad, (nx, ny, nz)


def _interpolation_coefficients(samples: np.ndarray) -> np.ndarray:
    """Coefficients (n + 2 per axis) of the cubic B-spline through ``samples`` on every axis.

    Along an axis, f_i = (c_{i−1} + 4 c_i + c_{i+1}) / 6 for i = 0 … n−1 with the natural end
    conditions c_{−1} = 2c_0 − c_1, c_n = 2c_{n−1} − c_{n−2} (zero second derivative at the
    end nodes, far from the part), which give c_0 = f_0, c_{n−1} = f_{n−1} and a tridiagonal
    (1, 4, 1)/6 system for the rest, solved by the Thomas algorithm along each axis in turn
    (a tensor-product spline: the three 1-D solves commute).
    """
    coef = np.array(samples, dtype=np.float64)
    for axis in range(3):
        coef = np.moveaxis(coef, axis, 0)
        coef = np.moveaxis(_solve_axis0(coef), 0, axis)
    padded = np.zeros(tuple(n + 2 for n in coef.shape))
    padded[1:-1, 1:-1, 1:-1] = coef
    for axis in range(3):  # c_{−1} and c_n by the end conditions, axis by axis (edges too)
        view = np.moveaxis(padded, axis, 0)
        view[0] = 2.0 * view[1] - view[2]
        view[-1] = 2.0 * view[-2] - view[-3]
    return padded


def _solve_axis0(f: np.ndarray) -> np.ndarray:
    """Solve (c_{i−1} + 4c_i + c_{i+1})/6 = f_i along axis 0 with c_0 = f_0, c_{n−1} = f_{n−1}."""
    n = f.shape[0]
    c = f.copy()
    if n <= 2:
        return c
    # unknowns c_1 … c_{n−2}: 4 c_i + c_{i−1} + c_{i+1} = 6 f_i, the known ends moved right
    rhs = 6.0 * f[1:-1].copy()
    rhs[0] -= f[0]
    rhs[-1] -= f[-1]
    m = n - 2
    diag = np.empty(m)
    diag[0] = 4.0
    for i in range(1, m):
        diag[i] = 4.0 - 1.0 / diag[i - 1]
        rhs[i] -= rhs[i - 1] / diag[i - 1]
    c[m] = rhs[m - 1] / diag[m - 1]
    for i in range(m - 2, -1, -1):
        c[i + 1] = (rhs[i] - c[i + 2]) / diag[i]
    return c


#: Every _STRIDE-th node is computed first; a node farther than _BAND·h from the surface by
#: that coarse grid's bound takes the coarse spline's value instead of an exact distance.
_STRIDE = 4
_BAND = 4.0


#: Nodes per call of :func:`_signed_chunk`: bounds the temporaries (about 10 arrays of 3
#: floats a node) to some 100 MB whatever the grid.
_CHUNK = 500_000


def _exact_signed(
    part: MeshPart, nodes: np.ndarray, inside: bool, patches: CurvedPatches | None
) -> np.ndarray:
    """The part's signed distance at nodes (m, 3) [m]: > 0 on the free side; to the curved
    ``patches`` when given (:meth:`.CurvedPatches.signed_distance`)."""
    if len(nodes) <= _CHUNK:
        return _signed_chunk(part, nodes, inside, patches)
    parts = [
        _signed_chunk(part, nodes[i : i + _CHUNK], inside, patches)
        for i in range(0, len(nodes), _CHUNK)
    ]
    return np.concatenate(parts)


def _signed_chunk(
    part: MeshPart, nodes: np.ndarray, inside: bool, patches: CurvedPatches | None
) -> np.ndarray:
    import igl

    # A watertight mesh: the sign of the angle-weighted pseudonormal at the closest feature
    # (Bærentzen & Aanæs 2005), exact there and computed with the distance. An open mesh: the
    # generalised winding number (Jacobson et al. 2013), robust near the surface but about 10x
    # slower per point on a 200k-face mesh (measured). Not libigl 2.6's fast-winding-number
    # mode of signed_distance: its magnitudes were up to 1.7 mm off the exact distance on a
    # 0.3 m sphere (measured).
    if part.watertight:
        signed, face, foot, _ = igl.signed_distance(
            nodes, part.vertices, part.faces, sign_type=igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL
        )
        signed = np.asarray(signed, dtype=np.float64)
    else:
        unsigned, face, foot, _ = igl.signed_distance(
            nodes, part.vertices, part.faces, sign_type=igl.SIGNED_DISTANCE_TYPE_UNSIGNED
        )
        winding = igl.winding_number(part.vertices, part.faces, nodes)
        signed = np.where(np.asarray(winding) < 0.5, 1.0, -1.0) * np.abs(
            np.asarray(unsigned, dtype=np.float64)
        )
    if patches is not None:
        face = np.asarray(face, dtype=np.int64)
        signed = patches.signed_distance(face, np.asarray(foot), nodes, signed)
    return -signed if inside else signed


def _axis_nodes(origin: np.ndarray, h: float, counts: tuple[int, ...], stride: int) -> list:
    return [origin[k] + stride * h * np.arange(counts[k]) for k in range(3)]


def _lattice(axes: list) -> np.ndarray:
    grids = np.meshgrid(*axes, indexing="ij")
    return np.column_stack([g.ravel() for g in grids])


def _signed_samples(
    part: MeshPart,
    origin: np.ndarray,
    counts: tuple[int, int, int],
    h: float,
    inside: bool,
    patches: CurvedPatches | None = None,
) -> np.ndarray:
    """Signed distances at the grid's nodes (nx, ny, nz): exact within a band of the surface.

    A narrow band: the exact distance is computed on every _STRIDE-th node first (H = 4h); as
    the distance is 1-Lipschitz, a node x whose nearest coarse node c has |d(c)| − |x − c| >
    _BAND·h is at least that far from the surface, and takes the value of the coarse nodes'
    cubic spline (its B-spline support and the interpolation's decay make nodes beyond 4h
    irrelevant to Φ within about 2h of the surface). The others get exact distances.
    """
    stride = _STRIDE
    coarse_counts = tuple(-(-(n - 1) // stride) + 1 for n in counts)
    if min(counts) <= 4 * stride:
        nodes = _lattice(_axis_nodes(origin, h, counts, 1))
        return _exact_signed(part, nodes, inside, patches).reshape(counts)
    coarse_nodes = _lattice(_axis_nodes(origin, h, coarse_counts, stride))
    coarse = _exact_signed(part, coarse_nodes, inside, patches)
    coarse = coarse.reshape(coarse_counts)
    # the coarse spline at every fine node, axis by axis (a tensor product: 3 small matrices)
    upsampled = _interpolation_coefficients(coarse)
    for axis in range(3):
        weights = _upsampling_matrix(counts[axis], coarse_counts[axis], stride)
        upsampled = np.moveaxis(
            np.tensordot(weights, np.moveaxis(upsampled, axis, 0), axes=(1, 0)), 0, axis
        )
    # the Lipschitz test against each fine node's nearest coarse node
    nearest = [
        np.minimum(np.rint(np.arange(n) / stride).astype(np.int64), m - 1)
        for n, m in zip(counts, coarse_counts, strict=True)
    ]
    offsets = [
        np.abs(np.arange(n) - stride * idx) * h for n, idx in zip(counts, nearest, strict=True)
    ]
    gap = np.sqrt(
        offsets[0][:, None, None] ** 2
        + offsets[1][None, :, None] ** 2
        + offsets[2][None, None, :] ** 2
    )
    # the patches lie within their largest height of the facets: d − h is 1-Lipschitz to that
    bend = 0.0 if patches is None else patches.largest
    bound = np.abs(coarse[np.ix_(*nearest)]) - gap - 2.0 * bend
    near = bound <= _BAND * h
    samples = upsampled
    # the nodes of the coarse grid already hold their exact distance
    on_coarse = tuple(slice(0, n, stride) for n in counts)
    samples[on_coarse] = coarse[tuple(slice(0, len(range(0, n, stride))) for n in counts)]
    near[on_coarse] = False
    index = np.nonzero(near)
    if index[0].size:
        points = np.column_stack([origin[k] + h * index[k] for k in range(3)])
        samples[index] = _exact_signed(part, points, inside, patches)
    return samples


def _upsampling_matrix(fine: int, coarse: int, stride: int) -> np.ndarray:
    """W (fine, coarse + 2): the coarse cubic spline's value at the fine nodes i/stride."""
    from hybrid_force.geometry import _field_kernels

    weights = np.zeros((fine, coarse + 2))
    b, d, s = np.empty(4), np.empty(4), np.empty(4)
    for i in range(fine):
        u = min(i / stride, coarse - 1.0)
        cell = min(int(u), coarse - 2)
        _field_kernels._basis(u - cell, b, d, s)
        weights[i, cell : cell + 4] = b
    return weights


def _cache_folder() -> Path:
    env = os.environ.get("HYBRID_FORCE_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "hybrid_force" / "fields"


def build_field(
    part: MeshPart,
    resolution: float | None = None,
    *,
    inside: bool = False,
    facets: str = "curved",
    crease_angle: float = CREASE_ANGLE,
    key: str = "surface.resolution",
    cache: bool = True,
) -> DistanceField:
    """The smooth field of ``part`` at grid spacing ``resolution`` [m] (None: the default).

    Φ > 0 on the side the face normals point to (``inside = False``), else on the other.
    ``facets``: "curved" (Φ = 0 on the patches through the vertices, faces bent within
    ``crease_angle`` [deg] of each other, :mod:`.mesh_patches`) or "flat" (on the faces).
    Read from the cache when a file of the same mesh, placement and settings is there.

    Raises:
        SurfaceError: ``key``: a resolution that is not a finite number > 0, or a
            grid above :data:`MAX_NODES` (the message gives the finest valid spacing); the
            table's ``facets`` not one of :data:`FACETS`, ``crease_angle`` not in [0, 180].
    """
    h = default_resolution(part) if resolution is None else resolution
    if not (isinstance(h, (int, float)) and not isinstance(h, bool)) or not (
        math.isfinite(h) and h > 0
    ):
        raise SurfaceError(f"{key}: must be a finite number > 0 [m], got {resolution!r}")
    table = key.rsplit(".", 1)[0]
    if facets not in FACETS:
        raise SurfaceError(
            f"{table}.facets: must be one of {', '.join(FACETS)}, got {facets!r}",
            key=f"{table}.facets",
            value=facets,
            choices=FACETS,
        )
    # the range the [surface] table's schema declares, for callers of the API too
    if not (isinstance(crease_angle, (int, float)) and not isinstance(crease_angle, bool)) or not (
        0.0 <= crease_angle <= 180.0
    ):
        raise SurfaceError(
            f"{table}.crease_angle: must be a number in [0, 180] [deg], got {crease_angle!r}",
            key=f"{table}.crease_angle",
            value=crease_angle,
        )
    h = float(h)
    crease = float(crease_angle) if facets == "curved" else 0.0
    origin, counts = _grid(part, h, key)
    settings = f"{_FORMAT}|{part.digest}|{h!r}|{inside}|{facets}|{crease!r}"
    name = hashlib.sha256(settings.encode()).hexdigest()[:32]
    target = _cache_folder() / f"{name}.npz"
    if cache:
        loaded = load_field(target)
        if loaded is not None:
            return loaded

    start = time.perf_counter()
    patches = curved_patches(part.vertices, part.faces, crease) if facets == "curved" else None
    samples = _signed_samples(part, origin, counts, h, inside, patches)
    coefficients = _interpolation_coefficients(samples)
    fitted = DistanceField(coefficients=coefficients, origin=origin, spacing=h)
    tolerance = _tolerance(part, fitted, patches)
    seconds = time.perf_counter() - start
    field = DistanceField(coefficients, origin, h, seconds, str(target) if cache else "", tolerance)
    if cache:
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            with atomic_file(target) as fh:
                np.savez(
                    fh,
                    coefficients=coefficients,
                    origin=origin,
                    spacing=np.float64(h),
                    tolerance=np.float64(tolerance),
                )
        except OSError:
            field = dataclasses.replace(field, cache_file="")
    return field


def _tolerance(part: MeshPart, field: DistanceField, patches: CurvedPatches | None) -> float:
    """:attr:`DistanceField.tolerance`: max |Φ| at the vertices plus max |Φ| at the faces'
    centres and edges' middles, on the patches (or the faces, ``patches`` None)."""
    third, half = 1.0 / 3.0, 0.5
    bary = np.array(
        [[third, third, third], [half, half, 0.0], [0.0, half, half], [half, 0.0, half]]
    )
    count = len(part.faces)
    face = np.repeat(np.arange(count), len(bary))
    weights = np.tile(bary, (count, 1))
    if patches is None:
        points = np.einsum("mk,mkj->mj", weights, part.vertices[part.faces[face]])
    else:
        points = patches.points(face, weights)
    on_vertices = float(np.abs(field.values(part.vertices)).max())
    return on_vertices + float(np.abs(field.values(points)).max())


def load_field(path: str | os.PathLike[str]) -> DistanceField | None:
    """The field cached in ``path``, or None when it is missing or not a valid field file."""
    try:
        with np.load(path, allow_pickle=False) as data:
            coefficients = np.ascontiguousarray(data["coefficients"], dtype=np.float64)
            origin = np.ascontiguousarray(data["origin"], dtype=np.float64)
            spacing = float(data["spacing"])
            tolerance = float(data["tolerance"])
    except (OSError, KeyError, ValueError, EOFError):
        return None
    ok = (
        coefficients.ndim == 3
        and min(coefficients.shape) >= 4
        and origin.shape == (3,)
        and math.isfinite(spacing)
        and spacing > 0
        and math.isfinite(tolerance)
        and tolerance >= 0
        and np.isfinite(coefficients).all()
    )
    return DistanceField(coefficients, origin, spacing, 0.0, str(path), tolerance) if ok else None

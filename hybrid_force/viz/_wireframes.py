"""Surface wireframes and the 2-D view of the run figures (pure numpy).

The surface dicts of a result are read by :func:`hybrid_force.geometry.surfaces.surface_from_dict`,
the one parser of a surface dict (a bad one is a BadInputError naming its index).

Wireframes of the built-in surfaces (cylinder, sphere, plane) cover the part of the surface near
the motion; :func:`_projection` chooses the plane of the paper's Fig. 3b.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid_force.errors import BadInputError, SurfaceError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.geometry.surfaces import surface_from_dict

# --------------------------------------------------------------------------------------------
# Geometry helpers
# --------------------------------------------------------------------------------------------
_DRAWN = ("cylinder", "sphere", "plane")


def _drawable(s: Mapping[str, Any], i: int) -> Surface | None:
    """The built-in surface of dict s (parsed by :func:`surface_from_dict`), or None for a type
    this module cannot draw (a function surface, an unknown type)."""
    if s.get("type") not in _DRAWN:
        return None
    try:
        return surface_from_dict(s)
    except SurfaceError as exc:
        raise BadInputError(f"result meta['surfaces'][{i}] cannot be drawn: {exc}") from exc


def _plane_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (u, w) with (u, w, n) a right-handed orthonormal frame.

    u is the world axis least aligned with n, projected on the plane normal to n, so that for
    n = ±z the pair is (x, ±y) and a cylinder of axis z projects on the paper's xy plane.
    n: (3,) unit. Returns u, w: (3,), (3,).
    """
    e = np.eye(3)[int(np.argmin(np.abs(n)))]
    u = e - (e @ n) * n
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def _finite_points(*arrays: np.ndarray) -> np.ndarray:
    pts = np.concatenate([a for a in arrays], axis=0)
    return pts[np.all(np.isfinite(pts), axis=1)]


def _cylinder_mesh(
    center: np.ndarray, axis: np.ndarray, radius: float, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wireframe grid (X, Y, Z: (n_s, n_theta) [m]) of a cylinder over the axial range of pts.

    pts: (M, 3) [m] the motion; the segment covers its projection on the axis, padded.
    """
    u, w = _plane_basis(axis)
    if pts.size:
        s = (pts - center) @ axis
        lo, hi = float(s.min()), float(s.max())
    else:
        lo = hi = 0.0
    pad = max(0.08 * (hi - lo), 0.25 * radius if hi - lo < 1e-9 else 0.0)
    ss = np.linspace(lo - pad, hi + pad, 9)
    th = np.linspace(0.0, 2.0 * np.pi, 37)
    ring = radius * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * w)  # (37, 3)
    grid = center + ss[:, None, None] * axis + ring[None, :, :]  # (9, 37, 3)
    return grid[..., 0], grid[..., 1], grid[..., 2]


def _sphere_mesh(
    center: np.ndarray, radius: float, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wireframe (X, Y, Z: (n_polar, n_azimuth) [m]) of the spherical cap around the motion.

    The cap is centred on the mean direction of pts from the centre and covers every point of
    pts with a margin; when it would exceed 150° the whole sphere is drawn.
    """
    amax = np.pi
    m = np.array([0.0, 0.0, 1.0])
    if pts.size:
        rel = pts - center
        mean = rel.mean(axis=0)
        if np.linalg.norm(mean) > 1e-9 * max(radius, 1.0):
            m = mean / np.linalg.norm(mean)
            norms = np.linalg.norm(rel, axis=1)
            ok = norms > 1e-12
            cosang = np.clip((rel[ok] @ m) / norms[ok], -1.0, 1.0)
            reach = float(np.arccos(cosang).max()) if cosang.size else 0.0
            amax = reach * 1.15 + np.radians(8.0)
            if amax > np.radians(150.0):
                amax = np.pi
    u, w = _plane_basis(m)
    th = np.linspace(0.0, amax, 13)
    ps = np.linspace(0.0, 2.0 * np.pi, 37)
    dirs = np.cos(th)[:, None, None] * m + np.sin(th)[:, None, None] * (
        np.cos(ps)[None, :, None] * u + np.sin(ps)[None, :, None] * w
    )
    grid = center + radius * dirs
    return grid[..., 0], grid[..., 1], grid[..., 2]


def _plane_mesh(
    point: np.ndarray, normal: np.ndarray, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wireframe (X, Y, Z: (11, 11) [m]) of the plane patch under the motion pts (M, 3), padded."""
    u, w = _plane_basis(normal)
    if pts.size:
        a, b = (pts - point) @ u, (pts - point) @ w
        a0, a1, b0, b1 = float(a.min()), float(a.max()), float(b.min()), float(b.max())
    else:
        a0 = a1 = b0 = b1 = 0.0
    span = max(a1 - a0, b1 - b0, 0.1)
    pad = 0.1 * span
    aa = np.linspace(a0 - pad, a1 + pad, 11)
    bb = np.linspace(b0 - pad, b1 + pad, 11)
    grid = point + aa[:, None, None] * u + bb[None, :, None] * w
    return grid[..., 0], grid[..., 1], grid[..., 2]


def _surface_mesh(
    s: Mapping[str, Any], i: int, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The wireframe of surface dict s (None for a type this module cannot draw)."""
    surface = _drawable(s, i)
    if isinstance(surface, Cylinder):
        axis = np.array(surface.axis)
        return _cylinder_mesh(np.array(surface.center), axis, surface.radius, pts)
    if isinstance(surface, Sphere):
        return _sphere_mesh(np.array(surface.center), surface.radius, pts)
    if isinstance(surface, Plane):
        return _plane_mesh(np.array(surface.point), np.array(surface.normal_vector), pts)
    return None


@dataclass(frozen=True)
class _Projection:
    """A 2-D view: coordinates (x·u, x·w) [m] with labels, and the circles to draw there."""

    u: np.ndarray
    w: np.ndarray
    xlabel: str
    ylabel: str
    title: str
    circles: tuple[tuple[float, float, float, str], ...]  # (centre u, centre w, radius, label)


def _axis_name(v: np.ndarray, fallback: str) -> str:
    for i, name in enumerate("xyz"):
        if abs(abs(v[i]) - 1.0) < 1e-12:
            return name if v[i] > 0 else f"−{name}"
    return f"{fallback} = ({v[0]:.2f}, {v[1]:.2f}, {v[2]:.2f})·p"


def _projection(surfaces: Sequence[Mapping[str, Any]]) -> _Projection:
    """Choose the 2-D view of Fig. 3b: first cylinder, else first plane, else the xy plane.

    Circles drawn: cylinders whose axis is parallel to the view normal, and every sphere (its
    outline in any orthographic view).
    """
    drawn = [(i, _drawable(s, i)) for i, s in enumerate(surfaces)]
    normal, what = np.array([0.0, 0.0, 1.0]), "xy plane"
    for cls in (Cylinder, Plane):
        found = [s for _, s in drawn if isinstance(s, cls)]
        if found:
            first = found[0]
            normal = np.array(first.axis if isinstance(first, Cylinder) else first.normal_vector)
            what = "plane normal to the cylinder axis" if cls is Cylinder else "the plane"
            break
    u, w = _plane_basis(normal)
    if what == "xy plane":
        u, w = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    circles: list[tuple[float, float, float, str]] = []
    for i, s in drawn:
        if isinstance(s, Cylinder):
            if abs(abs(np.array(s.axis) @ normal) - 1.0) < 1e-9:
                c = np.array(s.center)
                circles.append((float(c @ u), float(c @ w), s.radius, f"cylinder {i}"))
        elif isinstance(s, Sphere):
            c = np.array(s.center)
            circles.append((float(c @ u), float(c @ w), s.radius, f"sphere {i} outline"))
    return _Projection(
        u=u,
        w=w,
        xlabel=f"{_axis_name(u, 'u')} [m]",
        ylabel=f"{_axis_name(w, 'w')} [m]",
        title=f"projection on {what}",
        circles=tuple(circles),
    )

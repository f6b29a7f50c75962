"""Surface wireframes and the 2-D view of the run figures (pure numpy).

The surface dicts of a result are read by :func:`hybrid_force.geometry.surfaces.surface_from_dict`,
the one parser of a surface dict (a bad one is a BadInputError naming its index).

A surface's wireframe is its own patch near the motion (``Surface.patch``);
:func:`_projection` chooses the plane of the paper's Fig. 3b.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid_force.errors import BadInputError, SurfaceError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.surface_base import Surface, plane_basis, surface_types
from hybrid_force.geometry.surfaces import surface_from_dict


def _drawable(s: Mapping[str, Any], i: int) -> Surface | None:
    """The surface of dict s (parsed by :func:`surface_from_dict`), or None for a type that
    cannot be rebuilt (a function surface, an unknown type)."""
    if s.get("type") not in surface_types():
        return None
    try:
        return surface_from_dict(s)
    except SurfaceError as exc:
        raise BadInputError(f"result meta['surfaces'][{i}] cannot be drawn: {exc}") from exc


def _surface_triangles(
    s: Mapping[str, Any], i: int, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """A mesh part's own triangles (vertices (V, 3) [m], faces (F, 3)) near the motion pts, or
    None for a surface that draws a patch instead."""
    surface = _drawable(s, i)
    draw = getattr(surface, "triangles", None)
    return draw(pts) if callable(draw) else None


def _finite_points(*arrays: np.ndarray) -> np.ndarray:
    pts = np.concatenate([a for a in arrays], axis=0)
    return pts[np.all(np.isfinite(pts), axis=1)]


def _surface_mesh(
    s: Mapping[str, Any], i: int, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The wireframe (X, Y, Z: (n, m) [m]) of surface dict s near the motion pts (M, 3): the
    surface's own :meth:`~hybrid_force.geometry.surface_base.Surface.patch` (None: not drawn)."""
    surface = _drawable(s, i)
    grid = surface.patch(pts) if surface is not None else None
    if grid is None:
        return None
    return grid[..., 0], grid[..., 1], grid[..., 2]


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
    u, w = plane_basis(normal)
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

"""Offset surfaces: where the centre of a ball-end tool of radius r [m] is when it touches.

A ball of radius r centred at p touches a part whose signed metric distance is d exactly where
d(p) = r, so the tool centre (the arm's tip frame origin) follows the offset surface
Φ_r(p) = d(p) − r = 0 and the contact point is p − r n̂(p), n̂ the unit normal to the free side
(:func:`contact_points`). The built-in surfaces give their exact offset of the same type
(:meth:`Cylinder.offset <hybrid_force.geometry.builtin_surfaces.Cylinder.offset>`: radius
R ± r, ...); the others, by what their distance is (:attr:`Surface.metric_distance
<hybrid_force.geometry.surface_base.Surface.metric_distance>`):

* :class:`PhiOffset` – Φ itself is the metric distance (a mesh part's fitted field):
  Φ_r = Φ − r, ∇Φ_r = ∇Φ, ∇²Φ_r = ∇²Φ;
* :class:`DistanceOffset` – the distance is exact to an exact foot point f, Φ is not (the
  ellipsoid): Φ_r = d − r, ∇Φ_r = n̂(f) and ∇²Φ_r = ∇²d = W (I + d W)⁻¹, where
  W = P ∇²Φ(f) P / ‖∇Φ(f)‖ (P = I − n̂ n̂ᵀ) is the shape operator at the foot: each principal
  curvature κ of the part becomes κ / (1 + d κ) on the parallel surface at distance d.
  Singular where 1 + d κ = 0 (a centre of curvature: the offset has a cusp there).

Any other surface is refused (SurfaceError naming ``tool.radius`` and the value). The chart of
an offset surface (:class:`OffsetChart`, for ``frame = "surface"`` paths) is S + r n̂ of the
part's chart, with n̂'s derivatives from ∇Φ and ∇²Φ.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force.errors import RunWarning, SurfaceError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.charts import SurfaceChart, chart_for, register_chart
from hybrid_force.geometry.surface_base import Surface, Vec3, _xyz, register_offset, tool_radius

__all__ = [
    "DistanceOffset",
    "OffsetChart",
    "PhiOffset",
    "contact_points",
    "tool_surfaces",
]

#: ‖∇Φ‖ below this (in ∇Φ's units) at a foot point: no normal there.
_SINGULAR_GRADIENT = 1e-12
#: 1 + d κ below this: p is (nearly) at a centre of curvature of the part.
_FOCAL_TOL = 1e-9
#: Step [m] of the central difference of ∇²Φ in the chart of an offset of a non-quadric part.
_HESSIAN_STEP = 1e-4


def tool_surfaces(
    surfaces: Sequence[Surface],
    radius: float,
    *,
    warn: bool = True,
    along: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[Surface, ...]:
    """The surfaces the tool centre follows: each surface's :meth:`~Surface.offset` by
    ``radius`` [m] (the surfaces themselves for 0).

    With ``warn``, warns (RunWarning) where a part is concave with a smaller radius of
    curvature than the tool's (:meth:`~Surface.concave_radius`): the ball cannot reach the
    bottom there, the contact point found from the offset lies off the part. The warning names
    the radius, the point and the excess r − radius; with ``along`` = (times (N,) [s], the tool
    centre's path at them (N, 3) [m]) also the path's nearest approach to that point and its
    time. Raises SurfaceError (naming ``tool.radius``) where the offset does not exist."""
    r = tool_radius(radius)
    if r == 0.0:
        return tuple(surfaces)
    out = []
    for i, surface in enumerate(surfaces):
        out.append(surface.offset(r))
        if not warn:
            continue
        smallest, where = surface.concave_radius()
        if smallest < r:
            at = (
                " (its smallest, found over the part)"
                if where is None
                else f" at {np.round(np.asarray(where), 6).tolist()} m"
                + _nearest_approach(np.asarray(where, dtype=float), along)
            )
            warnings.warn(
                RunWarning(
                    f"tool.radius = {r:g} m exceeds the smallest concave radius of curvature of "
                    f"surfaces[{i}] ({surface!r}), {smallest:.6g} m{at}, by {r - smallest:.3g} m: "
                    "the ball cannot reach the bottom of the hollow there (it touches its sides)"
                ),
                stacklevel=2,
            )
    return tuple(out)


def _nearest_approach(point: np.ndarray, along: tuple[np.ndarray, np.ndarray] | None) -> str:
    """' (the tool centre's path passes d m from it, nearest at t = T s)', or '' without a
    path."""
    if along is None or len(along[0]) == 0:
        return ""
    times, points = along
    gaps = np.linalg.norm(np.asarray(points, dtype=float) - point, axis=1)
    j = int(np.argmin(gaps))
    return (
        f" (the tool centre's path passes {gaps[j]:.3g} m from it, nearest at t = {times[j]:.4g} s)"
    )


def contact_points(surface: Surface, radius: float, centres: np.ndarray) -> np.ndarray:
    """The contact points c = p − r n̂(p) of a ball of radius r [m] centred at each p of
    ``centres`` (N, 3) [m], n̂ the unit normal of ``surface`` (the offset surface the centre
    follows, or the part: their normals agree): (N, 3) [m]. On the part when the ball touches
    it; else the ball's point nearest the part. NaN rows where the normal is undefined."""
    points = np.asarray(centres, dtype=float)
    out = np.full(points.shape, np.nan)
    for i, p in enumerate(points):
        if np.all(np.isfinite(p)):
            with contextlib.suppress(SurfaceError):  # on an axis, at a centre: no normal
                out[i] = p - radius * surface.normal(p)
    return out


def _unit(g: np.ndarray, owner: object, x: np.ndarray) -> tuple[np.ndarray, float]:
    size = float(np.linalg.norm(g))
    if not size > _SINGULAR_GRADIENT:
        raise SurfaceError(f"{owner!r}: ∇Φ vanishes at the foot point {x.tolist()}: no normal")
    return g / size, size


class _Offset(Surface):
    """A surface at distance ``radius`` [m] from ``base`` on its free side."""

    kind: ClassVar[str] = "offset"
    base: Surface
    radius: float

    def __init__(self, base: Surface, radius: float) -> None:
        self.base = base
        self.radius = tool_radius(radius)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.base!r}, radius={self.radius!r})"

    def __eq__(self, other: object) -> bool:
        return (
            type(other) is type(self)
            and isinstance(other, _Offset)
            and other.base == self.base
            and other.radius == self.radius
        )

    def __hash__(self) -> int:
        return hash((type(self).__name__, self.base, self.radius))

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "offset", "radius": r, "surface": the part's dict}`` (not a scenario
        type: a scenario gives the part and ``tool.radius``)."""
        return {"type": self.kind, "radius": self.radius, "surface": self.base.to_dict()}

    def concave_radius(self) -> tuple[float, np.ndarray | None]:
        """The part's concave radius less r (a hollow of the offset is tighter)."""
        smallest, where = self.base.concave_radius()
        return smallest - self.radius, where

    def offset(self, radius: float) -> Surface:
        """The offset by r + ``radius`` of the part (offsets add along the normal)."""
        r = tool_radius(radius)
        return self if r == 0.0 else type(self)(self.base, self.radius + r)

    def phi(self, p: ArrayLike) -> float:
        """Φ_r(p) = d(p) − r [m]."""
        return self.evaluate(np.array(_xyz(p, self, "phi")))[0]

    def gradient(self, p: ArrayLike) -> np.ndarray:
        """∇Φ_r(p): (3,), unit."""
        return np.array(self.evaluate(np.array(_xyz(p, self, "gradient")))[1])

    def hessian(self, p: ArrayLike) -> np.ndarray:
        """∇²Φ_r(p): (3, 3) [1/m]."""
        return np.array(self.evaluate(np.array(_xyz(p, self, "hessian")))[2])

    def distance(self, p: ArrayLike) -> float:
        """d − r [m]: the metric distance to the offset surface."""
        return self.base.distance(p) - self.radius

    def normal(self, p: ArrayLike) -> np.ndarray:
        """The part's unit normal at p's foot point: (3,)."""
        return self.base.normal(self.base.closest_point(p))

    def closest_point(self, p: ArrayLike) -> np.ndarray:
        """f + r n̂(f), f the foot point on the part: (3,) [m]."""
        foot = self.base.closest_point(p)
        return np.asarray(foot + self.radius * self.base.normal(foot))

    def patch(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray | None:
        """The part's patch moved by r along its normals: (n, m, 3) [m], or None."""
        grid = self.base.patch(points, margin)
        if grid is None:
            return None
        flat = grid.reshape(-1, 3)
        normals = np.array([self.base.normal(x) for x in flat])
        return np.asarray((flat + self.radius * normals).reshape(grid.shape))


@register_offset("phi")
class PhiOffset(_Offset):
    """Φ_r = Φ − r of a part whose Φ is its signed metric distance [m] (``metric_distance =
    "phi"``, a mesh part's fitted field): the same derivatives."""

    metric_distance: ClassVar[str] = "phi"

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(Φ − r [m], ∇Φ: (3,), ∇²Φ: (3, 3) [1/m]) at p: float64 (3,) [m]."""
        value, grad, hess = self.base.evaluate(p)
        return value - self.radius, grad, hess

    def evaluate_with_distance(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
        """:meth:`evaluate` and d = Φ − r [m]."""
        value, grad, hess = self.evaluate(p)
        return value, grad, hess, value

    def distance(self, p: ArrayLike) -> float:
        """Φ − r [m]."""
        return self.phi(p)

    def normal(self, p: ArrayLike) -> np.ndarray:
        """∇Φ/‖∇Φ‖ at p: (3,) (the part's own normal, parallel at the foot)."""
        return self.base.normal(p)


@register_offset("exact")
class DistanceOffset(_Offset):
    """Φ_r = d − r of a part with an exact metric distance and foot point (``metric_distance
    = "exact"``, the ellipsoid), with ∇d and ∇²d from the foot point (module doc)."""

    metric_distance: ClassVar[str] = "exact"

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(d − r [m], ∇d = n̂(f): (3,), ∇²d = W (I + d W)⁻¹: (3, 3) [1/m]) at p (3,) [m]."""
        base = self.base
        foot = base.closest_point(p)
        d = base.distance(p)
        _, g, H = base.evaluate(foot)
        n, size = _unit(np.asarray(g, dtype=float), self, foot)
        P = np.eye(3) - np.outer(n, n)
        W = P @ H @ P / size
        A = np.eye(3) + d * W
        # A's eigenvalues are 1 (along n̂) and 1 + d κ_i: near 0 at a centre of curvature
        if not abs(np.linalg.det(A)) > _FOCAL_TOL:
            raise SurfaceError(
                f"{self!r}: p = {p.tolist()} is at a centre of curvature of the part (1 + d κ ≈ 0"
                f" at d = {d:.6g} m): the offset surface has no curvature there"
            )
        hess = np.linalg.solve(A.T, W.T).T  # W A⁻¹ (W and A commute: symmetric)
        return d - self.radius, n, 0.5 * (hess + hess.T)

    def evaluate_with_distance(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
        """:meth:`evaluate` and d − r [m]."""
        value, grad, hess = self.evaluate(p)
        return value, grad, hess, value


# --- chart -----------------------------------------------------------------------------------
def _quadric(surface: Surface) -> bool:
    """∇³Φ = 0: a built-in surface or an ellipsoid (Φ of degree 2)."""
    return isinstance(surface, Cylinder | Sphere | Plane) or surface.kind == "ellipsoid"


@register_chart(_Offset)
class OffsetChart(SurfaceChart):
    """S_r(u, v) = S(u, v) + r n̂(S(u, v)) of the part's chart S (the same coordinates, names
    and periods): the point of the offset surface above each point of the part.

    n̂ = g/‖g‖ with g = ∇Φ(S); g_u = ∇²Φ S_u, g_uv = ∇²Φ S_uv + ∇³Φ[S_u, S_v] (zero for a
    quadric part, else a central difference of ∇²Φ along S_v), and the derivatives of the unit
    vector by the quotient rule. ``u_axis`` goes to the part's chart (a plane's).
    """

    takes_u_axis: ClassVar[bool] = True

    def __init__(self, surface: _Offset, u_axis: ArrayLike | None = None) -> None:
        self.surface = surface
        self.part = chart_for(surface.base, u_axis)
        # the part's coordinates, with their names, units and periods (class-level on the
        # charts of one surface type, per instance here: they depend on the part's chart)
        for name in ("names", "units", "periods"):
            setattr(self, name, getattr(self.part, name))
        self._radius = surface.radius
        self._quadric = _quadric(surface.base)

    def _hessian(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(self.surface.base.evaluate(np.ascontiguousarray(x))[2], dtype=float)

    def _one(self, rows: np.ndarray) -> np.ndarray:
        """(6, 3) S_r and its derivatives from the part's (6, 3) rows S, S_u, S_v, S_uu, S_uv,
        S_vv at one (u, v)."""
        S, Su, Sv, Suu, Suv, Svv = rows
        base = self.surface.base
        _, g0, H0 = base.evaluate(np.ascontiguousarray(S))
        g, H = np.asarray(g0, dtype=float), np.asarray(H0, dtype=float)
        n, s = _unit(g, self.surface, S)
        gu, gv = H @ Su, H @ Sv
        guu, guv, gvv = H @ Suu, H @ Suv, H @ Svv
        if not self._quadric:  # ∇³Φ[a, b] = (d/dε ∇²Φ(S + ε b)) a
            for a, b, which in ((Su, Su, 0), (Su, Sv, 1), (Sv, Sv, 2)):
                size = float(np.linalg.norm(b))
                if size == 0.0:
                    continue
                h = _HESSIAN_STEP / size
                third = (self._hessian(S + h * b) - self._hessian(S - h * b)) @ a / (2.0 * h)
                if which == 0:
                    guu = guu + third
                elif which == 1:
                    guv = guv + third
                else:
                    gvv = gvv + third

        def first(gi: np.ndarray) -> tuple[np.ndarray, float]:
            si = float(n @ gi)  # d‖g‖
            return (gi - si * n) / s, si

        nu, su = first(gu)
        nv, sv = first(gv)

        def second(
            gi: np.ndarray, gj: np.ndarray, gij: np.ndarray, ni: np.ndarray, nj: np.ndarray,
            sj: float,
        ) -> np.ndarray:  # fmt: skip
            # s n_i = g_i − n (n·g_i), differentiated along j
            return (gij - nj * float(n @ gi) - n * float(nj @ gi + n @ gij) - sj * ni) / s

        nuu = second(gu, gu, guu, nu, nu, su)
        nuv = second(gu, gv, guv, nu, nv, sv)
        nvv = second(gv, gv, gvv, nv, nv, sv)
        r = self._radius
        return np.array([S + r * n, Su + r * nu, Sv + r * nv, Suu + r * nuu, Suv + r * nuv,
                         Svv + r * nvv])  # fmt: skip

    def derivatives(self, u: ArrayLike, v: ArrayLike) -> np.ndarray:
        """(6, N, 3): S_r, its first and second derivatives (the part's chart's units)."""
        part = self.part.derivatives(u, v)
        out = np.empty_like(part)
        for i in range(part.shape[1]):
            out[:, i, :] = self._one(part[:, i, :])
        return out

    def derivatives_at(self, u: float, v: float) -> tuple[Vec3, Vec3, Vec3, Vec3, Vec3, Vec3]:
        """:meth:`derivatives` at one (u, v)."""
        rows = self._one(np.array(self.part.derivatives_at(u, v), dtype=float)).tolist()
        t = [(x, y, z) for x, y, z in rows]
        return t[0], t[1], t[2], t[3], t[4], t[5]

    def coordinates(self, p: ArrayLike) -> tuple[float, float]:
        """The part's coordinates of the foot point of p (3,) [m] on the part."""
        return self.part.coordinates(self.surface.base.closest_point(p))

    def to_dict(self) -> dict[str, Any]:
        """The part's chart's parameters."""
        return self.part.to_dict()

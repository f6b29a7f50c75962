"""A workpiece given as a triangle mesh (STL, OBJ, PLY): Φ is its smooth signed distance.

Φ(p) is the tricubic B-spline field of :mod:`.mesh_field` (a metric distance to within the
fit error, Φ > 0 on the free side), so ``distance`` is Φ itself and a tool of radius r follows
the offset surface Φ − r exactly (up to that fit). The mesh's triangles are kept for drawing.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from hybrid_force.errors import ModelWarning, SurfaceError
from hybrid_force.geometry.mesh_field import DistanceField, MeshPart, build_field, read_mesh
from hybrid_force.geometry.surface_base import Surface, _xyz

__all__ = ["MeshSurface"]

#: ‖∇Φ‖ below this: the normal is undefined (a distance field has ‖∇Φ‖ ≈ 1 near the surface).
_SINGULAR_GRADIENT = 1e-6


@dataclass(frozen=True, eq=False)
class MeshSurface(Surface):
    """The surface of a mesh part: Φ(p) = ±d(p), the smoothed signed distance [m].

    Build it with :meth:`from_file`. ``inside = False``: the tool works on the side the face
    normals point to (outside a closed part exported the usual way).
    """

    kind: ClassVar[str] = "mesh"
    # Φ is the (fitted) signed distance: a ball tool of radius r follows Φ − r (geometry/offset)
    metric_distance: ClassVar[str] = "phi"
    part: MeshPart
    field: DistanceField
    inside: bool = False
    file: str = ""
    scale: float = 1.0
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @classmethod
    def from_file(
        cls,
        file: str | Path,
        *,
        scale: float = 1.0,
        position: tuple[float, float, float] = (0.0, 0.0, 0.0),
        rpy: tuple[float, float, float] = (0.0, 0.0, 0.0),
        inside: bool = False,
        resolution: float | None = None,
        cache: bool = True,
    ) -> MeshSurface:
        """Read, place and fit the mesh in ``file`` (cached field: :func:`.build_field`).

        Warns (ModelWarning) when the mesh is not watertight: the winding-number sign of Φ is
        then trusted only near the surface.
        """
        part = read_mesh(file, scale=scale, position=position, rpy=rpy)
        if not part.watertight:
            warnings.warn(
                f"surface.file = '{file}': the mesh is not watertight (some edges are not shared "
                "by exactly two faces); the sign of Φ is trusted only near the surface",
                ModelWarning,
                stacklevel=2,
            )
        fitted = build_field(part, resolution, inside=inside, cache=cache)
        return cls(
            part=part,
            field=fitted,
            inside=bool(inside),
            file=str(file),
            scale=float(scale),
            position=tuple(float(x) for x in position),  # type: ignore[arg-type]
            rpy=tuple(float(x) for x in rpy),  # type: ignore[arg-type]
        )

    def __repr__(self) -> str:
        return f"MeshSurface('{self.file}', h={self.field.spacing:.4g} m)"

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(Φ [m], ∇Φ: (3,), ∇²Φ: (3, 3) [1/m]) at p: (3,) float64 [m]; fresh arrays."""
        return self.field.evaluate(p)

    def evaluate_with_distance(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
        """:meth:`evaluate` and d = Φ [m]."""
        value, grad, hess = self.field.evaluate(p)
        return value, grad, hess, value

    def _checked(self, p: ArrayLike, method: str) -> np.ndarray:
        return np.array(_xyz(p, self, method))

    def phi(self, p: ArrayLike) -> float:
        """Φ(p) [m]."""
        return self.field.evaluate(self._checked(p, "phi"))[0]

    def gradient(self, p: ArrayLike) -> np.ndarray:
        """∇Φ(p): (3,) (unit length to within the fit)."""
        return self.field.evaluate(self._checked(p, "gradient"))[1]

    def hessian(self, p: ArrayLike) -> np.ndarray:
        """∇²Φ(p): (3, 3) [1/m]."""
        return self.field.evaluate(self._checked(p, "hessian"))[2]

    def distance(self, p: ArrayLike) -> float:
        """d = Φ [m] (the field is a signed distance)."""
        return self.phi(p)

    def normal(self, p: ArrayLike) -> np.ndarray:
        """∇Φ/‖∇Φ‖: (3,), to the free side."""
        x = self._checked(p, "normal")
        grad = self.field.evaluate(x)[1]
        norm = float(np.linalg.norm(grad))
        if not norm >= _SINGULAR_GRADIENT:
            raise SurfaceError(
                f"{self!r}.normal: ‖∇Φ‖ = {norm:.3g} at p = {x.tolist()} (on the part's medial "
                "axis, where the distance has no normal)"
            )
        return grad / norm

    def closest_point(self, p: ArrayLike) -> np.ndarray:
        """The foot point on Φ = 0: Newton steps x ← x − Φ ∇Φ/‖∇Φ‖² from p (≤ 20, to 1e-12 m)."""
        x = self._checked(p, "closest_point")
        for _ in range(20):
            value, grad, _ = self.field.evaluate(x)
            g2 = float(grad @ grad)
            if not g2 >= _SINGULAR_GRADIENT**2:
                raise SurfaceError(f"{self!r}.closest_point: ‖∇Φ‖ vanishes at {x.tolist()}")
            x = x - (value / g2) * grad
            if abs(value) <= 1e-12:
                break
        return x

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "mesh", "file", "scale", "position", "rpy", "inside", "resolution"}``."""
        return {
            "type": self.kind,
            "file": self.file,
            "scale": self.scale,
            "position": list(self.position),
            "rpy": list(self.rpy),
            "inside": self.inside,
            "resolution": self.field.spacing,
        }

    def concave_radius(self) -> tuple[float, np.ndarray | None]:
        """(:meth:`smallest_concave_radius`, None): the hook a ball tool's check calls."""
        return self.smallest_concave_radius(), None

    def smallest_concave_radius(self) -> float:
        """The smallest radius of curvature [m] of the part's concave regions, at its vertices.

        From the principal curvatures of Φ = 0 (the eigenvalues of the Hessian projected on the
        tangent plane, ∇Φ of unit length): a principal curvature κ < 0 is a concave direction
        (seen from the free side) of radius 1/|κ|; inf when there is none. A ball tool of
        radius r cannot reach the bottom where r exceeds it. A lower estimate: the fit's
        ripple at the facets' scale lowers it (by up to 25 % on a 128 × 48 torus, measured
        in tests/test_mesh_field.py), which errs on the side of a warning.
        """
        smallest = math.inf
        for vertex in self.part.vertices:
            _, grad, hess = self.field.evaluate(np.ascontiguousarray(vertex))
            norm = float(np.linalg.norm(grad))
            if norm < _SINGULAR_GRADIENT:
                continue
            n = grad / norm
            tangent = np.eye(3) - np.outer(n, n)
            kappa = np.linalg.eigvalsh(tangent @ (hess / norm) @ tangent)
            # the zero eigenvalue along n is not a curvature: drop the one nearest zero
            kappa = np.delete(kappa, int(np.argmin(np.abs(kappa))))
            most = float(kappa.min())
            if most < 0:
                smallest = min(smallest, 1.0 / -most)
        return smallest

"""Study: how far from an open edge a mesh part's Φ is trusted (docs/mesh_parts.md, "Open
meshes").

An open sine sheet z = A sin(k x) (A = 0.02 m, k = 10 /m, 0.4 m square, 40 × 40 quads, the one
of tests/test_mesh_field.py) fitted at h = 10 and 5 mm: along the line y = 0 from its border
x = −0.2 m inwards, Φ and the ratio of the fitted curvature across the waves (the most concave
principal curvature of Φ = 0) to the true one, −A k² sin(kx) / (1 + (A k cos kx)²)^(3/2), at
1 to 10 grid spacings from the edge. Then a flat 0.4 m sheet (10 × 10 quads) at h = 10 mm:
the band's fit error of ``part --check`` over the whole part and away from its open edges.
Run from the repository root (about 20 s):

    python benchmarks/study_open_mesh.py
"""

from __future__ import annotations

import math
import tempfile
import warnings
from pathlib import Path

import numpy as np
import trimesh

from hybrid_force.errors import ModelWarning
from hybrid_force.geometry.mesh_surface import UNTRUSTED_SPACINGS, MeshSurface, check_part
from hybrid_force.geometry.surface_base import principal_curvatures

A, K, HALF = 0.02, 10.0, 0.2
SPACINGS = (1, 2, 3, 4, 5, 6, 8, 10)


def _sheet(folder: Path, n: int, height: object) -> Path:
    x = np.linspace(-HALF, HALF, n + 1)
    gx, gy = np.meshgrid(x, x, indexing="ij")
    z = np.asarray(height(gx.ravel()))  # type: ignore[operator]
    vertices = np.column_stack([gx.ravel(), gy.ravel(), z])
    faces = [
        f
        for i in range(n)
        for j in range(n)
        for a in [i * (n + 1) + j]
        for f in ([a, a + n + 1, a + 1], [a + 1, a + n + 1, a + n + 2])
    ]
    path = folder / f"sheet_{n}_{id(height)}.stl"
    trimesh.Trimesh(vertices, np.array(faces), process=False).export(path)
    return path


def main() -> int:
    """Print the tables; return 0."""
    warnings.simplefilter("ignore", ModelWarning)  # not watertight: the point of the study
    folder = Path(tempfile.mkdtemp(prefix="open_mesh_"))
    sine = _sheet(folder, 40, lambda x: A * np.sin(K * x))
    print("fitted / true curvature across the waves at n grid spacings from the open edge")
    print("| h [m] | " + " | ".join(f"{n} h" for n in SPACINGS) + " |")
    print("|---|" + "---|" * len(SPACINGS))
    for h in (0.01, 0.005):
        surface = MeshSurface.from_file(sine, resolution=h, cache=False)
        cells = []
        for n in SPACINGS:
            x = -HALF + n * h
            p = np.array([x, 0.0, A * math.sin(K * x)])
            _, grad, hess = surface.field.evaluate(p)
            fitted = principal_curvatures(grad, hess)[1]
            true = A * K**2 * math.sin(K * x) / (1.0 + (A * K * math.cos(K * x)) ** 2) ** 1.5
            cells.append(f"{fitted / true:.3f}")
        print(f"| {h:g} | " + " | ".join(cells) + " |")
    flat = _sheet(folder, 10, lambda x: 0.0 * x)
    report = check_part(flat, resolution=0.01)
    assert report.fit_inner is not None
    print()
    print(
        f"flat 0.4 m sheet, h = 0.01 m: band fit error {report.fit_band:.3g} m over the whole "
        f"part, {report.fit_inner[2]:.3g} m farther than {UNTRUSTED_SPACINGS:g} h from its "
        f"{report.open_edges} open edges"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Study: flat against curved facets on the issue's sphere (a 20,480-face icosphere of radius
0.3 m, h = 10.5 mm): the field against the true sphere (docs/mesh_parts.md, "Curved facets").

Prints a Markdown table: max |Φ − d_true| within 5 mm of the surface, mean |Φ − d_true| within
0.1 mm, the largest angle between ∇Φ and the true normal, the largest turn of ∇Φ between
points 0.1 mm apart along the surface (the true sphere's: 0.0191°), ‖∇Φ‖'s range, and the
build time. Run from the repository root (about a minute):

    python benchmarks/study_mesh_facets.py
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import trimesh

from hybrid_force.geometry.mesh_surface import MeshSurface

RADIUS, RESOLUTION = 0.3, 0.0105


def _near(rng: np.random.Generator, count: int, band: float) -> tuple[np.ndarray, ...]:
    d = rng.normal(size=(count, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    r = RADIUS + rng.uniform(-band, band, count)
    return d * r[:, None], d, r


def main() -> int:
    """Print the table; return 0."""
    path = Path(tempfile.mkdtemp(prefix="facets_")) / "sphere.stl"
    trimesh.creation.icosphere(subdivisions=5, radius=RADIUS).export(path)
    print("| facets | max \\|Φ − d\\| ≤ 5 mm [m] | mean \\|Φ − d\\| ≤ 0.1 mm [m] "
          "| normal [°] | turn over 0.1 mm [°] | ‖∇Φ‖ | build [s] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for facets in ("flat", "curved"):
        surface = MeshSurface.from_file(path, resolution=RESOLUTION, facets=facets, cache=False)
        rng = np.random.default_rng(1)
        points, directions, r = _near(rng, 1500, 0.005)
        far = np.abs(surface.field.values(points) - (r - RADIUS)).max()
        near_points, _, r_near = _near(rng, 3000, 1e-4)
        near = np.abs(surface.field.values(near_points) - (r_near - RADIUS)).mean()
        angle = turn = 0.0
        norms = []
        for p, n in zip(points, directions, strict=True):
            _, g, _ = surface.evaluate(p)
            norms.append(float(np.linalg.norm(g)))
            angle = max(angle, math.degrees(math.acos(min(1.0, g @ n / norms[-1]))))
            tangent = np.cross(n, rng.normal(size=3))
            tangent /= np.linalg.norm(tangent)
            _, g2, _ = surface.evaluate(p + 1e-4 * tangent)
            cos = g @ g2 / (np.linalg.norm(g) * np.linalg.norm(g2))
            turn = max(turn, math.degrees(math.acos(min(1.0, cos))))
        print(
            f"| {facets} | {far:.2e} | {near:.2e} | {angle:.3f} | {turn:.4f} "
            f"| {min(norms):.4f} to {max(norms):.4f} | {surface.field.build_seconds:.1f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

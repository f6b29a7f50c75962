"""The direction of travel of a path on a surface (``SurfacePath.direction_jet``).

Independent references: T = ṗ_d / ‖ṗ_d‖ wherever the path moves (its own velocity, by the
chain rule of the module doc); Ṫ and T̈ against central differences of T(t) away from the
breaks (where p⃛ may jump); at the rest points (start, end) T is the limit of ṗ_d / ‖ṗ_d‖
from inside the path, i.e. defined where ṗ_d = 0.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import path_breaks

from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.raster import RasterPath
from hybrid_force.geometry.surface_path import SurfacePath
from hybrid_force.geometry.waypoints import WaypointPath

PATHS = {
    "plane raster": lambda: RasterPath(
        Plane((0.0, 0.0, 5.0), (0.0, 0.0, 1.0)), (0.5, -0.1), (0.3, 0.2), 0.1, 0.1, ramp=0.3
    ),
    "sphere raster": lambda: RasterPath(
        Sphere(0.5, center=(0.0, 0.0, 5.0)),
        (-0.8, -0.3),
        (0.4, 0.6),
        0.1,
        0.1,
        direction="v",
        ramp=0.3,
    ),
    "cylinder waypoints": lambda: WaypointPath(
        Cylinder(0.4, inside=True),
        [[-2.0, 0.0], [-1.6, 0.05], [-1.2, 0.02]],
        0.05,
        frame="surface",
    ),
}


@pytest.fixture(params=list(PATHS), scope="module")
def path(request: pytest.FixtureRequest) -> SurfacePath:
    return PATHS[request.param]()


def test_tangent_is_the_unit_velocity_where_the_path_moves(
    path: SurfacePath, rng: np.random.Generator
) -> None:
    for t in rng.uniform(0.01, path.duration - 0.01, 50):
        _, v, _ = path.evaluate(t)
        T = path.direction_jet(t)[0]
        assert np.linalg.norm(T) == pytest.approx(1.0, abs=1e-8)
        np.testing.assert_allclose(T, v / np.linalg.norm(v), atol=1e-8)


def test_derivatives_are_differences(path: SurfacePath, rng: np.random.Generator) -> None:
    h = 1e-4
    breaks = path_breaks(path)
    times = [t for t in rng.uniform(0.0, path.duration, 200) if np.abs(breaks - t).min() > 3 * h]
    for t in times[:40]:
        jet = path.direction_jet(t)
        plus, minus = path.direction_jet(t + h), path.direction_jet(t - h)
        scale = 1.0 + np.abs(jet[1:]).max()
        np.testing.assert_allclose(jet[1], (plus[0] - minus[0]) / (2 * h), atol=1e-5 * scale)
        np.testing.assert_allclose(jet[2], (plus[1] - minus[1]) / (2 * h), atol=1e-4 * scale)


def test_defined_at_rest_as_the_limit_from_inside(path: SurfacePath) -> None:
    for rest, inside in ((0.0, 1e-4), (path.duration, path.duration - 1e-4), (-1.0, 1e-4)):
        _, v_rest, _ = path.evaluate(rest)
        assert np.linalg.norm(v_rest) < 1e-6  # at rest: ṗ_d gives no direction there
        _, v, _ = path.evaluate(inside)
        T = path.direction_jet(rest)
        np.testing.assert_allclose(T[0], v / np.linalg.norm(v), atol=1e-6)
        assert np.abs(T[1:]).max() < 1e-9  # ℓ̇ = ℓ̈ = 0 there

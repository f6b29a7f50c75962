"""A ball-end tool (``[tool] radius``): the offset surfaces and the runs that follow them.

Independent references:
- runs: a ball of radius r on a cylinder, a sphere and a plane against the point tool on the
  surface at R + r written by hand (R + r exact in floats), q, v, u, f equal to the bit; the
  recorded contact points on the part (the hand formula of the cylinder's distance);
- offsets: Φ_r, ∇Φ_r, ∇²Φ_r against central differences (the ellipsoid's d − r, inside and
  outside), against the hand formulas of a sphere's distance (d = ‖p − c‖ − R, ∇d radial,
  ∇²d = (I − n nᵀ)/‖p − c‖), and the generic Φ − r against the exact larger sphere;
- the contact point c = p − r n̂: on the part (its distance 0), with the part's normal at c
  parallel to n̂ (a geometric identity, on every surface type);
- the chart of an offset: its points at distance r from the part, its derivatives against
  central differences of its points;
- refusals and warnings: the messages name ``tool.radius`` and the value;
- the replay: its tip marker is the ball, of the tool's radius, on the part's own surface.
"""

from __future__ import annotations

import base64
import copy
import re
import tomllib
import warnings
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest
import trimesh
import umsgpack
from numpy.typing import ArrayLike

from hybrid_force.errors import RunWarning, ScenarioError, SurfaceError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.charts import chart_for
from hybrid_force.geometry.ellipsoid import Ellipsoid
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.mesh_surface import MeshSurface
from hybrid_force.geometry.offset import (
    DistanceOffset,
    PhiOffset,
    contact_points,
    tool_surfaces,
)
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.result import Result
from hybrid_force.scenario.loader import scenario_from_document
from hybrid_force.sim.loop import simulate
from hybrid_force.viz import replay

REPO_ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = REPO_ROOT / "scenarios"


def _doc(name: str, duration: float) -> dict[str, Any]:
    with open(SCENARIOS / f"{name}.toml", "rb") as fh:
        doc = tomllib.load(fh)
    doc["sim"]["duration"] = duration
    return doc


def _run(doc: dict[str, Any]) -> Result:
    return simulate(scenario_from_document(doc, origin="test.toml", base_dir=SCENARIOS))


# --- runs: a ball of radius r on R is a point on R + r ------------------------------------------
@pytest.mark.parametrize(
    ("name", "part", "r"),
    [
        ("paper_contact", {"radius": 0.375}, 0.025),  # cylinder 0.375 + 0.025 = 0.4
        ("rtr_sphere", {"radius": 0.375}, 0.125),  # sphere 0.375 + 0.125 = 0.5
        ("rtr_plane", {"point": [0.0, 0.0, 4.75]}, 0.25),  # plane z = 4.75 shifted to z = 5
        ("panda_pipe_tilt", {"radius": 0.18125}, 0.03125),  # pipe 0.18125 − 0.03125 = 0.15
        ("ur5_sphere_normal", {"radius": 0.25}, 0.05),  # a raster on the sphere of 0.3
    ],
)
def test_ball_on_surface_runs_as_point_on_its_offset(
    name: str, part: dict[str, Any], r: float
) -> None:
    """The path (a helix, a circle, surface waypoints, a raster) is the tool centre's, written
    for the point tool on the surface at R ± r; the ball on R follows it to the bit."""
    point = _doc(name, 1.5)
    ball = copy.deepcopy(point)
    ball["surface"].update(part)
    ball.setdefault("tool", {})["radius"] = r
    sa = scenario_from_document(point, origin="point.toml", base_dir=SCENARIOS)
    sb = scenario_from_document(ball, origin="ball.toml", base_dir=SCENARIOS)
    # the premise: R ± r written by hand is the offset, exactly in floats
    assert sb.tool_surfaces == sa.surfaces and sb.surfaces != sa.surfaces
    a, b = simulate(sa), simulate(sb)
    assert b.status == a.status == "ok"
    for field in ("q", "v", "u", "f", "p", "phi", "phase"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert a.contact_point is None
    assert b.contact_point is not None and b.contact_point.shape == (b.n_samples, 3)
    # the tip's distance to the offset (the run's phi) is the contact point's to the part,
    # the contact point r from the centre
    touching = b.phase == 2
    assert touching.sum() > 0.5 * b.n_samples
    c = b.contact_point[touching]
    to_part = np.array([sb.surfaces[0].distance(x) for x in c])
    assert np.allclose(to_part, b.phi[touching], rtol=0.0, atol=1e-12)
    assert np.allclose(np.linalg.norm(b.p[touching] - c, axis=1), r, rtol=0.0, atol=1e-12)


def test_ball_on_an_ellipsoid_follows_its_offset() -> None:
    """The RTR arm with a ball on a spheroid (no offset of the same type: d − r): the tool
    centre's circle, above the part's circle of parametric latitude φ, by hand."""
    a_, c_, r, phi = 0.5, 0.4, 0.05, -0.6435011087932844  # φ of z = 4.7 on rtr_sphere's sphere
    n = np.array([np.cos(phi) / a_, np.sin(phi) / c_])
    n /= np.linalg.norm(n)
    rho, z = a_ * np.cos(phi) + r * n[0], 5.0 + c_ * np.sin(phi) + r * n[1]
    doc = _doc("rtr_sphere", 3.0)
    doc["surface"] = {"type": "ellipsoid", "semi_axes": [a_, a_, c_], "center": [0.0, 0.0, 5.0]}
    doc["tool"] = {"radius": r}
    doc["trajectory"].update(center=[0.0, 0.0, z], radius=rho)
    doc["initial"]["tip"] = [rho, 0.0, z]
    sc = scenario_from_document(doc, origin="spheroid.toml", base_dir=SCENARIOS)
    assert isinstance(sc.tool_surfaces[0], DistanceOffset)
    result = simulate(sc)
    assert result.status == "ok" and bool(np.all(result.phase == 2))
    settled = result.t >= 1.0
    assert np.abs(result.f[settled] - 10.0).max() < 1e-6
    assert np.abs(result.phi).max() < 1e-8
    assert result.contact_point is not None
    part = sc.surfaces[0]
    c = result.contact_point
    assert max(abs(part.distance(x)) for x in c[::50]) < 1e-8
    assert np.allclose(np.linalg.norm(result.p - c, axis=1), r, rtol=0.0, atol=1e-12)


def test_contact_point_saved_and_absent_for_a_point_tool(tmp_path: Path) -> None:
    doc = _doc("paper_contact", 0.05)
    point = _run(doc)
    doc["surface"]["radius"] = 0.375
    doc["tool"] = {"radius": 0.025}
    ball = _run(doc)
    assert ball.meta["tool"]["radius"] == 0.025 and "radius" not in point.meta["tool"]
    loaded = Result.load(ball.save(tmp_path / "ball.npz"))
    assert loaded.contact_point is not None
    assert np.array_equal(loaded.contact_point, ball.contact_point)
    point.save(tmp_path / "point.npz")
    with np.load(tmp_path / "point.npz") as archive:
        assert "contact_point" not in archive.files
    assert Result.load(tmp_path / "point.npz").contact_point is None


def test_replay_draws_the_ball_on_the_part() -> None:
    def marker_radius(result: Result) -> float:
        page = replay.html(result, fps=10)
        block = page[page.index("var commands = [") :]
        block = block[: block.index("];")]
        for blob in re.findall(r'"([A-Za-z0-9+/=]+)"', block):
            command = umsgpack.unpackb(base64.b64decode(blob))
            if command.get("path") == "/meshcat/replay/tip/contact":
                return float(command["object"]["geometries"][0]["radius"])
        raise AssertionError("no tip marker")

    doc = _doc("paper_contact", 0.05)
    point = _run(doc)
    doc["surface"]["radius"] = 0.375
    doc["tool"] = {"radius": 0.025}
    ball = _run(doc)
    assert marker_radius(ball) == pytest.approx(0.025)
    assert marker_radius(point) == pytest.approx(0.045)  # the marker's default size
    # the part drawn is the part's own surface (radius 0.375), not the offset
    assert ball.meta["surfaces"][0]["radius"] == 0.375


# --- the built-ins' exact offsets ----------------------------------------------------------------
def test_builtin_offsets_are_the_same_type() -> None:
    axis = (0.0, 0.6, 0.8)
    assert Cylinder(0.4, (1.0, 2.0, 3.0), axis).offset(0.1) == Cylinder(0.5, (1.0, 2.0, 3.0), axis)
    assert Cylinder(0.5, inside=True).offset(0.125) == Cylinder(0.375, inside=True)
    assert Sphere(0.5, (0.0, 0.0, 5.0)).offset(0.25) == Sphere(0.75, (0.0, 0.0, 5.0))
    assert Sphere(0.5, inside=True).offset(0.25) == Sphere(0.25, inside=True)
    plane = Plane((0.0, 0.0, 1.0), (0.0, 0.6, 0.8))
    assert plane.offset(0.5) == Plane((0.0, 0.3, 1.4), (0.0, 0.6, 0.8))
    for surface in (Cylinder(0.4), Sphere(0.2), plane):
        assert surface.offset(0.0) is surface


@pytest.mark.parametrize(
    "part",
    [
        Cylinder(0.4, (0.1, -0.2, 0.3), (1.0, 1.0, 0.5)),
        Cylinder(0.4, inside=True),
        Sphere(0.3, (0.0, 0.0, 1.0)),
        Sphere(0.3, inside=True),
        Plane((0.0, 0.0, 1.0), (1.0, -2.0, 2.0)),
        Ellipsoid((0.3, 0.2, 0.15), (0.1, 0.0, 0.0), (0.3, -0.2, 0.5)),
        Ellipsoid((0.3, 0.2, 0.15), inside=True),
    ],
    ids=repr,
)
def test_offset_distance_and_contact_point_identity(part: Surface) -> None:
    """d_r = d − r everywhere; on the offset, c = p − r n̂ lies on the part, normal ∥ n̂."""
    r = 0.05
    offset = part.offset(r)
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = rng.uniform(-0.35, 0.35, 3)
        try:
            d = part.distance(x)
            foot = offset.closest_point(x)
        except SurfaceError:
            continue
        assert abs(offset.distance(x) - (d - r)) <= 1e-12
        assert abs(offset.distance(foot)) <= 1e-11
        n = offset.normal(foot)
        c = contact_points(offset, r, foot[None, :])[0]
        assert abs(part.distance(c)) <= 1e-11
        assert np.linalg.norm(np.cross(part.normal(c), n)) <= 1e-9
        assert part.normal(c) @ n > 0.0


def test_ball_that_does_not_fit_is_refused() -> None:
    for part in (Cylinder(0.1, inside=True), Sphere(0.1, inside=True)):
        with pytest.raises(SurfaceError, match=r"tool\.radius = 0\.1 m .*does not fit"):
            part.offset(0.1)
    with pytest.raises(SurfaceError, match=r"tool\.radius"):
        Cylinder(0.4).offset(-0.01)


def test_pipe_refusal_names_the_key_in_a_scenario() -> None:
    with open(SCENARIOS / "panda_pipe_tilt.toml", "rb") as fh:
        doc = tomllib.load(fh)
    R = doc["surface"]["radius"]
    doc["tool"]["radius"] = R
    with pytest.raises(ScenarioError, match=rf"tool\.radius = {R}.*does not fit"):
        scenario_from_document(doc, origin="pipe.toml", base_dir=SCENARIOS)
    doc["tool"]["radius"] = -0.01
    with pytest.raises(ScenarioError, match=r"pipe\.toml: tool\.radius = -0\.01"):
        scenario_from_document(doc, origin="pipe.toml", base_dir=SCENARIOS)


def test_a_path_on_the_part_instead_of_the_offset_is_refused_with_a_hint() -> None:
    doc = _doc("paper_contact", 1.0)
    doc["tool"] = {"radius": 0.025}  # the helix of radius 0.4 is on the part, not 0.425
    with pytest.raises(ScenarioError, match=r"0\.025 m away .*tool centre's"):
        scenario_from_document(doc, origin="ball.toml", base_dir=SCENARIOS)


def test_hollow_tighter_than_the_ball_warns_where_and_by_how_much() -> None:
    part = Ellipsoid((0.4, 0.2, 0.1), inside=True)  # smallest radius 0.1² / 0.4 = 0.025 m
    with pytest.warns(RunWarning, match=r"0\.025 m at \[0\.4, 0\.0, 0\.0\] m, by 0\.005 m"):
        (offset,) = tool_surfaces([part], 0.03)
    assert isinstance(offset, DistanceOffset)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tool_surfaces([part], 0.02)  # fits: no warning
        tool_surfaces([Cylinder(0.4, inside=True)], 0.3)


# --- derivatives of the generic offsets ----------------------------------------------------------
def _fd_check(surface: Surface, p: np.ndarray, h: float = 1e-5) -> None:
    value, grad, hess = surface.evaluate(p)
    fd_grad, fd_hess = np.empty(3), np.empty((3, 3))
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        fd_grad[i] = (surface.phi(p + e) - surface.phi(p - e)) / (2 * h)
        fd_hess[:, i] = (surface.gradient(p + e) - surface.gradient(p - e)) / (2 * h)
    assert value == pytest.approx(surface.phi(p), abs=0.0)
    assert np.allclose(grad, fd_grad, rtol=0.0, atol=1e-8)
    assert np.allclose(hess, fd_hess, rtol=0.0, atol=1e-6 * max(1.0, np.abs(hess).max()))
    assert np.allclose(hess, hess.T, atol=1e-12)


@pytest.mark.parametrize("inside", [False, True])
def test_ellipsoid_offset_derivatives_by_finite_differences(inside: bool) -> None:
    part = Ellipsoid((0.3, 0.2, 0.15), (0.1, 0.0, 0.2), (0.3, -0.2, 0.5), inside=inside)
    offset = part.offset(0.03)
    assert isinstance(offset, DistanceOffset)
    rng = np.random.default_rng(5)
    for _ in range(8):
        direction = rng.normal(size=3)
        foot = part.closest_point(np.array(part.center) + direction)
        n = part.normal(foot)
        _fd_check(offset, foot + rng.uniform(0.0, 0.04) * n)


def test_distance_offset_of_a_sphere_is_the_hand_formula() -> None:
    part, r = Sphere(0.3, (0.1, 0.2, 0.3)), 0.05
    offset = DistanceOffset(part, r)  # the generic route, against the sphere's closed form
    rng = np.random.default_rng(7)
    for _ in range(10):
        p = np.array(part.center) + rng.uniform(-0.6, 0.6, 3)
        w = p - np.array(part.center)
        rho = np.linalg.norm(w)
        n = w / rho
        value, grad, hess = offset.evaluate(p)
        assert value == pytest.approx(rho - 0.3 - r, abs=1e-14)
        assert np.allclose(grad, n, atol=1e-14)
        assert np.allclose(hess, (np.eye(3) - np.outer(n, n)) / rho, atol=1e-12)


class _SphereDistance(Surface):
    """Φ = ‖p − c‖ − R: a metric distance itself (the generic Φ − r route)."""

    kind: ClassVar[str] = "sphere_distance"
    metric_distance: ClassVar[str] = "phi"

    def __init__(self, radius: float, center: ArrayLike) -> None:
        self.radius, self.center = radius, np.asarray(center, dtype=float)

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        w = p - self.center
        rho = float(np.linalg.norm(w))
        n = w / rho
        return rho - self.radius, n, (np.eye(3) - np.outer(n, n)) / rho

    def phi(self, p: ArrayLike) -> float:
        return self.evaluate(np.asarray(p, dtype=float))[0]

    def gradient(self, p: ArrayLike) -> np.ndarray:
        return self.evaluate(np.asarray(p, dtype=float))[1]

    def hessian(self, p: ArrayLike) -> np.ndarray:
        return self.evaluate(np.asarray(p, dtype=float))[2]

    def distance(self, p: ArrayLike) -> float:
        return self.phi(p)

    def normal(self, p: ArrayLike) -> np.ndarray:
        return self.gradient(p)

    def closest_point(self, p: ArrayLike) -> np.ndarray:
        q = np.asarray(p, dtype=float)
        return q - self.phi(q) * self.normal(q)


def test_phi_offset_of_a_metric_surface_is_the_larger_sphere() -> None:
    part, r = _SphereDistance(0.3, (0.0, 0.1, 0.0)), 0.07
    offset = part.offset(r)
    assert isinstance(offset, PhiOffset)
    exact = Sphere(0.37, (0.0, 0.1, 0.0))
    rng = np.random.default_rng(11)
    for _ in range(10):
        p = rng.uniform(-0.6, 0.6, 3)
        assert offset.distance(p) == pytest.approx(exact.distance(p), abs=1e-15)
        assert np.allclose(offset.normal(p), exact.normal(p), atol=1e-15)
        _fd_check(offset, p)
    assert isinstance(offset.offset(0.03), PhiOffset) and offset.offset(0.03).radius == 0.1


# --- a mesh part: its Φ is its (fitted) metric distance ------------------------------------------
def test_mesh_part_offset_is_phi_minus_r_and_warns_in_a_tight_hole(tmp_path: Path) -> None:
    path = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=3, radius=0.1).export(path)
    part = MeshSurface.from_file(path, resolution=0.01, cache=False)
    offset = part.offset(0.02)
    assert isinstance(offset, PhiOffset)
    exact = Sphere(0.12)  # the offset of the sphere the mesh approximates
    rng = np.random.default_rng(17)
    for _ in range(20):
        d = rng.normal(size=3)
        p = d / np.linalg.norm(d) * rng.uniform(0.11, 0.13)
        value, grad, hess = offset.evaluate(p)
        base = part.evaluate(p)
        assert value == base[0] - 0.02 and np.array_equal(grad, base[1])
        assert np.array_equal(hess, base[2])
        # the 642-vertex mesh lies within 0.4 mm of its sphere: so does the offset of its fit
        assert abs(offset.distance(p) - exact.distance(p)) < 1e-3
    torus = tmp_path / "torus.stl"
    trimesh.creation.torus(
        major_radius=0.2, minor_radius=0.05, major_sections=64, minor_sections=24
    ).export(torus)
    ring = MeshSurface.from_file(torus, cache=False)  # its hole: concave of radius ≈ 0.15 m
    smallest = ring.smallest_concave_radius()
    with pytest.warns(RunWarning, match=rf"tool\.radius = 0\.2 m exceeds .* {smallest:.6g} m"):
        tool_surfaces([ring], 0.2)


# --- user surfaces ---------------------------------------------------------------------------
def test_function_surface_needs_a_declared_metric_distance() -> None:
    def phi(p: np.ndarray) -> float:
        return float(p @ p - 0.09)

    with pytest.raises(SurfaceError, match=r"tool\.radius = 0\.02 m .*metric=True"):
        FunctionSurface(phi).offset(0.02)
    with pytest.raises(SurfaceError, match=r"tool\.radius = 0\.02 m"):
        tool_surfaces([FunctionSurface(phi)], 0.02)
    assert FunctionSurface(phi).offset(0.0) is not None  # a point tool needs nothing


def test_function_surface_offsets() -> None:
    def plane(p: np.ndarray) -> float:
        return float(p[2] - 1.0)

    shifted = FunctionSurface(plane, metric=True).offset(0.25)
    reference = Plane((0.0, 0.0, 1.0), (0.0, 0.0, 1.0)).offset(0.25)
    rng = np.random.default_rng(13)
    for _ in range(5):
        p = rng.uniform(-1.0, 2.0, 3)
        assert shifted.phi(p) == pytest.approx(reference.phi(p), abs=1e-15)
        assert shifted.distance(p) == pytest.approx(reference.distance(p), abs=1e-15)

    def quadric(p: np.ndarray) -> float:
        return float(p @ p - 0.09)

    def distance(p: np.ndarray) -> float:
        return float(np.linalg.norm(p) - 0.3)

    ball = FunctionSurface(quadric, distance=distance, metric=True).offset(0.05)
    exact = Sphere(0.35)
    for _ in range(5):
        p = rng.uniform(-0.6, 0.6, 3)
        assert ball.distance(p) == pytest.approx(exact.distance(p), abs=1e-15)
        assert np.allclose(ball.normal(p), exact.normal(p), atol=1e-9)


# --- the chart of a generic offset -----------------------------------------------------------
def test_offset_chart_lies_on_the_offset_with_its_derivatives() -> None:
    part, r = Ellipsoid((0.3, 0.2, 0.15), (0.1, 0.0, 0.2), (0.3, -0.2, 0.5)), 0.04
    offset = part.offset(r)
    chart = chart_for(offset)
    assert chart.names == chart_for(part).names
    u = np.array([0.1, -0.5, 0.9])
    v = np.array([0.3, 2.0, -2.5])
    rows = chart.derivatives(u, v)
    h = 1e-5
    for i in range(3):
        S = rows[0, i]
        assert abs(part.distance(S) - r) <= 1e-12
        assert abs(offset.distance(S)) <= 1e-12
        assert chart.coordinates(S) == pytest.approx((u[i], v[i]), abs=1e-9)

        def at(du: float, dv: float, i: int = i) -> np.ndarray:
            return chart.derivatives(u[i] + du, v[i] + dv)

        fd_u = (at(h, 0)[:3, 0] - at(-h, 0)[:3, 0]) / (2 * h)  # S_u, S_uu, S_uv
        fd_v = (at(0, h)[:3, 0] - at(0, -h)[:3, 0]) / (2 * h)  # S_v, S_uv, S_vv
        assert np.allclose(rows[1, i], fd_u[0], atol=1e-8)
        assert np.allclose(rows[2, i], fd_v[0], atol=1e-8)
        assert np.allclose(rows[3, i], (at(h, 0)[1, 0] - at(-h, 0)[1, 0]) / (2 * h), atol=1e-7)
        assert np.allclose(rows[4, i], fd_u[2], atol=1e-7)
        assert np.allclose(rows[4, i], fd_v[1], atol=1e-7)
        assert np.allclose(rows[5, i], fd_v[2], atol=1e-7)
        one = np.array(chart.derivatives_at(float(u[i]), float(v[i])))
        assert np.allclose(one, rows[:, i], atol=1e-15)

"""Preston removal under a Hertz or flat pad against closed forms (Hertz, Preston) and the
identity removed volume = k_p ∫ F v dt of a non-rotating tool (∫ p dA = F)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hybrid_force.errors import ScenarioError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.charts import chart_for
from hybrid_force.sim.removal import (
    FlatPad,
    HertzPad,
    RemovalGrid,
    flat_profile,
    hertz_profile,
)

K_P = 1e-13  # m²/N, a typical Preston coefficient of glass polishing
DT = 1e-3


def test_hertz_patch_is_johnsons_closed_form() -> None:
    pad = HertzPad(radius=0.02, modulus=5e6)
    force = 20.0
    a, p0 = pad.patch(force)
    assert a == pytest.approx((3 * force * 0.02 / (4 * 5e6)) ** (1 / 3), rel=1e-15)
    # ∫ p dA = 2π p0 ∫ ρ √(1 − ρ²/a²) dρ = (2/3) π a² p0 = F
    assert 2.0 / 3.0 * math.pi * a * a * p0 == pytest.approx(force, rel=1e-14)
    # on a convex sphere of radius R the effective radius is R_pad R / (R_pad + R)
    a_sphere, _ = pad.patch(force, 1 / 0.3, 1 / 0.3)
    r_eff = 0.02 * 0.3 / 0.32
    assert a_sphere == pytest.approx((3 * force * r_eff / (4 * 5e6)) ** (1 / 3), rel=1e-14)
    with pytest.raises(ScenarioError, match=r"tool\.pad\.radius = 0\.02 m.*concave"):
        pad.patch(force, -1 / 0.01, 0.0)
    with pytest.raises(ScenarioError, match=r"tool\.pad\.modulus"):
        HertzPad(radius=0.02, modulus=0.0)


def _straight_pass(
    grid: RemovalGrid,
    pad: HertzPad | FlatPad,
    start: np.ndarray,
    direction: np.ndarray,
    normal: np.ndarray,
    speed: float,
    length: float,
    force: float,
    omega: float = 0.0,
) -> float:
    """Slide the patch along a straight line; returns k_p ∫ F |v| dt."""
    steps = round(length / (speed * DT))
    for i in range(steps + 1):
        centre = start + direction * (speed * DT * i)
        grid.add(pad, K_P, DT, centre, normal, speed * direction, force, omega)
    return K_P * force * speed * DT * (steps + 1)


@pytest.mark.parametrize("pad", [HertzPad(radius=0.02, modulus=5e6), FlatPad(radius=0.004)])
def test_straight_pass_cross_profile_matches_the_closed_form(pad: HertzPad | FlatPad) -> None:
    force, speed = 20.0, 0.02
    a, p = pad.patch(force)
    plane = Plane(point=[0, 0, 0], normal=[0, 0, 1])
    grid = RemovalGrid.on_chart(chart_for(plane), (-0.03, 0.03), (-3 * a, 3 * a), a / 25)
    expected_volume = _straight_pass(
        grid,
        pad,
        np.array([-0.02, 0.0, 0.0]),
        np.array([1.0, 0, 0]),
        np.array([0.0, 0, 1]),
        speed,
        0.04,
        force,
    )
    assert grid.volume == pytest.approx(expected_volume, rel=1e-12)
    # the profile across the pass, in the middle (x = 0), where the pass is steady
    middle = np.abs(grid.uv[:, 0]) < 0.002
    y = grid.uv[middle, 1]
    depth = grid.depth[middle]
    exact = hertz_profile(y, a, p, K_P) if isinstance(pad, HertzPad) else flat_profile(y, a, p, K_P)
    assert np.abs(depth - exact).max() <= 0.02 * exact.max()


def test_spindle_dwell_gives_the_rotating_hertz_profile() -> None:
    pad = HertzPad(radius=0.02, modulus=5e6)
    force, omega, steps = 20.0, 2 * math.pi * 3000 / 60, 200
    a, p0 = pad.patch(force)
    plane = Plane(point=[0, 0, 0], normal=[0, 0, 1])
    grid = RemovalGrid.on_chart(chart_for(plane), (-2 * a, 2 * a), (-2 * a, 2 * a), a / 30)
    for _ in range(steps):
        grid.add(pad, K_P, DT, np.zeros(3), np.array([0.0, 0, 1]), np.zeros(3), force, omega)
    rho = np.linalg.norm(grid.uv, axis=1)
    # h(ρ) = k_p p(ρ) ω ρ T: the cell at ρ slides at ω ρ for the whole dwell T
    exact = np.where(rho < a, K_P * p0 * np.sqrt(np.clip(1 - rho**2 / a**2, 0, None)), 0)
    exact *= omega * rho * steps * DT
    # the discrete pressures are scaled to Σ p_i A_i = F; compare with that scale's continuum
    assert np.abs(grid.depth - exact).max() <= 0.02 * exact.max()


@pytest.mark.parametrize(
    ("surface", "centre", "normal", "direction"),
    [
        (Plane(point=[0, 0, 0], normal=[0, 0, 1]), [0, 0, 0], [0, 0, 1], [1, 0, 0]),
        (Cylinder(radius=0.4), [0.4, 0, 0], [1, 0, 0], [0, 0, 1]),
        (Sphere(radius=0.3), [0, 0, 0.3], [0, 0, 1], [1, 0, 0]),
    ],
)
def test_volume_is_k_p_times_force_times_sliding_distance(
    surface: Plane | Cylinder | Sphere, centre: list, normal: list, direction: list
) -> None:
    pad = HertzPad(radius=0.02, modulus=5e6)
    chart = chart_for(surface)
    u0, v0 = chart.coordinates(np.array(centre, dtype=float))
    span = 0.05 if isinstance(surface, Plane) else 0.15
    grid = RemovalGrid.on_chart(chart, (u0 - span, u0 + span), (v0 - span, v0 + span), 4e-4)
    force, speed = 15.0, 0.02
    expected = 0.0
    # along the surface (a straight line on the plane and the cylinder's generator; on the
    # sphere a short chord, the patch staying on the cells near the pole)
    c, n, d = (np.array(x, dtype=float) for x in (centre, normal, direction))
    for i in range(200):
        point = c + d * (speed * DT * i)
        if isinstance(surface, Sphere):
            point = surface.closest_point(point)
            n = surface.normal(point)
        grid.add(pad, K_P, DT, point, n, speed * d, force)
        expected += K_P * force * speed * DT
    assert grid.volume == pytest.approx(expected, rel=5e-3)


def test_raster_uniformity_matches_the_superposition_of_pass_profiles() -> None:
    pad = HertzPad(radius=0.02, modulus=5e6)
    force, speed = 20.0, 0.05
    a, p0 = pad.patch(force)
    spacing = 1.2 * a  # 0.6 of the contact diameter
    plane = Plane(point=[0, 0, 0], normal=[0, 0, 1])
    grid = RemovalGrid.on_chart(chart_for(plane), (-0.01, 0.01), (-a, 7 * spacing + a), a / 20)
    for k in range(8):
        _straight_pass(
            grid,
            pad,
            np.array([-0.015, k * spacing, 0.0]),
            np.array([1.0, 0, 0]),
            np.array([0.0, 0, 1]),
            speed,
            0.03,
            force,
        )
    middle = (np.abs(grid.uv[:, 0]) < 0.001) & (grid.uv[:, 1] > 2 * spacing)
    middle &= grid.uv[:, 1] < 5 * spacing
    y = grid.uv[middle, 1]
    depth = grid.depth[middle]
    superposed = sum(hertz_profile(y - k * spacing, a, p0, K_P) for k in range(8))
    uniformity = 1 - depth.std() / depth.mean()
    exact = 1 - superposed.std() / superposed.mean()
    assert uniformity == pytest.approx(exact, abs=0.02)
    assert np.abs(depth - superposed).max() <= 0.02 * superposed.max()


def test_a_patch_between_cell_centres_keeps_the_volume() -> None:
    pad = FlatPad(radius=1e-4)  # far smaller than the cells
    plane = Plane(point=[0, 0, 0], normal=[0, 0, 1])
    grid = RemovalGrid.on_chart(chart_for(plane), (-0.01, 0.01), (-0.01, 0.01), 2e-3)
    touched = grid.add(
        pad, K_P, DT, np.array([0.0, 0.0, 0]), np.array([0.0, 0, 1]), np.array([0.01, 0, 0]), 10.0
    )
    assert touched == 0
    assert grid.volume == pytest.approx(K_P * 10.0 * 0.01 * DT, rel=1e-12)


@pytest.mark.parametrize(
    ("surface", "u_range", "v_range"),
    [
        (Plane(point=[0, 0, 0.5], normal=[0, 0.6, 0.8]), (-0.01, 0.01), (-0.01, 0.01)),
        (Cylinder(radius=0.4), (-math.pi, math.pi), (-0.01, 0.01)),  # the whole period: a seam
        (Cylinder(radius=0.05), (2.9, 3.4), (-0.01, 0.01)),  # across θ = π, not wrapped
        # thinner than the patch: every row within its reach (the rows' half-angle table)
        (Cylinder(radius=0.002), (-math.pi, math.pi), (-0.01, 0.01)),
    ],
    ids=["plane", "cylinder-wrapped", "cylinder-arc", "cylinder-thin"],
)
def test_the_lattice_rows_find_exactly_the_cells_within_the_patch(
    surface: Plane | Cylinder, u_range: tuple, v_range: tuple
) -> None:
    """On a plane's and a cylinder's chart the patch's cells are found row by row of the (u, v)
    lattice: the cells that receive depth are exactly those within a of the centre (brute
    force over all cells), at centres on, above and below the surface, across a seam."""
    pad = HertzPad(radius=0.02, modulus=5e6)
    chart = chart_for(surface)
    grid = RemovalGrid.on_chart(chart, u_range, v_range, 2e-4)
    assert grid.lattice.shape[0] > 0  # the row-by-row search, not the buckets
    rng = np.random.default_rng(7)
    for u in [
        u_range[0] + 1e-4,
        -math.pi + 1e-5,
        math.pi - 1e-5,
        *rng.uniform(u_range[0], u_range[1], 5),
    ]:
        if not u_range[0] <= u <= u_range[1]:
            continue
        v = float(rng.uniform(v_range[0], v_range[1]))
        d = chart.derivatives(u, v)
        normal = np.cross(d[1, 0], d[2, 0])
        normal /= np.linalg.norm(normal)
        centre = d[0, 0] + normal * float(rng.uniform(-5e-4, 5e-4))
        force = float(rng.uniform(5.0, 30.0))
        a, _ = pad.patch(force)
        grid.depth[:] = 0.0
        touched = grid.add(pad, K_P, DT, centre, normal, np.cross(normal, [0.3, 0.2, 0.1]), force)
        inside = np.linalg.norm(grid.points - centre, axis=1) < a
        assert inside.sum() > 100
        assert touched == inside.sum()
        assert np.array_equal(grid.depth > 0, inside)


def _segment_reference(
    xy: np.ndarray, start: np.ndarray, end: np.ndarray, a: float, hertz: bool
) -> np.ndarray:
    """∫ w(|x − c(s)|) ds along the straight segment start → end (2,) [m] at the points xy
    (M, 2) [m], by the midpoint rule on 20,000 steps (w = √(a² − ρ²) or the disc's indicator):
    the numerical reference of the closed form."""
    s = (np.arange(20_000) + 0.5) / 20_000
    out = np.zeros(xy.shape[0])
    for chunk in np.array_split(s, 40):
        c = start[None, :] + chunk[:, None] * (end - start)[None, :]
        r2 = ((xy[:, None, :] - c[None, :, :]) ** 2).sum(axis=2)
        inside = r2 < a * a
        w = np.sqrt(np.where(inside, a * a - r2, 0.0)) if hertz else inside.astype(float)
        out += w.sum(axis=1)
    return out


@pytest.mark.parametrize("hertz", [True, False], ids=["hertz", "flat"])
@pytest.mark.parametrize(
    ("surface", "start", "step"),
    [
        (Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)), (0.001, -0.002), (0.0, 0.012)),
        (Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)), (0.0004, 0.0), (0.0021, 0.0013)),
        # a cylinder's (θ, h): the segment in the unrolled surface (R θ, h), across the seam
        (Cylinder(radius=0.02), (math.pi - 0.05, 0.001), (0.009, -0.004)),
    ],
    ids=["plane-long", "plane-short-oblique", "cylinder-seam"],
)
def test_a_segment_deposit_is_the_line_integral_of_the_patch(
    surface: Plane | Cylinder, start: tuple, step: tuple, hertz: bool
) -> None:
    """The segment deposit (a tool that does not spin slid along a straight segment of a plane's
    or a cylinder's chart): each cell's depth is the patch's profile integrated along the
    segment across the cell's centre (closed form), scaled to the volume given; against the
    midpoint rule on 20,000 steps in the unrolled surface, to 1e-4 of the peak, with no cell
    missed by the rows' search."""
    from hybrid_force.sim import _removal_kernels as K

    chart = chart_for(surface)
    cylinder = isinstance(surface, Cylinder)
    u_range = (-math.pi, math.pi) if cylinder else (-0.01, 0.015)
    grid = RemovalGrid.on_chart(chart, u_range, (-0.01, 0.015), 1.5e-4)
    assert grid.lattice.shape[0] > 0 and grid.uv is not None
    a, amount = 0.003, 2e-12
    metric = surface.radius if cylinder else 1.0
    # the cells in the unrolled surface about the start (a cylinder's angle within half a turn)
    du = grid.uv[:, 0] - start[0]
    if cylinder:
        du = (du + math.pi) % (2 * math.pi) - math.pi
    xy = np.column_stack([metric * du, grid.uv[:, 1] - start[1]])
    touched = K.deposit_segment(
        grid.lattice, grid.rows, grid.col, grid.areas, grid.depth, start[0], start[1], step[0],
        step[1], a, K.HERTZ if hertz else K.FLAT, amount, grid.index, grid.weight,
    )  # fmt: skip
    # the cells within a of the segment (the reference is 0 elsewhere)
    t = np.clip(xy @ np.asarray(step) / float(np.dot(step, step)), 0.0, 1.0)
    near = np.linalg.norm(xy - t[:, None] * np.asarray(step)[None, :], axis=1) < a
    reference = np.zeros(xy.shape[0])
    reference[near] = _segment_reference(xy[near], np.zeros(2), np.asarray(step), a, hertz)
    reference *= amount / float(reference @ grid.areas)
    peak = float(reference.max())
    assert touched == int((grid.depth > 0).sum()) > 1000
    assert float(grid.depth @ grid.areas) == pytest.approx(amount, rel=1e-12)
    # the flat pad's indicator is discontinuous: the rule's own error is a step of the 20,000
    tolerance = 1e-4 if hertz else 5e-4
    assert np.abs(grid.depth - reference).max() <= tolerance * peak

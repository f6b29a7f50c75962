"""Preston removal through whole runs (``[tool.pad]`` + ``[removal]``): the removed volume
against k_p ∫ F_n |v_t| dt computed from the recorded force and the tip velocity J(q) v
(Pinocchio), the cross-pass profiles against Hertz's and the flat pad's closed forms, a
raster's uniformity against the analytic superposition of its passes' profiles, and the
reader's refusals (file, key, value)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hybrid_force.errors import ScenarioError
from hybrid_force.result import Result
from hybrid_force.result_summary import REMOVAL_KEYS
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.schema_docs import json_schema
from hybrid_force.sim.loop import simulate
from hybrid_force.sim.removal import FlatPad, HertzPad, flat_profile, hertz_profile
from hybrid_force.sim.removal_run import BATCH, RemovalObserver

REPO = Path(__file__).resolve().parents[1]
SCENARIOS = REPO / "scenarios"
K_P = 1e-13  # m²/N
HERTZ = {"type": "hertz", "radius": 0.02, "modulus": 5e6}
FLAT = {"type": "flat", "radius": 0.004}


def _run(name: str, overrides: dict[str, Any]) -> tuple[Any, Result]:
    sc = load_scenario(SCENARIOS / name, overrides)
    return sc, simulate(sc)


def _preston_volume(sc: Any, r: Result) -> float:
    """k_p Σ_i F_i |P_n J(q_i) v_i| dt over the samples i < N − 1 (left rectangles), from the
    recorded force and the Jacobian of the arm's own model (not the observer's terms)."""
    surface, dt = sc.surfaces[0], sc.sim.dt
    total = 0.0
    for i in range(r.n_samples - 1):
        force = float(np.atleast_1d(r.f[i])[0])
        if force <= 0.0:
            continue
        velocity = sc.robot.jacobian(r.q[i]) @ r.v[i]
        n = surface.gradient(r.p[i])
        n = n / np.linalg.norm(n)
        total += force * float(np.linalg.norm(velocity - (velocity @ n) * n)) * dt
    return K_P * total


@pytest.mark.parametrize(
    ("scenario", "overrides"),
    [
        ("rtr_plane.toml", {"sim.duration": 2.0}),
        ("paper_contact.toml", {"sim.duration": 1.5, "initial.tip": [0.4, 0.0, 10.0]}),
        ("rtr_sphere.toml", {"sim.duration": 1.5}),
    ],
    ids=["plane", "cylinder", "sphere"],
)
def test_removed_volume_is_preston_integral_of_force_times_speed(
    scenario: str, overrides: dict[str, Any]
) -> None:
    """∫ p dA = F_n for a non-rotating pad: the volume is k_p ∫ F_n v dt (to 0.5 %)."""
    removal = {"k_p": K_P, "resolution": 4e-4}
    sc, r = _run(scenario, {**overrides, "tool.pad": HERTZ, "removal": removal})
    expected = _preston_volume(sc, r)
    assert expected > 0
    summary = r.summary()
    assert summary["removal_volume"] == pytest.approx(expected, rel=5e-3)
    # the file's arrays give the same volume: Σ h_i A_i with the grid's areas
    assert r.removal_depth is not None and r.removal_points is not None
    assert r.meta["removal"]["conforming_steps"] == 0


def test_removal_never_changes_the_motion_and_batches_as_sample_by_sample() -> None:
    """q, v, u, f of a run are bit-identical with removal on and off; the run's batched
    deposit (J v kept per sample, deposited every BATCH samples) gives the depth of the same
    samples deposited one by one, with J v from Pinocchio's Jacobian (to round-off)."""
    overrides = {"sim.duration": 0.6, "initial.tip": [0.4, 0.0, 10.0]}
    removal = {"k_p": K_P, "resolution": 4e-4}
    _, off = _run("paper_contact.toml", overrides)
    sc, on = _run("paper_contact.toml", {**overrides, "tool.pad": HERTZ, "removal": removal})
    for name in ("q", "v", "u", "f"):
        assert np.array_equal(getattr(on, name), getattr(off, name)), name
    observer = RemovalObserver(sc, on.n_samples)  # not attached: one deposit per call
    for i in range(on.n_samples):
        pdot = sc.robot.jacobian(on.q[i]) @ on.v[i]
        observer.observe(i, on.p[i], pdot, np.atleast_1d(on.f[i]))
    observer.finish(on.n_samples)
    assert on.removal_depth is not None and on.n_samples - 1 > BATCH
    assert observer.steps == on.meta["removal"]["steps"] > BATCH
    scale = float(on.removal_depth.max())
    assert scale > 0
    assert np.abs(observer.grid.depth - on.removal_depth).max() <= 1e-9 * scale


def _sub_sampled_depth(sc: Any, r: Result, sub: int) -> tuple[np.ndarray, RemovalObserver]:
    """The reference depth of a run's removal: each sample's span [t_i, t_i + dt) cut into
    ``sub`` point deposits (the tip moved linearly from p_i to p_{i+1}, the force and J v of
    sample i held), each deposited alone (no segments, no merging: the kernel's point
    deposit); and the run's observer (its grid holds the reference)."""
    from hybrid_force.sim import _removal_kernels as K

    n = r.n_samples
    tips = np.asarray(r.p, dtype=float)
    forces = np.asarray(r.f, dtype=float).reshape(n, -1)
    velocities = np.array([sc.robot.jacobian(r.q[i]) @ r.v[i] for i in range(n)])
    w = (np.arange(sub) / sub)[None, :, None]
    fine_tips = (tips[:-1, None, :] * (1 - w) + tips[1:, None, :] * w).reshape(-1, 3)
    fine_tips = np.ascontiguousarray(np.vstack([fine_tips, tips[-1:]]))
    fine_forces = np.ascontiguousarray(
        np.vstack([np.repeat(forces[:-1], sub, axis=0), forces[-1:]])
    )
    fine_velocities = np.repeat(velocities[:-1], sub, axis=0)
    obs = RemovalObserver(sc, n)
    g, tally = obs.grid, np.zeros(2, dtype=np.int64)
    m = fine_tips.shape[0] - 1
    factor, dt = obs._factor / sub, sc.sim.dt / sub
    for first in range(0, m, BATCH):
        count = min(BATCH, m - first)
        K.observe_batch(
            obs._desc, fine_tips, fine_forces, obs.surface_index,
            np.ascontiguousarray(fine_velocities[first : first + count]), first, count,
            obs._shape, obs.pad.radius, obs._modulus, 0.0, 0.0, factor, 0.0, 0.0, dt, g.points,
            g.areas, g.order, g.table, g.starts, g.box, g.dims, g.lattice, g.rows, g.col,
            g.depth, obs._group, obs._work, g.index, g.weight, tally,
        )  # fmt: skip
    K.flush(
        obs._group, obs._shape, factor, g.points, g.areas, g.order, g.table, g.starts, g.box,
        g.dims, g.lattice, g.rows, g.col, g.depth, obs._work, g.index, g.weight,
    )  # fmt: skip
    return g.depth.copy(), obs


@pytest.mark.parametrize(
    ("scenario", "overrides"),
    [
        ("paper_contact.toml", {"sim.duration": 1.5, "initial.tip": [0.4, 0.0, 10.0]}),
        ("rtr_plane.toml", {"sim.duration": 2.0}),
    ],
    ids=["cylinder-helix", "plane"],
)
def test_segment_deposits_match_sub_sampled_point_deposits(
    scenario: str, overrides: dict[str, Any]
) -> None:
    """A tool that does not spin on a plane's or a cylinder's chart deposits straight segments
    of samples (docs/removal.md, "Cost"): the run's depth against each sample's span cut
    into 20 point deposits (the helix moves 0.41 mm a sample, rtr_plane's circle 0.3 mm: as far
    as a 0.3 mm cell), to
    1 % of the peak depth everywhere, the volume to round-off."""
    removal = {"k_p": K_P, "resolution": 3e-4}
    sc, r = _run(scenario, {**overrides, "tool.pad": HERTZ, "removal": removal})
    reference, obs = _sub_sampled_depth(sc, r, 20)
    assert obs._deviation > 0.0  # the segments, not the merged points
    assert r.removal_depth is not None
    peak = float(reference.max())
    assert peak > 0.0
    assert np.abs(r.removal_depth - reference).max() <= 0.01 * peak
    volume = float(reference @ obs.grid.areas)
    assert float(r.removal_depth @ obs.grid.areas) == pytest.approx(volume, rel=1e-9)


# a sphere of radius 0.5 m as a 20,480-face mesh where rtr_sphere.toml has its sphere
MESH_CENTRE = np.array([0.0, 0.0, 5.0])
MESH_NORMAL = np.array([0.8, 0.0, -0.6])  # the sphere's outward normal at rtr_sphere's start
MESH_PATHS = {
    "circle": {"type": "circle", "center": [0.0, 0.0, 4.7], "radius": 0.4,
               "normal": [0.0, 0.0, 1.0], "omega": 0.5, "phase": 0.0},
    "raster": {"type": "raster", "origin": [-0.01, -0.01], "size": [0.02, 0.02],
               "spacing": 0.005, "speed": 0.05, "ramp": 0.1},
}  # fmt: skip


@pytest.mark.parametrize("path", sorted(MESH_PATHS))
@pytest.mark.usefixtures("field_cache")
def test_removed_volume_is_preston_integral_on_a_mesh_part(path: str, tmp_path: Path) -> None:
    """The same identity on a mesh part (removal cells on its triangles, ∇Φ from its smooth
    field): a circle of latitude (world frame) and a raster in a projection chart on an
    icosphere, to 0.5 %; the cells lie on the mesh's triangles (trimesh's closest point) and
    the depth only within the patch radius of the tip's track."""
    import trimesh

    from hybrid_force._file_errors import _Context
    from hybrid_force.geometry.mesh_surface import MeshSurface
    from hybrid_force.scenario._builders import _trajectory

    mesh = trimesh.creation.icosphere(subdivisions=5, radius=0.5)
    mesh.export(tmp_path / "sphere.stl")
    start = np.array([0.4, 0.0, 4.7])
    chart = {"type": "projection", "origin": (start + 0.1 * MESH_NORMAL).tolist(),
             "normal": (-MESH_NORMAL).tolist(), "u_axis": [0.0, 1.0, 0.0]}  # fmt: skip
    table = {"type": "mesh", "file": str(tmp_path / "sphere.stl"), "resolution": 0.0175,
             "position": MESH_CENTRE.tolist()}  # fmt: skip
    if path == "raster":  # (a chart acts only with a path laid in (u, v))
        table["chart"] = chart
    # the run starts in contact: at the path's start, on the field's Φ = 0
    surface = MeshSurface.from_table(table, tmp_path, "surface")
    trajectory = MESH_PATHS[path]
    tip = _trajectory(trajectory, [surface], _Context("x"))[0].position(0.0)
    tip = surface.closest_point(tip)
    removal = {"k_p": K_P, "resolution": 5e-4}
    overrides = {"surface": table, "trajectory": trajectory, "initial.tip": tip.tolist()}
    sc, r = _run(
        "rtr_sphere.toml", {**overrides, "sim.duration": 1.5, "tool.pad": HERTZ, "removal": removal}
    )
    assert isinstance(sc.surfaces[0], MeshSurface) and r.meta["removal"]["grid"] == "mesh"
    expected = _preston_volume(sc, r)
    assert expected > 0
    assert r.summary()["removal_volume"] == pytest.approx(expected, rel=5e-3)
    assert r.meta["removal"]["conforming_steps"] == 0
    points, depth = r.removal_points, r.removal_depth
    assert points is not None and depth is not None
    worn = points[depth > 0]
    rng = np.random.default_rng(31)
    some = worn[rng.choice(worn.shape[0], size=min(500, worn.shape[0]), replace=False)]
    placed = trimesh.load(tmp_path / "sphere.stl")  # (the file's float32 vertices)
    placed.apply_translation(MESH_CENTRE)
    _, gap, _ = trimesh.proximity.closest_point(placed, some)
    assert float(gap.max()) < 1e-9
    # the patch never reaches beyond a (at the largest force; R_eff = the pad's radius, larger
    # than on this convex part) + one cell (the ~19 mm facets split 38 times) of the track
    forces = np.atleast_1d(r.f).reshape(r.n_samples, -1)[:, 0]
    track = r.p[forces > 0]
    a_max = HertzPad(HERTZ["radius"], HERTZ["modulus"]).patch(float(forces.max()))[0]
    reach = max(float(np.linalg.norm(track - w, axis=1).min()) for w in worn)
    assert reach < a_max + 5e-4, (reach, a_max)


def _straight_pass(
    pad: dict[str, Any], tmp_path: Path, speed: float = 0.05, half: float = 0.03
) -> tuple[Any, Result]:
    """A straight pass along y from −half to half [m] at x = 0.6 on rtr_plane's plane z = 5 at
    ``speed`` [m/s], starting in contact."""
    return _run(
        "rtr_plane.toml",
        {
            "trajectory": {
                "type": "waypoints",
                "frame": "surface",
                "points": [[0.6, -half], [0.6, half]],
                "speed": speed,
                "ramp": 0.2,
            },
            "initial.tip": [0.6, -half, 5.0],
            "control.supervisor": False,
            "sim.duration": round(2 * half / speed + 0.4, 3),
            "tool.pad": pad,
            "removal": {"k_p": K_P, "resolution": 1e-4},
        },
    )


@pytest.mark.parametrize(
    ("pad", "speed"),
    [(HERTZ, 0.05), (FLAT, 0.05), (HERTZ, 0.01), (FLAT, 0.01)],
    ids=["hertz", "flat", "hertz-slow", "flat-slow"],
)
def test_straight_pass_profile_matches_the_closed_form(
    pad: dict[str, Any], speed: float, tmp_path: Path
) -> None:
    """Across a straight pass at constant force: Hertz h(x) = k_p p₀ π (a² − x²)/(2a), the
    flat pad h(x) = 2 k_p p √(a² − x²), within 2 % of the peak, with a, p₀ from the recorded
    force where the tool crossed the section (x across the pass, from the tip's track); and
    the volume k_p ∫ F v dt to 0.5 %. At 0.01 m/s the samples are 10 µm apart and about three
    are deposited as one (docs/removal.md, "Cost"); at 0.05 m/s each alone."""
    sc, r = _straight_pass(pad, tmp_path, speed, 0.03 if speed > 0.02 else 0.01)
    assert r.summary()["removal_volume"] == pytest.approx(_preston_volume(sc, r), rel=5e-3)
    points, depth = r.removal_points, r.removal_depth
    assert points is not None and depth is not None
    # the section y ∈ [−2 mm, 2 mm], crossed at steady speed and force
    crossing = np.abs(r.p[:, 1]) < 0.004
    force = float(np.mean(r.f[crossing]))
    track_x = float(np.mean(r.p[crossing, 0]))
    assert abs(force - 10.0) < 0.5  # the law holds the desired force there
    model = HertzPad(pad["radius"], pad["modulus"]) if pad["type"] == "hertz" else None
    if model is not None:
        a, p0 = model.patch(force)
        expected = hertz_profile(points[:, 0] - track_x, a, p0, K_P)
    else:
        flat = FlatPad(pad["radius"])
        a, p = flat.patch(force)
        expected = flat_profile(points[:, 0] - track_x, a, p, K_P)
    section = np.abs(points[:, 1]) < 0.002
    peak = float(expected[section].max())
    error = float(np.abs(depth[section] - expected[section]).max())
    assert error < 0.02 * peak, (error / peak, a)
    # and the patch is as wide as the closed form's: nothing beyond a (+ one cell)
    assert np.all(depth[section][np.abs(points[section, 0] - track_x) > a + 1e-4] == 0.0)


def _raster_uniformity(spacing: float) -> tuple[float, float, Any, Result]:
    """(the run's uniformity over the rectangle away from the turns, the analytic
    superposition's) of a raster with passes along y on rtr_plane's plane."""
    origin, size = [0.58, -0.02], [0.02, 0.04]
    sc, r = _run(
        "rtr_plane.toml",
        {
            "trajectory": {
                "type": "raster",
                "origin": origin,
                "size": size,
                "spacing": spacing,
                "speed": 0.1,
                "direction": "v",
                "ramp": 0.2,
            },
            "initial.tip": [origin[0], origin[1], 5.0],
            "control.supervisor": False,
            "sim.duration": 5.0,
            "tool.pad": HERTZ,
            "removal": {"k_p": K_P, "resolution": 1e-4},
        },
    )
    # the simulated time the path needs: its duration (held at rest afterwards)
    assert r.meta["removal"]["target"] == "rectangle"
    points, depth, target = r.removal_points, r.removal_depth, r.removal_target
    assert points is not None and depth is not None and target is not None
    in_contact = np.atleast_1d(r.f) > 0
    force = float(np.median(np.atleast_1d(r.f)[in_contact]))
    a, p0 = HertzPad(HERTZ["radius"], HERTZ["modulus"]).patch(force)
    # away from the turns: the passes' ends within 1.5 a of the rectangle's v edges
    middle = origin[1] + size[1] / 2
    inner = (target > 0) & (np.abs(points[:, 1] - middle) < size[1] / 2 - 1.5 * a)
    h = depth[inner]
    run_u = 1.0 - float(h.std()) / float(h.mean())
    passes = sc.path.passes
    centres = origin[0] + sc.path.pass_spacing * np.arange(passes)
    x = np.linspace(origin[0], origin[0] + size[0], 20001)
    analytic = sum(hertz_profile(x - c, a, p0, K_P) for c in centres)
    expected_u = 1.0 - float(analytic.std()) / float(analytic.mean())
    return run_u, expected_u, sc, r


@pytest.mark.parametrize("ratio", [0.5, 1.0, 1.5])
def test_raster_uniformity_matches_the_superposition_of_pass_profiles(ratio: float) -> None:
    """Uniformity 1 − std/mean of a raster against spacing / contact diameter: the run's and
    the analytic Σ_k h(x − x_k) (Hertz profiles at the pass centres) within 0.02."""
    a0 = HertzPad(HERTZ["radius"], HERTZ["modulus"]).patch(10.0)[0]
    run_u, expected_u, _, r = _raster_uniformity(ratio * 2 * a0)
    assert abs(run_u - expected_u) < 0.02, (run_u, expected_u)
    assert r.summary()["removal_uniformity"] is not None


def test_no_removal_table_no_removal_arrays() -> None:
    sc, r = _run("rtr_sphere.toml", {"sim.duration": 0.05})
    assert sc.removal is None and r.removal_depth is None and "removal" not in r.meta
    assert all(r.summary()[key] is None for key in REMOVAL_KEYS)


def test_result_file_keeps_the_removal(tmp_path: Path) -> None:
    _, r = _run(
        "rtr_sphere.toml",
        {"sim.duration": 0.3, "tool.pad": FLAT, "removal": {"k_p": K_P, "resolution": 1e-3}},
    )
    back = Result.load(r.save(tmp_path / "result.npz"))
    assert back.removal_points is not None and r.removal_points is not None
    assert np.array_equal(back.removal_depth, r.removal_depth)
    assert back.removal_points.shape == (r.removal_points.shape[0], 3)
    short = r.truncated(10)  # per cell, not per sample: kept whole
    assert np.array_equal(short.removal_depth, r.removal_depth)
    summary = back.summary()
    w = back.removal_target > 0
    depth = back.removal_depth[w]
    assert summary["removal_depth_max"] == pytest.approx(float(depth.max()), rel=1e-12)
    assert summary["removal_coverage"] is not None
    assert json.loads(json.dumps(summary))["removal_volume"] == summary["removal_volume"]


def _doc(**tables: Any) -> dict[str, Any]:
    import tomllib

    doc = tomllib.loads((SCENARIOS / "rtr_sphere.toml").read_text())
    doc.update(tables)
    return doc


def _write(tmp_path: Path, doc: dict[str, Any]) -> Path:
    """The document as a TOML file (tables only one level deep, plus [tool.pad])."""

    def value(v: Any) -> str:
        return json.dumps(v)

    lines = [f"name = {value(doc['name'])}"]
    for table, keys in doc.items():
        if not isinstance(keys, dict):
            continue
        lines.append(f"[{table}]")
        for k, v in keys.items():
            if isinstance(v, dict):
                continue
            lines.append(f"{k} = {value(v)}")
        for k, v in keys.items():
            if isinstance(v, dict):
                lines.append(f"[{table}.{k}]")
                lines.extend(f"{kk} = {value(vv)}" for kk, vv in v.items())
    path = tmp_path / "s.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_removal_without_pad_and_pad_without_removal_are_refused(tmp_path: Path) -> None:
    removal = {"k_p": K_P, "resolution": 1e-3}
    path = _write(tmp_path, _doc(removal=removal))
    needs_pad = r"s\.toml: removal = .*needs the tool's contact pad.*\[tool\.pad\]"
    with pytest.raises(ScenarioError, match=needs_pad):
        load_scenario(path)
    path = _write(tmp_path, _doc(tool={"pad": HERTZ}))
    with pytest.raises(ScenarioError, match=r"s\.toml: tool\.pad = .*no effect.*\[removal\]"):
        load_scenario(path)


@pytest.mark.parametrize(
    ("pad", "removal", "message"),
    [
        (HERTZ, {"k_p": -1.0, "resolution": 1e-3}, r"removal\.k_p = -1\.0: .*> 0"),
        (HERTZ, {"k_p": K_P}, r"removal\.resolution: missing required key"),
        (HERTZ, {"k_p": K_P, "resolution": 1e-3, "rpm": 1.0}, r"removal\.rpm = 1\.0: unknown"),
        (
            HERTZ,
            {"k_p": K_P, "resolution": 1e-3, "spindle_schedule": "feed"},
            r'removal\.spindle_schedule = "feed": .*spindle_speed > 0',
        ),
        ({"type": "hertz", "radius": 0.02}, {"k_p": K_P, "resolution": 1e-3}, r"modulus"),
        ({"type": "round", "radius": 0.02}, {"k_p": K_P, "resolution": 1e-3}, r"tool\.pad\.type"),
        (
            {"type": "flat", "radius": 0.0},
            {"k_p": K_P, "resolution": 1e-3},
            r"tool\.pad\.radius = 0\.0",
        ),
        (
            {"type": "flat", "radius": 0.01, "modulus": 1e6},
            {"k_p": K_P, "resolution": 1e-3},
            r"tool\.pad\.modulus = .*unknown key for a flat",
        ),
    ],
)
def test_bad_removal_keys_name_the_file_key_and_value(
    tmp_path: Path, pad: dict[str, Any], removal: dict[str, Any], message: str
) -> None:
    path = _write(tmp_path, _doc(tool={"pad": pad}, removal=removal))
    with pytest.raises(ScenarioError, match=rf"s\.toml: .*{message}"):
        load_scenario(path)


def test_a_hertz_pad_larger_than_a_concave_part_is_refused(tmp_path: Path) -> None:
    """Inside a pipe of radius 0.15 m a pad of radius 0.5 m conforms (1/0.5 − 1/0.15 < 0)."""
    sc = load_scenario(SCENARIOS / "panda_pipe_tilt.toml")
    assert sc.surfaces[0].inside
    with pytest.raises(ScenarioError, match=r"tool\.pad\.radius = 0\.5 m: the part is concave"):
        load_scenario(
            SCENARIOS / "panda_pipe_tilt.toml",
            {
                "tool.pad": {"type": "hertz", "radius": 0.5, "modulus": 1e6},
                "removal": {"k_p": K_P, "resolution": 1e-3},
            },
        )


def test_the_json_schema_takes_the_pad_and_removal() -> None:
    jsonschema = pytest.importorskip("jsonschema")
    schema = json_schema()
    doc = _doc(tool={"pad": HERTZ}, removal={"k_p": K_P, "resolution": 1e-3})
    jsonschema.validate(doc, schema)
    bad = _doc(tool={"pad": {"type": "flat", "radius": 0.01, "modulus": 1.0}})
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(bad, schema)
    assert math.isclose(
        schema["properties"]["removal"]["properties"]["k_p"]["exclusiveMinimum"], 0.0
    )


def test_the_removal_map_is_drawn_on_the_unrolled_surface(tmp_path: Path) -> None:
    """``removal.png`` in --plot's figures; the cylinder is unrolled by arc length: two cells
    0.1 rad apart at one height are r · 0.1 apart on the map."""
    pytest.importorskip("matplotlib")
    from hybrid_force.viz.removal_figure import unrolled
    from hybrid_force.viz.run_figures import plot_result

    sc, r = _run(
        "paper_contact.toml",
        {
            "sim.duration": 0.3,
            "initial.tip": [0.4, 0.0, 10.0],
            "tool.pad": FLAT,
            "removal": {"k_p": K_P, "resolution": 1e-3},
        },
    )
    written = plot_result(r, tmp_path)
    assert tmp_path / "removal.png" in written and (tmp_path / "removal.png").stat().st_size > 0
    assert r.removal_points is not None
    unroll, _, _ = unrolled(r.removal_points, r.meta)
    radius = sc.surfaces[0].radius
    two = np.array([[radius, 0.0, 10.0], [radius * math.cos(0.1), radius * math.sin(0.1), 10.0]])
    xy = unroll(two)
    assert abs(xy[1, 0] - xy[0, 0]) == pytest.approx(radius * 0.1, rel=1e-12)
    assert xy[1, 1] == pytest.approx(xy[0, 1], abs=1e-12)


def test_spindle_dwell_gives_the_rotating_hertz_profile() -> None:
    """A tool at rest on the plane, spinning at ω: a point at r from the patch centre slides
    at ω r, so the depth grows as k_p p₀ √(1 − r²/a²) ω r per second (Preston, Hertz). The
    difference of two runs that end 0.5 s apart during the same dwell, within 2 % of its
    peak (k_p p₀ ω a / 2 at r = a/√2)."""
    rpm = 600.0
    omega = rpm * 2 * math.pi / 60

    def dwell(duration: float) -> Result:
        return _run(
            "rtr_plane.toml",
            {
                "trajectory": {
                    "type": "waypoints",
                    "frame": "surface",
                    "points": [[0.6, 0.0], [0.6, 0.002]],
                    "speed": 0.01,
                    "ramp": 0.1,
                },
                "initial.tip": [0.6, 0.0, 5.0],
                "control.supervisor": False,
                "sim.duration": duration,
                "tool.pad": HERTZ,
                "removal": {"k_p": K_P, "resolution": 1e-4, "spindle_speed": rpm},
            },
        )[1]

    short, long = dwell(1.5), dwell(2.0)
    points, grown = long.removal_points, long.removal_depth - short.removal_depth
    assert points is not None and short.removal_points is not None
    assert np.array_equal(points, short.removal_points)  # the same grid (the same path)
    rest = long.t >= 1.5
    force = float(np.mean(long.f[rest]))
    centre = np.mean(long.p[rest], axis=0)
    assert float(np.max(np.abs(long.p[rest] - centre))) < 1e-6  # at rest
    a, p0 = HertzPad(HERTZ["radius"], HERTZ["modulus"]).patch(force)
    r = np.linalg.norm(points[:, :2] - centre[:2], axis=1)
    # samples 1500 … 1999 of the longer run deposit (the last one stands for nothing)
    seconds = 500 * 1e-3
    expected = np.where(r < a, K_P * p0 * np.sqrt(np.clip(1 - (r / a) ** 2, 0, 1)) * omega * r, 0)
    expected *= seconds
    peak = K_P * p0 * omega * a / 2 * seconds
    assert float(expected.max()) == pytest.approx(peak, rel=1e-3)
    error = float(np.abs(grown - expected).max())
    assert error < 0.02 * peak, error / peak


def _spun_pass(speed: float, rpm: float, schedule: str, dwell: float = 0.0) -> Result:
    """A straight pass on the plane at ``speed`` [m/s] with a spindle at ``rpm``, then
    ``dwell`` [s] at rest."""
    removal = {"k_p": K_P, "resolution": 2e-4, "spindle_speed": rpm}
    return _run(
        "rtr_plane.toml",
        {
            "trajectory": {
                "type": "waypoints",
                "frame": "surface",
                "points": [[0.6, -0.02], [0.6, 0.02]],
                "speed": speed,
                "ramp": 0.2,
            },
            "initial.tip": [0.6, -0.02, 5.0],
            "control.supervisor": False,
            "sim.duration": round(0.04 / speed + 0.25 + dwell, 3),
            "tool.pad": HERTZ,
            "removal": {**removal, "spindle_schedule": schedule},
        },
    )[1]


def test_the_feed_schedule_keeps_the_removal_per_unit_length() -> None:
    """With ω = ω₀ |v_t| / v_ref the slip is |v_t + ω n × ρ| = |v_t| |ê + (ω₀/v_ref) n × ρ|, so
    the depth k_p ∫ p · slip dt = k_p ∫ p |ê + (ω₀/v_ref) n × ρ| dℓ depends on the path and
    ω₀/v_ref only, not on how fast the tool goes where (ramps, a dwell):

    * a pass at 0.05 m/s and 600 rpm and the same pass at 0.02 m/s and 240 rpm (the same
      ω₀/v_ref, v_ref each run's cruise speed) remove the same depth, to 1 % of its peak,
      ramps included (with a constant spindle the slower pass removes about 3 × more);
    * a dwell of 0.5 s at the end adds nothing (the tool at rest, the spindle stopped), where a
      constant spindle digs a hole: its deepest point more than doubles.
    """
    fast, slow = _spun_pass(0.05, 600.0, "feed"), _spun_pass(0.02, 240.0, "feed")
    assert fast.meta["removal"]["v_ref"] == pytest.approx(0.05, rel=1e-3)
    assert fast.removal_depth is not None and slow.removal_depth is not None
    peak = float(fast.removal_depth.max())
    assert float(np.abs(fast.removal_depth - slow.removal_depth).max()) < 0.01 * peak
    constant = _spun_pass(0.02, 600.0, "constant").removal_depth
    assert constant is not None and float(constant.max()) > 1.8 * peak
    dwelt = _spun_pass(0.05, 600.0, "feed", dwell=0.5).removal_depth
    assert dwelt is not None
    assert float(np.abs(dwelt - fast.removal_depth).max()) < 5e-3 * peak  # (0.16 %: settling)
    held = _spun_pass(0.05, 600.0, "constant", dwell=0.5).removal_depth
    moving = _spun_pass(0.05, 600.0, "constant").removal_depth
    assert held is not None and moving is not None
    assert float(held.max()) > 2.0 * float(moving.max())


def test_a_mesh_grid_splits_the_triangles_near_the_path() -> None:
    """On a mesh the cells are the triangles near the path split into s² equal ones: their
    areas add up to the triangles' (a square of 2 × 2 cm in two triangles), their centres lie
    on them, and a patch deposits F · v · dt · k_p of volume on them (∫ p dA = F)."""
    from types import SimpleNamespace

    from hybrid_force.sim.removal_run import _mesh_grid

    side = 0.02
    part = SimpleNamespace(
        vertices=np.array([[0, 0, 0], [side, 0, 0], [side, side, 0], [0, side, 0]], float),
        faces=np.array([[0, 1, 2], [0, 2, 3]]),
    )
    path = np.column_stack([np.linspace(0.005, 0.015, 50), np.full(50, 0.01), np.zeros(50)])
    grid = _mesh_grid(part, path, margin=0.004, resolution=5e-4)
    s = math.ceil(side / 5e-4)  # the median of the six edges (four sides, two diagonals)
    assert grid.points.shape[0] == 2 * s * s
    assert float(grid.areas.sum()) == pytest.approx(side * side, rel=1e-12)
    assert np.all(grid.points[:, 2] == 0.0)
    pad = HertzPad(HERTZ["radius"], HERTZ["modulus"])
    grid.add(pad, K_P, 1e-3, np.array([0.01, 0.01, 0.0]), np.array([0, 0, 1.0]),
             np.array([0.05, 0, 0]), 10.0)  # fmt: skip
    assert grid.volume == pytest.approx(K_P * 10.0 * 0.05 * 1e-3, rel=1e-12)

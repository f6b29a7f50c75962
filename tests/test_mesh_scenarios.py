"""Mesh parts in scenario files: ``[surface] type = "mesh"`` and its ``[surface.chart]``, the
refusals (exit status 2 naming the key and the value), a sweep whose workers cannot see the
mesh nor the cache (the paper's 6.3 run on a cylinder mesh: tests/test_mesh_convergence.py).

References: the exact sphere and cylinder, central differences of the chart, the analytic
CylinderChart, the built-in paper_contact run."""

from __future__ import annotations

import math
import os
import pickle
import re
import shutil
import subprocess
import sys
import textwrap
import warnings
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pytest
import trimesh
from conftest import point_segment_distances

from hybrid_force.cli import main
from hybrid_force.errors import ModelWarning, PathError
from hybrid_force.geometry.builtin_surfaces import Cylinder
from hybrid_force.geometry.charts import CylinderChart, chart_for
from hybrid_force.geometry.mesh_charts import CylindricalChartSettings, ProjectionChartSettings
from hybrid_force.geometry.mesh_surface import MeshSurface
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

REPO = Path(__file__).resolve().parents[1]
RADIUS = 0.3


pytestmark = pytest.mark.usefixtures("field_cache")  # tests/conftest.py


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("parts")
    trimesh.creation.icosphere(subdivisions=5, radius=RADIUS).export(path / "sphere.stl")
    cylinder = trimesh.creation.cylinder(radius=0.4, height=2.0, sections=512)
    cylinder.apply_translation([0.0, 0.0, 10.5])
    cylinder.export(path / "cyl512.stl")
    return path


@pytest.fixture(scope="module")
def sphere(folder: Path, tmp_path_factory: pytest.TempPathFactory) -> MeshSurface:
    return MeshSurface.from_file(folder / "sphere.stl", resolution=0.0105, cache=False)


def _with_chart(surface: MeshSurface, chart: object) -> MeshSurface:
    return MeshSurface(
        file=surface.file, resolution=surface.resolution, chart=chart,
        part=surface.part, field=surface.field,
    )  # fmt: skip


def _central(chart: object, u: float, v: float, row: int, step: float = 1e-5) -> np.ndarray:
    """(∂/∂u, ∂/∂v) of the chart's row (0: S, 1: S_u, 2: S_v) by central differences."""
    at = chart.derivatives_at  # type: ignore[attr-defined]
    du = (np.array(at(u + step, v)[row]) - np.array(at(u - step, v)[row])) / (2 * step)
    dv = (np.array(at(u, v + step)[row]) - np.array(at(u, v - step)[row])) / (2 * step)
    return np.array([du, dv])


@pytest.mark.parametrize("kind", ["projection", "cylindrical"])
def test_chart_points_lie_on_the_field_and_derivatives_are_central_differences(
    sphere: MeshSurface, kind: str
) -> None:
    if kind == "projection":
        settings: object = ProjectionChartSettings((0.0, 0.0, 0.6), (0.1, 0.0, -1.0), (1, 1, 0))
        points = [(0.05, 0.02), (-0.1, 0.12), (0.18, -0.07)]
    else:
        settings = CylindricalChartSettings((0.01, 0.0, 0.0), (0.0, 0.2, 1.0))
        points = [(0.3, 0.05), (-2.5, -0.12), (3.1, 0.2)]
    chart = chart_for(_with_chart(sphere, settings))
    for u, v in points:
        s, su, sv, suu, suv, svv = (np.array(x) for x in chart.derivatives_at(u, v))
        assert abs(sphere.phi(s)) <= 1e-13
        assert np.linalg.norm(s) == pytest.approx(RADIUS, abs=2e-4)  # on the sphere
        first = _central(chart, u, v, 0)
        np.testing.assert_allclose(first, [su, sv], atol=1e-7)
        np.testing.assert_allclose(_central(chart, u, v, 1), [suu, suv], atol=2e-5)
        np.testing.assert_allclose(_central(chart, u, v, 2), [suv, svv], atol=2e-5)
        # the tangents are tangent: ∇Φ · S_u = ∇Φ · S_v = 0
        n = sphere.normal(s)
        assert abs(n @ su) <= 1e-12 * max(1.0, np.linalg.norm(su))
        assert abs(n @ sv) <= 1e-12 * max(1.0, np.linalg.norm(sv))
        # the inverse: the coordinates of S(u, v) are (u, v)
        np.testing.assert_allclose(chart.unwrap(chart.coordinates(s), (u, v)), (u, v), atol=1e-12)


def test_cylindrical_chart_of_a_cylinder_mesh_is_the_cylinders_chart(folder: Path) -> None:
    surface = MeshSurface.from_file(
        folder / "cyl512.stl", resolution=0.02, chart=CylindricalChartSettings((0, 0, 10.0))
    )
    mesh_chart = chart_for(surface)
    exact = CylinderChart(Cylinder(0.4, center=(0.0, 0.0, 10.0), axis=(0.0, 0.0, 1.0)))
    assert mesh_chart.periods == (2 * math.pi, 0.0)
    sagitta = 0.4 * (1 - math.cos(math.pi / 512))  # the faces inside the vertices' circle
    rng = np.random.default_rng(7)
    for u, v in zip(rng.uniform(-math.pi, math.pi, 30), rng.uniform(0.2, 0.8, 30), strict=True):
        ours = np.array(mesh_chart.derivatives_at(float(u), float(v)))
        theirs = np.array(exact.derivatives_at(float(u), float(v)))
        np.testing.assert_allclose(ours[0], theirs[0], atol=sagitta + 2e-6)
        # S_θ ≈ r e_θ, S_h = a: turned by the field's normal, within 0.05° of the true one
        np.testing.assert_allclose(ours[1:3], theirs[1:3], atol=0.4 * math.radians(0.05))
    # periodic: u and u − 2π are the same point, and the seam at ±π joins
    np.testing.assert_allclose(
        mesh_chart.point(3.0, 0.5), mesh_chart.point(3.0 - 2 * math.pi, 0.5), atol=1e-12
    )
    a = mesh_chart.point(math.pi - 1e-9, 0.5)
    b = mesh_chart.point(-math.pi + 1e-9, 0.5)
    assert np.linalg.norm(a - b) <= 1e-8  # across the seam


def test_a_chart_point_off_the_part_is_refused(sphere: MeshSurface) -> None:
    chart = chart_for(_with_chart(sphere, ProjectionChartSettings((0, 0, 0.6), (0, 0, -1))))
    with pytest.raises(PathError, match=r"surface\.chart \(projection\).*\(0\.5, 0\).*misses"):
        chart.derivatives_at(0.5, 0.0)
    inside = chart_for(_with_chart(sphere, ProjectionChartSettings((0, 0, 0.1), (0, 0, -1))))
    with pytest.raises(PathError, match=r"on the part's side"):
        inside.derivatives_at(0.0, 0.0)
    with pytest.raises(PathError, match="no chart"):
        chart_for(sphere)


def _scenario(folder: Path, surface: str, trajectory: str, name: str = "m") -> Path:
    """A UR5 scenario on ``surface`` following ``trajectory`` (TOML texts), started in contact
    at ``initial.tip = TIP`` (a placeholder: :func:`_with_start`)."""
    head = f'name = "{name}"\n\n[robot]\nmodel = "ur5"\ntip = "tool0"\n'
    rest = (
        "[initial]\ntip = TIP\nseed = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]\n\n"
        "[control]\nsupervisor = false\nf_d = 10.0\n\n[sim]\nduration = 0.2\ndt = 1e-3\n"
    )
    parts = [head, textwrap.dedent(surface).strip(), textwrap.dedent(trajectory).strip(), rest]
    path = folder / f"{name}.toml"
    path.write_text("\n\n".join(parts))
    return path


_SURFACE = """
[surface]
type = "mesh"
file = "sphere.stl"
position = [0.45, 0.1, 0.0]
resolution = 0.0105

[surface.chart]
type = "projection"
origin = [0.55, 0.1, 0.5]
normal = [0.0, 0.0, -1.0]
"""
_RASTER = """
[trajectory]
type = "raster"
origin = [-0.02, -0.02]
size = [0.04, 0.04]
spacing = 0.02
speed = 0.02
"""


def _with_start(path: Path) -> Path:
    """Put the path's start in ``initial.tip``."""
    from hybrid_force._file_errors import _Context
    from hybrid_force.scenario._builders import _surfaces, _trajectory
    from hybrid_force.scenario.loader import read_scenario_document

    text = path.read_text()
    path.write_text(text.replace("TIP", "[0.0, 0.0, 0.0]"))
    doc = read_scenario_document(path)
    surfaces, _ = _surfaces(doc, _Context("x"), path.parent)
    tip = _trajectory(doc["trajectory"], surfaces, _Context("x"))[0].position(0.0).tolist()
    path.write_text(text.replace("TIP", repr(list(tip))))
    return path


def test_a_mesh_scenario_runs_with_a_projected_raster(folder: Path) -> None:
    path = _with_start(_scenario(folder, _SURFACE, _RASTER, "raster_on_sphere"))
    scenario = load_scenario(path)
    (surface,) = scenario.surfaces
    assert isinstance(surface, MeshSurface)
    assert Path(surface.file) == folder / "sphere.stl"  # relative to the scenario file
    # the raster's start: the chart's origin + (u, v) = (−0.02, −0.02), straight down
    start = scenario.path.position(0.0)
    centre = np.array([0.45, 0.1, 0.0])
    assert start[:2] == pytest.approx([0.53, 0.1 + 0.02], abs=1e-12)  # e_v = n × x = y
    assert np.linalg.norm(start - centre) == pytest.approx(RADIUS, abs=2e-4)
    result = simulate(scenario)
    assert np.all(np.isfinite(result.f))
    assert result.meta["surfaces"][0]["type"] == "mesh"
    _draws_its_triangles(result, folder)


def _draws_its_triangles(result: object, folder: Path) -> None:
    """The figures and the replay draw the file's own triangles, placed."""
    from hybrid_force.viz._wireframes import _surface_triangles
    from hybrid_force.viz.scene_objects import _surface_geometry

    meta = result.meta  # type: ignore[attr-defined]
    mesh = trimesh.load(folder / "sphere.stl")
    vertices, faces = _surface_triangles(meta["surfaces"][0], 0, result.p)  # type: ignore[attr-defined]
    assert len(faces) == len(mesh.faces)
    placed = np.asarray(mesh.vertices) + np.array([0.45, 0.1, 0.0])
    np.testing.assert_allclose(np.sort(vertices, axis=0), np.sort(placed, axis=0), atol=1e-12)
    (surface,) = load_scenario(folder / "raster_on_sphere.toml").surfaces
    geometry, transform = _surface_geometry(surface, result.p, 0.05)  # type: ignore[attr-defined]
    assert np.array_equal(transform, np.eye(4))
    assert geometry.vertices.shape == vertices.shape and geometry.faces.shape == faces.shape
    # a big mesh keeps the faces near the motion only, each with a vertex in the padded box
    near_v, near_f = surface.triangles(result.p, 0.05, max_faces=100)  # type: ignore[attr-defined]
    assert 0 < len(near_f) < len(faces)
    low, high = result.p.min(axis=0) - 0.05, result.p.max(axis=0) + 0.05  # type: ignore[attr-defined]
    inside = np.all((near_v >= low - 1e-12) & (near_v <= high + 1e-12), axis=1)
    assert inside[near_f].any(axis=1).all()


def test_world_waypoints_are_projected_onto_the_part(folder: Path) -> None:
    waypoints = """
    [trajectory]
    type = "waypoints"
    points = [[0.56, 0.1, 0.29], [0.54, 0.14, 0.3]]
    speed = 0.01
    projection_tol = 0.05
    """
    path = _with_start(_scenario(folder, _SURFACE, waypoints, "waypoints_on_sphere"))
    scenario = load_scenario(path)
    centre = np.array([0.45, 0.1, 0.0])
    for t in (0.0, scenario.path.duration):
        p = scenario.path.position(t)
        assert np.linalg.norm(p - centre) == pytest.approx(RADIUS, abs=2e-4)
    # the first waypoint's closest point: along the ray from the sphere's centre
    first = np.array([0.56, 0.1, 0.29]) - centre
    expected = centre + RADIUS * first / np.linalg.norm(first)
    np.testing.assert_allclose(scenario.path.position(0.0), expected, atol=3e-4)


def _refusal(path: Path, capsys: pytest.CaptureFixture[str], out: Path) -> str:
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 2
    return capsys.readouterr().err


def test_bad_mesh_input_is_exit_2_naming_the_key_and_value(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "empty.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    tetra = "v 0 0 0\nv {x} 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    (tmp_path / "inf.obj").write_text(tetra.format(x="inf"))  # processing would drop it
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 0.1 0 0\nv 0.2 0 0\nf 1 2 3\n")
    (tmp_path / "index.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    (tmp_path / "garbage.stl").write_bytes(b"\x00\x01garbage" * 10)
    shutil.copy(folder / "sphere.stl", tmp_path / "sphere.stl")
    cases = {
        'file = "nowhere.stl"': r"surface\.file = .*nowhere\.stl.*cannot read",
        'file = "empty.obj"': r"surface\.file = .*empty\.obj.*no triangle faces",
        'file = "nan.obj"': r"surface\.file = .*nan\.obj.*(non-finite|no triangle)",
        'file = "inf.obj"': r"surface\.file = .*inf\.obj.*non-finite vertices.*vertex 1 = \[inf",
        'file = "flat.obj"': r"surface\.file = .*flat\.obj.*all 1 faces have zero area",
        'file = "index.obj"': r"surface\.file = .*index\.obj.*not a readable OBJ mesh",
        'file = "garbage.stl"': r"surface\.file = .*garbage\.stl.*no triangle faces",
        "scale = 1e6": r"surface\.scale = 1000000\.0: .*placed part is 1\.04e\+06 m across",
        "resolution = 0.0001": r"surface\.resolution = 0\.0001 m: the grid would have",
        "scale = -1.0": r"surface\.scale = -1\.0: must be a positive number",
        "chart = 5": r"surface\.chart = 5: must be a table",
    }
    for i, (line, pattern) in enumerate(cases.items()):
        key = line.split(" = ")[0]
        text = _SURFACE.replace('file = "sphere.stl"', "") if key == "file" else _SURFACE
        text = text.replace("resolution = 0.0105", "") if key == "resolution" else text
        text = text.replace("[surface.chart]", f"{line}\n[surface.chart]")
        if key == "chart":
            text = text.split("[surface.chart]")[0].replace("\nchart = 5\n", "\nchart = 5\n")
        path = _scenario(tmp_path, text, _RASTER, f"bad{i}")
        path.write_text(path.read_text().replace("TIP", "[0.53, 0.1, 0.28]"))
        err = _refusal(path, capsys, tmp_path / f"out{i}")
        assert re.search(pattern, err), (line, err)
    # the chart's own keys and a projection that misses the part
    text = _SURFACE.replace('type = "projection"', 'type = "projektion"')
    path = _scenario(tmp_path, text, _RASTER, "bad_kind")
    path.write_text(path.read_text().replace("TIP", "[0.53, 0.1, 0.28]"))
    err = _refusal(path, capsys, tmp_path / "out_kind")
    assert 'surface.chart.type = "projektion": unknown type' in err and "projection" in err
    wide = _RASTER.replace("size = [0.04, 0.04]", "size = [0.8, 0.04]")
    path = _scenario(tmp_path, _SURFACE, wide, "bad_miss")
    path.write_text(path.read_text().replace("TIP", "[0.53, 0.1, 0.28]"))
    err = _refusal(path, capsys, tmp_path / "out_miss")
    assert "trajectory" in err and "surface.chart (projection)" in err and "misses" in err


def test_an_open_mesh_loads_with_a_warning_naming_the_key(tmp_path: Path) -> None:
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=RADIUS)
    mesh.update_faces(np.arange(len(mesh.faces)) != 0)  # a hole (far from the path)
    mesh.export(tmp_path / "sphere.stl")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        coarse = _SURFACE.replace("resolution = 0.0105", "resolution = 0.03")
        load_scenario(_with_start(_scenario(tmp_path, coarse, _RASTER, "open")))
    messages = [str(w.message) for w in caught if issubclass(w.category, ModelWarning)]
    assert any(
        m.startswith("surface.file = 'sphere.stl'") and "trusted only near the surface" in m
        for m in messages
    ), messages


def test_zero_area_faces_are_left_out_with_a_warning(tmp_path: Path) -> None:
    """A closed sphere with one zero-area face added (a repeated vertex): the face would make
    its edge shared by three faces (not watertight, winding-number signs); it is left out with
    a warning naming the count and the face, and the part is the closed sphere again."""
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=RADIUS)
    faces = np.vstack([sphere.faces, [[0, 1, 1]]])
    trimesh.Trimesh(sphere.vertices, faces, process=False).export(tmp_path / "flat.stl")
    from hybrid_force.geometry.mesh_field import read_mesh

    with pytest.warns(
        ModelWarning,
        match=r"surface\.file = .*flat\.stl.*1 of its 1281 faces "
        r"have zero area \(the first: face \d+\); they are left out",
    ):
        part = read_mesh(tmp_path / "flat.stl")
    assert part.watertight and len(part.faces) == len(sphere.faces)


def _run_in_a_fresh_process(task: object) -> dict:
    from hybrid_force.studies.tasks import _execute

    row, _ = _execute(task)  # type: ignore[arg-type]
    return row


def test_a_sweep_worker_gets_the_field_not_the_file(folder: Path, tmp_path: Path) -> None:
    from hybrid_force.studies.tasks import _Source

    study = tmp_path / "study"
    study.mkdir()
    shutil.copy(folder / "sphere.stl", study / "sphere.stl")
    path = _with_start(_scenario(study, _SURFACE, _RASTER, "swept"))
    source = _Source(path)
    tasks = [source.job(f"r{i}", {"control.f_d": f}, keep=False) for i, f in enumerate((8, 12))]
    assert all(not isinstance(t, dict) for t in tasks)
    recorded = source.inputs[str((study / "sphere.stl").resolve())]
    assert recorded["key"] == "surface.file" and recorded["sha256"]
    # the file and the cache are gone before any worker starts; the worker's cache is elsewhere
    (study / "sphere.stl").unlink()
    shutil.rmtree(os.environ["HYBRID_FORCE_CACHE"], ignore_errors=True)
    os.environ["HYBRID_FORCE_CACHE"] = str(tmp_path / "no" / "cache")
    with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as pool:
        rows = list(pool.map(_run_in_a_fresh_process, tasks))
    assert [r["status"] for r in rows] == ["ok", "ok"], rows
    assert not (tmp_path / "no").exists()  # the workers wrote no cache: they built nothing
    assert len(pickle.dumps(tasks[0])) > tasks[0].surfaces["surface"][1].field.coefficients.nbytes


def test_a_dask_sweep_of_a_mesh_scenario_is_the_serial_run_without_the_file(
    folder: Path, tmp_path: Path
) -> None:
    """A sweep on a Dask cluster (local, one worker process) of a mesh scenario: each run is
    bit-identical to the same run made serially here, and its worker never reads a mesh file
    nor a field cache: read_mesh, build_field and load_field raise there, and its cache folder
    is one that does not exist (the sweep would report any such read as a failed row)."""
    pytest.importorskip("distributed")
    from dask.distributed import Client, LocalCluster

    from hybrid_force.result import load_result
    from hybrid_force.studies.sweep import run_sweep
    from hybrid_force.studies.table import read_sweep_csv
    from hybrid_force.studies.variants import run_id

    study = tmp_path / "study"
    study.mkdir()
    shutil.copy(folder / "sphere.stl", study / "sphere.stl")
    path = _with_start(_scenario(study, _SURFACE, _RASTER, "dask_swept"))
    variants = [{"control.f_d": 8.0}, {"control.f_d": 12.0}]
    nowhere = str(tmp_path / "no" / "cache")

    def refuse_mesh_reads() -> None:  # run in the worker (pickled by value: a local function)
        import hybrid_force.geometry.mesh_field as mesh_field
        import hybrid_force.geometry.mesh_surface as mesh_surface

        def refused(*args: object, **kwargs: object) -> None:
            raise AssertionError("a sweep worker read a mesh file or the field cache")

        for module in (mesh_field, mesh_surface):
            for name in ("read_mesh", "build_field", "load_field", "_fit"):
                if hasattr(module, name):
                    setattr(module, name, refused)
        os.environ["HYBRID_FORCE_CACHE"] = nowhere

    with (
        LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        Client(cluster) as client,
    ):
        client.run(refuse_mesh_reads)
        mesh_file = str(study / "sphere.stl")

        def load_in_worker() -> object:
            from hybrid_force.geometry.mesh_surface import MeshSurface as Loaded

            return Loaded.from_file(mesh_file, resolution=0.0105)

        # the control: a worker asked to load the part is refused
        with pytest.raises(AssertionError, match="read a mesh file"):
            client.submit(load_in_worker, pure=False).result()
        csv_path = run_sweep(
            path,
            variants,
            scheduler=cluster.scheduler_address,
            out_dir=tmp_path / "sweep",
            keep_results=True,
            progress=False,
        )
    _, rows = read_sweep_csv(csv_path)
    assert [r["status"] for r in rows] == ["ok", "ok"], rows
    assert not (tmp_path / "no").exists()  # the worker built nothing
    for variant in variants:
        swept = load_result(tmp_path / "sweep" / "results" / f"{run_id(variant)}.npz")
        serial = simulate(load_scenario(path, variant))
        for key in ("q", "v", "u", "f"):
            assert np.array_equal(getattr(swept, key), getattr(serial, key)), (variant, key)


def test_importing_and_running_an_analytic_scenario_loads_neither_igl_nor_trimesh() -> None:
    code = (
        "import sys, hybrid_force\n"
        "from hybrid_force.scenario.loader import load_scenario\n"
        "from hybrid_force.sim.loop import simulate\n"
        f"simulate(load_scenario({str(REPO / 'scenarios' / 'paper_contact.toml')!r}, "
        "{'sim.duration': 0.01}))\n"
        "print([m for m in ('igl', 'trimesh') if m in sys.modules])\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_a_chart_without_a_path_on_the_surface_is_refused(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    shutil.copy(folder / "sphere.stl", tmp_path / "sphere.stl")
    circle = """
    [trajectory]
    type = "circle"
    center = [0.45, 0.1, 0.3]
    radius = 0.01
    normal = [0.0, 0.0, 1.0]
    omega = 1.0
    """
    path = _scenario(tmp_path, _SURFACE, circle, "chart_unused")
    path.write_text(path.read_text().replace("TIP", "[0.46, 0.1, 0.3]"))
    err = _refusal(path, capsys, tmp_path / "out")
    assert "surface.chart = " in err and "has no effect" in err and "raster" in err


@pytest.mark.parametrize("stacked", [False, True])
def test_a_chart_without_a_path_in_surface_coordinates_is_refused(stacked: bool) -> None:
    """``chart`` acts only with waypoints or a raster: given with a circle it is refused, under
    [surface] and under [[surfaces]] alike, naming the table's own key."""
    import tomllib

    from hybrid_force.errors import ScenarioError
    from hybrid_force.scenario.loader import scenario_from_document

    doc = tomllib.loads((REPO / "scenarios" / "ur5_mesh_forearm.toml").read_text())
    circle = {"center": [0.5, 0.1, 0.4], "radius": 0.01, "normal": [0, 0, 1], "omega": 0.5}
    doc["trajectory"] = {"type": "circle", **circle}
    if stacked:
        doc["surfaces"] = [doc.pop("surface")]
    key = r"surfaces\.0\.chart" if stacked else r"surface\.chart"
    with pytest.raises(ScenarioError, match=rf"t\.toml: {key} = .*has no effect.*waypoints"):
        scenario_from_document(doc, origin="t.toml", base_dir=REPO / "scenarios")


def _sphere_with_a_hole_near(folder: Path, point: np.ndarray) -> Path:
    """The raster's sphere (centre at the part's position) without the face nearest
    ``point`` [m] in the world: an open part whose open edges are that face's three."""
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=RADIUS)
    centre = np.array([0.45, 0.1, 0.0])
    nearest = int(np.argmin(np.linalg.norm(mesh.triangles_center + centre - point, axis=1)))
    mesh.update_faces(np.arange(len(mesh.faces)) != nearest)
    mesh.export(folder / "sphere.stl")
    return folder / "sphere.stl"


@pytest.mark.parametrize("near", [True, False])
def test_a_path_near_an_open_edge_warns_where(near: bool, tmp_path: Path) -> None:
    """A hole 25 mm beside the raster (its v edge at y = 0.12 m) lies within 8 h = 84 mm of
    it: the scenario warns, naming the time and the path's point nearest the hole's edges,
    whose distance to them (libigl's, checked here by a point-segment distance written out)
    is the one the message gives. A hole on the far side of the sphere gives no warning."""
    from hybrid_force.errors import RunWarning

    target = np.array([0.55, 0.145, 0.0]) if near else np.array([0.45, 0.1, -1.0])
    target[2] = target[2] if not near else math.sqrt(RADIUS**2 - 0.1**2 - 0.045**2)
    _sphere_with_a_hole_near(tmp_path, target)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scenario = load_scenario(_with_start(_scenario(tmp_path, _SURFACE, _RASTER, "hole")))
    found = [str(w.message) for w in caught if issubclass(w.category, RunWarning)]
    found = [m for m in found if "open edge" in m]
    if not near:
        assert found == []
        return
    (message,) = found
    (surface,) = scenario.surfaces
    part = surface.part
    a, b = part.vertices[part.open_edges[:, 0]], part.vertices[part.open_edges[:, 1]]
    times = np.linspace(0.0, scenario.sim.duration, 2001)
    points = np.array([scenario.path.position(float(t)) for t in times])
    gaps = point_segment_distances(points, a, b)
    j = int(np.argmin(gaps))
    assert gaps[j] < 8 * 0.0105
    assert f"within {gaps[j]:.3g} m of an open edge" in message
    assert f"t = {times[j]:.4g} s" in message

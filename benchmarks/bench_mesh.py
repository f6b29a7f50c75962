"""Benchmark of mesh parts (issue 30): the field's evaluation, a run on a mesh part against the
same run on the analytic surface, building a large part's field, reloading it from the cache.

Run from the repository root:

    python benchmarks/bench_mesh.py [--quick] [--only build] [--json PATH]

Reports, in one run on one machine:

1. Φ, ∇Φ and ∇²Φ together per query: the compiled kernel called from compiled code (a loop
   over 10⁶ points near a 20,480-face sphere's surface, the cost of the arithmetic), and the
   same through ``MeshSurface.evaluate`` from Python (what the loop pays per call);
2. a Panda run on a mesh part against the equivalent analytic surface: panda_pipe_tilt (a pipe
   of radius 0.15 m, worked from inside, tool along the normal) with its cylinder as a
   1024-section cylinder mesh and a cylindrical chart (same coordinates), steps per second of
   the stepping loop (``meta["steps_per_second"]``), runs alternated, best of the repetitions;
3. building the field of a 200,000-face part (a torus, R = 0.2 m, r = 0.05 m) at 2 mm, and
   reloading it from the cache (the wall time of ``build_field`` with the file there), with
   curved facets (the default) and flat ones.

``--only query,pipe,build`` runs some of the three.

Not part of the test suite: timings depend on the machine's load.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import trimesh

REPO = Path(__file__).resolve().parents[1]


def _query_cost(count: int) -> dict[str, float]:
    import numba

    from hybrid_force.geometry import _field_kernels
    from hybrid_force.geometry.mesh_surface import MeshSurface

    folder = Path(tempfile.mkdtemp())
    trimesh.creation.icosphere(subdivisions=5, radius=0.3).export(folder / "sphere.stl")
    surface = MeshSurface.from_file(folder / "sphere.stl", resolution=0.0105, cache=False)
    rng = np.random.default_rng(0)
    d = rng.normal(size=(count, 3))
    points = d / np.linalg.norm(d, axis=1)[:, None] * rng.uniform(0.295, 0.305, count)[:, None]
    field = surface.field

    @numba.njit(cache=False)
    def loop(coef: np.ndarray, origin: np.ndarray, h: float, pts: np.ndarray) -> float:
        grad = np.empty(3)
        hess = np.empty((3, 3))
        total = 0.0
        for i in range(pts.shape[0]):
            total += _field_kernels.field_eval(coef, origin, h, pts[i], grad, hess)
            total += grad[0] + hess[0, 1]
        return total

    loop(field.coefficients, field.origin, field.spacing, points[:10])
    best = math.inf
    for _ in range(3):
        start = time.perf_counter()
        loop(field.coefficients, field.origin, field.spacing, points)
        best = min(best, time.perf_counter() - start)
    calls = points[: count // 10]
    start = time.perf_counter()
    for p in calls:
        surface.evaluate(p)
    python = (time.perf_counter() - start) / len(calls)
    return {"compiled_us": best / count * 1e6, "python_call_us": python * 1e6}


def _panda_pipe(repetitions: int, duration: float) -> dict[str, object]:
    from hybrid_force.scenario.loader import load_scenario
    from hybrid_force.sim.loop import simulate

    folder = Path(tempfile.mkdtemp())
    pipe = trimesh.creation.cylinder(radius=0.15, height=0.6, sections=1024)
    pipe.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
    pipe.apply_translation([0.45, 0.0, 0.4])
    pipe.export(folder / "pipe.stl")
    text = (REPO / "scenarios" / "panda_pipe_tilt.toml").read_text()
    text = text.replace(
        'type = "cylinder"\nradius = 0.15\ncenter = [0.45, 0.0, 0.4]\naxis = [1.0, 0.0, 0.0]\n'
        "inside = true              # the tool works inside the pipe",
        'type = "mesh"\nfile = "pipe.stl"\ninside = true\nresolution = 0.006\n\n'
        '[surface.chart]\ntype = "cylindrical"\ncenter = [0.45, 0.0, 0.4]\naxis = [1.0, 0.0, 0.0]',
    )
    assert 'type = "mesh"' in text
    (folder / "pipe.toml").write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analytic = load_scenario(
            REPO / "scenarios" / "panda_pipe_tilt.toml", {"sim.duration": duration}
        )
        mesh = load_scenario(folder / "pipe.toml", {"sim.duration": duration})
        simulate(load_scenario(folder / "pipe.toml", {"sim.duration": 0.01}))  # warm the kernels
        simulate(load_scenario(REPO / "scenarios" / "panda_pipe_tilt.toml", {"sim.duration": 0.01}))
        rates: dict[str, list[float]] = {"analytic": [], "mesh": []}
        errors: dict[str, float] = {}
        for _ in range(repetitions):
            for name, scenario in (("analytic", analytic), ("mesh", mesh)):
                result = simulate(scenario)
                rates[name].append(float(result.meta["steps_per_second"]))
                late = result.t >= 1.0
                errors[name] = float(np.abs(result.f[late] - 10.0).max())
    best = {k: max(v) for k, v in rates.items()}
    return {
        "steps_per_second": best,
        "all": rates,
        "ratio": best["mesh"] / best["analytic"],
        "force_error_after_1s": errors,
    }


def _build_and_reload(facets: str) -> dict[str, float]:
    from hybrid_force.geometry.mesh_field import build_field, read_mesh

    folder = Path(tempfile.mkdtemp())
    os.environ["HYBRID_FORCE_CACHE"] = str(folder / "cache")
    torus = trimesh.creation.torus(
        major_radius=0.2, minor_radius=0.05, major_sections=500, minor_sections=200
    )
    torus.export(folder / "torus.stl")
    part = read_mesh(folder / "torus.stl")
    start = time.perf_counter()
    field = build_field(part, 0.002, facets=facets)
    build = time.perf_counter() - start
    start = time.perf_counter()
    again = build_field(part, 0.002, facets=facets)
    reload = time.perf_counter() - start
    assert np.array_equal(again.coefficients, field.coefficients)
    nx, ny, nz = field.shape
    return {
        "faces": float(len(part.faces)),
        "nodes": float(nx * ny * nz),
        "build_s": build,
        "reload_s": reload,
        "cache_MB": Path(field.cache_file).stat().st_size / 1e6,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions, shorter runs")
    parser.add_argument("--json", default=None, help="write the numbers to this file")
    parser.add_argument("--only", default="query,pipe,build", help="which parts to run")
    args = parser.parse_args()
    parts = set(args.only.split(","))
    out: dict[str, object] = {}
    if "query" in parts:
        _print_query(out, args.quick)
    if "pipe" in parts:
        _print_pipe(out, args.quick)
    if "build" in parts:
        for facets in ("curved", "flat"):
            big = _build_and_reload(facets)
            out[f"build_{facets}"] = big
            print(
                f"200k-face torus ({big['faces']:.0f} faces) at 2 mm, {facets} facets: "
                f"{big['nodes']:,.0f} nodes, built in {big['build_s']:.1f} s, reloaded from the "
                f"cache in {big['reload_s']:.3f} s ({big['cache_MB']:.0f} MB)",
                flush=True,
            )
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


def _print_query(out: dict[str, object], quick: bool) -> None:
    query = _query_cost(200_000 if quick else 1_000_000)
    out["query"] = query
    print(
        f"Φ, ∇Φ, ∇²Φ per query: {query['compiled_us']:.3f} µs compiled, "
        f"{query['python_call_us']:.2f} µs per MeshSurface.evaluate call from Python"
    )


def _print_pipe(out: dict[str, object], quick: bool) -> None:
    pipe = _panda_pipe(2 if quick else 4, 3.0 if quick else 6.0)
    out["panda_pipe"] = pipe
    rates = pipe["steps_per_second"]
    assert isinstance(rates, dict)
    print(
        f"panda_pipe_tilt: analytic {rates['analytic']:.0f} steps/s, 1024-section mesh "
        f"{rates['mesh']:.0f} steps/s: {100 * float(pipe['ratio']):.0f} % "  # type: ignore[arg-type]
        f"(force error after 1 s: {pipe['force_error_after_1s']})"
    )


if __name__ == "__main__":
    main()

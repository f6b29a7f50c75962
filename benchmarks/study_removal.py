"""The study of docs/removal.md, "Study: law, spacing and feed" (issue 31, item 6).

On a curved part, with friction and force-sensor noise on, which control law, raster spacing
(as a fraction of the contact diameter 2 a₀) and feed give the most uniform Preston removal?

Setup: the RTR arm of the paper on its cylinder (radius 0.4 m, worked from outside), a raster
of passes along the circumference (20 mm of arc each) stacked along the axis over about 24 mm
(the spacing rounded so that a whole number of gaps fills it), 10 N on a Hertz pad (radius
20 mm, E* = 5 MPa: a₀ = 3.08 mm on this cylinder), Preston removal on 0.3 mm cells, Coulomb
friction μ = 0.3 (``contact.friction``, regularised over 2 mm/s) and a force sensor with white
noise σ = 0.5 N behind a 50 Hz low-pass (``sensor.force_noise``, ``sensor.force_cutoff``).
The grid: every registered law × spacing / 2a₀ in {0.4, 0.6, 0.8, 1.0, 1.2} × feed in {0.04,
0.08, 0.16} m/s, a sliding (non-spinning) tool; then the law with the best mean uniformity
again with a spindle at 1500 rpm (spacing × feed).

Measured per run, from its result.npz: the uniformity 1 − std/mean of the depth over the
raster's rectangle away from the turns (the cells more than 1.5 a₀ from the passes' ends),
against the analytic superposition Σ_k h(y − y_k) of the passes' cross profiles at the pass
centres y_k (the Hertz profile k_p p₀ π (a² − y²)/(2a) for the sliding tool; for the spinning
one the profile (k_p/v) ∫ p |v ê + ω n × ρ| dx by Gauss-Legendre quadrature, each pass's
mirrored, as its direction alternates), a and p₀ from the run's median contact force; the
toolkit's own ``removal_uniformity`` and ``removal_coverage`` over the whole rectangle; the
mean depth there; the RMS and largest |f − f_d| of the true force over the cruise.

Prints the tables (Markdown) and writes every row to benchmarks/results/study_removal.json.
The runs go through the sweep machinery (``run_sweep``, resumable in ``--out``). About 5 min
with 2 workers on a shared 2-core machine::

    python benchmarks/study_removal.py [--workers 2] [--out runs/study_removal]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from hybrid_force.control.laws.base import law_names
from hybrid_force.geometry.builtin_surfaces import Cylinder
from hybrid_force.geometry.raster import RasterPath
from hybrid_force.result import Result
from hybrid_force.sim.removal import HertzPad, hertz_profile
from hybrid_force.studies.sweep import run_sweep
from hybrid_force.studies.variants import run_id

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "study_removal.json"

RADIUS = 0.4  # m, the paper's cylinder
F_D = 10.0  # N
PAD = HertzPad(radius=0.02, modulus=5e6)
K_P = 1e-13  # m²/N
RESOLUTION = 3e-4  # m
H0 = 7.0  # m, the height of the first pass
ALONG = 0.020  # m of arc, a pass's length
WIDTH = 0.024  # m, the nominal extent across the passes
RAMP = 0.3  # s
TAIL = 0.2  # s simulated after the path's end
RATIOS = (0.4, 0.6, 0.8, 1.0, 1.2)  # spacing / contact diameter
FEEDS = (0.04, 0.08, 0.16)  # m/s
SPINDLE_RPM = 1500.0

#: κ of the cylinder worked from outside: 1/R around it, 0 along its axis.
A0, P0 = PAD.patch(F_D, 1.0 / RADIUS, 0.0)

SCENARIO = f"""# written by benchmarks/study_removal.py: the paper's RTR cylinder, a raster
name = "study_removal"

[robot]
model = "rtr"

[surface]
type = "cylinder"
radius = {RADIUS}
center = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
inside = false

[trajectory]
type = "raster"
origin = [0.0, {H0}]
size = [{ALONG / RADIUS}, {WIDTH}]
spacing = {WIDTH / 4}
speed = 0.05
direction = "u"
ramp = {RAMP}

[initial]
tip = [{RADIUS}, 0.0, {H0}]
seed = [0.0, 6.0, 2.0]

[control]
supervisor = false
f_d = {F_D}

[contact]
friction = 0.3
friction_velocity = 2e-3

[sensor]
force_noise = 0.5
force_cutoff = 50.0

[tool.pad]
type = "hertz"
radius = {PAD.radius}
modulus = {PAD.modulus}

[removal]
k_p = {K_P}
resolution = {RESOLUTION}

[sim]
duration = 3.0
dt = 1e-3
"""


def _raster(ratio: float, feed: float) -> tuple[RasterPath, float]:
    """The raster of a spacing ratio and a feed, and its extent across the passes [m]."""
    spacing = ratio * 2.0 * A0
    gaps = max(1, round(WIDTH / spacing))
    across = gaps * spacing
    path = RasterPath(
        Cylinder(RADIUS),
        [0.0, H0],
        [ALONG / RADIUS, across],
        spacing * (1.0 + 1e-9),  # a whole number of gaps: n = gaps + 1 passes
        feed,
        direction="u",
        ramp=RAMP,
    )
    assert path.passes == gaps + 1, (ratio, path.passes, gaps)
    return path, across


def _variant(law: str, ratio: float, feed: float, rpm: float = 0.0) -> dict[str, Any]:
    path, across = _raster(ratio, feed)
    variant: dict[str, Any] = {
        "control.law": law,
        "trajectory.size": [ALONG / RADIUS, across],
        "trajectory.spacing": ratio * 2.0 * A0 * (1.0 + 1e-9),
        "trajectory.speed": feed,
        "sim.duration": round(path.duration + TAIL, 3),
    }
    if rpm:
        variant["removal.spindle_speed"] = rpm
    return variant


def spindle_profile(y: np.ndarray, a: float, p0: float, v: float, omega: float) -> np.ndarray:
    """The depth (M,) [m] a Hertz patch (radius a [m], peak p0 [Pa]) spinning at ω [rad/s]
    about the normal removes at the lateral offsets y (M,) [m] of a straight pass at v [m/s]:
    (k_p / v) ∫ p(x, y) |(v − ω y) ê + ω x (n × ê)| dx (the slip of the pad's point at
    ρ = x ê + y n × ê, ê the direction of travel), by Gauss-Legendre quadrature on
    x = w sin φ, w = √(a² − y²) (64 nodes). With ω = 0 it is the Hertz profile."""
    nodes, weights = np.polynomial.legendre.leggauss(64)
    phi = 0.5 * math.pi * nodes
    yy = np.asarray(y, dtype=float)[:, None]
    w = np.sqrt(np.clip(a * a - yy * yy, 0.0, None))
    x = w * np.sin(phi)[None, :]
    pressure_dx = p0 * (w * np.cos(phi)[None, :]) ** 2 / a  # p dx = p0 w² cos² φ / a dφ
    slip = np.hypot(v - omega * yy, omega * x)
    out: np.ndarray = (K_P / v) * 0.5 * math.pi * (pressure_dx * slip) @ weights
    return out


def _analytic_uniformity(
    path: RasterPath, across: float, force: float, feed: float, rpm: float
) -> float:
    """1 − std/mean of the superposition of the passes' cross profiles over [0, across]."""
    a, p0 = PAD.patch(force, 1.0 / RADIUS, 0.0)
    y = np.linspace(0.0, across, 20001)
    centres = path.pass_spacing * np.arange(path.passes)
    omega = 2.0 * math.pi * rpm / 60.0
    total = np.zeros_like(y)
    for k, c in enumerate(centres):
        # the first pass runs along +θ: n × ê is +z there, and flips with every pass
        lateral = (y - c) * (1.0 if k % 2 == 0 else -1.0)
        if omega == 0.0:
            total += hertz_profile(lateral, a, p0, K_P)
        else:
            total += spindle_profile(lateral, a, p0, feed, omega)
    return 1.0 - float(total.std()) / float(total.mean())


def _measure(
    row: dict[str, Any], result: Result, law: str, ratio: float, feed: float, rpm: float
) -> dict[str, Any]:
    """The study's numbers of one finished run."""
    path, across = _raster(ratio, feed)
    removal = result.meta["removal"]
    assert abs(removal["contact_radius"] - A0) < 1e-12 * A0, removal["contact_radius"]
    points, depth, target = result.removal_points, result.removal_depth, result.removal_target
    assert points is not None and depth is not None and target is not None
    arc = RADIUS * np.arctan2(points[:, 1], points[:, 0])
    inner = (target > 0) & (arc > 1.5 * A0) & (arc < ALONG - 1.5 * A0)
    h = depth[inner]
    f = np.atleast_1d(result.f).reshape(result.n_samples, -1)[:, 0]
    cruise = (result.t >= RAMP) & (result.t <= path.duration - RAMP)
    error = f[cruise] - F_D
    force = float(np.median(f[(result.phase == 2) & cruise]))
    return {
        "law": law,
        "ratio": ratio,
        "feed": feed,
        "spindle_rpm": rpm,
        "status": row["status"],
        "run_id": row["run_id"],
        "passes": path.passes,
        "pass_spacing": path.pass_spacing,
        "path_duration": path.duration,
        "uniformity_inner": 1.0 - float(h.std()) / float(h.mean()),
        "uniformity_analytic": _analytic_uniformity(path, across, force, feed, rpm),
        "depth_mean_inner": float(h.mean()),
        "removal_uniformity": removal["removal_uniformity"],
        "removal_coverage": removal["removal_coverage"],
        "removal_depth_mean": removal["removal_depth_mean"],
        "removal_depth_max": removal["removal_depth_max"],
        "force_error_rms": float(np.sqrt(np.mean(error**2))),
        "force_error_max": float(np.max(np.abs(error))),
        "force_median": force,
    }


def _sweep(
    variants: list[dict[str, Any]], scenario: Path, out: Path, workers: int
) -> dict[str, dict[str, Any]]:
    """Run the variants (resumable) and return the sweep's rows by run id."""
    table = run_sweep(
        scenario, variants, workers=workers, out_dir=out, keep_results=True, progress=True
    )
    with open(table, newline="") as fh:
        return {r["run_id"]: r for r in csv.DictReader(fh)}


def _rows(
    keys: list[tuple[str, float, float, float]], scenario: Path, out: Path, workers: int
) -> list[dict[str, Any]]:
    variants = [_variant(*k) for k in keys]
    by_id = _sweep(variants, scenario, out, workers)
    rows = []
    for key, variant in zip(keys, variants, strict=True):
        rid = run_id(variant)
        row = by_id[rid]
        if row["status"] != "ok":
            rows.append(
                {
                    "law": key[0],
                    "ratio": key[1],
                    "feed": key[2],
                    "spindle_rpm": key[3],
                    "status": row["status"],
                    "run_id": rid,
                    "error": row.get("error", ""),
                }
            )
            continue
        result = Result.load(out / "results" / f"{rid}.npz")
        rows.append(_measure(row, result, *key))
    return rows


def _fmt(row: dict[str, Any], key: str) -> str:
    return f"{row[key]:.3f}" if row["status"] == "ok" else f"fails ({row['status']})"


def _uniformity_table(
    rows: list[dict[str, Any]], laws: list[str], feeds: tuple[float, ...], label: str
) -> str:
    cells = {(r["law"], r["feed"], r["ratio"]): r for r in rows}
    head = " | ".join(f"{x:g}" for x in RATIOS)
    lines = [
        f"**{label}**",
        "",
        f"| law | feed [m/s] | {head} |",
        "|---|---|" + "---|" * len(RATIOS),
    ]
    for law in laws:
        for feed in feeds:
            line = " | ".join(_fmt(cells[(law, feed, x)], "uniformity_inner") for x in RATIOS)
            lines.append(f"| {law} | {feed:g} | {line} |")
    for feed in feeds:
        analytic = []
        for x in RATIOS:
            ok = [cells[(law, feed, x)] for law in laws if cells[(law, feed, x)]["status"] == "ok"]
            analytic.append(f"{np.mean([r['uniformity_analytic'] for r in ok]):.3f}" if ok else "")
        lines.append(f"| analytic superposition | {feed:g} | {' | '.join(analytic)} |")
    return "\n".join(lines)


def _detail_table(
    rows: list[dict[str, Any]], laws: list[str], feeds: tuple[float, ...], ratio: float
) -> str:
    cells = {(r["law"], r["feed"], r["ratio"]): r for r in rows}
    lines = [
        f"**spacing {ratio:g} × 2a₀: force tracking and the toolkit's metrics**",
        "",
        "| law | feed [m/s] | RMS \\|f − f_d\\| [N] | max \\|f − f_d\\| [N] | mean depth [nm] "
        "| uniformity (rectangle) | coverage | max / mean |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for law in laws:
        for feed in feeds:
            r = cells[(law, feed, ratio)]
            if r["status"] != "ok":
                lines.append(f"| {law} | {feed:g} | fails ({r['status']}) | | | | | |")
                continue
            lines.append(
                f"| {law} | {feed:g} | {r['force_error_rms']:.3f} | {r['force_error_max']:.2f} "
                f"| {r['depth_mean_inner'] * 1e9:.2f} | {r['removal_uniformity']:.3f} "
                f"| {r['removal_coverage']:.3f} "
                f"| {r['removal_depth_max'] / r['removal_depth_mean']:.2f} |"
            )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("runs/study_removal"))
    args = parser.parse_args()
    start = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    scenario = args.out / "study_removal.toml"
    scenario.write_text(SCENARIO, encoding="utf-8")
    laws = list(law_names())
    # the spinning quadrature reduces to the Hertz profile without spin (a check of it)
    y = np.linspace(-A0, A0, 101)
    assert np.allclose(
        spindle_profile(y, A0, P0, 0.05, 0.0),
        hertz_profile(y, A0, P0, K_P),
        rtol=0,
        atol=1e-12 * K_P * P0 * A0,
    )
    print(f"a0 = {A0 * 1e3:.3f} mm, contact diameter {2e3 * A0:.3f} mm, p0 = {P0:.4g} Pa")

    keys = [(law, x, v, 0.0) for law in laws for x in RATIOS for v in FEEDS]
    main_rows = _rows(keys, scenario, args.out / "sliding", args.workers)
    ok = [r for r in main_rows if r["status"] == "ok"]
    mean_u = {
        law: np.mean([r["uniformity_inner"] for r in ok if r["law"] == law])
        for law in laws
        if any(r["law"] == law for r in ok)
    }
    best = max(mean_u, key=lambda law: mean_u[law])
    print(
        _uniformity_table(main_rows, laws, FEEDS, "uniformity away from the turns, sliding tool"),
        end="\n\n",
    )
    print(_detail_table(main_rows, laws, FEEDS, 0.6), end="\n\n")
    print(
        "mean uniformity away from the turns over the 15 (spacing, feed) runs: "
        + ", ".join(f"{law} {u:.4f}" for law, u in mean_u.items()),
        end="\n\n",
    )

    spin_keys = [(best, x, v, SPINDLE_RPM) for x in RATIOS for v in FEEDS]
    spin_rows = _rows(spin_keys, scenario, args.out / "spindle", args.workers)
    print(
        _uniformity_table(
            spin_rows,
            [best],
            FEEDS,
            f"uniformity away from the turns, {best}, spindle {SPINDLE_RPM:g} rpm",
        ),
        end="\n\n",
    )
    print(_detail_table(spin_rows, [best], FEEDS, 0.6), end="\n\n")
    elapsed = time.perf_counter() - start
    print(f"{len(keys) + len(spin_keys)} runs, {elapsed:.0f} s")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(
        json.dumps(
            {
                "setup": {
                    "radius": RADIUS,
                    "f_d": F_D,
                    "pad": {"radius": PAD.radius, "modulus": PAD.modulus},
                    "k_p": K_P,
                    "resolution": RESOLUTION,
                    "a0": A0,
                    "p0": P0,
                    "along": ALONG,
                    "width": WIDTH,
                    "ramp": RAMP,
                    "friction": 0.3,
                    "friction_velocity": 2e-3,
                    "force_noise": 0.5,
                    "force_cutoff": 50.0,
                    "spindle_rpm": SPINDLE_RPM,
                    "ratios": RATIOS,
                    "feeds": FEEDS,
                },
                "mean_uniformity_inner": mean_u,
                "best_law": best,
                "sliding": main_rows,
                "spindle": spin_rows,
                "elapsed_s": elapsed,
            },
            indent=1,
        ),
        encoding="utf-8",
    )
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()

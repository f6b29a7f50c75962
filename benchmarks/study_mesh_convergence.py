"""Study: paper_contact (section 6.3) on its cylinder given as an N-section mesh, the settled
error split into (a) the field vs the mesh's exact distance at the tip and (b) the mesh vs the
true cylinder, as ``resolution`` h is refined (tests/test_mesh_convergence.py: the split,
the helpers, the asserted orders).

Four tables (Markdown, pasted into docs/mesh_parts.md):

0. curved facets (the default): N = 512 from h = 40 mm to w / 2 and N = 64 at w/2, w/4, w/8,
   the settled error against the true cylinder (no faceting floor: the patches through the
   vertices are the cylinder to R φ⁴/8);

the others with flat facets:

1. N = 512 (the issue's mesh, facet width w = 4.9 mm) from h = 40 mm to w / 2: the full
   cylinder down to h = w, the wedge of it over the path below (within ``--max-nodes``);
2. the order: N = 64 and 128 at h = w, w/2, w/4, w/8 (log2 ratios of (a)), self-similar in
   h/w with amplitude the sagitta s;
3. the faceting floor: N = 512, 1024, 2048 at fixed h (full cylinder), against s ∝ 1/N².

Run from the repository root (about 3 minutes on 2 cores, 2 GB at the finest grid):

    python benchmarks/study_mesh_convergence.py [--max-nodes 48000000] [--tables 0,1,2,3]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

import test_mesh_convergence as mc  # noqa: E402  (the helpers the test uses)

import hybrid_force.geometry.mesh_field as mesh_field  # noqa: E402

DURATION = 2.5  # [s] 2.5 rad of helix
SETTLED = 1.5  # [s] position and force: the analytic run is within 1e-9 m from here
ON_PATH = 0.5  # [s] (a), (b): the tip is on Φ = 0 throughout; from here on, the whole path


def _row(
    folder: Path, sections: int, h: float, wedge: bool, facets: str = "flat"
) -> dict[str, float]:
    result, mesh = mc.run_on(folder, sections, h, DURATION, wedge, facets)
    settled = mc.settled_parts(result, mesh, SETTLED)
    along = mc.settled_parts(result, mesh, ON_PATH)
    return {
        "position": settled["position"],
        "radial": settled["radial"],
        "force": settled["force"],
        "fit_max": along["fit_max"],
        "fit_mean": along["fit_mean"],
        "facet": along["facet"],
    }


def _order(previous: dict[str, float] | None, row: dict[str, float], key: str) -> str:
    return "" if previous is None else f"{math.log2(previous[key] / row[key]):.2f}"


def main(argv: list[str] | None = None) -> int:
    """Run the three tables and print them; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--max-nodes",
        type=int,
        default=48_000_000,
        help="the grid bound for this study (mesh_field.MAX_NODES, 16e6 in a run)",
    )
    parser.add_argument("--tables", default="0,1,2,3", help="which tables to run (0 to 3)")
    args = parser.parse_args(argv)
    tables = {int(k) for k in args.tables.split(",")}
    mesh_field.MAX_NODES = args.max_nodes  # the wedge at w / 2: about 3e7 nodes
    folder = Path(tempfile.mkdtemp(prefix="mesh_convergence_"))
    os.environ["HYBRID_FORCE_CACHE"] = str(folder / "cache")

    w512 = mc.facet_width(512)
    cases = [(0.04, False), (0.02, False), (0.01, False), (w512, False), (w512, True)]
    cases.append((w512 / 2, True))
    if 0 in tables:
        _curved(folder, cases)
    if 1 in tables:
        _table1(folder, cases)
    if 2 in tables:
        _table2(folder)
    if 3 in tables:
        _table3(folder)
    return 0


def _curved(folder: Path, cases: list[tuple[float, bool]]) -> None:
    print("## 0. Curved facets: the settled error against the cylinder\n")
    print("| N | h [mm] | h/w | part | ‖p − p_d‖ | max \\|d_true\\| | order "
          "| h φ²/2 | \\|f − f_d\\| [N] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for sections, rows in (
        (512, cases),
        (64, [(mc.facet_width(64) / k, True) for k in (2, 4, 8)]),
    ):
        w, phi = mc.facet_width(sections), math.pi / sections
        previous: tuple[float, dict[str, float]] | None = None
        for h, wedge in rows:
            r = _row(folder, sections, h, wedge, "curved")
            order = ""
            if previous is not None and previous[0] != h:
                ratio = previous[1]["radial"] / r["radial"]
                order = f"{math.log(ratio) / math.log(previous[0] / h):.2f}"
            print(
                f"| {sections} | {h * 1e3:.3g} | {h / w:.2f} | {'wedge' if wedge else 'cylinder'} "
                f"| {r['position']:.2e} | {r['radial']:.2e} | {order} | {h * phi**2 / 2:.1e} "
                f"| {r['force']:.1e} |",
                flush=True,
            )
            previous = (h, r)
    print()


def _table1(folder: Path, cases: list[tuple[float, bool]]) -> None:
    s512, w512 = mc.sagitta(512), mc.facet_width(512)
    print(f"## 1. N = 512: s = {s512:.3g} m, w = {w512 * 1e3:.2f} mm\n")
    print("| h [mm] | h/w | part | ‖p − p_d‖ | max \\|d_true\\| | (a) max | (a) mean | (b) max "
          "| \\|f − f_d\\| [N] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for h, wedge in cases:
        r = _row(folder, 512, h, wedge)
        print(
            f"| {h * 1e3:.3g} | {h / w512:.2f} | {'wedge' if wedge else 'cylinder'} "
            f"| {r['position']:.2e} | {r['radial']:.2e} | {r['fit_max']:.2e} "
            f"| {r['fit_mean']:.2e} | {r['facet']:.2e} | {r['force']:.1e} |",
            flush=True,
        )


def _table2(folder: Path) -> None:
    print("\n## 2. The order of (a): N = 64, 128 (wedge), in units of the sagitta s\n")
    print("| N | h/w | h [mm] | (a) max / s | order | (a) mean / s | order | \\|f − f_d\\| [N] |")
    print("|---|---|---|---|---|---|---|---|")
    for sections in (64, 128):
        s, w = mc.sagitta(sections), mc.facet_width(sections)
        previous = None
        for fraction in (1, 2, 4, 8):
            r = _row(folder, sections, w / fraction, True)
            print(
                f"| {sections} | 1/{fraction} | {w / fraction * 1e3:.3g} | {r['fit_max'] / s:.3f} "
                f"| {_order(previous, r, 'fit_max')} | {r['fit_mean'] / s:.4f} "
                f"| {_order(previous, r, 'fit_mean')} | {r['force']:.1e} |",
                flush=True,
            )
            previous = r


def _table3(folder: Path) -> None:
    print("\n## 3. The faceting floor: N = 512, 1024, 2048 (full cylinder)\n")
    print("| h [mm] | N | s [m] | ‖p − p_d‖ | ‖p − p_d‖ / s | max \\|d_true\\| / s | (b) max / s |")
    print("|---|---|---|---|---|---|---|")
    for h in (0.02, 0.01):
        for sections in (512, 1024, 2048):
            s = mc.sagitta(sections)
            r = _row(folder, sections, h, False)
            print(
                f"| {h * 1e3:.3g} | {sections} | {s:.3g} | {r['position']:.2e} "
                f"| {r['position'] / s:.2f} | {r['radial'] / s:.2f} | {r['facet'] / s:.3f} |",
                flush=True,
            )


if __name__ == "__main__":
    raise SystemExit(main())

"""Benchmark: the cost of Preston removal ([tool.pad] + [removal], docs/removal.md) in a run.

Run from the repository root:

    python benchmarks/bench_removal.py [--repeats N] [--duration S] [--json PATH]
        [--setups NAME ...]
    python benchmarks/bench_removal.py --profile [--setups NAME ...]

For each setup, the same scenario runs with removal off and on, in pairs (off first in even
pairs, on first in odd ones, so that a change of the machine's load hits both alike); each
run's loop is timed by its ``meta["wall_time"]`` (the stepping loop: it starts once the record
and its removal grid are built; the last < 256 samples' deposit, after the loop, is left out:
16 of 10,000 here), and the grid's set-up is timed alone (CPU seconds). Reported, each as the
median over the pairs of on / off, with the pairs' range:

* **wall**: the loop's wall time (and the ratio of the best of each);
* **CPU**: the loop's CPU time (the process's, from the first ``progress`` call, after step 0,
  to the last, after the loop: the time the machine's other processes took is left out, which
  the wall time of a shared machine is not);
* **block**: the loop's rate over its fastest block of 2,600 steps in a 10 s run (26 of
  ``simulate``'s progress intervals, the first left out; each block holds 10 or 11 of the
  deposit's batches of 256 samples), off over on: the rate when the process had the core
  (bench_peer.py's block rates); also the best block of all the off runs over the best of all
  the on runs;
* **in the run**: a third run per pair with removal on, its loop's wall time over itself
  less the time spent in the removal's calls (``RemovalObserver.observe`` per sample, with
  the batches' compiled deposits, timed by ``time.perf_counter`` around each call, the
  timer's own cost counted in; what removal costs the rest of the loop through the caches is
  not in it). The pairs' runs are not timed so.

Setups:

* ``rtr_plane_pass``: the RTR arm (3 joints, the cheapest step, so the worst ratio) on
  rtr_plane's plane, a straight pass of 0.1 m at 0.01 m/s in contact (10 s), Hertz pad
  (a = 3.1 mm at 10 N), 0.3 mm cells (a / 10: about 340 cells under the patch; 10 µm a
  sample: a straight segment of many samples is deposited as one, docs/removal.md "Cost");
* ``rtr_plane_fine``: the same with 0.1 mm cells (a / 31: about 3,000 cells under the patch,
  the resolution of the profile tests);
* ``rtr_cylinder``: paper_contact's helix on the cylinder for 10 s (quadric: the compiled surface),
  Hertz pad, 0.3 mm cells (0.41 mm a sample, a straight line on the unrolled cylinder);
* ``ur5_plane``: the UR5 circle on a plane (6 joints) for 10 s, Hertz pad, 0.3 mm cells;
* ``ur5_plane_polish`` (``--profile`` only): the shipped example as it is (a raster, removal
  on).

``--profile``: per setup, one run with removal on, then its removal alone replayed from its
record (the tip, the force, J v from the arm's Jacobian), CPU time per sample, best of 7: the
batched deposit as the run does it (``observe_batch``: straight segments of samples, the
setups' tool does not spin), the same with the merged point deposits instead (the deposit of a
spinning tool, and of every tool before the segments), and the samples' own work with nothing
to deposit (the merged points' reach made infinite); beside the loop's wall time per step
(``meta["steps_per_second"]``). And the accuracy of both against a reference: each sample's
span [t_i, t_i + dt) cut into 20 point deposits (the tip moved linearly from p_i to p_{i+1},
the force and J v of sample i held), none merged: the largest and the RMS difference over the
grid, relative to the peak.

``--duration S`` runs each setup for S simulated seconds instead (the block is then 26 % of
the run): shorter runs put a pair's two runs closer in time, so that more pairs see the same
load on a shared machine.

Not part of the test suite; timings depend on the machine's load.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
import warnings
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from hybrid_force.scenario.loader import load_scenario  # noqa: E402
from hybrid_force.sim.loop import simulate  # noqa: E402
from hybrid_force.sim.removal_run import RemovalObserver  # noqa: E402

PAD = {"type": "hertz", "radius": 0.02, "modulus": 5e6}
PASS = {
    "trajectory": {
        "type": "waypoints",
        "frame": "surface",
        "points": [[0.6, -0.05], [0.6, 0.05]],
        "speed": 0.01,
        "ramp": 0.2,
    },
    "initial.tip": [0.6, -0.05, 5.0],
    "control.supervisor": False,
    "sim.duration": 10.0,
}
SETUPS: dict[str, tuple[str, dict[str, Any], float]] = {
    "rtr_plane_pass": ("rtr_plane.toml", PASS, 3e-4),
    "rtr_plane_fine": ("rtr_plane.toml", PASS, 1e-4),
    "rtr_cylinder": (
        "paper_contact.toml",
        {"sim.duration": 10.0, "initial.tip": [0.4, 0.0, 10.0]},
        3e-4,
    ),
    "ur5_plane": ("ur5_plane.toml", {"sim.duration": 10.0}, 3e-4),
}
PROFILE_ONLY: dict[str, tuple[str, dict[str, Any], float]] = {
    # the shipped example (its own pad and removal, the same as PAD's and 0.3 mm cells)
    "ur5_plane_polish": ("ur5_plane_polish.toml", {}, 3e-4),
}


class _Timed:
    """Wall time [s] spent inside ``RemovalObserver.observe`` (the calls of a run), while
    ``on`` (the runs that measure the removal's share; the pairs' runs are not timed so)."""

    spent = 0.0
    on = False

    @classmethod
    def install(cls) -> None:
        observe = RemovalObserver.observe

        def timed(self: RemovalObserver, *args: Any) -> None:
            if not cls.on:
                observe(self, *args)
                return
            start = time.perf_counter()
            observe(self, *args)
            cls.spent += time.perf_counter() - start

        RemovalObserver.observe = timed  # type: ignore[method-assign, assignment]


SUB = 20
"""--profile: the reference depth cuts each sample's span into SUB point deposits."""
BLOCK = 26
"""Progress intervals (of N // 100 = 100 steps in a 10 s run) in a block: 2,600 steps, 10 or 11
of the deposit's batches of 256 samples."""


def _block_rate(stamps: list[tuple[int, float]]) -> float:
    """The fastest rate [steps/s] over BLOCK consecutive progress intervals (the first
    interval left out: the kernels' first calls; the last stamp is after the loop)."""
    marks = stamps[1:-1]
    rates = [
        (i1 - i0) / (t1 - t0)
        for (i0, t0), (i1, t1) in zip(marks, marks[BLOCK:], strict=False)
        if i1 > i0 and t1 > t0
    ]
    return max(rates) if rates else math.nan


def _run(
    file: str, overrides: dict[str, Any], timed: bool = False
) -> tuple[float, float, float, float, float]:
    """(the loop's wall time [s], ``meta["wall_time"]``: it starts after the run's record and
    its removal grid are built; the loop's CPU time [s] from step 0 on (the ``progress``
    callback's first and last calls); the grid's set-up alone, in CPU seconds (0 without
    removal); the wall time [s] the loop spent in the removal's calls (``timed``, else 0);
    the block rate [steps/s], :func:`_block_rate`)."""
    sc = load_scenario(REPO / "scenarios" / file, overrides)
    setup = 0.0
    if sc.removal is not None:
        start = time.process_time()
        RemovalObserver(sc, round(sc.sim.duration / sc.sim.dt) + 1)
        setup = time.process_time() - start
    marks: list[float] = []
    stamps: list[tuple[int, float]] = []
    steps = round(sc.sim.duration / sc.sim.dt) + 1

    def progress(fraction: float) -> None:
        marks.append(time.process_time())
        stamps.append((round(fraction * steps), time.perf_counter()))

    _Timed.spent, _Timed.on = 0.0, timed
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = simulate(sc, progress=progress)
    return (
        float(result.meta["wall_time"]),
        marks[-1] - marks[0],
        setup,
        _Timed.spent,
        _block_rate(stamps),
    )


def _profile(name: str) -> dict[str, float]:
    """µs per sample of the removal on setup ``name`` (module docstring, --profile)."""
    import numpy as np

    from hybrid_force.sim import _removal_kernels as K

    file, overrides, resolution = {**SETUPS, **PROFILE_ONLY}[name]
    removal = {"k_p": 1e-13, "resolution": resolution}
    sc = load_scenario(
        REPO / "scenarios" / file, {**overrides, "tool.pad": PAD, "removal": removal}
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = simulate(sc)
    n = r.n_samples
    tips, forces = np.ascontiguousarray(r.p), np.ascontiguousarray(r.f.reshape(n, -1))
    velocities = np.array([sc.robot.jacobian(r.q[i]) @ r.v[i] for i in range(n)])
    obs = RemovalObserver(sc, n)
    g = obs.grid

    def batches(deviation: float, factor: float) -> float:
        g.depth[:] = 0.0
        obs._group[:] = 0.0
        tally = np.zeros(2, dtype=np.int64)
        start = time.process_time()
        for first in range(0, n - 1, 256):
            count = min(256, n - 1 - first)
            K.observe_batch(
                obs._desc, tips, forces, obs.surface_index, velocities[first : first + count],
                first, count, obs._shape, obs.pad.radius, obs._modulus, obs.settings.omega,
                obs.v_ref, factor, obs._merge, deviation, obs._dt, g.points, g.areas, g.order,
                g.table, g.starts, g.box, g.dims, g.lattice, g.rows, g.col, g.depth, obs._group,
                obs._work, g.index, g.weight, tally,
            )  # fmt: skip
        K.flush(
            obs._group, obs._shape, factor, g.points, g.areas, g.order, g.table, g.starts, g.box,
            g.dims, g.lattice, g.rows, g.col, g.depth, obs._work, g.index, g.weight,
        )  # fmt: skip
        return time.process_time() - start

    dev, factor = obs._deviation, obs._factor
    batches(dev, factor), batches(0.0, factor)  # compiled, caches warm
    segments = min(batches(dev, factor) for _ in range(7))
    h_segments = g.depth.copy()
    points = min(batches(0.0, factor) for _ in range(7))
    h_points = g.depth.copy()
    # the samples' own work alone (surface, patch, group): the point groups' reach made
    # infinite, one deposit at the end
    merge, obs._merge = obs._merge, math.inf
    alone = min(batches(0.0, factor) for _ in range(7))
    obs._merge = merge
    # the reference: each sample's span [t_i, t_i + dt) cut into SUB point deposits (the tip
    # moved linearly from p_i to p_{i+1}, the force and J v of sample i held), none merged
    w = (np.arange(SUB) / SUB)[None, :, None]
    fine = (tips[:-1, None, :] * (1 - w) + tips[1:, None, :] * w).reshape(-1, 3)
    tips = np.ascontiguousarray(np.vstack([fine, tips[-1:]]))
    forces = np.ascontiguousarray(np.vstack([np.repeat(forces[:-1], SUB, axis=0), forces[-1:]]))
    velocities = np.repeat(velocities[:-1], SUB, axis=0)
    n, dt = tips.shape[0], obs._dt
    obs._dt = dt / SUB
    merge, obs._merge = obs._merge, 0.0
    batches(0.0, factor / SUB)
    obs._dt, obs._merge = dt, merge
    reference = g.depth.copy()
    peak = float(reference.max())
    us = 1e6 / (r.n_samples)
    return {
        "loop_us_per_step": 1e6 / float(r.meta["steps_per_second"]),
        "removal_us_per_sample": segments * us,
        "points_us_per_sample": points * us,
        "observe_us_per_sample": alone * us,
        "segments_error_max_over_peak": float(np.abs(h_segments - reference).max()) / peak,
        "points_error_max_over_peak": float(np.abs(h_points - reference).max()) / peak,
        "segments_error_rms_over_peak": float(np.sqrt(np.mean((h_segments - reference) ** 2)))
        / peak,
        "points_error_rms_over_peak": float(np.sqrt(np.mean((h_points - reference) ** 2))) / peak,
        "segments": float(dev > 0.0),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument(
        "--duration", type=float, default=10.0,
        help="simulated seconds of each run (10: the setups' own; shorter runs put a pair's "
        "two runs closer in time, so more pairs see the same load of a shared machine)",
    )  # fmt: skip
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument(
        "--setups", nargs="*", choices=sorted({**SETUPS, **PROFILE_ONLY}), default=None
    )
    parser.add_argument("--profile", action="store_true", help="the removal's parts (docstring)")
    args = parser.parse_args()
    report: dict[str, Any] = {}
    if args.setups is None:
        args.setups = list(SETUPS) + (list(PROFILE_ONLY) if args.profile else [])
    if not args.profile and set(args.setups) & set(PROFILE_ONLY):
        parser.error(f"{sorted(PROFILE_ONLY)}: with --profile only (its removal is always on)")
    if args.profile:
        for name in args.setups:
            report[name] = part = _profile(name)
            print(
                f"{name:16s} µs per sample: removal {part['removal_us_per_sample']:.2f} (of which "
                f"the samples without a deposit {part['observe_us_per_sample']:.2f}), merged "
                f"points instead {part['points_us_per_sample']:.2f}; the loop "
                f"{part['loop_us_per_step']:.1f} µs a step. Depth against {SUB} point deposits "
                f"a sample, max (RMS) / peak: segments "
                f"{100 * part['segments_error_max_over_peak']:.3f} % "
                f"({100 * part['segments_error_rms_over_peak']:.4f} %), merged points "
                f"{100 * part['points_error_max_over_peak']:.3f} % "
                f"({100 * part['points_error_rms_over_peak']:.4f} %)",
                flush=True,
            )
        if args.json is not None:
            args.json.write_text(json.dumps(report, indent=2))
        return 0
    _Timed.install()
    for name in args.setups:
        file, overrides, resolution = SETUPS[name]
        overrides = {**overrides, "sim.duration": args.duration}
        on = {**overrides, "tool.pad": PAD, "removal": {"k_p": 1e-13, "resolution": resolution}}
        _run(file, {**on, "sim.duration": 0.05})  # compile and load the kernels once
        _run(file, {**overrides, "sim.duration": 0.05})
        offs, ons, setups, cpu_offs, cpu_ons, shares = [], [], [], [], [], []
        block_offs, block_ons = [], []
        for rep in range(args.repeats):
            # off first in even pairs, on first in odd ones (a drift of the load cancels)
            for removal_on in (False, True) if rep % 2 == 0 else (True, False):
                loop, cpu, setup, spent, block = _run(file, on if removal_on else overrides)
                if removal_on:
                    ons.append(loop)
                    cpu_ons.append(cpu)
                    setups.append(setup)
                    block_ons.append(block)
                else:
                    offs.append(loop)
                    cpu_offs.append(cpu)
                    block_offs.append(block)
            # the removal's share: a third run, its calls timed (the timer's cost counted in)
            loop, _, _, spent, _ = _run(file, on, timed=True)
            shares.append(loop / (loop - spent))
        pairs = [b / a for a, b in zip(offs, ons, strict=True)]
        cpu_pairs = [b / a for a, b in zip(cpu_offs, cpu_ons, strict=True)]
        block_pairs = [a / b for a, b in zip(block_offs, block_ons, strict=True)]
        report[name] = {
            "duration_s": args.duration,
            "ratio_median": statistics.median(pairs),
            "ratio_best": min(ons) / min(offs),
            "ratios": pairs,
            "cpu_ratio_median": statistics.median(cpu_pairs),
            "cpu_ratios": cpu_pairs,
            "block_ratio_median": statistics.median(block_pairs),
            "block_ratio_best": max(block_offs) / max(block_ons),
            "block_ratios": block_pairs,
            "inrun_ratio_median": statistics.median(shares),
            "inrun_ratios": shares,
            "off_loop_seconds": offs,
            "on_loop_seconds": ons,
            "off_loop_cpu_seconds": cpu_offs,
            "on_loop_cpu_seconds": cpu_ons,
            "setup_cpu_seconds_median": statistics.median(setups),
        }
        r = report[name]
        print(
            f"{name:16s} on/off, medians of {args.repeats} pairs: wall {r['ratio_median']:.3f} "
            f"(best on / best off {r['ratio_best']:.3f}; pairs {min(pairs):.2f}-"
            f"{max(pairs):.2f}), CPU {r['cpu_ratio_median']:.3f} ({min(cpu_pairs):.2f}-"
            f"{max(cpu_pairs):.2f}), block {r['block_ratio_median']:.3f} (best "
            f"{r['block_ratio_best']:.3f}; {min(block_pairs):.2f}-{max(block_pairs):.2f}), in "
            f"the run {r['inrun_ratio_median']:.3f}; loop off {min(offs):.2f} s; grid set-up "
            f"{r['setup_cpu_seconds_median']:.2f} s (before the loop); load "
            f"{os.getloadavg()[0]:.1f}",
            flush=True,
        )
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

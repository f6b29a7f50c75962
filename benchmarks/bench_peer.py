"""The toolkit's closed loop against the same task in MuJoCo, written as a user of MuJoCo would.

Run from the repository root (needs the ``bench`` extra: ``pip install ".[bench]"``):

    python benchmarks/bench_peer.py [--quick] [--reps 5] [--duration 2] [--laws A,B]
                                    [--arms ur5e,panda] [--json PATH]

The task, the same in both: the Menagerie-like UR5e or Panda of ``benchmarks/models/`` (one
MJCF file, loaded by :func:`hybrid_force.load_robot` and by ``mujoco.MjModel``), a 1 cm tool
ball whose centre draws a circle of radius 0.1 m at ω = 1 rad/s on the plane z = 0.3 m,
pressing with f_d = 10 N, dt = 1 ms, starting in contact at the circle's start (the same q0,
found by the toolkit's inverse kinematics).

* **hybrid_force**: a scenario with that robot (tip: the ball's centre), the plane z = 0.31 m
  (the plane the centre rides on), the circle, f_d = 10 N, ``supervisor = false``, each
  registered law with its default gains; steps/s is ``meta["steps_per_second"]`` (the
  stepping loop, not the set-up).
* **MuJoCo**: a plane geom and the ball geom (soft contact, MuJoCo's default solver
  settings; ``condim = 1``, frictionless as the toolkit's surfaces are), ``mj_step1`` /
  control / ``mj_step2`` (one forward pass per step), and an operational-space hybrid
  controller (Khatib 1987): J from ``mj_jacSite``, M from ``mj_fullM``, J̇q̇ from
  ``mj_jacDot``, Λ = (J M⁻¹ Jᵀ)⁻¹, a task-space PD on the circle in the plane's tangent
  directions, a damped normal direction, a PI loop on the measured normal force
  (``mj_contactForce`` of the ball's contacts, one step old: what a sensor gives), the bias
  forces ``qfrc_bias`` compensated and a joint posture held in the dynamically consistent null
  space, applied as ``qfrc_applied``; steps/s is the steps over the wall time of the
  stepping loop (the model and data made before).

Reported per arm: steps/s of MuJoCo and of each law (best of the repetitions), the ratio
law / MuJoCo (of the best, and the paired median: each run of a law is paired with a MuJoCo
run right beside it, MuJoCo first in even repetitions and second in odd ones, so a slow spell
of a shared machine hits both runs of a pair; the median of the pairs' ratios), RMS |f − f_d|
and the RMS position error of the ball's centre (in the plane, and along the normal) over the
run and after t ≥ 0.5 s, and the load average. MuJoCo's row: every one of its runs (one per
law and repetition). On a shared machine a whole run's rate also counts the time the process
waited for a core; so each run also stamps the clock every steps // 100 steps (20 in a 2 s
run; the toolkit through ``simulate``'s progress callback, MuJoCo in its loop), and its
**block rate** is the fastest of those blocks (the first left out: the kernels' loading): the
rate of the loop when it had the core. "block x": the paired median of the block rates'
ratios. Not part of the test suite.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

MODELS = ROOT / "benchmarks" / "models"
DT = 1e-3
F_D = 10.0
BALL = 0.01  # [m] the tool ball's radius (benchmarks/models/*.xml)
PLANE_Z = 0.3  # [m] the table's plane; the ball's centre rides on PLANE_Z + BALL
RADIUS = 0.1
OMEGA = 1.0
SETTLED = 0.5  # [s] errors also reported from here on
# arm: (circle centre (x, y), IK seed) — the UR5e's base is turned by 180° (Menagerie's)
ARMS: dict[str, tuple[tuple[float, float], list[float]]] = {
    "ur5e": ((-0.4, -0.1), [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]),
    "panda": ((0.4, 0.1), [0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 0.785]),
}
NORMAL = np.array([0.0, 0.0, 1.0])


def circle(t: float, centre: tuple[float, float]) -> tuple[np.ndarray, ...]:
    """p_d, ṗ_d, p̈_d of the ball's centre at time t."""
    c, s = math.cos(OMEGA * t), math.sin(OMEGA * t)
    z = PLANE_Z + BALL
    p = np.array([centre[0] + RADIUS * c, centre[1] + RADIUS * s, z])
    v = np.array([-RADIUS * OMEGA * s, RADIUS * OMEGA * c, 0.0])
    a = np.array([-RADIUS * OMEGA**2 * c, -RADIUS * OMEGA**2 * s, 0.0])
    return p, v, a


# ---------------------------------------------------------------------------- the toolkit
def scenario_text(arm: str, law: str, duration: float) -> str:
    """The toolkit's scenario of the task (TOML)."""
    (cx, cy), seed = ARMS[arm]
    z = PLANE_Z + BALL
    return f"""name = "peer_{arm}_{law}"
[robot]
model = "{(MODELS / f"{arm}.xml").as_posix()}"
tip = "tool_center"
[surface]
type = "plane"
point = [0.0, 0.0, {z}]
normal = [0.0, 0.0, 1.0]
[trajectory]
type = "circle"
center = [{cx}, {cy}, {z}]
radius = {RADIUS}
normal = [0.0, 0.0, 1.0]
omega = {OMEGA}
phase = 0.0
[initial]
tip = [{cx + RADIUS}, {cy}, {z}]
seed = {seed}
[control]
law = "{law}"
supervisor = false
f_d = {F_D}
[sim]
duration = {duration}
dt = {DT}
"""


def load_toolkit(arm: str, law: str, duration: float, folder: Path) -> Any:
    from hybrid_force.scenario.loader import load_scenario

    path = folder / f"peer_{arm}_{law}.toml"
    path.write_text(scenario_text(arm, law, duration))
    return load_scenario(path)


def run_toolkit(arm: str, law: str, duration: float, folder: Path) -> dict[str, Any]:
    """One run of the task with ``law``: steps/s and errors."""
    import warnings

    from hybrid_force.sim.loop import simulate

    scenario = load_toolkit(arm, law, duration, folder)
    steps = round(duration / DT) + 1
    stamps: list[tuple[int, float]] = []

    def stamp(fraction: float) -> None:  # every steps // 100 steps (block_steps)
        stamps.append((round(fraction * steps), time.perf_counter()))

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = simulate(scenario, progress=stamp)
    f = np.asarray(result.f).reshape(len(result.t), -1)[:, 0]
    f_d = np.asarray(result.f_d).reshape(len(result.t), -1)[:, 0]
    out = {
        "steps_per_second": float(result.meta["steps_per_second"]),
        "block_steps_per_second": block_rate(stamps[:-1]),  # (the last: after the loop)
        "status": result.status,
    }
    out |= _errors(np.asarray(result.t), f, f_d, np.asarray(result.p), np.asarray(result.p_d))
    return out


def block_steps(steps: int) -> int:
    """Steps between two clock stamps of a run of ``steps`` samples: simulate's progress
    calls, every steps // 100 (20 for a 2 s run)."""
    return max(1, steps // 100)


def block_rate(stamps: list[tuple[int, float]]) -> float:
    """The fastest rate [steps/s] between consecutive (step, time [s]) stamps, the first
    block (the kernels' loading, MuJoCo's first step) left out."""
    rates = [
        (i1 - i0) / (t1 - t0)
        for (i0, t0), (i1, t1) in itertools.pairwise(stamps[1:])
        if i1 > i0 and t1 > t0
    ]
    return max(rates) if rates else math.nan


# ---------------------------------------------------------------------------- MuJoCo
class MujocoTask:
    """The task in MuJoCo with an operational-space hybrid controller (see the module doc)."""

    # task-space PD [1/s², 1/s] (in the plane), normal damping [1/s], force PI [-, 1/s],
    # posture PD in the null space [1/s², 1/s]
    KP, KD, KD_N, KF_P, KF_I, KQ, DQ = 400.0, 40.0, 40.0, 0.5, 20.0, 25.0, 10.0

    def __init__(self, arm: str, q0: np.ndarray) -> None:
        import mujoco

        self.mj = mujoco
        self.arm = arm
        self.centre = ARMS[arm][0]
        self.m = mujoco.MjModel.from_xml_path(str(MODELS / f"{arm}.xml"))
        self.m.opt.timestep = DT
        self.q0 = np.array(q0, dtype=float)
        self.site = self.m.site("tool_center").id
        self.body = int(self.m.site_bodyid[self.site])
        self.ball = self.m.geom("tool_ball").id
        self.table = self.m.geom("table").id

    def run(self, duration: float) -> dict[str, Any]:
        """Simulate ``duration`` s; steps/s of the stepping loop and the errors."""
        mj, m = self.mj, self.m
        d = mj.MjData(m)
        d.qpos[:] = self.q0
        mj.mj_forward(m, d)
        nv = m.nv
        steps = round(duration / DT) + 1
        jac = np.zeros((3, nv))
        jdot = np.zeros((3, nv))
        M = np.zeros((nv, nv))
        f6 = np.zeros(6)
        S = np.eye(3) - np.outer(NORMAL, NORMAL)
        n = NORMAL
        eye = np.eye(nv)
        log_t = np.empty(steps)
        log_f = np.empty(steps)
        log_p = np.empty((steps, 3))
        log_pd = np.empty((steps, 3))
        f_meas = 0.0
        integral = 0.0
        stamps: list[tuple[int, float]] = []
        block = block_steps(steps)
        t0 = time.perf_counter()
        for i in range(steps):
            if i % block == 0:  # the block rate's clock (module docstring)
                stamps.append((i, time.perf_counter()))
            t = i * DT
            mj.mj_step1(m, d)  # kinematics, M, bias forces, contacts at (q, v)
            mj.mj_jacSite(m, d, jac, None, self.site)
            mj.mj_jacDot(m, d, jdot, None, d.site_xpos[self.site], self.body)
            mj.mj_fullM(m, d, M)
            q, qd = d.qpos, d.qvel
            x = d.site_xpos[self.site]
            xd = jac @ qd
            p_d, v_d, a_d = circle(t, self.centre)
            minv_jt = np.linalg.solve(M, jac.T)
            lam = np.linalg.inv(jac @ minv_jt)
            a = S @ (a_d + self.KD * (v_d - xd) + self.KP * (p_d - x))
            a -= self.KD_N * (n @ xd) * n
            err = F_D - f_meas
            integral += err * DT
            f_cmd = F_D + self.KF_P * err + self.KF_I * integral
            F = lam @ (a - jdot @ qd) - f_cmd * n
            tau = jac.T @ F + d.qfrc_bias
            jbar = minv_jt @ lam  # dynamically consistent generalised inverse (nv × 3)
            tau0 = M @ (self.KQ * (self.q0 - q) - self.DQ * qd)
            tau += (eye - jac.T @ jbar.T) @ tau0
            d.qfrc_applied[:] = tau
            mj.mj_step2(m, d)  # constraint forces, integration
            f_meas = 0.0
            for k in range(d.ncon):
                c = d.contact[k]
                if self.ball in (c.geom1, c.geom2):
                    mj.mj_contactForce(m, d, k, f6)
                    f_meas += f6[0]
            log_t[i] = t
            log_f[i] = f_meas
            log_p[i] = x
            log_pd[i] = p_d
        wall = time.perf_counter() - t0
        out = {
            "steps_per_second": steps / wall,
            "block_steps_per_second": block_rate(stamps),
            "status": "ok",
        }
        if not np.all(np.isfinite(log_p)):
            out["status"] = "diverged"
        out |= _errors(log_t, log_f, np.full(steps, F_D), log_p, log_pd)
        return out


# ---------------------------------------------------------------------------- both
def _errors(t: np.ndarray, f: np.ndarray, f_d: np.ndarray, p: np.ndarray, p_d: np.ndarray) -> dict:
    """RMS |f − f_d| [N], RMS position error in the plane and along the normal [m]."""
    e = p - p_d
    normal = e @ NORMAL
    tangential = np.linalg.norm(e - np.outer(normal, NORMAL), axis=1)
    late = t >= SETTLED

    def rms(x: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.square(x)))) if len(x) else math.nan

    return {
        "rms_force_error": rms(f - f_d),
        "rms_force_error_settled": rms((f - f_d)[late]),
        "rms_position_error_plane": rms(tangential),
        "rms_position_error_plane_settled": rms(tangential[late]),
        "rms_position_error_normal": rms(normal),
    }


def main(argv: list[str] | None = None) -> int:
    from hybrid_force.control.laws.base import law_names

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="1 repetition of 0.3 s")
    parser.add_argument("--reps", type=int, default=5)
    parser.add_argument("--duration", type=float, default=2.0, help="simulated s (2)")
    parser.add_argument("--laws", default=",".join(law_names()))
    parser.add_argument("--arms", default=",".join(ARMS))
    parser.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "peer.json"))
    args = parser.parse_args(argv)
    reps, duration = (1, 0.3) if args.quick else (args.reps, args.duration)
    laws = args.laws.split(",")
    arms = args.arms.split(",")
    out: dict[str, Any] = {
        "command": " ".join(["python", *sys.argv]),
        "reps": reps,
        "duration_s": duration,
        "dt_s": DT,
        "loadavg_start": list(os.getloadavg()),
        "arms": {},
    }
    import mujoco

    out["mujoco"] = mujoco.__version__
    with tempfile.TemporaryDirectory(prefix="bench_peer_") as tmp:
        folder = Path(tmp)
        tasks = {}
        for arm in arms:
            q0 = np.asarray(load_toolkit(arm, laws[0], 0.01, folder).q0, dtype=float)
            tasks[arm] = MujocoTask(arm, q0)
            tasks[arm].run(0.05)  # warm-up
            for law in laws:
                run_toolkit(arm, law, 0.01, folder)  # the compiled kernels loaded
        runs: dict[str, dict[str, list[dict]]] = {
            arm: {name: [] for name in ["mujoco", *laws]} for arm in arms
        }
        for rep in range(reps):  # each law beside a MuJoCo run of its own, in both orders
            for arm in arms:
                for law in laws:
                    if rep % 2 == 0:
                        peer = tasks[arm].run(duration)
                    try:
                        run = run_toolkit(arm, law, duration, folder)
                    except Exception as exc:  # a law refused on this arm: reported, not fatal
                        run = {"error": f"{type(exc).__name__}: {exc}"}
                    if rep % 2 == 1:
                        peer = tasks[arm].run(duration)
                    runs[arm]["mujoco"].append(peer)
                    run["peer_steps_per_second"] = peer["steps_per_second"]
                    run["peer_block_steps_per_second"] = peer["block_steps_per_second"]
                    runs[arm][law].append(run)
            print(f"repetition {rep + 1}/{reps} done (load {os.getloadavg()[0]:.2f})", flush=True)
    out["loadavg_end"] = list(os.getloadavg())
    for arm in arms:
        peer = runs[arm]["mujoco"]
        peer_best = max(r["steps_per_second"] for r in peer)
        rows = {}
        for name, rs in runs[arm].items():
            ok = [r for r in rs if "error" not in r]
            if not ok:
                rows[name] = {"error": rs[0]["error"]}
                continue
            best = max(r["steps_per_second"] for r in ok)
            per_rep = [  # each run against its MuJoCo run (MuJoCo's own: 1)
                r["steps_per_second"] / r.get("peer_steps_per_second", r["steps_per_second"])
                for r in ok
            ]
            per_block = [
                r["block_steps_per_second"]
                / r.get("peer_block_steps_per_second", r["block_steps_per_second"])
                for r in ok
            ]
            last = ok[-1]
            rows[name] = {
                "steps_per_second_best": best,
                "steps_per_second_all": [r["steps_per_second"] for r in ok],
                "ratio_to_mujoco_best": best / peer_best,
                "ratio_to_mujoco_paired_median": statistics.median(per_rep),
                "block_steps_per_second_best": max(r["block_steps_per_second"] for r in ok),
                "block_ratio_to_mujoco_paired_median": statistics.median(per_block),
                "status": last["status"],
                **{k: v for k, v in last.items() if k.startswith("rms_")},
            }
        out["arms"][arm] = rows
    _print(out)
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {path}")
    return 0


def _print(out: dict[str, Any]) -> None:
    la, lb = out["loadavg_start"], out["loadavg_end"]
    print(
        f"\nthe task: 10 N, circle r = 0.1 m, ω = 1, dt = 1 ms, {out['duration_s']:g} s "
        f"simulated, best of {out['reps']}; MuJoCo {out['mujoco']}; load average "
        f"{la[0]:.2f} {la[1]:.2f} {la[2]:.2f} -> {lb[0]:.2f} {lb[1]:.2f} {lb[2]:.2f}"
    )
    head = (
        f"{'arm':<7}{'loop':<18}{'steps/s':>9}{'x MuJoCo':>10}{'paired':>8}{'block/s':>9}"
        f"{'block x':>9}{'status':>10}"
        f"{'RMS|f-fd| N':>13}{'(t>=0.5)':>10}{'RMS pos m':>11}{'(t>=0.5)':>10}{'normal m':>10}"
    )
    print(head)
    print("-" * len(head))
    for arm, rows in out["arms"].items():
        for name, r in rows.items():
            if "error" in r:
                print(f"{arm:<7}{name:<18} {r['error'][:100]}")
                continue
            print(
                f"{arm:<7}{name:<18}{r['steps_per_second_best']:>9.0f}"
                f"{r['ratio_to_mujoco_best']:>9.2f}x{r['ratio_to_mujoco_paired_median']:>7.2f}x"
                f"{r['block_steps_per_second_best']:>9.0f}"
                f"{r['block_ratio_to_mujoco_paired_median']:>8.2f}x"
                f"{r['status']:>10}{r['rms_force_error']:>13.2e}"
                f"{r['rms_force_error_settled']:>10.2e}{r['rms_position_error_plane']:>11.2e}"
                f"{r['rms_position_error_plane_settled']:>10.2e}"
                f"{r['rms_position_error_normal']:>10.2e}"
            )


if __name__ == "__main__":
    raise SystemExit(main())

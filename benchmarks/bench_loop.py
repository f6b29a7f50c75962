"""Benchmark of the closed simulation loop against the floor of its Pinocchio calls (issue 8).

Run from the repository root:

    python benchmarks/bench_loop.py [--quick] [--json PATH]

Reports, in one run on one machine:

1. steps per second of the full closed loop (:func:`hybrid_force.sim.loop.simulate`: control
   law, constrained dynamics, integration, projection, logging), median over repetitions of a
   2 s simulated run, for the paper_contact setup (RTR arm on the cylinder, section 6.3) and for
   UR5 / Panda on a plane z = 0.3 m;
2. the floor: the time per step of the Pinocchio calls alone that one step makes (same calls,
   same counts, same argument shapes, in a tight loop with no other Python logic). The call
   counts are measured on the real loop by wrapping every ``pinocchio`` function with a counter
   and checked against the list the floor loop makes;
3. the overhead factor (loop time / floor time) and the real-time factor at dt = 1 ms;
4. cost per step versus number of joints (rtr 3, ur5 6, panda 7, g1 29);
5. linearity in simulated time (RTR, 1, 2, 4 s simulated);
6. a cProfile of 1 s of the RTR loop (top 15 functions by tottime);
7. every registered law on rtr (paper_contact), ur5 and panda (a circle on a plane, starting
   in contact) and on the two tool-orientation scenarios (ur5_sphere_normal, panda_pipe_tilt):
   steps per second (best of the repetitions; each repetition runs every law in turn) and the
   ratio to the paper's law (arimoto) of the same repetition, median over repetitions
   (``--laws-only``: this table alone).

Not part of the test suite. Timings depend on machine load: the JSON records ``uptime``.
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import io
import json
import os
import platform
import pstats
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hybrid_force.control.clik import inverse_kinematics
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane
from hybrid_force.geometry.paths import Circle, paper_helix
from hybrid_force.model.loading import load_robot
from hybrid_force.model.robot import Robot
from hybrid_force.sim.loop import simulate
from hybrid_force.sim.settings import Scenario, SimSettings

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_DT = 1e-3
_ROOT = Path(__file__).resolve().parents[1]

# Pinocchio calls per contact step (k = 1, an arm whose joints are all bounded revolute or
# prismatic, so that q ⊕ dq = q + dq is done without Pinocchio), read from simulate.py /
# robot.py / clik.py / dynamics.py / supervisor.py and confirmed by counting (_count_calls):
#   Robot.terms: crba, computeGeneralizedGravity, computeCoriolisMatrix (also fills J, J̇ and
#                the placements), updateFramePlacement, getFrameJacobian,
#                getFrameJacobianTimeVariation
#   ConstrainedDynamics.solve: forwardDynamics × 1 (the algebraic loop u = u0 + B f is resolved
#                with the factorisation it leaves in data.U, data.D)
#   DesiredJointPath.advance: forwardKinematics(q) + updateFramePlacement (Newton residual),
#                computeJointJacobians + getFrameJacobian (q̇_d; getFrameJacobian by frame id
#                sets data.oMf[frame] itself, so no updateFramePlacement),
#                computeJointJacobiansTimeVariation + getFrameJacobianTimeVariation (q̈_d)
#   Plant.advance in contact: computeJointJacobians + updateFramePlacement + getFrameJacobian
#                (projection rows at the Euler-integrated q), impulseDynamics (the velocity's
#                constraint impulse at the projected q)
_EXPECTED = {
    "crba": 1,
    "computeGeneralizedGravity": 1,
    "computeCoriolisMatrix": 1,
    "updateFramePlacement": 3,
    "getFrameJacobian": 3,
    "getFrameJacobianTimeVariation": 2,
    "forwardDynamics": 1,
    "forwardKinematics": 1,
    "computeJointJacobians": 2,
    "computeJointJacobiansTimeVariation": 1,
    "impulseDynamics": 1,
}


@dataclass(frozen=True)
class Setup:
    """A closed-loop benchmark case: a scenario factory for a given duration [s]."""

    name: str
    robot: Robot
    make: Callable[[float], Scenario] | None
    note: str = ""


# ---------------------------------------------------------------------------- scenarios
def _rtr_setup() -> Setup:
    robot = load_robot("rtr")
    q0 = inverse_kinematics(robot, [0.4, 0, 7], seed=[0, 6, 2.0])

    def make(duration: float) -> Scenario:
        return Scenario(
            robot,
            [Cylinder(0.4)],
            paper_helix(),
            q0,
            control=ControlSettings(supervisor=False),
            sim=SimSettings(duration=duration, dt=_DT),
            name="paper_contact",
        )

    return Setup("rtr", robot, make, "paper_contact (6.3): cylinder r = 0.4 m, paper helix")


def _plane_setup(name: str, seed: list[float], tip: str | None = None) -> Setup:
    robot = load_robot(name, tip=tip)
    plane = Plane(point=(0.0, 0.0, 0.3), normal=(0.0, 0.0, 1.0))
    circle = Circle(center=(0.4, 0.1, 0.3), radius=0.1, normal=(0, 0, 1), omega=1)
    q0 = inverse_kinematics(robot, circle.position(0), seed=np.array(seed))
    make = _plane_scenarios(robot, plane, circle, q0, f"{name}_plane")
    return Setup(name, robot, make, "plane z = 0.3 m, circle r = 0.1 m at (0.4, 0.1), ω = 1")


def _plane_scenarios(
    robot: Robot, plane: Plane, circle: Circle, q0: np.ndarray, name: str
) -> Callable[[float], Scenario]:
    """Scenario factory for a tool in contact with ``plane`` tracing ``circle`` from q0."""

    def make(duration: float) -> Scenario:
        return Scenario(
            robot,
            [plane],
            circle,
            q0,
            control=ControlSettings(supervisor=False),
            sim=SimSettings(duration=duration, dt=_DT),
            name=name,
        )

    return make


def _g1_setup() -> Setup:
    """G1 (29 joints, fixed pelvis), right hand on a horizontal plane at its own height."""
    robot = load_robot("g1", tip="right_rubber_hand")
    seed = robot.neutral()
    model = robot.model
    for joint, value in (
        ("right_shoulder_pitch_joint", -0.6),
        ("right_shoulder_roll_joint", -0.3),
        ("right_elbow_joint", 0.8),
    ):
        seed[model.joints[model.getJointId(joint)].idx_q] = value
    p = robot.tip_position(seed)
    radius = 0.03
    plane = Plane(point=(0.0, 0.0, float(p[2])), normal=(0.0, 0.0, 1.0))
    circle = Circle(
        center=(float(p[0]) - radius, float(p[1]), float(p[2])),
        radius=radius,
        normal=(0, 0, 1),
        omega=1,
    )
    q0 = inverse_kinematics(robot, circle.position(0), seed=seed)
    make = _plane_scenarios(robot, plane, circle, q0, "g1_plane")
    return Setup("g1", robot, make, f"right hand on plane z = {p[2]:.3f} m, circle r = 3 cm")


# ---------------------------------------------------------------------------- laws
# case: (scenario file, overrides) — each starts in contact, supervisor off
LAW_CASES: dict[str, tuple[str, dict[str, object]]] = {
    "rtr": ("scenarios/paper_contact.toml", {}),
    "ur5": (
        "scenarios/ur5_plane.toml",
        {"control.supervisor": False, "initial.tip": [0.5, 0.1, 0.3]},
    ),
    "panda": (
        "benchmarks/scenarios/panda_plane.toml",
        {"control.supervisor": False, "initial.tip": [0.5, 0.1, 0.3]},
    ),
    "ur5 tool normal": ("scenarios/ur5_sphere_normal.toml", {}),
    "panda tool tilt": ("scenarios/panda_pipe_tilt.toml", {}),
}
PAPER_LAW = "arimoto"


def _law_run(case: str, law: str, duration: float) -> dict:
    """steps/s of one run of ``case`` with ``law`` (or the error it is refused with)."""
    import warnings

    from hybrid_force.control.laws.base import law_spec
    from hybrid_force.scenario.loader import read_scenario_document, scenario_from_document

    name, overrides = LAW_CASES[case]
    path = _ROOT / name
    try:
        doc = read_scenario_document(
            path, {**overrides, "control.law": law, "sim.duration": duration}
        )
        if "Lambda" not in law_spec(law).gains:  # the file's Λ: refused by the laws without it
            doc["control"].pop("Lambda", None)
        scenario = scenario_from_document(doc, origin=str(path), base_dir=path.parent)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = simulate(scenario)
    except Exception as exc:  # a law refused on a case: reported, not fatal
        return {"error": f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"}
    return {"steps_per_second": float(result.meta["steps_per_second"]), "status": result.status}


def _laws_table(reps: int, duration: float) -> dict:
    """Every registered law on every LAW_CASES case, ``reps`` times in turn."""
    from hybrid_force.control.laws.base import law_names

    laws = list(law_names())
    if PAPER_LAW in laws:  # the reference first in each repetition
        laws.remove(PAPER_LAW)
        laws.insert(0, PAPER_LAW)
    runs: dict[str, dict[str, list[dict]]] = {c: {law: [] for law in laws} for c in LAW_CASES}
    for case in LAW_CASES:
        for law in laws:
            _law_run(case, law, 0.01)  # the compiled kernels loaded before timing
    for rep in range(reps):
        for case in LAW_CASES:
            for law in laws:
                runs[case][law].append(_law_run(case, law, duration))
        print(f"[laws] repetition {rep + 1}/{reps} (load {os.getloadavg()[0]:.2f})", flush=True)
    table: dict[str, dict[str, dict]] = {}
    for case, by_law in runs.items():
        ref = by_law[PAPER_LAW]
        table[case] = {}
        for law, rs in by_law.items():
            ok = [r for r in rs if "error" not in r]
            if not ok:
                table[case][law] = {"error": rs[0]["error"]}
                continue
            ratios = [
                r["steps_per_second"] / p["steps_per_second"]
                for r, p in zip(rs, ref, strict=True)
                if "error" not in r and "error" not in p
            ]
            table[case][law] = {
                "steps_per_second_best": max(r["steps_per_second"] for r in ok),
                "steps_per_second_all": [r["steps_per_second"] for r in ok],
                "ratio_to_paper_law_paired_median": statistics.median(ratios) if ratios else None,
                "status": ok[-1]["status"],
            }
    return {"duration_s": duration, "reps": reps, "laws": laws, "cases": table}


def _print_laws(out: dict) -> None:
    laws = out["laws"]
    print(
        f"every law: steps/s, best of {out['reps']} runs of {out['duration_s']:g} s "
        f"(x: the ratio to {PAPER_LAW} of the same repetition, median); load "
        + " -> ".join(f"{a[0]:.2f} {a[1]:.2f} {a[2]:.2f}" for a in out["loadavg"])
    )
    width = max(len(c) for c in out["cases"]) + 2
    print(f"{'case':<{width}}" + "".join(f"{law:>24}" for law in laws))
    for case, by_law in out["cases"].items():
        cells = []
        for law in laws:
            r = by_law[law]
            if "error" in r:
                cells.append(f"{'refused':>24}")
            else:
                ratio = r["ratio_to_paper_law_paired_median"]
                cells.append(f"{r['steps_per_second_best']:>15.0f} ({ratio:4.2f}x)")
        print(f"{case:<{width}}" + "".join(cells))
    for case, by_law in out["cases"].items():
        for law, r in by_law.items():
            if "error" in r:
                print(f"  {case} / {law}: {r['error']}")


# ---------------------------------------------------------------------------- floor
def _count_calls(setup: Setup) -> dict[str, float]:
    """Pinocchio calls per step of the real loop (difference of two run lengths)."""
    counts: collections.Counter[str] = collections.Counter()
    originals: dict[str, object] = {}
    for name in dir(pin):
        obj = getattr(pin, name)
        if callable(obj) and name[:1].islower() and not isinstance(obj, type):
            originals[name] = obj

            def wrapper(*a: object, _f: Callable = obj, _n: str = name, **k: object) -> object:
                counts[_n] += 1
                return _f(*a, **k)

            setattr(pin, name, wrapper)
    try:
        per_run = []
        for duration in (0.05, 0.1):
            counts.clear()
            simulate(setup.make(duration))
            per_run.append(dict(counts))
    finally:
        for name, obj in originals.items():
            setattr(pin, name, obj)
    steps = round(0.1 / _DT) - round(0.05 / _DT)
    names = set(per_run[0]) | set(per_run[1])
    out = {n: (per_run[1].get(n, 0) - per_run[0].get(n, 0)) / steps for n in sorted(names)}
    return {n: c for n, c in out.items() if c > 0}


def _floor_step(robot: Robot) -> Callable[[], None]:
    """One step's Pinocchio calls with realistic arguments, as a closure (no other logic)."""
    model, fid, n = robot.model, robot.tip_id, robot.nv
    rng = np.random.default_rng(8)
    q = pin.neutral(model) + 0.3 * rng.standard_normal(robot.nq)
    v = 0.2 * rng.standard_normal(n)
    qd = 0.2 * rng.standard_normal(n)
    tau = rng.standard_normal(n)
    d_plant, d_clik, d_proj = model.createData(), model.createData(), model.createData()
    d_imp = model.createData()  # the plant's velocity correction has its own data
    pin.computeJointJacobians(model, d_plant, q)
    A = pin.getFrameJacobian(model, d_plant, fid, _LWA)[2:3].copy()  # a plane row n̂ᵀJ (1, n)
    gamma = np.array([0.01])
    pin.crba(model, d_plant, q)

    def step() -> None:
        # Robot.terms
        pin.crba(model, d_plant, q)
        pin.computeGeneralizedGravity(model, d_plant, q)
        pin.computeCoriolisMatrix(model, d_plant, q, v)
        pin.updateFramePlacement(model, d_plant, fid)
        pin.getFrameJacobian(model, d_plant, fid, _LWA)
        pin.getFrameJacobianTimeVariation(model, d_plant, fid, _LWA)
        # constrained dynamics (one KKT solve; the loop uses its factorisation)
        pin.forwardDynamics(model, d_plant, tau, A, gamma)
        # desired path: Newton residual, then q̇_d and q̈_d
        pin.forwardKinematics(model, d_clik, q)
        pin.updateFramePlacement(model, d_clik, fid)
        pin.computeJointJacobians(model, d_clik, q)
        pin.getFrameJacobian(model, d_clik, fid, _LWA)
        pin.computeJointJacobiansTimeVariation(model, d_clik, q, qd)
        pin.getFrameJacobianTimeVariation(model, d_clik, fid, _LWA)
        # plant: projection rows at the integrated q
        pin.computeJointJacobians(model, d_proj, q)
        pin.updateFramePlacement(model, d_proj, fid)
        pin.getFrameJacobian(model, d_proj, fid, _LWA)
        # plant: the velocity's constraint impulse at the projected q (crba inside)
        pin.impulseDynamics(model, d_imp, q, v, A, 0.0, 0.0)

    return step


def _floor_expected(n: int) -> dict[str, int]:
    """The floor's call counts (the same for every n on arms with vector-space joints)."""
    del n
    return dict(_EXPECTED)


def _time_floor(robot: Robot, batches: int, iters: int) -> dict:
    """Median and min time per step [µs] of the floor loop, over ``batches`` batches."""
    step = _floor_step(robot)
    for _ in range(200):
        step()
    per_step = []
    for _ in range(batches):
        t0 = time.perf_counter()
        for _ in range(iters):
            step()
        per_step.append((time.perf_counter() - t0) / iters * 1e6)
    # the bare Python loop + closure call, subtracted from nothing (it is < 0.1 µs)
    return {"us_median": statistics.median(per_step), "us_min": min(per_step)}


def _time_each_call(robot: Robot, iters: int) -> dict[str, float]:
    """Time per call [µs] of each Pinocchio function of the floor, for the cost breakdown."""
    model, fid, n = robot.model, robot.tip_id, robot.nv
    rng = np.random.default_rng(8)
    q = pin.neutral(model) + 0.3 * rng.standard_normal(robot.nq)
    v, tau = 0.2 * rng.standard_normal(n), rng.standard_normal(n)
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    A = pin.getFrameJacobian(model, data, fid, _LWA)[2:3].copy()
    gamma = np.array([0.01])
    pin.crba(model, data, q)
    calls: dict[str, Callable[[], object]] = {
        "computeJointJacobiansTimeVariation": lambda: pin.computeJointJacobiansTimeVariation(
            model, data, q, v
        ),
        "getFrameJacobianTimeVariation": lambda: pin.getFrameJacobianTimeVariation(
            model, data, fid, _LWA
        ),
        "crba": lambda: pin.crba(model, data, q),
        "computeCoriolisMatrix": lambda: pin.computeCoriolisMatrix(model, data, q, v),
        "computeGeneralizedGravity": lambda: pin.computeGeneralizedGravity(model, data, q),
        "forwardDynamics": lambda: pin.forwardDynamics(model, data, tau, A, gamma),
        "computeJointJacobians": lambda: pin.computeJointJacobians(model, data, q),
        "updateFramePlacement": lambda: pin.updateFramePlacement(model, data, fid),
        "getFrameJacobian": lambda: pin.getFrameJacobian(model, data, fid, _LWA),
        "forwardKinematics": lambda: pin.forwardKinematics(model, data, q),
        "impulseDynamics": lambda: pin.impulseDynamics(model, data, q, v, A, 0.0, 0.0),
    }
    return {name: _best_us(call, 100, iters, 3) for name, call in calls.items()}


def _best_us(call: Callable[[], object], warmup: int, iters: int, batches: int) -> float:
    """Best time per call [µs] of ``call`` over ``batches`` batches of ``iters`` calls."""
    for _ in range(warmup):
        call()
    best = np.inf
    for _ in range(batches):
        t0 = time.perf_counter()
        for _ in range(iters):
            call()
        best = min(best, (time.perf_counter() - t0) / iters * 1e6)
    return best


# ---------------------------------------------------------------------------- loop
def _time_loop(
    setup: Setup,
    duration: float,
    reps: int,
    floor_step: Callable[[], None] | None = None,
    floor_iters: int = 2000,
) -> dict:
    """Median steps per second (meta['steps_per_second']) and wall time of simulate().

    With ``floor_step``, a batch of the floor loop is timed right before each repetition, so
    each repetition has its own floor measured in the same machine state ("pairs").
    """
    sps, walls, totals, pairs = [], [], [], []
    status = "ok"
    simulate(setup.make(0.01))  # compiled kernels loaded (or compiled) before timing
    for _ in range(reps):
        if floor_step is not None:
            floor_us = _best_us(floor_step, 100, floor_iters, 1)
        scenario = setup.make(duration)
        t0 = time.perf_counter()
        result = simulate(scenario)
        totals.append(time.perf_counter() - t0)
        sps.append(float(result.meta["steps_per_second"]))
        walls.append(float(result.meta["wall_time"]))
        status = result.meta["status"]
        err = float(np.abs(result.phi).max())
        if floor_step is not None:
            pairs.append({"floor_us": floor_us, "loop_us": 1e6 / sps[-1]})
    paired = [x["loop_us"] / x["floor_us"] for x in pairs]
    return {
        "pairs": pairs,
        "overhead_paired_median": statistics.median(paired) if paired else None,
        "duration_s": duration,
        "reps": reps,
        "steps_per_second_median": statistics.median(sps),
        "steps_per_second_all": sps,
        "loop_wall_s_median": statistics.median(walls),
        "simulate_call_s_median": statistics.median(totals),
        "us_per_step_median": 1e6 / statistics.median(sps),
        "steps_per_second_best": max(sps),
        "us_per_step_best": 1e6 / max(sps),
        "status": status,
        "max_abs_distance_m": err,
    }


def _startup(reps: int) -> dict:
    """Start-up costs, each in a fresh interpreter (median of ``reps``) [s].

    * ``import_hybrid_force``: ``import hybrid_force`` (Numba, plotting and the viewer are not
      imported by it);
    * ``kernels_cold`` / ``kernels_warm``: importing Numba and getting the compiled kernels
      ready for a 10 ms RTR run, with an empty kernel cache (NUMBA_CACHE_DIR pointed at a new
      folder: compilation) and then with that cache filled (loading);
    * ``cli_run_0.1s``: the whole ``hybrid-force run scenarios/paper_contact.toml`` with
      ``--set sim.duration=0.1`` (warm cache), process start to exit.
    """
    import tempfile

    exe = sys.executable
    code_import = (
        "import time; t=time.perf_counter(); import hybrid_force; print(time.perf_counter()-t)"
    )
    here = str(Path(__file__).resolve().parent)
    code_kernels = (
        f"import time, sys; sys.path.insert(0, {here!r}); import bench_loop as b; "
        "s = b._rtr_setup(); "
        "from hybrid_force.sim.loop import simulate; t=time.perf_counter(); "
        "simulate(s.make(0.01)); print(time.perf_counter()-t)"
    )

    def run(code: str, env: dict[str, str]) -> float:
        res = subprocess.run(
            [exe, "-c", code], capture_output=True, text=True, env=env, check=True, cwd=_ROOT
        )
        return float(res.stdout.strip().splitlines()[-1])

    env = dict(os.environ)
    out: dict[str, float] = {}
    out["import_hybrid_force"] = statistics.median(run(code_import, env) for _ in range(reps))
    cold, warm = [], []
    for _ in range(reps):
        with tempfile.TemporaryDirectory() as cache:
            env_c = {**env, "NUMBA_CACHE_DIR": cache}
            cold.append(run(code_kernels, env_c))
            warm.append(run(code_kernels, env_c))
    out["kernels_cold"] = statistics.median(cold)
    out["kernels_warm"] = statistics.median(warm)
    cli = Path(exe).with_name("hybrid-force")
    if cli.exists():
        walls = []
        with tempfile.TemporaryDirectory() as tmp:
            for _ in range(reps):
                t0 = time.perf_counter()
                subprocess.run(
                    [str(cli), "run", "scenarios/paper_contact.toml", "--set", "sim.duration=0.1",
                     "--out", tmp, "--quiet"],
                    check=True, cwd=_ROOT, env=env, capture_output=True,
                )  # fmt: skip
                walls.append(time.perf_counter() - t0)
        out["cli_run_0.1s"] = statistics.median(walls)
    return out


def _parts(setup: Setup, iters: int, batches: int) -> dict[str, float]:
    """Cost [µs] of each part of one contact step, each timed alone in a tight loop.

    The state is the last one of a 0.2 s run; every part is called with the objects the loop
    uses (its own controller, plant, buffers), best of ``batches`` batches of ``iters``
    calls. Parts in the loop run interleaved, with colder caches, so their sum is below the
    loop's time per step; the shares say what dominates.
    """
    from hybrid_force.control.constraint import Constraint, ConstraintTerms
    from hybrid_force.control.supervisor import HybridController
    from hybrid_force.model.robot import RobotTerms
    from hybrid_force.sim.control_side import build_control_side
    from hybrid_force.sim.dynamics import ConstrainedDynamics
    from hybrid_force.sim.plant import Plant
    from hybrid_force.sim.record import Record

    sc = setup.make(0.2)
    res = simulate(sc)
    robot, sim = sc.robot, sc.sim
    q, v = res.q[-1].copy(), res.v[-1].copy()
    n = robot.nv
    data = robot.new_data()
    constraint = Constraint(sc.surfaces, normalization=sim.normalization)
    k = constraint.k
    terms = robot.terms(q, v, data, out=RobotTerms.zeros(n))
    cbuf = ConstraintTerms.zeros(k, n)
    cons = constraint.evaluate(terms, v, out=cbuf)
    ctrl = HybridController(robot, constraint, sc.path, sc.q0, sc.control, dt=sim.dt)
    cmd = ctrl.command(0.0, q, v, terms, cons)
    gamma = np.zeros(k)
    sim.baumgarte.gamma_into(cons.drift, cons.rate, cons.phi, cons.scale, gamma)
    solver = ConstrainedDynamics(robot.model, data, k)
    ddq, f = solver.solve(terms.nle, cmd.u0, cmd.B, cons.A, gamma)
    plant = Plant(robot, constraint, sim, sc.control.contact_tol)
    plant.in_contact = True
    log = Record(sc, plant, build_control_side(sc, None, sc.q0), 2)
    parts: dict[str, Callable[[], object]] = {
        "robot terms (6 Pinocchio calls + 1 kernel)": lambda: robot.terms(q, v, data, out=terms),
        "constraint rows, Q, drift (1 kernel)": lambda: constraint.evaluate(terms, v, out=cbuf),
        "controller command (supervisor + law kernel)": lambda: ctrl.command(
            0.0, q, v, terms, cons
        ),
        "Baumgarte γ (1 kernel)": lambda: sim.baumgarte.gamma_into(
            cons.drift, cons.rate, cons.phi, cons.scale, gamma
        ),
        "constrained dynamics (forwardDynamics + loop kernel)": lambda: solver.solve(
            terms.nle, cmd.u0, cmd.B, cons.A, gamma
        ),
        "sample row (1 kernel)": lambda: log.record(0, 0.0, q, v, terms, cmd, f, cons.distance),
        # dt = 1 ns: the state stays put, and the CLIK's predictor is made ahead as in the loop
        "controller update (momenta + CLIK: 7 Pinocchio calls + 4 kernels)": lambda: ctrl.update(
            1e-9, f
        ),
        "plant Euler + projection (4 Pinocchio calls + 2 kernels)": lambda: plant.advance(
            q, v, ddq, cmd, 0.0, 0.0, cons.distance
        ),
    }
    return {name: _best_us(call, 200, iters, batches) for name, call in parts.items()}


def _profile(
    setup: Setup, duration: float, top: int = 15
) -> tuple[str, list[dict], dict[str, float]]:
    scenario = setup.make(duration)
    prof = cProfile.Profile()
    prof.enable()
    simulate(scenario)
    prof.disable()
    stream = io.StringIO()
    stats = pstats.Stats(prof, stream=stream).sort_stats("tottime")
    stats.print_stats(top)
    stream.write("--- the same profile by cumulative time ---\n")
    stats.sort_stats("cumulative").print_stats(top + 10)
    stats.sort_stats("tottime")
    rows = []
    entries = sorted(stats.stats.items(), key=lambda kv: kv[1][2], reverse=True)[:top]
    for (file, line, func), (_cc, nc, tt, ct, _) in entries:
        rows.append(
            {
                "function": f"{Path(file).name}:{line}({func})",
                "ncalls": nc,
                "tottime_s": tt,
                "cumtime_s": ct,
            }
        )
    categories = {"pinocchio": 0.0, "numpy": 0.0, "hybrid_force (Python)": 0.0, "other": 0.0}
    for (file, _line, func), (_cc, _nc, tt, _ct, _) in stats.stats.items():
        if "pinocchio" in func or "pinocchio" in file:
            categories["pinocchio"] += tt
        elif "numpy" in file or "numpy" in func:
            categories["numpy"] += tt
        elif "hybrid_force" in file:
            categories["hybrid_force (Python)"] += tt
        else:
            categories["other"] += tt
    text = (
        stream.getvalue()
        + "tottime by origin: "
        + ", ".join(f"{k} {v:.3f} s" for k, v in categories.items())
    )
    return text, rows, categories


# ---------------------------------------------------------------------------- machine
def _machine() -> dict:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        uptime = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        uptime = ""
    try:
        commit = subprocess.run(
            ["git", "-C", str(_ROOT), "rev-parse", "HEAD"], capture_output=True, text=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(_ROOT), "status", "--porcelain", "hybrid_force"],
            capture_output=True,
            text=True,
        ).stdout.split()
    except OSError:
        commit, dirty = "", []
    return {
        "nproc": os.cpu_count(),
        "cpu": cpu,
        "python": platform.python_version(),
        "pinocchio": pin.__version__,
        "numpy": np.__version__,
        "platform": platform.platform(),
        "uptime": uptime,
        "loadavg": list(os.getloadavg()),
        "git_commit": commit,
        "hybrid_force_uncommitted_changes": [d for d in dirty if d.endswith(".py")],
    }


# ---------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    """Run the benchmark, print the table, write JSON; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="3 repetitions instead of 5")
    parser.add_argument(
        "--laws-only", action="store_true", help="only the table of every law (item 7)"
    )
    parser.add_argument(
        "--law-duration", type=float, default=2.0, help="simulated s per law run (2)"
    )
    parser.add_argument(
        "--json", default=str(_ROOT / "benchmarks" / "results" / "latest.json"), help="output"
    )
    args = parser.parse_args(argv)
    reps = 3 if args.quick else 5
    batches, iters = (3, 2000) if args.quick else (5, 5000)
    out: dict = {"command": " ".join(["python", *sys.argv]), "machine_start": _machine()}
    out["dt_s"] = _DT
    if args.laws_only:
        load0 = list(os.getloadavg())
        out["laws"] = _laws_table(reps, args.law_duration)
        out["laws"]["loadavg"] = [load0, list(os.getloadavg())]
        _print_laws(out["laws"])
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(out, indent=2, default=float) + "\n")
        print(f"wrote {path}")
        return 0

    setups: dict[str, Setup] = {"rtr": _rtr_setup()}
    setups["ur5"] = _plane_setup("ur5", [0, -1.0, 1.5, -2.0, -1.57, 0])
    setups["panda"] = _plane_setup("panda", [0, -0.3, 0, -2.2, 0, 1.9, 0.785])
    g1_note = ""
    try:
        setups["g1"] = _g1_setup()
    except Exception as exc:  # report, do not abort the benchmark
        g1_note = f"closed loop not set up: {type(exc).__name__}: {exc}"
        setups["g1"] = Setup("g1", load_robot("g1", tip="right_rubber_hand"), None, g1_note)

    rows = []
    for name, setup in setups.items():
        robot = setup.robot
        print(f"[{name}] n = {robot.nv}: floor ...", flush=True)
        floor = _time_floor(robot, batches, iters if robot.nv < 20 else iters // 4)
        row: dict = {
            "robot": name,
            "n": robot.nv,
            "tip": robot.tip,
            "setup": setup.note,
            "floor_us_per_step": floor["us_median"],
            "floor_us_per_step_min": floor["us_min"],
            "floor_steps_per_second": 1e6 / floor["us_median"],
        }
        if setup.make is not None:
            try:
                calls = _count_calls(setup)
                row["pinocchio_calls_per_step_measured"] = calls
                expected = _floor_expected(robot.nv)
                row["floor_call_list_matches"] = {k: round(v, 3) for k, v in calls.items()} == {
                    k: float(v) for k, v in expected.items()
                }
                print(f"[{name}] closed loop {reps} x 2 s ...", flush=True)
                loop = _time_loop(setup, 2.0, reps, _floor_step(robot), iters // 2)
                row["loop"] = loop
                row["loop_steps_per_second"] = loop["steps_per_second_median"]
                row["loop_us_per_step"] = loop["us_per_step_median"]
                row["overhead_factor"] = loop["us_per_step_median"] / floor["us_median"]
                row["real_time_factor"] = loop["steps_per_second_median"] * _DT
                row["overhead_factor_best"] = loop["us_per_step_best"] / floor["us_min"]
            except Exception as exc:
                row["loop_error"] = f"{type(exc).__name__}: {exc}"
                print(f"[{name}] closed loop failed: {row['loop_error']}", flush=True)
        else:
            row["loop_error"] = setup.note
        rows.append(row)
    out["per_robot"] = rows
    out["per_call_us"] = {
        name: _time_each_call(setups[name].robot, 2000 if setups[name].robot.nv < 20 else 500)
        for name in setups
    }
    for row in rows:  # cross-check: Σ count × best time per call
        costs = out["per_call_us"][row["robot"]]
        row["floor_us_per_step_from_call_costs"] = sum(
            c * costs[k] for k, c in _floor_expected(row["n"]).items()
        )

    print("[rtr] linearity 1, 2, 4 s ...", flush=True)
    runs: dict[float, list[float]] = {1.0: [], 2.0: [], 4.0: []}
    for _ in range(reps):  # interleaved, so a load burst does not hit one duration only
        for duration in runs:
            runs[duration].append(_time_loop(setups["rtr"], duration, 1)["loop_wall_s_median"])
    lin = [
        {
            "duration_s": d,
            "loop_wall_s_all": w,
            "wall_per_simulated_second_s_median": statistics.median(w) / d,
            "wall_per_simulated_second_s_best": min(w) / d,
        }
        for d, w in runs.items()
    ]
    best = [x["wall_per_simulated_second_s_best"] for x in lin]
    spread = (max(best) - min(best)) / statistics.median(best)
    # noise: the spread between repetitions of the same run, on this (loaded) machine
    noise = statistics.median((max(w) - min(w)) / statistics.median(w) for w in runs.values())
    out["linearity_rtr"] = {
        "runs": lin,
        "relative_spread_of_best": spread,
        "repetition_noise": noise,
        "linear_within_noise": spread <= max(0.15, noise),
    }

    print("[rtr] parts of one step ...", flush=True)
    out["parts_rtr_us"] = _parts(setups["rtr"], 2000, 5)

    print("start-up ...", flush=True)
    out["startup_s"] = _startup(3)

    print("[rtr] cProfile of 1 s ...", flush=True)
    text, prof_rows, categories = _profile(setups["rtr"], 1.0)
    out["profile_rtr_1s"] = {
        "top15_tottime": prof_rows,
        "tottime_by_origin_s": categories,
        "text": text,
    }
    print("every law on every case ...", flush=True)
    load0 = list(os.getloadavg())
    out["laws"] = _laws_table(reps, args.law_duration)
    out["laws"]["loadavg"] = [load0, list(os.getloadavg())]
    out["machine_end"] = {"uptime": _machine()["uptime"], "loadavg": list(os.getloadavg())}

    _print_table(out)
    _print_laws(out["laws"])
    print()
    print(text)
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2, default=float) + "\n")
    print(f"wrote {path}")
    return 0


def _print_table(out: dict) -> None:
    m = out["machine_start"]
    print()
    print(
        f"machine: {m['nproc']} CPUs, {m['cpu']}, Python {m['python']}, "
        f"pinocchio {m['pinocchio']}, numpy {m['numpy']}"
    )
    print(f"load at start: {m['uptime']}")
    print(f"load at end:   {out['machine_end']['uptime']}")
    head = (
        f"{'robot':<6}{'n':>4}{'floor µs/step':>15}{'floor steps/s':>15}"
        f"{'loop µs/step':>14}{'loop steps/s':>14}{'overhead':>10}{'RT factor':>11}"
        f"{'best: floor µs':>16}{'loop µs':>9}{'overhead':>10}{'Σcalls µs':>11}"
    )
    print("median columns, then best-of (min time) columns; Σcalls = Σ count × µs per call")
    print(head)
    print("-" * len(head))
    for r in out["per_robot"]:
        if "loop_us_per_step" in r:
            tail = (
                f"{r['loop_us_per_step']:>14.1f}{r['loop_steps_per_second']:>14.0f}"
                f"{r['overhead_factor']:>9.1f}x{r['real_time_factor']:>10.2f}x"
                f"{r['floor_us_per_step_min']:>16.1f}{r['loop']['us_per_step_best']:>9.1f}"
                f"{r['overhead_factor_best']:>9.1f}x"
                f"{r['floor_us_per_step_from_call_costs']:>11.1f}"
            )
        else:
            tail = f"   closed loop: {r.get('loop_error', 'n/a')}"
        print(
            f"{r['robot']:<6}{r['n']:>4}{r['floor_us_per_step']:>15.1f}"
            f"{r['floor_steps_per_second']:>15.0f}{tail}"
        )
    print()
    print("each repetition with a floor batch timed just before it: floor µs -> loop µs (ratio)")
    for r in out["per_robot"]:
        pairs = r.get("loop", {}).get("pairs") or []
        if pairs:
            text = ", ".join(
                f"{x['floor_us']:.1f}->{x['loop_us']:.1f} ({x['loop_us'] / x['floor_us']:.1f}x)"
                for x in pairs
            )
            print(
                f"  {r['robot']:<6}{text}; median ratio {r['loop']['overhead_paired_median']:.1f}x"
            )
    print()
    print("linearity (rtr): simulated s -> wall s per simulated s")
    for x in out["linearity_rtr"]["runs"]:
        print(
            f"  {x['duration_s']:>4.0f} s -> best {x['wall_per_simulated_second_s_best']:.4f}, "
            f"median {x['wall_per_simulated_second_s_median']:.4f} wall s per simulated s"
        )
    lin = out["linearity_rtr"]
    print(
        f"  spread of best {lin['relative_spread_of_best']:.1%} "
        f"across durations, repetition noise {lin['repetition_noise']:.1%} "
        f"(linear within noise: {lin['linear_within_noise']})"
    )
    print()
    print("Pinocchio call cost [µs per call], rtr / ur5 / panda / g1:")
    names = list(out["per_call_us"])
    for call in out["per_call_us"][names[0]]:
        vals = " / ".join(f"{out['per_call_us'][n][call]:.2f}" for n in names)
        print(f"  {call:<36}{vals}")
    print()
    parts = out["parts_rtr_us"]
    total = sum(parts.values())
    print("rtr: parts of one contact step, each timed alone [µs] (best of 5 batches):")
    for name, us in parts.items():
        print(f"  {name:<70}{us:>7.2f}  {us / total:>5.1%}")
    print(f"  {'sum':<70}{total:>7.2f}")
    print()
    st = out["startup_s"]
    print("start-up [s], fresh interpreters, median of 3:")
    print(f"  import hybrid_force                       {st['import_hybrid_force']:.2f}")
    print(f"  kernels for a 10 ms RTR run, empty cache  {st['kernels_cold']:.2f}  (compilation)")
    print(f"  kernels for a 10 ms RTR run, cached       {st['kernels_warm']:.2f}")
    if "cli_run_0.1s" in st:
        print(f"  hybrid-force run paper_contact, 0.1 s     {st['cli_run_0.1s']:.2f}")
    print()


if __name__ == "__main__":
    raise SystemExit(main())

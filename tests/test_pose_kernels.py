"""The pose CLIK's kernels (hybrid_force.control._pose_kernels) against their numpy oracle.

:class:`PoseJointPath` (compiled) and ``ReferencePoseJointPath`` (numpy, the readable form, in
tests/oracles/control.py) are put in the same random state and must agree to round-off,
max|fast − ref| ≤ 1e-12 · max(max|ref|, 1), in every kernel's result (random states with
cond(A) < 30):

1. ``pose_goal``: a_d, ȧ_d, ω_d, ω̇_d (and R_d, roll held) at random times, against
   ``ToolTarget.axis`` / ``frame``: the sphere (no tilt), the pipe (tilt towards the travel),
   a tilt axis, on closed-form paths and on the shipped scenarios' raster and waypoints;
2. ``pose_velocity`` + ``pose_acceleration``: q̇_d, q̈_d, A⁺ at random q (off the pose, so
   the error terms act) and random times;
3. ``pose_newton`` (with the predictor): one advance from a random (q, q̇, q̈);
4. 500 steps of advance(1 ms) from the start pose;
5. whole runs (0.3 s) of scenarios/ur5_sphere_normal.toml and panda_pipe_tilt.toml, roll free
   and held: the compiled run against the oracle plant and the reference controller in q, u,
   f to 1e-10;
6. the non-Euclidean branches (pinocchio.integrate / difference): a UR5 whose first joint is
   stored as (cos, sin), 200 steps;
7. ``Path.evaluate_with_direction_into`` against ``evaluate`` + ``direction_jet``, exactly;
8. a surface without a descriptor (a FunctionSurface: ∇Φ, ∇²Φ and the Hessian's rate given
   to ``pose_goal`` from Python), 200 steps.

On the UR5 (6 joints: roll free m = 5 with a null-space posture term, held m = 6 without) and
the Panda (7 joints, both with one). The RTR arm (3 joints) has no pose task (it is refused:
tests/test_clik_pose.py).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from oracles.control import ReferencePoseJointPath
from oracles.run import oracle_run
from test_clik_pose import CASES

from hybrid_force.control.clik import inverse_kinematics
from hybrid_force.control.pose_clik import PoseJointPath, pose_inverse_kinematics
from hybrid_force.control.tool import ToolSettings, ToolTarget
from hybrid_force.model.robot import Robot
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate

ROOT = Path(__file__).resolve().parents[1]
RTOL = 1e-12
DT = 1e-3
SCENARIOS = {"ur5": "ur5_sphere_normal", "panda": "panda_pipe_tilt"}
WORST: dict[str, float] = {}
FLOOR = 1.0  # [rad/s, rad/s², ...] the scale of a result that cancels (q̇_d near rest:
#             its γ e and null-space terms, O(0.1–1) off the pose, nearly cancel)
COND_MAX = 30.0  # random states kept: cond(A) below (both agree to about cond² · 1e-16)


def _close(what: str, got: object, ref: object) -> None:
    """max|got − ref| ≤ RTOL · max(max|ref|, FLOOR): FLOOR for a result that cancels (q̇_d at
    the raster's start, where the path is at rest)."""
    g = np.asarray(got, dtype=float)
    r = np.asarray(ref, dtype=float)
    assert g.shape == r.shape, what
    assert np.all(np.isfinite(g)), what
    scale = max(float(np.abs(r).max(initial=0.0)), FLOOR)
    err = float(np.abs(g - r).max(initial=0.0))
    WORST[what] = max(WORST.get(what, 0.0), err / scale if scale > 0 else err)
    assert err <= RTOL * scale, f"{what}: {err:.3g} > {RTOL:g} · {scale:.3g}"


def _pair(
    robot: Robot, which: str, roll: str, source: str, tilt_axis: bool = False
) -> tuple[PoseJointPath, ReferencePoseJointPath]:
    """The compiled and the reference pose CLIK from the same start pose.

    source "closed": the closed-form path of tests/test_clik_pose.py; "scenario": the shipped
    scenario's surface and path (raster on the sphere, waypoints in the pipe)."""
    if source == "closed":
        _, surface, path, seed, tilt, _ = CASES[which]
    else:
        sc = load_scenario(ROOT / "scenarios" / f"{SCENARIOS[which]}.toml")
        surface, path, seed, tilt = sc.surfaces[0], sc.path, sc.q0, sc.tool.tilt
    k = (0.0, 1.0, 0.3) if tilt_axis else None
    if tilt_axis and tilt == 0.0:
        tilt = 0.2
    tool = ToolSettings(orientation="normal", tilt=tilt, tilt_axis=k, roll=roll)
    target = ToolTarget(tool, surface, path)
    q0 = inverse_kinematics(robot, path.position(0.0), seed=seed)
    q0 = pose_inverse_kinematics(robot, target, 0.0, q0)
    return PoseJointPath(robot, path, target, q0), ReferencePoseJointPath(robot, path, target, q0)


def _compare_goal(fast: PoseJointPath, ref: ReferencePoseJointPath) -> None:
    _close("p_d", fast._smp, np.array([ref.p_d, ref.pdot_d, ref.pddot_d]))
    _close("a_d", fast.a_d, ref.a_d)
    _close("w_d", fast._goal[2], ref._w_d)
    _close("wdot_d", fast._goal[3], ref._wdot_d)
    if ref.R_d is None:
        assert fast.R_d is None
        _close("adot_d", fast._goal[1], ref._a[1])
    else:
        _close("R_d", fast.R_d, ref.R_d)


def _compare(fast: PoseJointPath, ref: ReferencePoseJointPath) -> None:
    _close("q", fast.q, ref.q)
    _close("qd", fast.qd, ref.qd)
    _close("qdd", fast.qdd, ref.qdd)
    _close("Ap", fast._Ap, ref._Ap)


def _set(path: PoseJointPath, t: float, q: np.ndarray) -> None:
    """Put a pose CLIK at time t and configuration q (then its derivatives there)."""
    path.t = t
    path._sample()
    path.q[:] = q
    if isinstance(path, ReferencePoseJointPath):
        path.q = q.copy()
    path._update_derivatives()


CASES_GOAL = [
    ("ur5", "free", "closed", False),
    ("ur5", "held", "closed", False),
    ("ur5", "free", "closed", True),
    ("panda", "free", "closed", False),
    ("panda", "held", "closed", False),
    ("panda", "held", "closed", True),
    ("ur5", "free", "scenario", False),
    ("ur5", "held", "scenario", False),
    ("panda", "free", "scenario", False),
    ("panda", "held", "scenario", False),
]
IDS = [f"{a}-{r}-{s}{'-tilt_axis' if k else ''}" for a, r, s, k in CASES_GOAL]


@pytest.fixture(scope="module")
def arms(ur5: Robot, panda: Robot) -> dict[str, Robot]:
    return {"ur5": ur5, "panda": panda}


@pytest.mark.parametrize(("which", "roll", "source", "tilt_axis"), CASES_GOAL, ids=IDS)
def test_kernels_equal_the_reference_on_random_states(
    arms: dict[str, Robot], which: str, roll: str, source: str, tilt_axis: bool
) -> None:
    robot = arms[which]
    fast, ref = _pair(robot, which, roll, source, tilt_axis)
    _compare_goal(fast, ref)
    _compare(fast, ref)
    rng = np.random.default_rng(32)
    q0 = ref.q.copy()
    horizon = 4.0 if source == "scenario" else 6.0
    kept = 0
    for _ in range(100):
        t = float(rng.uniform(0.0, horizon))
        q = q0 + rng.uniform(-0.2, 0.2, robot.nq)  # off the pose: the error terms act
        _set(fast, t, q)
        if not _cond(fast._A) < COND_MAX:
            continue
        kept += 1
        if kept > 20:
            break
        _set(ref, t, q)
        _compare_goal(fast, ref)
        _compare(fast, ref)
        # one step from a random (q, q̇, q̈) near the start pose, early on (a Newton step from
        # far off may land near a singular configuration, where both agree only to about
        # cond² · 1e-16): predictor, Newton with this state's A⁺, derivatives
        t = float(rng.uniform(0.0, 0.1))
        q = q0 + rng.uniform(-0.02, 0.02, robot.nq)
        _set(fast, t, q)
        _set(ref, t, q)
        qd = rng.uniform(-0.5, 0.5, robot.nv)
        qdd = rng.uniform(-2.0, 2.0, robot.nv)
        fast.qd[:], fast.qdd[:] = qd, qdd
        fast._dt_pred = 0.0  # the predictor made ahead was for the state just overwritten
        ref.qd, ref.qdd = qd.copy(), qdd.copy()
        fast.advance(DT)
        ref.advance(DT)
        _compare_goal(fast, ref)
        _compare(fast, ref)
    assert kept > 20


def _cond(A: np.ndarray) -> float:
    s = np.linalg.svd(A, compute_uv=False)
    return float(s[0] / s[-1])


@pytest.mark.parametrize(
    ("which", "roll"), [("ur5", "free"), ("ur5", "held"), ("panda", "free"), ("panda", "held")]
)
def test_500_steps_equal_the_reference(arms: dict[str, Robot], which: str, roll: str) -> None:
    fast, ref = _pair(arms[which], which, roll, "closed")
    arrays = (fast.q, fast.qd, fast.qdd, fast.p_d, fast.a_d)
    for _ in range(500):
        fast.advance(DT)
        ref.advance(DT)
        _compare(fast, ref)
    _compare_goal(fast, ref)
    for now, before in zip((fast.q, fast.qd, fast.qdd, fast.p_d, fast.a_d), arrays, strict=True):
        assert now is before  # updated in place


@pytest.mark.parametrize("roll", ["free", "held"])
@pytest.mark.parametrize("which", ["ur5", "panda"])
def test_whole_runs_equal_the_reference_runs(
    which: str, roll: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """0.3 s of the shipped scenario (in contact, pressing): compiled against the oracle
    plant and the reference controller."""
    sc = load_scenario(ROOT / "scenarios" / f"{SCENARIOS[which]}.toml", {"sim.duration": 0.3})
    sc = dataclasses.replace(sc, tool=dataclasses.replace(sc.tool, roll=roll))
    fast, ref = simulate(sc), oracle_run(monkeypatch, sc)
    assert fast.n_samples == ref.n_samples > 100
    for name in ("q", "u", "f", "q_d"):
        got, want = np.asarray(getattr(fast, name)), np.asarray(getattr(ref, name))
        scale = float(np.abs(want).max())
        err = float(np.abs(got - want).max())
        WORST[f"run.{name}"] = max(WORST.get(f"run.{name}", 0.0), err / scale)
        assert err <= 1e-10 * scale, f"{name}: {err:.3g} > 1e-10 · {scale:.3g}"
    assert math.isfinite(float(np.abs(np.asarray(fast.tool_angle)).max()))


@pytest.fixture(scope="module", autouse=True)
def _report_worst() -> Iterator[None]:
    """The largest relative differences seen (shown with ``pytest -s``)."""
    yield
    for what, rel in sorted(WORST.items()):
        print(f"pose kernels, worst |fast - reference| / scale: {what:8} {rel:.2e}")


@pytest.mark.parametrize("which", ["ur5", "panda", "helix"])
def test_evaluate_with_direction_equals_the_two_calls(which: str) -> None:
    """Path.evaluate_with_direction_into (the shape at ℓ(t) shared on a path on a surface)
    gives exactly evaluate(t) and direction_jet(t): the raster, the waypoints, a helix."""
    if which == "helix":
        path = CASES["panda"][2]
    else:
        path = load_scenario(ROOT / "scenarios" / f"{SCENARIOS[which]}.toml").path
    sample, jet = np.zeros((3, 3)), np.zeros((3, 3))
    for t in np.linspace(0.0, 15.0, 61):
        path.evaluate_with_direction_into(float(t), sample, jet)
        np.testing.assert_array_equal(sample, np.array(path.evaluate(float(t))))
        np.testing.assert_array_equal(jet, path.direction_jet(float(t)))


def test_non_euclidean_arm_equals_the_reference(ur5: Robot, tmp_path: Path) -> None:
    """The pinocchio.integrate / difference branches: the UR5 with its first joint stored as
    (cos q1, sin q1) (Pinocchio's JointModelRUBZ, from a continuous URDF joint), roll free."""
    text = Path(ur5.urdf_path).read_text()
    old = '<joint name="shoulder_pan_joint" type="revolute">'
    assert old in text
    urdf = tmp_path / "ur5_rubz.urdf"
    urdf.write_text(text.replace(old, old.replace("revolute", "continuous"), 1))
    model = pin.buildModelFromUrdf(str(urdf))
    assert model.joints[1].shortname() == "JointModelRUBZ"
    robot = Robot(model, name="ur5_rubz", urdf_path=urdf, tip="tool0")
    assert not robot.euclidean and (robot.nq, robot.nv) == (7, 6)
    _, surface, path, seed, tilt, _ = CASES["ur5"]
    target = ToolTarget(ToolSettings(orientation="normal", tilt=tilt), surface, path)
    seed_q = np.concatenate([[math.cos(seed[0]), math.sin(seed[0])], seed[1:]])
    q0 = inverse_kinematics(robot, path.position(0.0), seed=seed_q)
    q0 = pose_inverse_kinematics(robot, target, 0.0, q0)
    fast = PoseJointPath(robot, path, target, q0)
    ref = ReferencePoseJointPath(robot, path, target, q0)
    for _ in range(200):
        fast.advance(DT)
        ref.advance(DT)
        _compare(fast, ref)


def test_function_surface_equals_the_reference(ur5: Robot) -> None:
    """A surface without a descriptor (its ∇Φ, ∇²Φ and the Hessian's rate from Python):
    Φ = ‖p − c‖⁴ − r⁴, the sphere of the UR5 case with a varying Hessian."""
    from hybrid_force.geometry.function_surface import FunctionSurface

    _, sphere, path, seed, _, _ = CASES["ur5"]
    c, r = np.array(sphere.center), sphere.radius

    def phi(p: np.ndarray) -> float:
        w = p - c
        return float((w @ w) ** 2 - r**4)

    def gradient(p: np.ndarray) -> np.ndarray:
        w = p - c
        return 4.0 * float(w @ w) * w

    def hessian(p: np.ndarray) -> np.ndarray:
        w = p - c
        return 4.0 * (float(w @ w) * np.eye(3) + 2.0 * np.outer(w, w))

    surface = FunctionSurface(phi, gradient, hessian)
    target = ToolTarget(ToolSettings(orientation="normal"), surface, path)
    assert target.kernel_inputs()[0].shape == (0,)
    q0 = inverse_kinematics(ur5, path.position(0.0), seed=seed)
    q0 = pose_inverse_kinematics(ur5, target, 0.0, q0)
    fast = PoseJointPath(ur5, path, target, q0)
    ref = ReferencePoseJointPath(ur5, path, target, q0)
    for _ in range(200):
        fast.advance(DT)
        ref.advance(DT)
        _compare_goal(fast, ref)
        _compare(fast, ref)

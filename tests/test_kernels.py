"""The compiled kernels (each concept's ``_kernels.py``) against their numpy references.

Every kernel is reached through the public or module API that uses it, never through its raw
signature, and compared with its readable numpy definition (the controller's in tests/oracles):

1. ``Robot.terms`` (crba + gravity + computeCoriolisMatrix + frame calls + kernel) against
   ``oracles.terms.robot_terms`` (one public method per term), with and without ``out``;
2. ``Robot.euclidean`` against the behaviour of ``pinocchio.integrate`` (plain addition or not);
3. ``Constraint.evaluate`` (k = 1 kernel) against ``oracles.terms.constraint_terms`` (general k-row
   algebra) for every surface type and both normalizations, and the same singular points;
4. ``Surface.evaluate_with_distance`` against ``evaluate`` and ``distance``;
5. ``Path.evaluate_into`` against ``Path.evaluate``;
6. ``LawWorkspace.hybrid`` / ``free_space`` against ``arimoto_law`` / ``free_space_law``
   (k = 1 and 2, β = 0 and > 0, with and without the approach term);
7. ``DesiredJointPath`` against ``ReferenceJointPath`` over 500 steps of 1 ms;
8. ``Plant.advance`` in contact against Euler + ``pinocchio.integrate`` + ``Plant.project``;
9. ``HybridController`` against ``ReferenceController`` through free, near and contact;
10. ``ConstrainedDynamics.solve`` (one forwardDynamics, the loop resolved with its U D Uᵀ
    factorisation) against a dense KKT solve and the defining equations, k = 1, 2, 3;
    ``Baumgarte.gamma_into`` against the formula; the run table's row layout and limits.

(ConstrainedDynamics.solve with k = 1 and B given is already checked against the dense KKT solve in
tests/test_control.py::test_loop_resolved_force_and_closed_loop.)

Both sides are the same formulas in a different order, so they must agree to round-off: the
check is max|fast − reference| ≤ 1e-12 · (scale of the reference array), the scale being the
largest magnitude of the reference or, where a result cancels, of the terms it is made of.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from oracles.control import (
    ReferenceController,
    ReferenceJointPath,
    arimoto_law,
    free_space_law,
)
from oracles.plant import kkt
from oracles.terms import constraint_terms, robot_terms

from hybrid_force.control.clik import DesiredJointPath, inverse_kinematics
from hybrid_force.control.constraint import Constraint, ConstraintTerms
from hybrid_force.control.laws.arimoto import LawWorkspace, make_gains
from hybrid_force.control.laws.base import Command, ControlTrace, Desired, Gains, LawInput
from hybrid_force.control.supervisor import ControlSettings, HybridController
from hybrid_force.errors import BadInputError, SurfaceError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.paths import Circle, FunctionPath, Helix, paper_helix
from hybrid_force.geometry.paths import Path as TaskPath
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.model.loading import load_robot
from hybrid_force.model.robot import Robot, RobotTerms
from hybrid_force.phases import CONTACT, FREE, NEAR
from hybrid_force.sim.plant import Plant
from hybrid_force.sim.settings import SimSettings

ARMS = ("rtr", "ur5", "panda")
RTOL = 1e-12  # relative to the scale of the compared array (see the module docstring)
DT = 1e-3  # [s]
ROBOT_FIELDS = ("M", "C", "g", "nle", "p", "J", "Jdot", "Jdot_v", "pdot")
CONSTRAINT_FIELDS = (
    "phi",
    "distance",
    "J_phi",
    "J_phi_n",
    "scale",
    "A",
    "Adot",
    "A_pinv",
    "A_pinv_dot",
    "Q",
    "Qdot",
    "rate",
    "raw_drift",
    "drift",
)
TRACE_ARRAYS = ("e_q", "s", "s0", "s1", "e_F", "qdot_r", "qddot_r0", "f_d")

# Largest measured |fast − reference| / scale per compared quantity (inspect after a run).
WORST: dict[str, float] = {}


def _close(what: str, got: object, ref: object, scale: float | None = None) -> None:
    """Assert max|got − ref| ≤ RTOL · scale; scale defaults to max|ref| (exact if ref = 0)."""
    got_a = np.asarray(got, dtype=float)
    ref_a = np.asarray(ref, dtype=float)
    assert got_a.shape == ref_a.shape, f"{what}: shape {got_a.shape} != {ref_a.shape}"
    assert np.all(np.isfinite(got_a)), f"{what}: non-finite fast result {got_a}"
    assert np.all(np.isfinite(ref_a)), f"{what}: non-finite reference {ref_a}"
    if scale is None:
        scale = float(np.abs(ref_a).max(initial=0.0))
    err = float(np.abs(got_a - ref_a).max(initial=0.0))
    rel = err / scale if scale > 0 else (0.0 if err == 0 else math.inf)
    WORST[what] = max(WORST.get(what, 0.0), rel)
    assert err <= RTOL * scale, (
        f"{what}: max|fast − reference| = {err:.3g} > {RTOL:g} × scale {scale:.3g}\n"
        f"fast = {got_a}\nreference = {ref_a}"
    )


@pytest.fixture(scope="module")
def arms() -> dict[str, Robot]:
    return {name: load_robot(name) for name in ARMS}


def _random_state(robot: Robot, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """q uniform within the joint limits (±π for an unbounded joint), v uniform in [−2, 2]."""
    lo, hi = robot.position_limits
    lo, hi = np.where(np.isfinite(lo), lo, -math.pi), np.where(np.isfinite(hi), hi, math.pi)
    q = lo + (hi - lo) * rng.random(robot.nq)
    return q, rng.uniform(-2.0, 2.0, robot.nv)


def _fill_nan(obj: RobotTerms | ConstraintTerms) -> None:
    """Poison every array of a buffer, so an entry the fast path forgets to write shows."""
    for value in vars(obj).values():
        if isinstance(value, np.ndarray):  # the fields (private packs are views' owners)
            value[...] = np.nan


# --- 1. robot terms ------------------------------------------------------------------------------
def _check_robot_terms(robot: Robot, got: RobotTerms, q: np.ndarray, v: np.ndarray) -> None:
    ref = robot_terms(robot, q, v)
    for name in ROBOT_FIELDS:
        a, b = getattr(got, name), getattr(ref, name)
        if name == "nle":  # C v + g: scaled by its terms, not by the (possibly cancelling) sum
            scale = float(np.abs(ref.C).max() * np.abs(v).sum() + np.abs(ref.g).max())
        elif name in ("Jdot_v", "pdot"):  # J̇ v and J v
            M = ref.Jdot if name == "Jdot_v" else ref.J
            scale = float(np.abs(M).max() * np.abs(v).sum())
        else:
            scale = None
        _close(f"terms.{name}", a, b, scale)
    np.testing.assert_array_equal(got.M, got.M.T)  # the mirrored crba output is exactly symmetric


@pytest.mark.parametrize("arm", ARMS)
def test_robot_terms_equal_the_oracle_terms(arms: dict[str, Robot], arm: str) -> None:
    robot = arms[arm]
    rng = np.random.default_rng(101)
    data = robot.new_data()
    for _ in range(8):
        q, v = _random_state(robot, rng)
        _check_robot_terms(robot, robot.terms(q, v, data), q, v)
        _check_robot_terms(robot, robot.terms(q, v), q, v)  # the robot's own data


@pytest.mark.parametrize("arm", ARMS)
def test_robot_terms_fill_the_given_buffer_completely(arms: dict[str, Robot], arm: str) -> None:
    robot = arms[arm]
    rng = np.random.default_rng(102)
    data = robot.new_data()
    buf = RobotTerms.zeros(robot.nv)
    arrays = {name: getattr(buf, name) for name in ROBOT_FIELDS}
    for _ in range(3):  # each call overwrites the previous state's values (no stale entries)
        q, v = _random_state(robot, rng)
        _fill_nan(buf)
        out = robot.terms(q, v, data, out=buf)
        assert out is buf
        for name in ROBOT_FIELDS:
            assert getattr(out, name) is arrays[name]  # written in place, not rebound
        _check_robot_terms(robot, out, q, v)
        fresh = robot.terms(q, v, robot.new_data())
        for name in ROBOT_FIELDS:  # same code path: bit for bit
            np.testing.assert_array_equal(getattr(out, name), getattr(fresh, name))
    # and without poisoning: a second state after a first one
    q1, v1 = _random_state(robot, rng)
    q2, v2 = _random_state(robot, rng)
    robot.terms(q1, v1, data, out=buf)
    _check_robot_terms(robot, robot.terms(q2, v2, data, out=buf), q2, v2)


@pytest.mark.parametrize("arm", ARMS)
def test_bound_robot_terms_equal_the_oracle_and_terms(arms: dict[str, Robot], arm: str) -> None:
    """Robot.terms_into(data, out)(q, v): the oracle's terms (one public method per term), in
    out's arrays, and bit for bit Robot.terms at the same state, state after state."""
    robot = arms[arm]
    rng = np.random.default_rng(103)
    buf = RobotTerms.zeros(robot.nv)
    arrays = {name: getattr(buf, name) for name in ROBOT_FIELDS}
    terms_at = robot.terms_into(robot.new_data(), buf)
    for _ in range(4):
        q, v = _random_state(robot, rng)
        _fill_nan(buf)
        out = terms_at(q, v)
        assert out is buf and all(getattr(out, n) is arrays[n] for n in ROBOT_FIELDS)
        _check_robot_terms(robot, out, q, v)
        fresh = robot.terms(q, v, robot.new_data())
        for name in ROBOT_FIELDS:
            np.testing.assert_array_equal(getattr(out, name), getattr(fresh, name))
    with pytest.raises(BadInputError, match=r"RobotTerms\.zeros"):
        robot.terms_into(robot.new_data(), robot_terms(robot, q, v))


# --- 2. euclidean configuration spaces -----------------------------------------------------------
@pytest.mark.parametrize("arm", ARMS)
def test_bundled_arms_are_euclidean(arms: dict[str, Robot], arm: str) -> None:
    robot = arms[arm]
    assert robot.euclidean is True
    rng = np.random.default_rng(103)
    assert robot.nq == robot.nv
    for _ in range(5):  # the independent reason: q ⊕ dq is plain addition
        q, dq = _random_state(robot, rng)
        np.testing.assert_array_equal(pin.integrate(robot.model, q, dq), q + dq)


def _rtr_with_continuous_base(rtr_urdf: Path) -> Robot:
    """The RTR arm with q1 stored as (cos q1, sin q1): Pinocchio's own JointModelRUBZ.

    ``pin.buildModelFromUrdf`` builds rtr.urdf's continuous q1 that way; ``load_robot`` no
    longer does (it makes it an unbounded revolute joint), so the non-Euclidean branches are
    reached through a Robot made directly from the model.
    """
    model = pin.buildModelFromUrdf(str(rtr_urdf))
    assert model.joints[1].shortname() == "JointModelRUBZ"
    return Robot(model, name="rtr_rubz", urdf_path=rtr_urdf, tip="tip")


def test_continuous_urdf_joint_is_euclidean(arms: dict[str, Robot]) -> None:
    """rtr.urdf's q1 is continuous: loaded as one unbounded angle, integrated by addition."""
    robot = arms["rtr"]
    assert robot.model.joints[1].shortname() == "JointModelRZ"
    assert (robot.nq, robot.nv) == (3, 3)
    lower, upper = robot.position_limits
    assert (lower[0], upper[0]) == (-math.inf, math.inf)
    q0 = np.array([6.0, 2.0, 0.3])
    dq = np.array([7.5, -0.2, 0.1])  # q1 passes 4π: the angle is not wrapped
    q1 = pin.integrate(robot.model, q0, dq)
    np.testing.assert_array_equal(q1, q0 + dq)
    assert q1[0] == 13.5
    # the angle still means the same pose: 13.5 rad and 13.5 − 4π give one tip position
    wrapped = q1 - np.array([4 * math.pi, 0.0, 0.0])
    np.testing.assert_allclose(robot.tip_position(q1), robot.tip_position(wrapped), atol=1e-14)


def test_continuous_joint_as_rubz_is_not_euclidean(rtr_urdf: Path) -> None:
    robot = _rtr_with_continuous_base(rtr_urdf)
    assert robot.euclidean is False
    # the independent reason: q has 4 numbers for 3 velocities, and integrate rotates the
    # unit complex number (cos q1, sin q1) instead of adding to it
    assert (robot.nq, robot.nv) == (4, 3)
    q0 = robot.neutral()
    np.testing.assert_array_equal(q0[:2], [1.0, 0.0])
    dq = np.array([0.7, 0.2, -0.3])
    q1 = pin.integrate(robot.model, q0, dq)
    np.testing.assert_allclose(q1[:2], [math.cos(0.7), math.sin(0.7)], rtol=0, atol=1e-15)
    assert abs(q1[0] - (q0[0] + dq[0])) > 0.1
    np.testing.assert_allclose(q1[2:], q0[2:] + dq[1:], rtol=0, atol=1e-15)


# --- 3. constraint terms, k = 1 ------------------------------------------------------------------
def _ellipsoid() -> FunctionSurface:
    """(x/a)² + (y/b)² + (z/c)² − 1 around (0.1, 0, 0.4), analytic derivatives."""
    c = np.array([0.1, 0.0, 0.4])
    w = 1.0 / np.array([0.5, 0.7, 0.9]) ** 2

    def phi(p: np.ndarray) -> float:
        d = p - c
        return float(d @ (w * d) - 1.0)

    def gradient(p: np.ndarray) -> np.ndarray:
        return 2.0 * w * (p - c)

    def hessian(p: np.ndarray) -> np.ndarray:
        return np.diag(2.0 * w)

    return FunctionSurface(phi, gradient, hessian)


def _wavy() -> FunctionSurface:
    """z − 0.3 − 0.05 sin(3x) cos(2y), derivatives by finite differences (deterministic)."""

    def phi(p: np.ndarray) -> float:
        return float(p[2] - 0.3 - 0.05 * math.sin(3 * p[0]) * math.cos(2 * p[1]))

    return FunctionSurface(phi)


SURFACES: dict[str, Callable[[], Surface]] = {
    "cylinder": lambda: Cylinder(0.4),
    "cylinder_inside_tilted": lambda: Cylinder(
        0.6, center=(0.1, -0.2, 0.3), axis=(0.3, -0.2, 1.0), inside=True
    ),
    "sphere_outside": lambda: Sphere(0.3, center=(0.2, 0.1, 0.4)),
    "sphere_inside": lambda: Sphere(1.5, center=(0.1, 0.2, 0.5), inside=True),
    "plane": lambda: Plane((0.0, 0.0, 0.3), (0.2, -0.1, 1.0)),
    "function_analytic": _ellipsoid,
    "function_fd": _wavy,
}


def _check_constraint_terms(
    got: ConstraintTerms, ref: ConstraintTerms, terms: RobotTerms, v: np.ndarray, surface: Surface
) -> None:
    _, grad, hess = surface.evaluate(terms.p)
    # raw drift ṗᵀ∇²Φṗ + ∇ΦᵀJ̇v: scaled by its two terms, not by their (cancelling) sum
    raw_scale = float(
        np.abs(hess).max() * np.abs(terms.pdot).sum() ** 2
        + np.abs(grad).sum() * np.abs(terms.Jdot_v).max()
    )
    # d(J_Φ)/dt = (∇²Φ ṗ)ᵀJ + ∇ΦᵀJ̇, by its terms: Ȧ is exactly 0 where A is constant
    row_dot_scale = float(
        np.abs(hess @ terms.pdot).sum() * np.abs(terms.J).max()
        + np.abs(grad).sum() * np.abs(terms.Jdot).max()
    )
    adot_scale = float(np.abs(ref.Adot).max() + row_dot_scale / ref.scale[0])
    apd_scale = float(np.abs(ref.A_pinv_dot).max() + 3.0 * adot_scale / (ref.A @ ref.A.T)[0, 0])
    for name in CONSTRAINT_FIELDS:
        a, b = getattr(got, name), getattr(ref, name)
        scale = None
        if name == "Adot":
            scale = adot_scale
        elif name == "rate":  # A v: scaled by its terms
            scale = float(np.abs(ref.A).max() * np.abs(v).sum())
        elif name == "raw_drift":
            scale = raw_scale
        elif name == "drift":
            scale = raw_scale / float(ref.scale[0])
        elif name == "A_pinv_dot":  # Ȧᵀ/‖A‖² + Aᵀ d(1/‖A‖²)/dt
            scale = apd_scale
        elif name == "Qdot":  # −(Ȧ⁺A + A⁺Ȧ), exactly 0 where Q is constant
            scale = float(apd_scale * np.abs(ref.A).max() + np.abs(ref.A_pinv).max() * adot_scale)
        elif name in ("phi", "distance"):  # a scalar: relative to itself
            scale = max(float(np.abs(b).max()), 1e-300)
        _close(f"constraint.{name}", a, b, scale)


@pytest.mark.parametrize("normalization", ["tip", "joint"])
@pytest.mark.parametrize("surface_name", list(SURFACES))
@pytest.mark.parametrize("arm", ARMS)
def test_constraint_fast_equals_general_algebra(
    arms: dict[str, Robot], arm: str, surface_name: str, normalization: str
) -> None:
    robot = arms[arm]
    con = Constraint(SURFACES[surface_name](), normalization)
    rng = np.random.default_rng(104)
    data = robot.new_data()
    buf = ConstraintTerms.zeros(1, robot.nv)
    for _ in range(4):
        q, v = _random_state(robot, rng)
        terms = robot.terms(q, v, data)
        ref = constraint_terms(con, terms, v)
        _check_constraint_terms(con.evaluate(terms, v), ref, terms, v, con.surfaces[0])
        _fill_nan(buf)
        out = con.evaluate(terms, v, out=buf)
        assert out is buf
        _check_constraint_terms(out, ref, terms, v, con.surfaces[0])


@pytest.mark.parametrize("arm", ARMS)
def test_constraint_buffer_is_overwritten_by_the_next_state(
    arms: dict[str, Robot], arm: str
) -> None:
    robot = arms[arm]
    con = Constraint(Sphere(0.3, center=(0.2, 0.1, 0.4)))
    rng = np.random.default_rng(105)
    buf = ConstraintTerms.zeros(1, robot.nv)
    arrays = {name: getattr(buf, name) for name in CONSTRAINT_FIELDS}
    for _ in range(3):
        q, v = _random_state(robot, rng)
        terms = robot.terms(q, v, robot.new_data())
        out = con.evaluate(terms, v, out=buf)
        assert out is buf
        for name in CONSTRAINT_FIELDS:
            assert getattr(out, name) is arrays[name]
        ref = constraint_terms(con, terms, v)
        _check_constraint_terms(out, ref, terms, v, con.surfaces[0])


def _rtr_terms(robot: Robot, q: list[float], v: list[float]) -> tuple[RobotTerms, np.ndarray]:
    qa, va = np.array(q), np.array(v)
    return robot.terms(qa, va, robot.new_data()), va


@pytest.mark.parametrize("reference", [True, False])
def test_singular_points_raise_on_both_paths(arms: dict[str, Robot], reference: bool) -> None:
    robot = arms["rtr"]
    terms, v = _rtr_terms(robot, [0.4, 6.0, 0.7], [0.3, -0.2, 0.5])
    p = terms.p
    # tip on the axis of a vertical cylinder: w⊥ = 0 exactly, ∇Φ = 0
    on_axis = Cylinder(0.4, center=(float(p[0]), float(p[1]), 0.0))
    _, grad, _ = on_axis.evaluate(p)
    np.testing.assert_array_equal(grad, np.zeros(3))
    for normalization in ("tip", "joint"):
        with pytest.raises(SurfaceError, match="∇Φ vanishes"):
            _evaluate(Constraint(on_axis, normalization), terms, v, reference)
    # q1 = q3 = 0: the tip (1.9, 0, z) cannot move along x (J_Φ = n̂ᵀJ = 0 for a plane ⟂ x)
    terms, v = _rtr_terms(robot, [0.0, 6.0, 0.0], [0.3, -0.2, 0.5])
    assert np.abs(terms.J[0]).max() < 1e-15
    wall = Plane((2.5, 0.0, 0.0), (-1.0, 0.0, 0.0))
    for normalization in ("tip", "joint"):
        with pytest.raises(SurfaceError, match="J_Φ is \\(near\\) zero"):
            _evaluate(Constraint(wall, normalization), terms, v, reference)


# --- 4. surfaces: value, derivatives and distance in one call ------------------------------------
def test_evaluate_with_distance_equals_evaluate_and_distance() -> None:
    rng = np.random.default_rng(106)
    surfaces = {name: make() for name, make in SURFACES.items()}
    surfaces["function_with_distance"] = FunctionSurface(
        lambda p: float(p @ p - 0.25), distance=lambda p: float(np.linalg.norm(p) - 0.5)
    )
    surfaces["sphere_outside_2"] = Sphere(0.7, center=(-0.3, 0.2, 0.1))
    surfaces["cylinder_tilted"] = Cylinder(0.25, center=(0.0, 0.5, 0.0), axis=(1.0, 1.0, 0.2))
    for name, surface in surfaces.items():
        for _ in range(20):
            p = rng.uniform(-1.5, 1.5, 3)
            value, grad, hess, dist = surface.evaluate_with_distance(p)
            ref_value, ref_grad, ref_hess = surface.evaluate(p)
            _close(f"surface.phi[{name}]", value, ref_value, max(abs(ref_value), 1e-300))
            _close(f"surface.grad[{name}]", grad, ref_grad)
            _close(f"surface.hess[{name}]", hess, ref_hess)
            ref_dist = surface.distance(p)
            _close(f"surface.distance[{name}]", dist, ref_dist, max(abs(ref_dist), 1e-300))


# --- 5. paths ------------------------------------------------------------------------------------
def _function_path() -> FunctionPath:
    def position(t: float) -> np.ndarray:
        return np.array([0.4 + 0.1 * math.cos(2 * t), 0.1 * math.sin(3 * t), 0.3 + 0.02 * t])

    return FunctionPath(position)


PATHS: dict[str, Callable[[], TaskPath]] = {
    "helix": lambda: Helix(
        (0.1, -0.2, 0.5), 0.3, axis=(0.2, 0.3, 1.0), omega=-1.7, rise=0.05, phase=0.4
    ),
    "circle": lambda: Circle((0.4, 0.1, 0.3), 0.1, normal=(0.0, 0.1, 1.0), omega=2.3, phase=-1.0),
    "paper_helix": paper_helix,
    "function": _function_path,
}


@pytest.mark.parametrize("path_name", list(PATHS))
def test_evaluate_into_equals_evaluate(path_name: str) -> None:
    path = PATHS[path_name]()
    rng = np.random.default_rng(107)
    p, v, a = np.full(3, np.nan), np.full(3, np.nan), np.full(3, np.nan)
    times = [0.0, 1e-3, 0.5, math.pi, 17.25, *rng.uniform(-5.0, 50.0, 8).tolist()]
    for t in times:
        path.evaluate_into(t, p, v, a)
        ref_p, ref_v, ref_a = path.evaluate(t)
        _close("path.p", p, ref_p)
        _close("path.v", v, ref_v)
        _close("path.a", a, ref_a)


# --- 6. control laws -----------------------------------------------------------------------------
# IK seeds that reach the circle of benchmarks/bench_loop.py on the plane z = 0.3 m
PLANE_SEEDS = {"ur5": [0, -1.0, 1.5, -2.0, -1.57, 0], "panda": [0, -0.3, 0, -2.2, 0, 1.9, 0.785]}
TWO_PLANES = (Plane((0.0, 0.0, 0.3), (0.0, 0.1, 1.0)), Plane((0.4, 0.0, 0.0), (1.0, 0.2, 0.1)))


def _gains(robot: Robot, rng: np.random.Generator, beta: float) -> Gains:
    G = rng.normal(size=(robot.nv, robot.nv))
    Kd = G @ G.T + robot.nv * np.eye(robot.nv)
    return make_gains(0.5 * (Kd + Kd.T), 7.0, beta, 20.0, robot.nv)


def _compare_trace(got: ControlTrace, ref: ControlTrace, M: np.ndarray) -> None:
    for name in TRACE_ARRAYS:
        _close(f"trace.{name}", getattr(got, name), getattr(ref, name))
    if ref.qddot_r_f is None:
        assert got.qddot_r_f is None
    else:
        assert got.qddot_r_f is not None
        _close("trace.qddot_r_f", got.qddot_r_f, ref.qddot_r_f)
    s_scale = float(np.abs(ref.s).max())
    _close("trace.V", got.V, ref.V, float(np.abs(M).max()) * s_scale**2 + abs(ref.V))


def _law_inputs(
    robot: Robot, rng: np.random.Generator
) -> tuple[np.ndarray, RobotTerms, Desired, np.ndarray]:
    q, v = _random_state(robot, rng)
    terms = robot.terms(q, v, robot.new_data())
    n = robot.nv
    desired = Desired(
        q=q + rng.uniform(-0.1, 0.1, n), qd=rng.uniform(-1, 1, n), qdd=rng.uniform(-2, 2, n)
    )
    return v, terms, desired, q - desired.q


def _u0_scale(
    terms: RobotTerms, Kd: np.ndarray, trace: ControlTrace, u0: np.ndarray, mass: float = 1.0
) -> float:
    """Size of the terms u0 is a sum of: M q̈_r, C q̇_r, g, K_d s and Aᵀ(f_d − γ e_F)."""
    return float(
        mass * np.abs(terms.M).max() * np.abs(trace.qddot_r0).sum()
        + mass * np.abs(terms.C).max() * np.abs(trace.qdot_r).sum()
        + mass * np.abs(terms.g).max()
        + np.abs(Kd).max() * np.abs(trace.s).sum()
        + np.abs(u0).max()
    )


@pytest.mark.parametrize("with_approach", [False, True])
@pytest.mark.parametrize("beta", [0.0, 0.3])
@pytest.mark.parametrize("k", [1, 2])
@pytest.mark.parametrize("arm", ARMS)
def test_law_workspace_equals_the_reference_laws(
    arms: dict[str, Robot], arm: str, k: int, beta: float, with_approach: bool
) -> None:
    robot = arms[arm]
    rng = np.random.default_rng(108)
    surfaces = [Sphere(0.3, center=(0.2, 0.1, 0.4))] if k == 1 else list(TWO_PLANES)
    con = Constraint(surfaces)
    gains = _gains(robot, rng, beta)
    ws = LawWorkspace(robot.nv, k, gains)
    for step in range(6):  # one workspace, hybrid and free calls interleaved
        v, terms, desired, e_q = _law_inputs(robot, rng)
        cons = constraint_terms(con, terms, v)
        if step % 3 == 2:
            cmd = ws.free_space(LawInput(terms, v, e_q, desired))
            u0, B, trace = cmd.u0.copy(), cmd.B, ws.trace(e_q, np.zeros(k), np.zeros(k))
            ref_cmd, ref_trace = free_space_law(gains, terms, v, e_q, desired)
            assert B is None and ref_cmd.B is None
            assert ws.in_contact_law is False
        else:
            e_F = rng.uniform(-1, 1, k)
            f_d = rng.uniform(0, 20, k)
            approach = rng.uniform(-0.5, 0.5, k) if with_approach else None
            cmd = ws.hybrid(LawInput(terms, v, e_q, desired, cons, e_F, f_d, approach))
            u0, B = cmd.u0.copy(), None if cmd.B is None else cmd.B.copy()
            trace = ws.trace(e_q, e_F, f_d)
            ref_cmd, ref_trace = arimoto_law(
                gains, terms, cons, v, e_q, desired, e_F, f_d, approach
            )
            assert ws.in_contact_law is True
            if beta == 0.0:
                assert B is None and ref_cmd.B is None
            else:
                assert B is not None and ref_cmd.B is not None
                _close("law.B", B, ref_cmd.B)
        assert ws.V == trace.V
        _close("law.u0", u0, ref_cmd.u0, _u0_scale(terms, gains.Kd, ref_trace, ref_cmd.u0))
        _compare_trace(trace, ref_trace, terms.M)


# --- 7. desired joint path (CLIK) ----------------------------------------------------------------
def _clik_case(arms: dict[str, Robot], arm: str) -> tuple[Robot, TaskPath, np.ndarray]:
    robot = arms[arm]
    if arm == "rtr":
        path: TaskPath = paper_helix()
        seed = [0.0, 6.0, 2.0]
    else:  # the reachable circle of benchmarks/bench_loop.py, on the plane z = 0.3 m
        path = Circle(center=(0.4, 0.1, 0.3), radius=0.1, normal=(0, 0, 1), omega=1)
        seed = PLANE_SEEDS[arm]
    return robot, path, inverse_kinematics(robot, path.position(0), seed=np.array(seed))


def _compare_clik(fast: DesiredJointPath, ref: DesiredJointPath) -> None:
    assert fast.t == ref.t
    for name in ("p_d", "pdot_d", "pddot_d", "q"):
        _close(f"clik.{name}", getattr(fast, name), getattr(ref, name))
    # q̇_d = J⁺(ṗ_d − γ(p(q_d) − p_d)) + …: the γ-term cancels positions of size |p_d|, so
    # the round-off of q_d reaches q̇_d amplified by γ‖J⁺‖; q̈_d = J⁺(p̈_d − γ(Jq̇_d − ṗ_d)
    # − J̇q̇_d) + … likewise (on the paper's helix the RTR q̈_d is exactly 0). Scales by terms:
    gamma = ref.settings.gamma
    Jp = float(np.abs(np.linalg.pinv(ref.robot.jacobian(ref.q))).max())
    qd_scale = float(
        np.abs(ref.qd).max() + Jp * (np.abs(ref.pdot_d).max() + gamma * np.abs(ref.p_d).max())
    )
    qdd_scale = float(
        np.abs(ref.qdd).max()
        + Jp * (np.abs(ref.pddot_d).max() + gamma * np.abs(ref.pdot_d).max())
        + Jp * np.abs(ref.qd).max() ** 2
        + gamma * qd_scale
    )
    _close("clik.qd", fast.qd, ref.qd, qd_scale)
    _close("clik.qdd", fast.qdd, ref.qdd, qdd_scale)


def _advance_both(fast: DesiredJointPath, ref: DesiredJointPath, steps: int) -> None:
    _compare_clik(fast, ref)
    arrays = [fast.q, fast.qd, fast.qdd]
    for _ in range(steps):
        fast.advance(DT)
        ref.advance(DT)
        _compare_clik(fast, ref)
    for now, before in zip([fast.q, fast.qd, fast.qdd], arrays, strict=True):
        assert now is before  # the fast path updates q_d, q̇_d, q̈_d in place


@pytest.mark.parametrize("arm", ["rtr", "panda"])
def test_desired_joint_path_fast_equals_reference(arms: dict[str, Robot], arm: str) -> None:
    robot, path, q0 = _clik_case(arms, arm)
    fast = DesiredJointPath(robot, path, q0)
    ref = ReferenceJointPath(robot, path, q0)
    _advance_both(fast, ref, 500)


def test_desired_joint_path_fast_on_a_continuous_joint(rtr_urdf: Path) -> None:
    """The non-Euclidean branches (pinocchio.integrate / difference) of the fast CLIK."""
    robot = _rtr_with_continuous_base(rtr_urdf)
    path = paper_helix()
    q0 = inverse_kinematics(robot, path.position(0), seed=np.array([1.0, 0.0, 6.0, 2.0]))
    fast = DesiredJointPath(robot, path, q0)
    ref = ReferenceJointPath(robot, path, q0)
    _advance_both(fast, ref, 200)


def _plant(robot: Robot, con: Constraint) -> Plant:
    """A plant in contact with the surface of ``con`` (Euler: its compiled contact step)."""
    plant = Plant(robot, con, SimSettings(), 1e-5)
    plant.in_contact = True
    return plant


_NO_COMMAND = Command(u0=np.zeros(0), B=None)  # the Euler step does not read the command
_ON_SURFACE = np.zeros(1)


def _evaluate(
    con: Constraint, terms: RobotTerms, v: np.ndarray, reference: bool
) -> ConstraintTerms:
    return constraint_terms(con, terms, v) if reference else con.evaluate(terms, v)


# --- 8. plant: semi-implicit Euler and post-stabilisation ----------------------------------------
def _contact_states(
    robot: Robot, surface: Surface, rng: np.random.Generator, count: int
) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(q on the surface, v tangent to it, random q̈) for the plant tests."""
    if robot.name == "rtr":
        path: TaskPath = paper_helix()
        seed = np.array([0.0, 6.0, 2.0])
    else:
        path = Circle(center=(0.4, 0.1, 0.3), radius=0.1, normal=(0, 0, 1), omega=1)
        seed = np.array(PLANE_SEEDS[robot.name])
    con = Constraint(surface)
    for t in rng.uniform(0, 6, count):
        q = inverse_kinematics(robot, path.position(t), seed=seed)
        assert abs(surface.distance(robot.tip_position(q))) < 1e-10
        v = con.at(robot, q).Q @ rng.uniform(-1, 1, robot.nv)
        yield q, v, rng.uniform(-3, 3, robot.nv)


def _plant_reference(
    plant: Plant, q: np.ndarray, v: np.ndarray, ddq: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    v1 = v + ddq * DT
    q1 = pin.integrate(plant.robot.model, q, v1 * DT)
    return plant.project(q1, v1)


@pytest.mark.parametrize("arm", ARMS)
def test_contact_step_equals_euler_and_projection(arms: dict[str, Robot], arm: str) -> None:
    robot = arms[arm]
    surface = Cylinder(0.4) if arm == "rtr" else Plane((0, 0, 0.3), (0, 0, 1))
    con = Constraint(surface)
    plant, ref_plant = _plant(robot, con), _plant(robot, con)
    rng = np.random.default_rng(109)
    for q0, v0, ddq0 in _contact_states(robot, surface, rng, 3):
        inputs = [q0.copy(), v0.copy()]
        q1, v1 = plant.advance(q0, v0, ddq0, _NO_COMMAND, 0.0, DT, _ON_SURFACE)
        assert q1 is not q0 and v1 is not v0 and q1 is not v1
        np.testing.assert_array_equal(q0, inputs[0])  # inputs untouched
        np.testing.assert_array_equal(v0, inputs[1])
        rq1, rv1 = _plant_reference(ref_plant, q0, v0, ddq0)
        _close("plant.q", q1, rq1)
        _close("plant.v", v1, rv1, float(np.abs(v0).max() + np.abs(ddq0).max() * DT))
        # the next step, from the plant's own output arrays
        saved = (q1.copy(), v1.copy())
        ddq1 = rng.uniform(-3, 3, robot.nv)
        q2, v2 = plant.advance(q1, v1, ddq1, _NO_COMMAND, 0.0, DT, _ON_SURFACE)
        for out in (q2, v2):
            assert out is not q1 and out is not v1 and out is not q0 and out is not v0
        assert q2 is not v2
        np.testing.assert_array_equal(q1, saved[0])  # the input pair is not overwritten
        np.testing.assert_array_equal(v1, saved[1])
        rq2, rv2 = _plant_reference(ref_plant, saved[0], saved[1], ddq1)
        _close("plant.q", q2, rq2)
        _close("plant.v", v2, rv2, float(np.abs(v1).max() + np.abs(ddq1).max() * DT))
        # the step is not a no-op: it moved along the surface and stayed on it
        assert np.abs(q2 - q0).max() > 1e-6
        assert abs(surface.distance(robot.tip_position(q2))) < 1e-9


# --- 9. the whole controller ---------------------------------------------------------------------
def _controller_case(
    arms: dict[str, Robot], arm: str
) -> tuple[Robot, Surface, TaskPath, np.ndarray, list[np.ndarray]]:
    """Robot, surface, path, q0 and tip targets going free → near → contact."""
    robot = arms[arm]
    gaps = [0.12, 0.09, 0.06, 0.04, 0.03, 0.02, 0.01, 0.004] + [0.0] * 12
    if arm == "rtr":  # outside the paper's cylinder, approaching it radially
        surface: Surface = Cylinder(0.4)
        path: TaskPath = paper_helix()
        seed = np.array([0.0, 9.0, 2.0])
        targets = [
            np.array(
                [(0.4 + d) * math.cos(0.1 * i), (0.4 + d) * math.sin(0.1 * i), 10.0 + 0.01 * i]
            )
            for i, d in enumerate(gaps)
        ]
    else:  # above the plane z = 0.3, coming down
        surface = Plane((0, 0, 0.3), (0, 0, 1))
        path = Circle(center=(0.4, 0.1, 0.3), radius=0.1, normal=(0, 0, 1), omega=1)
        seed = np.array(PLANE_SEEDS[arm])
        targets = [path.position(0.02 * i) + np.array([0, 0, d]) for i, d in enumerate(gaps)]
    qs = []
    for p in targets:
        seed = inverse_kinematics(robot, p, seed=seed)
        qs.append(seed)
    return robot, surface, path, qs[0], qs


@pytest.mark.parametrize("mass_factor", [1.0, 1.25])
@pytest.mark.parametrize("arm", ARMS)
def test_hybrid_controller_fast_equals_reference(
    arms: dict[str, Robot], arm: str, mass_factor: float
) -> None:
    robot, surface, path, q0, qs = _controller_case(arms, arm)
    con = Constraint(surface)
    settings = ControlSettings(mass_factor=mass_factor)
    fast = HybridController(robot, con, path, q0, settings, dt=DT)
    ref = ReferenceController(robot, con, path, q0, settings, dt=DT)
    rng = np.random.default_rng(110)
    phases = []
    for i, q in enumerate(qs):
        t = i * DT
        v = rng.uniform(-0.3, 0.3, robot.nv)
        terms = robot.terms(q, v, robot.new_data())
        cons = None if i == 0 else constraint_terms(con, terms, v)
        cmd = fast.command(t, q, v, terms, cons)
        u0, B = cmd.u0.copy(), None if cmd.B is None else cmd.B.copy()
        V, trace = fast.V, fast.trace
        ref_cmd = ref.command(t, q, v, terms, cons)
        assert fast.phase == ref.phase
        phases.append(ref.phase)
        assert ref.trace is not None
        scale = _u0_scale(terms, ref.gains.Kd, ref.trace, ref_cmd.u0, mass_factor)
        _close("controller.u0", u0, ref_cmd.u0, scale)
        if ref_cmd.B is None:
            assert B is None
        else:
            assert B is not None
            _close("controller.B", B, ref_cmd.B)
        _close("controller.V", V, ref.V, abs(ref.V) + 1e-300)
        assert trace is not None and ref.trace is not None
        _compare_trace(trace, ref.trace, terms.M * mass_factor)
        np.testing.assert_array_equal(fast.f_d, ref.f_d)
        f = rng.uniform(5, 15, 1) if ref.phase == CONTACT else np.zeros(1)
        fast.update(DT, f)
        ref.update(DT, f)
        _compare_clik(fast.clik, ref.clik)
    assert phases[0] == FREE and NEAR in phases and phases[-1] == CONTACT
    assert [e.kind for e in fast.events] == [e.kind for e in ref.events]


@pytest.mark.parametrize("arm", ARMS)
def test_hybrid_controller_without_supervisor_steady_path(arms: dict[str, Robot], arm: str) -> None:
    """``supervisor = false``: after the first call every command takes the steady contact path
    (``HybridController._contact_command``, the law's input kept from the first call); at
    random states its commands, V, traces, f_d and CLIK equal the general path's bit for bit
    (the same controller with that path switched off) and the reference controller's to
    round-off."""
    robot, surface, path, q0, qs = _controller_case(arms, arm)
    con = Constraint(surface)
    settings = ControlSettings(supervisor=False)
    fast = HybridController(robot, con, path, q0, settings, dt=DT)
    general = HybridController(robot, con, path, q0, settings, dt=DT)
    general._steady_contact = False  # every call through the phase logic of command()
    ref = ReferenceController(robot, con, path, q0, settings, dt=DT)
    rng = np.random.default_rng(111)
    for i, q in enumerate(qs):
        t = i * DT
        v = rng.uniform(-0.3, 0.3, robot.nv)
        terms = robot.terms(q, v, robot.new_data())
        cons = constraint_terms(con, terms, v)
        cmd = fast.command(t, q, v, terms, cons)
        assert fast._steady and not general._steady
        # the law takes the packs (one argument each for e_q, e_F, f_d and for q_d, …)
        assert fast._input.steady is not None and fast._input.desired.pack is not None
        assert general._input.steady is None
        u0, B, V, trace = cmd.u0.copy(), cmd.B, fast.V, fast.trace
        assert B is not None and trace is not None
        B = B.copy()
        other = general.command(t, q, v, terms, cons)
        np.testing.assert_array_equal(u0, other.u0)
        assert other.B is not None
        np.testing.assert_array_equal(B, other.B)
        assert V == general.V
        other_trace = general.trace
        assert other_trace is not None
        for name in ("e_q", "s", "s0", "s1", "e_F", "qdot_r", "qddot_r0", "qddot_r_f", "f_d"):
            np.testing.assert_array_equal(getattr(trace, name), getattr(other_trace, name))
        ref_cmd = ref.command(t, q, v, terms, cons)
        assert fast.phase == general.phase == ref.phase == CONTACT
        assert ref.trace is not None
        scale = _u0_scale(terms, ref.gains.Kd, ref.trace, ref_cmd.u0, 1.0)
        _close("controller.u0", u0, ref_cmd.u0, scale)
        assert ref_cmd.B is not None
        _close("controller.B", B, ref_cmd.B)
        _compare_trace(trace, ref.trace, terms.M)
        np.testing.assert_array_equal(fast.f_d, ref.f_d)
        f = rng.uniform(5, 15, 1)
        for c in (fast, general, ref):
            c.update(DT, f)
        np.testing.assert_array_equal(fast.clik.q, general.clik.q)
        _compare_clik(fast.clik, ref.clik)
    assert [e.kind for e in fast.events] == [e.kind for e in general.events] == ["contact"]


@pytest.mark.parametrize(
    "law", ["arimoto", "arimoto_adaptive", "osc_hybrid", "impedance", "raibert_craig"]
)
@pytest.mark.parametrize("arm", ["rtr", "ur5"])
def test_every_law_steady_path_equals_the_general_path(
    arms: dict[str, Robot], arm: str, law: str
) -> None:
    """Each law's steady contact step (``Law.hybrid_at`` on the supervisor's, the CLIK's and
    its own packs) gives the commands, V and, after each update, the law's logged states of
    the general path (``hybrid`` on the separate arrays) bit for bit, over a run of states."""
    robot, surface, path, q0, qs = _controller_case(arms, arm)
    con = Constraint(surface)
    settings = ControlSettings(supervisor=False, law=law)
    fast = HybridController(robot, con, path, q0, settings, dt=DT)
    general = HybridController(robot, con, path, q0, settings, dt=DT)
    general._steady_contact = False
    rng = np.random.default_rng(112)
    m = len(fast.law.log_names())
    for i, q in enumerate(qs):
        t = i * DT
        v = rng.uniform(-0.3, 0.3, robot.nv)
        terms = robot.terms(q, v, robot.new_data())
        cons = constraint_terms(con, terms, v)
        cmd = fast.command(t, q, v, terms, cons)
        u0, B, V = cmd.u0.copy(), None if cmd.B is None else cmd.B.copy(), fast.V
        other = general.command(t, q, v, terms, cons)
        if i > 0:  # the first call sets the steady path up
            assert fast._input.steady is not None
        np.testing.assert_array_equal(u0, other.u0)
        if B is None:
            assert other.B is None
        else:
            assert other.B is not None
            np.testing.assert_array_equal(B, other.B)
        assert V == general.V or (math.isnan(V) and math.isnan(general.V))
        f = rng.uniform(5, 15, 1)
        fast.update(DT, f)
        general.update(DT, f)
        (a, ia), (b, ib) = fast.law.log_source(), general.law.log_source()
        assert ia.shape == ib.shape == (m,)
        np.testing.assert_array_equal(a[ia], b[ib])
        np.testing.assert_array_equal(fast.clik.q, general.clik.q)


# --- 11. constrained dynamics with its factorisation, Baumgarte γ, the run's table -------------
@pytest.mark.parametrize("k", [1, 2, 3])
@pytest.mark.parametrize("arm", ["ur5", "panda"])
def test_constrained_dynamics_solver_equals_dense_kkt(
    arms: dict[str, Robot], arm: str, k: int
) -> None:
    """ConstrainedDynamics.solve (one forwardDynamics + loop_resolve with U D Uᵀ) against a
    dense solve of the coupled KKT system, for arbitrary B (not a law's β M A⁺), B = None,
    and two calls in a row (the second overwrites the first's outputs)."""
    from hybrid_force.sim.dynamics import ConstrainedDynamics

    robot = arms[arm]
    rng = np.random.default_rng(31 + k)
    data = robot.new_data()
    solver = ConstrainedDynamics(robot.model, data, k)
    for trial in range(3):
        q, v = _random_state(robot, rng)
        terms = robot.terms(q, v, data)  # runs crba on data, as the loop does
        n = robot.nv
        A = rng.standard_normal((k, n))
        gamma = rng.standard_normal(k)
        u0 = 10.0 * rng.standard_normal(n)
        B = None if trial == 0 else 0.1 * rng.standard_normal((n, k))
        ddq, f = solver.solve(terms.nle, u0, B, A, gamma)
        ddq_ref, f_ref = kkt(terms.M, terms.nle, u0, B, A, gamma)
        scale = float(np.abs(ddq_ref).max() + np.abs(terms.nle).max())
        assert np.abs(ddq - ddq_ref).max() <= 1e-9 * scale
        assert np.abs(f - f_ref).max() <= 1e-9 * float(np.abs(f_ref).max() + 1.0)
        # and the defining equations: A q̈ + γ = 0, M q̈ + nle = u0 + B f + Aᵀ f
        assert np.abs(A @ ddq + gamma).max() <= 1e-9 * scale
        tau = u0 + (0.0 if B is None else B @ f) + A.T @ f
        assert np.abs(terms.M @ ddq + terms.nle - tau).max() <= 1e-9 * float(
            np.abs(tau).max() + np.abs(terms.nle).max()
        )


@pytest.mark.parametrize("k", [1, 2])
@pytest.mark.parametrize("arm", ["ur5", "panda"])
def test_checked_solve_equals_dense_kkt_and_the_limit_test(
    arms: dict[str, Robot], arm: str, k: int
) -> None:
    """ConstrainedDynamics.solve_checked (γ formed in its first kernel, the effort limits
    checked in its second, both reading the solver's buffer and the constraint's flat array)
    against the dense KKT solve with γ by hand (section 6.2) and the limits by numpy:
    |u0 + B f| > e, for B = None and B (n, k), limits none, loose and tight, with the terms'
    own flat array and without one (stacked rows: copied into the solver's); and bit for bit
    the path of solve + gamma_into it replaces in the plant."""
    import dataclasses

    from hybrid_force.control.constraint import ConstraintTerms
    from hybrid_force.sim.dynamics import Baumgarte, ConstrainedDynamics

    robot = arms[arm]
    rng = np.random.default_rng(57 + k)
    data = robot.new_data()
    other = ConstrainedDynamics(robot.model, robot.new_data(), k)
    baum = Baumgarte(alpha=37.0, beta=12.5)
    n = robot.nv
    for trial in range(6):
        q, v = _random_state(robot, rng)
        terms = robot.terms(q, v, data)
        robot.terms(q, v, other.data)
        cons = ConstraintTerms.zeros(k, n)
        A = cons.A
        A[...] = rng.standard_normal((k, n))
        drift, rate, value = cons.drift, cons.rate, cons.phi
        drift[...], rate[...], value[...] = rng.standard_normal((3, k))
        scale = cons.scale
        scale[...] = rng.uniform(0.5, 2.0, k)
        if trial % 3 == 2:  # fields only, as the stacked rows' terms
            cons = dataclasses.replace(cons, _packs=None, _flat=None)
        u0 = 10.0 * rng.standard_normal(n)
        B = None if trial % 2 == 0 else 0.1 * rng.standard_normal((n, k))
        _, f_free = kkt(terms.M, terms.nle, u0, B, A, drift + 74.0 * rate + 156.25 * value / scale)
        u_free = u0 + (0.0 if B is None else B @ f_free)
        effort = [np.zeros(0), np.abs(u_free) + 1.0, np.abs(u_free) * rng.uniform(0.5, 1.5, n)]
        for e in effort:
            solver = ConstrainedDynamics(robot.model, data, k, baum, e if e.size else None)
            beyond = solver.solve_checked(terms.nle, u0, np.zeros((n, 0)) if B is None else B, cons)
            gamma = solver.gamma
            ref_gamma = drift + 2 * 37.0 * rate + 12.5**2 * (value / scale)
            assert np.abs(gamma - ref_gamma).max() <= 1e-14 * float(np.abs(ref_gamma).max() + 1)
            ddq_ref, f_ref = kkt(terms.M, terms.nle, u0, B, A, ref_gamma)
            scale_q = float(np.abs(ddq_ref).max() + np.abs(terms.nle).max())
            assert np.abs(solver.ddq - ddq_ref).max() <= 1e-9 * scale_q
            assert np.abs(solver.f - f_ref).max() <= 1e-9 * float(np.abs(f_ref).max() + 1.0)
            u = u0 + (0.0 if B is None else B @ solver.f)
            assert beyond == bool(e.size and np.any(np.abs(u) > e))
            # the same numbers as the readable path: gamma_into, then solve
            g2 = baum.gamma_into(drift, rate, value, scale, np.zeros(k))
            np.testing.assert_array_equal(gamma, g2)
            ddq2, f2 = other.solve(terms.nle, u0, B, A, g2)
            np.testing.assert_array_equal(solver.ddq, ddq2)
            np.testing.assert_array_equal(solver.f, f2)


def test_baumgarte_gamma_into_equals_gamma() -> None:
    from hybrid_force.sim.dynamics import Baumgarte

    rng = np.random.default_rng(5)
    baum = Baumgarte(alpha=37.0, beta=12.5)
    for k in (1, 2, 3):
        drift, rate, value = rng.standard_normal((3, k))
        scale = rng.uniform(0.5, 2.0, k)
        out = np.full(k, np.nan)
        got = baum.gamma_into(drift, rate, value, scale, out)
        assert got is out
        ref = drift + 2 * 37.0 * rate + 12.5**2 * (value / scale)  # section 6.2, by hand
        assert np.abs(out - ref).max() <= 1e-14 * float(np.abs(ref).max() + 1.0)


def test_log_row_holds_the_fields_and_the_applied_command() -> None:
    """record_row writes [t, q, v, q_d, u0 + B f, p, p_d, f, f_d, phi, V, phase] in the columns
    of Record.widths and reports NaN in q, |v_i| above max_velocity and |f| above max_force;
    the table, u_cmd, the law's log and the limits are read from the record's buffer (header
    [max_velocity, max_force, N, W, u_cmd's columns, the log's columns], then the table's
    rows, u_cmd's and the log's); the log's row is the law's values at its index."""
    from hybrid_force.sim._kernels import RECORD_HEADER, record_row
    from hybrid_force.sim.record import Record

    rng = np.random.default_rng(9)
    nq = nv = 4
    k = 2
    widths = Record.widths(nq, nv, k)
    W = Record.width(nq, nv, k)
    h = RECORD_HEADER
    assert h == 6

    def buffer(m: int, m_log: int = 0) -> tuple[np.ndarray, ...]:  # buf, table, u_cmd, log
        buf = np.zeros(h + 3 * (W + m + m_log))
        buf[:h] = (5.0, 100.0, 3, W, m, m_log)
        o = h + 3 * W
        table, u_cmd = buf[h:o].reshape(3, W), buf[o : o + 3 * m].reshape(3, m)
        return buf, table, u_cmd, buf[o + 3 * m :].reshape(3, m_log)

    buf, table, _, _ = buffer(0)
    starts = np.concatenate([[0], np.cumsum(widths)])

    def field(row: int, index: int, table: np.ndarray = table) -> np.ndarray:  # field ``index``
        return table[row, starts[index] : starts[index + 1]]

    none, no_index = np.zeros(0), np.zeros(0, dtype=np.int64)

    def record(i: int, t: float, *args: object) -> bool:
        return bool(record_row(buf, i, t, *args, none, none, no_index))

    q, v, q_d, u0 = rng.standard_normal((4, nq))
    B = rng.standard_normal((nv, k))
    f, f_d, phi = rng.standard_normal((3, k))
    p, p_d = rng.standard_normal((2, 3))
    assert record(1, 0.25, q, v, q_d, u0, B, f, p, p_d, f_d, phi, 3.5, 2)
    expected = np.concatenate([[0.25], q, v, q_d, u0 + B @ f, p, p_d, f, f_d, phi, [3.5, 2.0]])
    assert np.abs(table[1] - expected).max() <= 1e-15 * float(np.abs(expected).max())
    assert np.array_equal(field(1, 1), q) and np.array_equal(field(1, 9), phi)
    assert field(1, 10)[0] == 3.5 and field(1, 11)[0] == 2 and field(1, 0)[0] == 0.25
    assert not np.any(table[0]) and not np.any(table[2])  # other rows untouched
    bad_q = q.copy()
    bad_q[2] = np.nan
    assert not record(0, 0.0, bad_q, v, q_d, u0, B, f, p, p_d, f_d, phi, 0.0, 0)
    fast_v = v.copy()
    fast_v[1] = -5.5
    assert not record(0, 0.0, q, fast_v, q_d, u0, B, f, p, p_d, f_d, phi, 0.0, 0)
    assert not record(0, 0.0, q, v, q_d, u0, B, np.array([0.0, 101.0]), p, p_d, f_d, phi, 0, 0)
    # effort limits: the applied torque in the u column, the command u0 + B f in u_cmd's row;
    # a law logging 3 of its 7 values: values[index] in the log's row
    applied = rng.standard_normal(nv)
    values, index = rng.standard_normal(7), np.array([6, 0, 3])
    buf2, table2, u_cmd, log = buffer(nv, index.size)
    args = (q, v, q_d, u0, B, f, p, p_d, f_d, phi, 3.5, 2, applied, values, index)
    assert record_row(buf2, 2, 0.5, *args)
    assert np.array_equal(field(2, 4, table2), applied)
    assert np.abs(u_cmd[2] - (u0 + B @ f)).max() <= 1e-15 * float(np.abs(u0 + B @ f).max())
    assert not np.any(u_cmd[[0, 1]])
    assert np.array_equal(log[2], values[index]) and not np.any(log[[0, 1]])


def test_carver_gives_consecutive_views_and_checks_the_layout() -> None:
    """A law's buffer carved into views (base.Carver): each view is the next slice, shares
    the buffer's memory, and done() refuses a layout that does not fill the buffer."""
    from hybrid_force.control.laws.base import Carver

    buffer = np.arange(10.0)
    carver = Carver(buffer, 1)
    a, b = carver.take(2, 3), carver.take(3)
    np.testing.assert_array_equal(a, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(b, [7, 8, 9])
    a[1, 2] = -1.0
    assert buffer[6] == -1.0
    carver.done()
    with pytest.raises(AssertionError, match="views end at 4 of 10"):
        short = Carver(buffer, 1)
        short.take(3)
        short.done()

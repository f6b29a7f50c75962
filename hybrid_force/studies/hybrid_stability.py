"""Where Raibert and Craig's original hybrid law goes unstable, and why (a study's tools).

The run (:func:`steep_plane_scenario`): the RTR arm starts folded (q₃ = 2π/3, tip 0.4 m from
its column), where the law's gains are set (K_P = ω_p ω_d M(q₀) …), at the foot of a plane
rising outwards at 60° (a bowl's wall: normal n̂ = (−cos 30°, 0, sin 30°), towards the column
and up), and slides 2.8 m up along it to 1.8 m from the column (q₃ ≈ 0.45), pressing 10 N on
a compliant surface.

The analysis. On a stiff contact the fastest mode of the closed loop is the tool vibrating on
the contact spring: the joints move along φ = M⁻¹Aᵀ (A = n̂ᵀJ, the way a normal push
accelerates them). To first order in 1/(contact stiffness) the mode's growth rate is the power
the controller's velocity terms put into it, over twice its kinetic energy, plus the integral
force term, whose lag acts as a negative damper of k_i/(1 + k_p) × the modal mass:

    σ = −φᵀ D φ / (2 φᵀ M φ) + k_i / (2 (1 + k_p))                                     (1)

with D the controller's joint damping: K_D J⁺ S J (original) or Jᵀ S D_x S J (corrected), plus
the normal damper Jᵀ n̂ D_n n̂ᵀ J of both (:mod:`hybrid_force.control.laws.raibert_craig`), whose
share of (1) is −(ω_p + ω_d)/2 everywhere. σ does not depend on the contact stiffness: the
instability survives a stiffer surface. The corrected form's Jᵀ S D_x S J is symmetric positive
semi-definite, so its position damper can only take energy out; the original's K_D J⁺ S J is
not symmetric, and where the vibration's tip velocity J φ = Λ⁻¹n̂ has a tangential part (n̂ not
an eigenvector of the Cartesian inertia Λ) its answer can push the vibration along:
φᵀ K_D J⁺ S J φ < 0. At q₀ it vanishes (φᵀ M J⁻¹ S J φ = n̂ᵀ S Λ⁻¹ n̂ = 0); the farther the
arm works from q₀, the larger it can be. With the law's projection P (``decouple``) the
feedback becomes P D, and φᵀ P = 0: it drops out of (1), σ = −(ω_p + ω_d)/2 + λ_f/2 for both.

:func:`contact_mode_growth` evaluates (1) from the gains; :func:`closed_loop_matrix` is the
independent check: the Jacobian, by central differences, of the whole closed loop (plant with a
linear compliant contact, the law as the simulator runs it, the supervisor's integral).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.base import LawInput
from hybrid_force.control.laws.raibert_craig import (
    RaibertCraigGains,
    pseudo_inverse,
    selection_matrix,
)
from hybrid_force.control.supervisor import ControlSettings, HybridController
from hybrid_force.geometry.builtin_surfaces import Plane
from hybrid_force.geometry.paths import FunctionPath
from hybrid_force.model.loading import load_robot
from hybrid_force.model.robot import Robot
from hybrid_force.sim.contact import ContactSettings
from hybrid_force.sim.settings import Scenario, SimSettings

__all__ = [
    "FOLDED",
    "STEEP_NORMAL",
    "closed_loop_matrix",
    "contact_mode_growth",
    "steep_plane_scenario",
]

FOLDED = np.array([0.0, 5.0, 2.0 * math.pi / 3.0])
"""RTR start configuration [rad, m, rad]: link 3 folded back, tip 0.4 m from the column."""

_ELEVATION = math.radians(30.0)
STEEP_NORMAL = np.array([-math.cos(_ELEVATION), 0.0, math.sin(_ELEVATION)])
"""Unit normal of the steep plane (its free side: towards the column and up)."""
_UP_THE_SLOPE = np.array([math.sin(_ELEVATION), 0.0, math.cos(_ELEVATION)])


def _smooth_step(t: float, length: float, duration: float) -> tuple[float, float, float]:
    """s, ṡ, s̈ of a quintic rest-to-rest move of ``length`` [m] over ``duration`` [s]."""
    x = min(max(t / duration, 0.0), 1.0)
    if x >= 1.0:
        return length, 0.0, 0.0
    s = length * x**3 * (10.0 - 15.0 * x + 6.0 * x**2)
    s_dot = length * 30.0 * x**2 * (1.0 - x) ** 2 / duration
    s_ddot = length * 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / duration**2
    return s, s_dot, s_ddot


def steep_plane_scenario(
    options: Mapping[str, object],
    *,
    stiffness: float = 1e6,
    travel: float = 2.8,
    move_time: float = 4.0,
    duration: float = 6.0,
    robot: Robot | None = None,
) -> Scenario:
    """The RTR sliding up the steep plane from :data:`FOLDED` (module docstring).

    Args:
        options: the raibert_craig law's table, e.g. {"form": "original", "decouple": False}.
        stiffness: the compliant contact's k [N/m] (linear, undamped).
        travel: distance along the plane [m] (2.8 m: from 0.4 m to 1.8 m from the column).
        move_time: duration of the quintic move [s]; the tip then holds its last point.
        duration: simulated time [s].
        robot: the RTR (loaded when None).
    """
    arm = load_robot("rtr") if robot is None else robot
    start = arm.tip_position(FOLDED)

    def position(t: float) -> np.ndarray:
        return start + _UP_THE_SLOPE * _smooth_step(t, travel, move_time)[0]

    def velocity(t: float) -> np.ndarray:
        return _UP_THE_SLOPE * _smooth_step(t, travel, move_time)[1]

    def acceleration(t: float) -> np.ndarray:
        return _UP_THE_SLOPE * _smooth_step(t, travel, move_time)[2]

    return Scenario(
        robot=arm,
        surfaces=(Plane(start, STEEP_NORMAL),),
        path=FunctionPath(position, velocity, acceleration),
        q0=FOLDED,
        control=ControlSettings(
            law="raibert_craig", options={"raibert_craig": dict(options)}, supervisor=False
        ),
        sim=SimSettings(duration=duration, settle_time=min(5.0, duration)),
        contact=ContactSettings(model="compliant", stiffness=stiffness),
        name="steep_plane",
        description="RTR sliding up a steep compliant plane, away from its start (study)",
    )


def contact_mode_growth(
    gains: RaibertCraigGains, M: np.ndarray, J: np.ndarray, normal: np.ndarray
) -> float:
    """Eq. 1: the growth rate [1/s] of the contact vibration on a stiff surface (> 0: unstable).

    Args:
        gains: the law's gains (set at q₀). M: (n, n) mass matrix at the working point [kg …].
        J: (3, n) tip Jacobian there. normal: (3,) the surface's unit normal.
    """
    S = selection_matrix(normal[:, None])
    if gains.form == "original":
        D = gains.Dq @ pseudo_inverse(J) @ S @ J
    else:
        D = J.T @ S @ gains.Dx @ S @ J
    a = J.T @ normal
    phi = np.linalg.solve(M, a)
    if gains.decouple:  # the law projects its feedback with P = I − a (aᵀM⁻¹a)⁻¹ φᵀ
        D = D - np.outer(a, phi @ D) / float(a @ phi)
    Dn = (gains.position_rate + gains.damping_rate) / float(a @ phi)
    D = D + Dn * np.outer(a, a)
    return -float(phi @ D @ phi) / (2.0 * float(phi @ M @ phi)) + gains.force_rate / 2.0


def closed_loop_matrix(
    robot: Robot,
    q_work: np.ndarray,
    q0: np.ndarray,
    normal: np.ndarray,
    options: Mapping[str, object],
    stiffness: float,
    f_d: float = 10.0,
    h: float = 1e-7,
    plant: Robot | None = None,
) -> tuple[np.ndarray, HybridController]:
    """The closed loop's Jacobian (2n + 1, 2n + 1) at rest at q_work, by central differences.

    The state is (q, q̇, e_F); the plant is M q̈ + C q̇ + g = u + Aᵀ f with the linear compliant
    force f = k·max(−d, 0); the law (gains set at q0) holds the tip point p(q_work) on a plane
    of the given normal placed so that f = f_d there, and u = u0 + B f as the simulator
    resolves it; ė_F = f − f_d.

    Args:
        q_work: (n,) the working configuration. q0: (n,) where the gains are set.
        normal: (3,) unit normal. options: the raibert_craig table ({"form": "original"} …).
        stiffness: k [N/m].
        f_d: desired force [N]. h: difference step.
        plant: the arm the law acts on (default: ``robot``, the law's own model).

    Returns:
        The matrix and the controller (its ``law`` has the gains).
    """
    tip = robot.tip_position(q_work)
    plane = Plane(tip + normal * f_d / stiffness, normal)
    zero = np.zeros(3)
    path = FunctionPath(lambda t: tip, lambda t: zero, lambda t: zero)
    settings = ControlSettings(
        law="raibert_craig",
        options={"raibert_craig": dict(options)},
        supervisor=False,
        f_d=f_d,
    )
    controller = HybridController(robot, Constraint(plane), path, q0, settings)
    n = robot.nv
    desired = controller.desired
    arm = robot if plant is None else plant

    def field(x: np.ndarray) -> np.ndarray:
        q, v, e_F = x[:n], x[n : 2 * n], x[2 * n :]
        terms = robot.terms(q, v)
        cons = controller.constraint.evaluate(terms, v)
        f = stiffness * np.maximum(-cons.distance, 0.0)
        cmd = controller.law.hybrid(
            LawInput(terms, v, q - desired.q, desired, cons, e_F, controller.f_d_contact)
        )
        u = cmd.u0 if cmd.B is None else cmd.u0 + cmd.B @ f
        real = terms if plant is None else arm.terms(q, v)
        qdd = np.linalg.solve(real.M, u - real.nle + cons.A.T @ f)
        return np.concatenate([v, qdd, f - controller.f_d_contact])

    x0 = np.concatenate([q_work, np.zeros(n), np.zeros(1)])
    jacobian = np.empty((2 * n + 1, 2 * n + 1))
    for i in range(2 * n + 1):
        dx = np.zeros(2 * n + 1)
        dx[i] = h
        jacobian[:, i] = (field(x0 + dx) - field(x0 - dx)) / (2.0 * h)
    return jacobian, controller

"""A surface and a path of your own, defined in Python: an elliptic cylinder and a helix on it.

A scenario file takes the built-in surfaces and paths (docs/scenarios.md); from Python any
surface Φ(p) = 0 and any path p_d(t) can be used. Here the RTR arm follows an elliptic helix

    p_d(t) = (a cos ωt, b sin ωt, z0 + r t)

on the elliptic cylinder Φ(p) = (x/a)² + (y/b)² − 1 = 0 (the tool outside, where Φ > 0),
pressing with f_d = 10 N. ``FunctionSurface`` takes Φ and, optionally, its gradient and
Hessian (missing ones are finite differences) and a metric distance (missing: Φ/‖∇Φ‖, first
order); ``FunctionPath`` takes p_d(t) and, optionally, its velocity and acceleration.
``check_on_surface`` confirms the path lies on the surface before the run.

Run from anywhere:

    python examples/user_surface_and_path.py
"""

from __future__ import annotations

import numpy as np

from hybrid_force import (
    ControlSettings,
    FunctionPath,
    FunctionSurface,
    Scenario,
    SimSettings,
    check_on_surface,
    inverse_kinematics,
    load_robot,
    simulate,
)

A, B = 0.5, 0.35  # semi-axes of the ellipse [m]
OMEGA, Z0, RISE = 0.8, 10.0, 0.1  # [rad/s], [m], [m/s]


def phi(p: np.ndarray) -> float:
    return float((p[0] / A) ** 2 + (p[1] / B) ** 2 - 1.0)


def gradient(p: np.ndarray) -> np.ndarray:
    return np.array([2.0 * p[0] / A**2, 2.0 * p[1] / B**2, 0.0])


def hessian(p: np.ndarray) -> np.ndarray:
    return np.diag([2.0 / A**2, 2.0 / B**2, 0.0])


def position(t: float) -> np.ndarray:
    return np.array([A * np.cos(OMEGA * t), B * np.sin(OMEGA * t), Z0 + RISE * t])


def velocity(t: float) -> np.ndarray:
    return np.array([-A * OMEGA * np.sin(OMEGA * t), B * OMEGA * np.cos(OMEGA * t), RISE])


def acceleration(t: float) -> np.ndarray:
    return np.array([-A * OMEGA**2 * np.cos(OMEGA * t), -B * OMEGA**2 * np.sin(OMEGA * t), 0.0])


def main(duration: float = 3.0) -> None:
    surface = FunctionSurface(phi, gradient, hessian)
    path = FunctionPath(position, velocity, acceleration)
    on_surface = check_on_surface(path, surface, 0.0, duration)
    print(f"path on the surface: worst |d| = {on_surface.worst_distance:.3g} m")

    robot = load_robot("rtr")
    q0 = inverse_kinematics(robot, position(0.0), seed=np.array([0.0, Z0 - 1.0, 2.0]))
    scenario = Scenario(
        robot=robot,
        surfaces=[surface],
        path=path,
        q0=q0,
        control=ControlSettings(supervisor=False, f_d=10.0),  # starts and stays in contact
        sim=SimSettings(duration=duration),
        name="elliptic_helix",
    )
    result = simulate(scenario)
    metrics = result.metrics(settle_time=duration / 2)
    print(f"{scenario.name}: {result.n_samples} samples, status {result.status}")
    print(f"largest distance |d| to the surface: {np.abs(result.phi).max():.3g} m")
    print(f"final force error |f - f_d|: {metrics.final_force_error:.3g} N")
    print(f"final position error ||p - p_d||: {metrics.final_position_error:.3g} m")


if __name__ == "__main__":
    main()

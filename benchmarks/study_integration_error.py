"""Study: the steady tracking error of a sampled loop on a path with joint accelerations.

The RTR arm presses on the plane z = 5 m while following a circle of radius 0.3 m centred at
(0.5, 0.3, 5) m, off its base axis, at 0.5 rad/s (the joint accelerations never vanish), for
5 s from a start on the path, as ``tests/test_simulate.py::
test_off_axis_circle_error_is_first_order_in_dt`` does. It prints the final position error
‖p − p_d‖ for semi-implicit Euler and RK4 at dt = 1 ms and 0.5 ms: the numbers quoted in the
README ("Where the paper is unclear or departs from physics", integration error).

Run from the repository root:

    python benchmarks/study_integration_error.py
"""

from __future__ import annotations

import numpy as np

from hybrid_force import (
    Circle,
    ControlSettings,
    Plane,
    Scenario,
    SimSettings,
    inverse_kinematics,
    load_robot,
    simulate,
)


def final_error(integrator: str, dt: float) -> float:
    """‖p − p_d‖ [m] at the end of the 5 s run."""
    rtr = load_robot("rtr")
    circle = Circle(center=(0.5, 0.3, 5.0), radius=0.3, normal=(0, 0, 1), omega=0.5)
    q0 = inverse_kinematics(rtr, circle.position(0.0), seed=np.array([0.3, 5.0, 1.0]))
    scenario = Scenario(
        robot=rtr,
        surfaces=[Plane(point=(0, 0, 5.0), normal=(0, 0, 1))],
        path=circle,
        q0=q0,
        control=ControlSettings(supervisor=False),
        sim=SimSettings(duration=5.0, dt=dt, integrator=integrator),  # type: ignore[arg-type]
        name="off_axis_circle",
    )
    result = simulate(scenario)
    return float(np.linalg.norm(result.p[-1] - result.p_d[-1]))


def main() -> None:
    print("| integrator | dt = 1 ms | dt = 0.5 ms | ratio |")
    print("|---|---|---|---|")
    for integrator in ("euler", "rk4"):
        e1, e2 = final_error(integrator, 1e-3), final_error(integrator, 5e-4)
        print(f"| {integrator} | {e1:.2g} m | {e2:.2g} m | {e1 / e2:.2f} |")


if __name__ == "__main__":
    main()

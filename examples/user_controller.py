"""Your own controller in the loop: press on the surface and hold the start configuration.

A controller is any object with ``command(t, q, v, f) -> u``. It receives only what the
sensors measure (``[sensor]`` and ``control.rate`` of the scenario) and computes everything
else from its own model. This one, for the paper's section 6.3 setup (the RTR arm on the
cylinder), is a joint-space PD around the start configuration with gravity compensation and
a constant push f_push along the surface's inward normal:

    u = g(q̃) + K_p (q0 − q̃) − K_v ṽ − (n̂ᵀ J(q̃))ᵀ f_push

At rest on the surface at q0 the plant's balance u − g + (n̂ᵀJ)ᵀ f = 0 gives a contact force
f = f_push exactly (a frictionless surface takes any normal force).

Run from the repository root:

    python examples/user_controller.py
"""

from __future__ import annotations

import numpy as np

from hybrid_force import load_robot, simulate
from hybrid_force.geometry.builtin_surfaces import Cylinder
from hybrid_force.scenario.loader import load_scenario


class PressAndHold:
    """Hold q0 and push with f_push [N] on a surface, from the controller's own model."""

    def __init__(self, q0: np.ndarray, surface: Cylinder, f_push: float = 10.0) -> None:
        self.robot = load_robot("rtr")  # the controller's own model of the arm
        self.surface = surface
        self.q0 = np.array(q0, dtype=float)
        self.f_push = f_push
        M0 = self.robot.mass_matrix(self.q0)
        self.Kp, self.Kv = 400.0 * M0, 40.0 * M0  # 20 rad/s, critically damped

    def command(self, t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray) -> np.ndarray:
        p = self.robot.tip_position(q)
        n = self.surface.normal(p)  # unit normal to the free side
        push = self.robot.jacobian(q).T @ n * self.f_push
        return self.robot.gravity(q) + self.Kp @ (self.q0 - q) - self.Kv @ v - push


def main() -> None:
    scenario = load_scenario("scenarios/paper_contact.toml", {"sim.duration": 2.0})
    controller = PressAndHold(scenario.q0, scenario.surfaces[0], f_push=10.0)
    result = simulate(scenario, controller=controller)
    print(f"true contact force at the end: {result.f[-1]:.9f} N (pushed with 10 N)")
    print(f"largest joint error at the end: {np.abs(result.q[-1] - scenario.q0).max():.3g}")


if __name__ == "__main__":
    main()

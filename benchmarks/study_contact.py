"""Study: the paper's law on a surface that rubs and yields (docs/contact.md).

1. Friction: scenarios/paper_contact.toml (section 6.3, 20 s) with Coulomb friction
   μ ∈ {0, 0.1, 0.3, 0.5} on the rigid cylinder: the settled position error (t ≥ 5 s), its
   hand prediction (docs/contact.md: the law has no integral action, so friction leaves a
   steady lag e = J P_K τ_f / Λ), the force error and the energy friction dissipated.
2. Stiffness: the same run and the section 6.4 approach (scenarios/paper_approach.toml) on a
   compliant cylinder, k ∈ {1e4, 1e5, 1e6, 1e7} N/m (Hunt–Crossley, n = 1, c = 0, then
   c = 1 s/m for the approach), against the rigid runs: settled force error, penetration,
   position error, and the approach's peak force after the first touch.

Writes docs/figures/contact_friction.png and docs/figures/contact_stiffness.png and prints the
tables in Markdown. Run from the repository root (about 2 minutes):

    python benchmarks/study_contact.py
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from hybrid_force import Result, simulate
from hybrid_force.control.constraint import Constraint
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.contact import ContactSettings

FIGURES = Path("docs/figures")
SETTLE = 5.0
STIFFNESS = ((1e4, 1e-3), (1e5, 1e-3), (1e6, 1e-3), (1e7, 1e-4))  # (k [N/m], dt [s])


def run(name: str, contact: ContactSettings, dt: float = 1e-3) -> Result:
    sc = load_scenario(f"scenarios/{name}.toml", {"sim.dt": dt})
    return simulate(dataclasses.replace(sc, contact=contact))


def predicted_lag(name: str, result: Result, mu: float) -> float:
    """‖J P_K τ_f‖ / Λ at the last sample: the steady lag friction leaves (docs/contact.md)."""
    sc = load_scenario(f"scenarios/{name}.toml")
    robot, control = sc.robot, sc.control
    q, v = result.q[-1], result.v[-1]
    terms = robot.terms(q, v, robot.new_data())
    A = Constraint(sc.surfaces).evaluate(terms, v).A
    M0 = robot.terms(sc.q0, np.zeros(robot.nv), robot.new_data()).M
    Kd_inv = np.linalg.inv(control.kd_rate * M0)  # the default K_d = κ M(q0)
    P_K = Kd_inv - Kd_inv @ A.T @ np.linalg.solve(A @ Kd_inv @ A.T, A @ Kd_inv)
    n = sc.surfaces[0].normal(terms.p)
    v_t = terms.pdot - n * (n @ terms.pdot)
    tau_f = -mu * control.f_d * terms.J.T @ (v_t / np.linalg.norm(v_t))
    return float(np.linalg.norm(terms.J @ P_K @ tau_f) / control.Lambda)


def settled(result: Result) -> np.ndarray:
    return result.t >= SETTLE


def friction_study() -> None:
    print("| μ | RMS ‖p − p_d‖, t ≥ 5 s [m] | predicted lag [m] | max \\|f − f_d\\| [N] "
          "| friction loss [J] |")  # fmt: skip
    print("|---|---|---|---|---|")
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for mu in (0.0, 0.1, 0.3, 0.5):
        r = run("paper_contact", ContactSettings(friction=mu))
        late = settled(r)
        e = np.linalg.norm(r.p - r.p_d, axis=1)
        lag = predicted_lag("paper_contact", r, mu) if mu else 0.0
        f_err = np.abs(r.f - 10.0)[late].max()
        print(
            f"| {mu:g} | {np.sqrt(np.mean(e[late] ** 2)):.3e} | {lag:.3e} | {f_err:.1e} "
            f"| {r.meta['friction_energy']:.2f} |"
        )
        ax.semilogy(r.t[1:], e[1:], label=f"μ = {mu:g}")
    ax.set(xlabel="t [s]", ylabel="‖p − p_d‖ [m]", title="Section 6.3 with Coulomb friction")
    ax.legend()
    fig.tight_layout()
    fig.savefig(FIGURES / "contact_friction.png", dpi=120)
    plt.close(fig)


def stiffness_study() -> None:
    rigid = run("paper_contact", ContactSettings())
    rigid_e = np.linalg.norm(rigid.p - rigid.p_d, axis=1)[settled(rigid)].max()
    print()
    print("| k [N/m] | dt [s] | max \\|f − f_d\\|, t ≥ 5 s [N] | penetration [m] "
          "| max ‖p − p_d‖, t ≥ 5 s [m] | touch speed [mm/s] "
          "| approach: peak f [N], c = 0 | c = 1 s/m |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    approach_rigid = run("paper_approach", ContactSettings())
    impulse = approach_rigid.metrics().impact_impulse
    print(
        f"| rigid | 1e-3 | {np.abs(rigid.f - 10)[settled(rigid)].max():.1e} | 0 | {rigid_e:.1e} "
        f"| {approach_rigid.metrics().impact_speed * 1e3:.2f} | impulse {impulse:.3g} N·s | |"
    )
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.5))
    for k, dt in STIFFNESS:
        r = run("paper_contact", ContactSettings(model="compliant", stiffness=k), dt)
        late = settled(r)
        penetration = -float(np.min(r.phi[late]))  # phi: the metric distance [m]
        e = np.linalg.norm(r.p - r.p_d, axis=1)[late].max()
        peaks, speed = [], 0.0
        for c in (0.0, 1.0):
            a = run(
                "paper_approach", ContactSettings(model="compliant", stiffness=k, damping=c), dt
            )
            peaks.append(float(np.max(a.f)))
            if c == 0.0:
                first = next(ev for ev in a.events if ev["kind"] == "touch")
                touch, speed = first["t"], first["speed"]
                window = (a.t >= touch - 0.02) & (a.t <= touch + 0.3)
                axes[1].plot(a.t[window] - touch, a.f[window], label=f"k = {k:.0e}")
        print(
            f"| {k:.0e} | {dt:g} | {np.abs(r.f - 10)[late].max():.1e} | {penetration:.3e} "
            f"| {e:.3e} | {speed * 1e3:.2f} | {peaks[0]:.1f} | {peaks[1]:.1f} |"
        )
        axes[0].semilogy(r.t[1:], np.abs(r.f[1:] - 10) + 1e-12, label=f"k = {k:.0e}")
    axes[0].set(xlabel="t [s]", ylabel="|f − f_d| [N]", title="Section 6.3, compliant cylinder")
    axes[1].set(xlabel="t − t_touch [s]", ylabel="f [N]", title="Section 6.4 approach, c = 0")
    for ax in axes:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(FIGURES / "contact_stiffness.png", dpi=120)
    plt.close(fig)


def main() -> None:
    FIGURES.mkdir(parents=True, exist_ok=True)
    friction_study()
    stiffness_study()


if __name__ == "__main__":
    main()

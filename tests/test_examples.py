"""Every script in examples/ runs and shows what its docstring says.

Each runs as a user would run it (a subprocess from the repository root); the checks are on
its printed numbers against what they must be independently of the code (the scenario file's
f_d, a robot's joint count, a mass matrix's symmetry and positive definiteness, an analytic path
on an analytic surface). tests/test_controller.py also imports examples/user_controller.py
to test its controller class.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "examples"


def run(script: str, *args: str) -> str:
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / script), *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def number(text: str, label: str) -> float:
    """The number printed after ``label`` (the first match)."""
    match = re.search(re.escape(label) + r"\s*([-+0-9.eE]+)", text)
    assert match is not None, f"{label!r} not in the output:\n{text}"
    return float(match.group(1))


def test_every_example_has_a_test() -> None:
    tested = {
        "inspect_robot.py",
        "run_and_plot.py",
        "user_surface_and_path.py",
        "user_controller.py",
    }
    assert {p.name for p in EXAMPLES.glob("*.py")} == tested


def test_inspect_robot_prints_joints_and_a_positive_definite_mass_matrix() -> None:
    out = run("inspect_robot.py")
    # the RTR arm: q1 (revolute), q2 (prismatic), q3 (revolute); the UR5: six revolute joints
    assert "rtr: 3 joints" in out and "ur5: 6 joints" in out
    for joint in ("q1", "q2", "q3", "shoulder_pan_joint", "wrist_3_joint"):
        assert re.search(rf"^\s+{joint}\s", out, re.MULTILINE), joint
    assert out.count("M symmetric: True") == 2
    smallest = re.findall(r"smallest eigenvalue of M\(q0\): ([-+0-9.eE]+)", out)
    assert len(smallest) == 2 and all(float(x) > 0 for x in smallest)


@pytest.mark.slow
def test_run_and_plot_converges_and_writes_the_figures(tmp_path: Path) -> None:
    out_dir = tmp_path / "out"
    out = run("run_and_plot.py", "--out", str(out_dir), "--duration", "3")
    scenario = tomllib.loads((REPO / "scenarios" / "paper_contact.toml").read_text())
    f_d = scenario["control"]["f_d"]
    assert number(out, "desired force f_d at the end:") == pytest.approx(f_d)
    # the hybrid law of section 6.3 on the exact model: force and position converge
    assert number(out, "final force error |f - f_d|:") < 1e-6 * f_d
    assert number(out, "final position error ||p - p_d||:") < 1e-6
    figures = sorted(out_dir.glob("*.png"))
    assert len(figures) == 6
    for figure in figures:
        assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", figure
    assert f"result: {out_dir / 'result.npz'}" in out
    with np.load(out_dir / "result.npz", allow_pickle=False) as saved:
        assert saved["t"][-1] == pytest.approx(3.0)


def test_user_surface_and_path_stays_on_the_surface_and_presses_with_f_d() -> None:
    out = run("user_surface_and_path.py")
    # p_d(t) = (a cos ωt, b sin ωt, ·) satisfies (x/a)² + (y/b)² = 1 exactly: rounding only
    assert number(out, "worst |d| =") < 1e-12
    assert "status ok" in out
    # the loop holds the tool on the surface (Baumgarte); the force converges to f_d = 10 N
    assert number(out, "largest distance |d| to the surface:") < 1e-9
    assert number(out, "final force error |f - f_d|:") < 1e-3


def test_user_controller_presses_with_the_force_it_asks() -> None:
    # at rest on a frictionless surface, u − g + (n̂ᵀJ)ᵀ f = 0 with u = g − (n̂ᵀJ)ᵀ f_push
    out = run("user_controller.py")
    assert number(out, "true contact force at the end:") == pytest.approx(10.0, abs=1e-6)

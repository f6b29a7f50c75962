"""hybrid_force.control.controller: the controller's own model, and controllers from Python."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

from hybrid_force import load_robot, simulate
from hybrid_force.control.controller import ControllerModel
from hybrid_force.errors import (
    BadInputError,
    ControlError,
    RunFailedError,
    RunWarning,
    ScenarioError,
)
from hybrid_force.model.robot import check_same_joints
from hybrid_force.scenario.loader import load_scenario

REPO = Path(__file__).resolve().parents[1]
CONTACT = REPO / "scenarios" / "paper_contact.toml"


def _rtr_variant(tmp_path: Path, name: str, mass_scale: float, link3_only: bool) -> Path:
    """The RTR URDF with link masses and inertias × mass_scale (all links, or link3 only)."""
    text = (REPO / "robots" / "rtr.urdf").read_text()

    def scale(match: re.Match[str]) -> str:
        return f'{match.group(1)}"{float(match.group(2)) * mass_scale!r}"'

    pattern = re.compile(r'((?:value|ixx|iyy|izz|ixy|ixz|iyz)=)"([-0-9.eE+]+)"')
    if link3_only:
        start = text.index('<link name="link3">')
        end = text.index("</link>", start)
        text = text[:start] + pattern.sub(scale, text[start:end]) + text[end:]
    else:
        text = pattern.sub(scale, text)
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_controller_computes_its_own_models_terms(tmp_path: Path) -> None:
    """A controller model with a heavier link 3 (22 kg): its M, C v + g are that model's,
    not the plant's (the plant's differ by the 2 kg)."""
    plant = load_robot("rtr")
    heavy = load_robot(_rtr_variant(tmp_path, "heavy.urdf", 1.1, link3_only=True))
    scenario = load_scenario(CONTACT)
    own = ControllerModel(heavy, scenario.surfaces, "tip")
    rng = np.random.default_rng(5)
    for _ in range(3):
        q, v = rng.uniform(-2, 2, 3) + np.array([0.0, 6.0, 0.0]), rng.normal(size=3)
        terms, _ = own.evaluate(q, v)
        np.testing.assert_allclose(terms.M, heavy.mass_matrix(q), atol=1e-12)
        np.testing.assert_allclose(
            terms.nle, heavy.coriolis(q, v) @ v + heavy.gravity(q), atol=1e-11
        )
        assert abs(heavy.gravity(q)[1] - plant.gravity(q)[1]) == pytest.approx(2.0 * 9.81)


def test_a_model_with_every_mass_scaled_runs_as_the_mass_factor(tmp_path: Path) -> None:
    """control.model = the RTR with all masses × 1.1 is the same controller as
    control.mass_factor = 1.1 on the plant's model: the runs agree to round-off."""
    scaled = _rtr_variant(tmp_path, "scaled.urdf", 1.1, link3_only=False)
    by_model = load_scenario(CONTACT, {"sim.duration": 2.0, "control.model": str(scaled)})
    by_factor = load_scenario(CONTACT, {"sim.duration": 2.0, "sim.model_mass_factor": 1.1})
    a, b = simulate(by_model), simulate(by_factor)
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.f, b.f, rtol=0, atol=1e-6)
    assert a.meta["controller"]["model"]["model"] == str(scaled.resolve())


def test_a_heavier_link_in_the_model_shows_as_an_offset(tmp_path: Path) -> None:
    """The controller's model over-estimates gravity along the cylinder axis: with no
    integral action the tip settles above the helix (e_z > 0), x and y still tracked."""
    heavy = _rtr_variant(tmp_path, "heavy.urdf", 1.1, link3_only=True)
    exact = simulate(load_scenario(CONTACT, {"sim.duration": 6.0}))
    off = simulate(load_scenario(CONTACT, {"sim.duration": 6.0, "control.model": str(heavy)}))
    e_exact, e_off = exact.p[-1] - exact.p_d[-1], off.p[-1] - off.p_d[-1]
    assert np.abs(e_exact).max() < 1e-10
    assert e_off[2] > 1e-4 and np.abs(e_off[:2]).max() < 1e-2 * e_off[2]
    assert abs(off.f[-1] - 10.0) < 1e-6  # the force is still regulated


def test_control_model_errors_name_the_key(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from hybrid_force.cli import main

    for value, words in (("none.urdf", "URDF file not found"), ("ur5", "must have the plant")):
        with pytest.raises(ScenarioError, match=rf"control\.model = \"{value}\": .*{words}"):
            load_scenario(CONTACT, {"control.model": value})
    out = tmp_path / "out"
    assert main(["run", str(CONTACT), "--set", "control.model=ur5", "--out", str(out)]) == 2
    assert "control.model" in capsys.readouterr().err and not out.exists()
    with pytest.raises(ControlError, match=r"control\.model"):
        check_same_joints(load_robot("rtr"), load_robot("ur5"))


# --- controllers from Python -------------------------------------------------------------------
def _example() -> type:
    spec = importlib.util.spec_from_file_location(
        "user_controller", REPO / "examples" / "user_controller.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.PressAndHold


def test_the_example_controller_presses_with_the_force_it_asks() -> None:
    """At rest on a frictionless surface, u − g + (n̂ᵀJ)ᵀ f = 0 with u = g − (n̂ᵀJ)ᵀ f_push:
    the contact force is f_push."""
    scenario = load_scenario(CONTACT, {"sim.duration": 2.0})
    controller = _example()(scenario.q0, scenario.surfaces[0], f_push=7.5)
    # it presses 7.5 N, not the scenario's f_d = 10 N the run's force error is measured from
    with pytest.warns(RunWarning, match="the force error did not settle"):
        result = simulate(scenario, controller=controller)
    assert result.status == "ok" and result.f[-1] == pytest.approx(7.5, abs=1e-6)
    assert np.all(np.isnan(result.q_d)) and np.all(np.isnan(result.V))
    assert result.meta["controller"]["law"] == "PressAndHold" and result.meta["gains"] is None
    np.testing.assert_allclose(result.p_d[-1], scenario.path.position(2.0))


class _Recorder:
    """Holds still with gravity compensation; records its calls and scribbles on its inputs."""

    def __init__(self, robot_name: str = "rtr") -> None:
        self.robot = load_robot(robot_name)
        self.times: list[float] = []

    def command(self, t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray) -> np.ndarray:
        self.times.append(t)
        u = self.robot.gravity(q) - 50.0 * v
        q[:] = 1e6  # the simulator hands copies: this must not reach the plant
        v[:] = 1e6
        return u


@pytest.mark.filterwarnings("ignore::hybrid_force.errors.RunWarning")  # it only holds still
def test_a_user_controller_runs_at_its_rate_on_copies() -> None:
    scenario = load_scenario(CONTACT, {"sim.duration": 0.2, "control.rate": 250})
    recorder = _Recorder()
    result = simulate(scenario, controller=recorder)
    assert recorder.times == pytest.approx([0.004 * i for i in range(len(recorder.times))])
    assert len(recorder.times) == 51  # ticks at 0, 4, ..., 200 ms of the 201 samples
    assert np.all(np.abs(result.q) < 100.0)
    changes = np.flatnonzero(np.any(np.diff(result.u, axis=0) != 0.0, axis=1)) + 1
    assert np.all(changes % 4 == 0)


def test_a_user_controller_returning_garbage_stops_the_run_with_its_samples() -> None:
    class Broken:
        def command(self, t: float, q: np.ndarray, v: np.ndarray, f: np.ndarray) -> np.ndarray:
            return np.zeros(2) if t > 0.05 else np.zeros(3)

    with pytest.raises(RunFailedError, match="must return 3 finite joint torques") as info:
        simulate(load_scenario(CONTACT, {"sim.duration": 0.2}), controller=Broken())
    # the first bad command (t = 0.051 s) is refused: the samples up to 0.050 s are kept
    assert info.value.result is not None and info.value.result.t[-1] == pytest.approx(0.05)
    with pytest.raises(BadInputError, match="command"):
        simulate(load_scenario(CONTACT, {"sim.duration": 0.2}), controller=object())  # type: ignore[arg-type]


def test_the_law_is_named_and_checked() -> None:
    assert load_scenario(CONTACT, {"control.law": "arimoto"}).control.law == "arimoto"
    with pytest.raises(ScenarioError, match=r"control\.law"):
        load_scenario(CONTACT, {"control.law": "pid"})
    scenario = load_scenario(CONTACT)
    with pytest.raises(ControlError, match=r"control\.law"):
        dataclasses.replace(scenario.control, law="pid")

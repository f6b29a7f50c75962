"""Scenario files: the shipped scenarios load, every broken file gives a precise error."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hybrid_force.errors import BadInputError, ScenarioError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.scenario.overrides import parse_override
from hybrid_force.sim.settings import Scenario

REPO_ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((REPO_ROOT / "scenarios").glob("*.toml"))

# A valid base file (paper section 6.3); broken variants are built by editing its text.
BASE = """\
name = "base"
description = "paper 6.3"

[robot]
model = "rtr"

[surface]
type = "cylinder"
radius = 0.4
center = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]

[trajectory]
type = "helix"
center = [0.0, 0.0, 10.0]
radius = 0.4
axis = [0.0, 0.0, 1.0]
omega = 1.0
rise = 0.1
phase = 0.0

[initial]
tip = [0.4, 0.0, 7.0]
seed = [0.0, 6.0, 2.0]

[control]
supervisor = false
f_d = 10.0

[sim]
duration = 2.0
"""


def _write(tmp_path: Path, text: str, name: str = "broken.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _error(path: Path, overrides: dict[str, object] | None = None) -> str:
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, overrides)
    return str(info.value)


# --- shipped scenarios --------------------------------------------------------------------------
def test_shipped_scenarios_exist() -> None:
    names = {p.stem for p in SHIPPED}
    assert {"paper_contact", "paper_approach", "rtr_sphere", "rtr_plane"} <= names
    assert any(n.startswith(("ur5_", "panda_")) for n in names)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_scenario_loads(path: Path) -> None:
    sc = load_scenario(path)
    assert isinstance(sc, Scenario)
    assert sc.name == path.stem  # the output folder runs/<name>/ matches the file name
    # the start is the configuration the file asks for: on the tip given, or q given
    raw = sc.source
    assert raw is not None
    if "tip" in raw["initial"]:
        np.testing.assert_allclose(sc.robot.tip_position(sc.q0), raw["initial"]["tip"], atol=1e-9)
    # the desired path lies on every surface at a few times (independent of check_on_surface)
    for t in np.linspace(0.0, sc.sim.duration, 7):
        p = sc.path.position(float(t))
        for s in sc.surfaces:
            assert abs(s.distance(p)) < 1e-9
    json.dumps(raw)  # JSON-able


def test_paper_contact_matches_section_6_3() -> None:
    sc = load_scenario(REPO_ROOT / "scenarios" / "paper_contact.toml")
    (cyl,) = sc.surfaces
    assert isinstance(cyl, Cylinder) and cyl.radius == 0.4 and cyl.inside is False
    # eq. 25: p_d(t) = (0.4 cos t, 0.4 sin t, 10 + t/10)
    for t in (0.0, 1.3, 7.0):
        np.testing.assert_allclose(
            sc.path.position(t), [0.4 * math.cos(t), 0.4 * math.sin(t), 10 + t / 10], atol=1e-12
        )
    np.testing.assert_allclose(sc.robot.tip_position(sc.q0), [0.4, 0.0, 7.0], atol=1e-10)
    assert sc.q0[2] > 0  # the elbow branch of the seed [0, 6, 2.0]
    assert sc.control.supervisor is False and sc.control.f_d == 10.0
    assert sc.sim.duration == 20.0 and sc.sim.dt == 1e-3


def test_paper_approach_is_inside_and_off_the_surface() -> None:
    sc = load_scenario(REPO_ROOT / "scenarios" / "paper_approach.toml")
    (cyl,) = sc.surfaces
    assert cyl.inside is True
    p0 = sc.robot.tip_position(sc.q0)
    np.testing.assert_allclose(p0, [0.1, 0.1, 2.0], atol=1e-10)
    # inside the pipe the free-side distance is r − ρ = 0.4 − √0.02 > 0
    assert cyl.distance(p0) == pytest.approx(0.4 - math.sqrt(0.02), abs=1e-12)
    assert sc.control.supervisor is True


def test_defaults_are_the_dataclass_defaults(tmp_path: Path) -> None:
    from hybrid_force.control.supervisor import ControlSettings
    from hybrid_force.sim.dynamics import Baumgarte
    from hybrid_force.sim.settings import SimSettings

    # no [control] and no [sim]; the start 0.1 m off the cylinder (the supervisor, on by
    # default, approaches it)
    text = BASE[: BASE.index("[control]")].replace("tip = [0.4, 0.0, 7.0]", "tip = [0.5, 0.0, 7.0]")
    sc = load_scenario(_write(tmp_path, text, "defaults.toml"))
    assert sc.control == ControlSettings()
    sim = SimSettings()
    assert (sc.sim.duration, sc.sim.dt, sc.sim.integrator) == (sim.duration, sim.dt, "euler")
    assert sc.sim.baumgarte == Baumgarte()
    assert (sc.sim.settle_time, sc.sim.unilateral, sc.sim.normalization) == (
        sim.settle_time,
        sim.unilateral,
        sim.normalization,
    )


def test_every_key_maps_to_the_settings(tmp_path: Path) -> None:
    text = BASE.replace(
        "[control]\nsupervisor = false\nf_d = 10.0\n",
        # supervised: max_dist and approach_rate act only then; kd_rate only without Kd and P
        # never (tests/test_unused_keys.py)
        "[control]\nsupervisor = true\nf_d = 12.5\nKd = [100, 200, 300]\n"
        "Lambda = 8\nbeta = 0.02\ngamma = 15\nclik_gain = 6\nmax_dist = 0.04\n"
        "contact_tol = 2e-5\napproach_rate = 5\n",
    ).replace(
        "[sim]\nduration = 2.0\n",
        '[sim]\nduration = 2.0\ndt = 5e-4\nintegrator = "rk4"\nbaumgarte_alpha = 40\n'
        "baumgarte_beta = 30\nmodel_mass_factor = 1.1\nsettle_time = 1\nunilateral = false\n"
        'normalization = "joint"\n',
    )
    sc = load_scenario(_write(tmp_path, text, "all.toml"))
    c, s = sc.control, sc.sim
    np.testing.assert_array_equal(np.asarray(c.Kd), [100.0, 200.0, 300.0])
    assert (c.Lambda, c.beta, c.gamma, c.f_d) == (8, 0.02, 15, 12.5)
    assert (c.clik_gain, c.max_dist, c.contact_tol, c.approach_rate) == (6, 0.04, 2e-5, 5)
    assert c.mass_factor == 1.1
    assert (s.dt, s.integrator, s.baumgarte.alpha, s.baumgarte.beta) == (5e-4, "rk4", 40, 30)
    assert (s.settle_time, s.unilateral, s.normalization) == (1, False, "joint")


def test_surfaces_list_and_initial_q(tmp_path: Path) -> None:
    # the start on the edge of two planes x = 0.4 (free side +x) and z = 7 (free side +z)
    text = """\
name = "two"
[robot]
model = "rtr"
[[surfaces]]
type = "plane"
point = [0.4, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
[[surfaces]]
type = "plane"
point = [0.0, 0.0, 7.0]
normal = [0.0, 0.0, 2.0]
[trajectory]
type = "circle"
center = [0.3, 0.0, 7.0]
radius = 0.1
normal = [0.0, 0.0, 1.0]
omega = 0.0  # stands still at center + radius·x = [0.4, 0, 7], on both planes
[initial]
q = [0.0, 6.1339746, 2.0943951]
v = [0.0, 0.0, 0.0]
[control]
supervisor = false  # stacked surfaces: the run starts in contact with both
[sim]
duration = 1.0
"""
    sc = load_scenario(_write(tmp_path, text, "two.toml"))
    assert [type(s) for s in sc.surfaces] == [Plane, Plane]
    np.testing.assert_allclose(sc.surfaces[1].normal([0, 0, 9]), [0, 0, 1])
    np.testing.assert_array_equal(sc.q0, [0.0, 6.1339746, 2.0943951])
    np.testing.assert_array_equal(sc.v0, [0.0, 0.0, 0.0])


def test_sphere_and_relative_urdf_path(tmp_path: Path) -> None:
    import shutil

    (tmp_path / "arms").mkdir()
    shutil.copy(REPO_ROOT / "robots" / "rtr.urdf", tmp_path / "arms" / "my_rtr.urdf")
    text = BASE.replace('model = "rtr"', 'model = "arms/my_rtr.urdf"\ntip = "tip"')
    text = text.replace(
        'type = "cylinder"\nradius = 0.4\ncenter = [0.0, 0.0, 0.0]\naxis = [0.0, 0.0, 1.0]',
        'type = "sphere"\nradius = 0.5\ncenter = [0.0, 0.0, 5.0]',
    ).replace(
        'type = "helix"\ncenter = [0.0, 0.0, 10.0]\nradius = 0.4\naxis = [0.0, 0.0, 1.0]\n'
        "omega = 1.0\nrise = 0.1\n",
        'type = "circle"\ncenter = [0.0, 0.0, 5.3]\nradius = 0.4\nnormal = [0.0, 0.0, 1.0]\n'
        "omega = 0.5\n",
    )
    text = text.replace("tip = [0.4, 0.0, 7.0]", "tip = [0.4, 0.0, 5.3]")
    sc = load_scenario(_write(tmp_path, text, "sphere.toml"))
    assert isinstance(sc.surfaces[0], Sphere)
    assert Path(sc.robot.urdf_path).name == "my_rtr.urdf"


# --- overrides ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "key", "value"),
    [
        ("sim.duration=0.2", "sim.duration", 0.2),
        ("control.Kd=5", "control.Kd", 5),
        ("control.supervisor=true", "control.supervisor", True),
        ("initial.tip=[0.4, 0, 7]", "initial.tip", [0.4, 0, 7]),
        ("sim.dt=1e-3", "sim.dt", 1e-3),
        ('name="x"', "name", "x"),
        ("sim.integrator=rk4", "sim.integrator", "rk4"),  # not TOML: the raw string
        ("  sim.integrator = euler ", "sim.integrator", "euler"),
        ("robot.model=a=b", "robot.model", "a=b"),
    ],
)
def test_parse_override(text: str, key: str, value: object) -> None:
    k, v = parse_override(text)
    assert k == key
    assert v == value and type(v) is type(value)


@pytest.mark.parametrize("text", ["sim.duration", "=3", "sim..dt=1", ".dt=1"])
def test_parse_override_rejects(text: str) -> None:
    with pytest.raises(ScenarioError, match=r"table\.key=value"):
        parse_override(text)


def test_overrides_replace_and_add(tmp_path: Path) -> None:
    path = _write(tmp_path, BASE, "ok.toml")
    sc = load_scenario(
        path,
        {
            "sim.duration": 0.5,
            "sim.integrator": "rk4",
            "control.Kd": 300,
            "control.f_d": 4,
            "name": "renamed",
        },
    )
    assert sc.sim.duration == 0.5 and sc.sim.integrator == "rk4"
    assert float(sc.control.Kd) == 300.0 and sc.control.f_d == 4
    assert sc.name == "renamed"
    assert sc.source["sim"]["duration"] == 0.5 and sc.source["control"]["Kd"] == 300
    assert sc.source["name"] == "renamed"
    # the file is unchanged
    assert load_scenario(path).sim.duration == 2.0


def test_override_into_surfaces_list(tmp_path: Path) -> None:
    text = BASE.replace("[surface]", "[[surfaces]]")
    sc = load_scenario(_write(tmp_path, text, "list.toml"), {"surfaces.0.inside": False})
    assert sc.surfaces[0].inside is False
    msg = _error(_write(tmp_path, text, "list2.toml"), {"surfaces.3.radius": 1.0})
    assert "surfaces.3" in msg and "list2.toml" in msg


def test_unknown_override_key_is_an_error(tmp_path: Path) -> None:
    path = _write(tmp_path, BASE, "ok.toml")
    msg = _error(path, {"control.Lamda": 3})
    assert "ok.toml" in msg and "control.Lamda = 3" in msg and "did you mean 'Lambda'" in msg
    msg = _error(path, {"contrl.Kd": 3})
    assert "contrl" in msg and "did you mean 'control'" in msg


def test_no_eval(tmp_path: Path) -> None:
    path = _write(tmp_path, BASE, "ok.toml")
    key, value = parse_override("sim.duration=__import__('os').system('false')")
    assert value == "__import__('os').system('false')"
    msg = _error(path, {key: value})
    assert "sim.duration" in msg and "must be a number, got a string" in msg
    text = BASE.replace("radius = 0.4\ncenter", "radius = \"__import__('os')\"\ncenter")
    msg = _error(_write(tmp_path, text))
    assert "surface.radius" in msg and "__import__" in msg and "got a string" in msg


# --- broken files ---------------------------------------------------------------------------------
_BROKEN = [
    # (id, old text, new text, key named, value named, words in the problem)
    (
        "unknown key",
        "rise = 0.1",
        "rise = 0.1\nphse = 0.0",
        "trajectory.phse",
        "0.0",
        "did you mean 'phase'",
    ),
    ("unknown table", "[sim]", "[simulation]", "simulation", "duration", "did you mean"),
    (
        "unknown top key",
        'name = "base"',
        'name = "base"\nnmae = "x"',
        "nmae",
        '"x"',
        "did you mean 'name'",
    ),
    ("missing key", "rise = 0.1\n", "", "trajectory.rise", "", "missing required key"),
    ("missing model", 'model = "rtr"', 'tip = "tip"', "robot.model", "", "missing required key"),
    (
        "missing table",
        "[initial]\ntip = [0.4, 0.0, 7.0]\nseed = [0.0, 6.0, 2.0]\n",
        "",
        "[initial]",
        "",
        "missing required table",
    ),
    (
        "2-vector",
        "center = [0.0, 0.0, 10.0]",
        "center = [0.0, 10.0]",
        "trajectory.center",
        "[0.0, 10.0]",
        "3 numbers",
    ),
    (
        "radius string",
        "radius = 0.4\ncenter = [0.0, 0.0, 0.0]",
        'radius = "0.4"\ncenter = [0.0, 0.0, 0.0]',
        "surface.radius",
        '"0.4"',
        "got a string",
    ),
    ("bool for number", "omega = 1.0", "omega = true", "trajectory.omega", "true", "got a boolean"),
    (
        "number for bool",
        "supervisor = false",
        "supervisor = 0",
        "control.supervisor",
        "0",
        "true or false",
    ),
    ("nan", "f_d = 10.0", "f_d = nan", "control.f_d", "NaN", "finite"),
    (
        "negative radius",
        "radius = 0.4\ncenter = [0.0, 0.0, 0.0]",
        "radius = -0.4\ncenter = [0.0, 0.0, 0.0]",
        "surface.radius",
        "-0.4",
        "positive",
    ),
    (
        "zero axis",
        "axis = [0.0, 0.0, 1.0]\n\n",
        "axis = [0.0, 0.0, 0.0]\n\n",
        "surface.axis",
        "[0.0, 0.0, 0.0]",
        "non-zero",
    ),
    (
        "surface type",
        'type = "cylinder"',
        'type = "cylindre"',
        "surface.type",
        '"cylindre"',
        "did you mean 'cylinder'",
    ),
    (
        "path type",
        'type = "helix"',
        'type = "spiral"',
        "trajectory.type",
        '"spiral"',
        "helix, circle",
    ),
    (
        "integrator",
        "duration = 2.0",
        'duration = 2.0\nintegrator = "rk5"',
        "sim.integrator",
        '"rk5"',
        "did you mean 'rk4'",
    ),
    ("negative dt", "duration = 2.0", "duration = 2.0\ndt = -1e-3", "sim.dt", "-0.001", "> 0"),
    ("dt > duration", "duration = 2.0", "duration = 2.0\ndt = 3.0", "sim.dt", "3.0", "larger than"),
    (
        "bad Kd",
        "f_d = 10.0",
        "f_d = 10.0\nKd = [1.0, -2.0, 3.0]",
        "control.Kd",
        "[1.0, -2.0, 3.0]",
        "positive definite",
    ),
    (
        "Kd shape",
        "f_d = 10.0",
        "f_d = 10.0\nKd = [1.0, 2.0]",
        "control.Kd",
        "[1.0, 2.0]",
        "vector of 3",
    ),
    ("bad P", "f_d = 10.0", "f_d = 10.0\nP = 1.5", "control.P", "1.5", "(0, 1)"),
    (
        "seed length",
        "seed = [0.0, 6.0, 2.0]",
        "seed = [0.0, 6.0]",
        "initial.seed",
        "[0.0, 6.0]",
        "3 numbers",
    ),
    (
        "both tip and q",
        "seed = [0.0, 6.0, 2.0]",
        "q = [0.0, 6.0, 2.0]",
        "initial.tip, initial.q",
        "",
        "not both",
    ),
    (
        "out of reach",
        "tip = [0.4, 0.0, 7.0]",
        "tip = [5.0, 0.0, 7.0]",
        "initial.tip",
        "[5.0, 0.0, 7.0]",
        "out of reach",
    ),
    ("unknown robot", 'model = "rtr"', 'model = "ur55"', "robot.model", '"ur55"', "ur5"),
    ("bad tip frame", 'model = "rtr"', 'model = "rtr"\ntip = "nib"', "robot.tip", '"nib"', "nib"),
    (
        "missing urdf",
        'model = "rtr"',
        'model = "arms/none.urdf"',
        "robot.model",
        '"arms/none.urdf"',
        "not found",
    ),
    (
        "missing xacro",
        'model = "rtr"',
        'model = "arm.urdf.xacro"',
        "robot.model",
        '"arm.urdf.xacro"',
        "xacro file not found (paths are relative to the scenario file)",
    ),
    (
        "missing mjcf",
        'model = "rtr"',
        'model = "arm.xml"',
        "robot.model",
        '"arm.xml"',
        "MJCF file not found",
    ),
    (
        "package folder missing",
        'model = "rtr"',
        'model = "rtr"\npackage_dirs = ["meshes", "nowhere"]',
        "robot.package_dirs",
        '["meshes", "nowhere"]',
        "folder not found (paths are relative to the scenario file)",
    ),
    (
        "package folders not a list",
        'model = "rtr"',
        'model = "rtr"\npackage_dirs = "meshes"',
        "robot.package_dirs",
        '"meshes"',
        "must be an array of strings, got a string",
    ),
    (
        "package folder empty",
        'model = "rtr"',
        'model = "rtr"\npackage_dirs = [""]',
        "robot.package_dirs",
        '[""]',
        "element 0 is empty",
    ),
    (
        "xacro arguments for a name",
        'model = "rtr"',
        'model = "rtr"\nxacro_args = {l2 = "1"}',
        "robot.xacro_args",
        '{"l2": "1"}',
        'robot.model = "rtr" is not a .xacro file',
    ),
    (
        "xacro arguments not a table",
        'model = "rtr"',
        'model = "rtr"\nxacro_args = ["l2"]',
        "robot.xacro_args",
        '["l2"]',
        "must be a table of texts",
    ),
    (
        "xacro argument an array",
        'model = "rtr"',
        'model = "rtr"\nxacro_args = {l2 = [1]}',
        "robot.xacro_args.l2",
        "[1]",
        "must be a text (a string), got an array",
    ),
    (
        "lock_off_chain not a boolean",
        'model = "rtr"',
        'model = "rtr"\nlock_off_chain = "no"',
        "robot.lock_off_chain",
        '"no"',
        "must be true or false",
    ),
    (
        "both surface forms",
        "[trajectory]",
        '[[surfaces]]\ntype = "plane"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n'
        "\n[trajectory]",
        "surface, surfaces",
        "",
        "not both",
    ),
    ("bad name", 'name = "base"', 'name = "../up"', "name", '"../up"', "simple name"),
]


@pytest.mark.parametrize(
    ("old", "new", "key", "value", "problem"),
    [case[1:] for case in _BROKEN],
    ids=[case[0] for case in _BROKEN],
)
def test_broken_file(
    tmp_path: Path, old: str, new: str, key: str, value: str, problem: str
) -> None:
    assert old in BASE
    path = _write(tmp_path, BASE.replace(old, new, 1))
    msg = _error(path)
    assert str(path) in msg
    assert key in msg
    assert value in msg
    assert problem in msg


def test_robot_package_dirs_are_relative_to_the_scenario_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "study" / "meshes").mkdir(parents=True)
    text = BASE.replace('model = "rtr"', 'model = "rtr"\npackage_dirs = ["meshes"]')
    path = _write(tmp_path / "study", text, "s.toml")
    monkeypatch.chdir(tmp_path)
    sc = load_scenario("study/s.toml")
    assert sc.robot.package_dirs[0] == str(tmp_path / "study" / "meshes")
    assert sc.robot.reference["package_dirs"] == [str(tmp_path / "study" / "meshes")]
    assert sc.source["robot"]["package_dirs"] == ["meshes"]  # the file's data, as written
    assert path.is_file()


def test_robot_xacro_argument_values_become_texts(tmp_path: Path) -> None:
    """Strings stay; numbers and booleans are passed to xacro as their TOML text; a number
    that is not finite is refused."""
    from hybrid_force.model.xacro_files import xacro_argument_text

    assert [xacro_argument_text(v) for v in ("a b", 0.7, 3, 1e-3, True, False)] == [
        "a b", "0.7", "3", "0.001", "true", "false",
    ]  # fmt: skip
    text = BASE.replace('model = "rtr"', 'model = "rtr"\nxacro_args = {l2 = inf}')
    msg = _error(_write(tmp_path, text))
    assert "robot.xacro_args.l2 = Infinity" in msg and "finite" in msg


def test_toml_syntax_error_gives_line_and_column(tmp_path: Path) -> None:
    path = _write(tmp_path, BASE.replace("omega = 1.0", "omega = = 1.0"))
    msg = _error(path)
    line = BASE.splitlines().index("omega = 1.0") + 1
    assert str(path) in msg and "TOML syntax error" in msg
    assert f"line {line}" in msg and "column" in msg


def test_missing_file(tmp_path: Path) -> None:
    msg = _error(tmp_path / "nope.toml")
    assert "nope.toml" in msg and "not found" in msg


def test_trajectory_off_the_surface_says_how_far_and_when(tmp_path: Path) -> None:
    # radius 0.4 + 1e-3: 1 mm off the cylinder at every time
    path = _write(tmp_path, BASE.replace("radius = 0.4\naxis", "radius = 0.401\naxis"))
    msg = _error(path)
    assert str(path) in msg and "trajectory.radius = 0.401" in msg and "not on [surface]" in msg
    assert "0.001 m away" in msg
    # a helix tilted off the cylinder axis leaves it: the worst |d| is at the end (t = 2)
    tilted = BASE.replace(
        "radius = 0.4\naxis = [0.0, 0.0, 1.0]\nomega",
        "radius = 0.4\naxis = [0.0, 0.01, 1.0]\nomega",
    )
    msg = _error(_write(tmp_path, tilted, "tilted.toml"))
    assert "trajectory.axis = [0.0, 0.01, 1.0]" in msg and "at t = 2 s" in msg


@pytest.mark.parametrize("supervisor", [False, True])
def test_file_load_scans_the_path_once_and_a_run_built_by_hand_is_still_checked(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, supervisor: bool
) -> None:
    from hybrid_force.control.supervisor import ControlSettings
    from hybrid_force.geometry import on_surface
    from hybrid_force.geometry.paths import Helix

    scans: list[float] = []
    scan = on_surface._scan

    def counted(path, surface, a, b, n):  # type: ignore[no-untyped-def]
        scans.append(b)
        return scan(path, surface, a, b, n)

    monkeypatch.setattr(on_surface, "_scan", counted)
    text = BASE if not supervisor else BASE.replace("supervisor = false", "supervisor = true")
    loaded = load_scenario(_write(tmp_path, text, "ok.toml"))
    # Scenario checks the path, once (the loader names the file in its refusal): one scan of
    # the single surface over [0, sim.duration]
    assert scans == [2.0]
    assert loaded.control.supervisor is supervisor
    # the same objects in a Scenario built by hand: checked again, nothing remembered
    parts = {
        "robot": loaded.robot,
        "surfaces": loaded.surfaces,
        "q0": loaded.q0,
        "control": ControlSettings(supervisor=False, f_d=10.0),
        "sim": loaded.sim,
    }
    Scenario(path=loaded.path, **parts)
    assert scans == [2.0, 2.0]
    off = Helix((0.0, 0.0, 10.0), 0.45, omega=1.0, rise=0.1)  # 5 cm outside the cylinder
    with pytest.raises(BadInputError, match=r"path is not on surfaces\[0\]") as info:
        Scenario(path=off, **parts)
    assert "0.05 m away" in str(info.value) and len(scans) == 3


def test_start_not_on_surface_when_starting_in_contact(tmp_path: Path) -> None:
    path = _write(tmp_path, BASE.replace("tip = [0.4, 0.0, 7.0]", "tip = [0.41, 0.0, 7.0]"))
    msg = _error(path)
    assert str(path) in msg and "initial.tip = [0.41, 0.0, 7.0]" in msg
    assert "0.01 m from the surface" in msg and "control.supervisor = false" in msg
    # the same start is fine with the supervisor (the arm approaches the surface)
    sc = load_scenario(path, {"control.supervisor": True})
    assert sc.surfaces[0].distance(sc.robot.tip_position(sc.q0)) == pytest.approx(0.01)


def test_start_inside_the_solid(tmp_path: Path) -> None:
    path = _write(tmp_path, BASE.replace("tip = [0.4, 0.0, 7.0]", "tip = [0.3, 0.0, 7.0]"))
    msg = _error(path, {"control.supervisor": True})
    assert "initial.tip = [0.3, 0.0, 7.0]" in msg and "0.1 m behind the surface" in msg


def test_stiff_default_gain_names_kd_and_dt(tmp_path: Path) -> None:
    path = _write(tmp_path, BASE)
    msg = _error(path, {"control.kd_rate": 1000.0, "sim.dt": 0.002})
    assert "control.Kd" in msg and "dt" in msg


# --- bounded resources and absurd values (exit 2, one 'error:' line naming file and key) --------
def _cli_run(
    capsys: pytest.CaptureFixture[str], path: Path, out: Path, *extra: str
) -> tuple[int, str]:
    """``hybrid-force run path --out out --quiet ...``: (status, the single stderr line)."""
    from hybrid_force.cli import main

    capsys.readouterr()
    status = main(["run", str(path), "--out", str(out), "--quiet", *extra])
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return status, lines[0]


_HUGE = "1" + "0" * 400  # an integer beyond float range (10**400)

_ABSURD_NUMBERS = [
    # (id, old text, new text, key named, words in the problem)
    (
        "int 10**400",
        "radius = 0.4\ncenter",
        f"radius = {_HUGE}\ncenter",
        "surface.radius",
        "finite",
    ),
    (
        "int 10**400 in vector",
        "center = [0.0, 0.0, 10.0]",
        f"center = [1e0, {_HUGE}, 0]",
        "trajectory.center",
        "element 1 is not finite",
    ),
    ("1e400", "radius = 0.4\ncenter", "radius = 1e400\ncenter", "surface.radius", "finite"),
    ("-inf", "omega = 1.0", "omega = -inf", "trajectory.omega", "finite"),
    ("nan", "radius = 0.4\ncenter", "radius = nan\ncenter", "surface.radius", "finite"),
    (
        "nan in vector",
        "tip = [0.4, 0.0, 7.0]",
        "tip = [0.4, nan, 7.0]",
        "initial.tip",
        "element 1 is not finite",
    ),
    ("int 10**400 in sim", "duration = 2.0", f"duration = {_HUGE}", "sim.duration", "finite"),
]


@pytest.mark.parametrize(
    ("old", "new", "key", "problem"),
    [case[1:] for case in _ABSURD_NUMBERS],
    ids=[case[0] for case in _ABSURD_NUMBERS],
)
def test_absurd_numbers_exit_2_naming_file_and_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], old: str, new: str, key: str, problem: str
) -> None:
    assert old in BASE
    path = _write(tmp_path, BASE.replace(old, new, 1))
    msg = _error(path)
    assert str(path) in msg and f"{key} = " in msg and problem in msg
    out = tmp_path / "out"
    status, line = _cli_run(capsys, path, out)
    assert status == 2 and str(path) in line and f"{key} = " in line and problem in line
    assert not out.exists()


_DEEP = 100_000


@pytest.mark.parametrize(
    "text",
    [
        "x = " + "[" * _DEEP + "]" * _DEEP + "\n" + BASE,
        "x = " + "{a = " * _DEEP + "1" + "}" * _DEEP + "\n" + BASE,
        BASE.replace("duration = 2.0", "duration = " + "[" * _DEEP + "]" * _DEEP),
        BASE.replace("duration = 2.0", "duration = " + "{a = " * _DEEP + "1" + "}" * _DEEP),
    ],
    ids=["arrays-top", "inline-tables-top", "arrays-in-sim", "inline-tables-in-sim"],
)
def test_deep_nesting_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    path = _write(tmp_path, text, "deep.toml")
    msg = _error(path)
    assert str(path) in msg and "nested too deeply" in msg
    out = tmp_path / "out"
    status, line = _cli_run(capsys, path, out)
    assert status == 2 and str(path) in line and "nested too deeply" in line
    assert not out.exists()


def test_moderately_deep_value_is_an_ordinary_error(tmp_path: Path) -> None:
    # deep enough to be absurd, shallow enough for tomllib: the key's own check refuses it
    path = _write(tmp_path, BASE.replace("seed = [0.0, 6.0, 2.0]", "seed = " + "[" * 50 + "]" * 50))
    msg = _error(path)
    assert str(path) in msg and "initial.seed = [[[" in msg and "element 0 is an array" in msg


def test_scenario_file_over_the_size_limit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from hybrid_force.scenario.loader import MAX_FILE_BYTES

    pad = MAX_FILE_BYTES - len(BASE.encode()) - 2
    exact = BASE + "#" + "x" * pad + "\n"
    assert len(exact.encode()) == MAX_FILE_BYTES
    assert load_scenario(_write(tmp_path, exact, "exact.toml")).name == "base"
    path = _write(tmp_path, BASE + "#" + "x" * (pad + 1) + "\n", "big.toml")
    msg = _error(path)
    assert str(path) in msg and f"larger than {MAX_FILE_BYTES} bytes" in msg
    out = tmp_path / "out"
    status, line = _cli_run(capsys, path, out)
    assert status == 2 and str(path) in line and str(MAX_FILE_BYTES) in line
    assert not out.exists()
    # a (sparse) file of 256 MiB is refused after reading MAX_FILE_BYTES + 1 bytes of it
    sparse = tmp_path / "sparse.toml"
    with sparse.open("wb") as fh:
        fh.truncate(256 << 20)
    msg = _error(sparse)
    assert str(sparse) in msg and f"larger than {MAX_FILE_BYTES} bytes" in msg


@pytest.mark.parametrize(
    ("value", "problem"),
    [
        (_HUGE, "finite"),
        ("1e400", "finite"),
        ("nan", "finite"),
        ("[" * _DEEP + "]" * _DEEP, "nested too deeply"),
        ("{a=" * _DEEP + "1" + "}" * _DEEP, "nested too deeply"),
    ],
    ids=["int 10**400", "1e400", "nan", "deep arrays", "deep inline tables"],
)
def test_absurd_override_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str, problem: str
) -> None:
    if problem == "nested too deeply":
        with pytest.raises(ScenarioError, match=r"'sim\.dt'.*nested too deeply"):
            parse_override(f"sim.dt={value}")
    else:
        key, parsed = parse_override(f"sim.dt={value}")
        msg = _error(_write(tmp_path, BASE, "ok.toml"), {key: parsed})
        assert "ok.toml" in msg and "sim.dt = " in msg and problem in msg
    out = tmp_path / "out"
    status, line = _cli_run(
        capsys, _write(tmp_path, BASE, "ok.toml"), out, "--set", f"sim.dt={value}"
    )
    assert status == 2 and "sim.dt" in line and problem in line
    assert not out.exists()


@pytest.mark.parametrize(
    "toml_value",
    [
        r'"ok\n"',  # a trailing newline (basic string escape)
        '"""ok\n"""',  # the same, as a multi-line string
        '"a/b"',
        '"../up"',
        '".."',
        '"."',
        '".hidden"',
        '""',
        '"-rf"',
        '"a b"',
        r'"a\\b"',
        r'"a\u0000b"',
        '"café"',
        '"' + "a" * 101 + '"',
        "1",
        "[]",
    ],
    ids=[
        "newline",
        "newline-multiline",
        "slash",
        "dotdot-slash",
        "dotdot",
        "dot",
        "leading-dot",
        "empty",
        "leading-dash",
        "space",
        "backslash",
        "nul",
        "non-ascii",
        "101 chars",
        "number",
        "array",
    ],
)
def test_bad_names_exit_2_naming_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], toml_value: str
) -> None:
    path = _write(tmp_path, BASE.replace('name = "base"', f"name = {toml_value}", 1))
    msg = _error(path)
    assert str(path) in msg and "name = " in msg
    out = tmp_path / "out"
    status, line = _cli_run(capsys, path, out)
    assert status == 2 and str(path) in line and ": name = " in line
    assert not out.exists()


@pytest.mark.parametrize("name", ["run_1.a-b", "_x", "9", "a..b", "A" * 100])
def test_valid_names_are_accepted(tmp_path: Path, name: str) -> None:
    sc = load_scenario(_write(tmp_path, BASE.replace('name = "base"', f'name = "{name}"', 1)))
    assert sc.name == name


# --- the desired path followed over the whole run (RTR arm on the plane z = 5) ------------------
RTR_PLANE = (REPO_ROOT / "scenarios" / "rtr_plane.toml").read_text(encoding="utf-8")
REACH = 1.9  # [m] largest distance of the RTR tip from the z axis (l2 + l3)


def _plane_circle(center_x: float, radius: float, phase: float) -> str:
    """rtr_plane.toml with the circle moved to center [center_x, 0, 5], radius and phase; the
    start 2 cm above the circle's start point (omega 0.5 rad/s, duration 12 s as shipped)."""
    x0 = center_x + radius * math.cos(phase)
    y0 = radius * math.sin(phase)
    text = RTR_PLANE
    for old, new in (
        ("center = [0.0, 0.0, 5.0]", f"center = [{center_x!r}, 0.0, 5.0]"),
        ("radius = 0.6", f"radius = {radius!r}"),
        ("phase = 0.0 ", f"phase = {phase!r} "),
        ("tip = [0.6, 0.0, 5.02]", f"tip = [{x0:.9f}, {y0:.9f}, 5.02]"),
    ):
        assert old in text
        text = text.replace(old, new, 1)
    return text


def _failure_time(line: str) -> float:
    match = re.search(r"at t = ([0-9.e+-]+) s", line)
    assert match, line
    return float(match.group(1))


def test_path_out_of_reach_in_the_middle_of_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # center x = 1.2, radius 0.8, phase pi: starts at [0.4, 0, 5] (reachable); the far side is
    # 2.0 m from the z axis. The circle leaves the reach (1.9 m) when
    # |c + r e(θ)|² = 2.08 + 1.92 cos θ = 1.9², θ = π + 0.5 t  →  t ≈ 4.99 s.
    path = _write(tmp_path, _plane_circle(1.2, 0.8, math.pi), "far.toml")
    t_leave = (math.pi - math.acos((REACH**2 - 2.08) / 1.92)) / 0.5
    # the start and the first 4 s are fine: the same file with a shorter run loads
    assert load_scenario(path, {"sim.duration": 4.0}).name == "rtr_plane"
    msg = _error(path)
    out = tmp_path / "out"
    status, line = _cli_run(capsys, path, out)
    assert status == 2
    for text in (msg, line):
        assert str(path) in text and "out of reach" in text
        assert "trajectory.center = [1.2, 0.0, 5.0]" in text and "trajectory.radius = 0.8" in text
        t = _failure_time(text)
        assert t_leave <= t <= t_leave + 0.021, (t, t_leave)  # the first sample beyond reach
        match = re.search(r"p_d = \[([^\]]*)\]", text)
        assert match, text
        p = [float(v) for v in match.group(1).split(",")]
        assert math.hypot(p[0], p[1]) > REACH and p[2] == 5.0
    assert not out.exists()


@pytest.mark.parametrize(
    ("center_x", "radius", "phase", "where"),
    [
        # center x = 1.0, radius 0.9: the far side [1.9, 0, 5] is the full extension (q3 = 0)
        (1.0, 0.9, -3.0, [1.9, 0.0, 5.0]),
        # center x = 0.5, radius 0.5: the circle passes over the z axis at [0, 0, 5]
        (0.5, 0.5, math.pi - 3.0, [0.0, 0.0, 5.0]),
    ],
    ids=["full-extension", "over-the-z-axis"],
)
def test_path_through_a_singular_configuration_in_the_middle_of_the_run(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    center_x: float,
    radius: float,
    phase: float,
    where: list[float],
) -> None:
    # θ(t) = phase + 0.5 t reaches the singular point at t = 6 s, a sample of the check
    path = _write(tmp_path, _plane_circle(center_x, radius, phase), "singular.toml")
    np.testing.assert_allclose(
        [center_x + radius * math.cos(phase + 3.0), radius * math.sin(phase + 3.0), 5.0],
        where,
        atol=1e-12,
    )
    assert load_scenario(path, {"sim.duration": 5.5}).name == "rtr_plane"
    msg = _error(path)
    out = tmp_path / "out"
    status, line = _cli_run(capsys, path, out)
    assert status == 2
    for text in (msg, line):
        assert str(path) in text and "singular configuration" in text
        assert f"trajectory.center = [{center_x!r}, 0.0, 5.0]" in text
        assert f"trajectory.phase = {phase!r}" in text
        assert _failure_time(text) == pytest.approx(6.0)
        assert f"p_d = {where}" in text
    assert not out.exists()


def test_shipped_scenarios_follow_their_whole_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each shipped scenario still loads with the path check, which solves the inverse
    kinematics (of the tip position, or of the tool pose with ``[tool] orientation =
    "normal"``) at every sample of [0, duration] (each load takes well under a second)."""
    import hybrid_force.control.clik as clik
    import hybrid_force.control.pose_clik as pose_clik
    import hybrid_force.sim.prerun as scenario_checks
    from hybrid_force.sim.prerun import PATH_CHECK_SAMPLES, PATH_CHECK_STEP

    calls: list[int] = []
    # the solver where it is defined and where the path check calls it
    targets = ((clik, "newton_ik"), (scenario_checks, "newton_ik"), (pose_clik, "_pose_newton"))
    for module, name in targets:
        solve = getattr(module, name)

        def counting(*args: object, _solve: Any = solve, **kwargs: object) -> Any:
            calls.append(1)
            return _solve(*args, **kwargs)

        monkeypatch.setattr(module, name, counting)
    for path in SHIPPED:
        calls.clear()
        sc = load_scenario(path)
        samples = min(PATH_CHECK_SAMPLES, math.ceil(sc.sim.duration / PATH_CHECK_STEP) + 1)
        assert len(calls) >= samples, path.name


def test_sensor_table_control_rate_and_seed_are_loaded(tmp_path: Path) -> None:
    from hybrid_force.sim.sensors import SensorSettings

    scenario = load_scenario(
        REPO_ROOT / "scenarios" / "paper_contact.toml",
        {
            "sensor.force_noise": 0.5,
            "sensor.force_cutoff": 50,
            "sensor.force_delay": 1,
            "control.rate": 500,
            "sim.seed": 7,
        },
    )
    assert scenario.sensor == SensorSettings(force_noise=0.5, force_cutoff=50.0, force_delay=1)
    assert scenario.control.rate == 500.0 and scenario.sim.seed == 7


@pytest.mark.parametrize(
    ("override", "key"),
    [
        ("control.rate=300", "control.rate"),  # 1 / (300 Hz · 1 ms) is not a whole number
        ("control.rate=2000", "control.rate"),  # faster than the plant
        ("sensor.force_delay=1.5", "sensor.force_delay"),
        ("sensor.force_cutoff=-1", "sensor.force_cutoff"),
        ("sensor.bias=1", "sensor.bias"),  # unknown key
        ("sim.seed=true", "sim.seed"),
    ],
)
def test_bad_sensor_and_rate_settings_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], override: str, key: str
) -> None:
    from hybrid_force.cli import main

    out = tmp_path / "out"
    argv = ["run", str(REPO_ROOT / "scenarios" / "paper_contact.toml"), "--set", override]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and f"{key} = " in err[0] and not out.exists()


def test_the_gain_check_uses_the_control_period(capsys: pytest.CaptureFixture[str]) -> None:
    """K_d = 100 M(q0) at a 100 Hz controller: period · λ_max(M⁻¹K_d) = 0.01 · 100 = 1 > 0.5,
    refused by the loader, while the same gain at the plant's 1 kHz (0.1) is accepted."""
    load_scenario(REPO_ROOT / "scenarios" / "paper_contact.toml")
    with pytest.raises(ScenarioError, match=r"control\.Kd = .*= 1 at q0.*control period 0\.01 s"):
        load_scenario(REPO_ROOT / "scenarios" / "paper_contact.toml", {"control.rate": 100})


def test_a_scenario_error_carries_the_file_key_and_value() -> None:
    path = REPO_ROOT / "scenarios" / "paper_contact.toml"
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, {"surface.radius": -0.4})
    assert info.value.key == "surface.radius" and info.value.value == -0.4
    assert info.value.file == str(path)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, {"sim.duration": "long"})
    assert (info.value.key, info.value.value) == ("sim.duration", "long")

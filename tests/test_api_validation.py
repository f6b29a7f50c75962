"""The Python API validates like the scenario loader.

Every public constructor (surfaces, paths, settings, gains, Scenario) is called with wrong
types (strings, None, bools where a number is expected, two numbers where three are needed,
nested lists, dicts, arrays of the wrong shape, complex numbers, 10**400, which does not fit
in a float), non-finite and out-of-range values. Each must raise a BadInputError subclass
(never a raw TypeError, ValueError, AttributeError, numpy or Boost.Python error) whose message
names the parameter the way the scenario file's key spells it, so that the loader, which looks
for the key in the message, points at the right ``table.key``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from hybrid_force.control.clik import ClikSettings, inverse_kinematics
from hybrid_force.control.constraint import Constraint
from hybrid_force.control.laws.arimoto import check_damping_gain, make_gains
from hybrid_force.control.supervisor import ControlSettings
from hybrid_force.errors import (
    BadInputError,
    ControlError,
    PathError,
    RunFailedError,
    ScenarioError,
    SurfaceError,
)
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.on_surface import check_on_surface
from hybrid_force.geometry.paths import Circle, FunctionPath, Helix, paper_helix, path_from_dict
from hybrid_force.geometry.surfaces import surface_from_dict
from hybrid_force.model.loading import load_robot
from hybrid_force.model.robot import Robot
from hybrid_force.sim.dynamics import Baumgarte
from hybrid_force.sim.settings import Scenario, SimSettings

# --- bad values, by what was expected ------------------------------------------------------------
NOT_A_NUMBER: list[tuple[str, object]] = [
    ("str", "1.0"),
    ("None", None),
    ("bool", True),
    ("two numbers", [1.0, 2.0]),
    ("dict", {"value": 1.0}),
    ("array of size 1", np.array([1.0])),
    ("complex", 1j),
    ("10**400", 10**400),
    ("nan", math.nan),
    ("inf", math.inf),
    ("-inf", -math.inf),
]
NEGATIVE: list[tuple[str, object]] = [("-1", -1.0), ("-1e-300", -1e-300)]
ZERO: list[tuple[str, object]] = [("0", 0.0)]

BAD_VECTORS: list[tuple[str, object]] = [
    ("str", "abc"),
    ("None", None),
    ("bool", True),
    ("a number", 1.0),
    ("two numbers", [1.0, 2.0]),
    ("four numbers", [1.0, 2.0, 3.0, 4.0]),
    ("nested list", [[1.0, 2.0, 3.0]]),
    ("ragged nesting", [[1.0], [2.0, 3.0], 4.0]),
    ("a string inside", [1.0, "a", 3.0]),
    ("None inside", [1.0, None, 3.0]),
    ("dict", {"x": 1.0}),
    ("column array", np.zeros((3, 1))),
    ("complex", [1j, 0.0, 0.0]),
    ("10**400 inside", [10**400, 0.0, 0.0]),
    ("nan inside", [math.nan, 0.0, 0.0]),
    ("inf inside", [0.0, math.inf, 0.0]),
    ("bools", [True, False, True]),
]
ZERO_VECTOR: list[tuple[str, object]] = [("zero vector", [0.0, 0.0, 0.0])]
BAD_FLAGS: list[tuple[str, object]] = [
    ("str 'yes'", "yes"),
    ("str 'false'", "false"),
    ("int 1", 1),
    ("int 0", 0),
    ("None", None),
    ("float", 1.0),
    ("list", [True]),
]
BAD_CALLABLES: list[tuple[str, object]] = [
    ("str", "lambda p: p[2]"),
    ("number", 1.0),
    ("list of a function", [abs]),
]
BAD_CHOICES: list[tuple[str, object]] = [
    ("other case", "RK4"),
    ("empty", ""),
    ("None", None),
    ("number", 1),
    ("list", ["euler"]),
    ("array", np.array(["euler"])),
]

# valid for f_d (one per surface; None for K_d: the default) and K_d (its diagonal)
SEQUENCES_OK = ("two numbers", "None", "array of size 1")

Case = tuple[str, Callable[[object], object], str, type[BadInputError], list[tuple[str, object]]]


def _numbers(rule: str) -> list[tuple[str, object]]:
    """Bad values for a number that must be 'real', '>= 0' or '> 0'."""
    extra = {"real": [], ">= 0": NEGATIVE, "> 0": NEGATIVE + ZERO}[rule]
    return NOT_A_NUMBER + extra


def _keyword(cls: Callable[..., object], name: str) -> Callable[[object], object]:
    """``value -> cls(name=value)``."""
    return lambda value: cls(**{name: value})


def _fs(**kwargs: Any) -> FunctionSurface:
    return FunctionSurface(lambda p: float(p[2]), **kwargs)


def _fp(**kwargs: Any) -> FunctionPath:
    return FunctionPath(lambda t: (t, 0.0, 0.0), **kwargs)


def _helix(**kwargs: Any) -> Helix:
    args: dict[str, Any] = {"center": (0, 0, 0), "radius": 1.0, "omega": 1.0, "rise": 0.0}
    return Helix(**{**args, **kwargs})


def _circle(**kwargs: Any) -> Circle:
    args: dict[str, Any] = {"center": (0, 0, 0), "radius": 1.0, "normal": (0, 0, 1), "omega": 1.0}
    return Circle(**{**args, **kwargs})


# (what is built, how a bad value is passed, the key the message must name, error, bad values)
CASES: list[Case] = [
    # surfaces
    ("Cylinder", lambda v: Cylinder(v), "radius", SurfaceError, _numbers("> 0")),
    ("Cylinder", lambda v: Cylinder(1.0, v), "center", SurfaceError, BAD_VECTORS),
    (
        "Cylinder",
        lambda v: Cylinder(1.0, (0, 0, 0), v),
        "axis",
        SurfaceError,
        BAD_VECTORS + ZERO_VECTOR,
    ),
    ("Cylinder", lambda v: Cylinder(1.0, inside=v), "inside", SurfaceError, BAD_FLAGS),
    ("Sphere", lambda v: Sphere(v), "radius", SurfaceError, _numbers("> 0")),
    ("Sphere", lambda v: Sphere(1.0, v), "center", SurfaceError, BAD_VECTORS),
    ("Sphere", lambda v: Sphere(1.0, inside=v), "inside", SurfaceError, BAD_FLAGS),
    ("Plane", lambda v: Plane(v, (0, 0, 1)), "point", SurfaceError, BAD_VECTORS),
    (
        "Plane",
        lambda v: Plane((0, 0, 0), v),
        "normal",
        SurfaceError,
        BAD_VECTORS + ZERO_VECTOR,
    ),
    ("FunctionSurface", lambda v: FunctionSurface(v), "phi", SurfaceError, BAD_CALLABLES),
    (
        "FunctionSurface",
        lambda v: FunctionSurface(abs, gradient=v),
        "gradient",
        SurfaceError,
        BAD_CALLABLES,
    ),
    ("FunctionSurface", lambda v: _fs(step=v), "step", SurfaceError, _numbers("> 0")),
    (
        "FunctionSurface",
        lambda v: _fs(singular_tol=v),
        "singular_tol",
        SurfaceError,
        _numbers("> 0"),
    ),
    # paths
    ("Helix", lambda v: _helix(radius=v), "radius", PathError, _numbers("> 0")),
    ("Helix", lambda v: _helix(center=v), "center", PathError, BAD_VECTORS),
    ("Helix", lambda v: _helix(axis=v), "axis", PathError, BAD_VECTORS + ZERO_VECTOR),
    ("Helix", lambda v: _helix(omega=v), "omega", PathError, _numbers("real")),
    ("Helix", lambda v: _helix(rise=v), "rise", PathError, _numbers("real")),
    ("Helix", lambda v: _helix(phase=v), "phase", PathError, _numbers("real")),
    ("Circle", lambda v: _circle(radius=v), "radius", PathError, _numbers("> 0")),
    ("Circle", lambda v: _circle(center=v), "center", PathError, BAD_VECTORS),
    (
        "Circle",
        lambda v: _circle(normal=v),
        "normal",
        PathError,
        BAD_VECTORS + ZERO_VECTOR,
    ),
    ("Circle", lambda v: _circle(omega=v), "omega", PathError, _numbers("real")),
    ("FunctionPath", lambda v: FunctionPath(v), "position", PathError, BAD_CALLABLES),
    (
        "FunctionPath",
        lambda v: _fp(velocity=v),
        "velocity",
        PathError,
        BAD_CALLABLES,
    ),
    ("FunctionPath", lambda v: _fp(step=v), "step", PathError, _numbers("> 0")),
    (
        "check_on_surface",
        lambda v: check_on_surface(paper_helix(), Cylinder(0.4), 0.0, v),
        "t1",
        PathError,
        _numbers("> 0"),
    ),
    (
        "check_on_surface",
        lambda v: check_on_surface(paper_helix(), Cylinder(0.4), 0.0, 1.0, samples=v),
        "samples",
        PathError,
        [*NOT_A_NUMBER, ("1", 1), ("a float", 10.0)],
    ),
    (
        "check_on_surface",
        lambda v: check_on_surface(v, Cylinder(0.4), 0.0, 1.0),
        "path",
        PathError,
        [("None", None), ("str", "helix"), ("dict", {"type": "helix"})],
    ),
    # the stacked constraint
    (
        "Constraint",
        lambda v: Constraint(v),  # type: ignore[arg-type]
        "surfaces",
        SurfaceError,
        [("None", None), ("number", 1.0), ("str", "cylinder"), ("empty", []), ("list", [1.0])],
    ),
    (
        "Constraint",
        lambda v: Constraint([Cylinder(0.4)], normalization=v),  # type: ignore[arg-type]
        "normalization",
        SurfaceError,
        BAD_CHOICES,
    ),
    # controller settings and gains
    *[
        (
            "ControlSettings",
            _keyword(ControlSettings, name),
            name,
            ControlError,
            _numbers(rule),
        )
        for name, rule in (
            ("kd_rate", "> 0"),
            ("Lambda", "> 0"),
            ("beta", ">= 0"),
            ("gamma", "> 0"),
            ("clik_gain", "> 0"),
            ("max_dist", "> 0"),
            ("contact_tol", "> 0"),
            ("mass_factor", "> 0"),
            ("branch_check_time", ">= 0"),
            ("branch_error", "> 0"),
        )
    ],
    (
        "ControlSettings",
        lambda v: ControlSettings(approach_rate=v),  # None means Λ
        "approach_rate",
        ControlError,
        [(label, v) for label, v in _numbers("> 0") if v is not None],
    ),
    (
        "ControlSettings",
        lambda v: ControlSettings(P=v),
        "P",
        ControlError,
        [*_numbers("> 0"), ("1", 1.0), ("2", 2.0)],
    ),
    (
        "ControlSettings",
        lambda v: ControlSettings(f_d=v),
        "f_d",
        ControlError,
        [
            *[(label, v) for label, v in NOT_A_NUMBER if label not in SEQUENCES_OK],
            ("None", None),
            ("-5 N", -5.0),
            ("a negative component", (10.0, -1.0)),
            ("a negative array entry", np.array([1.0, -2.0])),
            ("empty", []),
            ("nested", [[1.0, 2.0]]),
            ("a string inside", [1.0, "2"]),
            ("nan inside", [1.0, math.nan]),
        ],
    ),
    (
        "ControlSettings",
        lambda v: ControlSettings(Kd=v),
        "Kd",
        ControlError,
        [
            *[(label, v) for label, v in NOT_A_NUMBER if label not in SEQUENCES_OK],
            ("negative", -1.0),
            ("zero", 0.0),
            ("a negative diagonal entry", [1.0, -2.0, 3.0]),
            ("not symmetric", [[1.0, 0.5], [0.0, 1.0]]),
            ("not positive definite", [[1.0, 2.0], [2.0, 1.0]]),
            ("not square", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
            ("3-D", np.ones((2, 2, 2))),
            ("empty", []),
            ("complex matrix", np.eye(3) * 1j),
            ("strings", np.array(["1", "2", "3"])),
        ],
    ),
    (
        "ControlSettings",
        lambda v: ControlSettings(supervisor=v),
        "supervisor",
        ControlError,
        BAD_FLAGS,
    ),
    (
        "make_gains",
        lambda v: make_gains(1.0, v, 0.01, 20.0, 3),
        "Lambda",
        ControlError,
        _numbers("> 0"),
    ),
    (
        "make_gains",
        lambda v: make_gains(1.0, 10.0, v, 20.0, 3),
        "beta",
        ControlError,
        _numbers(">= 0"),
    ),
    (
        "make_gains",
        lambda v: make_gains(1.0, 10.0, 0.01, v, 3),
        "gamma",
        ControlError,
        _numbers("> 0"),
    ),
    (
        "make_gains",
        lambda v: make_gains(v, 10.0, 0.01, 20.0, 3),
        "Kd",
        ControlError,
        [
            *[(label, v) for label, v in NOT_A_NUMBER if label != "array of size 1"],
            ("wrong length", [1.0, 2.0, 3.0, 4.0]),
            ("wrong matrix", np.eye(2)),
            ("negative", -1.0),
        ],
    ),
    (
        "make_gains",
        lambda v: make_gains(1.0, 10.0, 0.01, 20.0, v),
        "n",
        ControlError,
        [*NOT_A_NUMBER, ("0", 0), ("a float", 3.0), ("10**6", 10**6)],
    ),
    *[
        (
            "ClikSettings",
            _keyword(ClikSettings, name),
            name,
            ControlError,
            _numbers(rule),
        )
        for name, rule in (("gamma", "> 0"), ("damping", ">= 0"), ("posture_gain", ">= 0"))
    ],
    # simulation settings
    *[
        (
            "SimSettings",
            _keyword(SimSettings, name),
            name,
            ScenarioError,
            _numbers(rule),
        )
        for name, rule in (
            ("duration", "> 0"),
            ("dt", "> 0"),
            ("release_tol", "> 0"),
            ("max_velocity", "> 0"),
            ("max_force", "> 0"),
            ("settle_time", ">= 0"),
        )
    ],
    *[
        (
            "SimSettings",
            _keyword(SimSettings, name),
            name,
            ScenarioError,
            BAD_CHOICES,
        )
        for name in ("integrator", "normalization")
    ],
    *[
        (
            "SimSettings",
            _keyword(SimSettings, name),
            name,
            ScenarioError,
            BAD_FLAGS,
        )
        for name in ("unilateral", "torque_limits")
    ],
    (
        "SimSettings",
        lambda v: SimSettings(baumgarte=v),  # type: ignore[arg-type]
        "baumgarte",
        ScenarioError,
        [("None", None), ("number", 50.0), ("tuple", (50.0, 50.0)), ("dict", {"alpha": 1.0})],
    ),
    (
        "Baumgarte",
        lambda v: Baumgarte(alpha=v),
        "baumgarte_alpha",
        ScenarioError,
        _numbers(">= 0"),
    ),
    (
        "Baumgarte",
        lambda v: Baumgarte(beta=v),
        "baumgarte_beta",
        ScenarioError,
        _numbers(">= 0"),
    ),
]

PARAMS = [
    pytest.param(build, value, key, error, id=f"{owner}-{key}-{label}")
    for owner, build, key, error, bad in CASES
    for label, value in bad
]


def _names(message: str, key: str) -> bool:
    """Whether ``key`` appears as a word, the way the scenario loader looks for it."""
    return re.search(rf"(?<![A-Za-z_]){re.escape(key)}(?![A-Za-z_])", message) is not None


@pytest.mark.parametrize(("build", "value", "key", "error"), PARAMS)
def test_bad_value_raises_a_bad_input_error_naming_the_key(
    build: Callable[[object], object], value: object, key: str, error: type[BadInputError]
) -> None:
    with pytest.raises(BadInputError) as info:
        build(value)
    assert isinstance(info.value, error), f"{type(info.value).__name__}: {info.value}"
    assert not isinstance(info.value, RunFailedError)
    message = str(info.value)
    assert _names(message, key), message


@pytest.mark.parametrize(
    "value", [-5, -0.1, (10.0, -1.0), [0.0, -1e-9]], ids=["-5", "-0.1", "tuple", "list"]
)
def test_negative_desired_force_is_refused_because_a_surface_only_pushes(value: object) -> None:
    with pytest.raises(ControlError, match="f_d") as info:
        ControlSettings(f_d=value)  # type: ignore[arg-type]
    assert "a surface can only push" in str(info.value)
    assert ">= 0 N" in str(info.value)


def test_valid_values_are_kept_and_normalised() -> None:
    assert ControlSettings(f_d=0).f_d == 0.0  # touching without pressing is allowed
    assert ControlSettings(f_d=[1, 2]).f_d == (1.0, 2.0)
    assert ControlSettings(f_d=np.array([3.0])).f_d == (3.0,)
    assert type(ControlSettings(Lambda=np.int64(4)).Lambda) is float
    assert ControlSettings(supervisor=np.bool_(False)).supervisor is False
    assert ControlSettings(approach_rate=None).approach_rate is None
    assert ControlSettings(beta=0).beta == 0.0
    kd = ControlSettings(Kd=[1, 2, 3]).Kd
    assert isinstance(kd, np.ndarray) and kd.dtype == float and not kd.flags.writeable
    assert ControlSettings(Kd=np.float64(5)).Kd == 5.0
    sim = SimSettings(duration=2, dt=np.float32(0.5), settle_time=0, unilateral=np.bool_(False))
    assert (sim.duration, sim.dt, sim.settle_time, sim.unilateral) == (2.0, 0.5, 0.0, False)
    assert type(sim.duration) is float and type(sim.unilateral) is bool
    assert Baumgarte(0, 0) == Baumgarte(0.0, 0.0)
    assert ClikSettings(damping=0).damping == 0.0
    assert Helix((0, 0, 0), 1, omega=-1, rise=0).omega == -1.0  # turning clockwise is fine
    assert Cylinder(np.float64(0.4), inside=np.bool_(True)).inside is True
    assert check_damping_gain(2) == 2.0


def test_kd_and_f_d_are_checked_against_the_arm_and_the_surfaces(rtr: Robot, contact: dict) -> None:
    with pytest.raises(ControlError, match=r"Kd must be a scalar, a vector of 3"):
        Scenario(**{**contact, "control": ControlSettings(supervisor=False, Kd=[1.0, 2.0])})
    with pytest.raises(ControlError, match=r"f_d must be one number or 1 numbers") as info:
        Scenario(**{**contact, "control": ControlSettings(supervisor=False, f_d=(1.0, 2.0))})
    assert "(1.0, 2.0)" in str(info.value)
    ok = Scenario(**{**contact, "control": ControlSettings(supervisor=False, Kd=[1.0, 2.0, 3.0])})
    assert ok.control.Kd.shape == (3,)


def test_user_callables_returning_garbage_raise_bad_input_errors() -> None:
    with pytest.raises(SurfaceError, match="phi returned 'abc'"):
        FunctionSurface(lambda p: "abc").phi([0.0, 0.0, 0.0])
    with pytest.raises(SurfaceError, match="distance returned"):
        FunctionSurface(lambda p: 1.0, distance=lambda p: [1.0, 2.0]).distance([0, 0, 0])
    with pytest.raises(SurfaceError, match="gradient returned"):
        FunctionSurface(lambda p: 1.0, gradient=lambda p: ["a", 0, 0]).gradient([0, 0, 0])
    with pytest.raises(PathError, match="position"):
        FunctionPath(lambda t: (10**400, 0, 0)).position(0.0)
    with pytest.raises(BadInputError, match="point p"):
        Cylinder(1.0).distance([10**400, 0, 0])
    with pytest.raises(BadInputError, match="target"):
        inverse_kinematics(load_robot("rtr"), "abc")  # type: ignore[arg-type]


def test_dict_constructors_reject_bad_values_with_the_key() -> None:
    with pytest.raises(SurfaceError, match="radius"):
        surface_from_dict({"type": "cylinder", "radius": "0.4"})
    with pytest.raises(PathError, match="omega"):
        circle = {"type": "circle", "center": [0, 0, 0], "radius": 1, "normal": [0, 0, 1]}
        path_from_dict({**circle, "omega": None})


# --- Scenario ------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def contact(rtr: Robot) -> dict[str, Any]:
    """Section 6.3's run, 1 s: on the cylinder of eq. 26, 3 m below the helix of eq. 25."""
    q0 = inverse_kinematics(rtr, np.array([0.4, 0.0, 7.0]), seed=np.array([0.0, 6.0, 2.0]))
    return {
        "robot": rtr,
        "surfaces": [Cylinder(0.4)],
        "path": paper_helix(),
        "q0": q0,
        "control": ControlSettings(supervisor=False),
        "sim": SimSettings(duration=1.0),
        "name": "paper_contact",
    }


SCENARIO_BAD: dict[str, list[tuple[str, object]]] = {
    "robot": [("None", None), ("name", "rtr"), ("number", 1)],
    "surfaces": [
        ("None", None),
        ("empty", []),
        ("bare surface", Cylinder(0.4)),
        ("str", "cylinder"),
        ("list of str", ["cylinder"]),
        ("None inside", [Cylinder(0.4), None]),
        ("dict", {"type": "cylinder"}),
    ],
    "path": [("None", None), ("str", "helix"), ("dict", {"type": "helix"}), ("a surface", Plane)],
    "q0": [
        ("None", None),
        ("str", "abc"),
        ("two numbers", [1.0, 2.0]),
        ("four numbers", np.zeros(4)),
        ("nan inside", [math.nan, 6.0, 2.0]),
        ("complex", [1j, 6.0, 2.0]),
        ("column", np.zeros((3, 1))),
        ("10**400 inside", [10**400, 6.0, 2.0]),
        ("bools", [True, False, True]),
        ("strings", ["0", "6", "2"]),
    ],
    "v0": [
        ("str", "abc"),
        ("two numbers", [1.0, 2.0]),
        ("nan inside", [math.nan, 0.0, 0.0]),
        ("nested", [[0.0, 0.0, 0.0]]),
    ],
    "control": [("None", None), ("dict", {"f_d": 1.0}), ("str", "default")],
    "sim": [("None", None), ("dict", {"dt": 1e-3}), ("str", "default")],
    "name": [
        ("None", None),
        ("number", 1),
        ("empty", ""),
        ("hidden", ".hidden"),
        ("option-like", "-x"),
        ("a slash", "a/b"),
        ("a backslash", "a\\b"),
        ("trailing newline", "run\n"),
        ("a newline inside", "ok\nrm"),
        ("a space", "a b"),
        ("non-ASCII", "é"),
        ("101 characters", "x" * 101),
    ],
    "description": [("None", None), ("number", 1), ("list", ["a"])],
    "source": [("str", "x"), ("number", 1), ("list", [1])],
}


@pytest.mark.parametrize(
    ("field", "value"),
    [
        pytest.param(field, value, id=f"{field}-{label}")
        for field, bad in SCENARIO_BAD.items()
        for label, value in bad
    ],
)
def test_scenario_rejects_a_bad_field(contact: dict[str, Any], field: str, value: object) -> None:
    if field == "path" and value is Plane:
        value = Plane((0, 0, 0), (0, 0, 1))
    with pytest.raises(ScenarioError) as info:
        Scenario(**{**contact, field: value})
    assert _names(str(info.value), field), str(info.value)


def test_scenario_accepts_and_stores_valid_fields(contact: dict[str, Any]) -> None:
    sc = Scenario(**{**contact, "q0": list(contact["q0"]), "v0": (0, 0, 0), "name": "a" * 100})
    assert isinstance(sc.surfaces, tuple)
    assert sc.q0.dtype == float and not sc.q0.flags.writeable
    assert sc.v0 is not None and sc.v0.dtype == float and not sc.v0.flags.writeable
    for name in ("x", "_x", "0.run-1", "paper_contact.v2"):
        assert Scenario(**{**contact, "name": name}).name == name


def test_contact_start_needs_the_path_on_every_surface(contact: dict[str, Any]) -> None:
    wide = Helix((0.0, 0.0, 10.0), 0.5, omega=1.0, rise=0.1)  # 0.1 m off the cylinder
    with pytest.raises(ScenarioError, match=r"path is not on surfaces\[0\]") as info:
        Scenario(**{**contact, "path": wide})
    message = str(info.value)
    assert "0.1 m away" in message and "1e-06 m" in message and "sim.duration = 1 s" in message

    # a path that leaves the surface only after the run's end (t = 2 s) is fine
    def leaving(t: float) -> tuple[float, float, float]:
        r = 0.4 + 0.1 * max(t - 2.0, 0.0)
        return (r * math.cos(t), r * math.sin(t), 10.0 + 0.1 * t)

    start = {**contact, "path": FunctionPath(leaving), "q0": _q_at(contact, 10.0)}
    Scenario(**{**start, "sim": SimSettings(duration=2.0)})
    with pytest.raises(ScenarioError, match="path is not on") as info:
        Scenario(**{**start, "sim": SimSettings(duration=3.0)})
    assert "0.1 m away at t = 3 s" in str(info.value)


def _q_at(contact: dict[str, Any], z: float) -> np.ndarray:
    return inverse_kinematics(contact["robot"], [0.4, 0.0, z], seed=np.array([0.0, z - 1, 2.0]))


def test_contact_start_needs_the_tip_on_every_surface(contact: dict[str, Any]) -> None:
    off = _q_at(contact, 7.0) + np.array([0.0, 0.0, 0.01])  # the elbow bent: tip off the cylinder
    with pytest.raises(ScenarioError, match="q0") as info:
        Scenario(**{**contact, "q0": off})
    assert "contact_tol = 1e-05 m" in str(info.value)
    # the same start is fine with a tolerance that covers it
    d = abs(Cylinder(0.4).distance(contact["robot"].tip_position(off)))
    loose = ControlSettings(supervisor=False, contact_tol=2 * d, max_dist=4 * d)
    Scenario(**{**contact, "q0": off, "control": loose})


def test_supervised_start_off_the_surface_is_fine_but_not_inside_the_solid(
    contact: dict[str, Any],
) -> None:
    rtr = contact["robot"]
    outside = inverse_kinematics(rtr, [0.6, 0.0, 7.0], seed=np.array([0.0, 6.0, 2.0]))
    Scenario(**{**contact, "q0": outside, "control": ControlSettings()})  # approach from 0.2 m
    inside = inverse_kinematics(rtr, [0.2, 0.0, 7.0], seed=np.array([0.0, 6.0, 2.0]))
    with pytest.raises(ScenarioError, match="inside the solid") as info:
        Scenario(**{**contact, "q0": inside, "control": ControlSettings()})
    assert "q0" in str(info.value) and "0.2 m behind" in str(info.value)


def test_stacked_surfaces_with_the_supervisor_are_refused_at_construction(
    contact: dict[str, Any],
) -> None:
    groove = {
        **contact,
        "surfaces": [Cylinder(0.4), Plane(point=(0, 0, 10), normal=(0, 0, -1))],
        "path": Circle(center=(0, 0, 10), radius=0.4, normal=(0, 0, 1), omega=1.0),
        "q0": _q_at(contact, 10.0),
    }
    Scenario(**groove)  # starting in contact with both: supported
    with pytest.raises(ScenarioError, match="supervisor = false"):
        Scenario(**{**groove, "control": ControlSettings(supervisor=True)})

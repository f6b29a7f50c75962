"""Shared pytest fixtures for the hybrid_force test suite."""

from __future__ import annotations

import os
import struct
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pytest

if TYPE_CHECKING:
    from hybrid_force.model.robot import Robot

REPO_ROOT = Path(__file__).resolve().parents[1]

# every kernel bound for its call site's argument types checks them at every call
# (hybrid_force._jit.entry), in this process and in the CLI's processes the tests start
os.environ["HYBRID_FORCE_CHECK_ENTRIES"] = "1"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

# --- the browser tests: Debian's Chromium through Playwright (never `playwright install`) ---
CHROMIUM = Path("/usr/bin/chromium")
BROWSER_ARGS = [
    "--no-sandbox",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


def _unavailable_reason() -> str | None:
    if not CHROMIUM.exists():
        return f"no browser at {CHROMIUM} (Debian: apt-get install chromium)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "Playwright's Python package is not installed (pip install playwright)"
    return None


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    reason = _unavailable_reason()
    if reason is not None:
        if os.environ.get("HYBRID_FORCE_CI") == "1":
            pytest.fail(f"browser tests must run in CI (HYBRID_FORCE_CI=1): {reason}")
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=str(CHROMIUM), args=BROWSER_ARGS)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def repo_root() -> Path:
    """Top folder of the source checkout (holds robots/, scenarios/, README.md)."""
    return REPO_ROOT


@pytest.fixture
def rtr_urdf() -> Path:
    """Path of the bundled RTR arm URDF in the source checkout."""
    return REPO_ROOT / "robots" / "rtr.urdf"


@pytest.fixture
def field_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A fresh cache folder for mesh parts' distance fields ($HYBRID_FORCE_CACHE), so that a
    test neither reads nor writes the user's cache."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("HYBRID_FORCE_CACHE", str(folder))
    return folder


# --- the arms most tests use: one load per test module (a Robot owns mutable Pinocchio data) ---
@pytest.fixture(scope="module")
def rtr() -> Robot:
    """The paper's RTR arm (robots/rtr.urdf), tip "tip"."""
    from hybrid_force.model.loading import load_robot

    return load_robot("rtr")


@pytest.fixture(scope="module")
def ur5() -> Robot:
    """The UR5 of example-robot-data (6 revolute joints)."""
    from hybrid_force.model.loading import load_robot

    return load_robot("ur5")


@pytest.fixture(scope="module")
def panda() -> Robot:
    """The Franka Panda of example-robot-data (7 joints; its fingers locked by the registry)."""
    from hybrid_force.model.loading import load_robot

    return load_robot("panda")


@pytest.fixture
def rng() -> np.random.Generator:
    """A random generator with a fixed seed (tests must be reproducible)."""
    return np.random.default_rng(20240611)


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) [px] from the PNG IHDR chunk; asserts the file is a complete PNG."""
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC, f"{path.name} is not a PNG"
    assert data[12:16] == b"IHDR"
    assert data[-8:-4] == b"IEND", f"{path.name} is truncated"
    return struct.unpack(">II", data[16:24])


def process_alive(pid: int) -> bool:
    """Whether process pid runs (exists and is not a zombie), read from /proc."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat", encoding="ascii") as fh:
        return fh.read().split(")")[-1].split()[0] != "Z"


# --- a model written as xacro files (tests of model sources and of sweeps) ------------------
#: A xacro macro making a thin rod link (mass [kg], length [m] along +x), for parts/rod.xacro.
ROD_MACRO = """\
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="rod" params="name length mass">
    <link name="${name}">
      <inertial>
        <origin xyz="${length / 2} 0 0"/>
        <mass value="${mass}"/>
        <inertia ixx="0" ixy="0" ixz="0" iyy="${mass * length**2 / 12}" iyz="0"
                 izz="${mass * length**2 / 12}"/>
      </inertial>
    </link>
  </xacro:macro>
</robot>
"""

#: The paper's RTR arm as xacro: link 2's length is the argument l2 (0.9 m: the bundled arm),
#: its links made by the macro of the included parts/rod.xacro (relative to the arm's file).
RTR_XACRO = """\
<?xml version="1.0"?>
<robot name="rtr" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="l2" default="0.9"/>
  <xacro:property name="l2" value="$(arg l2)"/>
  <xacro:include filename="parts/rod.xacro"/>
  <link name="world"/>
  <link name="link1"/>
  <xacro:rod name="link2" length="${l2}" mass="20"/>
  <xacro:rod name="link3" length="1.0" mass="20"/>
  <link name="tip"/>
  <joint name="q1" type="continuous"><parent link="world"/><child link="link1"/>
    <axis xyz="0 0 1"/></joint>
  <joint name="q2" type="prismatic"><parent link="link1"/><child link="link2"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="16" effort="0" velocity="100"/></joint>
  <joint name="q3" type="revolute"><parent link="link2"/><child link="link3"/>
    <origin xyz="${l2} 0 0"/><axis xyz="0 -1 0"/>
    <limit lower="-3.2" upper="3.2" effort="0" velocity="100"/></joint>
  <joint name="tip_joint" type="fixed"><parent link="link3"/><child link="tip"/>
    <origin xyz="1.0 0 0"/></joint>
</robot>
"""

#: The paper's RTR arm in MJCF (hinge, slide, hinge; capsule geoms), its tip a body "tip".
RTR_MJCF = """\
<mujoco model="rtr">
  <compiler angle="radian"/>
  <worldbody>
    <body name="link1">
      <joint name="q1" type="hinge" axis="0 0 1"/>
      <body name="link2">
        <joint name="q2" type="slide" axis="0 0 1" range="-1 16"/>
        <inertial pos="0.45 0 0" mass="20" diaginertia="0 1.35 1.35"/>
        <geom type="capsule" fromto="0 0 0 0.9 0 0" size="0.02"/>
        <body name="link3" pos="0.9 0 0">
          <joint name="q3" type="hinge" axis="0 -1 0" range="-3.2 3.2"/>
          <inertial pos="0.5 0 0" mass="20" diaginertia="0 1.6666666666666667 1.6666666666666667"/>
          <geom type="capsule" fromto="0 0 0 1 0 0" size="0.02"/>
          <body name="tip" pos="1 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture
def write_xacro_rtr() -> Callable[[Path], Path]:
    """Writes folder/rtr.urdf.xacro and folder/parts/rod.xacro; returns the arm's path."""

    def write(folder: Path) -> Path:
        (folder / "parts").mkdir(parents=True, exist_ok=True)
        (folder / "parts" / "rod.xacro").write_text(ROD_MACRO)
        path = folder / "rtr.urdf.xacro"
        path.write_text(RTR_XACRO)
        return path

    return write


# --- checks of a desired path's smoothness (tests of the paths on surfaces) ---------------------
def path_breaks(path: Any) -> np.ndarray:
    """The times [s] where a SurfacePath's p⃛ may jump: the junctions of its curve and of its
    arc-length map, and the ends of the ramps of its time law."""
    law = path.law
    ramp = min(law.ramp, 0.5 * law.duration)
    own = [0.0, ramp, law.duration - ramp, law.duration]
    arc = [law.time_at(float(ell)) for ell in path.arc.breaks]
    return np.unique(np.concatenate((path.junction_times, arc, own)))


def assert_continuous_at(path: Any, times: np.ndarray, delta: float = 1e-7) -> None:
    """p, ṗ, p̈ continuous at each time: across [t − δ, t + δ] each changes by at most 2δ times
    (twice) the largest next derivative, measured on a grid of the whole path."""
    grid = np.linspace(-1.0, path.law.duration + 1.0, 4001)
    samples = np.array([path.evaluate(t) for t in grid])
    jerk = np.abs(np.diff(samples[:, 2], axis=0)).max() / (grid[1] - grid[0])
    bounds = 2.0 * np.array([*np.abs(samples[:, 1:]).max(axis=(0, 2)), jerk])
    for t in times:
        before = np.array(path.evaluate(t - delta))
        after = np.array(path.evaluate(t + delta))
        jumps = np.abs(after - before).max(axis=1)
        assert np.all(jumps <= 2.0 * delta * bounds + 1e-13), (t, jumps, bounds)


def assert_derivatives_are_differences(
    path: Any, rng: np.random.Generator, n: int = 60, h: float = 1e-4, tol: float = 1e-6
) -> None:
    """ṗ and p̈ against central differences of p and ṗ (step h [s], error ~ h²) at n random
    times at least 3h from the breaks, where p⃛ may jump."""
    breaks = path_breaks(path)
    duration = float(breaks[-1])
    times: list[float] = []
    while len(times) < n:
        t = float(rng.uniform(-0.5, duration + 0.5))
        if np.abs(breaks - t).min() > 3.0 * h:
            times.append(t)
    for t in times:
        _, v, a = path.evaluate(t)
        p_plus, v_plus, _ = path.evaluate(t + h)
        p_minus, v_minus, _ = path.evaluate(t - h)
        np.testing.assert_allclose(v, (p_plus - p_minus) / (2.0 * h), rtol=0, atol=tol)
        np.testing.assert_allclose(a, (v_plus - v_minus) / (2.0 * h), rtol=0, atol=tol)


def point_segment_distances(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (P,) [m] of each of ``points`` (P, 3) to the nearest of the segments a–b
    ((E, 3) each), by hand: the foot's parameter along each segment clamped to [0, 1]."""
    ab = b - a
    s = np.einsum("pij,ij->pi", points[:, None, :] - a, ab) / (ab * ab).sum(axis=1)
    feet = a + np.clip(s, 0.0, 1.0)[..., None] * ab
    return np.asarray(np.linalg.norm(points[:, None, :] - feet, axis=2).min(axis=1))

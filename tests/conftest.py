"""Shared pytest fixtures for the hybrid_force test suite."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def repo_root() -> Path:
    """Top folder of the source checkout (holds robots/, scenarios/, README.md)."""
    return REPO_ROOT


@pytest.fixture
def rtr_urdf() -> Path:
    """Path of the bundled RTR arm URDF in the source checkout."""
    return REPO_ROOT / "robots" / "rtr.urdf"


@pytest.fixture
def rng() -> np.random.Generator:
    """A random generator with a fixed seed (tests must be reproducible)."""
    return np.random.default_rng(20240611)

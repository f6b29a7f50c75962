"""The version of hybrid_force, written here alone: pyproject.toml declares it dynamic and
hatchling reads it from this file (``[tool.hatch.version]``), so the installed metadata says
the same. A command reads it from here: through ``importlib.metadata`` it cost about 0.01 to
0.02 s of each command (a search of every installed package and an e-mail header parser)."""

from __future__ import annotations

__all__ = ["VERSION"]

VERSION = "0.2.0"

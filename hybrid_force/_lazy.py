"""Lazy access to the compiled kernels, so ``import hybrid_force`` does not import Numba."""

from __future__ import annotations

import importlib
from typing import Any


class LazyKernels:
    """The kernels module of one concept, imported on first attribute access (Numba: ~0.5 s).

    Each function found is stored on the instance, so later lookups cost a plain attribute
    access in the hot loop.
    """

    def __init__(self, module: str) -> None:
        self._module = module

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        value = getattr(importlib.import_module(self._module), name)
        setattr(self, name, value)
        return value

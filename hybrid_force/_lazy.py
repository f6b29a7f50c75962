"""Lazy access to the compiled kernels, so ``import hybrid_force`` does not import Numba."""

from __future__ import annotations

from types import ModuleType

_kernels: ModuleType | None = None


def kernels() -> ModuleType:
    """The module :mod:`hybrid_force._kernels`, imported on first use (Numba: about 0.5 s)."""
    global _kernels
    if _kernels is None:
        from hybrid_force import _kernels as module

        _kernels = module
    return _kernels

"""The Numba decorator shared by every ``_kernels`` module (which alone import Numba)."""

from __future__ import annotations

import numba

# error_model="numpy": a division by zero gives inf/nan (checked by the caller) instead of
# raising inside compiled code. No fastmath: the IEEE operation order is kept.
jit = numba.njit(cache=True, error_model="numpy")

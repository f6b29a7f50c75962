"""The Numba decorator shared by every ``_kernels`` module (which alone import Numba).

Why the kernels exist: the hot loop spends its time in a few hundred operations on arrays of
3 to 30 numbers; from numpy each costs about a microsecond of call overhead, far more than the
arithmetic, so the formulas are written as loops and compiled once (cached on disk). Each
``_kernels`` module sits beside the concept it computes and is imported only on first use
(:class:`hybrid_force._lazy.LazyKernels`; Numba takes about 0.5 s to import). Conventions:
outputs are preallocated arrays passed last and written in place.
"""

from __future__ import annotations

import numba

# error_model="numpy": a division by zero gives inf/nan (checked by the caller) instead of
# raising inside compiled code. No fastmath: the IEEE operation order is kept.
jit = numba.njit(cache=True, error_model="numpy")

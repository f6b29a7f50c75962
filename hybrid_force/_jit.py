"""The Numba decorator shared by every ``_kernels`` module (which alone import Numba).

Why the kernels exist: the hot loop spends its time in a few hundred operations on arrays of
3 to 30 numbers; from numpy each costs about a microsecond of call overhead, far more than the
arithmetic, so the formulas are written as loops and compiled once (cached on disk). Each
``_kernels`` module sits beside the concept it computes and is imported only on first use
(:class:`hybrid_force._lazy.LazyKernels`; Numba takes about 0.5 s to import). Conventions:
outputs are preallocated arrays passed last and written in place.

Numba is imported by the first :func:`jit`, not by this module, so that the command line can
say beforehand (:func:`own_kernels_only`) that its process compiles no other code.

A call site of the hot loop calls its kernel through :func:`entry`, the compiled code for the
argument types of that site, without Numba's dispatcher (which types every argument at every
call: about 0.05 µs an array, 13 % of a UR5 step in all).
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

import numpy as np

__all__ = ["CHECK_ENTRIES", "entry", "jit", "jit_inline", "own_kernels_only"]

F = TypeVar("F", bound=Callable[..., Any])

_decorator: Any = None  # numba.njit(...), made by the first jit()
_kernels_only = False


def jit(func: F) -> F:
    """Compile ``func`` with Numba: nopython, cached on disk, numpy's error model.

    error_model="numpy": a division by zero gives inf/nan (checked by the caller) instead of
    raising inside compiled code. No fastmath: the IEEE operation order is kept.
    """
    global _decorator
    if _decorator is None:
        import numba

        if _kernels_only:
            _load_numpy_support_without_scipy()
            _load_typing_without_cffi()
            _skip_extension_scan()
            _load_caches_without_registries()
            _type_plain_arrays_without_numpy_ma()
        _decorator = numba.njit(cache=True, error_model="numpy")
    compiled: F = _decorator(func)
    return compiled


def jit_inline(func: F) -> F:
    """:func:`jit` for a small helper of other kernels, inlined into each caller at Numba's
    IR level (``inline="always"``): no call, no reference counting of its array arguments
    (a call of a few products cost ~50 ns of it, more than the products), and the same
    operations in the same order as the loops written out."""
    jit(_no_op)  # Numba imported and set up as jit does
    import numba

    decorator: Any = numba.njit(cache=True, error_model="numpy", inline="always")
    compiled: F = decorator(func)
    return compiled


#: The environment variable that makes every :func:`entry` check its arguments' types at every
#: call (the test suite sets it: tests/conftest.py).
CHECK_ENTRIES = "HYBRID_FORCE_CHECK_ENTRIES"


def entry(kernel: F, *args: Any) -> F:
    """The compiled code of ``kernel`` for the types of ``args`` (compiled or loaded from the
    cache now), called without Numba's dispatcher.

    The dispatcher finds the compiled version for the types of a call's arguments (dtype,
    dimensions, layout, writeability of each array) at every call; the code it returns does
    not check them again. So the caller promises what the dispatcher would check: every call
    passes arguments of these same types. The hot loop's call sites pass arrays they own
    (made C-contiguous float64 by the toolkit), Pinocchio's results of fixed shapes and
    Python numbers (a float parameter is bound with a float: an int given later is
    converted, a float given to an int parameter would not be), and bind their kernels when
    they are built or at their first call. With the environment variable
    :data:`CHECK_ENTRIES` set to 1 (the test suite), the calls check the types with the
    dispatcher's own fingerprints: the first 64 calls, then every 16th (a check costs about
    0.2 µs an argument, more than the call), raising TypeError on a change. Without Numba's
    compilation (a plain function): ``kernel`` itself.

    Args:
        kernel: a kernel of :func:`jit`. args: arguments of the types of every later call.
    """
    compile_for = getattr(kernel, "compile", None)
    if compile_for is None:
        return kernel
    typeof = kernel.typeof_pyval  # type: ignore[attr-defined]
    types = tuple(typeof(a) for a in args)
    code: F = compile_for(types)
    if os.environ.get(CHECK_ENTRIES) != "1":
        return code
    from numba._dispatcher import compute_fingerprint

    def key(value: Any) -> Any:
        try:
            return compute_fingerprint(value)
        except Exception:  # (a value without the dispatcher's fast path)
            return typeof(value)

    keys = tuple(map(key, args))
    name = getattr(kernel, "__name__", repr(kernel))
    calls = [0]

    def checked(*call: Any) -> Any:
        calls[0] += 1
        if (calls[0] <= 64 or not calls[0] & 15) and tuple(map(key, call)) != keys:
            got = tuple(typeof(a) for a in call)
            raise TypeError(f"kernel {name} bound for argument types {types}, called with {got}")
        return code(*call)

    return checked  # type: ignore[return-value]


def _no_op() -> None:
    """Compiled by :func:`jit_inline` (lazily, never called) so that Numba is set up first."""


@contextlib.contextmanager
def own_kernels_only() -> Iterator[None]:
    """While open, Numba is loaded (by the first :func:`jit`) for the kernels alone.

    For processes that compile no other code than the kernels: the command line's. Five things
    Numba does by default are then skipped, each at most a change to code no kernel has:

    * its NumPy support checks at its import whether SciPy's BLAS is there, by importing
      ``scipy.linalg`` (about 0.1 s, a tenth of a short command). The answer changes only how
      np.convolve and np.correlate are compiled (a loop instead of a BLAS call); no kernel
      uses them (they use loops, np.empty, np.zeros and np.abs), and np.dot or np.linalg
      still find SciPy when first compiled;
    * on its first compilation or cache load it imports CFFI (and with it pycparser, about
      0.04 s), to recognise CFFI functions and ``ffi`` objects among a kernel's arguments; no
      kernel takes one (their arguments are arrays and numbers);
    * on its first compilation or cache load it reads the entry points of every installed
      package for Numba extensions (support for other libraries' types; about 0.02 s here,
      more where more packages are installed);
    * before each cache load it refreshes its target context: it imports and installs the
      lowering of all of Python's and NumPy's operations it supports (about 130 modules,
      0.1 to 0.2 s, the largest part of a short command after the imports), which only a
      compilation uses: code loaded from the cache is already machine code. A load then
      starts Numba's runtime (NRT, which that code calls) alone; a miss refreshes as before,
      then compiles;
    * the first time it types an argument array of a kind (dtype, dimensions, layout), its
      ``typeof`` asks whether the array is a ``numpy.ma.MaskedArray``, and numpy imports
      ``numpy.ma`` for that question (about 0.01 s); a plain ``np.ndarray`` is none, and is
      then typed without the question (the other steps as Numba's), any other array by Numba.

    A Python program that imports hybrid_force keeps Numba's defaults.
    """
    global _kernels_only
    before = _kernels_only
    _kernels_only = True
    try:
        yield
    finally:
        _kernels_only = before


def _load_numpy_support_without_scipy() -> None:
    """Import Numba's NumPy support while ``scipy.linalg.cython_blas`` is marked absent.

    A None in ``sys.modules`` makes an import of that name fail at once (Python's documented
    way to block one), so Numba records "no BLAS" instead of importing SciPy; the mark is
    removed afterwards, and a later ``import scipy.linalg`` works as usual.
    """
    name = "scipy.linalg.cython_blas"
    if "numba.np.arraymath" in sys.modules or name in sys.modules:
        return
    sys.modules[name] = None  # type: ignore[assignment]
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        if sys.modules.get(name, 0) is None:
            del sys.modules[name]


def _block_import(blocked: str, module: str) -> None:
    """Import ``module`` while ``blocked`` is marked absent (a None in ``sys.modules`` makes an
    import of that name fail at once, Python's documented way to block one); the mark is
    removed afterwards, so a later import of ``blocked`` works as usual. Nothing is done if
    either is imported already."""
    if module in sys.modules or blocked in sys.modules:
        return
    sys.modules[blocked] = None  # type: ignore[assignment]
    try:
        importlib.import_module(module)
    finally:
        if sys.modules.get(blocked, 0) is None:
            del sys.modules[blocked]


def _load_typing_without_cffi() -> None:
    """Import Numba's CFFI support while ``cffi`` is marked absent: it then records "CFFI not
    available" (``cffi_utils.SUPPORTED = False``), as on an installation without CFFI, instead
    of importing CFFI and pycparser (see :func:`own_kernels_only`)."""
    _block_import("cffi", "numba.core.typing.cffi_utils")


def _load_caches_without_registries() -> None:
    """Let a cache load skip Numba's target refresh (see :func:`own_kernels_only`): the
    pinned 0.68 series' ``Cache.load_overload`` refreshes, then loads; here the runtime is
    started, the load tried, and only a miss goes through Numba's own method (refresh, load
    again, then compile). Once per process."""
    from numba.core import caching
    from numba.core.runtime import rtsys

    full = caching.Cache.load_overload
    if getattr(full, "_without_registries", False):
        return

    def load_overload(self: Any, sig: Any, target_context: Any) -> Any:
        rtsys.initialize(target_context)
        data = None
        with self._guard_against_spurious_io_errors():
            data = self._load_overload(sig, target_context)
        return data if data is not None else full(self, sig, target_context)

    load_overload._without_registries = True  # type: ignore[attr-defined]
    caching.Cache.load_overload = load_overload  # type: ignore[method-assign]


def _skip_extension_scan() -> None:
    """Mark Numba's extensions as loaded, so it does not look for them (see
    :func:`own_kernels_only`). Numba keeps the mark in its ``entrypoints`` module (the pinned
    0.68 series); without it, the scan is left to happen."""
    from numba.core import entrypoints

    if getattr(entrypoints, "_already_initialized", None) is False:
        entrypoints._already_initialized = True


def _type_plain_arrays_without_numpy_ma() -> None:
    """Let Numba type a plain ``np.ndarray`` argument without importing ``numpy.ma`` (see
    :func:`own_kernels_only`). The pinned 0.68 series' ``typeof`` of an ndarray refuses a
    masked array (``isinstance(val, np.ma.MaskedArray)``: numpy imports numpy.ma on that first
    access), then reads the dtype, layout and writeability; an array whose type is exactly
    ``np.ndarray`` is no masked array, and takes those last steps alone here. Anything else
    (a subclass, a masked array, a dtype Numba does not support) goes to Numba's own function
    with its own errors. Once per process."""
    from numba.core import errors, types
    from numba.core.typing.typeof import typeof_impl
    from numba.np import numpy_support

    numbas = typeof_impl.dispatch(np.ndarray)
    if getattr(numbas, "_plain_arrays_first", False):
        return

    def typeof_array(val: Any, c: Any) -> Any:
        if type(val) is not np.ndarray:
            return numbas(val, c)
        try:
            dtype = numpy_support.from_dtype(val.dtype)
        except errors.NumbaNotImplementedError:
            return numbas(val, c)
        layout = numpy_support.map_layout(val)
        return types.Array(dtype, val.ndim, layout, readonly=not val.flags.writeable)

    typeof_array._plain_arrays_first = True  # type: ignore[attr-defined]
    typeof_impl.register(np.ndarray)(typeof_array)

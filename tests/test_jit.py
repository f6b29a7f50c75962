"""The kernels' entry points (hybrid_force._jit.entry) and the commands they are given."""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
import pytest

from hybrid_force._jit import CHECK_ENTRIES, entry
from hybrid_force.control.laws.base import Command
from hybrid_force.errors import ControlError

RNG = np.random.default_rng(20261203)


@numba.njit
def take_into(values: np.ndarray, index: np.ndarray, out: np.ndarray) -> None:
    """out[j] = values[index[j]]: a kernel of three arrays of three types."""
    for j in range(index.shape[0]):
        out[j] = values[index[j]]


def _inputs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    values = RNG.normal(size=12)
    index = np.array([0, 3, 4, 11])
    return values, index, np.zeros(index.size)


def test_entry_computes_what_the_dispatcher_and_numpy_compute() -> None:
    values, index, out = _inputs()
    take = entry(take_into, values, index, out)
    take(values, index, out)
    np.testing.assert_array_equal(out, values[index])  # numpy's fancy indexing
    again = np.zeros_like(out)
    take_into(values, index, again)  # through the dispatcher
    np.testing.assert_array_equal(out, again)


def test_unchecked_entry_is_the_compiled_code(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(CHECK_ENTRIES, raising=False)
    values, index, out = _inputs()
    take = entry(take_into, values, index, out)
    dispatcher: Any = take_into
    types = tuple(dispatcher.typeof_pyval(a) for a in (values, index, out))
    assert take is dispatcher.overloads[types].entry_point
    take(values, index, out)
    np.testing.assert_array_equal(out, values[index])


@pytest.mark.parametrize(
    "change",
    [
        lambda v: v.astype(np.float32),  # another dtype
        lambda v: np.repeat(v, 2)[::2],  # strided: another layout, the same values
        lambda v: v.reshape(3, 4),  # another number of dimensions
        lambda v: np.require(v, requirements=["C"]).copy().view(),  # the same type: no error
    ],
)
def test_checked_entry_refuses_other_argument_types(change) -> None:  # type: ignore[no-untyped-def]
    values, index, out = _inputs()
    take = entry(take_into, values, index, out)
    other = change(values)
    same = other.dtype == values.dtype and other.ndim == 1 and other.flags.c_contiguous
    if same:
        take(other, index, out)
        np.testing.assert_array_equal(out, values[index])
        return
    with pytest.raises(TypeError, match="take_into bound for argument types"):
        take(other, index, out)


def test_checked_entry_checks_every_16th_call_after_the_first_64() -> None:
    values, index, out = _inputs()
    take = entry(take_into, values, index, out)
    for _ in range(64):
        take(values, index, out)
    bad = values.astype(np.float32)
    # calls 65..79 are not checked (and a float32 array is not read by them here: the
    # kernel is given the right one); call 80 is
    for _ in range(15):
        take(values, index, out)
    with pytest.raises(TypeError):
        take(bad, index, out)


def test_a_plain_function_is_its_own_entry() -> None:
    def plain(x: np.ndarray) -> float:
        return float(x[0])

    assert entry(plain, np.zeros(1)) is plain


def test_a_float_parameter_bound_with_a_float(monkeypatch: pytest.MonkeyPatch) -> None:
    """dt bound as a float: unchecked, an int dt is converted (F += f dt by hand); checked,
    it is a changed type."""
    from hybrid_force.control import _kernels as ck

    # the steady pack [e_q (n = 3), e_F, f_d, F, F_d (k = 2 each)]
    pack = np.zeros(3 + 4 * 2)
    pack[3 + 2 : 3 + 4] = [4.0, 6.0]  # f_d
    f = np.array([1.0, 2.0])
    checked = entry(ck.accumulate_steady, pack, f, 0.5)
    with pytest.raises(TypeError):
        checked(pack, f, 2)
    monkeypatch.delenv(CHECK_ENTRIES)
    unchecked = entry(ck.accumulate_steady, pack, f, 0.5)
    unchecked(pack, f, 2)
    np.testing.assert_array_equal(pack[7:9], [2.0, 4.0])  # F = f dt
    np.testing.assert_array_equal(pack[9:11], [8.0, 12.0])  # F_d = f_d dt
    np.testing.assert_array_equal(pack[3:5], [-6.0, -8.0])  # e_F = F − F_d


def test_a_command_is_made_c_contiguous_float64() -> None:
    u = np.arange(12.0)[::2]  # strided view
    B = np.asfortranarray(RNG.normal(size=(6, 2)))
    cmd = Command(u, B)
    assert cmd.u0.flags.c_contiguous and cmd.B is not None and cmd.B.flags.c_contiguous
    np.testing.assert_array_equal(cmd.u0, u)
    np.testing.assert_array_equal(cmd.B, B)
    ints = Command(np.arange(6), None)
    assert ints.u0.dtype == np.float64 and ints.B is None


def test_a_command_keeps_a_laws_own_buffers() -> None:
    buffer = np.zeros(6 + 6)
    u0, B = buffer[:6], buffer[6:].reshape(6, 1)
    cmd = Command(u0, B)
    assert cmd.u0 is u0 and cmd.B is B  # the law writes them in place at every call


@pytest.mark.parametrize(("u0", "B"), [(np.zeros((6, 1)), None), (np.zeros(6), np.zeros(6))])
def test_a_command_of_the_wrong_dimensions_is_refused(u0: np.ndarray, B: np.ndarray) -> None:
    with pytest.raises(ControlError, match="a command's"):
        Command(u0, B)

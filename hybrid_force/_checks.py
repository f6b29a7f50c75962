"""Checks of user-given values shared by the public constructors (surfaces, paths, settings).

Each check returns the value in its canonical form (a float, a bool, a float64 array) or
raises the given :class:`~hybrid_force.errors.BadInputError` subclass with a message
``"<what> must be <what is valid>, got <value> (<type>)"``: ``what`` names the parameter the
way the caller wants it shown (``"Cylinder: parameter 'radius'"``, ``"sim.dt"``), so that the
scenario loader, which finds the TOML key in the message, can point at the right key.

What counts as a number: a Python or numpy integer or float (``numbers.Real``), but not a
bool (``True`` is not a gain), not a complex, not a string, not an array (even of size 1),
and not an integer too large for a float (``10**400``). Arrays must hold real numbers
(integer or float dtype: bools, complex, strings, ``None`` and ragged nestings are refused).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterable
from typing import NoReturn

import numpy as np

from hybrid_force.errors import BadInputError

__all__ = [
    "array",
    "flag",
    "function",
    "integer",
    "number",
    "one_of",
    "shown",
    "suggested",
]

ErrorType = type[BadInputError]


def shown(value: object) -> str:
    """A short readable form of a bad value, with its type when that is what is wrong."""
    if isinstance(value, np.ndarray):
        text = np.array2string(value, precision=6, separator=", ", threshold=12)
        text = f"array({text}, shape {value.shape}, dtype {value.dtype})"
    else:
        text = repr(value)
    if len(text) > 80:
        text = text[:77] + "..."
    if isinstance(value, bool) or not isinstance(value, float | int | list | tuple | np.ndarray):
        text += f" ({type(value).__name__})"
    return text


def suggested(value: float, accepted: Callable[[float], bool]) -> str:
    """``value`` printed with the fewest digits (≥ 4) whose text, copied back, is ``accepted``.

    A suggestion in a message is only useful if the value it prints is accepted: 1000/3 Hz
    shown as ``333.333`` would be refused again. Falls back to ``repr`` (the exact float)."""
    if not math.isfinite(value) or value == 0.0:
        return repr(value)
    for digits in range(4, 18):
        # the nearest text first, then its neighbours at this many digits (a bound that
        # rounds to the wrong side is shown one unit of the last digit further out)
        scale = 10.0 ** (math.floor(math.log10(abs(value))) - digits + 1)
        for candidate in (
            value,
            math.ceil(value / scale) * scale,
            math.floor(value / scale) * scale,
        ):
            text = f"{candidate:.{digits}g}"
            if accepted(float(text)):
                return text
    return repr(value)


def _fail(
    error: ErrorType,
    what: str,
    valid: str,
    value: object,
    choices: Iterable[str] | None = None,
) -> NoReturn:
    raise error(f"{what} must be {valid}, got {shown(value)}", value=value, choices=choices)


def _rule(minimum: float | None, strict: bool, maximum: float | None, unit: str) -> str:
    if minimum == 0 and strict and maximum is None:
        text = "a positive finite number"
    elif minimum is not None and maximum is not None:
        text = f"a finite number in {'(' if strict else '['}{minimum:g}, {maximum:g})"
    elif minimum is not None:
        text = f"a finite number {'>' if strict else '>='} {minimum:g}"
    else:
        text = "a finite real number"
    return f"{text} [{unit}]" if unit else text


def number(
    value: object,
    what: str,
    error: ErrorType,
    *,
    minimum: float | None = None,
    strict: bool = False,
    maximum: float | None = None,
    unit: str = "",
) -> float:
    """``value`` as a finite float, optionally ≥ (``strict``: >) ``minimum`` and < ``maximum``.

    Args:
        value: the user's value.
        what: how the message names the parameter.
        error: the BadInputError subclass to raise.
        minimum, strict, maximum: the valid range; ``maximum`` is always excluded.
        unit: the unit shown in the message (e.g. "m", "1/s").
    """
    valid = _rule(minimum, strict, maximum, unit)
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        _fail(error, what, valid, value)
    try:
        out = float(value)
    except OverflowError:
        _fail(error, what, valid + " (this one does not fit in a float)", value)
    if not math.isfinite(out):
        _fail(error, what, valid, value)
    if minimum is not None and (out <= minimum if strict else out < minimum):
        _fail(error, what, valid, value)
    if maximum is not None and out >= maximum:
        _fail(error, what, valid, value)
    return out


def integer(
    value: object, what: str, error: ErrorType, *, minimum: int, maximum: int | None = None
) -> int:
    """``value`` as a Python int in [minimum, maximum] (Python or numpy integer, not a bool)."""
    valid = (
        f"an integer >= {minimum}" if maximum is None else f"an integer in [{minimum}, {maximum}]"
    )
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Integral):
        _fail(error, what, valid, value)
    out = int(value)
    if out < minimum or (maximum is not None and out > maximum):
        _fail(error, what, valid, value)
    return out


def flag(value: object, what: str, error: ErrorType) -> bool:
    """``value`` as a bool: only True or False (Python or numpy), never a truthy 1 or "yes"."""
    if not isinstance(value, bool | np.bool_):
        _fail(error, what, "True or False", value)
    return bool(value)


def one_of(value: object, what: str, error: ErrorType, choices: Iterable[str]) -> str:
    """``value`` if it is one of the strings ``choices`` (listed in the message otherwise)."""
    options = tuple(choices)
    if not isinstance(value, str) or value not in options:
        _fail(error, what, "one of " + ", ".join(repr(c) for c in options), value, options)
    return value


def array(value: object, what: str, error: ErrorType, *, valid: str) -> np.ndarray:
    """``value`` as a new float64 array of finite real numbers (any shape: the caller checks it).

    ``valid`` describes what the caller expects (e.g. "3 finite numbers [m]") for the message.
    Refused: strings, None, mappings, ragged nestings, bool / complex / object / string dtypes
    (which is where a ``10**400`` or a ``None`` inside a list ends up), non-finite entries.
    """
    if value is None or isinstance(value, str | bytes | dict):
        _fail(error, what, valid, value)
    try:
        out = np.array(value)
    except (TypeError, ValueError, OverflowError):  # ragged nestings and the like
        _fail(error, what, valid, value)
    if out.dtype.kind not in "iuf":
        _fail(error, what, f"{valid} (real numbers, not dtype {out.dtype})", value)
    out = out.astype(np.float64)
    if not np.all(np.isfinite(out)):
        _fail(error, what, f"{valid}, without non-finite entries (nan, inf)", value)
    return out


def function(value: object, what: str, error: ErrorType, *, valid: str) -> Callable[..., object]:
    """``value`` if it is callable (a function, a lambda, an object with ``__call__``)."""
    if not callable(value):
        _fail(error, what, valid, value)
    return value

"""A control law's own signals in a run's result: an (N, m) array and its m column names.

A law may log signals of its own at every sample (parameter estimates, an admittance state)
through the optional hook of :class:`~hybrid_force.control.laws.base.Law`: ``log_names()`` and
``log_source()`` (the law's own array and where its signals are in it). The simulator stores
them as ``Result.law_log`` (N, m) and their names as ``meta["law_log_names"]``; a law without
the hook logs nothing (m = 0), and so does a result file written before the log existed.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hybrid_force.errors import BadInputError

__all__ = ["NAMES_KEY", "check_law_log", "law_log_names"]

#: The key of ``Result.meta`` that names the columns of ``Result.law_log``.
NAMES_KEY = "law_log_names"


def law_log_names(meta: Mapping[str, Any]) -> tuple[str, ...]:
    """The names of the law's logged signals in a result's meta (empty when it logged none)."""
    names = meta.get(NAMES_KEY) or []
    if not isinstance(names, list) or not all(isinstance(x, str) for x in names):
        raise BadInputError(
            f"Result meta '{NAMES_KEY}' must be a list of strings (one per column of law_log), "
            f"got {names!r}"
        )
    return tuple(names)


def check_law_log(value: Any, n_samples: int, meta: Mapping[str, Any]) -> np.ndarray:
    """The law's log as a new read-only float64 (N, m) array, m = len(meta's names).

    Args:
        value: (N, m) real numbers, or None: no log (an (N, 0) array).
        n_samples: N. meta: the result's meta (its ``law_log_names``).

    Raises:
        BadInputError: not real numbers, or names that are not a list of strings;
        BadInputError: a shape other than (N, m).
    """
    names = law_log_names(meta)
    if value is None:
        value = np.zeros((n_samples, 0))
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        raise BadInputError(
            f"Result array 'law_log' must hold real numbers (float64), got dtype {arr.dtype}"
        )
    if arr.shape != (n_samples, len(names)):
        raise BadInputError(
            f"Result array 'law_log' must have shape (N, m) = ({n_samples}, {len(names)}), one "
            f"column per name of meta['{NAMES_KEY}'], got shape {tuple(arr.shape)}"
        )
    out = np.array(arr, dtype=np.float64, copy=True)
    out.setflags(write=False)
    return out

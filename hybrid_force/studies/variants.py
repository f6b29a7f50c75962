"""The variants of a sweep: a grid and random samples expanded into overrides, with stable ids.

A variant is a dict of overrides ``"table.key"`` → value (the keys of ``hybrid-force run
--set``); its run id is a hash of its sorted parameters, so a sweep can be resumed. The
``--grid``/``--random`` option texts of the command line are parsed here too.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hybrid_force.errors import BadInputError
from hybrid_force.scenario._tables import MAX_NESTING
from hybrid_force.scenario.overrides import parse_override

__all__ = ["MAX_RUNS", "expand", "parse_grid", "parse_random", "run_id", "split_values"]

MAX_RUNS = 100_000
"""Most variants one sweep may have (the grid sizes' product × samples; values of one --grid).

Larger sweeps are refused before anything is expanded or run: split them into several sweeps.
"""


def _canonical(value: Any) -> Any:
    """A JSON-able canonical form of a parameter value (numpy scalars → Python numbers)."""
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (bool, int, str)) or value is None:
        return value
    if isinstance(value, float):
        return value
    return str(value)


def run_id(params: Mapping[str, Any]) -> str:
    """Stable id of a variant: the first 16 hex digits of the SHA-1 of its sorted-key JSON.

    Independent of the order of the keys, of the process and of the machine; numpy scalars
    hash like the equal Python numbers. (1 and 1.0 differ: ``{"a": 1}`` ≠ ``{"a": 1.0}``.)
    """
    text = json.dumps(
        {str(k): _canonical(v) for k, v in params.items()},
        sort_keys=True,
        separators=(",", ":"),
        allow_nan=True,
    )
    return hashlib.sha1(text.encode("utf-8")).hexdigest()[:16]


def _check_key(key: str, option: str) -> None:

    table, dot, name = key.partition(".")
    if not (dot and table and name):
        raise BadInputError(
            f"{option} key {key!r:.80} must be of the form table.key (e.g. control.Lambda)"
        )
    parts = key.count(".") + 1
    if parts > MAX_NESTING:  # each part nests a table: copying the variant would recurse
        raise BadInputError(
            f"{option} key {key[:60]!r}... has {parts} parts, more than a scenario's tables "
            f"nest (MAX_NESTING = {MAX_NESTING}, docs/scenarios.md)"
        )


def expand(
    grid: Mapping[str, Sequence[Any]],
    random: Mapping[str, tuple[float, float]],
    samples: int,
    seed: int,
) -> list[dict[str, Any]]:
    """Expand a grid and random ranges into the list of variants (dicts of overrides).

    Args:
        grid: ``"table.key"`` → list of values. Variants are the Cartesian product, in the order
            of the keys as given, the last key varying fastest.
        random: ``"table.key"`` → (lo, hi): uniform samples in [lo, hi). Drawn with
            ``numpy.random.default_rng(seed)``, a (samples, m) matrix of the keys in sorted
            order (so the draws do not depend on the order of the options); the SAME samples are
            combined with every grid point (common random numbers: the grid effect is not
            confounded with sampling noise). Ignored when empty.
        samples: number of random samples per grid point (≥ 1 when ``random`` is given; not used
            otherwise).
        seed: seed of the random generator.

    Returns:
        ``len(product) × samples`` dicts (grid keys first, then random keys), grid-major.
        An empty grid and no random ranges give one variant, ``{}`` (the scenario as is).

    Raises:
        BadInputError: a key not of the form table.key, a key both in grid and random, an empty
            value list, a value listed twice, a range with lo > hi or not finite, samples < 1,
            more than :data:`MAX_RUNS` variants (checked before anything is expanded).
    """

    for key, values in grid.items():
        _check_key(key, "--grid")
        if len(values) == 0:
            raise BadInputError(f"--grid {key} has no values")
        if len(values) > MAX_RUNS:
            raise BadInputError(
                f"--grid {key} lists {len(values)} values; at most {MAX_RUNS} (MAX_RUNS) are "
                "allowed"
            )
    if random and (isinstance(samples, bool) or not isinstance(samples, int) or samples < 1):
        raise BadInputError(f"--samples must be a positive integer with --random, got {samples!r}")
    n_runs = math.prod(len(values) for values in grid.values()) * (samples if random else 1)
    if n_runs > MAX_RUNS:
        sizes = [f"--grid {key}: {len(values)} values" for key, values in grid.items()]
        if random:
            sizes.append(f"--samples {samples}")
        raise BadInputError(
            f"the sweep would have {n_runs} runs ({' × '.join(sizes)}); at most {MAX_RUNS} "
            "(MAX_RUNS) are allowed: split it into several sweeps, each with its own --out"
        )
    for key, values in grid.items():
        seen: set[str] = set()
        for v in values:
            text = json.dumps(_canonical(v), sort_keys=True)
            if text in seen:
                raise BadInputError(f"--grid {key} lists the value {v!r} twice")
            seen.add(text)
    both = sorted(set(grid) & set(random))
    if both:
        raise BadInputError(f"{', '.join(both)} is given both as --grid and as --random")
    for key, rng_range in random.items():
        _check_key(key, "--random")
        try:
            lo, hi = (float(x) for x in rng_range)
        except (TypeError, ValueError) as exc:
            raise BadInputError(f"--random {key} must be a pair lo:hi, got {rng_range!r}") from exc
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise BadInputError(f"--random {key}={lo}:{hi} needs finite lo <= hi")
    points = [dict(zip(grid, combo, strict=True)) for combo in itertools.product(*grid.values())]
    if not random:
        return [{k: _canonical(v) for k, v in p.items()} for p in points]
    keys = sorted(random)
    gen = np.random.default_rng(seed)
    unit = gen.random((samples, len(keys)))  # (samples, m) in [0, 1)
    lows = np.array([float(random[k][0]) for k in keys])
    highs = np.array([float(random[k][1]) for k in keys])
    draws = lows + unit * (highs - lows)
    order = [k for k in random]  # column order of the rows: as given
    out: list[dict[str, Any]] = []
    for p in points:
        for row in draws:
            sample = {k: float(row[keys.index(k)]) for k in order}
            out.append({**{k: _canonical(v) for k, v in p.items()}, **sample})
    return out


def split_values(text: str) -> list[str]:
    """Split ``"v1,v2,[1,2],'a,b'"`` at the commas that are not inside brackets or quotes."""
    parts: list[str] = []
    depth = 0
    quote: str | None = None
    current: list[str] = []
    for ch in text:
        if quote is not None:
            current.append(ch)
            if ch == quote:
                quote = None
            continue
        if ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append("".join(current).strip())
            current = []
            continue
        current.append(ch)
    parts.append("".join(current).strip())
    return parts


def parse_grid(items: Sequence[str]) -> dict[str, list[Any]]:
    """``--grid`` options (``table.key=v1,v2,...``, TOML values) → ``{key: [values]}``."""

    grid: dict[str, list[Any]] = {}
    for item in items:
        key, sep, values = item.partition("=")
        key = key.strip()
        if not sep or not key or not values.strip():
            raise BadInputError(f"--grid {item!r} must be table.key=v1,v2,...")
        if key in grid:
            raise BadInputError(f"--grid {key} is given twice; list all its values in one option")
        texts = split_values(values)
        if len(texts) > MAX_RUNS:
            raise BadInputError(
                f"--grid {key} lists {len(texts)} values; at most {MAX_RUNS} (MAX_RUNS) are allowed"
            )
        parsed = []
        for text in texts:
            if not text:
                raise BadInputError(f"--grid {item!r} has an empty value")
            parsed.append(parse_override(f"{key}={text}")[1])
        grid[key] = parsed
    return grid


def parse_random(items: Sequence[str]) -> dict[str, tuple[float, float]]:
    """``--random`` options (``table.key=lo:hi``) → ``{key: (lo, hi)}``."""
    out: dict[str, tuple[float, float]] = {}
    for item in items:
        key, sep, rng = item.partition("=")
        key = key.strip()
        lo_text, colon, hi_text = rng.partition(":")
        try:
            if not (sep and key and colon):
                raise ValueError
            lo, hi = float(lo_text), float(hi_text)
        except ValueError:
            raise BadInputError(
                f"--random {item!r} must be table.key=lo:hi (two numbers)"
            ) from None
        if key in out:
            raise BadInputError(f"--random {key} is given twice")
        out[key] = (lo, hi)
    return out

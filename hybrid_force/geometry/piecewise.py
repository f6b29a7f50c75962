"""Piecewise polynomial curves γ(σ) of degree ≤ 5, with values in one or more columns.

A :class:`PiecewiseCurve` holds pieces joined at breakpoints; the paths on surfaces
(:mod:`.surface_path`) use one in the surface coordinates (u, v) and one for the parameter as
a function of arc length (:mod:`.arc_length`). The pieces are made by:

* :func:`natural_cubic_spline` – the C² interpolating cubic spline through points at given
  parameters, with γ'' = 0 at both ends (the spline of least ∫‖γ''‖² through the points);
* :func:`line_piece` – a straight piece, γ'' = 0;
* :func:`blend_piece` – the quintic Hermite piece from (P0, D0, A0) to (P1, D1, A1), value,
  first and second derivative at both ends: pieces that agree on them at their junctions make
  a C² curve (joined to straight pieces with A = 0, for instance).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field

import numpy as np

__all__ = ["PiecewiseCurve", "blend_piece", "line_piece", "natural_cubic_spline"]

DEGREE = 5
"""Highest degree of a piece; every piece stores DEGREE + 1 coefficients."""


@dataclass(frozen=True)
class PiecewiseCurve:
    """γ(σ) = Σ_j coeffs[k, j] (σ − breaks[k])^j on [breaks[k], breaks[k + 1]].

    Attributes:
        breaks: (m + 1,) increasing parameters of the junctions.
        coeffs: (m, DEGREE + 1, d) coefficients, lowest order first, of the d columns.
    """

    breaks: np.ndarray
    coeffs: np.ndarray
    _starts: list[float] = field(init=False, repr=False, compare=False)
    _table: list[list[list[float]]] = field(init=False, repr=False, compare=False)
    _first: float = field(init=False, repr=False, compare=False)
    _last: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_starts", self.breaks[:-1].tolist())
        object.__setattr__(self, "_table", self.coeffs.tolist())
        object.__setattr__(self, "_first", float(self.breaks[0]))
        object.__setattr__(self, "_last", float(self.breaks[-1]))
        for array in (self.breaks, self.coeffs):
            array.setflags(write=False)

    @classmethod
    def join(cls, lengths: list[float], pieces: list[np.ndarray] | np.ndarray) -> PiecewiseCurve:
        """Pieces (each (DEGREE + 1, d) in its local parameter) laid end to end from σ = 0."""
        breaks = np.concatenate(([0.0], np.cumsum(lengths)))
        return cls(breaks, np.array(pieces, dtype=float))

    @property
    def length(self) -> float:
        """σ at the end of the last piece."""
        return float(self.breaks[-1])

    def evaluate(self, sigma: float) -> tuple[list[float], list[float], list[float]]:
        """(γ, γ', γ'') at σ, each d floats; σ is clamped to [breaks[0], breaks[-1]].

        Plain Python floats (Horner's rule): this runs at every step of a simulation.
        """
        starts = self._starts
        k = max(0, min(bisect.bisect_right(starts, sigma) - 1, len(starts) - 1))
        x = min(max(sigma, self._first), self._last) - starts[k]
        c0, c1, c2, c3, c4, c5 = self._table[k]
        g, g1, g2 = [], [], []
        for a0, a1, a2, a3, a4, a5 in zip(c0, c1, c2, c3, c4, c5, strict=True):
            g.append((((((a5 * x + a4) * x + a3) * x + a2) * x + a1) * x) + a0)
            g1.append(((((5.0 * a5 * x + 4.0 * a4) * x + 3.0 * a3) * x + 2.0 * a2) * x) + a1)
            g2.append((((20.0 * a5 * x + 12.0 * a4) * x + 6.0 * a3) * x) + 2.0 * a2)
        return g, g1, g2

    def sample_piece(self, k: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(γ, γ', γ'') of piece k at local parameters x (N,): three (N, d) arrays."""
        c = self.coeffs[k]
        j = np.arange(DEGREE + 1)
        powers = x[:, None] ** j  # (N, 6)
        slopes = j[1:] * powers[:, :DEGREE]  # d/dx of x^j, j = 1..5
        bends = (j[2:] * j[1:-1]) * powers[:, : DEGREE - 1]  # d²/dx², j = 2..5
        return powers @ c, slopes @ c[1:], bends @ c[2:]


def natural_cubic_spline(knots: np.ndarray, points: np.ndarray) -> PiecewiseCurve:
    """The C² cubic spline through ``points`` (n, d) at increasing ``knots`` (n,), n ≥ 2, with
    γ'' = 0 at the first and last knot.

    The second derivatives M at the knots solve the tridiagonal system
    h_{i−1} M_{i−1} + 2(h_{i−1} + h_i) M_i + h_i M_{i+1} = 6 (s_i − s_{i−1}), with h_i the knot
    spacings and s_i the chord slopes, M_0 = M_{n−1} = 0 (diagonally dominant: solved without
    pivoting). Two points give a straight line.
    """
    x = np.asarray(knots, dtype=float)
    y = np.asarray(points, dtype=float)
    h = np.diff(x)
    slope = np.diff(y, axis=0) / h[:, None]
    n = x.shape[0]
    m = np.zeros(y.shape)
    if n > 2:
        diag = 2.0 * (h[:-1] + h[1:])
        rhs = 6.0 * np.diff(slope, axis=0)
        for i in range(1, n - 2):  # forward elimination of the sub-diagonal h[i]
            w = h[i] / diag[i - 1]
            diag[i] -= w * h[i]
            rhs[i] -= w * rhs[i - 1]
        inner = np.empty_like(rhs)
        inner[-1] = rhs[-1] / diag[-1]
        for i in range(n - 4, -1, -1):
            inner[i] = (rhs[i] - h[i + 1] * inner[i + 1]) / diag[i]
        m[1:-1] = inner
    coeffs = np.zeros((n - 1, DEGREE + 1, y.shape[1]))
    coeffs[:, 0] = y[:-1]
    coeffs[:, 1] = slope - h[:, None] * (2.0 * m[:-1] + m[1:]) / 6.0
    coeffs[:, 2] = m[:-1] / 2.0
    coeffs[:, 3] = (m[1:] - m[:-1]) / (6.0 * h[:, None])
    return PiecewiseCurve(x.copy(), coeffs)


def line_piece(start: np.ndarray, slope: np.ndarray) -> np.ndarray:
    """The straight piece γ(x) = start + slope·x: (DEGREE + 1, d) coefficients."""
    out = np.zeros((DEGREE + 1, np.shape(start)[0]))
    out[0], out[1] = start, slope
    return out


def blend_piece(
    p0: np.ndarray,
    d0: np.ndarray,
    p1: np.ndarray,
    d1: np.ndarray,
    length: float | np.ndarray,
    a0: np.ndarray | float = 0.0,
    a1: np.ndarray | float = 0.0,
) -> np.ndarray:
    """The quintic with value p0, first derivative d0 and second a0 at x = 0, and p1, d1, a1 at
    x = ``length``: (DEGREE + 1, d) coefficients in x (each argument (d,) or a number), or
    (..., DEGREE + 1, d) for many pieces at once (``length`` (...,), the others (..., d)).

    In s = x / length it is p0 H0 + p1 H5 + L (d0 H1 + d1 H4) + L² (a0 H2 + a1 H3), L = length,
    with the quintic Hermite basis H0 = 1 − 10s³ + 15s⁴ − 6s⁵, H5 = 1 − H0,
    H1 = s − 6s³ + 8s⁴ − 3s⁵, H4 = −4s³ + 7s⁴ − 3s⁵, H2 = (s² − 3s³ + 3s⁴ − s⁵) / 2,
    H3 = (s³ − 2s⁴ + s⁵) / 2.
    """
    big_l = np.asarray(length, dtype=float)[..., None]  # broadcasts against the columns
    start = np.asarray(p0, dtype=float)
    jump = np.asarray(p1, dtype=float) - start
    a, b = big_l * np.asarray(d0, dtype=float), big_l * np.asarray(d1, dtype=float)
    c = 0.5 * big_l**2 * np.asarray(a0, dtype=float) * np.ones_like(start)
    e = 0.5 * big_l**2 * np.asarray(a1, dtype=float) * np.ones_like(start)
    in_s = np.stack(
        [
            start * np.ones_like(a),
            a,
            c,
            10.0 * jump - 6.0 * a - 4.0 * b - 3.0 * c + e,
            -15.0 * jump + 8.0 * a + 7.0 * b + 3.0 * c - 2.0 * e,
            6.0 * jump - 3.0 * a - 3.0 * b - c + e,
        ],
        axis=-2,
    )
    return in_s / big_l[..., None] ** np.arange(DEGREE + 1)[:, None]

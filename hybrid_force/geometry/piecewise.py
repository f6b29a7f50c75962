"""Piecewise polynomial curves γ(σ) in the plane of two surface coordinates (u, v).

A :class:`PiecewiseCurve` holds pieces of degree ≤ 5 joined at breakpoints; the paths on
surfaces (:mod:`.surface_path`) map it through a chart. The pieces are made by:

* :func:`natural_cubic_spline` – the C² interpolating cubic spline through points at given
  parameters, with γ'' = 0 at both ends (the spline of least ∫‖γ''‖² through the points);
* :func:`line_piece` – a straight piece, γ'' = 0;
* :func:`blend_piece` – the quintic Hermite piece from (P0, D0, γ'' = 0) to (P1, D1, γ'' = 0):
  joined to straight pieces with the same end derivatives it keeps the curve C².
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
        breaks: (m + 1,) increasing parameters of the junctions [m of arc length, for the
            surface paths].
        coeffs: (m, DEGREE + 1, 2) coefficients, lowest order first, of (u, v).
    """

    breaks: np.ndarray
    coeffs: np.ndarray
    _starts: list[float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_starts", self.breaks[:-1].tolist())
        for array in (self.breaks, self.coeffs):
            array.setflags(write=False)

    @classmethod
    def join(cls, lengths: list[float], pieces: list[np.ndarray]) -> PiecewiseCurve:
        """Pieces (each (DEGREE + 1, 2) in its local parameter) laid end to end from σ = 0."""
        breaks = np.concatenate(([0.0], np.cumsum(lengths)))
        return cls(breaks, np.array(pieces, dtype=float).reshape(len(pieces), DEGREE + 1, 2))

    @property
    def length(self) -> float:
        """σ at the end of the last piece."""
        return float(self.breaks[-1])

    def evaluate(self, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(γ, γ', γ'') at σ, each (2,); σ is clamped to [breaks[0], breaks[-1]]."""
        k = max(0, min(bisect.bisect_right(self._starts, sigma) - 1, len(self._starts) - 1))
        x = min(max(sigma, float(self.breaks[0])), float(self.breaks[-1])) - self._starts[k]
        c = self.coeffs[k]
        g = c[5] * x + c[4]
        g1 = 5.0 * c[5] * x + 4.0 * c[4]
        g2 = 20.0 * c[5] * x + 12.0 * c[4]
        for j in (3, 2):
            g = g * x + c[j]
            g1 = g1 * x + j * c[j]
        g2 = g2 * x + 6.0 * c[3]
        g2 = g2 * x + 2.0 * c[2]
        g = (g * x + c[1]) * x + c[0]
        g1 = g1 * x + c[1]
        return g, g1, g2

    def sample_piece(self, k: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(γ, γ') of piece k at local parameters x (N,): two (N, 2) arrays (for quadrature)."""
        c = self.coeffs[k]
        powers = x[:, None] ** np.arange(DEGREE + 1)  # (N, 6)
        slopes = np.arange(1, DEGREE + 1) * powers[:, :DEGREE]  # d/dx of x^j, j = 1..5
        return powers @ c, slopes @ c[1:]


def natural_cubic_spline(knots: np.ndarray, points: np.ndarray) -> PiecewiseCurve:
    """The C² cubic spline through ``points`` (n, 2) at increasing ``knots`` (n,), n ≥ 2, with
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
    m = np.zeros((n, 2))
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
    coeffs = np.zeros((n - 1, DEGREE + 1, 2))
    coeffs[:, 0] = y[:-1]
    coeffs[:, 1] = slope - h[:, None] * (2.0 * m[:-1] + m[1:]) / 6.0
    coeffs[:, 2] = m[:-1] / 2.0
    coeffs[:, 3] = (m[1:] - m[:-1]) / (6.0 * h[:, None])
    return PiecewiseCurve(x.copy(), coeffs)


def line_piece(start: np.ndarray, slope: np.ndarray) -> np.ndarray:
    """The straight piece γ(x) = start + slope·x: (DEGREE + 1, 2) coefficients."""
    out = np.zeros((DEGREE + 1, 2))
    out[0], out[1] = start, slope
    return out


def blend_piece(
    p0: np.ndarray, d0: np.ndarray, p1: np.ndarray, d1: np.ndarray, length: float
) -> np.ndarray:
    """The quintic from γ = p0, γ' = d0, γ'' = 0 at x = 0 to γ = p1, γ' = d1, γ'' = 0 at
    x = ``length``: (DEGREE + 1, 2) coefficients in x.

    In s = x / length it is p0 H0 + p1 H5 + length (d0 H1 + d1 H4) with the quintic Hermite
    basis H0 = 1 − 10s³ + 15s⁴ − 6s⁵, H5 = 1 − H0, H1 = s − 6s³ + 8s⁴ − 3s⁵,
    H4 = −4s³ + 7s⁴ − 3s⁵ (the bases of the second derivatives are not needed: they are 0).
    """
    a, b = length * np.asarray(d0, dtype=float), length * np.asarray(d1, dtype=float)
    jump = np.asarray(p1, dtype=float) - np.asarray(p0, dtype=float)
    in_s = np.array(
        [
            p0,
            a,
            np.zeros(2),
            10.0 * jump - 6.0 * a - 4.0 * b,
            -15.0 * jump + 8.0 * a + 7.0 * b,
            6.0 * jump - 3.0 * a - 3.0 * b,
        ],
        dtype=float,
    )
    return in_s / (length ** np.arange(DEGREE + 1))[:, None]

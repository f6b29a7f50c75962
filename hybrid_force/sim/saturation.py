"""Torque saturation in contact: the consistent set of joints held at their effort limits.

In contact the applied torque τ = sat(u0 + B f) (each joint clipped to ±e_j) and the contact
force f (k,) depend on each other. For a given applied torque the constrained dynamics
(:mod:`hybrid_force.sim.dynamics`, eq. 2 with the friction torque F f of the contact) give f
affinely,

    f(τ) = f̄ − W τ,      W = (A M⁻¹ (Aᵀ + F))⁻¹ A M⁻¹   (k, n),

and the command is affine in f, x(f) = u0 + B f. A *held set* assigns each joint a sign
s_j ∈ {−1, 0, +1}: held at +e_j, free, or held at −e_j. It is consistent when, with the held
joints at s_j e_j and the free ones at x_j(f), the force f of that torque satisfies

    |x_j(f)| ≤ e_j  for the free joints,    s_j x_j(f) ≥ e_j  for the held ones

(the held joints' command is beyond the limit on the side they are held at). The consistent
sets are exactly the solutions of τ = sat(x(f(τ))): a box-constrained mixed linear
complementarity problem in τ with the matrix I + B W.

Method (terminates by construction):

* k = 1 (one surface, every bundled scenario): h(f) = f − f̄ + W sat(u0 + B f) is a
  continuous, piecewise-affine function of the scalar f, affine between the ≤ 2n breakpoints
  f where some x_j(f) = ±e_j; the held set is constant on each of the ≤ 2n + 1 segments. Each
  segment's affine root is computed and kept if it lies in the segment: every solution is
  found, in O(n log n). Since sat is bounded, h(f) → ±∞ as f → ±∞, so a solution always
  exists. The slope of h on a segment is 1 + Σ_free W_j B_j = det(I + B W) restricted to
  the free joints (matrix determinant lemma): when it is positive on every segment (I + B W
  a P-matrix along the path) h is strictly increasing and the solution is unique.
* k > 1 (stacked surfaces): every sign pattern of the joints whose command can reach a limit
  (finite e_j, B_j ≠ 0) is tried, 3^m of them, vectorised; m ≤ 7 for the bundled arms
  (2187 k × k solves; more than 10 such joints is refused). For a P-matrix I + B W the box
  problem has exactly one solution (the P-matrix uniqueness theorem of linear
  complementarity, Samelson, Thrall & Wesler 1958, in its box-constrained form; see Cottle,
  Pang & Stone, *The Linear Complementarity Problem*, 1992, ch. 3). The code relies on no
  such property: it lists every solution and refuses to choose among several.

Where the solution is not unique (I + B W not a P-matrix and the state in the region where
that matters) the plant cannot choose among physically different torques:
:func:`held_set` raises ``numpy.linalg.LinAlgError``, as the unsaturated loop does when it
has no unique solution (the run fails as diverged, with the reason in its message). Only
with a unilateral contact, a solution whose surface would have to pull is not one the
surface can hold, and is dropped first.

This replaces an active-set iteration that fixed a joint at the limit its first,
unsaturated pass implied and never released it, which could hold a joint at the wrong limit
(issue 28: a UR5 wrist held at −28 N·m under a +28.6 N·m command).
"""

from __future__ import annotations

import itertools

import numpy as np

from hybrid_force.errors import RunFailedError

__all__ = ["held_set", "saturation_solutions"]

#: relative tolerance of "the root lies in its segment" and of "two roots are one"
_TOL = 1e-10
#: k > 1: most joints whose held sets are enumerated (3^10 = 59049 k × k solves)
_MAX_ENUMERATED = 10


def saturation_solutions(
    u0: np.ndarray,
    B: np.ndarray,
    f_bar: np.ndarray,
    W: np.ndarray,
    effort: np.ndarray,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Every consistent held set (module docstring), each as (signs (n,) int, f (k,) [N]).

    Args:
        u0: (n,) the command's force-independent part [N·m or N].
        B: (n, k) the command's force gain: x(f) = u0 + B f.
        f_bar, W: (k,) [N] and (k, n) [N per N·m]: the force of an applied torque τ is
            f̄ − W τ.
        effort: (n,) effort limits e > 0 (+inf: none).

    Two solutions closer than a relative 1e-10 in f (a root on a breakpoint, where a joint
    is exactly at its limit held or free) are one; the first found is kept.
    """
    if B.shape[1] == 1:
        return _sweep(u0, B[:, 0], float(f_bar[0]), W[0], effort)
    return _enumerate(u0, B, f_bar, W, effort)


def held_set(
    u0: np.ndarray,
    B: np.ndarray,
    f_bar: np.ndarray,
    W: np.ndarray,
    effort: np.ndarray,
    min_force: float = -np.inf,
) -> tuple[np.ndarray, np.ndarray]:
    """The unique consistent held set (signs (n,) int) and its force f (k,) [N].

    ``min_force`` [N]: for a unilateral contact, where there are several consistent sets,
    those whose force pulls (some f_i < min_force) are dropped: the surface cannot hold
    them (with none left, the first is returned and the contact releases).

    Raises:
        numpy.linalg.LinAlgError: there are several consistent sets (the applied torque is
            not determined), or a continuum of them.
    """
    found = saturation_solutions(u0, B, f_bar, W, effort)
    if len(found) > 1:
        pushing = [s for s in found if float(s[1].min()) >= min_force]
        found = pushing if pushing else found[:1]
    if len(found) != 1:
        forces = ", ".join(f"{float(s[1][0]):.6g}" for s in found)
        raise np.linalg.LinAlgError(
            f"torque saturation in contact has {len(found)} consistent sets of joints held at "
            f"their effort limits (forces {forces} N): the applied torque is not determined"
        )
    return found[0]


def _pattern(x: np.ndarray, effort: np.ndarray) -> np.ndarray:
    """Signs (n,) of the commands x beyond their limits: +1 above, −1 below, 0 within."""
    return np.where(x > effort, 1, np.where(x < -effort, -1, 0))


def _sweep(
    u0: np.ndarray, b: np.ndarray, f_bar: float, w: np.ndarray, effort: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """k = 1: the roots of the piecewise-affine h(f), segment by segment (module docstring)."""
    moving = np.isfinite(effort) & (b != 0.0)
    bm, um, em = b[moving], u0[moving], effort[moving]
    breaks = np.unique(np.concatenate([(em - um) / bm, (-em - um) / bm]))
    lows = np.concatenate([[-np.inf], breaks])
    highs = np.concatenate([breaks, [np.inf]])
    # a point inside each segment fixes its held set
    width = 1.0 + np.abs(breaks).max() if breaks.size else 1.0
    mids = np.where(
        np.isinf(lows),
        highs - width,
        np.where(np.isinf(highs), lows + width, 0.5 * (lows + highs)),
    )
    if not breaks.size:
        mids = np.zeros(1)
    S = _pattern(u0[None] + mids[:, None] * b[None], effort[None])  # (m, n) per segment
    free = S == 0
    e = np.where(free, 0.0, effort[None])  # 0 where free (also for e = inf)
    # h(f) = slope f + offset on each segment: slope = 1 + Σ_free w_j b_j
    slope = 1.0 + (free * (w * b)[None]).sum(axis=1)
    offset = -f_bar + (free * (w * u0)[None]).sum(axis=1) + (S * e) @ w
    scale = 1.0 + abs(f_bar) + np.abs(np.where(free, u0[None], S * e)) @ np.abs(w)
    flat = np.abs(slope) < 1e-14
    if np.any(flat & (np.abs(offset) <= _TOL * scale)):
        raise np.linalg.LinAlgError(
            "torque saturation in contact: a continuum of consistent held sets "
            "(I + B W singular on a segment)"
        )
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.where(flat, np.nan, -offset / np.where(flat, 1.0, slope))
    tol = _TOL * (1.0 + np.abs(root))
    inside = ~flat & (lows - tol <= root) & (root <= highs + tol)
    found: list[tuple[np.ndarray, np.ndarray]] = []
    for i in np.flatnonzero(inside):
        if not any(abs(float(g[1][0]) - root[i]) <= tol[i] for g in found):
            found.append((S[i].astype(np.int64), np.array([root[i]])))
    return found


def _enumerate(
    u0: np.ndarray, B: np.ndarray, f_bar: np.ndarray, W: np.ndarray, effort: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """k > 1: every sign pattern of the joints that can reach a limit, checked at once."""
    k = B.shape[1]
    can = np.isfinite(effort) & np.any(B != 0.0, axis=1)
    fixed = _pattern(u0, effort) * ~can  # a command that does not depend on f
    idx = np.flatnonzero(can)
    if idx.size > _MAX_ENUMERATED:
        raise RunFailedError(
            f"torque saturation on {B.shape[1]} stacked surfaces tries every held set of the "
            f"joints that can reach a limit: 3^{idx.size} sets for {idx.size} joints is too "
            f"many (at most {_MAX_ENUMERATED} joints); switch sim.torque_limits off or use "
            "one surface"
        )
    patterns = np.array(list(itertools.product((-1, 0, 1), repeat=idx.size)), dtype=np.int64)
    S = np.tile(fixed, (patterns.shape[0], 1))
    S[:, idx] = patterns
    free = S == 0  # (P, n)
    e = np.where(np.isfinite(effort), effort, 0.0)
    # (I_k + W_free B_free) f = f̄ − W_free u0_free − W_held s e, for every pattern P
    Wf = W[None, :, :] * free[:, None, :]  # (P, k, n)
    lhs = np.eye(k)[None] + Wf @ B  # (P, k, k)
    rhs = f_bar[None] - Wf @ u0 - np.einsum("kn,pn->pk", W, S * e)
    ok = np.abs(np.linalg.det(lhs)) > 1e-14
    found: list[tuple[np.ndarray, np.ndarray]] = []
    if not ok.any():
        return found
    f = np.full((S.shape[0], k), np.nan)
    f[ok] = np.linalg.solve(lhs[ok], rhs[ok][..., None])[..., 0]
    x = u0[None] + f @ B.T  # (P, n) the commands at each pattern's force
    tol = _TOL * (1.0 + np.abs(x))
    good = np.where(free, np.abs(x) <= e + tol, S * x >= e - tol) | ~np.isfinite(effort)
    for p in np.flatnonzero(ok & good.all(axis=1)):
        ftol = _TOL * (1.0 + float(np.abs(f[p]).max()))
        if not any(float(np.abs(g[1] - f[p]).max()) <= ftol for g in found):
            found.append((S[p].copy(), f[p].copy()))
    return found

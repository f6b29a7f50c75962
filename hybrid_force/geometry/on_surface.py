"""Whether a desired path lies on a surface: the worst |d| of p_d(t) over a time span.

The paper requires p_d to lie on Φ(p) = 0 (eq. 26); ``Scenario`` (which the scenario loader
builds) refuses a path farther than :data:`ON_SURFACE_TOL` from a surface.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from hybrid_force import _checks as checks
from hybrid_force.errors import BadInputError, PathError, RunWarning, ScenarioError, SurfaceError

if TYPE_CHECKING:
    from hybrid_force.geometry.paths import Path

__all__ = [
    "ON_SURFACE_TOL",
    "OnSurfaceReport",
    "check_on_surface",
    "check_path_on_surfaces",
    "path_samples",
    "warn_untrusted_path",
]

_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0  # 0.618...

_MAX_SAMPLES = 10_000_000
"""Most samples :func:`check_on_surface` accepts (each costs a path and a surface call)."""

ON_SURFACE_TOL = 1e-6
"""Largest |d| [m] of a desired path from a surface over a run accepted by the scenario loader
and by ``Scenario`` for a run that starts in contact (:func:`check_on_surface`)."""


@dataclass(frozen=True)
class OnSurfaceReport:
    """Result of :func:`check_on_surface`.

    worst_distance: [m] max over the span of |d(p_d(t))|, d the surface's signed distance.
    time_of_worst: [s] the t where it occurs.
    point_of_worst: (3,) [m] p_d(time_of_worst).
    """

    worst_distance: float
    time_of_worst: float
    point_of_worst: np.ndarray = field(compare=False)


def _abs_distance(path: Path, surface: Any, t: float) -> tuple[float, np.ndarray]:
    raw = path.position(t)
    try:
        p = np.asarray(raw, dtype=float)
    except (TypeError, ValueError, OverflowError):
        p = np.full(1, np.nan)
    # math.isfinite on the 3 floats: a fifth of np.isfinite(p).all()'s cost, 2001+ times a check
    if p.shape != (3,) or not all(map(math.isfinite, p.tolist())):
        raise PathError(
            f"path {path!r} gives a non-finite or wrongly shaped position "
            f"{checks.shown(raw)} at t={t!r}"
        )
    value = surface.distance(p)
    try:
        d = float(value)
    except (TypeError, ValueError, OverflowError):
        d = math.nan
    if not math.isfinite(d):
        raise SurfaceError(
            f"surface {surface!r} returned a non-finite distance {checks.shown(value)} "
            f"at p={p.tolist()} (path time t={t!r})"
        )
    return abs(d), p


def check_on_surface(
    path: Path, surface: Any, t0: float, t1: float, samples: int = 2001
) -> OnSurfaceReport:
    """Worst |d| [m] of ``path`` on ``surface`` over times t0 ≤ t ≤ t1 [s].

    surface: any object with ``distance(p: (3,) ndarray) -> float``, the signed metric
    distance [m] (e.g. hybrid_force.geometry.builtin_surfaces.Cylinder). The span is sampled at
    ``samples`` (≥ 2) uniform times; the bracket around the worst sample is then refined
    by a golden-section search for the maximum of |d|, so the reported value is accurate
    to rounding even between samples as long as |d| has a single peak within one sample
    spacing of the worst sample. The time of the worst is less precise (about 1e-8·scale
    s, since |d| is flat at its peak: the golden search resolves t to ~√ε).

    Raises PathError if t0, t1 are not finite, t1 <= t0, or samples < 2;
    SurfaceError if the surface returns a non-finite distance.
    """
    a = checks.number(t0, "check_on_surface.t0", PathError, unit="s")
    b = checks.number(t1, "check_on_surface.t1", PathError, unit="s")
    if not b > a:
        raise PathError(f"check_on_surface.t1 must be > t0, got t0={t0!r}, t1={t1!r}")
    n = checks.integer(samples, "check_on_surface.samples", PathError, minimum=2)
    if n > _MAX_SAMPLES:
        raise PathError(f"check_on_surface.samples must be <= {_MAX_SAMPLES:.0e}, got {samples!r}")
    if not callable(getattr(path, "position", None)):
        raise PathError(
            f"check_on_surface.path must be a Path (with position(t) -> (3,)), "
            f"got {checks.shown(path)}"
        )
    if not callable(getattr(surface, "distance", None)):
        raise PathError(
            f"check_on_surface.surface must have a method distance(p) -> float, got {surface!r}"
        )
    return _scan(path, surface, a, b, n)


def _scan(path: Path, surface: Any, a: float, b: float, n: int) -> OnSurfaceReport:
    """The scan of :func:`check_on_surface` (its arguments checked): n samples, then the
    golden-section refinement around the worst."""
    times = np.linspace(a, b, n)
    best_t = a
    best_d = -1.0
    best_p = np.zeros(3)
    best_k = 0
    for k, t in enumerate(times):
        d, p = _abs_distance(path, surface, float(t))
        if d > best_d:
            best_t, best_d, best_p, best_k = float(t), d, p, k
    lo = float(times[max(best_k - 1, 0)])
    hi = float(times[min(best_k + 1, len(times) - 1)])
    best_t, best_d, best_p = _golden_max(path, surface, lo, hi, best_t, best_d, best_p)
    return OnSurfaceReport(worst_distance=best_d, time_of_worst=best_t, point_of_worst=best_p)


def _golden_max(
    path: Path,
    surface: Any,
    lo: float,
    hi: float,
    best_t: float,
    best_d: float,
    best_p: np.ndarray,
) -> tuple[float, float, np.ndarray]:
    """Golden-section search for max |d| on [lo, hi]; keeps the best point ever evaluated."""
    x1 = hi - _GOLDEN * (hi - lo)
    x2 = lo + _GOLDEN * (hi - lo)
    f1, p1 = _abs_distance(path, surface, x1)
    f2, p2 = _abs_distance(path, surface, x2)
    for x, f, p in ((x1, f1, p1), (x2, f2, p2)):
        if f > best_d:
            best_t, best_d, best_p = x, f, p
    tol = 1e-12 * max(1.0, abs(lo), abs(hi))
    for _ in range(200):
        if hi - lo <= tol:
            break
        if f1 >= f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - _GOLDEN * (hi - lo)
            f1, p1 = _abs_distance(path, surface, x1)
            if f1 > best_d:
                best_t, best_d, best_p = x1, f1, p1
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + _GOLDEN * (hi - lo)
            f2, p2 = _abs_distance(path, surface, x2)
            if f2 > best_d:
                best_t, best_d, best_p = x2, f2, p2
    return best_t, best_d, best_p


def check_path_on_surfaces(path: Path, surfaces: Sequence[Any], duration: float) -> None:
    """The desired path within ``ON_SURFACE_TOL`` of every surface for 0 ≤ t ≤ duration [s]
    (or within a surface's own ``path_tolerance`` [m] when larger: a mesh part's fit):
    ScenarioError (key "Scenario.path", value (surface index, its OnSurfaceReport, or
    None when the path cannot be checked against it)) otherwise."""

    for i, surface in enumerate(surfaces):
        # a surface known only to within a fit (a mesh part) says how far (path_tolerance)
        tol = max(ON_SURFACE_TOL, float(getattr(surface, "path_tolerance", 0.0)))
        try:
            report = check_on_surface(path, surface, 0.0, duration)
        except BadInputError as exc:  # e.g. Φ(p_d) not finite
            raise ScenarioError(
                f"Scenario.path cannot be checked against surfaces[{i}] ({surface!r}): "
                f"{' '.join(str(exc).split())}",
                key="Scenario.path",
                value=(i, None),
            ) from None
        if report.worst_distance > tol:
            raise ScenarioError(
                f"Scenario.path is not on surfaces[{i}] ({surface!r}): "
                f"{report.worst_distance:.3g} m away at t = {report.time_of_worst:.4g} s "
                f"(p_d = {np.round(report.point_of_worst, 6).tolist()}); it must stay "
                f"within {tol:g} m of every surface (ON_SURFACE_TOL, or a fitted surface's "
                f"path_tolerance) over "
                f"[0, sim.duration = {duration:g} s]",
                key="Scenario.path",
                value=(i, report),
            )


def path_samples(path: Path, duration: float, samples: int = 2001) -> tuple[np.ndarray, np.ndarray]:
    """(times (N,) [s], p_d at them (N, 3) [m]): ``samples`` uniform times over [0,
    ``duration``], what the path warnings look at."""
    times = np.linspace(0.0, duration, samples)
    return times, np.array([path.position(float(t)) for t in times])


def warn_untrusted_path(
    along: tuple[np.ndarray, np.ndarray], surfaces: Sequence[Any], radius: float
) -> None:
    """Warn (RunWarning) where the desired path comes near a part's open edge, where Φ follows
    the fit's jump rather than the part (:meth:`.MeshSurface.untrusted`): the path's tool
    centre ``along`` = (times (N,) [s], points (N, 3) [m], :func:`path_samples`) within the
    part's ``untrusted_width`` plus the tool ``radius`` [m] of an open edge. Parts without open
    edges (every built-in surface, a watertight mesh) are skipped."""
    times, points = along
    for i, surface in enumerate(surfaces):
        if not getattr(surface, "untrusted_width", 0.0) > 0.0 or len(times) == 0:
            continue
        distance = surface.open_edge_distance(points) - radius
        j = int(np.argmin(distance))
        if distance[j] < surface.untrusted_width:
            warnings.warn(
                RunWarning(
                    f"the path comes within {max(distance[j], 0.0):.3g} m of an open edge of "
                    f"surfaces[{i}] ({surface!r}) at t = {times[j]:.4g} s (p_d = "
                    f"{np.round(points[j], 6).tolist()} m): within "
                    f"{surface.untrusted_width:.3g} m of an open edge Φ is not trusted (the "
                    "signed distance of an open mesh jumps past its edge; docs/mesh_parts.md)"
                ),
                stacklevel=3,
            )

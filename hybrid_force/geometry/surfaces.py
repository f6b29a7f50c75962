"""Rigid surfaces Φ(p) = 0 that the tool of the arm stays on (paper eq. 1).

Pure geometry, no robot: every surface gives, at a task-space point p: (3,) [m],

- Φ(p) (``phi``), its gradient ∇Φ: (3,) and Hessian ∇²Φ: (3, 3); ``evaluate`` returns all three in
  one call and is the hot path of the simulation;
- a signed *metric* distance d(p) [m] (Φ itself is not a distance: the paper's cylinder, eq. 26,
  has Φ = x² + y² − r², in m²), used by the phase switching of section 6.4 (max_dist = 0.05 m,
  contact at d ≤ 1e-5 m);
- the unit normal ∇Φ/‖∇Φ‖ and the foot point on the surface.

Orientation. Every surface has a *free side*, where the tool is, and Φ > 0, d > 0 there. The
contact force f of the whole toolkit acts along the unit normal pointing to the free side, so
f > 0 always means "the tool presses on the surface". Cylinders and spheres carry an ``inside``
flag: ``inside=False`` (default) makes the outside free, with Φ exactly the paper's eq. 26 for
``Cylinder(0.4)``; ``inside=True`` negates Φ so the interior is free (section 6.4 of the paper,
where the tool starts inside the cylinder and presses on its wall from within). A plane's normal
points to its free side; a :class:`FunctionSurface`'s Φ must be positive on its free side.

Built in: :class:`Cylinder`, :class:`Sphere`, :class:`Plane`; user-defined:
:class:`FunctionSurface`; other types register themselves in their own module
(:func:`~.surface_base.register_surface`, e.g. :mod:`.ellipsoid`).
:func:`surface_from_dict` inverts ``to_dict`` for every registered type: the one parser of a
surface dict. The interface and the registry are in :mod:`.surface_base`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from hybrid_force.errors import SurfaceError, did_you_mean
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.surface_base import (
    Surface,
    _fmt,
    surface_parameters,
    surface_types,
)
from hybrid_force.schema import MISSING_VALUE, default_of

__all__ = ["surface_from_dict"]


def surface_from_dict(d: Mapping[str, Any]) -> Surface:
    """Build a registered surface from ``to_dict``'s output (the inverse of ``to_dict``).

    ``d["type"]`` is a registered type (:func:`~.surface_base.surface_types`: "cylinder",
    "sphere", "plane", ...); the other keys are its declared parameters (lists for vectors).
    Raises SurfaceError on an unknown type, on the non-serialisable "function" type,
    on missing or unknown keys, and on bad parameter values.
    """
    types = surface_types()
    if not isinstance(d, Mapping):
        raise SurfaceError(f"surface_from_dict: expected a dict with a 'type' key, got {_fmt(d)}")
    valid = ", ".join(repr(name) for name in types)
    if "type" not in d:
        raise SurfaceError(
            f"surface_from_dict: missing key 'type' in {_fmt(dict(d))}; valid types: {valid}"
        )
    kind = d["type"]
    if kind == FunctionSurface.kind:
        raise SurfaceError(
            "surface_from_dict: type 'function' cannot be rebuilt from a dict (its Python "
            f"callables are not serialised); build a FunctionSurface in code. Valid types: {valid}"
        )
    if not isinstance(kind, str) or kind not in types:
        hint = did_you_mean(kind, types) if isinstance(kind, str) else ""
        raise SurfaceError(
            f"surface_from_dict: unknown surface type {kind!r}{hint}; valid types: {valid}"
        )
    declared = surface_parameters(types[kind])
    required = [key for key, f, _ in declared if default_of(f) is MISSING_VALUE]
    allowed = [key for key, _, _ in declared]
    params = {key: value for key, value in d.items() if key != "type"}
    missing = [key for key in required if key not in params]
    if missing:
        raise SurfaceError(
            f"surface_from_dict: {kind} is missing parameter(s) "
            f"{', '.join(repr(key) for key in missing)}; required: {', '.join(required)}"
        )
    unknown = [key for key in params if key not in allowed]
    if unknown:
        key = str(unknown[0])
        raise SurfaceError(
            f"surface_from_dict: unknown parameter {unknown[0]!r} for {kind}"
            f"{did_you_mean(key, allowed)}; valid parameters: {', '.join(allowed)}"
        )
    return types[kind](**params)

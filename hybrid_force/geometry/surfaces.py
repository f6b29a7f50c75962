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
:class:`FunctionSurface`.
:func:`surface_from_dict` inverts ``to_dict`` for the built-ins: the one parser of a surface
dict. The interface is in :mod:`.surface_base`, the built-ins in :mod:`.builtin_surfaces`, the
user-defined surface in :mod:`.function_surface`; this module gathers their names.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from hybrid_force.errors import SurfaceError, did_you_mean
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.function_surface import FunctionSurface
from hybrid_force.geometry.surface_base import Surface, _fmt

__all__ = ["surface_from_dict"]

# --- from a dict -----------------------------------------------------------------------------
_BUILT_INS: dict[str, tuple[type[Surface], tuple[str, ...], tuple[str, ...]]] = {
    # type: (class, required keys, optional keys)
    "cylinder": (Cylinder, ("radius",), ("center", "axis", "inside")),
    "sphere": (Sphere, ("radius",), ("center", "inside")),
    "plane": (Plane, ("point", "normal"), ()),
}


def surface_from_dict(d: Mapping[str, Any]) -> Surface:
    """Build a built-in surface from ``to_dict``'s output (the inverse of ``to_dict``).

    ``d["type"]`` is one of "cylinder", "sphere", "plane"; the other keys are the constructor's
    parameters (lists for vectors). Raises SurfaceError on an unknown type, on the
    non-serialisable "function" type, on missing or unknown keys, and on bad parameter values.
    """
    if not isinstance(d, Mapping):
        raise SurfaceError(f"surface_from_dict: expected a dict with a 'type' key, got {_fmt(d)}")
    valid = ", ".join(repr(name) for name in _BUILT_INS)
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
    if not isinstance(kind, str) or kind not in _BUILT_INS:
        hint = did_you_mean(kind, _BUILT_INS) if isinstance(kind, str) else ""
        raise SurfaceError(
            f"surface_from_dict: unknown surface type {kind!r}{hint}; valid types: {valid}"
        )
    cls, required, optional = _BUILT_INS[kind]
    params = {key: value for key, value in d.items() if key != "type"}
    missing = [key for key in required if key not in params]
    if missing:
        raise SurfaceError(
            f"surface_from_dict: {kind} is missing parameter(s) "
            f"{', '.join(repr(key) for key in missing)}; required: {', '.join(required)}"
        )
    allowed = required + optional
    unknown = [key for key in params if key not in allowed]
    if unknown:
        key = str(unknown[0])
        raise SurfaceError(
            f"surface_from_dict: unknown parameter {unknown[0]!r} for {kind}"
            f"{did_you_mean(key, allowed)}; valid parameters: {', '.join(allowed)}"
        )
    return cls(**params)

"""The tool's desired direction along a path on a surface: the ``[tool]`` table.

The tool axis â is a fixed unit vector of the tip frame (``axis``). With ``orientation =
"normal"`` it must point into the surface at the desired point p_d(t) of the first surface:

    n(t) = ∇Φ(p_d) / ‖∇Φ(p_d)‖           (unit normal, towards the free side)
    a_d(t) = −cos θ · n + sin θ · d      (θ = ``tilt`` [rad], d a unit tangent: d ⟂ n)

so the angle between a_d and −n is exactly |θ|. The lean direction d is

* the direction of travel, d = P_n τ / ‖P_n τ‖ (P_n = I − n nᵀ), by default: a positive
  tilt puts the tool's back behind its tip (the tool is pushed), a negative one ahead of it
  (the tool is dragged);
* d = n × k / ‖n × k‖ with k = ``tilt_axis`` (world): the tool turns by θ about k projected
  on the tangent plane.

τ is ṗ_d for a helix, a circle or a user path (undefined where ṗ_d = 0), and the unit tangent
dp_d/dℓ for a path on a surface (waypoints, raster), defined also at its rest points, so a
lean or a held roll works on paths that start and stop at rest
(:meth:`~hybrid_force.geometry.surface_path.SurfacePath.direction_jet`).

With ``roll = "held"`` the tip frame's whole orientation is prescribed: the desired rotation
R_d(t) = F(t) F(0)ᵀ R(q_d(0)), F = [x, a_d × x, a_d] with x = P_a τ / ‖P_a τ‖ the
direction of travel across the axis, keeps the roll the tool has at t = 0 relative to the
direction of travel (R_d â = a_d, since R(q_d(0)) â = a_d(0)). Its angular velocity is
ω_d = ½ Σ f_i × ḟ_i and ω̇_d = ½ Σ f_i × f̈_i (f_i the columns of F).

Every vector is carried with its first two time derivatives (a "jet", rows v, v̇, v̈): the
pose CLIK (:mod:`hybrid_force.control.pose_clik`) needs ȧ_d and ä_d for an exact q̈_d. They
use ∇Φ, ∇²Φ ṗ_d and ∇²Φ p̈_d + (d/dt ∇²Φ) ṗ_d, whose last term is zero on the built-in
(quadric) surfaces and a central difference of the Hessian otherwise, and, for a lean towards
the direction of travel or a held roll, the path's third derivative p⃛_d (closed form for a
helix or a circle, a central difference of p̈_d, error ~1e-10 relative, for user paths) or, on
a path on a surface, d³p/dℓ³ (a central difference of d²p/dℓ² in arc length).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from hybrid_force import _checks as checks
from hybrid_force.errors import ControlError, ReachError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.geometry.paths import Path
from hybrid_force.geometry.surface_base import MAX_LENGTH, Surface
from hybrid_force.schema import check_fields, param
from hybrid_force.sim.removal import PAD_TYPES, Pad

__all__ = [
    "ToolAngleProbe",
    "ToolSettings",
    "ToolTarget",
    "axis_angle",
    "cross3",
]

#: A direction built from a shorter vector is undefined ([-] for a cross product of unit
#: vectors, [m/s] for the travel speed across the axis or the normal).
_MIN_NORM = 1e-6
_HESSIAN_STEP = 1e-4  # [m] central difference of ∇²Φ along ṗ_d (non-quadric surfaces)
_NORMAL = ("orientation", "normal")  # the keys that act only with a pointed tool


@dataclass(frozen=True)
class ToolSettings:
    """The ``[tool]`` table: which way the tool points (module docstring).

    Attributes:
        axis: (3,) the tool axis in the tip frame (any non-zero length; stored as a unit
            tuple). Default: the tip frame's z axis.
        orientation: ``"free"`` (only the tip position is controlled: the paper's CLIK) or
            ``"normal"`` (the axis points into the surface, leaning by ``tilt``).
        tilt: θ [rad], |θ| < π/2: the angle between the tool axis and the inward normal.
        tilt_axis: None (lean towards the direction of travel) or (3,) a world direction k
            to turn the tool about (projected on the tangent plane).
        roll: ``"free"`` (the rotation about the axis is left to the null-space posture) or
            ``"held"`` (the tip frame's whole orientation is prescribed, module docstring).
        radius: r [m] ≥ 0 of a ball-end tool or a rounded pad. The tip frame's origin is the
            ball's centre: the run controls it on the offset surface at distance r from the
            part (:mod:`hybrid_force.geometry.offset`), and the contact point lies r along −n̂
            from it. 0 (default): a point tool.
        pad: None or the tool's contact pad (the ``[tool.pad]`` table, a
            :class:`~hybrid_force.sim.removal.HertzPad` or
            :class:`~hybrid_force.sim.removal.FlatPad`): its pressure patch, which the
            ``[removal]`` table needs (docs/removal.md).

    Raises ControlError (key ``tool.<field>``) for a bad value, and for a tilt, tilt axis or
    held roll with ``orientation = "free"``, which has no desired direction to apply them to.
    """

    axis: tuple[float, float, float] = param(
        (0.0, 0.0, 1.0), acts_when=_NORMAL, doc="the tool axis in the tip frame (normalised)"
    )
    orientation: Literal["free", "normal"] = param(
        "free", doc="free: only the tip position; normal: the axis into the surface"
    )
    tilt: float = param(
        0.0,
        unit="rad",
        minimum=-math.pi / 2,
        maximum=math.pi / 2,
        strict=True,
        acts_when=_NORMAL,
        doc="angle between the tool axis and the inward normal",
    )
    tilt_axis: tuple[float, float, float] | None = param(
        None, acts_when=_NORMAL, doc="world direction to lean about (none: towards the travel)"
    )
    roll: Literal["free", "held"] = param(
        "free",
        acts_when=_NORMAL,
        doc="free: left to the posture; held: the whole orientation prescribed",
    )
    radius: float = param(
        0.0,
        unit="m",
        minimum=0.0,
        maximum=MAX_LENGTH,
        doc="radius of a ball-end tool or rounded pad: the tip frame is its centre",
    )
    pad: Pad | None = param(None, doc="[tool.pad]: the contact pad, which [removal] needs")

    def __post_init__(self) -> None:
        """Check every field (module conventions) and store the axes as unit float tuples."""
        set_ = object.__setattr__
        set_(self, "axis", _unit_tuple(self.axis, "tool.axis"))
        check_fields(self, ControlError, "tool.")
        if self.tilt_axis is not None:
            set_(self, "tilt_axis", _unit_tuple(self.tilt_axis, "tool.tilt_axis"))
        if self.pad is not None and not isinstance(self.pad, tuple(PAD_TYPES.values())):
            raise ControlError(
                "tool.pad must be None or a HertzPad or FlatPad (hybrid_force.sim.removal), "
                f"got {checks.shown(self.pad)}",
                key="tool.pad",
                value=self.pad,
            )
        if self.orientation == "free":
            for name, default in (("tilt", 0.0), ("tilt_axis", None), ("roll", "free")):
                value = getattr(self, name)
                if value != default:
                    raise ControlError(
                        f'tool.{name} = {value!r} needs tool.orientation = "normal" '
                        '(with "free" only the tip position is controlled)',
                        key=f"tool.{name}",
                        value=value,
                    )

    @property
    def controlled(self) -> bool:
        """True when the tool direction is controlled (``orientation = "normal"``)."""
        return self.orientation != "free"

    @property
    def task_size(self) -> int:
        """Rows of the CLIK's task: 3 (position), 5 (+ the axis) or 6 (+ the roll)."""
        if not self.controlled:
            return 3
        return 6 if self.roll == "held" else 5

    def to_dict(self) -> dict[str, Any]:
        """The settings as the ``[tool]`` table's keys (JSON-able)."""
        return {
            "axis": list(self.axis),
            "orientation": self.orientation,
            "tilt": self.tilt,
            "tilt_axis": None if self.tilt_axis is None else list(self.tilt_axis),
            "roll": self.roll,
            **({"radius": self.radius} if self.radius else {}),
            # only with a pad: the dict of a run without one is as before pads existed
            **({} if self.pad is None else {"pad": {"type": self.pad.kind, **vars(self.pad)}}),
        }

    def check_arm(self, robot: Any) -> None:
        """Refuse an arm with fewer joints than the task has rows (ControlError)."""
        n, m = robot.nv, self.task_size
        if n >= m:
            return
        key, value = ("tool.roll", self.roll) if m == 6 and n >= 5 else (
            "tool.orientation", self.orientation
        )  # fmt: skip
        what = "the tool axis (5 rows)" if m == 5 else "the tool's full orientation (6 rows)"
        raise ControlError(
            f"{key} = {value!r} needs an arm of at least {m} joints to control the tip "
            f"position and {what}; arm '{robot.name}' has {n} joints (only "
            f'tool.orientation = "free" works with it)',
            key=key,
            value=value,
        )


def _unit_tuple(value: object, what: str) -> tuple[float, float, float]:
    valid = "3 finite real numbers (a non-zero direction)"
    try:
        vec = checks.array(value, what, ControlError, valid=valid)
    except ControlError as exc:
        raise ControlError(str(exc), key=what, value=value) from None
    norm = float(np.linalg.norm(vec)) if vec.shape == (3,) else 0.0
    if not norm > 1e-12:
        raise ControlError(f"{what} must be {valid}, got {checks.shown(value)}", key=what)
    x, y, z = (vec / norm).tolist()
    return (x, y, z)


# --- jets: a vector and its first two time derivatives, rows (v, v̇, v̈) --------------------------
def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two (3,) vectors (np.cross costs ~10 µs a call: this runs many times a step)."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))


def axis_angle(a: np.ndarray, a_d: np.ndarray) -> float:
    """The angle [rad] between two unit vectors (3,), accurate near 0: atan2(‖a × a_d‖, a·a_d)."""
    c = cross3(a, a_d)
    return math.atan2(math.sqrt(float(c @ c)), float(a @ a_d))


def _unit(j: np.ndarray) -> tuple[np.ndarray, float]:
    """u = v/‖v‖ as a jet, and ‖v‖: u̇ = (v̇ − ṡu)/s, ü = (v̈ − 2ṡu̇ − s̈u)/s, s = ‖v‖.

    A zero jet for v = 0 (callers refuse a size below ``_MIN_NORM``)."""
    v, dv, ddv = j
    s = math.sqrt(float(v @ v))
    if s == 0.0:
        return np.zeros((3, 3)), 0.0
    u = v / s
    sd = float(u @ dv)
    du = (dv - sd * u) / s
    sdd = float(du @ dv + u @ ddv)
    return np.array([u, du, (ddv - 2.0 * sd * du - sdd * u) / s]), s


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b as a jet (Leibniz)."""
    c = cross3
    return np.array(
        [
            c(a[0], b[0]),
            c(a[1], b[0]) + c(a[0], b[1]),
            c(a[2], b[0]) + 2 * c(a[1], b[1]) + c(a[0], b[2]),
        ]
    )


def _across(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The part of the jet v across the unit jet a: v − (a·v) a."""
    s = np.array(
        [a[0] @ v[0], a[1] @ v[0] + a[0] @ v[1], a[2] @ v[0] + 2 * a[1] @ v[1] + a[0] @ v[2]]
    )
    return v - np.array(
        [s[0] * a[0], s[1] * a[0] + s[0] * a[1], s[2] * a[0] + 2 * s[1] * a[1] + s[0] * a[2]]
    )


# where the desired direction is undefined (ToolTarget.undefined; _pose_kernels.pose_goal's codes)
NORMAL_UNDEFINED, LEAN_UNDEFINED, ROLL_UNDEFINED = 1, 2, 3


class ToolTarget:
    """The desired tool direction a_d(t) (and frame, roll held) along ``path`` on ``surface``.

    Args:
        settings: the ``[tool]`` settings (``orientation = "normal"``).
        surface: the surface the tool points into (the first of stacked surfaces).
        path: the desired tip path p_d(t).

    Methods raise ReachError naming t where a direction is undefined (∇Φ = 0, a lean towards
    a direction of travel or a held roll where the path stops, a tilt axis along the normal).
    """

    def __init__(self, settings: ToolSettings, surface: Surface, path: Path) -> None:
        if not settings.controlled:
            raise ControlError(
                'ToolTarget needs tool.orientation = "normal"', key="tool.orientation"
            )
        self.settings = settings
        self.surface = surface
        self.path = path
        self._quadric = isinstance(surface, Cylinder | Sphere | Plane)  # ∇³Φ = 0
        # MeshSurface.orientation_terms: surface_terms compiled (None for other surfaces)
        self._compiled_terms = getattr(surface, "orientation_terms", None)
        self._cos, self._sin = math.cos(settings.tilt), math.sin(settings.tilt)
        k = settings.tilt_axis
        self._k = None if k is None else np.array([k, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)])

    def normal(self, t: float, sample: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(n jet (3, 3), path sample (3, 3) rows p_d, ṗ_d, p̈_d) at time t [s].

        ``sample``: the path sample at t when the caller has it (else evaluated here)."""
        if sample is None:
            sample = np.array(self.path.evaluate(t))
        p, pd, pdd = sample
        g, H, third = self.surface_terms(sample)
        gj = np.array([g, H @ pd, H @ pdd + third])
        if not math.sqrt(float(g @ g)) > 1e-12:
            raise self.undefined(NORMAL_UNDEFINED, t, p)
        return _unit(gj)[0], sample

    def surface_terms(self, sample: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(∇Φ (3,), ∇²Φ (3, 3), (d/dt ∇²Φ) ṗ_d (3,)) at the path sample (3, 3) rows p_d, ṗ_d,
        p̈_d: the surface's part of :meth:`normal` (the last zero on a quadric)."""
        if self._compiled_terms is not None:  # a mesh part: the same terms in one call
            terms = self._compiled_terms(sample, _HESSIAN_STEP)
            if terms is not None:
                return terms
        p, pd, _ = sample
        _, g, H = self.surface.evaluate(p)
        third = np.zeros(3)
        if not self._quadric and pd @ pd > 0.0:
            h = _HESSIAN_STEP / math.sqrt(float(pd @ pd))
            Hp = self.surface.hessian(p + h * pd)
            Hm = self.surface.hessian(p - h * pd)
            third = ((Hp - Hm) / (2.0 * h)) @ pd
        return g, H, third

    def kernel_inputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """What ``_pose_kernels.pose_goal`` needs beside the path sample: (the surface's
        descriptor, or empty where :meth:`surface_terms` gives ∇Φ, ∇²Φ; tool (4,) cos θ, sin θ,
        lean (0 none, 1 tilt axis, 2 travel), held; the tilt axis jet (3, 3); whether the
        path's direction jet is needed)."""
        held = self.settings.roll == "held"
        lean = 0 if self._sin == 0.0 else (1 if self._k is not None else 2)
        desc = self.surface._descriptor if self._quadric else np.zeros(0)
        tool = np.array([self._cos, self._sin, float(lean), float(held)])
        k = np.zeros((3, 3)) if self._k is None else self._k.copy()
        return np.asarray(desc, dtype=float), tool, k, lean == 2 or held

    def axis(self, t: float, sample: np.ndarray | None = None) -> np.ndarray:
        """a_d(t) with ȧ_d, ä_d: (3, 3) rows [-, 1/s, 1/s²] (``sample``: as :meth:`normal`)."""
        n, _ = self.normal(t, sample)
        if self._sin == 0.0:
            return -n
        if self._k is not None:
            d, size = _unit(_cross(n, self._k))
        else:
            d, size = _unit(_across(n, self.path.direction_jet(t)))
        if not size > _MIN_NORM:
            raise self.undefined(LEAN_UNDEFINED, t)
        return -self._cos * n + self._sin * d

    def frame(
        self, t: float, sample: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(F (3, 3) columns x, a_d × x, a_d; ω_F (3,) [rad/s]; ω̇_F (3,) [rad/s²]) at t [s]
        (``sample``: as :meth:`normal`)."""
        a = self.axis(t, sample)
        x, size = _unit(_across(a, self.path.direction_jet(t)))
        if not size > _MIN_NORM:
            raise self.undefined(ROLL_UNDEFINED, t)
        y = _cross(a, x)
        omega = 0.5 * (cross3(x[0], x[1]) + cross3(y[0], y[1]) + cross3(a[0], a[1]))
        omega_dot = 0.5 * (cross3(x[0], x[2]) + cross3(y[0], y[2]) + cross3(a[0], a[2]))
        return np.column_stack([x[0], y[0], a[0]]), omega, omega_dot

    def undefined(self, what: int, t: float, p: np.ndarray | None = None) -> ReachError:
        """The ReachError of a direction undefined at time t [s]: ``what`` is
        NORMAL_UNDEFINED (∇Φ = 0 at p_d = p (3,) [m]), LEAN_UNDEFINED or ROLL_UNDEFINED (the
        codes of ``_pose_kernels.pose_goal``)."""
        if what == NORMAL_UNDEFINED:
            where = "?" if p is None else p.tolist()
            return ReachError(f"the surface normal is undefined at p_d(t = {t:.6g} s) = {where}")
        if what == LEAN_UNDEFINED:
            why = (
                "tool.tilt_axis is along the surface normal"
                if self._k is not None
                else "the path does not move across the normal (tool.tilt leans towards the travel)"
            )
            return ReachError(f"the tool's lean direction is undefined at t = {t:.6g} s: {why}")
        return ReachError(
            f'the tool\'s roll is undefined at t = {t:.6g} s: tool.roll = "held" keeps it '
            "relative to the direction of travel, and the path does not move across the axis"
        )


class ToolAngleProbe:
    """Measures the angle [rad] between an arm's tool axis and a desired direction.

    Args:
        robot: the arm (its own Pinocchio data is made here).
        settings: the ``[tool]`` settings (their ``axis``, in the tip frame).
    """

    def __init__(self, robot: Any, settings: ToolSettings) -> None:
        self.robot = robot
        self._data = robot.new_data()
        self._axis = np.array(settings.axis)

    def angle(self, q: np.ndarray, a_d: np.ndarray) -> float:
        """atan2(‖a × a_d‖, a·a_d) [rad] with a = R(q) â the tool axis at q (nq,) (world)."""
        model, data = self.robot.model, self._data
        pin.forwardKinematics(model, data, q)
        a = pin.updateFramePlacement(model, data, self.robot.tip_id).rotation @ self._axis
        return axis_angle(a, a_d)

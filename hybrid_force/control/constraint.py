"""Surfaces seen in joint space: J_Φ, its normalised rows, the projection Q and the drift.

For one surface Φ(p) = 0 (paper eq. 1) and an arm with tip p(q), the constraint row is

    J_Φ = ∇Φ(p)ᵀ J(q)                          (1, n)     (section 2)

The toolkit works with scaled rows A = J_Φ / s. Two scalings are offered:

* ``"joint"`` — the paper's J_Φn = J_Φ / ‖J_Φ‖ (section 2), a unit row in joint space. The
  multiplier f of eq. 2 is then a generalised force along that row, not newtons.
* ``"tip"`` (default) — A = n̂ᵀ J with n̂ = ∇Φ / ‖∇Φ‖ the unit surface normal. Then the
  multiplier f of ``M q̈ + C q̇ + g = u + Aᵀ f`` IS the normal contact force at the tip in
  newtons (the tool pushes on the surface with f n̂ … and the surface pushes back with −f n̂).

Both rows point the same way, so the projection (eq. 5, generalised to k rows)

    Q = I − A⁺ A,   A⁺ = Aᵀ (A Aᵀ)⁻¹

is the same matrix for either scaling; with k = 1 and the "joint" scaling, A⁺ = J_Φnᵀ and Q
is literally eq. 5. The sign convention: every surface has Φ > 0 on its free side (where the
tool is), so f > 0 means the surface pushes the tool back, i.e. the tool presses on it.

The acceleration-level constraint used by the simulator is the exact second time derivative
Φ̈ = J_Φ q̈ + J̇_Φ q̇ = 0 divided by s: A q̈ + γ = 0 with the drift

    γ = (q̇ᵀ Jᵀ ∇²Φ J q̇ + ∇Φᵀ J̇ q̇) / s       (issue 3: d(J_Φ)/dt · q̇, scaled)
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal, NamedTuple

import numpy as np

from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.errors import SurfaceError
from hybrid_force.geometry.surface_base import Surface
from hybrid_force.model.robot import Robot, RobotTerms

_K = LazyKernels("hybrid_force.control._kernels")

__all__ = ["DEPENDENT_RTOL", "Constraint", "ConstraintTerms", "Normalization", "dependent_rows"]

DEPENDENT_RTOL = 1e-9
"""Stacked constraint rows are dependent when σ_min(A) ≤ this · σ_max(A): A M⁻¹ Aᵀ is then
singular and the contact force undefined (two parallel planes through one point)."""

Normalization = Literal["tip", "joint"]
_NORMALIZATIONS = ("tip", "joint")
_GRAD_TOL = 1e-12  # ‖∇Φ‖ below this (relative to the surface's scale) is a singular point
_ROW_TOL = 1e-9  # ‖J_Φ‖ / (‖∇Φ‖ (1 + ‖J‖)) below this: the arm is singular w.r.t. the surface
_COND_TOL = 1e12  # cond(A Aᵀ) above this for k > 1: the stacked rows are dependent


@dataclass(frozen=True)
class ConstraintTerms:
    """Joint-space view of k surfaces at one state (q, v).

    Attributes:
        phi: (k,) Φ_i(p) [surface units, e.g. m² for the paper's cylinder].
        distance: (k,) signed metric distance d_i(p) [m], > 0 on the free side.
        J_phi: (k, n) raw rows J_Φ = ∇Φᵀ J.
        J_phi_n: (k, n) the paper's unit rows J_Φ / ‖J_Φ‖.
        scale: (k,) s_i, with A = J_Φ / s.
        A: (k, n) scaled constraint rows (see module docstring).
        Adot: (k, n) Ȧ.
        A_pinv: (n, k) A⁺ = Aᵀ (A Aᵀ)⁻¹.
        A_pinv_dot: (n, k) d(A⁺)/dt.
        Q: (n, n) projection I − A⁺A onto the tangent space (eq. 5).
        Qdot: (n, n) Q̇.
        rate: (k,) A v = Φ̇ / s.
        raw_drift: (k,) d(J_Φ)/dt · v = vᵀJᵀ∇²ΦJv + ∇ΦᵀJ̇v.
        drift: (k,) raw_drift / s: with it, A q̈ + drift = Φ̈ / s.
    """

    phi: np.ndarray
    distance: np.ndarray
    J_phi: np.ndarray
    J_phi_n: np.ndarray
    scale: np.ndarray
    A: np.ndarray
    Adot: np.ndarray
    A_pinv: np.ndarray
    A_pinv_dot: np.ndarray
    Q: np.ndarray
    Qdot: np.ndarray
    rate: np.ndarray
    raw_drift: np.ndarray
    drift: np.ndarray
    # (rows (4, k, n), cols (2, n, k), squares (2, n, n), scalars (6, k)) whose slices are
    # the fields above, when made by zeros(): what the compiled evaluation writes
    _packs: tuple[np.ndarray, ...] | None = field(default=None, repr=False, compare=False)
    # the one flat array the four packs are views of, in that order (zeros() only): the
    # kernels take it as one argument (``_kernels.constraint_parts``)
    _flat: np.ndarray | None = field(default=None, repr=False, compare=False)

    @classmethod
    def zeros(cls, k: int, n: int) -> ConstraintTerms:
        """Terms of k rows and n joints, every array zero (a buffer for ``evaluate``).

        The fields are views of four arrays: rows = [J_Φ, J_Φn, A, Ȧ], cols = [A⁺, Ȧ⁺],
        squares = [Q, Q̇], scalars = [Φ, d, s, A v, raw drift, drift], themselves views of
        one flat array in that order.
        """
        sizes = np.cumsum([4 * k * n, 2 * n * k, 2 * n * n, 6 * k])
        flat = np.zeros(int(sizes[-1]))
        rows = flat[: sizes[0]].reshape((4, k, n))
        cols = flat[sizes[0] : sizes[1]].reshape((2, n, k))
        squares = flat[sizes[1] : sizes[2]].reshape((2, n, n))
        scalars = flat[sizes[2] :].reshape((6, k))
        return cls(
            phi=scalars[0],
            distance=scalars[1],
            J_phi=rows[0],
            J_phi_n=rows[1],
            scale=scalars[2],
            A=rows[2],
            Adot=rows[3],
            A_pinv=cols[0],
            A_pinv_dot=cols[1],
            Q=squares[0],
            Qdot=squares[1],
            rate=scalars[3],
            raw_drift=scalars[4],
            drift=scalars[5],
            _packs=(rows, cols, squares, scalars),
            _flat=flat,
        )


class _Row(NamedTuple):
    """One surface's joint-space row at a state (see :meth:`Constraint._row`)."""

    phi: float
    row: np.ndarray
    row_dot: np.ndarray
    row_norm: float
    scale: float
    scale_dot: float
    raw_drift: float


class Constraint:
    """k rigid surfaces acting on one tip, as stacked joint-space rows.

    Args:
        surfaces: one surface or a sequence of k surfaces (all touched by the same tip).
        normalization: ``"tip"`` (default, f in newtons) or ``"joint"`` (the paper's J_Φn).
    """

    def __init__(
        self, surfaces: Surface | Sequence[Surface], normalization: Normalization = "tip"
    ) -> None:
        items: tuple[object, ...]
        if isinstance(surfaces, Surface):
            items = (surfaces,)
        elif isinstance(surfaces, Iterable) and not isinstance(surfaces, str | bytes | Mapping):
            items = tuple(surfaces)
        else:
            raise SurfaceError(
                f"surfaces must be a Surface or a sequence (list, tuple) of Surfaces, got "
                f"{surfaces!r} ({type(surfaces).__name__})"
            )
        if not items:
            raise SurfaceError("surfaces is empty: a constraint needs at least one surface")
        checked: list[Surface] = []
        for i, s in enumerate(items):
            if not isinstance(s, Surface):
                raise SurfaceError(
                    f"surfaces[{i}] is not a hybrid_force Surface (Cylinder, Sphere, Plane, "
                    f"FunctionSurface): {s!r} ({type(s).__name__})"
                )
            checked.append(s)
        if not isinstance(normalization, str) or normalization not in _NORMALIZATIONS:
            raise SurfaceError(
                f"normalization must be one of {', '.join(_NORMALIZATIONS)}, got {normalization!r}"
            )
        self.surfaces: tuple[Surface, ...] = tuple(checked)
        self.normalization: Normalization = normalization
        self._tip_scaling = normalization == "tip"
        # scratch ∇Φ and ∇²Φ written by the compiled evaluation (k = 1), after the flag
        # "tip": one array argument for three (_kernels.constraint_one_ws)
        self._scratch = np.zeros(13)
        self._scratch[0] = float(self._tip_scaling)
        self._grad, self._hess = self._scratch[1:4], self._scratch[4:].reshape(3, 3)
        self._one = len(self.surfaces) == 1  # evaluate() in one compiled call
        self._one_ws: Callable[..., tuple[float, float, float]] | None = None  # its entry

    @property
    def k(self) -> int:
        """Number of stacked constraints."""
        return len(self.surfaces)

    def distance(self, p: np.ndarray) -> np.ndarray:
        """(k,) signed metric distances of the point p (3,) to each surface [m]."""
        return np.array([s.distance(p) for s in self.surfaces])

    def evaluate(
        self,
        terms: RobotTerms,
        v: np.ndarray,
        out: ConstraintTerms | None = None,
    ) -> ConstraintTerms:
        """Joint-space quantities from the robot terms of one step.

        One surface (k = 1): one compiled call
        (:func:`hybrid_force.control._kernels.constraint_one`); k > 1: the general k-row
        algebra in numpy (:meth:`_evaluate_stacked`).

        Args:
            terms: the robot's terms at (q, v) (:meth:`Robot.terms`).
            v: (n,) joint velocity.
            out: for k = 1, terms whose arrays are overwritten (see
                :meth:`ConstraintTerms.zeros`); default: fresh arrays. Ignored for k > 1.

        Raises:
            SurfaceError: ∇Φ vanishes at the tip, J_Φ is (near) zero, or the
                stacked rows are dependent.
        """
        if self._one:
            return self._evaluate_one(terms, v, out)
        return self._evaluate_stacked(terms, v)

    def _evaluate_stacked(self, terms: RobotTerms, v: np.ndarray) -> ConstraintTerms:
        """The k > 1 case of :meth:`evaluate`: each surface's row (:meth:`_row`), then the
        stacked algebra A⁺ = Aᵀ(AAᵀ)⁻¹, Q = I − A⁺A and their derivatives (new arrays)."""
        rows = [self._row(i, s, terms) for i, s in enumerate(self.surfaces)]
        k, n = self.k, terms.J.shape[1]
        J_phi = np.array([r.row for r in rows])
        J_phi_dot = np.array([r.row_dot for r in rows])
        scale = np.array([r.scale for r in rows])
        scale_dot = np.array([r.scale_dot for r in rows])
        raw_drift = np.array([r.raw_drift for r in rows])
        inv_s = 1.0 / scale
        A = J_phi * inv_s[:, None]
        Adot = J_phi_dot * inv_s[:, None] - J_phi * (scale_dot * inv_s * inv_s)[:, None]
        gram = A @ A.T
        cond = np.linalg.cond(gram)
        if not np.isfinite(cond) or cond > _COND_TOL:
            raise SurfaceError(
                f"the {k} stacked constraint rows are (nearly) dependent at tip {terms.p.tolist()} "
                f"(cond(A Aᵀ) = {cond:.3g}): the surfaces are tangent there or the arm cannot "
                "move independently along their normals"
            )
        W = np.linalg.inv(gram)
        A_pinv = A.T @ W
        W_dot = -W @ (Adot @ A.T + A @ Adot.T) @ W
        A_pinv_dot = Adot.T @ W + A.T @ W_dot
        Q = np.eye(n) - A_pinv @ A
        Qdot = -(A_pinv_dot @ A + A_pinv @ Adot)
        return ConstraintTerms(
            phi=np.array([r.phi for r in rows]),
            distance=np.array([s.distance(terms.p) for s in self.surfaces]),
            J_phi=J_phi,
            J_phi_n=J_phi / np.array([r.row_norm for r in rows])[:, None],
            scale=scale,
            A=A,
            Adot=Adot,
            A_pinv=A_pinv,
            A_pinv_dot=A_pinv_dot,
            Q=Q,
            Qdot=Qdot,
            rate=A @ v,
            raw_drift=raw_drift,
            drift=raw_drift * inv_s,
        )

    def _row(self, i: int, surface: Surface, terms: RobotTerms) -> _Row:
        """One surface's row J_Φ = ∇ΦᵀJ (1, n), its derivative, scale and raw drift."""
        p, J, pdot = terms.p, terms.J, terms.pdot
        value, grad, hess, grad_norm = _gradient(
            i,
            surface,
            p,
            "the surface normal is undefined there (e.g. on a cylinder's axis or at a sphere's "
            "centre)",
        )
        h_pdot = hess @ pdot
        row = grad @ J
        row_dot = h_pdot @ J + grad @ terms.Jdot
        row_norm = float(np.sqrt(row @ row))
        if row_norm < _ROW_TOL * grad_norm * (1.0 + float(np.abs(J).max())):
            raise SurfaceError(
                f"J_Φ is (near) zero for surface {i} ({surface!r}) at tip {p.tolist()}: the arm "
                "cannot move its tip along the surface normal in this configuration, so J_Φn "
                "is undefined"
            )
        if self.normalization == "tip":
            scale, scale_dot = grad_norm, float(grad @ h_pdot) / grad_norm
        else:
            scale, scale_dot = row_norm, float(row @ row_dot) / row_norm
        return _Row(
            phi=float(value),
            row=row,
            row_dot=row_dot,
            row_norm=row_norm,
            scale=scale,
            scale_dot=scale_dot,
            raw_drift=float(pdot @ h_pdot + grad @ terms.Jdot_v),
        )

    def _evaluate_one(
        self, terms: RobotTerms, v: np.ndarray, out: ConstraintTerms | None
    ) -> ConstraintTerms:
        """The k = 1 case of :meth:`evaluate` in one compiled call (hot path).

        Surfaces with a closed form (``Surface._descriptor``) are evaluated inside the call;
        others (FunctionSurface) in Python first.
        """
        surface = self.surfaces[0]
        c = ConstraintTerms.zeros(1, terms.J.shape[1]) if out is None else out
        flat = c._flat
        if flat is None:
            raise SurfaceError("out must come from ConstraintTerms.zeros(k, n)")
        desc = surface._descriptor
        grad, hess = self._grad, self._hess
        if desc.shape[0] == 0:
            value, grad, hess, distance = surface.evaluate_with_distance(terms.p)
            c.phi[0] = value
            c.distance[0] = distance
        packs = terms._packs
        if packs is None:  # terms not made by RobotTerms.zeros: a packed copy
            packs = terms.packed()._packs
            assert packs is not None  # packed() always returns terms with their packs
        _, _, jac, tip = packs
        if grad is self._grad:  # a closed form: ∇Φ, ∇²Φ written into the scratch
            kernel = self._one_ws
            if kernel is None:  # bound at the first call: the packs of any terms and rows
                # made by zeros(), an (n,) velocity, the surface's own descriptor
                kernel = self._one_ws = entry(
                    _K.constraint_one_ws, desc, self._scratch, jac, tip, v, flat
                )
            grad_norm, row_norm, jmax = kernel(desc, self._scratch, jac, tip, v, flat)
        else:
            grad_norm, row_norm, jmax = _K.constraint_one_flat(
                desc, grad, hess, jac, tip, v, self._tip_scaling, flat
            )
        if not grad_norm >= _GRAD_TOL or not row_norm >= _ROW_TOL * grad_norm * (1.0 + jmax):
            self._row(0, surface, terms)  # raises the precise SurfaceError
        return c

    def normal_rows(self, p: np.ndarray, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit-normal rows and first-order distances, for placing the tip on the surfaces.

        Args:
            p: (3,) tip position [m]. J: (3, n) tip Jacobian.

        Returns:
            rows: (k, n) n̂ᵀJ (the "tip" scaling, whatever ``normalization`` is);
            dist: (k,) Φ / ‖∇Φ‖ [m], the Newton step length along n̂ to the surface.
        """
        rows = np.empty((self.k, J.shape[1]))
        dist = np.empty(self.k)
        for i, surface in enumerate(self.surfaces):
            phi, grad, _, norm = _gradient(i, surface, p, "no normal to place the tip along")
            rows[i] = (grad / norm) @ J
            dist[i] = phi / norm
        return rows, dist

    def at(self, robot: Robot, q: object, v: object | None = None) -> ConstraintTerms:
        """Convenience: validate (q, v) and evaluate for ``robot`` (v defaults to zero)."""
        q = robot.check_q(q)
        v = np.zeros(robot.nv) if v is None else robot.check_v(v)
        return self.evaluate(robot.terms(q, v, robot.new_data()), v)

    def __repr__(self) -> str:
        return f"Constraint({list(self.surfaces)!r}, normalization={self.normalization!r})"


def dependent_rows(rows: np.ndarray) -> tuple[list[int], np.ndarray] | None:
    """The rows of a (k, n) constraint matrix A that are linearly dependent, or None.

    Returns:
        None when A has full row rank (σ_min > DEPENDENT_RTOL · σ_max), else the rows that
        take part in the dependency (those with a large share of the left singular vector of
        σ_min) and A's singular values (k,).
    """
    u, sigma, _ = np.linalg.svd(rows, full_matrices=True)
    k = rows.shape[0]
    smallest = sigma[k - 1] if sigma.size == k else 0.0  # k > n: rank at most n < k
    if smallest > DEPENDENT_RTOL * max(float(sigma[0]) if sigma.size else 0.0, 1e-300):
        return None
    share = np.abs(u[:, k - 1])
    return [int(i) for i in np.flatnonzero(share > 0.1 * share.max())], sigma


def _gradient(
    i: int, surface: Surface, p: np.ndarray, consequence: str
) -> tuple[float, np.ndarray, np.ndarray, float]:
    """(Φ, ∇Φ, ∇²Φ, ‖∇Φ‖) of surface i at p; SurfaceError where ∇Φ vanishes
    (the message ends with ``consequence``)."""
    value, grad, hess = surface.evaluate(p)
    norm = float(np.sqrt(grad @ grad))
    if norm < _GRAD_TOL:
        raise SurfaceError(
            f"∇Φ vanishes at tip position {p.tolist()} on surface {i} ({surface!r}): " + consequence
        )
    return value, grad, hess, norm

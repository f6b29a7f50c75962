"""The oracle of the plant: the same plant in readable numpy, and the dense KKT solve.

:class:`OraclePlant` is :class:`~hybrid_force.sim.plant.Plant` with every robot term from its
own Pinocchio call and the general k-row constraint algebra (:mod:`oracles.terms`), the
constrained dynamics from a dense solve of the KKT system (:func:`kkt`) instead of
``pin.forwardDynamics`` and the loop's kernel, the velocity correction by its formula with
dense solves instead of ``pin.impulseDynamics``, and no compiled contact step.
:func:`use_oracle_plant` makes :func:`~hybrid_force.sim.loop.simulate` build it.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import hybrid_force.sim.loop as loop
from hybrid_force.control.constraint import ConstraintTerms
from hybrid_force.control.laws.base import Command
from hybrid_force.errors import SurfaceError
from hybrid_force.model.robot import RobotTerms
from hybrid_force.sim.plant import Plant
from hybrid_force.sim.rigid_contact import RigidContact
from oracles.terms import constraint_terms, robot_terms

__all__ = ["OraclePlant", "OracleRigidContact", "kkt", "use_oracle_plant"]


def kkt(
    M: np.ndarray,
    nle: np.ndarray,
    u0: np.ndarray,
    B: np.ndarray | None,
    A: np.ndarray,
    gamma: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """q̈ (n,) and f (k,) of M q̈ + nle = u0 + B f + Aᵀ f, A q̈ + γ = 0 (eq. 2 with the loop
    u = u0 + B f), by one dense solve of

    ```text
    [ M   −(Aᵀ + B) ] [q̈]   [u0 − nle]
    [ A        0    ] [f ] = [  −γ    ]
    ```
    """
    n, k = M.shape[0], A.shape[0]
    K = np.zeros((n + k, n + k))
    K[:n, :n] = M
    K[:n, n:] = -(A.T + (0.0 if B is None else B))
    K[n:, :n] = A
    sol = np.linalg.solve(K, np.concatenate([u0 - nle, -gamma]))
    return sol[:n], sol[n:]


class OracleRigidContact(RigidContact):
    """The rigid contact with the dense KKT solve and no compiled contact step."""

    compiles = False

    def _constrained(
        self, terms: RobotTerms, cons: ConstraintTerms, cmd: Command
    ) -> tuple[np.ndarray, np.ndarray]:
        arm = self.arm
        gamma = arm.baumgarte.gamma(cons.drift, cons.rate, cons.phi / cons.scale)
        return kkt(arm._M(terms), arm._nle(terms), cmd.u0, self._loop_B(cmd.B), cons.A, gamma)


class OraclePlant(Plant):
    """:class:`~hybrid_force.sim.plant.Plant` in readable numpy (module docstring)."""

    rigid_contact = OracleRigidContact

    def evaluate(self, q: np.ndarray, v: np.ndarray) -> tuple[RobotTerms, ConstraintTerms | None]:
        terms = robot_terms(self.robot, q, v)
        self._joints_at(v, None)  # the dense solves read _M(terms)
        try:
            return terms, constraint_terms(self.constraint, terms, v)
        except SurfaceError:  # undefined rows: an error in contact, none off the surface
            if self.in_contact:
                raise
            return terms, None

    def _impulse(self, q: np.ndarray, v: np.ndarray, A: np.ndarray) -> np.ndarray:
        """v⁺ = v − M⁻¹Aᵀ (A M⁻¹ Aᵀ)⁻¹ A v with M = M(q), by dense solves."""
        M = pin.crba(self.robot.model, self._imp, q)
        M = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle
        X = np.linalg.solve(M, A.T)
        return v - X @ np.linalg.solve(A @ X, A @ v)


def use_oracle_plant(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make :func:`~hybrid_force.sim.loop.simulate` build :class:`OraclePlant` (for this test)."""
    monkeypatch.setattr(loop, "Plant", OraclePlant)

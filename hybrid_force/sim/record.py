"""The run's record: every sample of a run in one preallocated table, one compiled call per row.

The column layout is defined here (:meth:`Record.widths`) and written in the same order by
:func:`hybrid_force.sim._kernels.record_row`.
"""

from __future__ import annotations

import numpy as np

from hybrid_force._lazy import LazyKernels
from hybrid_force.result import Result

_K = LazyKernels("hybrid_force.sim._kernels")

__all__ = ["Record"]


class Record:
    """The run's samples, preallocated as one (N, width) table; one compiled call per row.

    The fields (t, q, v, q_d, u, p, p_d, f, f_d, phi, V, phase) are column views of the table,
    in that order (:func:`hybrid_force._kernels.record_row` writes a row in the same order).
    """

    @staticmethod
    def widths(nq: int, nv: int, k: int) -> tuple[int, ...]:
        """Columns of each field, in table order."""
        return (1, nq, nv, nq, nv, 3, 3, k, k, k, 1, 1)

    @classmethod
    def width(cls, nq: int, nv: int, k: int) -> int:
        """Float64 numbers per sample."""
        return sum(cls.widths(nq, nv, k))

    def __init__(
        self,
        N: int,
        nq: int,
        nv: int,
        k: int,
        max_velocity: float,
        max_force: float,
        *,
        measured: bool = False,
        commanded: bool = False,
        law_signals: int = 0,
        tool: bool = False,
    ) -> None:
        self.max_velocity, self.max_force = max_velocity, max_force
        # the measured force (N, k), when it is not the plant's force (sampled sensing)
        self.f_meas: np.ndarray | None = np.zeros((N, k)) if measured else None
        # the commanded torque (N, n), when effort limits may make it differ from the applied
        self.u_cmd: np.ndarray | None = np.zeros((N, nv)) if commanded else None
        # the law's own signals (N, m), when it logs some (Law.log_names)
        self.law_log: np.ndarray | None = np.zeros((N, law_signals)) if law_signals else None
        # the tool axis' angle from its desired direction (N,) [rad], when the run controls it
        self.tool_angle: np.ndarray | None = np.zeros(N) if tool else None
        widths = self.widths(nq, nv, k)
        self.table = np.zeros((N, sum(widths)))
        views = []
        start = 0
        for w in widths:
            views.append(self.table[:, start : start + w])
            start += w
        (t, self.q, self.v, self.q_d, self.u, self.p, self.p_d, self.f, self.f_d, self.phi, V,
         phase) = views  # fmt: skip
        self.t, self.V, self.phase = t[:, 0], V[:, 0], phase[:, 0]

    def record(
        self,
        i: int,
        t: float,
        q: np.ndarray,
        v: np.ndarray,
        q_d: np.ndarray,
        u0: np.ndarray,
        B: np.ndarray,
        f: np.ndarray,
        p: np.ndarray,
        p_d: np.ndarray,
        f_d: np.ndarray,
        phi: np.ndarray,
        V: float,
        phase: int,
    ) -> bool:
        """Write sample i, with the command u = u0 + B f (B: (n, k), zeros when u ignores f).

        Returns True when q, v, f are finite, |v_i| ≤ max_velocity and |f_m| ≤ max_force
        (otherwise :func:`hybrid_force.sim.loop` says which and raises).
        """
        return _K.record_row(
            self.table, i, t, q, v, q_d, u0, B, f, p, p_d, f_d, phi, V, phase,
            self.max_velocity, self.max_force,
        )  # fmt: skip

    def result(self, n: int, meta: dict, k: int) -> Result:
        def own(a: np.ndarray) -> np.ndarray:
            return np.ascontiguousarray(a[:n])

        def col(a: np.ndarray) -> np.ndarray:
            return own(a[:, 0] if k == 1 else a)

        return Result(
            t=own(self.t),
            q=own(self.q),
            v=own(self.v),
            q_d=own(self.q_d),
            u=own(self.u),
            p=own(self.p),
            p_d=own(self.p_d),
            f=col(self.f),
            f_d=col(self.f_d),
            phi=col(self.phi),
            V=own(self.V),
            phase=self.phase[:n].astype(np.int64),
            meta=meta,
            f_meas=None if self.f_meas is None else col(self.f_meas),
            u_cmd=None if self.u_cmd is None else own(self.u_cmd),
            law_log=None if self.law_log is None else own(self.law_log),
            tool_angle=None if self.tool_angle is None else own(self.tool_angle),
        )

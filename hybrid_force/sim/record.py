"""The run's record: every sample of a run in one preallocated table, one call per sample.

:class:`Record` is built from the run's objects (the scenario, the plant, the control side)
and pulls from them what a sample holds: the desired joint path and point, the desired force,
the law's Lyapunov function and its own signals, the applied and the commanded torque, the
measured force, the tool's angle and the phase. The column layout is defined here
(:meth:`Record.widths`) and written in the same order by
:func:`hybrid_force.sim._kernels.record_row`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.control.laws.base import Command, check_log_source, law_log_names
from hybrid_force.geometry.offset import contact_points
from hybrid_force.model.robot import RobotTerms
from hybrid_force.phases import CONTACT
from hybrid_force.result import Result
from hybrid_force.sim.control_side import ControlSide, ToolLog
from hybrid_force.sim.plant import Plant
from hybrid_force.sim.removal_run import RemovalObserver
from hybrid_force.sim.run_checks import check_log_memory
from hybrid_force.sim.settings import Scenario

_K = LazyKernels("hybrid_force.sim._kernels")

__all__ = ["Record"]

# entries of the record's buffer before its table (_kernels.RECORD_HEADER)
_RECORD_HEADER = 6


class Record:
    """The samples of one run, preallocated as one (N, width) table, one call per sample.

    Args:
        sc: the run. plant: its plant. ctrl: its control side. N: samples of the run.

    Raises:
        BadInputError (from :func:`~hybrid_force.sim.run_checks.check_log_memory`): the
            record would not fit in memory.

    The fields (t, q, v, q_d, u, p, p_d, f, f_d, phi, V, phase) are column views of the table,
    in that order (:func:`hybrid_force.sim._kernels.record_row` writes a row in the same
    order); ``f_meas`` (N, k) [N], ``u_cmd`` (N, n), ``law_log`` (N, m) and ``tool_angle``
    (N,) [rad] are kept beside it when the run has them; a ball-end tool's contact points
    (``tool.radius`` > 0) are found from p when the result is made.

    Attributes:
        law_signals: the names of the law's own signals (``law_log``'s columns).
        filled: the samples written so far (a failed run's partial result keeps them).
    """

    @staticmethod
    def widths(nq: int, nv: int, k: int) -> tuple[int, ...]:
        """Columns of each field, in table order."""
        return (1, nq, nv, nq, nv, 3, 3, k, k, k, 1, 1)

    @classmethod
    def width(cls, nq: int, nv: int, k: int) -> int:
        """Float64 numbers per sample."""
        return sum(cls.widths(nq, nv, k))

    def __init__(self, sc: Scenario, plant: Plant, ctrl: ControlSide, N: int) -> None:
        sim, nq, nv, k = sc.sim, sc.robot.nq, sc.robot.nv, plant.constraint.k
        law = ctrl.law
        self.law_signals = law_log_names(law.law if law is not None else None)
        check_log_memory(N, self.width(nq, nv, k) + len(self.law_signals), sim.duration, sim.dt)
        self.max_velocity, self.max_force = sim.max_velocity, sim.max_force
        self._plant, self._ctrl, self._law, self._path = plant, ctrl, law, sc.path
        self._clik = law.clik if law is not None else None
        self._task_f_d = sc.control.f_d_for(k)
        self._no_q_d, self._no_B = np.full(nq, np.nan), np.zeros((nv, k))
        self._p_d = np.zeros(3)  # the path's point, when it is not the CLIK's
        self._row: Callable[..., bool] | None = None  # record_row's entry, at the first sample
        # the law's own signals (its optional log hook): gathered by record_row at every
        # sample from the law's own array
        m = len(self.law_signals)
        source: tuple[np.ndarray, np.ndarray] = (
            check_log_source(law.law, m)
            if law is not None and m
            else (np.zeros(0), np.zeros(0, dtype=np.int64))
        )
        self._log_values, self._log_index = source
        self._tool = ToolLog(sc, law, ctrl.measured) if sc.tool.controlled else None
        # the measured force (N, k), when it is not the plant's force (sampled sensing)
        self.f_meas: np.ndarray | None = np.zeros((N, k)) if ctrl.measured else None
        # the commanded torque (N, n), when effort limits may make it differ from the applied
        m_cmd = nv if plant.effort is not None else 0
        self._no_u = np.zeros(0)  # no applied torque of the limits: the command is applied
        # the tool axis' angle from its desired direction (N,) [rad], when the run controls it
        self.tool_angle: np.ndarray | None = np.zeros(N) if self._tool is not None else None
        # a ball-end tool: its contact points, found from the centres p after the run
        self._ball = (sc.tool_surfaces, sc.tool.radius) if sc.tool.radius > 0.0 else None
        # Preston's removal on the part, when the run has [removal] (None: nothing is done)
        self.removal = RemovalObserver(sc, N) if sc.removal is not None else None
        widths = self.widths(nq, nv, k)
        W = sum(widths)
        # the table, u_cmd and the law's signals (N, m) as views of one buffer, with the
        # limits record_row checks: its one argument instead of five (Numba's call costs
        # ~0.14 µs per array argument); the layout of _kernels.record_parts
        o = _RECORD_HEADER
        self._buf = np.zeros(o + N * (W + m_cmd + m))
        self._buf[:o] = (sim.max_velocity, sim.max_force, N, W, m_cmd, m)
        self.table = self._buf[o : o + N * W].reshape(N, W)
        o += N * W
        self.u_cmd: np.ndarray | None = (
            self._buf[o : o + N * m_cmd].reshape(N, m_cmd) if m_cmd else None
        )
        o += N * m_cmd
        self.law_log: np.ndarray | None = self._buf[o:].reshape(N, m) if m else None
        views = []
        start = 0
        for w in widths:
            views.append(self.table[:, start : start + w])
            start += w
        (t, self.q, self.v, self.q_d, self.u, self.p, self.p_d, self.f, self.f_d, self.phi, V,
         phase) = views  # fmt: skip
        self.t, self.V, self.phase = t[:, 0], V[:, 0], phase[:, 0]
        self.filled = 0
        if self.removal is not None:  # it reads the recorded tip and force in batches
            self.removal.attach(self.p, self.f)
        # what a sample holds besides the table's row: decided once, not tested per sample
        self._extras = self.f_meas is not None or self._tool is not None or self.removal is not None
        # the desired point is the law's own CLIK sample (the law runs at every plant step)
        self._own_p_d = self._clik is not None and not ctrl.measured

    def record(
        self,
        i: int,
        t: float,
        q: np.ndarray,
        v: np.ndarray,
        terms: RobotTerms,
        cmd: Command,
        f: np.ndarray,
        distance: np.ndarray,
    ) -> bool:
        """Write sample i at time t [s]: the state (q, v), the plant's terms there, the command
        u = u0 + B f (or the torque the effort limits let through), the contact force f (k,)
        [N] and the tip's distances (k,) [m]; the rest from the run's objects.

        Returns True when q, v, f are finite, |v_i| ≤ max_velocity and |f_m| ≤ max_force
        (otherwise :func:`~hybrid_force.sim.run_checks.check_finite` says which).
        """
        plant, law, clik = self._plant, self._law, self._clik
        applied, B = plant.applied, cmd.B
        if self._own_p_d and clik is not None:
            p_d = clik.p_d
        else:  # sampled: the desired point now, not the one of the last tick (held 1/rate s)
            p_d = self._p_d
            p_d[:] = self._path.position(t)  # (into this buffer: any path's array)
        args = (
            self._buf, i, t, q, v,
            clik.q if clik is not None else self._no_q_d,
            # the command u0 + B f: the applied torque unless the effort limits changed it
            cmd.u0, self._no_B if B is None else B,
            f, terms.p, p_d,
            law.f_d if law is not None else self._task_f_d,
            distance,
            law.V if law is not None else math.nan,
            # the plant's contact state: a tool off the surface is never logged in contact
            CONTACT if plant.in_contact else self._ctrl.phase(distance),
            # the applied torque (the commanded torque, before the limits, goes to u_cmd)
            self._no_u if applied is None else applied,
            self._log_values, self._log_index,
        )  # fmt: skip
        row = self._row
        if row is None:  # bound at the first sample (entry): the arrays of later ones,
            # t and V as floats (a Python int given later is converted, not the reverse)
            row = self._row = entry(_K.record_row, *args[:2], float(t), *args[3:13],
                                    float(args[13]), *args[14:])  # fmt: skip
        ok = row(*args)
        if self._extras:
            self._record_extras(i, t, q, terms, f)
        self.filled = i + 1
        return bool(ok)

    def _record_extras(
        self, i: int, t: float, q: np.ndarray, terms: RobotTerms, f: np.ndarray
    ) -> None:
        """Sample i of what the run keeps beside the table and its buffer (measured force, the
        tool's angle, the removal)."""
        ctrl = self._ctrl
        if self.f_meas is not None:
            self.f_meas[i] = ctrl.f_meas
        if self._tool is not None:
            assert self.tool_angle is not None
            self.tool_angle[i] = self._tool.angle(t, q)
        if self.removal is not None:  # the tip, its velocity J v and the contact force
            self.removal.observe(i, terms.p, terms.pdot, f)

    def result(self, n: int, meta: dict, k: int) -> Result:
        """The first n samples as a Result with ``meta``; k: the constraint's rows."""

        def own(a: np.ndarray) -> np.ndarray:
            return np.ascontiguousarray(a[:n])

        def col(a: np.ndarray) -> np.ndarray:
            return own(a[:, 0] if k == 1 else a)

        removal = self.removal
        if removal is not None:
            removal.finish(min(n, self.filled))
            meta = {**meta, "removal": removal.summary()}

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
            contact_point=None if self._ball is None else self._contact_points(own(self.p), k),
            removal_points=None if removal is None else removal.grid.points,
            removal_depth=None if removal is None else removal.grid.depth,
            removal_target=None if removal is None else removal.target.astype(np.float64),
        )

    def _contact_points(self, centres: np.ndarray, k: int) -> np.ndarray:
        """The ball's contact points c = p − r n̂ at the tool centres (N, 3) [m]: (N, 3), or
        (N, k, 3) for k stacked surfaces (one on each)."""
        assert self._ball is not None
        surfaces, radius = self._ball
        each = [contact_points(s, radius, centres) for s in surfaces[:k]]
        return each[0] if k == 1 else np.stack(each, axis=1)

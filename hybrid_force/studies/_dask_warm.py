"""The Dask worker plugin of a sweep: each worker loads the compiled kernels once, not per task.

A module of its own because it subclasses ``distributed.WorkerPlugin``: imported only by a
sweep on Dask (and by the workers, which unpickle the plugin by reference).
"""

from __future__ import annotations

from typing import Any

from distributed import WorkerPlugin

from hybrid_force.studies.tasks import _Task, warm_up


class WarmUp(WorkerPlugin):
    """Registered by the sweep: every worker, present or joining later, runs :func:`warm_up`
    on the sweep's first task when it gets the plugin (before it takes the sweep's tasks)."""

    name = "hybrid_force-warm-up"

    def __init__(self, task: _Task) -> None:
        self.task = task

    def setup(self, worker: Any) -> None:
        warm_up(self.task)

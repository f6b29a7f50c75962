"""Where a sweep's tasks run: a local process pool or a Dask cluster, workers warmed once.

Both engines keep a bounded number of tasks in flight (:func:`_pump`) and hand every finished
row back as it arrives. Local workers start with the numeric libraries on one thread, load the
compiled kernels once (before their first task), and die with the sweep.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import gc
import itertools
import logging
import multiprocessing
import os
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import wait as _futures_wait
from typing import Any, Literal

from hybrid_force._extras import require as require_extra
from hybrid_force.errors import BadInputError
from hybrid_force.studies.tasks import _execute, _one_line, _Outcome, _Task, warm_up

__all__ = ["THREAD_VARIABLES", "single_threaded_workers"]

# ----------------------------------------------------------------------------- worker processes
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def _watch_parent(parent_pid: int) -> None:
    """Make this worker process die (SIGKILL) as soon as its parent, ``parent_pid``, dies.

    The initialiser of the sweep's local worker processes, so that even a ``kill -9`` of the
    sweep leaves none behind. On Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` (the kernel kills
    us when the parent's thread that started us exits: the sweep's main thread); elsewhere, or
    if prctl fails, a daemon thread polls ``os.getppid()`` every 0.2 s. A parent that died
    before the watch was armed is caught by comparing ``os.getppid()`` with ``parent_pid``.
    """
    armed = False
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent_pid:
        os._exit(1)  # orphaned already

    if not armed:

        def poll() -> None:
            while os.getppid() == parent_pid:
                time.sleep(0.2)
            os._exit(1)

        threading.Thread(target=poll, name="hybrid_force parent watch", daemon=True).start()


Job = tuple[str, _Task | dict[str, Any]]
"""A variant's run id and its task, or its finished row when it is bad input already."""
Finish = Callable[[dict[str, Any], bytes | None], None]

#: A chunk of short runs is sized to take about this long [s] in a worker: long enough that the
#: per-task cost of a dispatch (pickling, a queue or a scheduler round trip) is small beside it,
#: short enough that rows stream back and the work stays balanced between workers.
CHUNK_SECONDS = 0.25


def _execute_chunk(tasks: list[_Task]) -> list[_Outcome]:
    """Run tasks one after the other in this worker (a chunk of short runs); never raises."""
    return [_execute(task) for task in tasks]


class _ChunkSize:
    """How many tasks go in the next dispatch: 1 until runs have finished, then as many as fill
    :data:`CHUNK_SECONDS` at the median run time, and never more than a fair share of what is
    left (so no worker is handed the tail of the sweep while another is idle)."""

    def __init__(self, n_jobs: int, workers: int) -> None:
        self.left = n_jobs
        self.workers = max(1, workers)
        self.times: list[float] = []

    def observe(self, row: dict[str, Any]) -> None:
        wall = row.get("wall_time")
        if isinstance(wall, float) and row.get("status") != "bad input":
            self.times.append(wall)

    def next(self) -> int:
        if not self.times:
            return 1
        ordered = sorted(self.times)
        median = max(ordered[len(ordered) // 2], 1e-6)
        share = max(1, self.left // (2 * self.workers))
        return max(1, min(int(CHUNK_SECONDS / median), share))


def _pump(
    jobs: Iterator[Job],
    submit: Callable[[list[_Task]], Any],
    wait_first: Callable[[list[Any]], Iterable[Any]],
    limit: int,
    finish: Finish,
    lost: list[str],
    sizes: _ChunkSize,
    *,
    stop_on_loss: bool,
    in_flight: Mapping[Any, list[str]] | None = None,
) -> None:
    """Keep at most ``limit`` chunks in flight and hand each finished row to ``finish``.

    Tasks are made (their scenario data read) only when submitted, so a long sweep holds a few
    of them in memory, not all. A future that raised (a lost worker, not a failed run:
    :func:`_execute` never raises) is recorded in ``lost`` with its run ids; with
    ``stop_on_loss`` (a broken process pool takes no more work) nothing more is submitted.
    ``in_flight``: chunks submitted already (future → run ids), waited for like the others.
    """
    pending: dict[Any, list[str]] = dict(in_flight or {})
    more = True

    def refill() -> None:
        nonlocal more
        while more and len(pending) < limit:
            chunk: list[_Task] = []
            want = sizes.next()
            while len(chunk) < want:
                job = next(jobs, None)
                if job is None:
                    more = False
                    break
                sizes.left -= 1
                if isinstance(job[1], _Task):
                    chunk.append(job[1])
                else:
                    finish(job[1], None)  # bad input found here: no worker needed
            if not chunk:
                return
            try:
                pending[submit(chunk)] = [t.run_id for t in chunk]
            except Exception as exc:  # e.g. BrokenProcessPool: a worker died
                lost.append(f"{chunk[0].run_id}: {type(exc).__name__}: {_one_line(str(exc))}")
                more = False

    refill()
    while pending:
        for fut in wait_first(list(pending)):
            rids = pending.pop(fut)
            try:
                outcomes = fut.result()
            except Exception as exc:
                lost.extend(f"{rid}: {type(exc).__name__}: {_one_line(str(exc))}" for rid in rids)
                more = more and not stop_on_loss
                continue
            for row, blob in outcomes:
                sizes.observe(row)
                finish(row, blob)
        refill()


def _first_done(futures: list[Future[Any]]) -> Iterable[Future[Any]]:
    return _futures_wait(futures, return_when=FIRST_COMPLETED).done


#: Thread-pool sizes of the numeric libraries, set to 1 in the workers a sweep starts: each
#: run is one small serial loop, and n workers × the machine's cores threads would only fight
#: over the cores (oversubscription).
THREAD_VARIABLES = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "NUMBA_NUM_THREADS",
)


@contextlib.contextmanager
def single_threaded_workers() -> Iterator[None]:
    """While open, processes started from this one run their numeric libraries on one thread.

    Sets each of :data:`THREAD_VARIABLES` that is not already set to "1" (a value the user set
    is kept), and restores the environment on exit. The workers read them when they start
    (a "spawn" pool, a LocalCluster's worker processes).
    """
    added = [name for name in THREAD_VARIABLES if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


StartMethod = Literal["auto", "fork", "spawn"]
"""How pool workers start: "fork" (a copy of this process, its kernels loaded already),
"spawn" (a fresh interpreter that imports and loads them itself), "auto" (fork where safe)."""


def _start_worker(parent_pid: int, warm: _Task | None, forked: bool) -> None:
    """Initialiser of a pool worker: die with the sweep, then load the kernels ``warm`` uses.

    Runs once per worker process, before its first task and while the sweep still prepares
    (the workers are started first), so no run pays for the imports and the kernels. A forked
    worker has them already; it drops the sweep's SIGTERM handler (the sweep stops its
    workers itself) and the thread pools the numeric libraries started before the fork, and
    freezes the objects it inherited (see :func:`gc.freeze`).
    """
    _watch_parent(parent_pid)
    if forked:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        _one_blas_thread()
        # what the fork copied (modules, kernels) lives as long as the worker: out of the
        # garbage collector's scans, which would otherwise walk it again and again
        gc.freeze()
    if warm is not None:
        warm_up(warm)


def _one_blas_thread() -> None:
    """Set every OpenBLAS loaded in this process (numpy's, scipy's) to one thread.

    The thread variables are read when a library loads: in a forked worker the libraries were
    loaded by the sweep's process, with a thread per core. Linux only (reads /proc); a library
    without the usual entry point is left as it is.
    """
    try:
        with open("/proc/self/maps", encoding="utf-8") as fh:
            paths = {line.split()[-1] for line in fh if "openblas" in line.lower()}
    except OSError:
        return
    names = (
        "scipy_openblas_set_num_threads64_",
        "scipy_openblas_set_num_threads",
        "openblas_set_num_threads64_",
        "openblas_set_num_threads",
    )
    for path in sorted(p for p in paths if p.startswith("/")):
        with contextlib.suppress(OSError):
            lib = ctypes.CDLL(path)
            for name in names:
                setter = getattr(lib, name, None)
                if setter is not None:
                    setter(1)
                    break


def _ready() -> None:
    """A no-op task: submitting one per worker makes the pool start every worker now."""


def _fork_is_safe() -> bool:
    """Fork only on Linux, from a process with no other Python thread (a thread holding a lock
    at the fork would leave the copy stuck). Native threads of OpenBLAS, which pauses them
    across a fork (pthread_atfork), are allowed."""
    return (
        sys.platform.startswith("linux")
        and "fork" in multiprocessing.get_all_start_methods()
        and threading.active_count() == 1
    )


class PoolEngine:
    """Local worker processes, started by :meth:`start` and warmed there, reused for every run.

    With ``start_method`` "fork" (the default "auto" where :func:`_fork_is_safe`), this process
    loads the kernels once (a few steps of the first task) and forks the workers, ready at
    once: no worker pays for a Python start, the imports and the kernels. With "spawn", each
    worker is a fresh interpreter that does that in its initialiser, while this process goes
    on preparing the sweep. The workers die with this process (:func:`_watch_parent`);
    :meth:`close` kills them (SIGKILL) and reaps them, at once whether idle or running.
    """

    def __init__(
        self, workers: int | None, n_jobs: int, start_method: StartMethod = "auto"
    ) -> None:
        if start_method not in ("auto", "fork", "spawn"):
            raise BadInputError(f"start_method must be auto, fork or spawn, got {start_method!r}")
        self.n = max(1, min(int(workers or os.cpu_count() or 1), n_jobs))
        if start_method == "auto":
            start_method = "fork" if _fork_is_safe() else "spawn"
        self.start_method = start_method
        self.pool: ProcessPoolExecutor | None = None
        self.ahead: dict[Future[list[_Outcome]], str] = {}

    def start(self, warm: _Task | None) -> None:
        """Start every worker now; each has the kernels of ``warm`` before taking work."""
        forked = self.start_method == "fork"
        ctx = multiprocessing.get_context(self.start_method)
        # a worker reads the thread variables when it starts: keep them set while it does
        with single_threaded_workers(), warnings.catch_warnings():
            # Python >= 3.12 warns at any fork of a process with several OS threads; the
            # only ones here are OpenBLAS's (see _fork_is_safe)
            warnings.filterwarnings("ignore", ".*fork.*", DeprecationWarning)
            if forked and warm is not None:
                warm_up(warm)
            self.pool = ProcessPoolExecutor(
                max_workers=self.n,
                mp_context=ctx,
                initializer=_start_worker,
                initargs=(os.getpid(), None if forked else warm, forked),
            )
            for _ in range(self.n):
                self.pool.submit(_ready)

    def send_ahead(self, tasks: Iterable[_Task]) -> None:
        """Start the first of ``tasks`` now, one per worker, while the sweep checks its
        scenario and writes its files (a few hundredths of a second that the workers would
        otherwise wait). Their rows are taken by :meth:`run` if their variants are still to
        do then, and dropped if not; a failed check stops them with the workers."""
        assert self.pool is not None, "start() first"
        for task in itertools.islice(tasks, self.n):
            self.ahead[self.pool.submit(_execute_chunk, [task])] = task.run_id

    @property
    def sent_ahead(self) -> frozenset[str]:
        """The run ids of the tasks :meth:`send_ahead` started (and :meth:`keep_ahead` kept)."""
        return frozenset(self.ahead.values())

    def keep_ahead(self, todo: Collection[str]) -> frozenset[str]:
        """Keep the tasks sent ahead whose run ids are in ``todo`` (:meth:`run` takes their
        rows; the others' are dropped); return the run ids kept."""
        self.ahead = {f: rid for f, rid in self.ahead.items() if rid in todo}
        return self.sent_ahead

    def run(self, jobs: Iterator[Job], n_jobs: int, finish: Finish, lost: list[str]) -> None:
        """Run every job (``n_jobs`` of them) and the tasks kept ahead, rows handed to
        ``finish`` as they come back."""
        pool = self.pool
        assert pool is not None, "start() first"
        _pump(
            jobs,
            lambda chunk: pool.submit(_execute_chunk, chunk),
            _first_done,
            2 * self.n,
            finish,
            lost,
            _ChunkSize(n_jobs, self.n),
            stop_on_loss=True,
            in_flight={f: [rid] for f, rid in self.ahead.items()},
        )

    def close(self, failed: bool = False) -> None:
        """Kill and reap the workers (idle at the end of a sweep, or busy after a failure)."""
        if self.pool is not None:
            _kill_pool(self.pool)
            self.pool = None


def _kill_pool(pool: ProcessPoolExecutor) -> None:
    """Stop a process pool now: cancel what is queued, kill (SIGKILL) and reap its workers."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        with contextlib.suppress(Exception):
            proc.kill()
    for proc in processes:
        with contextlib.suppress(Exception):
            proc.join(timeout=5.0)
    if isinstance(manager, threading.Thread):
        manager.join(timeout=5.0)  # it sees the pool broken and releases its queues


class DaskEngine:
    """A Dask cluster: a LocalCluster for "local" (started and closed here), else the scheduler
    at that address. Tasks carry the scenario's data and model, so remote workers need no
    shared file system; a LocalCluster's worker processes exit when this process dies (Dask's
    nanny pipe)."""

    def __init__(self, workers: int | None, scheduler: str) -> None:
        self.workers = workers
        self.scheduler = scheduler
        self.stack = contextlib.ExitStack()
        self.cluster: Any = None
        self.client: Any = None
        self.submitted: list[Any] = []

    def start(self, warm: _Task | None) -> None:
        """Start (or connect to) the cluster and warm its workers with ``warm``."""
        require_extra("dask", "the Dask engine (--scheduler)")
        from dask.distributed import Client, LocalCluster

        from hybrid_force.studies._dask_warm import WarmUp

        stack = self.stack
        if self.scheduler == "local":
            stack.enter_context(single_threaded_workers())
            self.cluster = stack.enter_context(
                LocalCluster(
                    n_workers=int(self.workers or 2),
                    threads_per_worker=1,
                    processes=True,
                    # any free port: None means Dask's default 8787, and a second cluster on
                    # the machine (another sweep, a notebook) then makes it warn at start
                    dashboard_address=":0",
                )
            )
            self.client = stack.enter_context(Client(self.cluster))
        else:
            try:
                self.client = stack.enter_context(Client(self.scheduler, timeout=30))
            except (OSError, TimeoutError, ValueError) as exc:
                raise BadInputError(
                    f"cannot connect to the Dask scheduler at {self.scheduler!r}: {exc} "
                    "(give tcp://host:port of a running scheduler, or 'local')"
                ) from exc
        if warm is not None:
            # a worker that cannot take the plugin (e.g. another version) fails its tasks instead
            with contextlib.suppress(Exception):
                self.client.register_plugin(WarmUp(warm), name=WarmUp.name)

    def send_ahead(self, tasks: Iterable[_Task]) -> None:
        """Nothing is sent ahead to a cluster (its workers warm up on their own schedule)."""

    def keep_ahead(self, todo: Collection[str]) -> frozenset[str]:
        """None sent ahead, none kept."""
        return frozenset()

    def run(self, jobs: Iterator[Job], n_jobs: int, finish: Finish, lost: list[str]) -> None:
        """Run every job, rows handed to ``finish`` as they come back."""
        from dask.distributed import wait as dask_wait

        client = self.client
        threads = max(1, sum(client.nthreads().values()))

        def submit(chunk: list[_Task]) -> Any:
            key = f"runs-{chunk[0].run_id}-{len(chunk)}"
            fut = client.submit(_execute_chunk, chunk, key=key, pure=False)
            self.submitted.append(fut)
            return fut

        def wait_first(futures: list[Any]) -> Iterable[Any]:
            return dask_wait(futures, return_when="FIRST_COMPLETED").done

        sizes = _ChunkSize(n_jobs, threads)
        _pump(jobs, submit, wait_first, 2 * threads, finish, lost, sizes, stop_on_loss=False)

    def close(self, failed: bool = False) -> None:
        """Close the cluster (or leave someone else's): after a failure, at once."""
        if failed:
            if self.cluster is not None:
                _stop_local_workers(self.cluster)
            elif self.client is not None:  # someone else's cluster: only take our tasks off it
                with contextlib.suppress(Exception):
                    self.client.cancel([f for f in self.submitted if not f.done()])
        self.stack.close()


def _stop_local_workers(cluster: Any) -> None:
    """Close a LocalCluster's workers now: a busy worker is killed after 0.4 s, not 4 s.

    (Closing the cluster would ask each worker to finish its task for 4 s first.) Dask's
    warnings about the cancelled and killed tasks are silenced: they are expected here.
    """

    async def close_all() -> None:
        nannies = list(cluster.workers.values())
        await asyncio.gather(*(n.close(timeout=0.5) for n in nannies), return_exceptions=True)

    log = logging.getLogger("distributed")
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        cluster.sync(close_all)
    except Exception:  # the cluster's own close still follows
        pass
    finally:
        log.setLevel(level)

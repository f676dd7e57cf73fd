"""Where assets are built: in this process, in local worker processes, or on a Dask cluster.

Every executor runs the same task function (``pipeline.batch.build_task``) on
plain-data arguments and hands each finished ``AssetReport`` to a callback in
the main process, in completion order. The build itself never depends on the
executor: every asset runs its kernels with ``ASSET_THREADS`` threads wherever
it runs, so its outputs are byte-identical whichever executor and however
many jobs build it (the learned model's convolutions give other float
roundings with another thread count; ``tests/pipeline/test_integrity.py``
compares every output byte of -j 1 and -j 2 builds).

Stopping: ``run`` records in ``started`` the position of every task it handed
out (anew for each build: ``--watch`` runs many builds on one executor). On any exception (Ctrl-C's KeyboardInterrupt, a ``--fail-fast`` stop
raised by ``done``) an executor stops its work before it re-raises: worker
processes are killed (``pipeline/workers.py``); a cluster's queued tasks are
cancelled, and its running ones stop at their next lease check
(``pipeline/lock.py``). A task whose worker died is reported through
``lost(position, why)``.

Worker processes import the heavy stack once when they start and keep
detailizers loaded between assets, so no asset pays for imports or model
loading.

A cluster build runs the tasks on Dask workers (``--executor dask --address
tcp://scheduler:8786``). Workers must see the recipe's input files and the
output folder at the same paths (a shared filesystem), and have this project
installed. ``--gpus-per-task 1`` asks Dask for a ``GPU`` resource per task, so
tasks only land on workers started with ``--resources "GPU=1"``.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from enum import StrEnum

from core.errors import UsageError
from core.files import allow_commits, forbid_commits
from pipeline.forked import available_cores
from pipeline.workers import WorkerPool

#: Seconds to wait for a cluster scheduler before giving up.
CONNECT_TIMEOUT_S = 10

#: Seconds between two looks at an in-process task's thread (the main thread stays responsive to signals).
WAIT_SLICE_S = 0.05

#: CPU threads every asset's kernels run with, wherever it is built (in process, a worker, a cluster).
#: One: the unit of parallelism is the asset (``--jobs``), and a count that does not depend on the
#: machine or on the number of jobs keeps the outputs byte-identical.
ASSET_THREADS = 1


def _report_lost(lost: Callable[[int, str], None] | None, position: int, why: str) -> None:
    if lost is None:
        raise RuntimeError(f"task {position} was lost: {why}")
    lost(position, why)


class LocalExecutor:
    """Builds in this process, one asset after the other (``--jobs 1``), with stage-level progress.

    Each task runs in a thread of its own while the main thread waits on it, so Ctrl-C is answered
    at once even while a kernel (a convolution, marching cubes) holds that thread in C code for
    seconds. The interrupted task cannot be stopped mid-call: it is abandoned, its thread may no
    longer move files into place (``core.files.forbid_commits``), and it stops at its next stage
    (its lease is gone, ``pipeline/lock.py``). ``abandoned_work()`` says whether such a thread still
    runs; the command line then ends the process without waiting for it.
    """

    def __init__(self, progress=None) -> None:
        self.progress = progress
        self.started: list[int] = []
        #: Processes an asset may use: a long asset's blocks in two halves when a second core is free.
        self.block_processes = min(2, available_cores())

    def start(self) -> None:
        """Nothing to connect to (every executor has ``start``: the build calls it before writing anything)."""

    def run(self, fn: Callable, tasks: Sequence[tuple], done: Callable, names: Sequence[str] = (),
            lost: Callable[[int, str], None] | None = None) -> None:
        self.started = []  # an executor may serve several builds (--watch)
        for n, args in enumerate(tasks):
            if self.progress is not None:
                self.progress.asset_started(n, len(tasks), names[n] if names else str(n))
            self.started.append(n)
            done(_run_in_thread(fn, args, self.progress))


_ABANDONED: set[int] = set()  # ids of threads running tasks that a stopped build abandoned
_ABANDON_LOCK = threading.Lock()


def abandoned_work() -> bool:
    """Whether a task that a stopped in-process build abandoned still runs in this process."""
    with _ABANDON_LOCK:
        return bool(_ABANDONED)


def _run_in_thread(fn: Callable, args: tuple, progress):
    """``fn(*args, progress=progress)`` in a new thread; its result or exception, once it ends.

    The wait is on an event, not ``Thread.join``: an interrupted ``join`` marks a running thread
    as stopped in Python 3.11 (the bpo-45274 fix), and the thread must stay known as running.
    """
    outcome: dict = {}
    ended = threading.Event()

    def target() -> None:
        try:
            outcome["result"] = fn(*args, progress=progress)
        except BaseException as exc:  # noqa: BLE001 - handed to the waiting thread
            outcome["error"] = exc
        finally:
            with _ABANDON_LOCK:
                ended.set()
                if threading.get_ident() in _ABANDONED:
                    allow_commits(threading.get_ident())
                    _ABANDONED.discard(threading.get_ident())

    thread = threading.Thread(target=target, name="decollage-build", daemon=True)
    thread.start()
    try:
        while not ended.wait(WAIT_SLICE_S):  # short waits: a signal's handler runs between them
            pass
    except BaseException:
        with _ABANDON_LOCK:
            if not ended.is_set():
                _ABANDONED.add(thread.ident)
                forbid_commits(thread.ident)
        raise
    if "error" in outcome:
        raise outcome["error"]
    return outcome["result"]


class ProcessExecutor:
    """``jobs`` worker processes on this machine (``--jobs N``, ``pipeline/workers.py``)."""

    def __init__(self, jobs: int) -> None:
        if jobs < 1:
            raise UsageError(f"--jobs must be at least 1, got {jobs}")
        self.jobs = jobs
        self.started: list[int] = []
        self.block_processes = 1  # the jobs share the cores: one process per asset

    def start(self) -> None:
        """Workers start inside ``run``; nothing can fail before it."""

    def run(self, fn: Callable, tasks: Sequence[tuple], done: Callable, names: Sequence[str] = (),
            lost: Callable[[int, str], None] | None = None) -> None:
        self.started = []
        if tasks:
            WorkerPool(self.jobs, ASSET_THREADS).run(fn, tasks, done,
                                                     lambda i, why: _report_lost(lost, i, why), self.started)


class DaskExecutor:
    """Tasks on a Dask distributed cluster (``--executor dask --address ...``)."""

    def __init__(self, address: str | None, gpus_per_task: float = 0.0) -> None:
        if not address:
            raise UsageError("--executor dask needs --address (e.g. tcp://scheduler:8786)")
        self.address = address
        self.gpus_per_task = gpus_per_task
        self.started: list[int] = []
        self.block_processes = 1  # a cluster worker's cores belong to its other tasks
        self._client = None

    def start(self) -> None:
        """Connect to the scheduler; a ``UsageError`` within ``CONNECT_TIMEOUT_S`` when it cannot be reached.

        The build calls this before it writes anything, so an unreachable cluster leaves the
        output folder (and its manifest) as it was.
        """
        if self._client is not None:
            return
        try:
            from distributed import Client
        except ImportError:
            raise UsageError("the dask executor needs the 'distributed' package",
                             hint="pip install 'decollage[cluster]' (or: pip install distributed)") from None
        try:
            self._client = Client(self.address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise UsageError(f"cannot reach the Dask scheduler at {self.address} within {CONNECT_TIMEOUT_S} s "
                             f"({type(exc).__name__})", hint="check --address and that the scheduler runs") from None

    def run(self, fn: Callable, tasks: Sequence[tuple], done: Callable, names: Sequence[str] = (),
            lost: Callable[[int, str], None] | None = None) -> None:
        """Submit every task; a queued or running task counts as started (the cluster does not say which)."""
        from distributed import as_completed

        self.start()
        self.started = []
        client, self._client = self._client, None
        resources = {"GPU": self.gpus_per_task} if self.gpus_per_task else None
        futures = []
        try:
            for i, args in enumerate(tasks):
                futures.append(client.submit(fn, *args, key=f"decollage-{names[i] if names else i}-{args[3][:12]}",
                                             pure=False, resources=resources))
                self.started.append(i)
            position = {future.key: i for i, future in enumerate(futures)}
            for future in as_completed(futures, loop=client.loop):
                if future.status == "error":
                    exc = future.exception()
                    _report_lost(lost, position[future.key], f"{type(exc).__name__}: {exc}")
                else:
                    done(future.result())
        except BaseException:
            client.cancel(futures)
            raise
        finally:
            client.close()


class ExecutorKind(StrEnum):
    """Where a build runs (``--executor``)."""

    LOCAL = "local"  # this machine: in process (--jobs 1) or worker processes
    DASK = "dask"  # a Dask cluster (needs --address)


def make_executor(kind: ExecutorKind, jobs: int, address: str | None, gpus_per_task: float, progress=None):
    """The executor for the CLI's ``--executor``/``--jobs``/``--address`` options."""
    if kind == ExecutorKind.LOCAL:
        if gpus_per_task:
            raise UsageError("--gpus-per-task is a cluster resource request; it needs --executor dask",
                             field="--gpus-per-task",
                             hint="on one machine the recipe's detailize.device picks the GPU (auto, cpu, cuda)")
        return LocalExecutor(progress) if jobs == 1 else ProcessExecutor(jobs)
    if kind == ExecutorKind.DASK:
        return DaskExecutor(address, gpus_per_task)
    raise UsageError(f"unknown executor {kind!r} (known: local, dask)")

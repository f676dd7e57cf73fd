"""Where assets are built: in this process, in local worker processes, or on a Dask cluster.

Every executor runs the same task function (``pipeline.build.build_task``) on
plain-data arguments and hands each finished ``AssetReport`` to a callback in
the main process, in completion order. The build itself never depends on the
executor: outputs are identical whichever runs them.

Worker processes import the heavy stack once when they start (their
initializer) and keep detailizers loaded between assets, so no asset pays for
imports or model loading. Each worker uses ``cores // jobs`` threads so that
the workers together do not oversubscribe the machine.

A cluster build runs the tasks on Dask workers (``--executor dask --address
tcp://scheduler:8786``). Workers must see the recipe's input files and the
output folder at the same paths (a shared filesystem), and have this project
installed. ``--gpus-per-task 1`` asks Dask for a ``GPU`` resource per task, so
tasks only land on workers started with ``--resources "GPU=1"``.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable, Sequence
from enum import StrEnum

from core.errors import UsageError

#: Seconds to wait for a cluster scheduler before giving up.
CONNECT_TIMEOUT_S = 10


def _worker_init(threads: int, task_module: str) -> None:
    """Runs once per worker process: pin thread counts, import the heavy stack and the task's module once."""
    os.environ["OMP_NUM_THREADS"] = str(threads)
    import numpy  # noqa: F401
    import trimesh  # noqa: F401
    from skimage import measure  # noqa: F401

    importlib.import_module(task_module)  # the task function's module and everything it imports

    try:
        import torch

        torch.set_num_threads(threads)
    except ImportError:  # torch is only needed by learned detailizers
        pass


class LocalExecutor:
    """Builds in this process, one asset after the other (``--jobs 1``), with stage-level progress."""

    def __init__(self, progress=None) -> None:
        self.progress = progress

    def start(self) -> None:
        """Nothing to connect to (every executor has ``start``: the build calls it before writing anything)."""

    def run(self, fn: Callable, tasks: Sequence[tuple], done: Callable, names: Sequence[str] = ()) -> None:
        for n, args in enumerate(tasks):
            if self.progress is not None:
                self.progress.asset_started(n, len(tasks), names[n] if names else str(n))
            done(fn(*args, progress=self.progress))


class ProcessExecutor:
    """``jobs`` worker processes on this machine (``--jobs N``)."""

    def __init__(self, jobs: int) -> None:
        if jobs < 1:
            raise UsageError(f"--jobs must be at least 1, got {jobs}")
        self.jobs = jobs

    def start(self) -> None:
        """Workers start inside ``run``; nothing can fail before it."""

    def run(self, fn: Callable, tasks: Sequence[tuple], done: Callable, names: Sequence[str] = ()) -> None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        if not tasks:
            return
        workers = min(self.jobs, len(tasks))
        threads = max(1, (os.cpu_count() or 1) // workers)
        # spawn: a clean interpreter per worker (fork after threads started is unsafe).
        context = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                   initializer=_worker_init, initargs=(threads, fn.__module__))
        try:
            futures = [pool.submit(fn, *args) for args in tasks]
            for future in as_completed(futures):
                done(future.result())
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)


class DaskExecutor:
    """Tasks on a Dask distributed cluster (``--executor dask --address ...``)."""

    def __init__(self, address: str | None, gpus_per_task: float = 0.0) -> None:
        if not address:
            raise UsageError("--executor dask needs --address (e.g. tcp://scheduler:8786)")
        self.address = address
        self.gpus_per_task = gpus_per_task
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

    def run(self, fn: Callable, tasks: Sequence[tuple], done: Callable, names: Sequence[str] = ()) -> None:
        from distributed import as_completed

        self.start()
        client, self._client = self._client, None
        resources = {"GPU": self.gpus_per_task} if self.gpus_per_task else None
        try:
            futures = [client.submit(fn, *args, key=f"decollage-{names[i] if names else i}-{args[3][:12]}",
                                     pure=False, resources=resources)
                       for i, args in enumerate(tasks)]
            for future in as_completed(futures, loop=client.loop):
                done(future.result())
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

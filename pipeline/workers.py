"""Local worker processes for ``--jobs N``: started clean, one task at a time, never outliving the build.

Each worker is a fresh interpreter (``spawn``: forking a process that already
runs threads is unsafe) that imports the heavy stack and the task's module once
(``warm``) and then runs the tasks the parent hands it over a pipe, one at a
time: nothing is queued in a worker, so a stopped build leaves no task that
starts later.

A worker never outlives the build:

- it ignores SIGINT. A terminal's Ctrl-C reaches the whole foreground process
  group; the parent alone decides, kills every worker (``WorkerPool.kill``)
  and then writes the manifest (``pipeline/batch.py``), so no asset lands
  after it;
- it dies with its parent: SIGKILL from the kernel when the parent exits
  (``core.processes.die_with_parent``, Linux) and, on every platform, a thread
  that exits the worker within 0.25 s of its parent going
  (``core.processes.watch_parent``). A ``kill -9`` of the parent therefore
  leaves no worker running;
- a worker that dies on its own (a crash, the out-of-memory killer) costs only
  its asset: the parent reports it through ``lost`` and starts another worker
  for the tasks left.
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import signal
from collections import deque
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait

from core.processes import die_with_parent, watch_parent

#: Seconds an idle worker gets to leave after the last task before it is killed (it holds nothing to save).
CLOSE_TIMEOUT_S = 0.5


def warm(threads: int, task_module: str) -> None:
    """Pin kernel thread counts, import the heavy stack and the task function's module once."""
    for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[name] = str(threads)  # for libraries loaded from here on
    import numpy  # noqa: F401
    import trimesh  # noqa: F401
    from skimage import measure  # noqa: F401

    importlib.import_module(task_module)  # the task function's module and everything it imports
    try:
        import torch

        torch.set_num_threads(threads)
    except ImportError:  # torch is only needed by learned detailizers
        pass


def _worker_main(conn: Connection, parent_pid: int, threads: int, task_module: str) -> None:
    """A worker's life: guard against outliving the parent, warm up, then run tasks until told to stop."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent()
    if os.getppid() != parent_pid:  # the parent went before the guard was in place
        os._exit(1)
    watch_parent(parent_pid)
    warm(threads, task_module)
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        fn, args = message
        try:
            reply = ("done", fn(*args))
        except Exception as exc:  # noqa: BLE001 - handed to the parent, which raises it
            reply = ("error", exc)
        try:
            conn.send(reply)
        except Exception as exc:  # noqa: BLE001 - an unpicklable result or exception
            conn.send(("error", RuntimeError(f"{type(exc).__name__}: {exc}")))


class _Worker:
    def __init__(self, context, threads: int, task_module: str, number: int) -> None:
        self.conn, child = context.Pipe(duplex=True)
        self.process = context.Process(target=_worker_main, args=(child, os.getpid(), threads, task_module),
                                       name=f"decollage-worker-{number}", daemon=True)
        self.process.start()  # from the caller's thread: the main thread, as die_with_parent needs
        child.close()
        self.task: int | None = None


def _death(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        name = signal.Signals(-exitcode).name
        return f"killed by {name}" + (" (out of memory?)" if name == "SIGKILL" else "")
    return f"exit code {exitcode}"


class WorkerPool:
    """``size`` worker processes running ``fn(*args)`` for each task; see the module docstring."""

    def __init__(self, size: int, threads: int) -> None:
        self.size = size
        self.threads = threads
        self._workers: list[_Worker] = []
        self._spawned = 0

    def run(self, fn: Callable, tasks: Sequence[tuple], done: Callable, lost: Callable[[int, str], None],
            started: list[int]) -> None:
        """Run every task; ``done(result)`` as each finishes, ``lost(position, why)`` for a task whose worker died.

        ``started`` gets each task's position when it is handed to a worker. Any exception
        (a KeyboardInterrupt, one raised by ``done``, one a task raised) kills every worker
        before it propagates.
        """
        context = multiprocessing.get_context("spawn")
        pending = deque(enumerate(tasks))
        try:
            while pending or any(w.task is not None for w in self._workers):
                self._workers = [w for w in self._workers if w.task is not None or w.process.is_alive()]
                while pending and len(self._workers) < min(self.size, len(tasks)):
                    self._spawned += 1
                    self._workers.append(_Worker(context, self.threads, fn.__module__, self._spawned))
                for worker in self._workers:
                    if worker.task is None and pending:
                        worker.task, args = pending.popleft()
                        worker.conn.send((fn, args))
                        started.append(worker.task)
                busy = [w for w in self._workers if w.task is not None]
                ready = wait([w.conn for w in busy] + [w.process.sentinel for w in busy])
                for worker in busy:
                    if worker.conn in ready:
                        try:
                            kind, payload = worker.conn.recv()
                        except (EOFError, OSError):
                            kind, payload = "died", None
                        if kind == "error":
                            raise payload
                        if kind == "done":
                            worker.task = None
                            done(payload)
                            continue
                    if worker.task is not None and (worker.conn in ready or worker.process.sentinel in ready):
                        worker.process.join(1.0)
                        position, worker.task = worker.task, None
                        self._workers.remove(worker)
                        lost(position, _death(worker.process.exitcode))
        except BaseException:
            self.kill()
            raise
        self.close()

    def kill(self) -> None:
        """SIGKILL every worker and reap it (a worker holds no state worth a clean exit)."""
        for worker in self._workers:
            if worker.process.is_alive():
                worker.process.kill()
        for worker in self._workers:
            worker.process.join(CLOSE_TIMEOUT_S)
            worker.conn.close()
        self._workers = []

    def close(self) -> None:
        """Tell every worker to leave, then kill those that do not within ``CLOSE_TIMEOUT_S``."""
        for worker in self._workers:
            try:
                worker.conn.send(None)
            except OSError:
                pass
        for worker in self._workers:
            worker.process.join(CLOSE_TIMEOUT_S)
        self.kill()

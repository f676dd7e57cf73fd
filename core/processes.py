"""Processes: children that die with their parent, and whether a recorded process still runs.

Role: the ground floor's process plumbing, used by the build's worker processes
(``pipeline/workers.py``) and by the output folder's lock (``pipeline/lock.py``).
(The script runner, ``sources/script_runner.py``, keeps its own guard: it reads
requests on stdin, which closes when the build is gone, and stops a running
script once its parent process id changes.)

A child can outlive its parent: a parent killed with SIGKILL runs no clean-up,
and its children are re-parented and keep running. Two guards stop that:
``die_with_parent`` asks Linux to send the child SIGKILL when its parent
exits (``prctl(PR_SET_PDEATHSIG)``), and ``watch_parent`` is a thread that
exits the process once its parent id changes (every platform, within
``WATCH_INTERVAL_S``).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

#: How often ``watch_parent`` looks at the parent process id, seconds.
WATCH_INTERVAL_S = 0.25

_PR_SET_PDEATHSIG = 1


def die_with_parent(sig: int = signal.SIGKILL) -> bool:
    """Have the kernel send ``sig`` to this process when its parent exits; True where supported (Linux).

    Usable as ``subprocess.Popen(preexec_fn=die_with_parent)``. The signal follows the parent
    *thread* that started this process, so start children from a thread that lives as long as
    the parent (the main thread).
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def watch_parent(parent_pid: int, interval_s: float = WATCH_INTERVAL_S) -> threading.Thread:
    """Start a daemon thread that ends this process (exit status 1) once ``parent_pid`` is no longer its parent.

    Also ends it at once when the parent is already gone (a race with ``die_with_parent``).
    """

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(interval_s)
        os._exit(1)  # no clean-up: the work in hand belongs to a build that no longer exists

    thread = threading.Thread(target=watch, name="decollage-parent-watch", daemon=True)
    thread.start()
    return thread


def _stat(pid: int) -> tuple[str, int] | None:
    """(state letter, start time in clock ticks since boot) from Linux ``/proc/<pid>/stat``; None elsewhere."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as handle:
            stat = handle.read()
        # The command name (field 2) may hold spaces and parentheses: split after its last ")".
        fields = stat[stat.rindex(b")") + 2:].split()
        return fields[0].decode(), int(fields[19])  # fields 3 and 22
    except (OSError, ValueError, IndexError):
        return None


def start_ticks(pid: int) -> int | None:
    """The process's start time in clock ticks since boot (Linux), else None.

    Together with the pid it names one process: a pid reused by a later process has another start time.
    """
    stat = _stat(pid)
    return stat[1] if stat else None


def process_alive(pid: int, ticks: int | None = None) -> bool:
    """Whether process ``pid`` runs (and, when ``ticks`` is given and knowable, is the one started then).

    A zombie (exited, not yet reaped by its parent) does not run.
    """
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # it exists, under another user
    stat = _stat(pid)
    if stat is not None and (stat[0] in ("Z", "X") or (ticks is not None and stat[1] != ticks)):
        return False
    return True


def own_peak_rss_mb() -> float:
    """This process's own peak resident memory, MiB.

    ``getrusage(RUSAGE_SELF).ru_maxrss`` is not that in a process started by
    fork/vfork + exec (``subprocess``, ``multiprocessing``'s spawn): Linux
    keeps the parent's peak across exec, so a child of a 2 GB test runner
    reports at least 2 GB. ``VmHWM`` in ``/proc/self/status`` belongs to the
    process's own address space; ``ru_maxrss`` is the fallback where there is
    no /proc.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except (OSError, ValueError, IndexError):
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def children_peak_rss_mb() -> float:
    """The largest peak resident memory of this process's ended, waited-for children, MiB (0 without any).

    A forked child's figure counts the pages it shares with this process, so ``own_peak_rss_mb() +
    children_peak_rss_mb()`` bounds a build's memory from above when it used a block process
    (``pipeline/forked.py``). Exec'd children (a script runner) count too.
    """
    import resource

    return resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024


@contextmanager
def blas_threads(threads: int) -> Iterator[None]:
    """Run the block with numpy's BLAS (OpenBLAS) limited to ``threads`` threads, process-wide.

    The asset stages' matrix products are small (the quilt's ranking: a few hundred rows), and
    OpenBLAS's helper threads cost more than they give: on the 2-core reference machine (AMD EPYC,
    2026-12-03, runs alternated in the same minutes, ``OPENBLAS_NUM_THREADS`` 1 vs 2) castle_word built
    in 3.82-5.38 s against 4.40-5.82 s in one process, and in 2.27-3.15 s against 2.67-3.41 s with its
    two block processes, where two threads each oversubscribe the cores. A forked child keeps the limit.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=threads, user_api="blas"):
        yield

"""The output folder's lock: one build writes into a folder at a time, and its tasks hold a lease on it.

``<out>/.decollage/build.lock`` is held with ``flock(LOCK_EX)`` from before a
build plans until its manifest is written. The kernel drops the lock of a
process that ends, whatever ended it (SIGKILL, a crash, a closed terminal), so
a lock left by a killed build never blocks: the next build finds the file
still naming the killed holder (a build that ends cleanly empties it), takes
the lock over and says whose it was. A second build while the first runs
waits for it (``wait=True``, polling every ``POLL_S``) or stops at once with a
``LockedError`` naming the holder.

The file's JSON names the holder (``Holder``): a random build id, pid, the
process's start time (so a reused pid is not taken for the holder), host and
start time (UTC).

**Lease.** Every task of a build carries the build id. A task checks
``lease_holds`` before it starts, between its stages and before it records
its asset: the file must still name its build, and the holder must still run
(same host: by pid and start time; another host, a cluster worker: by a
shared ``flock`` probe, which fails while the holder keeps its lock). A build
that ends, normally or interrupted, empties the file before it unlocks, so a
task still running somewhere (a cluster does not stop a running task when its
client goes away) stops at its next check instead of writing into a folder
whose manifest is already written. POSIX only (``fcntl``); on a filesystem
that refuses locks the build goes on with the holder record alone.
"""

from __future__ import annotations

import fcntl
import json
import os
import secrets
import socket
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from pathlib import Path

from core.errors import LockedError
from core.processes import process_alive, start_ticks
from pipeline.cache import RECORD_DIR

LOCK_NAME = "build.lock"
#: Seconds between two attempts while waiting for another build's lock.
POLL_S = 0.1


@dataclass(frozen=True)
class Holder:
    """Who holds (or last held) an output folder's lock."""

    build: str
    pid: int
    ticks: int | None
    host: str
    started_at: str

    def describe(self) -> str:
        return f"pid {self.pid} on {self.host}, started {self.started_at}"

    def runs(self) -> bool:
        """Whether the holder still runs: by pid and start time on this host; by the lock itself elsewhere."""
        if self.host == socket.gethostname():
            return process_alive(self.pid, self.ticks)
        return True  # another host: only the flock can tell (lease_holds probes it)


def lock_path(out_dir: Path) -> Path:
    return Path(out_dir) / RECORD_DIR / LOCK_NAME


def read_holder(out_dir: Path) -> Holder | None:
    """The holder the lock file names; None when it is empty, missing or unreadable."""
    try:
        return _parse(lock_path(out_dir).read_bytes())
    except OSError:
        return None


def _parse(data: bytes) -> Holder | None:
    try:
        fields = json.loads(data)
        return Holder(build=str(fields["build"]), pid=int(fields["pid"]),
                      ticks=None if fields.get("ticks") is None else int(fields["ticks"]),
                      host=str(fields["host"]), started_at=str(fields["started_at"]))
    except (ValueError, KeyError, TypeError):
        return None


class BuildLock:
    """The lock of one build on ``out_dir`` (a context manager, or ``acquire``/``release``).

    Attributes:
        build_id: this build's id, the lease its tasks carry.
        started_ns: the lock file's mtime once taken (the folder's clock, ns): files written
            by this build are at least this new.
        previous: the holder named by a build that ended without releasing (killed), taken over.
    """

    def __init__(self, out_dir: Path) -> None:
        self.path = lock_path(out_dir)
        self.build_id = secrets.token_hex(8)
        self.started_ns = 0
        self.previous: Holder | None = None
        self._fd: int | None = None

    def acquire(self, wait: bool = True, on_wait: Callable[[Holder | None], None] | None = None) -> bool:
        """Take the lock; returns True when another build held it first (this one waited).

        Raises:
            LockedError: another build holds it and ``wait`` is False.
        """
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
        waited = False
        try:
            while True:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except BlockingIOError:
                    holder = _parse(os.pread(fd, 4096, 0))
                    if not wait:
                        who = holder.describe() if holder else "another build"
                        raise LockedError(f"another build is writing into this folder ({who})",
                                          file=self.path.parent.parent,
                                          hint="wait for it to finish, or build again without --no-wait to wait "
                                               "for it") from None
                    if not waited and on_wait is not None:
                        on_wait(holder)
                    waited = True
                    time.sleep(POLL_S)
                except OSError:  # a filesystem without locks (some network mounts): the holder record still serves
                    break
            self.previous = _parse(os.pread(fd, 4096, 0))  # a build that did not release: it was killed
            holder = Holder(build=self.build_id, pid=os.getpid(), ticks=start_ticks(os.getpid()),
                            host=socket.gethostname(),
                            started_at=datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"))
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(asdict(holder)).encode(), 0)
            os.fsync(fd)
            self.started_ns = os.fstat(fd).st_mtime_ns
        except BaseException:
            os.close(fd)
            raise
        self._fd = fd
        return waited

    def release(self) -> None:
        """Empty the file (revoking the lease of any task still running) and unlock."""
        fd, self._fd = self._fd, None
        if fd is None:
            return
        try:
            os.ftruncate(fd, 0)
        finally:
            os.close(fd)  # closing the last descriptor drops the flock

    def __enter__(self) -> "BuildLock":
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def lease_holds(out_dir: Path, build_id: str) -> bool:
    """Whether the build ``build_id`` still holds ``out_dir``: what a task checks before it writes."""
    path = lock_path(out_dir)
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        holder = _parse(os.pread(fd, 4096, 0))
        if holder is None or holder.build != build_id or not holder.runs():
            return False
        if holder.host == socket.gethostname():
            return True
        try:  # another host: a shared lock is only granted when nobody holds the exclusive one
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        except OSError:
            return True  # the filesystem cannot tell (no lock support): trust the file
        return False
    finally:
        os.close(fd)

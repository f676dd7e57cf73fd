"""Worker processes, the in-process executor's stop, the output folder's lock and lease, closure paths.

Unit tests of pipeline/workers.py, executors.py, lock.py, cache.py and sources/script_reads.py; the
end-to-end behaviour of whole builds is in test_integrity.py.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import pytest

from core.errors import ExportError, LockedError
from core.files import write_bytes_atomic
from pipeline.batch import build_task
from pipeline.cache import PROJECT_PREFIX, STYLES_PREFIX, portable_path, resolve_portable
from stylesets.format import style_dir
from pipeline.executors import LocalExecutor, abandoned_work
from pipeline.lock import BuildLock, lease_holds, read_holder
from pipeline.report import AssetStatus
from pipeline.workers import WorkerPool
from sources.script_reads import ScriptReads

REPO = Path(__file__).resolve().parents[2]


def square_or_die(x):
    """A task for the worker pool: a worker that gets "die" ends the way the out-of-memory killer ends it."""
    if x == "die":
        os.kill(os.getpid(), signal.SIGKILL)
    return x * x


@pytest.mark.e2e  # worker processes
def test_a_worker_that_dies_costs_only_its_task():
    done, lost, started = [], [], []
    WorkerPool(2, 1).run(square_or_die, [(2,), ("die",), (3,), (4,)], done.append,
                         lambda i, why: lost.append((i, why)), started)
    assert sorted(done) == [4, 9, 16]
    assert lost == [(1, "killed by SIGKILL (out of memory?)")] and sorted(started) == [0, 1, 2, 3]


@pytest.mark.e2e  # a worker process
def test_an_exception_in_a_task_reaches_the_caller_and_stops_the_workers():
    with pytest.raises(TypeError):
        WorkerPool(1, 1).run(square_or_die, [("text",)], print, lambda i, why: None, [])


def test_ctrl_c_abandons_an_in_process_task_that_can_no_longer_write(tmp_path):
    """The main thread answers at once; the task, stuck in its work, may not move a file into place later."""
    release, outcome = threading.Event(), {}

    def slow_task(progress=None):
        release.wait(10)  # a kernel that cannot be interrupted
        try:
            write_bytes_atomic(tmp_path / "late.glb", b"late")
        except ExportError as exc:
            outcome["refused"] = exc.message

    previous = signal.signal(signal.SIGALRM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    signal.setitimer(signal.ITIMER_REAL, 0.2)
    started = time.perf_counter()
    try:
        with pytest.raises(KeyboardInterrupt):
            LocalExecutor().run(slow_task, [()], lambda r: None)
    finally:
        signal.signal(signal.SIGALRM, previous)
    assert time.perf_counter() - started < 1.0 and abandoned_work()
    release.set()
    deadline = time.time() + 10
    while abandoned_work() and time.time() < deadline:
        time.sleep(0.01)
    assert not abandoned_work() and outcome == {"refused": "not written: the build was interrupted"}
    assert not (tmp_path / "late.glb").exists()
    write_bytes_atomic(tmp_path / "now.glb", b"ok")  # this thread still writes


def test_lock_holder_lease_and_release(tmp_path):
    lock = BuildLock(tmp_path)
    assert lock.acquire() is False and lock.previous is None
    holder = read_holder(tmp_path)
    assert holder.build == lock.build_id and holder.pid == os.getpid()
    assert lease_holds(tmp_path, lock.build_id) and not lease_holds(tmp_path, "another build")
    with pytest.raises(LockedError, match="another build is writing into this folder"):
        BuildLock(tmp_path).acquire(wait=False)
    lock.release()
    assert not lease_holds(tmp_path, lock.build_id) and read_holder(tmp_path) is None
    again = BuildLock(tmp_path)
    again.acquire(wait=False)
    assert again.previous is None  # a clean release leaves nothing to take over
    again.release()


def test_a_waiting_build_gets_the_lock_when_the_holder_releases_it(tmp_path):
    first, second, waited = BuildLock(tmp_path), BuildLock(tmp_path), []
    first.acquire()
    threading.Timer(0.3, first.release).start()
    assert second.acquire(wait=True, on_wait=waited.append) is True
    assert [h.build for h in waited] == [first.build_id] and lease_holds(tmp_path, second.build_id)
    second.release()


def test_a_task_whose_build_is_gone_writes_nothing(tmp_path):
    recipe = tmp_path / "r.yaml"
    text = """
version: 1
assets:
  - name: a
    source: {kind: cad, parts: [{name: a, shape: box, size: [1, 1, 1]}]}
    grid: {resolution: 4}
    regions: [{part: body, style: stone}]
    detailize: {detailizer: upsample}
"""
    recipe.write_text(text)
    out = tmp_path / "out"
    out.mkdir()
    report = build_task(text, str(recipe), 0, "key", str(out), None, "a build that no longer holds the folder")
    assert report.status == AssetStatus.FAILED and "the build that asked for this asset stopped" in report.error
    assert sorted(p.name for p in out.iterdir()) == []


def test_closure_paths_are_portable(tmp_path):
    font = REPO / "sources" / "fonts" / "DejaVuSans-Bold.ttf"
    assert portable_path(font, tmp_path) == PROJECT_PREFIX + "sources/fonts/DejaVuSans-Bold.ttf"
    assert resolve_portable(portable_path(font, tmp_path), tmp_path) == font
    assert portable_path(tmp_path / "in" / "a.bin", tmp_path) == "in/a.bin"
    assert portable_path(tmp_path.parent / "b.bin", tmp_path) == "../b.bin"
    assert resolve_portable("../b.bin", tmp_path).resolve() == (tmp_path.parent / "b.bin").resolve()
    built_set = style_dir() / "things.npz"
    assert portable_path(built_set, tmp_path) == STYLES_PREFIX + "things.npz"
    assert resolve_portable(STYLES_PREFIX + "things.npz", tmp_path) == built_set


def test_script_reads_records_local_modules_and_data_files_only(tmp_path, monkeypatch):
    (tmp_path / "helper_for_reads.py").write_text("import json\nVALUE = 2\n")
    (tmp_path / "data.txt").write_text("3")
    monkeypatch.syspath_prepend(str(tmp_path))
    with ScriptReads() as reads:
        import helper_for_reads  # noqa: F401 - what a script does

        (tmp_path / "data.txt").read_text()
        (tmp_path / "scratch.txt").write_text("written, then read back: not an input")
        (tmp_path / "scratch.txt").read_text()
        with pytest.raises(FileNotFoundError):  # looked for in vain: recorded, as absent
            (tmp_path / "optional.txt").read_text()
        with pytest.raises(IsADirectoryError):  # a folder is not an input
            open(tmp_path)
    assert reads.files() == [tmp_path / "helper_for_reads.py", tmp_path / "data.txt", tmp_path / "optional.txt"]
    with ScriptReads() as again:  # a second run imports (and records) the helper again
        import helper_for_reads  # noqa: F401,F811
    assert again.files() == [tmp_path / "helper_for_reads.py"]

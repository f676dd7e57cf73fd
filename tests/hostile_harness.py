"""Runs the hostile-input catalogue's CLI cases, each in a forked child under resource limits (not a test).

Usage (from ``tests/test_hostile_inputs.py``)::

    python tests/hostile_harness.py CASES.json RESULTS.json

CASES.json is a list of ``{"id", "args", "cwd", "env", "timeout_s"}``.
The harness imports the CLI and the libraries its cases need once, then for
each case forks a child that: starts a process group of its own, limits its address
space to its size at the fork plus ``EXTRA_ADDRESS_SPACE`` (so a runaway case
fails instead of taking the machine), sends stdout and stderr to files in the
case's folder, sets the case's environment and runs ``cli.app.main`` with the
case's arguments. The parent waits up to the case's timeout (then kills the
child's group), and records the exit code (or signal), the wall time and the
child's peak RSS (``ru_maxrss``: it counts the pages shared with the harness
too, so it is what the case would weigh as a fresh ``decollage`` process, give
or take the libraries the case does not use). RESULTS.json maps case id →
``{"exit", "signal", "timed_out", "wall_s", "peak_rss_mb", "stdout", "stderr"}``.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import sys
import time
from pathlib import Path

#: Address space a case may add to the harness's own (bytes).
EXTRA_ADDRESS_SPACE = 3 << 30


def _preload() -> None:
    import numpy  # noqa: F401
    import trimesh  # noqa: F401
    from fontTools import ttLib  # noqa: F401

    import cli.app  # noqa: F401
    import model.upsample  # noqa: F401
    import sources.cad_script  # noqa: F401


def _address_space() -> int:
    with open("/proc/self/statm") as handle:
        return int(handle.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")


def _child(case: dict) -> None:
    """Never returns."""
    code = 70
    try:
        os.setsid()
        limit = _address_space() + EXTRA_ADDRESS_SPACE
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        folder = Path(case["cwd"])
        os.chdir(folder)
        for fd, name in ((1, "stdout.txt"), (2, "stderr.txt")):
            out = os.open(folder / name, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
            os.dup2(out, fd)
            os.close(out)
        os.environ.update(case.get("env") or {})
        sys.argv = ["decollage", *case["args"]]
        from cli.app import main

        try:
            main()
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except BaseException:  # noqa: BLE001 - anything here is a harness failure, reported as exit 70
        import traceback

        traceback.print_exc()
        code = 70
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


def run_case(case: dict) -> dict:
    started = time.perf_counter()
    pid = os.fork()
    if pid == 0:
        _child(case)
    deadline = started + float(case.get("timeout_s", 30))
    timed_out = False
    while True:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            break
        if time.perf_counter() > deadline:
            timed_out = True
            os.killpg(pid, signal.SIGKILL)
            _, status, usage = os.wait4(pid, 0)
            break
        time.sleep(0.005)
    wall = time.perf_counter() - started
    try:
        os.killpg(pid, signal.SIGKILL)  # nothing a case started may outlive it
    except (ProcessLookupError, PermissionError):
        pass
    folder = Path(case["cwd"])
    read = (lambda name: (folder / name).read_text(encoding="utf-8", errors="replace")
            if (folder / name).is_file() else "")
    return {"exit": os.WEXITSTATUS(status) if os.WIFEXITED(status) else None,
            "signal": os.WTERMSIG(status) if os.WIFSIGNALED(status) else None,
            "timed_out": timed_out, "wall_s": round(wall, 3), "peak_rss_mb": round(usage.ru_maxrss / 1024, 1),
            "stdout": read("stdout.txt")[-20_000:], "stderr": read("stderr.txt")[-20_000:]}


def main(argv: list[str]) -> int:
    here = str(Path(__file__).resolve().parent)
    sys.path[:] = [p for p in sys.path if p and str(Path(p).resolve()) != here]  # tests/core is not core/
    cases = json.loads(Path(argv[0]).read_text(encoding="utf-8"))
    _preload()
    results = {case["id"]: run_case(case) for case in cases}
    Path(argv[1]).write_text(json.dumps(results, indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

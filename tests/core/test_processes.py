"""A child's peak memory is its own, not the (large) parent's that started it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from core.processes import own_peak_rss_mb

REPO = Path(__file__).resolve().parents[2]


def test_a_child_reports_its_own_peak_not_its_parents():
    ballast = bytearray(400 * 2**20)  # touch 400 MiB in this (the parent) process
    for i in range(0, len(ballast), 4096):
        ballast[i] = 1
    assert own_peak_rss_mb() > 400
    code = ("import resource; from core.processes import own_peak_rss_mb; "
            "print(own_peak_rss_mb(), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True).stdout
    own, inherited = map(float, out.split())
    assert own < 200  # a bare interpreter
    assert inherited > 400 or sys.platform != "linux"  # what ru_maxrss says there, and why it is not used
    del ballast


def test_blas_threads_limits_numpy_blas_in_the_block_and_in_a_forked_child():
    import numpy as np  # noqa: F401  (loads OpenBLAS)
    from threadpoolctl import threadpool_info

    from core.processes import blas_threads

    def blas_counts() -> list[int]:
        return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]

    before = blas_counts()
    assert before, "numpy's BLAS is not visible to threadpoolctl"
    with blas_threads(1):
        assert blas_counts() == [1] * len(before)
        read, write = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child reports what it sees and leaves at once
            os.write(write, bytes([max(blas_counts())]))
            os._exit(0)
        os.waitpid(pid, 0)
        assert os.read(read, 1) == bytes([1])
    assert blas_counts() == before

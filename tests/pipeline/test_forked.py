"""A share of a computation in a forked child (pipeline/forked.py)."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from pipeline.forked import CAN_FORK, ChildDied, run_with_child

pytestmark = pytest.mark.skipif(not CAN_FORK, reason="needs fork")


def test_messages_arrive_in_order_and_both_results_come_back():
    def child(send):
        for i in range(3):
            send(i * 10)
        return "child done"

    def parent(receive):
        return [receive() for _ in range(3)]

    assert run_with_child(child, parent) == ([0, 10, 20], "child done")


def test_a_large_message_does_not_hold_the_child_while_the_parent_is_busy():
    big = np.arange(2_000_000, dtype=np.float32)  # 8 MB: far more than a pipe holds

    def child(send):
        send(big)
        return time.perf_counter()  # when the child got past its send

    def parent(receive):
        time.sleep(1.0)  # busy with its own share before it reads
        return time.perf_counter(), receive()

    (parent_read, got), child_done = run_with_child(child, parent)
    assert np.array_equal(got, big)
    assert child_done < parent_read  # the child finished without waiting for the parent to read


def test_the_childs_exception_is_raised_here():
    def child(send):
        raise ValueError("bad block 7")

    with pytest.raises(ValueError, match="bad block 7"):
        run_with_child(child, lambda receive: None)


def test_an_exception_that_does_not_pickle_comes_back_as_text():
    class Local(Exception):  # a local class cannot be pickled
        pass

    def child(send):
        raise Local("odd")

    with pytest.raises(RuntimeError, match="Local: odd"):
        run_with_child(child, lambda receive: None)


def test_a_child_that_dies_is_reported_not_waited_for():
    def child(send):
        os.kill(os.getpid(), signal.SIGKILL)

    with pytest.raises(ChildDied, match="SIGKILL"):
        run_with_child(child, lambda receive: receive())


def test_the_child_is_killed_when_the_parent_fails():
    pids = []

    def child(send):
        send(os.getpid())
        time.sleep(60)

    def parent(receive):
        pids.append(receive())
        raise KeyError("stop")

    start = time.perf_counter()
    with pytest.raises(KeyError):
        run_with_child(child, parent)
    assert time.perf_counter() - start < 10
    with pytest.raises(ProcessLookupError):
        os.kill(pids[0], 0)

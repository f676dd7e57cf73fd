"""Run part of a computation in a forked child process, with messages from the child to this one.

Role: the one place where an asset's build uses a second CPU core (``pipeline/chunks.py`` detailizes
and meshes the second half of a long asset's blocks in a child). ``fork`` is used, not ``spawn``: the
child starts at once with everything already loaded (the detailizer, its library, the coarse grid),
and shares those pages with this process until either writes them.

The child runs ``child(send)``; each ``send(message)`` reaches this process's ``receive()``, in order.
Its return value is sent last. An exception in the child is raised here again (as itself when it
pickles, else as a ``RuntimeError`` naming it); a child that dies (killed for memory, a crash) raises
``ChildDied``. The child never outlives the call: it is killed when this process stops waiting for it.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import queue
import signal
import sys
import threading
import traceback
from collections.abc import Callable
from typing import Any

from core.processes import die_with_parent

#: Whether this platform can fork (Linux, macOS); elsewhere callers run everything in one process.
CAN_FORK = "fork" in multiprocessing.get_all_start_methods() and sys.platform != "win32"

_RESULT, _MESSAGE, _ERROR = "result", "message", "error"


class ChildDied(RuntimeError):
    """The child process ended without sending its result (killed, out of memory, crashed)."""


def _child_main(conn, child: Callable[[Callable[[Any], None]], Any]) -> None:
    """The child's body. Messages go out through a thread of their own: a pipe holds only ~64 KB, and
    the child must not wait while the parent is still busy with its own part before it reads."""
    die_with_parent()  # killed when the thread that forked it ends
    outbox: queue.SimpleQueue = queue.SimpleQueue()

    def sender() -> None:
        while (item := outbox.get()) is not None:
            conn.send(item)

    thread = threading.Thread(target=sender, name="decollage-blocks-send", daemon=True)
    thread.start()
    try:
        result = child(lambda message: outbox.put((_MESSAGE, message)))
        outbox.put((_RESULT, result))
    except BaseException as exc:  # noqa: BLE001 - handed to the parent
        try:
            pickle.dumps(exc)
            error: BaseException = exc
        except Exception:  # noqa: BLE001 - an exception that does not pickle travels as text
            error = RuntimeError(f"{type(exc).__name__}: {exc}")
        outbox.put((_ERROR, (error, traceback.format_exc())))
    finally:
        outbox.put(None)
        thread.join()
        conn.close()


def run_with_child(child: Callable[[Callable[[Any], None]], Any],
                   parent: Callable[[Callable[[], Any]], Any]) -> tuple[Any, Any]:
    """(parent's result, child's result) of ``parent(receive)`` here and ``child(send)`` in a forked process.

    Raises:
        whatever ``parent`` raises (the child is killed); the child's exception; ``ChildDied``.
    """
    context = multiprocessing.get_context("fork")
    reader, writer = context.Pipe(duplex=False)
    process = context.Process(target=_child_main, args=(writer, child), daemon=True, name="decollage-blocks")
    process.start()
    writer.close()

    def receive() -> Any:
        try:
            kind, payload = reader.recv()
        except EOFError:
            process.join(5)
            raise ChildDied(f"the block process ended unexpectedly ({_exit_reason(process.exitcode)})") from None
        if kind == _ERROR:
            error, text = payload
            raise error from RuntimeError(f"in the block process:\n{text}")
        return kind, payload

    def receive_message() -> Any:
        kind, payload = receive()
        if kind != _MESSAGE:
            raise ChildDied("the block process finished without sending what was expected")
        return payload

    try:
        mine = parent(receive_message)
        kind, theirs = receive()
        while kind != _RESULT:  # messages the parent did not ask for
            kind, theirs = receive()
        process.join()
        return mine, theirs
    finally:
        reader.close()
        if process.is_alive():
            process.kill()
            process.join()


def _exit_reason(code: int | None) -> str:
    if code is None:
        return "still running"
    if code < 0:
        name = signal.Signals(-code).name if -code in signal.valid_signals() else str(-code)
        return f"killed by {name}" + (", probably for lack of memory" if -code == signal.SIGKILL else "")
    return f"exit code {code}"


def available_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS
        return os.cpu_count() or 1

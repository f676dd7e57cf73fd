"""What every sub-command shares: exit codes, the stderr console, the one way an error ends a command, and
the one way a page server (``view``, ``paint``) runs until Ctrl-C.

Library code raises ``DecollageError`` subclasses (``core/errors.py``); a
sub-command catches them and calls ``fail``, which prints the one-line
message and exits with the code for invalid input.
"""

from __future__ import annotations

import sys
import webbrowser
from enum import IntEnum

import typer
from rich.console import Console
from rich.markup import escape

from core.errors import DecollageError
from studio.http import serve


class ExitCode(IntEnum):
    """Exit codes of every ``decollage`` command."""

    OK = 0  # everything asked for was done (all assets built / recipe valid)
    ASSETS_FAILED = 1  # some assets failed; the others were still built and are in the manifest
    INVALID = 2  # invalid recipe or usage (nothing was built or written)
    INTERNAL = 3  # internal error (a bug; run with --debug for the traceback)
    INTERRUPTED = 130  # Ctrl-C (128 + SIGINT)
    TERMINATED = 143  # SIGTERM (128 + SIGTERM), e.g. a CI timeout


def stderr() -> Console:
    """The console for people: stderr, no highlighting, soft-wrapped."""
    return Console(stderr=True, highlight=False, soft_wrap=True)


def fail(exc: DecollageError, code: ExitCode = ExitCode.INVALID) -> None:
    """Print ``error: <file>: <field>: <message> (<hint>)`` and exit with ``code``.

    The message is printed literally: brackets in it (``assets[2]``, ``pip install 'decollage[cluster]'``)
    are not read as console markup.
    """
    stderr().print(f"[bold red]error:[/] {escape(exc.one_line())}", markup=True)
    raise typer.Exit(int(code))


LOOPBACK = ("127.0.0.1", "localhost", "::1")


def serve_page(server, title: str, open_browser: bool = False) -> None:
    """Print the page's URL (stdout) and how to stop (stderr), serve until Ctrl-C, say it stopped.

    ``server`` comes from ``studio.http.make_server``.
    """
    host = server.server_address[0]
    if host not in LOOPBACK:
        stderr().print(f"[yellow]warning:[/] listening on {host}: the studio has no login; anyone who can reach "
                       "this address can use it (default: --host 127.0.0.1)")

    def ready(url: str) -> None:
        sys.stdout.write(url + "\n")
        sys.stdout.flush()
        stderr().print(f"{title} at {url} (Ctrl-C stops)", markup=False)
        if open_browser:
            webbrowser.open(url)

    serve(server, ready)
    stderr().print("stopped")

def literal(text: str) -> str:
    """``text`` safe to embed in console markup (brackets shown as they are)."""
    return escape(str(text))

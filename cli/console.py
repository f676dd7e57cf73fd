"""What every sub-command shares: exit codes, the stderr console, and the one way an error ends a command.

Library code raises ``DecollageError`` subclasses (``core/errors.py``); a
sub-command catches them and calls ``fail``, which prints the one-line
message and exits with the code for invalid input.
"""

from __future__ import annotations

from enum import IntEnum

import typer
from rich.console import Console

from core.errors import DecollageError


class ExitCode(IntEnum):
    """Exit codes of every ``decollage`` command."""

    OK = 0  # everything asked for was done (all assets built / recipe valid)
    ASSETS_FAILED = 1  # some assets failed; the others were still built and are in the manifest
    INVALID = 2  # invalid recipe or usage (nothing was built or written)
    INTERNAL = 3  # internal error (a bug; run with --debug for the traceback)
    INTERRUPTED = 130  # Ctrl-C


def stderr() -> Console:
    """The console for people: stderr, no highlighting, soft-wrapped."""
    return Console(stderr=True, highlight=False, soft_wrap=True)


def fail(exc: DecollageError, code: ExitCode = ExitCode.INVALID) -> None:
    """Print ``error: <file>: <field>: <message> (<hint>)`` and exit with ``code``."""
    stderr().print(f"[bold red]error:[/] {exc.one_line()}", markup=True)
    raise typer.Exit(int(code))

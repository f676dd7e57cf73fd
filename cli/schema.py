"""``decollage schema`` and ``decollage version``: the recipe JSON Schema (for editor autocomplete) and the version."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Optional

import typer

from cli.console import fail
from core import __version__
from core.errors import DecollageError
from core.files import write_bytes_atomic
from core.recipe_loader import json_schema


def schema_command(out: Optional[Path] = typer.Option(None, "--out", "-o", help="Write to a file instead of stdout.")) -> None:
    """Print the JSON Schema of recipes (for editor autocomplete)."""

    text = json.dumps(json_schema(), indent=2) + "\n"
    if out is None:
        sys.stdout.write(text)
    else:

        try:
            write_bytes_atomic(out, text.encode())
        except DecollageError as exc:
            fail(exc)


def version_command() -> None:
    """Print the version."""

    typer.echo(f"decollage {__version__}")



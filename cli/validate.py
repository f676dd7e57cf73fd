"""``decollage validate``: check recipes without building."""

from __future__ import annotations

from pathlib import Path

import typer

from cli.console import fail
from core.errors import DecollageError
from core.recipe_loader import load_recipe
from pipeline.build import check_recipe


def validate_command(recipes: list[Path] = typer.Argument(..., help="Recipe files to check.")) -> None:
    """Check recipes (schema, input files, detailizer and style names) without building."""

    for path in recipes:
        try:
            loaded = load_recipe(path)
            check_recipe(loaded)
        except DecollageError as exc:
            fail(exc)
        typer.echo(f"{path}: ok ({len(loaded.recipe.assets)} assets)")



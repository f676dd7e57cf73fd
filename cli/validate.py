"""``decollage validate``: check recipes without building."""

from __future__ import annotations

from pathlib import Path

import typer

from cli.console import fail
from core.errors import DecollageError
from core.recipe_loader import load_recipe
from core.variants import DEFAULT_MAX_ASSETS
from pipeline.build import check_recipe


def validate_command(
    recipes: list[Path] = typer.Argument(..., help="Recipe files to check."),
    max_assets: int = typer.Option(DEFAULT_MAX_ASSETS, "--max-assets", min=1,
                                   help="Refuse a recipe whose variants expand to more assets than this."),
) -> None:
    """Check recipes without building: schema, input files (kind, size, format), fonts covering their text,
    detailizer, checkpoint, style and part names. Scripts are never run."""

    for path in recipes:
        try:
            loaded = load_recipe(path, max_assets)
            check_recipe(loaded)
        except DecollageError as exc:
            fail(exc)
        typer.echo(f"{path}: ok ({len(loaded.recipe.assets)} assets)")



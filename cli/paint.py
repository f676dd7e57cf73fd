"""``decollage paint``: a local page to paint parts and styles onto an asset's grid, detailize it, save the recipe."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from cli.console import fail, serve_page
from core.errors import DecollageError
from studio.http import make_server
from studio.painter import PaintSession, painter_app


def paint_command(
    recipe: Path = typer.Argument(..., help="Recipe YAML file (the painter saves into it)."),
    asset: Optional[str] = typer.Option(None, "--asset", help="Asset to show first (default: the first one)."),
    allow_scripts: bool = typer.Option(False, "--allow-scripts",
                                       help="Run the build123d/cadquery scripts the recipe names (off: such "
                                            "assets are refused and no script runs)."),
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on (default: this machine only)."),
    port: int = typer.Option(8766, "--port", min=0, max=65535, help="Port; 0 picks a free one."),
    open_browser: bool = typer.Option(False, "--open", help="Open the page in the default browser."),
) -> None:
    """Paint styles onto an asset's coarse grid, see the detailed mesh, save the edits into the recipe."""

    session = None
    try:
        session = PaintSession(recipe, asset, allow_scripts)
        server = make_server(painter_app(session), host, port)
    except DecollageError as exc:
        if session is not None:
            session.close()
        fail(exc)
    serve_page(server, f"painter of {recipe}", open_browser)

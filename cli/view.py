"""``decollage view``: a local page showing a build folder (3D view, previews, manifest figures, failures)."""

from __future__ import annotations

from pathlib import Path

import typer

from cli.console import fail, serve_page
from core.errors import DecollageError
from studio.gallery import gallery_app
from studio.http import make_server


def view_command(
    out: Path = typer.Argument(..., help="Build folder (what 'decollage build -o' wrote)."),
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on (default: this machine only)."),
    port: int = typer.Option(8765, "--port", min=0, max=65535, help="Port; 0 picks a free one."),
    open_browser: bool = typer.Option(False, "--open", help="Open the page in the default browser."),
) -> None:
    """Show a build folder in the browser: every asset in 3D, its preview, figures and warnings; failures."""

    try:
        server = make_server(gallery_app(out), host, port)
    except DecollageError as exc:
        fail(exc)
    serve_page(server, f"gallery of {out}", open_browser)

"""``decollage view``'s page: a gallery of one build folder (3D view, preview, manifest figures, failures).

Role: the gallery's routes. The page (``studio/static/view.html``, ``view.js``)
reads the build's ``manifest.json`` (``pipeline/manifest.py``) through
``/api/manifest`` and the files it lists through ``/files/<path>``; it renders
the selected asset's GLB with three.js. It polls ``/api/build`` (the build
signal ``build.json``, whose counter goes up after every build, ``decollage
build --watch`` included) and reloads what was rebuilt. Nothing is built or run: the gallery
only reads the build folder, and only its regular, non-hidden files (so not the
cache records in ``.decollage/``).
"""

from __future__ import annotations

import json
from http import HTTPStatus
from pathlib import Path

from core.errors import StudioError
from pipeline.manifest import BUILD_SIGNAL, MANIFEST_NAME
from studio.http import App, HttpError, Request, Response
from studio.pages import base_app


def read_manifest(out_dir: Path) -> dict:
    """The build folder's manifest as a dict; raises StudioError when it is missing or not a manifest."""
    path = out_dir / MANIFEST_NAME
    if not out_dir.is_dir():
        raise StudioError("not a folder", file=out_dir, hint="give the folder 'decollage build -o' wrote")
    if not path.is_file():
        raise StudioError(f"no {MANIFEST_NAME} in this folder", file=out_dir,
                          hint="build into it first: decollage build RECIPE -o " + str(out_dir))
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise StudioError(f"cannot read {MANIFEST_NAME}: {exc}", file=path) from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("assets"), list):
        raise StudioError("not a decollage manifest (no 'assets' list)", file=path)
    return manifest


def gallery_app(out_dir: Path) -> App:
    """The gallery of ``out_dir``: ``/`` (the page), ``/api/manifest``, ``/files/...`` (the build's files)."""
    out_dir = Path(out_dir)
    read_manifest(out_dir)  # fail at start, not on the first request
    app = base_app("view.html")

    def manifest(_: Request) -> Response:
        try:
            data = read_manifest(out_dir)
        except StudioError as exc:
            raise HttpError(HTTPStatus.NOT_FOUND, exc.one_line()) from None
        data["studio"] = {"folder": out_dir.resolve().name, "path": str(out_dir.resolve())}
        return Response.json(data)

    def build_signal(_: Request) -> Response:
        try:
            data = json.loads((out_dir / BUILD_SIGNAL).read_text(encoding="utf-8"))
        except (OSError, ValueError, UnicodeDecodeError):
            data = {}
        if not isinstance(data, dict):
            data = {}
        return Response.json({"counter": data.get("counter", 0), "rebuilt": data.get("rebuilt", []),
                              "failed": data.get("failed", [])})

    app.routes[("GET", "/api/manifest")] = manifest
    app.routes[("GET", "/api/build")] = build_signal
    app.trees["/files/"] = out_dir
    return app

"""The studio's own files: the pages in ``studio/static/`` and the WebGL library installed by npm.

Role: where the static files are and the routes every page shares. three.js
(the WebGL library both pages draw with) is installed from the npm registry by
``bash scripts/install.sh`` (``npm ci --prefix studio/web``, pinned by
``studio/web/package-lock.json``) and served from ``studio/web/node_modules/three``
under ``/vendor/three/``: nothing comes from a CDN, and the pages work offline.
"""

from __future__ import annotations

import base64
import hashlib
import re
from pathlib import Path

from core.errors import StudioError
from studio.http import App, Request, Response, file_response

STUDIO_DIR = Path(__file__).resolve().parent
STATIC_DIR = STUDIO_DIR / "static"
WEB_DIR = STUDIO_DIR / "web"
THREE_DIR = WEB_DIR / "node_modules" / "three"

#: The parts of the three package the pages import: the core module and its add-ons (controls, GLTF loader).
_THREE_TREES = {"/vendor/three/build/": THREE_DIR / "build", "/vendor/three/examples/jsm/": THREE_DIR / "examples" / "jsm"}

_IMPORT_MAP = re.compile(r'<script type="importmap">(.*?)</script>', re.S)


def three_version() -> str:
    """The installed three.js version; raises StudioError with the install command when it is missing."""
    package = THREE_DIR / "package.json"
    if not (package.is_file() and (THREE_DIR / "build" / "three.module.js").is_file()):
        raise StudioError(
            f"the WebGL library three.js is not installed in {THREE_DIR.parent}",
            hint="run: bash scripts/install.sh   (or: npm ci --prefix studio/web)",
        )
    match = re.search(r'"version"\s*:\s*"([^"]+)"', package.read_text(encoding="utf-8"))
    return match.group(1) if match else "unknown"


def page_csp(html: Path) -> str:
    """Content-Security-Policy for a page: scripts from this server and the page's import map (by its hash).

    ``'wasm-unsafe-eval'`` lets the page compile WebAssembly (and nothing else: no ``eval``, no inline
    scripts): three.js's meshopt decoder is WebAssembly, and GLBs written with ``export.compression:
    meshopt`` need it."""
    hashes = []
    for block in _IMPORT_MAP.findall(html.read_text(encoding="utf-8")):
        digest = base64.b64encode(hashlib.sha256(block.encode("utf-8")).digest()).decode("ascii")
        hashes.append(f"'sha256-{digest}'")
    return ("default-src 'self'; script-src 'self' 'wasm-unsafe-eval' " + " ".join(hashes) + "; style-src 'self'; "
            "img-src 'self' data: blob:; connect-src 'self' blob:; object-src 'none'; base-uri 'none'; "
            "frame-ancestors 'none'; form-action 'none'")


def base_app(page: str) -> App:
    """An app serving ``page`` (an HTML file in ``studio/static``) at ``/``, the static files and three.js."""
    three_version()
    html = STATIC_DIR / page

    def index(_: Request) -> Response:
        response = file_response(html)
        response.headers["Cache-Control"] = "no-store"
        return response

    app = App(csp=page_csp(html))
    app.routes[("GET", "/")] = index
    app.trees["/static/"] = STATIC_DIR
    app.trees.update(_THREE_TREES)
    return app

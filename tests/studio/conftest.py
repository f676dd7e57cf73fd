"""Fixtures of the studio's tests: servers run in a thread, recipes and builds made in code, a real Chromium.

The browser is the distribution's Chromium (``/usr/bin/chromium``, installed by
``bash scripts/install.sh test``) driven by playwright; nothing is downloaded.
Without it the browser tests are skipped, except under ``CI=true`` where they
fail. Pages keep their Content-Security-Policy in the tests, so waiting is done
by polling ``page.evaluate`` (playwright's ``wait_for_function`` needs eval).
"""

from __future__ import annotations

import io
import os
import tempfile
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from core.recipe_loader import load_recipe
from pipeline.batch import build_recipe
from studio.http import App, make_server, url_of

CHROMIUM = Path("/usr/bin/chromium")
#: Launch flags that work on CI's machine (root, no display, closed network).
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]
#: The 3D views' background (studio/static/viewer3d.js BACKGROUND).
BACKGROUND_RGB = (0x1D, 0x21, 0x29)

#: A small recipe: two CAD assets and a text, with the fast detailizer and small grids (fine grid 128³).
SMALL_RECIPE = """\
# A small studio test recipe. This comment must survive a save.
version: 1
defaults:
  detailize: {detailizer: upsample}
  export: {max_triangles: 6000, preview_size_px: 96}
assets:
  - name: hut                       # two parts, two styles
    source:
      kind: cad
      parts:
        - {name: walls, shape: box, size: [1.0, 1.0, 0.6], at: [0, 0, 0.3]}
        - {name: roof, shape: cone, radius_bottom: 0.7, height: 0.6, at: [0, 0, 0.6]}
    grid: {resolution: 8}
    regions:
      - {parts: [walls], part: body, style: brick}   # the walls
      - {parts: [roof], part: roof, style: moss}
  - name: word                      # a compressed GLB: the page decodes it with meshopt's decoder
    source: {kind: text, text: HI, size_m: 0.3, depth_m: 0.1}
    grid: {resolution: 8}
    regions:
      - {parts: ["*"], part: body, style: slate}
    export: {compression: meshopt}
"""


@contextmanager
def serving(app: App):
    """Run ``app`` on 127.0.0.1 (a free port) in a thread; yields its URL; stops and closes it after."""
    server = make_server(app, "127.0.0.1", 0)
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.1}, daemon=True)
    thread.start()
    try:
        yield url_of(server)
    finally:
        server.shutdown()
        server.server_close()
        app.close()
        thread.join(timeout=5)


@pytest.fixture
def small_recipe(tmp_path) -> Path:
    path = tmp_path / "recipes" / "small.yaml"
    path.parent.mkdir()
    path.write_text(SMALL_RECIPE)
    return path


@pytest.fixture(scope="session")
def small_build(tmp_path_factory) -> Path:
    """A build folder of SMALL_RECIPE plus an asset that fails (an empty voxel grid): 3 assets, 1 failed."""
    root = tmp_path_factory.mktemp("small_build")
    np.savez(root / "empty.npz", occupancy=np.zeros((4, 4, 4), dtype=bool))
    recipe = root / "small.yaml"
    recipe.write_text(SMALL_RECIPE + """\
  - name: broken
    source: {kind: voxels, path: empty.npz}
    regions:
      - {parts: ["*"], part: body, style: brick}
""")
    out = root / "out"
    build_recipe(load_recipe(recipe), out)
    return out


def _chromium_or_skip() -> None:
    if not CHROMIUM.is_file():
        message = f"{CHROMIUM} is missing: bash scripts/install.sh test installs Debian's chromium (as root)"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)


@pytest.fixture(scope="session")
def browser():
    """A headless Chromium (the distribution's), shared by the browser tests; closed at the end."""
    _chromium_or_skip()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p, tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as profile:
        context = p.chromium.launch_persistent_context(
            profile, executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_FLAGS,
            viewport={"width": 1400, "height": 860})
        try:
            yield context
        finally:
            context.close()


@pytest.fixture
def page(browser):
    """A fresh tab that records page errors (``page.errors``); closed after the test."""
    tab = browser.new_page()
    tab.errors = []
    tab.on("pageerror", lambda exc: tab.errors.append(str(exc)))
    tab.on("console", lambda msg: tab.errors.append(msg.text) if msg.type == "error" else None)
    yield tab
    tab.close()


def wait_js(page, expression: str, timeout_s: float = 60.0):
    """Poll ``expression`` in the page until it is truthy; returns its value, or fails naming it."""
    end = time.monotonic() + timeout_s
    while True:
        value = page.evaluate(expression)
        if value:
            return value
        if time.monotonic() > end:
            errors = page.evaluate("window.studio && window.studio.error")
            pytest.fail(f"timed out after {timeout_s} s waiting for {expression} (page error: {errors}; "
                        f"console: {getattr(page, 'errors', [])[-3:]})")
        time.sleep(0.1)


def drawn_fraction(page, selector: str) -> float:
    """Share of a canvas's pixels that differ clearly from the 3D views' background colour."""
    from PIL import Image

    image = np.asarray(Image.open(io.BytesIO(page.locator(selector).screenshot())).convert("RGB")).astype(int)
    differs = np.abs(image - np.asarray(BACKGROUND_RGB)).sum(axis=2) > 30
    return float(differs.mean())

"""The studio's pages in a real headless Chromium: the gallery draws, painting changes the mesh, saving rebuilds it.

Marked e2e: each test starts a server, drives the distribution's Chromium
(playwright, ``/usr/bin/chromium``) and builds with the fast detailizer.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from core.recipe_loader import load_recipe
from pipeline.batch import build_recipe
from pipeline.build import check_recipe
from studio.gallery import gallery_app
from studio.painter import PaintSession, painter_app
from tests.studio.conftest import drawn_fraction, serving, wait_js

pytestmark = pytest.mark.e2e


def _page_errors(page) -> list[str]:
    """Errors the page raised or logged (WebGL driver performance notes are warnings, not errors)."""
    return [e for e in page.errors if "favicon" not in e]


def test_gallery_lists_every_asset_draws_it_and_filters(page, small_build, tmp_path):
    small_build = Path(shutil.copytree(small_build, tmp_path / "build"))  # this test rewrites its manifest
    manifest = json.loads((small_build / "manifest.json").read_text())
    with serving(gallery_app(small_build)) as url:
        page.goto(url)
        wait_js(page, "window.studio.ready")
        assert page.locator(".card").count() == len(manifest["assets"]) == 3
        wait_js(page, "window.studio.shown === 'hut' && window.studio.viewer.frames > 0")
        assert drawn_fraction(page, "#viewer") > 0.02
        assert page.locator(".card img").count() == 2  # the previews of the two built assets
        failed = page.locator(".card.failed")
        assert failed.count() == 1 and "voxel grid is empty" in failed.inner_text()
        assert "Strict-IOU" in page.inner_text("#details")

        page.fill("#filter", "slate")  # by style
        assert wait_js(page, "window.studio.visibleCards === 1")
        assert page.locator(".card:not([hidden])").get_attribute("data-name") == "word"
        page.fill("#filter", "HU")  # by name, any case
        assert page.locator(".card:not([hidden])").get_attribute("data-name") == "hut"
        page.fill("#filter", "")
        page.select_option("#status-filter", "failed")
        assert wait_js(page, "window.studio.visibleCards === 1")
        page.select_option("#status-filter", "")
        page.locator(".card[data-name=word]").click()
        wait_js(page, "window.studio.shown === 'word'")
        assert drawn_fraction(page, "#viewer") > 0.01

        # A new build into the folder (build.json's counter goes up): the page reloads the manifest.
        signal = small_build / "build.json"
        counter = json.loads(signal.read_text())["counter"]
        manifest["assets"] = [a for a in manifest["assets"] if a["name"] != "broken"]
        (small_build / "manifest.json").write_text(json.dumps(manifest))
        signal.write_text(json.dumps({"counter": counter + 1, "rebuilt": ["word"], "failed": []}))
        wait_js(page, "window.studio.refreshes >= 1 && window.studio.cards === 2", 30)
        wait_js(page, "window.studio.shown === 'word'")
    assert _page_errors(page) == []


def _sha256(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _detailize(page) -> str:
    page.evaluate("window.studio.result = null")
    page.click("#detailize")
    return wait_js(page, "window.studio.result && window.studio.result.sha256", 180)


def _build_hut(recipe, out) -> str:
    loaded = load_recipe(recipe)
    check_recipe(loaded)
    reports = build_recipe(loaded, out, only=lambda a: a.name == "hut", force=True)
    assert [r.status for r in reports] == ["built"], [r.error for r in reports]
    return _sha256(out / "hut.glb")


def test_painter_restyle_detailize_save_and_build_the_same_glb(page, small_recipe, tmp_path):
    session = PaintSession(small_recipe, "hut")
    with serving(painter_app(session)) as url:
        page.goto(url)
        wait_js(page, "window.studio.ready && window.studio.state.asset")
        assert page.locator("#parts .part-row").count() == 2
        assert drawn_fraction(page, "#coarse") > 0.02
        page.uncheck("#live")
        first = _detailize(page)
        assert drawn_fraction(page, "#fine") > 0.02

        # Change the roof's style in the parts panel, press detailize: the mesh changes.
        page.select_option('select[data-part="roof"]', "brick")
        second = _detailize(page)
        assert second != first
        assert page.evaluate("window.studio.result.sha256 === window.studio.result.server_sha256")

        # Save: the YAML validates, keeps its comments, and builds the page's GLB byte for byte.
        page.click("#save")
        saved = wait_js(page, "window.studio.saved")
        assert saved["changed"] and saved["edits"] == ["assets[0].regions[1].style: moss → brick"]
        text = small_recipe.read_text()
        assert "# A small studio test recipe. This comment must survive a save." in text
        assert "  - name: hut                       # two parts, two styles" in text
        assert _build_hut(small_recipe, tmp_path / "out1") == second

        # Paint one voxel with the brush, detailize, save: a cells rule, and again the same GLB.
        page.click("#tool-brush")
        page.select_option("#paint-style", "moss")
        state = page.evaluate("({cells: window.studio.state.asset.cells, style: Array.from(window.studio.state.style)})")
        cells = np.asarray(state["cells"]).reshape(-1, 3)
        front = int(np.argmax(cells @ np.array([0.9, 0.55, 1.3])))  # the voxel nearest the camera
        x, y = page.evaluate(f"window.studio.screenOf({front})")
        page.mouse.click(x, y)
        after = page.evaluate("Array.from(window.studio.state.style)")
        changed = [i for i, (a, b) in enumerate(zip(state["style"], after)) if a != b]
        assert len(changed) == 1
        third = _detailize(page)
        assert third not in (first, second)
        page.evaluate("window.studio.saved = null")
        page.click("#save")
        saved = wait_js(page, "window.studio.saved")
        assert saved["changed"] and "cells:" in small_recipe.read_text()
        assert _build_hut(small_recipe, tmp_path / "out2") == third
    assert _page_errors(page) == []

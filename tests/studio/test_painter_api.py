"""The painter's API without a browser: script opt-in, saving, conflicts, variants, cross-origin writes."""

from __future__ import annotations

import http.client
import json
from urllib.parse import urlsplit

import pytest

from core.errors import StudioError, UsageError
from core.recipe_loader import load_recipe
from studio.painter import PaintSession, painter_app
from tests.studio.conftest import serving

SCRIPT = '''\
from pathlib import Path

from build123d import Box


def build():
    Path(__file__).with_name("ran.txt").write_text("the script ran")
    return {"block": Box(1, 1, 1)}
'''


def _call(url: str, method: str, path: str, data=None, headers: dict | None = None):
    parts = urlsplit(url)
    conn = http.client.HTTPConnection(parts.hostname, parts.port, timeout=60)
    body = None if data is None else json.dumps(data).encode()
    conn.request(method, path, body=body, headers={"Content-Type": "application/json", **(headers or {})})
    response = conn.getresponse()
    payload = response.read()
    conn.close()
    return response.status, json.loads(payload) if payload else None


def _target(asset: dict, **restyle) -> dict:
    """The asset's own labels as a target, with part label → new style for the parts named."""
    styles = list(asset["style_names"])
    style = list(asset["style"])
    for part, new in restyle.items():
        if new not in styles:
            styles.append(new)
        k = asset["part_names"].index(part)
        style = [styles.index(new) if p == k else s for p, s in zip(asset["part"], style)]
    return {"part_names": asset["part_names"], "style_names": styles, "part": asset["part"], "style": style}


def test_a_script_runs_only_with_the_opt_in(tmp_path):
    (tmp_path / "block.py").write_text(SCRIPT)
    recipe = tmp_path / "scripted.yaml"
    recipe.write_text("version: 1\nassets:\n  - name: scripted\n    source: {kind: cad, script: block.py}\n"
                      "    grid: {resolution: 4}\n    detailize: {detailizer: upsample}\n"
                      "    regions: [{part: body, style: brick}]\n")
    session = PaintSession(recipe)
    try:
        assert session.session_json()["assets"][0]["script"] == "block.py"
        with pytest.raises(StudioError, match="--allow-scripts") as info:
            session.asset_json("scripted")
        assert info.value.field == "assets[0].source.script"
        assert not (tmp_path / "ran.txt").exists()
    finally:
        session.close()
    session = PaintSession(recipe, allow_scripts=True)
    try:
        assert session.asset_json("scripted")["shape"] == [4, 4, 4]
        assert (tmp_path / "ran.txt").read_text() == "the script ran"
    finally:
        session.close()


def test_unknown_asset_is_a_usage_error(small_recipe):
    with pytest.raises(UsageError, match="'nope' is not in the recipe"):
        PaintSession(small_recipe, "nope")


def test_save_writes_the_recipe_and_refuses_stale_or_foreign_writes(small_recipe):
    session = PaintSession(small_recipe, "hut")
    with serving(painter_app(session)) as url:
        status, asset = _call(url, "GET", "/api/asset?name=hut")
        assert status == 200 and asset["part_names"] == ["body", "roof"] and asset["savable"]
        body = {"asset": "hut", "target": _target(asset, roof="slate"), "recipe_sha256": asset["recipe_sha256"]}

        port = urlsplit(url).port
        assert _call(url, "POST", "/api/save", body, {"Origin": "http://evil.example"})[0] == 403
        assert _call(url, "POST", "/api/save", body, {"Origin": f"http://127.0.0.1:{port}", "Content-Type": "text/plain"})[0] == 415
        assert _call(url, "POST", "/api/save", {**body, "recipe_sha256": "0" * 64})[0] == 409
        bad = {**body, "target": {**body["target"], "part": body["target"]["part"][:-1]}}
        status, error = _call(url, "POST", "/api/save", bad)
        assert status == 400 and "one per occupied voxel" in error["error"]
        assert small_recipe.read_text().count("style: moss") == 1  # nothing written so far

        status, saved = _call(url, "POST", "/api/save", body, {"Origin": f"http://127.0.0.1:{port}"})
        assert status == 200 and saved["changed"], saved
        assert saved["edits"] == ["assets[0].regions[1].style: moss → slate"]
        text = small_recipe.read_text()
        assert "      - {parts: [roof], part: roof, style: slate}" in text
        assert "# A small studio test recipe. This comment must survive a save." in text
        assert load_recipe(small_recipe).recipe.assets[0].regions[1].style == "slate"
        # Saving the same labels again changes nothing.
        again = {**body, "recipe_sha256": saved["recipe_sha256"]}
        assert _call(url, "POST", "/api/save", again)[1]["changed"] is False


def test_variant_assets_are_painted_but_not_saved(tmp_path):
    recipe = tmp_path / "variants.yaml"
    recipe.write_text("version: 1\nassets:\n  - name: sign\n    variants: {style: [brick, moss]}\n"
                      "    source: {kind: text, text: A, size_m: 0.3}\n    grid: {resolution: 4}\n"
                      "    detailize: {detailizer: upsample}\n"
                      "    regions: [{part: body, style: '${style}'}]\n")
    session = PaintSession(recipe)
    with serving(painter_app(session)) as url:
        _, meta = _call(url, "GET", "/api/session")
        assert [a["variant"] for a in meta["assets"]] == ["sign_brick", "sign_moss"]
        _, asset = _call(url, "GET", "/api/asset?name=sign_brick")
        assert not asset["savable"] and "every variant" in asset["save_note"]
        body = {"asset": "sign_brick", "target": _target(asset, body="plum"), "recipe_sha256": asset["recipe_sha256"]}
        status, error = _call(url, "POST", "/api/save", body)
        assert status == 400 and "not saved" in error["error"]
        before = recipe.read_text()
        status, job = _call(url, "POST", "/api/detailize", body)
        assert status == 200 and job["job"] >= 1
        assert recipe.read_text() == before


def test_api_rejects_unknown_routes_and_bad_queries(small_recipe):
    session = PaintSession(small_recipe)
    with serving(painter_app(session)) as url:
        assert _call(url, "GET", "/api/asset")[0] == 400
        assert _call(url, "GET", "/api/asset?name=nope")[0] == 404
        assert _call(url, "GET", "/api/job?id=x")[0] == 400
        assert _call(url, "GET", "/api/job?id=999")[0] == 404
        assert _call(url, "GET", "/api/detailizer?name=nope")[0] == 404
        assert _call(url, "GET", "/api/save")[0] == 405
        assert _call(url, "GET", "/results/../../etc/passwd")[0] in (403, 404)
        assert _call(url, "GET", "/results/%2e%2e/%2e%2e/etc/passwd")[0] in (403, 404)
        assert _call(url, "GET", "/recipes/small.yaml")[0] == 404
        status, palette = _call(url, "POST", "/api/palette", {"styles": ["brick", "moss"]})
        assert status == 200 and len(palette["brick"]) == 3 and palette["brick"] != palette["moss"]
        _, asset = _call(url, "GET", "/api/asset?name=hut")
        body = {"asset": "hut", "target": _target(asset, roof="slate"), "extra": ["plum"]}
        status, palette = _call(url, "POST", "/api/palette", body)
        assert status == 200 and set(palette) == {"brick", "slate", "plum"}
        assert _call(url, "POST", "/api/palette", {"styles": "brick"})[0] == 400

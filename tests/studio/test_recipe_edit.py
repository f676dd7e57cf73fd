"""The recipe round trip: unchanged files write back byte for byte; edits keep comments, order and layout."""

from __future__ import annotations

from pathlib import Path

import pytest

from core.errors import StudioError
from core.recipe_loader import load_recipe, parse_recipe
from studio.paint_rules import RuleEdits
from studio.recipe_edit import RecipeDocument, check_saved, detailize_changes
from tests.conftest import REPO
from tests.studio.conftest import SMALL_RECIPE


@pytest.mark.parametrize("recipe", sorted((REPO / "recipes").glob("*.yaml")), ids=lambda p: p.name)
def test_every_shipped_recipe_round_trips_byte_for_byte(recipe: Path):
    text = recipe.read_text()
    doc = RecipeDocument(text, recipe)
    assert doc.lossless and doc.render() == text


def test_other_layouts_round_trip_too(tmp_path):
    text = "# four-space layout\nversion: 1\nassets:\n-   name: a   # keep me\n    source:\n" \
           "        kind: text\n        text: A\n    regions:\n    -   {part: body, style: x}\n"
    doc = RecipeDocument(text, tmp_path / "r.yaml")
    assert doc.render() == text


def test_edits_keep_comments_and_order(tmp_path):
    path = tmp_path / "small.yaml"
    doc = RecipeDocument(SMALL_RECIPE, path)
    edits = RuleEdits({1: {"style": "slate"}}, [
        {"parts": ["walls"], "part": "body", "style": "ochre"},
        {"parts": ["*"], "cells": [[0, 1, 2], [3, 4, 5]], "part": "roof", "style": "plum"},
    ])
    doc.apply("assets[0]", edits, {"detailizer": "decollage"})
    text = doc.render()
    old, new = SMALL_RECIPE.splitlines(), text.splitlines()
    # Every line of the original is still there, in order, except the one rule whose style changed.
    changed = [line for line in old if line not in new]
    assert changed == ["      - {parts: [roof], part: roof, style: moss}"]
    assert "      - {parts: [roof], part: roof, style: slate}" in new
    assert "# A small studio test recipe. This comment must survive a save." in new
    assert "  - name: hut                       # two parts, two styles" in new
    assert "      - {parts: [walls], part: body, style: ochre}" in new  # flow style like its neighbours
    assert "          - [0, 1, 2]" in new and "          - [3, 4, 5]" in new
    assert "    detailize: {detailizer: decollage}" in new
    asset = parse_recipe(text, path).assets[0]
    assert [r.style for r in asset.regions] == ["brick", "slate", "ochre", "plum"]
    assert asset.regions[3].cells == [(0, 1, 2), (3, 4, 5)]
    assert asset.detailize.detailizer == "decollage"


def test_detailize_changes_only_what_differs(tmp_path):
    path = tmp_path / "small.yaml"
    path.write_text(SMALL_RECIPE)
    asset = load_recipe(path).recipe.assets[0]
    wanted = asset.detailize.model_dump(mode="json")
    assert detailize_changes(asset, wanted) == {}
    assert detailize_changes(asset, {**wanted, "detailizer": "decollage"}) == {"detailizer": "decollage"}


def test_check_saved_refuses_text_that_would_build_something_else(tmp_path):
    path = tmp_path / "small.yaml"
    path.write_text(SMALL_RECIPE)
    asset = load_recipe(path).recipe.assets[0]
    check_saved(SMALL_RECIPE, path, asset)
    with pytest.raises(StudioError, match="would not give the asset 'hut'"):
        check_saved(SMALL_RECIPE.replace("style: moss", "style: plum"), path, asset)
    with pytest.raises(StudioError, match="would not validate"):
        check_saved(SMALL_RECIPE.replace("style: moss", "stile: moss"), path, asset)


def test_an_asset_that_is_gone_is_reported(tmp_path):
    doc = RecipeDocument(SMALL_RECIPE, tmp_path / "small.yaml")
    with pytest.raises(StudioError, match="assets\\[5\\] is not in the file"):
        doc.asset_node("assets[5]")

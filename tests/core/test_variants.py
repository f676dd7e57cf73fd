"""Variant matrices expand to named assets with ${key} substituted; mistakes name the field."""

from __future__ import annotations

from pathlib import Path

import pytest

from core.errors import RecipeError
from core.recipe_loader import parse_recipe

MATRIX = """
version: 1
defaults:
  detailize: {detailizer: upsample}
assets:
  - name: word
    variants: {text: [CASTLE, "Tower!"], style: [stone, moss], seed: [0, 1]}
    source: {kind: text, text: "${text}", size_m: 0.3}
    regions: [{part: body, style: "${style}"}]
    detailize: {seed: "${seed}"}
  - name: plain
    source: {kind: text, text: A}
    regions: [{part: body, style: x}]
"""


def _parse(text):
    return parse_recipe(text, Path("r.yaml"))


def test_matrix_expands_in_key_order_with_typed_values():
    assets = _parse(MATRIX).assets
    names = [a.name for a in assets]
    assert names[:3] == ["word_CASTLE_stone_0", "word_CASTLE_stone_1", "word_CASTLE_moss_0"]
    assert "word_Tower_moss_1" in names and names[-1] == "plain" and len(names) == 9
    last = assets[7]
    assert last.source.text == "Tower!" and last.regions[0].style == "moss"
    assert last.detailize.seed == 1 and isinstance(last.detailize.seed, int)
    assert last.variant == {"text": "Tower!", "style": "moss", "seed": 1}
    assert assets[-1].variant is None


def test_name_template_and_partial_substitution():
    text = MATRIX.replace('source: {kind: text, text: "${text}", size_m: 0.3}',
                          'name_template: "{text}-{style}-s{seed}"\n    source: {kind: text, text: "Big ${text}"}')
    assets = _parse(text).assets
    assert assets[0].name == "CASTLE-stone-s0" and assets[0].source.text == "Big CASTLE"


@pytest.mark.parametrize(
    "change, field, words",
    [
        (('"${seed}"}', '"${sed}"}'), "assets[0].detailize.seed", "not a variant key"),
        (("seed: [0, 1]}", "seed: [0, 1], size: [1, 2]}"), "assets[0].variants", "never used"),
        (('    source: {kind: text, text: "${text}"', '    name_template: "{asset}_{text}"\n    source: {kind: text, text: "${text}"'),
         "assets[0].name_template", "duplicate names"),
        (("seed: [0, 1]}", "seed: []}"), "assets[0].variants.seed", "non-empty"),
        (("seed: [0, 1]}", "seed: [0, 0]}"), "assets[0].variants.seed", "twice"),
        (("seed: [0, 1]}", "seed: [0, -1]}"), "assets[0].detailize.seed", "variant word_CASTLE_stone_1"),
        (("  - name: plain", "  - name: word_CASTLE_stone_0"), "assets", "unique"),
    ],
)
def test_variant_mistakes(change, field, words):
    with pytest.raises(RecipeError) as info:
        _parse(MATRIX.replace(*change))
    assert info.value.field == field, info.value.one_line()
    assert words in info.value.one_line()
    assert info.value.one_line().startswith("r.yaml: ")

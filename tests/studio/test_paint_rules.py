"""Painted labels → region rules: fewest edits, always exactly the painted labels."""

from __future__ import annotations

import numpy as np
import pytest

from core.grid import EMPTY
from core.recipe import RegionRule
from geometry.voxelize import PartGrid
from studio.paint_rules import compile_edits, labels_of, owners


def _grid() -> PartGrid:
    """4×6×4: source part 'walls' at y 0..3, 'roof' at y 4..5; column x = 3 empty."""
    part = np.full((4, 6, 4), EMPTY, np.int16)
    part[:3, :4] = 0
    part[:3, 4:] = 1
    return PartGrid(part=part, part_names=("walls", "roof"), voxel_size_m=0.1, origin_m=(0.0, 0.0, 0.0))


def _rules(*dicts) -> list[RegionRule]:
    return [RegionRule.model_validate(d) for d in dicts]


BASE = _rules({"parts": ["walls"], "part": "body", "style": "brick"}, {"parts": ["roof"], "part": "roof", "style": "moss"})


def test_no_change_gives_no_edits():
    parts, styles = labels_of(_grid(), BASE)
    edits = compile_edits(_grid(), BASE, parts, styles)
    assert edits.empty


def test_a_whole_rule_restyled_is_changed_in_place():
    grid = _grid()
    parts, styles = labels_of(grid, BASE)
    styles = np.where(parts == "roof", "slate", styles)
    edits = compile_edits(grid, BASE, parts, styles)
    assert edits.changed == {1: {"style": "slate"}} and edits.appended == []
    assert edits.describe(BASE) == ["regions[1].style: moss → slate"]


def test_single_voxels_become_a_cells_rule():
    grid = _grid()
    parts, styles = labels_of(grid, BASE)
    cells = np.argwhere(grid.part != EMPTY)
    pick = [i for i, c in enumerate(cells.tolist()) if c in ([0, 0, 0], [2, 3, 1])]
    styles = styles.copy()
    styles[pick] = "ochre"
    edits = compile_edits(grid, BASE, parts, styles)
    assert edits.changed == {}
    assert edits.appended == [{"parts": ["*"], "cells": [[0, 0, 0], [2, 3, 1]], "part": "body", "style": "ochre"}]
    after_parts, after_styles = labels_of(grid, edits.apply(BASE))
    assert np.array_equal(after_styles, styles) and np.array_equal(after_parts, parts)


def test_a_whole_source_part_under_a_shared_rule_gets_a_parts_rule():
    grid = _grid()
    rules = _rules({"parts": ["*"], "part": "body", "style": "brick"})
    parts, styles = labels_of(grid, rules)
    roof = np.asarray(grid.part[grid.part != EMPTY] == 1)
    styles = np.where(roof, "moss", styles)
    parts = np.where(roof, "roof", parts)
    edits = compile_edits(grid, rules, parts, styles)
    assert edits.changed == {}
    assert edits.appended == [{"parts": ["roof"], "part": "roof", "style": "moss"}]


def test_band_rules_and_mixed_edits_reproduce_exactly():
    grid = _grid()
    rules = _rules({"parts": ["*"], "part": "body", "style": "brick"},
                   {"band": {"from": 0.5}, "part": "top", "style": "moss"})
    rng = np.random.default_rng(7)
    parts, styles = labels_of(grid, rules)
    for _ in range(20):
        p, s = parts.copy(), styles.copy()
        idx = rng.choice(len(p), size=rng.integers(1, 12), replace=False)
        s[idx] = rng.choice(["brick", "moss", "slate", "plum"], size=len(idx))
        p[idx[: len(idx) // 2]] = "crest"
        edits = compile_edits(grid, rules, p, s)
        got_p, got_s = labels_of(grid, edits.apply(rules))
        assert np.array_equal(got_p, p) and np.array_equal(got_s, s)


def test_source_rules_are_not_rewritten_in_place():
    grid = _grid()
    rules = _rules({"parts": ["*"], "part": "@source", "style": "brick"})
    parts, styles = labels_of(grid, rules)
    assert set(parts) == {"walls", "roof"}
    parts = np.where(parts == "roof", "cap", parts)
    edits = compile_edits(grid, rules, parts, styles)
    assert 0 not in edits.changed
    assert edits.appended == [{"parts": ["roof"], "part": "cap", "style": "brick"}]


def test_owners_names_the_deciding_rule():
    grid = _grid()
    own = owners(grid, BASE)
    assert set(own.tolist()) == {0, 1}


def test_invalid_names_are_refused():
    from core.errors import StudioError

    grid = _grid()
    parts, styles = labels_of(grid, BASE)
    styles = styles.astype(object)
    styles[0] = "bad name"
    with pytest.raises(StudioError, match="cannot write the rule"):
        compile_edits(grid, BASE, parts, styles.astype(str))

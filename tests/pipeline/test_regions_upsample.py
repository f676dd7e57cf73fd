"""Region rules → LabeledGrid, and the non-learned ``upsample`` detailizer."""

from __future__ import annotations

import numpy as np
import pytest

from model.upsample import UpsampleDetailizer, nearest_upsample
from core.errors import RecipeError
from core.grid import EMPTY, ISO_LEVEL, LabeledGrid
from core.recipe import RegionRule
from pipeline.regions import apply_regions
from geometry.voxelize import PartGrid


def _tower() -> PartGrid:
    """4×8×4 grid: part 'base' in y 0..3, part 'top' in y 4..7; x = 3 column empty."""
    part = np.full((4, 8, 4), EMPTY, np.int16)
    part[:3, :4] = 0
    part[:3, 4:] = 1
    return PartGrid(part=part, part_names=("base", "top"), voxel_size_m=0.1, origin_m=(0.0, 0.0, 0.0))


def _rule(**kw) -> RegionRule:
    return RegionRule.model_validate(kw)


def test_rules_in_order_later_wins():
    grid, warnings = apply_regions(_tower(), [
        _rule(part="body", style="stone"),
        _rule(parts=["top"], part="roof", style="tiles"),
    ])
    assert grid.part_names == ("body", "roof") and grid.style_names == ("stone", "tiles")
    assert (grid.part[:3, :4] == 0).all() and (grid.part[:3, 4:] == 1).all()
    assert (grid.style[:3, 4:] == 1).all()
    assert (grid.part[3] == EMPTY).all() and grid.count == 3 * 8 * 4
    assert warnings == []


def test_band_selects_fraction_of_occupied_height():
    grid, _ = apply_regions(_tower(), [
        _rule(part="body", style="a"),
        _rule(band={"from": 0.75}, part="crest", style="b"),  # top quarter: y = 6, 7
    ])
    crest = grid.part_names.index("crest")
    ys = np.unique(np.nonzero(grid.part == crest)[1])
    assert ys.tolist() == [6, 7]
    top, _ = apply_regions(_tower(), [_rule(part="a", style="a"), _rule(band="top", part="t", style="t")])
    assert np.unique(np.nonzero(top.part == 1)[1]).tolist() == [4, 5, 6, 7]


def test_uncovered_parts_are_an_error():
    with pytest.raises(RecipeError, match=r"\['top'\].*no region rule") as info:
        apply_regions(_tower(), [_rule(parts=["base"], part="body", style="a")], field="assets[0].regions")
    assert info.value.field == "assets[0].regions"


def test_glob_matching_nothing_warns():
    _, warnings = apply_regions(_tower(), [_rule(part="a", style="a"), _rule(parts=["roof*"], part="r", style="r")])
    assert len(warnings) == 1 and "roof*" in warnings[0]


def test_from_source_keeps_names_and_styles():
    pg = _tower()
    style = np.where(pg.part == EMPTY, EMPTY, 1 - pg.part).astype(np.int16)
    pg = PartGrid(part=pg.part, part_names=pg.part_names, voxel_size_m=0.1, origin_m=(0, 0, 0),
                  style=style, style_names=("s0", "s1"))
    grid, _ = apply_regions(pg, [_rule(part="@source", style="@source")])
    assert set(grid.part_names) == {"base", "top"}
    assert grid.style_names[grid.style[0, 0, 0]] == "s1" and grid.style_names[grid.style[0, 7, 0]] == "s0"
    with pytest.raises(RecipeError, match="carries no styles"):
        apply_regions(_tower(), [_rule(part="a", style="@source")])


def test_cells_limit_a_rule_to_listed_coarse_cells():
    grid, warnings = apply_regions(_tower(), [
        _rule(part="body", style="a"),
        _rule(cells=[[0, 7, 0], [1, 7, 2], [3, 0, 0]], part="body", style="b"),  # [3, 0, 0] is empty: ignored
    ])
    b = grid.style_names.index("b")
    assert sorted(map(tuple, np.argwhere(grid.style == b).tolist())) == [(0, 7, 0), (1, 7, 2)]
    assert warnings == []
    with pytest.raises(RecipeError, match=r"cell \[0, 8, 0\] is outside the 4×8×4 coarse grid") as info:
        apply_regions(_tower(), [_rule(part="a", style="a"), _rule(cells=[[0, 1, 0], [0, 8, 0]], part="a", style="b")],
                      field="assets[0].regions")
    assert info.value.field == "assets[0].regions[1].cells[1]"


def test_cells_are_validated_by_the_schema():
    from pydantic import ValidationError

    with pytest.raises(ValidationError):
        _rule(cells=[[0, -1, 0]], part="a", style="b")
    with pytest.raises(ValidationError):
        _rule(cells=[], part="a", style="b")
    with pytest.raises(ValidationError):
        _rule(cells=[[0, 1]], part="a", style="b")


def _labeled(occ: np.ndarray) -> LabeledGrid:
    idx = np.where(occ, 0, EMPTY).astype(np.int16)
    return LabeledGrid(occ, idx, idx.copy(), ("body",), ("stone",), voxel_size_m=0.16, origin_m=(1.0, 2.0, 3.0))


def test_nearest_upsample():
    a = np.arange(8).reshape(2, 2, 2)
    up = nearest_upsample(a, 3)
    assert up.shape == (6, 6, 6) and up[5, 0, 3] == a[1, 0, 1]


def test_upsample_detailizer_keeps_the_coarse_shape():
    occ = np.zeros((6, 5, 4), bool)
    occ[1:5, 1:4, 1:3] = True
    fine = UpsampleDetailizer().detailize(_labeled(occ))
    assert fine.shape == (96, 80, 64) and fine.occupancy.dtype == np.float32
    assert fine.voxel_size_m == pytest.approx(0.01) and fine.origin_m == (1.0, 2.0, 3.0)
    binary = fine.binary()
    # max-pool by 16 gives the coarse input back exactly (strict IOU 1 for a box)
    pooled = binary.reshape(6, 16, 5, 16, 4, 16).any(axis=(1, 3, 5))
    assert (pooled == occ).all()
    # deep inside stays solid, far outside stays empty, and no detail was invented
    assert fine.occupancy[40, 40, 32] == pytest.approx(1.0, abs=1e-5) and fine.occupancy[2, 2, 2] == 0.0
    assert 0.9 < binary.sum() / (occ.sum() * 16**3) < 1.1
    assert fine.detailizer == "upsample" and UpsampleDetailizer.learned is False
    assert (fine.style == 0).all()


def test_upsample_styles_fill_empty_cells_from_nearest():
    occ = np.zeros((4, 1, 1), bool)
    occ[0] = occ[3] = True
    style = np.array([0, EMPTY, EMPTY, 1], np.int16).reshape(4, 1, 1)
    part = np.where(occ, 0, EMPTY).astype(np.int16)
    grid = LabeledGrid(occ, part, style, ("p",), ("a", "b"), 0.1)
    fine = UpsampleDetailizer().detailize(grid)
    assert fine.style[16 * 1 + 3, 0, 0] == 0 and fine.style[16 * 2 + 3, 0, 0] == 1
    assert fine.occupancy.max() >= ISO_LEVEL


def test_separable_blur_equals_gaussian_filter():
    from scipy import ndimage

    from model.upsample import smooth_upsample

    occ = np.zeros((5, 4, 3), bool)
    occ[1:4, 1:3, 1] = True
    occ[0, 0, 0] = True
    reference = nearest_upsample(occ, 16).astype(np.float32)
    ndimage.gaussian_filter(reference, 3.0, output=reference, mode="constant", cval=0.0)
    fast = smooth_upsample(occ, 16, 3.0)
    assert fast.shape == reference.shape
    assert np.abs(fast - reference).max() < 5e-3

"""LP-detail, style specificity and the bounded patch search (evaluation/detail.py, detail_index.py)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from evaluation.detail import PatchRecords, is_extrusion, match_all, patch_owners
from evaluation.detail_index import PatchBank, exemplar_patches, make_queries, packed_patch_words
from evaluation.patch_index import _pack, iou_similar, style_patch_dictionary
from evaluation.patches import extract_patches, sample_surface_patches

N = 64


def _pitted(seed: int, period: int) -> np.ndarray:
    """A 64³ block whose faces carry a seeded pattern of pits and bumps (patches that are not extrusions)."""
    rng = np.random.default_rng(seed)
    occ = np.zeros((N, N, N), bool)
    occ[10:54, 10:54, 10:54] = True
    x, y, z = np.meshgrid(*[np.arange(N)] * 3, indexing="ij")
    shell = occ & ((x < 14) | (x > 49) | (y < 14) | (y > 49) | (z < 14) | (z > 49))
    pits = ((x // period + 3 * (y // period) + 7 * (z // period)) % 5 == 0) & shell
    occ[pits & (rng.random(occ.shape) < 0.9)] = False
    bumps = np.zeros_like(occ)
    bumps[8:10, 12:52:period, 12:52:period] = True
    return occ | bumps


def _prism() -> np.ndarray:
    """An L-shaped prism running through the whole grid along z: every patch is constant along z."""
    occ = np.zeros((N, N, N), bool)
    occ[16:48, 16:24, :] = True
    occ[16:24, 16:48, :] = True
    return occ


def _score(shape, table_shapes, names, cats, owner):
    rec = PatchRecords()
    rec.add("o", shape, owner, seed=3)
    match_all([rec], lambda e: table_shapes[e], names, cats)
    return rec.scores()["o"]


def test_extrusion_test_on_hand_made_patches():
    p = np.zeros((4, 12, 12, 12), bool)
    p[1, :, :6, :] = True  # a flat face: constant along x and z
    p[2, :6, :6, :] = True  # a straight edge: constant along z
    p[3, :6, :6, :6] = True  # a corner: constant along no axis
    assert is_extrusion(_pack(p.reshape(4, -1))).tolist() == [True, True, True, False]


def test_lp_detail_of_an_extrusion_only_shape_is_zero_even_when_every_patch_matches():
    prism = _prism()
    s = _score(prism, [prism], ["prism"], ["building"], 0)
    assert s["patches"] > 100 and s["extrusions"] == 1.0
    assert s["lp_iou"] == 1.0 and s["own_lp_iou"] == 1.0  # the paper's LP-IOU calls it perfect
    assert s["lp_detail"] == 0.0 and s["lp_detail_all"] == 0.0


def test_lp_detail_of_an_exemplar_against_itself_is_its_share_of_detailed_patches():
    a = _pitted(0, 3)
    s = _score(a, [a], ["a"], ["building"], 0)
    assert s["own_lp_iou"] == 1.0  # every patch is its own
    assert s["lp_detail"] == pytest.approx(1.0 - s["extrusions"]) and s["lp_detail"] > 0.5


def test_specificity_is_positive_for_the_copied_style_and_negative_for_another():
    a, b = _pitted(0, 3), _pitted(1, 5)
    shapes, names, cats = [a, b], ["a", "b"], ["building", "plant"]
    as_a = _score(a, shapes, names, cats, 0)
    as_b = _score(a, shapes, names, cats, 1)
    assert as_a["lp_detail"] > 0.5 and as_a["specificity"] > 0.3
    assert as_b["lp_detail"] < 0.2 and as_b["specificity"] < -0.3
    # "against all exemplars" does not depend on the assignment
    assert as_a["lp_detail_all"] == as_b["lp_detail_all"]


def test_patches_take_the_style_of_the_region_at_their_centre():
    regions = np.zeros((4, 4, 4), np.int16)
    regions[:, 2:, :] = 1
    pos = np.array([[20, 20, 20], [20, 30, 20], [20, 31, 20], [63, 63, 63]])
    # centre voxel = position + 1: y 21 → cell 1 (style 0), y 31 → cell 1, y 32 → cell 2 (style 1)
    assert patch_owners(pos, regions, 16).tolist() == [0, 0, 1, 1]


@pytest.mark.parametrize("cap", [256, 100_000])
def test_bounded_iou_search_misses_only_capped_pairs_and_equals_the_exhaustive_one_uncapped(cap, monkeypatch):
    from evaluation import detail_index

    monkeypatch.setattr(detail_index, "K_IOU", cap)
    a, b = _pitted(0, 3), _pitted(1, 5)
    query = np.concatenate([a[:32], b[32:]])  # patches of a, of b, and seams matching neither
    pos = sample_surface_patches(query, n=400, seed=1)
    exhaustive = iou_similar(extract_patches(torch.from_numpy(query), pos), style_patch_dictionary([a, b]))
    rec = PatchRecords()
    rec.add("q", query, 0, seed=1, n=400)
    bank = PatchBank((exemplar_patches(a, "a", "x"), exemplar_patches(b, "b", "y")))
    match_all([rec], None, ["a", "b"], ["x", "y"], bank=bank)
    assert 0 < exhaustive.mean() < 1
    assert not (rec.any & ~exhaustive).any()  # every hit is a real match
    missed = int((exhaustive & ~rec.any).sum())
    assert missed <= rec.stats.capped  # and every miss is a pair the bound left undecided
    if cap > len(bank.tables[0].occ_count):
        assert rec.stats.capped == 0 and missed == 0


def test_search_cost_is_bounded_per_patch_and_exemplar():
    """A query that matches nothing visits at most K rows of each table, not the whole table."""
    from evaluation import detail_index

    a = _pitted(0, 3)
    table = exemplar_patches(a, "a", "x")
    noise = np.random.default_rng(5).random((N, N, N)) < 0.5
    q = make_queries(packed_patch_words(noise), sample_surface_patches(noise, n=200, seed=0))
    calls = []
    real = detail_index._iou_pass

    def counting(qq, t, qi, ri):
        calls.append(len(qi))
        return real(qq, t, qi, ri)

    detail_index._iou_pass = counting
    try:
        hit = detail_index.iou_matches(q, table)
    finally:
        detail_index._iou_pass = real
    assert not hit.any()
    assert sum(calls) <= len(q) * (detail_index.K_FIRST + detail_index.K_IOU) < len(table.occ_count) * len(q)

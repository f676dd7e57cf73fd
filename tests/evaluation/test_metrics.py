"""Tests of the structure and LP metrics (core/structure.py, evaluation/patches.py, patch_index.py, lp.py) on hand-made grids with known answers."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import torch

from core import structure
from evaluation import lp, patch_index, patches


def _up(coarse: np.ndarray, factor: int) -> np.ndarray:
    return np.kron(coarse.astype(np.uint8), np.ones((factor,) * 3, np.uint8)).astype(bool)


def _cube_coarse() -> np.ndarray:
    c = np.zeros((4, 4, 4), bool)
    c[1:3, 1:3, 1:3] = True  # 8 cells
    return c


# --------------------------------------------------------------------------- Strict / Loose


def test_iou_identical_is_one():
    rng = np.random.default_rng(3)
    c = rng.random((4, 5, 3)) > 0.5
    assert structure.strict_loose_iou(_up(c, 2), c, factor=2) == (1.0, 1.0)
    assert structure.strict_loose_iou(_up(c, 16), c) == (1.0, 1.0)  # default factor 16


def test_iou_shift_by_one_fine_voxel():
    c = _cube_coarse()
    out = np.roll(_up(c, 2), 1, axis=0)  # fine x [2,6) → [3,7): touches coarse cells 1, 2, 3
    strict, loose = structure.strict_loose_iou(out, c, factor=2)
    assert strict == pytest.approx(8 / 12) and loose == 1.0


def test_strict_vs_loose_over_and_under_coverage():
    c = _cube_coarse()
    extra = np.zeros_like(c)
    extra[3, 0, :] = True  # 4 cells outside C
    strict, loose = structure.strict_loose_iou(_up(c | extra, 2), c, factor=2)
    assert loose == 1.0 and strict == pytest.approx(8 / 12)
    half = c.copy()
    half[1] = False  # output covers 4 of the 8 cells
    strict, loose = structure.strict_loose_iou(_up(half, 2), c, factor=2)
    assert strict == pytest.approx(0.5) and loose == pytest.approx(0.5)


def test_iou_one_fine_voxel_per_cell_is_enough():
    c = _cube_coarse()
    out = np.zeros((8, 8, 8), bool)
    out[2::2, 2::2, 2::2][:2, :2, :2] = True  # one voxel in each cell of C
    assert structure.strict_loose_iou(out, c, factor=2) == (1.0, 1.0)


def test_iou_empty_cases():
    c = _cube_coarse()
    empty_out = np.zeros((8, 8, 8), bool)
    assert structure.strict_loose_iou(empty_out, c, factor=2) == (0.0, 0.0)
    assert structure.strict_loose_iou(empty_out, np.zeros_like(c), factor=2) == (1.0, 1.0)
    assert structure.strict_loose_iou(_up(c, 2), np.zeros_like(c), factor=2) == (0.0, 0.0)


def test_iou_binarises_floats_at_iso_level():
    c = _cube_coarse()
    out = _up(c, 2).astype(np.float32) * 0.41
    out[0, 0, 0] = 0.4  # exactly the iso level: empty (> 0.4 is occupied)
    assert structure.strict_loose_iou(out, c, factor=2) == (1.0, 1.0)


def test_iou_shape_mismatch_is_a_clear_error():
    with pytest.raises(ValueError, match="factor 2"):
        structure.strict_loose_iou(np.zeros((8, 8, 7), bool), _cube_coarse(), factor=2)
    with pytest.raises(ValueError, match="3-D"):
        structure.strict_loose_iou(np.zeros((8, 8), bool), _cube_coarse(), factor=2)


# --------------------------------------------------------------------------- patches


def _brute_candidates(x: np.ndarray) -> np.ndarray:
    out = []
    X, Y, Z = x.shape
    for i in range(5, X - 6):
        for j in range(5, Y - 6):
            for k in range(5, Z - 6):
                cell = x[i : i + 2, j : j + 2, k : k + 2]
                if cell.any() and not cell.all():
                    out.append((i, j, k))
    return np.array(out, dtype=np.int64).reshape(-1, 3)


def test_candidates_match_brute_force():
    rng = np.random.default_rng(0)
    for shape in [(16, 14, 13), (12, 12, 12)]:
        x = rng.random(shape) > 0.7
        np.testing.assert_array_equal(patches.surface_candidates(x), _brute_candidates(x))
    assert patches.surface_candidates(np.ones((11, 20, 20), bool)).shape == (0, 3)


def test_surface_and_dilation_match_brute_force():
    rng = np.random.default_rng(1)
    x = rng.random((7, 6, 8)) > 0.3
    surf, dil = (t.numpy() for t in patches.surface_and_dilation(x))
    want_s = np.zeros_like(x)
    for i, j, k in np.argwhere(x):
        box = x[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2, max(k - 1, 0) : k + 2]
        want_s[i, j, k] = not box.all()  # outside the grid is not empty
    want_d = np.zeros_like(x)
    for i, j, k in np.ndindex(x.shape):
        want_d[i, j, k] = want_s[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2, max(k - 1, 0) : k + 2].any()
    np.testing.assert_array_equal(surf, want_s)
    np.testing.assert_array_equal(dil, want_d)
    # a full grid has no surface: the border does not count as empty
    assert not patches.surface_and_dilation(np.ones((5, 5, 5), bool))[0].any()


def test_extract_patches_and_sampling():
    rng = np.random.default_rng(2)
    x = rng.random((20, 18, 19)) > 0.6
    pos = patches.sample_surface_patches(x, n=7, seed=11)
    assert pos.shape == (7, 3)
    np.testing.assert_array_equal(pos, patches.sample_surface_patches(x, n=7, seed=11))
    assert len({tuple(p) for p in pos}) == 7
    allpos = {tuple(p) for p in patches.surface_candidates(x)}
    assert {tuple(p) for p in pos} <= allpos
    assert len(patches.sample_surface_patches(x, n=10**6, seed=0)) == len(allpos)  # fewer: take all
    rows = patches.extract_patches(x, pos).numpy()
    for r, (i, j, k) in zip(rows, pos):
        np.testing.assert_array_equal(r.reshape(12, 12, 12), x[i - 5 : i + 7, j - 5 : j + 7, k - 5 : k + 7])


# --------------------------------------------------------------------------- LP-IOU / LP-F


def _two_boxes() -> np.ndarray:
    x = np.zeros((30, 28, 26), bool)
    x[6:20, 7:18, 8:15] = True
    x[14:24, 12:22, 12:20] = True
    return x


def test_lp_identical_shape_is_one():
    x = _two_boxes()
    d = patch_index.style_patch_dictionary([x])
    assert lp.lp_scores(x, d, n=200, seed=0) == (1.0, 1.0)


def test_lp_translated_copy_is_one():
    x = _two_boxes()
    d = patch_index.style_patch_dictionary([np.zeros((24, 24, 24), bool), x])  # an empty style adds nothing
    moved = np.roll(np.roll(x, 2, axis=0), -1, axis=2)  # stays clear of the borders
    assert lp.lp_scores(moved, d, n=1000, seed=5) == (1.0, 1.0)


def test_lp_one_voxel_step_hand_computed():
    """Style: a flat slab. Output: the slab with a one-voxel step at x = 12.

    Per j, 14 patches: 7 centred at z = 11 with k = 0..6 raised columns
    (IOU 864/(864+12k) > 0.95 ⟺ k <= 3: 4 similar) and 7 at z = 12 with
    k = 6..12 (IOU (720+12k)/864 > 0.95 ⟺ k >= 9: 4 similar). LP-IOU = 8/14.
    The surfaces stay within one voxel of the slab's: LP-F = 1.
    """
    style = np.zeros((24, 24, 24), bool)
    style[:, :, :12] = True
    out = style.copy()
    out[12:, :, 12] = True
    d = patch_index.style_patch_dictionary([style])
    assert len(d.occ_count) == 1  # every surface patch of a slab is the same
    assert len(patches.surface_candidates(out)) == 14 * 13
    lp_iou, lp_f = lp.lp_scores(out, d, n=1000, seed=0)
    assert lp_iou == pytest.approx(8 / 14)
    assert lp_f == 1.0


def test_lp_empty_output_and_empty_dictionary():
    d = patch_index.style_patch_dictionary([_two_boxes()])
    assert lp.lp_scores(np.zeros((30, 30, 30), bool), d) == (0.0, 0.0)
    empty = patch_index.style_patch_dictionary([np.zeros((20, 20, 20), bool)])
    assert len(empty.occ_count) == 0
    assert lp.lp_scores(_two_boxes(), empty) == (0.0, 0.0)


def test_dictionary_deduplicates_across_shapes():
    x = _two_boxes()
    once = patch_index.style_patch_dictionary([x])
    twice = patch_index.style_patch_dictionary([x, np.roll(x, 1, axis=1)])
    assert len(twice.occ_count) == len(once.occ_count)
    assert len(twice.surf_count) == len(once.surf_count)
    assert np.all(np.diff(once.occ_count) >= 0) and np.all(np.diff(once.surf_count) >= 0)


def _brute_iou(q: np.ndarray, dic: np.ndarray) -> np.ndarray:
    out = []
    for a in q:
        inter = (dic & a).sum(1)
        union = (dic | a).sum(1)
        out.append(any(Fraction(int(i), int(u)) > Fraction(19, 20) for i, u in zip(inter, union) if u))
    return np.array(out)


def _brute_f(qs, qd, ds, dd) -> np.ndarray:
    out = []
    for s_o, d_o in zip(qs, qd):
        ok = False
        for s_s, d_s in zip(ds, dd):
            n_so, n_ss = int(s_o.sum()), int(s_s.sum())
            if n_so == 0 or n_ss == 0:
                continue  # NaN
            p = Fraction(int((s_o & d_s).sum()), n_so)
            r = Fraction(int((d_o & s_s).sum()), n_ss)
            if p + r > 0 and 2 * p * r / (p + r) > Fraction(19, 20):
                ok = True
                break
        out.append(ok)
    return np.array(out)


def _flip(rng, rows: np.ndarray, lo: int, hi: int) -> np.ndarray:
    out = rows.copy()
    for r in out:
        idx = rng.choice(r.size, size=int(rng.integers(lo, hi)), replace=False)
        r[idx] = ~r[idx]
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pruned_search_equals_brute_force(seed, monkeypatch):
    # tiny blocks and chunks so that windows, outward chunk order and early exits are all exercised
    monkeypatch.setattr(patch_index, "_DICT_CHUNK", 16)
    monkeypatch.setattr(patch_index, "_QUERY_BLOCK", 8)
    monkeypatch.setattr(patch_index, "_TOP_K", 1)
    monkeypatch.setattr(patch_index, "_KNN", 1)
    monkeypatch.setattr(patch_index, "_PAIR_CHUNK", 7)
    monkeypatch.setattr(patch_index, "_BALL_BLOCK", 5)
    rng = np.random.default_rng(seed)
    n_q = 30
    density = rng.uniform(0.2, 0.7, size=(n_q, 1))
    q = rng.random((n_q, 1728)) < density
    # dictionary: perturbed queries (around the 0.95 thresholds), exact copies, unrelated rows
    dic = np.concatenate([_flip(rng, q, 5, 70), _flip(rng, q, 5, 70), q[:3], rng.random((40, 1728)) < 0.5])
    qs = rng.random((n_q, 1728)) < rng.uniform(0.05, 0.2, size=(n_q, 1))
    qs[0] = False  # an empty surface: NaN precision, never similar
    qd = qs | (rng.random((n_q, 1728)) < 0.2)
    ds = np.concatenate([_flip(rng, qs, 0, 12), _flip(rng, qs, 0, 25), rng.random((30, 1728)) < 0.1])
    ds[-1] = False  # an empty style surface: NaN recall
    dd = np.concatenate([_flip(rng, qd, 0, 40), _flip(rng, qd, 0, 80), rng.random((30, 1728)) < 0.3])
    # occupancy rows and (surface, dilation) rows are independent tables of the dictionary
    d_occ = patch_index.dictionary_from_patches(dic, np.zeros_like(dic), np.zeros_like(dic))
    d = patch_index.dictionary_from_patches(np.zeros_like(ds), ds, dd)
    got_iou = patch_index.iou_similar(torch.from_numpy(q.astype(np.int8)), d_occ)
    want_iou = _brute_iou(q, dic)
    np.testing.assert_array_equal(got_iou, want_iou)
    assert 0 < want_iou.sum() < n_q  # the case is not trivial
    got_f = patch_index.f_similar(torch.from_numpy(qs.astype(np.int8)), torch.from_numpy(qd.astype(np.int8)), d)
    want_f = _brute_f(qs, qd, ds, dd)
    np.testing.assert_array_equal(got_f, want_f)
    assert 0 < want_f.sum() < n_q
    assert not got_f[0]


def test_lp_is_seeded():
    x = _two_boxes()
    d = patch_index.style_patch_dictionary([np.roll(x, 3, axis=1)[:, :, ::-1]])
    a = lp.lp_scores(x, d, n=50, seed=4)
    assert a == lp.lp_scores(x, d, n=50, seed=4)
    assert 0.0 <= a[0] <= 1.0 and 0.0 <= a[1] <= 1.0


def test_packed_extraction_and_cell_counts_match_the_dense_path():
    rng = np.random.default_rng(11)
    vol = rng.random((20, 18, 23)) > 0.5
    pos = patches.surface_candidates(vol)
    dense = patches.extract_patches(vol, pos)
    packed = patch_index.extract_packed(patch_index._z_words(vol), pos)
    np.testing.assert_array_equal(packed, patch_index._pack(dense))
    np.testing.assert_array_equal(patch_index._bytes_to_words(packed), patch_index._bytes_to_words(patch_index._words_to_bytes(
        patch_index._bytes_to_words(packed))))
    counts, _ = patch_index.cell_signatures(dense)
    np.testing.assert_array_equal(patch_index.packed_cell_counts(packed), counts.numpy())
    np.testing.assert_array_equal(patch_index._octants_from_cells(patch_index.packed_cell_counts(packed)), patch_index._octants(dense))


def test_unique_rows_survive_hash_collisions():
    a = np.zeros(216, np.uint8)
    b = np.zeros(216, np.uint8)
    a[7] = 0x80  # top bit of 64-bit word 0
    b[15] = 0x80  # top bit of word 1: the same linear hash (2^63 · odd = 2^63 mod 2^64)
    assert patch_index._row_hash(a[None])[0] == patch_index._row_hash(b[None])[0]
    c = np.full(216, 3, np.uint8)
    got = patch_index._unique_packed([np.stack([a, a, c]), np.stack([b, b, a, c])], 216)
    np.testing.assert_array_equal(got, np.stack([a, c, b]))

"""Exemplars and seeded augmentation: label consistency, determinism, level alignment, combination."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from model.config import ModelConfig, TargetSmoothing
from model.data import (
    CENTRE,
    AugmentConfig,
    Exemplar,
    augment_exemplar,
    augmented_sample,
    centre_offset,
    combine,
    min_coarse_cells,
    place_in_crop,
    resample_labels,
    rng_for,
    rotate_y,
    smooth_target,
    style_sample,
)
from core.errors import DetailizeError
from core.grid import EMPTY

PARTS = ("bottom", "top")
AUG = AugmentConfig(resolution=64)


def _box(name, size=(40, 30, 20), split=0.5, parts=(0, 1), res=64, vocab=PARTS):
    """A solid box: part ``parts[0]`` below ``split`` of its height, ``parts[1]`` above, in a res³ grid."""
    lab = np.full((res, res, res), EMPTY, dtype=np.int16)
    x, y, z = size
    h = int(y * split)
    lab[2 : 2 + x, 1 : 1 + h, 3 : 3 + z] = parts[0]
    lab[2 : 2 + x, 1 + h : 1 + y, 3 : 3 + z] = parts[1]
    return Exemplar(name, "thing", lab, vocab, resolution=res)


def _set():
    column = np.full((64, 64, 64), EMPTY, dtype=np.int16)
    column[20:30, 0:50, 20:30] = 0  # only a "bottom" part
    return [_box("tower"), _box("slab", size=(50, 12, 44), split=0.3),
            Exemplar("column", "thing", column, PARTS, resolution=64)]


def _cfg(n_styles=3):
    return ModelConfig.lean(len(PARTS), n_styles).scaled(0.125)


def test_resample_never_invents_labels_at_borders():
    """Parts 0 and 2 touch; interpolating labels would create 1s at their border. Nearest never does."""
    vocab = ("a", "b", "c")
    ex = _box("x", size=(17, 23, 11), parts=(0, 2), vocab=vocab)
    for seed in range(12):
        rng = rng_for(seed, 0)
        out = augment_exemplar(ex, rng, AUG)
        values = set(np.unique(out).tolist())
        assert values <= {EMPTY, 0, 2} and {0, 2} <= values, values
    # upscaling and downscaling by odd factors: only source labels; geometry from the trilinear field
    for size in [(40, 9, 31), (5, 50, 7), (17, 23, 11)]:
        out = resample_labels(ex.labels[2:19, 1:24, 3:14], size)
        assert out.shape == size and set(np.unique(out).tolist()) <= {EMPTY, 0, 2}
        assert (out != EMPTY).mean() > 0.9  # a box stays (nearly) full


def test_resampled_parts_stay_ordered_along_y():
    """A horizontal split stays a horizontal split: per column, bottom voxels lie below top voxels."""
    ex = _box("tower")
    for seed in range(6):
        out = augment_exemplar(ex, rng_for(seed, 3), AUG)
        ys = np.arange(out.shape[1])[None, :, None]
        top_min = np.where(out == 1, ys, 10**6).min(axis=1)
        bottom_max = np.where(out == 0, ys, -1).max(axis=1)
        assert (bottom_max < top_min).all()


def test_augmented_labels_exist_in_their_sources_and_fit():
    exs = _set()
    cfg = _cfg()
    by_name = {e.name: e for e in exs}
    for step in range(8):
        s = augmented_sample(exs, cfg, AUG, seed=1, step=step)
        allowed = set().union(*(by_name[n].parts for n in s.sources))
        occ = s.fine_labels != EMPTY
        assert set(np.unique(s.fine_labels[occ]).tolist()) <= allowed
        ext = [np.ptp(np.flatnonzero(occ.any(axis=tuple(a for a in range(3) if a != ax)))) + 1 for ax in range(3)]
        assert max(ext) <= AUG.max_side  # 0.7·R
        # per-part style among the exemplars that have that part: "top" never goes to the column
        assert s.assignment[1] in (0, 1) and s.assignment[0] in (0, 1, 2)


def test_shapes_aligned_across_levels_and_margin_empty():
    s = augmented_sample(_set(), _cfg(), AUG, seed=0, step=5)
    c = s.coarse_occupancy.shape
    assert s.fine_labels.shape == tuple(16 * n for n in c)
    assert [t.shape for t in s.targets] == [tuple(2 ** (j + 1) * n for n in c) for j in range(4)]
    assert s.coarse_labels.shape == c and s.coarse_labels.min() >= 0
    # at least one empty coarse cell of margin on every side
    occ = s.coarse_occupancy
    for ax in range(3):
        prof = occ.any(axis=tuple(a for a in range(3) if a != ax))
        assert not prof[0] and not prof[-1] and prof.any()
    # coarse = ×16 max-pool of the fine crop; the last target is the smoothed fine crop
    f = s.fine_labels != EMPTY
    assert np.array_equal(occ, f.reshape(c[0], 16, c[1], 16, c[2], 16).any(axis=(1, 3, 5)))
    assert np.array_equal(s.targets[-1] > 0.4, f) or np.mean((s.targets[-1] > 0.4) != f) < 0.01
    for t in s.targets:
        assert t.dtype == np.float32 and t.min() >= 0 and t.max() <= 1
    assert s.style_index().shape == c


@pytest.mark.parametrize("smoothing", [TargetSmoothing.GAUSSIAN, TargetSmoothing.PROGRESSIVE])
def test_windowed_target_equals_cut_of_whole_target(smoothing):
    cfg = dataclasses.replace(_cfg(), losses=dataclasses.replace(_cfg().losses, target_smoothing=smoothing))
    s = augmented_sample(_set(), cfg, AUG, seed=3, step=2)
    fresh = augmented_sample(_set(), cfg, AUG, seed=3, step=2)  # nothing cached: the window path
    c = s.coarse_occupancy.shape
    for cells in [(slice(0, 2), slice(1, 3), slice(0, 2)), tuple(slice(n - 2, n) for n in c),
                  tuple(slice(0, n) for n in c)]:
        for j in range(4):
            r = 2 ** (j + 1)
            whole = s.targets[j][tuple(slice(a.start * r, a.stop * r) for a in cells)]
            windowed = fresh.target(j, cells)
            assert j not in fresh.__dict__.get("_whole_targets", {})
            np.testing.assert_allclose(windowed, whole, atol=1e-6)
            assert np.array_equal(s.target(j, cells), whole)  # cached path cuts the whole target


def test_deterministic_for_equal_seeds():
    exs, cfg = _set(), _cfg()
    a = augmented_sample(exs, cfg, AUG, seed=7, step=3)
    b = augmented_sample(exs, cfg, AUG, seed=7, step=3)
    assert np.array_equal(a.fine_labels, b.fine_labels) and a.assignment == b.assignment and a.sources == b.sources
    assert all(np.array_equal(x, y) for x, y in zip(a.targets, b.targets))
    others = [augmented_sample(exs, cfg, AUG, seed=7, step=k).fine_labels for k in (4, 5)]
    assert any(o.shape != a.fine_labels.shape or not np.array_equal(o, a.fine_labels) for o in others)


def test_combination_uses_two_different_exemplars():
    exs, cfg = _set(), _cfg()
    always = dataclasses.replace(AUG, combine_prob=1.0)
    for step in range(4):
        s = augmented_sample(exs, cfg, always, seed=2, step=step)
        assert len(s.sources) == 2 and s.sources[0] != s.sources[1]
    never = dataclasses.replace(AUG, combine_prob=0.0)
    assert len(augmented_sample(exs, cfg, never, seed=2, step=0).sources) == 1


def test_combine_aligns_bottoms_and_first_wins():
    a = np.zeros((4, 3, 4), dtype=np.int16)
    b = np.ones((4, 5, 4), dtype=np.int16)
    out = combine(a, b, rng_for(0, 0), dataclasses.replace(AUG, rotate=False))
    assert out.shape[1] == 5  # bottoms aligned: the union is as tall as the taller shape
    assert (out[:4, :3, :4] == 0).all()  # overlap keeps a's label
    assert (out[:, 3:, :] == 1).sum() == 4 * 2 * 4  # only b reaches above a: all of b's top is there
    assert set(np.unique(out).tolist()) <= {EMPTY, 0, 1}


def test_rotation_is_about_y():
    lab = np.full((3, 2, 5), EMPTY, dtype=np.int16)
    lab[0, 1, 4] = 1
    r = rotate_y(lab, 1)
    assert r.shape == (5, 2, 3) and (r == 1).sum() == 1 and np.argwhere(r == 1)[0][1] == 1  # y kept


def test_place_in_crop_random_subcell_offset():
    lab = np.zeros((20, 3, 17), dtype=np.int16)
    offsets = set()
    for step in range(6):
        crop = place_in_crop(lab, rng_for(0, step), 16)
        assert all(n % 16 == 0 for n in crop.shape)
        idx = np.argwhere(crop != EMPTY).min(axis=0)
        assert (idx >= 16).all() and (idx < 32).all()
        offsets.add(tuple(idx))
    assert len(offsets) > 1
    thin = place_in_crop(np.zeros((3, 3, 3), dtype=np.int16), rng_for(0, 0), 16, min_cells=6)
    assert thin.shape == (96, 96, 96)  # 1 bbox cell + 2 margin cells, padded to 6
    assert (np.argwhere(thin != EMPTY).min(axis=0) >= 32).all()


def test_min_coarse_cells_gives_every_discriminator_an_output():
    cfg = _cfg()
    c = min_coarse_cells(cfg)
    assert c == 4  # the RF-7 level-0 discriminator needs 2c ≥ 7
    assert all(d.output_size(c * 2 ** (j + 1)) >= 1 for j, d in enumerate(cfg.discriminators))
    s = augmented_sample(_set(), cfg, AUG, seed=0, step=1)
    assert min(s.coarse_occupancy.shape) >= c


def test_style_sample_is_the_exemplar_itself():
    exs, cfg = _set(), _cfg()
    s = style_sample(exs, 1, cfg, AUG, seed=0, step=0)
    assert s.assignment == (1, 1) and s.sources == ("slab",)
    occ = s.fine_labels != EMPTY
    assert occ.sum() == (exs[1].labels != EMPTY).sum()  # base scale 1: no resampling
    half = style_sample(exs, 1, cfg, dataclasses.replace(AUG, resolution=32), seed=0, step=0)
    assert abs((half.fine_labels != EMPTY).sum() - occ.sum() / 8) < 0.2 * occ.sum() / 8


def test_style_offset_fixes_the_style_sample():
    from model.train import TrainConfig

    exs, cfg = _set(), _cfg()
    drawn = [style_sample(exs, 1, cfg, AUG, seed=0, step=k).fine_labels for k in range(4)]
    assert any(d.shape != drawn[0].shape or not np.array_equal(d, drawn[0]) for d in drawn[1:])  # random offsets
    fixed = dataclasses.replace(AUG, style_offset=(3, 0, 15))
    same = [style_sample(exs, 1, cfg, fixed, seed=s, step=k).fine_labels for s, k in ((0, 0), (1, 7), (2, 99))]
    assert all(np.array_equal(d, same[0]) for d in same[1:])
    occ = np.argwhere(same[0] != EMPTY)
    assert tuple(occ.min(0) % cfg.factor) == (3, 0, 15)  # the shape starts at that sub-cell offset
    with pytest.raises(DetailizeError, match="style_offset"):
        style_sample(exs, 1, cfg, dataclasses.replace(AUG, style_offset=(0, 16, 0)), seed=0, step=0)
    # the training setting (a JSON list) reaches the augmentation as a tuple
    t = TrainConfig(out_dir="unused", steps=0, resolution=64, style_offset=[3, 0, 15])
    assert t.style_offset == (3, 0, 15) and t.augment().style_offset == (3, 0, 15)
    assert TrainConfig(out_dir="unused", steps=0).augment().style_offset is None
    with pytest.raises(DetailizeError, match="style_offset"):
        TrainConfig(out_dir="unused", steps=0, style_offset=[1, 2])


def test_centre_places_each_exemplar_as_the_reference_pads_it():
    from model.train import TrainConfig

    assert centre_offset((256, 100, 37), 256, 16) == (0, 78 % 16, 109 % 16)  # start (R − n) // 2, mod f
    exs, cfg = _set(), _cfg()
    centred = dataclasses.replace(AUG, style_offset=CENTRE)
    for k in range(len(exs)):
        drawn = [style_sample(exs, k, cfg, centred, seed=s, step=t).fine_labels for s, t in ((0, 0), (3, 5), (9, 77))]
        assert all(np.array_equal(d, drawn[0]) for d in drawn[1:])  # one placement per exemplar, whatever the draw
        occ = np.argwhere(drawn[0] != EMPTY)
        extent = occ.max(0) - occ.min(0) + 1
        assert tuple(occ.min(0) % cfg.factor) == centre_offset(extent, AUG.resolution, cfg.factor)
    t = TrainConfig(out_dir="unused", steps=0, resolution=64, style_offset="centre")
    assert t.augment().style_offset == CENTRE
    with pytest.raises(DetailizeError, match="style_offset"):
        TrainConfig(out_dir="unused", steps=0, style_offset="middle")
    with pytest.raises(DetailizeError, match="style_offset"):
        style_sample(exs, 0, cfg, dataclasses.replace(AUG, style_offset="middle"), seed=0, step=0)


def test_progressive_smoothing_keeps_thin_parts():
    thin = np.zeros((16, 16, 16), dtype=bool)
    thin[8, 4:12, 4:12] = True  # one voxel thick plate
    lc = _cfg().losses
    prog = smooth_target(thin, lc)
    plain = smooth_target(thin, dataclasses.replace(lc, target_smoothing=TargetSmoothing.GAUSSIAN))
    assert plain[8, 8, 8] < 0.4  # a plain σ=1 blur loses the plate at iso 0.4 ...
    assert prog[8, 8, 8] > 0.4 and prog[6, 8, 8] < 0.4  # ... the progressive one keeps it, and no more


def test_bad_sets_refused():
    exs = _set()
    with pytest.raises(DetailizeError, match="3 exemplars for a model of 4"):
        augmented_sample(exs, _cfg(4), AUG, 0, 0)
    odd = Exemplar("odd", "x", exs[0].labels, ("a", "b"), 64)
    with pytest.raises(DetailizeError, match="vocabulary"):
        augmented_sample([*exs[:2], odd], _cfg(), AUG, 0, 0)
    with pytest.raises(DetailizeError, match="empty"):
        Exemplar("e", "x", np.full((4, 4, 4), EMPTY, dtype=np.int16), PARTS)

"""Coarse labels, discriminator-output mask alignment, joint masks and α maps."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch

from model.config import ModelConfig
from model.masks import (
    StyledCoarse,
    align_to_d_output,
    alpha_map,
    coarse_occupancy,
    coarse_part_labels,
    d_output_masks,
    fill_nearest,
    joint_mask,
)
from model.networks import build_discriminators
from core.errors import DetailizeError
from core.grid import EMPTY


def test_coarse_part_labels_majority_and_nearest_fill():
    fine = np.full((8, 2, 2), EMPTY, dtype=np.int16)  # factor 2 → coarse (4, 1, 1)
    fine[0:2].reshape(-1)[:5] = [1, 1, 0, 0, 0]  # block 0: majority part 0 (3 vs 2), 3 empty
    fine[6:8].reshape(-1)[:3] = [2, 2, 1]  # block 3: majority part 2
    coarse = coarse_part_labels(fine, factor=2)
    # blocks 1 and 2 are empty: filled from the nearest occupied block (0 and 3)
    assert coarse.dtype == np.int16 and coarse[:, 0, 0].tolist() == [0, 0, 2, 2]
    assert coarse_occupancy(fine != EMPTY, 2)[:, 0, 0].tolist() == [True, False, False, True]


def test_coarse_part_labels_tie_picks_lowest_index_and_checks_input():
    fine = np.full((2, 2, 2), EMPTY)
    fine[0, 0, 0], fine[1, 1, 1] = 3, 1
    assert coarse_part_labels(fine, factor=2).item() == 1
    with pytest.raises(DetailizeError, match="divisible"):
        coarse_part_labels(np.zeros((3, 2, 2), int), factor=2)
    with pytest.raises(DetailizeError, match="nothing"):
        coarse_part_labels(np.full((2, 2, 2), EMPTY), factor=2)


def test_fill_nearest_copies_from_closest_occupied_cell():
    occ = np.zeros((5, 1, 1), bool)
    occ[0], occ[4] = True, True
    vals = np.array([7, -1, -1, -1, 9]).reshape(5, 1, 1)
    out = fill_nearest(vals, occ)[:, 0, 0]
    assert out[0] == 7 and out[1] == 7 and out[3] == 9 and out[4] == 9 and out[2] in (7, 9)


def test_crop_table_of_paper_discriminators_matches_method_md():
    # DECOLLAGE's D-mask alignment: level 32: ×2, crop 3; 64: ×4, 4; 128 (D out 64): ×4, 4; 256 (D out 128): ×8, 4.
    cfg = ModelConfig.paper(5, 32)
    ups = [2 ** (j + 1) // d.stride() for j, d in enumerate(cfg.discriminators)]
    crops = [d.mask_offset() for d in cfg.discriminators]
    assert ups == [2, 4, 4, 8] and crops == [3, 4, 4, 4]
    # and the crop is symmetric (centre crop) for even level sizes, as in the reference
    for j, d in enumerate(cfg.discriminators):
        n = 6 * 2 ** (j + 1)
        assert 6 * ups[j] - d.output_size(n) == 2 * crops[j]


def _expected_cells(coarse_cell, level, spec, out_shape):
    """Output voxels whose receptive-field centre lies in the coarse cell (independent of masks.py)."""
    f, s, rf = 2 ** (level + 1), spec.stride(), spec.receptive_field()
    hit = np.zeros(out_shape, bool)
    for o in itertools.product(*(range(n) for n in out_shape)):
        centre = [oi * s + rf / 2 for oi in o]  # continuous coordinate, voxel i spans [i, i+1)
        hit[o] = all(c * f <= x < (c + 1) * f for c, x in zip(coarse_cell, centre))
    return hit


@pytest.mark.parametrize("layout", ["paper", "lean"])
def test_single_cell_maps_to_the_right_d_output_cells_at_every_level(layout):
    cfg = getattr(ModelConfig, layout)(2, 3)
    coarse_shape, cell = (5, 4, 6), (2, 1, 3)
    occ = np.zeros(coarse_shape, bool)
    occ[cell] = True
    labels = np.ones(coarse_shape, np.int64)
    for j, spec in enumerate(cfg.discriminators):
        out_shape = tuple(spec.output_size(n * 2 ** (j + 1)) for n in coarse_shape)
        m = d_output_masks(occ, labels, [0, 2], j, out_shape, spec, n_styles=3)
        assert m.style.shape == (3, *out_shape) and m.global_.shape == (1, *out_shape)
        expected = _expected_cells(cell, j, spec, out_shape)
        assert expected.any()
        assert np.array_equal(m.global_[0].numpy() > 0, expected)
        assert np.array_equal(m.style[2].numpy() > 0, expected)  # part 1 → style 2
        assert m.style[0].sum() == 0 and m.style[1].sum() == 0


def test_mask_cell_agrees_with_gradient_of_the_real_discriminator():
    """The output voxel the mask assigns to a coarse cell really looks at that cell's centre."""
    cfg = ModelConfig.paper(1, 2).scaled(0.125)
    discs = build_discriminators(cfg).double()
    coarse_shape, cell = (4, 4, 4), (1, 1, 2)
    occ = np.zeros(coarse_shape, bool)
    occ[cell] = True
    for j in (0, 3):
        f = 2 ** (j + 1)
        x = torch.zeros(1, 1, *(n * f for n in coarse_shape), dtype=torch.float64, requires_grad=True)
        y = discs[j](x)
        m = d_output_masks(occ, np.zeros(coarse_shape, int), [1], j, tuple(y.shape[2:]), cfg.discriminators[j], 2)
        o = torch.nonzero(m.global_[0])[0].tolist()
        y[0, -1, o[0], o[1], o[2]].backward()
        nz = torch.nonzero(x.grad[0, 0]).double()
        centre = (nz.min(0).values + nz.max(0).values + 1) / 2
        assert all(c * f <= v < (c + 1) * f for c, v in zip(cell, centre.tolist()))


def test_style_masks_follow_the_assignment_and_global_is_the_union():
    spec = ModelConfig.lean(2, 3).discriminators[0]
    occ = np.ones((4, 4, 4), bool)
    occ[0] = False
    labels = np.zeros((4, 4, 4), int)
    labels[2:] = 1
    out_shape = (2, 2, 2)
    m = d_output_masks(occ, labels, [2, 0], 0, out_shape, spec, 3)
    # output voxel o aligns with level cell o + 3, i.e. coarse cell (o + 3) // 2 = 1 or 2 along x
    assert m.style[2].sum() == 4 and m.style[2][0].sum() == 4  # part 0 at coarse x=1 → style 2
    assert m.style[0].sum() == 4 and m.style[0][1].sum() == 4  # part 1 at coarse x=2 → style 0
    assert m.style[1].sum() == 0
    torch.testing.assert_close(m.style.sum(0, keepdim=True), m.global_)
    real = StyledCoarse.single_style(occ, 1).masks(0, spec, out_shape, 3)
    assert real.style[1].sum() == 8 and real.style[0].sum() == 0
    with pytest.raises(DetailizeError, match="assignment"):
        d_output_masks(occ, labels, [2, 3], 0, out_shape, spec, 3)
    with pytest.raises(DetailizeError, match="does not fit"):
        d_output_masks(occ, labels, [2, 0], 0, (6, 2, 2), spec, 3)


def test_align_keeps_channel_dims():
    spec = ModelConfig.paper(1, 1).discriminators[3]  # ×8 upsample at D output, crop 4
    field = torch.arange(8.0).view(1, 2, 2, 2)
    out = align_to_d_output(field, 3, spec, (8, 8, 8))
    assert out.shape == (1, 8, 8, 8)
    assert out[0, 0, 0, 0] == 0 and out[0, 3, 3, 3] == 0 and out[0, 4, 4, 4] == 7


def test_joint_mask_on_two_touching_parts():
    fine = np.full((16, 4, 4), EMPTY)
    fine[:8] = 0
    fine[8:] = 1
    joints = joint_mask(fine, factor=4, radius=1)
    assert joints.shape == (4, 1, 1)
    assert joints[:, 0, 0].tolist() == [False, True, True, False]  # joint voxels at x = 7, 8
    wide = joint_mask(fine, factor=4, radius=5)  # x = 3..12 → every cell
    assert wide.all()


def test_joint_mask_ignores_separate_parts_and_single_parts():
    fine = np.full((16, 4, 4), EMPTY)
    fine[:4] = 0
    fine[10:] = 1  # gap of 6 voxels > 2·radius
    assert not joint_mask(fine, factor=4, radius=2).any()
    fine[4:10] = 0  # now part 0 touches part 1 at x = 9 | 10: joints at x = 8..11, all in cell 2
    assert joint_mask(fine, factor=4, radius=2)[:, 0, 0].tolist() == [False, False, True, False]
    assert not joint_mask(np.where(fine >= 0, 0, EMPTY), factor=4).any()


def test_joint_mask_default_factor_16_radius_2():
    fine = np.full((32, 16, 16), EMPTY)
    fine[:16, :8] = 0
    fine[:16, 8:] = 2  # the joint plane y = 7 | 8 lies inside coarse cell (0, 0, 0) only
    fine[16:] = 2
    j = joint_mask(torch.as_tensor(fine))
    assert j.shape == (2, 1, 1) and j[:, 0, 0].tolist() == [True, True]  # x = 15 | 16 also a 0/2 contact
    # Dilated coverage counts even on empty voxels (as the reference): keep the parts
    # ≥ radius away from cell 1 so that only cell 0 holds joints.
    fine[8:] = EMPTY
    assert joint_mask(fine)[:, 0, 0].tolist() == [True, False]


def test_alpha_map_values():
    a = alpha_map(torch.tensor([[[True, False]]]))
    torch.testing.assert_close(a, torch.tensor([[[0.1, 0.5]]]))
    assert alpha_map(np.array([[[False]]]), 0.2, 0.7).item() == pytest.approx(0.7)

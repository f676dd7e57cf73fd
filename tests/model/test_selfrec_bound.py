"""The sub-cell offset bound of self-reconstruction (``model/selfrec_bound.py``) and ``place_at``."""

from __future__ import annotations

import numpy as np

from model.data import max_pool, place_at, place_in_crop
from model.selfrec_bound import offset_bound, offset_groups


def _placed_coarse(binary, offset, f):
    fine = place_at(binary.astype(np.int16) - 1, offset, f, margin=0) != -1
    return max_pool(fine, f)


def test_place_at_is_place_in_crop_at_the_drawn_offset():
    lab = np.zeros((5, 7, 3), dtype=np.int16)
    lab[1, 2, 0] = -1
    a = place_in_crop(lab, np.random.default_rng(4), 4, min_cells=3)
    b = place_at(lab, np.random.default_rng(4).integers(0, 4, size=3), 4, min_cells=3)
    assert np.array_equal(a, b)


def test_groups_are_the_offsets_with_equal_coarse_grids():
    rng = np.random.default_rng(0)
    binary = rng.random((6, 5, 7)) > 0.7
    binary[0, 0, 0] = binary[-1, -1, -1] = True
    f = 4
    groups = offset_groups(binary, f)
    assert len(groups) == f**3
    offsets = [(0, 0, 0), (1, 2, 3), (3, 3, 3), (2, 0, 1), (1, 2, 2)]
    for a in offsets:
        for b in offsets:
            same = np.array_equal(_placed_coarse(binary, a, f), _placed_coarse(binary, b, f))
            assert (groups[a] == groups[b]) == same


def test_a_solid_cube_hides_its_offset_and_caps_the_iou():
    f = 4
    cube = np.ones((8, 8, 8), dtype=bool)
    groups = offset_groups(cube, f)
    # at offset 0 the cube fills exactly 2 cells a side: no other offset gives that grid
    known = offset_bound(cube, (0, 0, 0), f, groups=groups)
    assert known.group_size == 1 and known.iou_expected == 1.0 and known.iou_at_offset == 1.0
    # offsets 1..3 per axis all give 3 full cells a side: 27 offsets, one input, up to 2 voxels of shift
    hidden = offset_bound(cube, (2, 1, 3), f, groups=groups, max_members=27)
    assert hidden.group_size == 27
    assert 0.5 < hidden.iou_expected < 0.95
    # a cube filling whole cells survives the fill projection; nothing to add
    assert known.projection_iou == 1.0


def test_the_projection_inflates_a_thin_exemplar():
    f = 4
    rod = np.zeros((1, 8, 1), dtype=bool)
    rod[:] = True  # one voxel thick: every cell it touches is 1/16 full
    b = offset_bound(rod, (0, 0, 0), f, min_fill=0.5)
    assert b.projection_iou < 0.2


def test_thin_cells_are_one_cell_thick_along_some_axis():
    from model.finish import thin_cells

    occ = np.zeros((6, 6, 6), dtype=bool)
    occ[1:4, 1:4, 1:4] = True  # a 3³ block: every cell has an occupied neighbour inward on every axis
    assert not thin_cells(occ).any()
    occ[2, 4:6, 2] = True  # a rod of two cells up from the block's top face, to the grid's edge
    thin = thin_cells(occ)
    assert {tuple(c) for c in np.argwhere(thin)} == {(2, 4, 2), (2, 5, 2)}
    flat = np.zeros((4, 1, 4), dtype=bool)
    flat[1:3, 0, 1:3] = True  # a slab one cell thick in y: all thin
    assert thin_cells(flat).sum() == 4


def test_thin_only_projection_leaves_thick_parts_alone():
    from model.finish import min_fill_projection

    f = 4
    occ = np.zeros((5, 5, 5), dtype=bool)
    occ[1:4, 1:4, 1:4] = True
    occ[2, 4, 2] = True  # one thin cell on top
    fine = np.zeros((20, 20, 20), dtype=np.float32)
    fine[4:16, 4:16, 4:16] = 0.9  # the block, solid...
    fine[4:5, 4:16, 4:16] = 0.0  # ...but its first layer of cells only 3/4 full in x
    fine[4:6, 4:6, 4:6] = 0.0
    fine[8:16, 4:5, 4:16] = 0.0  # a face cell row 3/4 full
    fine[8, 16, 8] = 0.9  # the thin cell: one voxel
    all_cells = min_fill_projection(fine.copy(), occ, f, 0.9)
    thin = min_fill_projection(fine.copy(), occ, f, 0.9, thin_only=True)
    block = (slice(8, 12), slice(16, 20), slice(8, 12))
    assert (thin[block] > 0.4).mean() >= 0.9 and (all_cells[block] > 0.4).mean() >= 0.9
    rest = np.ones_like(fine, dtype=bool)
    rest[block] = False
    assert np.array_equal(thin[rest], fine[rest])  # thick cells that hold a voxel: untouched
    assert not np.array_equal(all_cells[rest], fine[rest])  # the plain projection grew them
    # a thick cell the generator left empty gets one voxel (so Strict-IOU stays 1), no more
    fine[4:8, 4:8, 4:8] = 0.0
    floor = min_fill_projection(fine.copy(), occ, f, 0.9, thin_only=True)
    assert (floor[4:8, 4:8, 4:8] > 0.4).sum() == 1

"""The learned detailizer behind the pipeline protocol, with tiny random-init checkpoints."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

from model.checkpoint import Checkpoint, save_checkpoint
from model.config import ModelConfig
from model.masks import fill_nearest
from model.finish import finish_columns, min_fill_projection, remove_specks, thin_cells
from model.infer import DEFAULT_CHECKPOINT, DecollageDetailizer, resolve_device
from model.networks import Generator
from core import detailizer as pipeline_detailize
from core.errors import DetailizeError
from core.grid import EMPTY, ISO_LEVEL, LabeledGrid

STYLES = ("tower", "tree", "cake")
PARTS = ("body", "roof")


@pytest.fixture
def ckpt_path(tmp_path):
    cfg = ModelConfig.lean(len(PARTS), len(STYLES)).scaled(0.125)
    torch.manual_seed(0)
    gen = Generator(cfg)
    with torch.no_grad():  # distinct style codes, so styles change the output
        gen.style_codes.copy_(torch.randn(gen.style_codes.shape))
    ck = Checkpoint(cfg, STYLES, PARTS, (PARTS, ("body",), PARTS), gen.state_dict(), {"step": 0})
    return str(save_checkpoint(tmp_path / "tiny.pt", ck))


def _grid(shape=(3, 4, 2), style_names=("cake", "tower"), part_names=("roof", "body"), style_of=(0, 1)):
    occ = np.zeros(shape, dtype=bool)
    occ[: shape[0] - 1, : shape[1] - 1, :] = True
    part = np.where(occ, 0, EMPTY).astype(np.int16)
    part[:, 0, :][occ[:, 0, :]] = 1  # bottom layer is "body" (index 1 here), the rest "roof"
    style = np.where(occ, np.where(part == 1, style_of[1], style_of[0]), EMPTY).astype(np.int16)
    return LabeledGrid(occ, part, style, part_names, style_names, voxel_size_m=0.5, origin_m=(1.0, 2.0, 3.0))


@pytest.mark.parametrize("shape", [(3, 3, 3), (3, 4, 2), (6, 2, 1)])
def test_output_shapes_cubic_and_non_cubic(ckpt_path, shape):
    det = DecollageDetailizer(ckpt_path, device="cpu")
    g = _grid(shape)
    fine = det.detailize(g, seed=0)
    assert fine.shape == tuple(16 * n for n in shape)
    assert fine.occupancy.dtype == np.float32 and 0.0 <= fine.occupancy.min() and fine.occupancy.max() <= 1.0
    assert fine.style.shape == fine.shape and fine.style.dtype == np.int16
    assert fine.style.min() >= 0  # every voxel has a style, also empty ones
    assert fine.voxel_size_m == pytest.approx(0.5 / 16) and fine.origin_m == (1.0, 2.0, 3.0)
    assert fine.style_names == g.style_names and fine.detailizer == "decollage"


def test_styles_are_input_indices_upsampled(ckpt_path):
    det = DecollageDetailizer(ckpt_path, device="cpu")
    g = _grid((3, 4, 2))
    fine = det.detailize(g)
    # fine voxel (16i+a, 16j+b, 16k+c) carries coarse cell (i, j, k)'s style (an index into g.style_names)
    assert np.array_equal(fine.style[::16, ::16, ::16][g.occupancy], g.style[g.occupancy])
    assert fine.style[5, 3, 7] == 1 and fine.style[5, 20, 7] == 0  # body (tower = 1) at the bottom, roof (cake) above


def test_names_map_to_checkpoint_indices(ckpt_path):
    det = DecollageDetailizer(ckpt_path, device="cpu")
    assert det.style_names == STYLES and det.part_names == PARTS and det.learned
    # The same styling, spelled with different grid vocabularies, gives the same output.
    a = det.detailize(_grid(style_names=("cake", "tower"), style_of=(0, 1)))
    b = det.detailize(_grid(style_names=("tower", "cake", "tree"), style_of=(1, 0)))
    assert np.array_equal(a.occupancy, b.occupancy)
    c = det.detailize(_grid(style_names=("tree", "tower"), style_of=(0, 1)))  # roof now "tree"
    assert not np.allclose(a.occupancy, c.occupancy)
    # Swapping the part vocabulary order with the same meaning gives the same output too.
    g = _grid()
    swapped = LabeledGrid(g.occupancy, np.where(g.occupancy, 1 - g.part, EMPTY).astype(np.int16), g.style,
                          ("body", "roof"), g.style_names, g.voxel_size_m, g.origin_m)
    assert np.array_equal(det.detailize(swapped).occupancy, a.occupancy)


def test_unknown_style_and_part_list_known(ckpt_path):
    det = DecollageDetailizer(ckpt_path, device="cpu")
    with pytest.raises(DetailizeError, match=r"unknown style 'gothic' \(known: tower, tree, cake\)"):
        det.detailize(_grid(style_names=("gothic", "tower")))
    with pytest.raises(DetailizeError, match=r"unknown part 'leaf' \(known: body, roof\)"):
        det.detailize(_grid(part_names=("leaf", "body")))
    # A name in the grid's vocabulary that no voxel uses is not an error.
    det.detailize(_grid(style_names=("cake", "tower", "gothic")))


def test_part_aliases_map_to_their_part(tmp_path):
    cfg = ModelConfig.lean(2, len(STYLES)).scaled(0.125)
    torch.manual_seed(0)
    gen = Generator(cfg)
    ck = Checkpoint(cfg, STYLES, ("bottom", "top"), (("bottom", "top"),) * 3, gen.state_dict(), {"step": 0},
                    part_aliases={"body": "bottom", "roof": "top"})
    det = DecollageDetailizer(str(save_checkpoint(tmp_path / "a.pt", ck)), device="cpu")
    assert det.part_names == ("bottom", "top", "body", "roof")
    g = _grid(part_names=("roof", "body"))
    canonical = LabeledGrid(g.occupancy, g.part, g.style, ("top", "bottom"), g.style_names, g.voxel_size_m)
    assert np.array_equal(det.detailize(g).occupancy, det.detailize(canonical).occupancy)
    with pytest.raises(DetailizeError, match=r"unknown part 'leaf' \(known: bottom, top, body, roof\)"):
        det.detailize(_grid(part_names=("leaf", "body")))


def test_deterministic_and_describe(ckpt_path):
    det = DecollageDetailizer(ckpt_path, device="cpu")
    g = _grid()
    torch.manual_seed(123)
    before = torch.rand(1)
    a, b = det.detailize(g, seed=5), det.detailize(g, seed=5)
    assert np.array_equal(a.occupancy, b.occupancy)
    torch.manual_seed(123)
    assert torch.equal(torch.rand(1), before)  # the caller's RNG is untouched
    d = det.describe()
    assert d["name"] == "decollage" and d["learned"] is True and d["style_names"] == list(STYLES)
    assert d["factor"] == 16 and d["generator_params"] > 0 and d["device"] == "cpu"


def test_output_is_generator_on_bbox_plus_margin(ckpt_path):
    """The output is the generator run on the occupied box + 1 empty cell, cut to the grid, 0 elsewhere."""
    det = DecollageDetailizer(ckpt_path, device="cpu", speck_voxels=0)  # the raw field: no speck removed
    g = _grid((4, 3, 5))  # occupied: x 0..2, y 0..1, z 0..4
    fine = det.detailize(g)
    # box + margin: x [-1, 4), y [-1, 3), z [-1, 6): one empty cell added outside the grid where the box touches it
    pad = ((1, 0), (1, 0), (1, 1))
    occ = np.pad(g.occupancy, pad)
    gen = det.generator
    # Rebuild the inputs by hand: roof → checkpoint part 1, body → 0; cake → style 2 (roof), tower → 0 (body).
    lab = np.where(g.occupancy, np.where(g.part == 1, 0, 1), -1)
    sty = np.where(g.occupancy, np.where(g.part == 1, 0, 2), -1)
    part = fill_nearest(np.pad(lab, pad, constant_values=-1), occ)
    style = fill_nearest(np.pad(sty, pad, constant_values=-1), occ)
    with torch.inference_mode():
        ins = gen.make_inputs(torch.from_numpy(occ)[None], torch.from_numpy(part)[None], torch.from_numpy(style)[None])
        ref = gen(*ins)[-1][0, 0].clamp(0, 1).numpy()
    np.testing.assert_allclose(fine.occupancy, ref[16:, 16:, 16:-16], atol=1e-5)


def test_specks_go_unless_a_cell_has_nothing_else():
    """Pieces of ≤ max voxels go; a bigger piece stays, and so does a speck that alone occupies its cell."""
    f = 4
    occ = np.zeros((3, 2, 2), dtype=bool)
    occ[0, 0, 0] = occ[1, 0, 0] = occ[2, 1, 1] = True
    fine = np.zeros((12, 8, 8), dtype=np.float32)
    fine[0:8, 0:2, 0:2] = 0.9  # the body across cells (0,0,0) and (1,0,0): 32 voxels
    fine[1, 3, 3] = 0.8  # a 1-voxel speck in cell (0,0,0), which also holds the body: goes
    fine[6, 5, 5:7] = 0.7  # a 2-voxel speck in the empty cell (1,1,1): goes
    fine[9, 5, 5] = 0.6  # the only material of the occupied cell (2,1,1): stays
    fine[4:6, 6:8, 0:2] = 0.9  # 8 voxels, one more than the limit: stays
    fine[3, 3, 0] = 0.3  # below the iso level: not material, untouched
    before = fine.copy()
    assert remove_specks(fine, occ, f, max_voxels=7) == 2
    assert fine[1, 3, 3] == 0 and fine[6, 5, 5:7].max() == 0
    changed = fine != before
    assert changed.sum() == 3  # the two specks' voxels alone
    assert fine[9, 5, 5] == 0.6 and fine[4:6, 6:8, 0:2].min() == np.float32(0.9) and fine[3, 3, 0] == np.float32(0.3)
    assert remove_specks(fine, occ, f, max_voxels=0) == 0  # 0 keeps every piece
    # a speck touching the body diagonally (26-connected) is part of it
    touching = np.zeros_like(before)
    touching[0:8, 0:2, 0:2] = 0.9
    touching[8, 2, 2] = 0.9
    assert remove_specks(touching, occ, f, max_voxels=7) == 0 and touching[8, 2, 2] == np.float32(0.9)


def test_column_ranges_judge_specks_as_the_whole_grid():
    """A piece cut by a column boundary is judged whole: 3 + 3 voxels across the cut stay, 1 + 1 go."""
    f = 4
    occ = np.zeros((4, 2, 2), dtype=bool)
    occ[:, 0, 0] = True
    whole = np.zeros((16, 8, 8), dtype=np.float32)
    whole[:, 0:2, 0:2] = 0.9  # the body along x
    whole[5:11, 5, 5] = 0.8  # 6 voxels across the cut at column 2 (fine x 8), 3 a side: more than the limit
    whole[7:9, 7, 0] = 0.8  # 2 voxels across the cut: a speck
    whole[1, 7, 7] = 0.7  # a speck in the first column, away from the cut
    ref = whole.copy()
    assert remove_specks(ref, occ, f, max_voxels=f) == 2
    def field(lo, hi):
        return whole[lo * f:hi * f].copy()
    thin = np.zeros_like(occ)
    for cut in (1, 2, 3):
        joined = np.concatenate([finish_columns(field, occ, thin, 0, cut, f, f, 0.0, True),
                                 finish_columns(field, occ, thin, cut, 4, f, f, 0.0, True)])
        assert np.array_equal(joined, ref), cut
    with pytest.raises(ValueError, match="one column of halo"):
        finish_columns(field, occ, thin, 0, 2, f, f + 1, 0.0, True)


def test_the_floor_joins_its_one_voxel_to_the_neighbours_material():
    """A thick part's cell left empty gets one voxel on the face its neighbour's material touches, not at its
    highest value; with no neighbouring material, half its block; the same in column ranges."""
    f = 4
    occ = np.zeros((3, 2, 1), dtype=bool)
    occ[:, 0, 0] = occ[1, 1, 0] = True
    fine = np.zeros((12, 8, 4), dtype=np.float32)
    fine[0:4, 0:4, 0:4] = 0.9  # cell (0,0,0) full
    fine[8:12, 0:4, 0:4] = 0.9  # cell (2,0,0) full
    fine[5, 1, 1] = 0.35  # cell (1,0,0): empty, its highest value inside, away from the faces
    fine[4, 2, 2] = 0.2  # on the face towards cell (0,0,0)'s material
    thin = np.zeros_like(occ)  # every cell "thick": the one-voxel floor
    out = min_fill_projection(fine.copy(), occ, f, 0.5, thin_only=True, thin=thin)
    assert out[4, 2, 2] > ISO_LEVEL and out[5, 1, 1] < ISO_LEVEL  # joined, not the floating highest voxel
    assert (out[4:8, 0:4, 0:4] > ISO_LEVEL).sum() == 1
    # cell (1,1,0) above: its neighbour below, cell (1,0,0), had no material before the floor, so one voxel
    # would float: the cell gets the thin cells' floor, half its block, from its highest values
    fine[4:8, 4:8, 0:4] = np.linspace(0.0, 0.2, 64, dtype=np.float32).reshape(4, 4, 4)  # distinct, all below iso
    fine[6, 6, 1] = 0.3
    out = min_fill_projection(fine.copy(), occ, f, 0.5, thin_only=True, thin=thin)
    assert out[6, 6, 1] > ISO_LEVEL and (out[4:8, 4:8, 0:4] > ISO_LEVEL).sum() == 32
    def field(lo, hi):
        return fine[lo * f:hi * f].copy()
    whole = min_fill_projection(fine.copy(), occ, f, 0.5, thin_only=True, thin=thin)
    for cut in (1, 2):
        joined = np.concatenate([finish_columns(field, occ, thin, 0, cut, f, 0, 0.5, True),
                                 finish_columns(field, occ, thin, cut, 3, f, 0, 0.5, True)])
        assert np.array_equal(joined, whole), cut


def test_a_raised_block_drops_its_islands_and_still_meets_the_floor():
    """Raising a noisy block to half full puts scattered voxels above iso; with ``island_voxels`` they go, the
    block is raised again, and it still ends at least half full, in one piece."""
    import cc3d

    f = 8
    occ = np.zeros((1, 1, 1), dtype=bool)
    occ[0, 0, 0] = True  # a lone cell: thin along every axis
    rng = np.random.default_rng(0)
    fine = (rng.random((f, f, f)) * 0.2).astype(np.float32)  # noise below iso
    xs, ys, zs = np.meshgrid(*[np.arange(f)] * 3, indexing="ij")
    fine += np.where(xs < 4, 0.3, 0.0).astype(np.float32)  # a smooth half: the block's shape
    fine[6, 2, 2] = fine[6, 5, 6] = fine[7, 1, 5] = 0.39  # isolated high values on the far side
    pieces = []
    for islands in (0, 16):
        out = min_fill_projection(fine.copy(), occ, f, 0.5, thin_only=True, island_voxels=islands)
        above = out > ISO_LEVEL
        assert above.sum() >= 256  # the floor holds either way
        pieces.append(int(cc3d.connected_components(above.view(np.uint8), connectivity=26).max()))
    assert pieces[0] > 1 and pieces[1] == 1
    # beside a full neighbour cell, the high value on the shared face is joined to it, not an island: it stays
    two = np.zeros((2 * f, f, f), dtype=np.float32)
    two[:f], two[f:] = fine, 0.9
    out = min_fill_projection(two, np.ones((2, 1, 1), dtype=bool), f, 0.5, thin_only=True, island_voxels=16)
    assert out[7, 1, 5] > ISO_LEVEL and out[6, 2, 2] < ISO_LEVEL


def test_the_detailizer_removes_specks_and_refuses_a_limit_above_the_factor(ckpt_path):
    g = _grid((4, 3, 5))
    raw = DecollageDetailizer(ckpt_path, device="cpu", speck_voxels=0).detailize(g).occupancy
    det = DecollageDetailizer(ckpt_path, device="cpu")  # the default limit
    clean = det.detailize(g).occupancy
    assert det.describe()["speck_voxels"] == 16
    removed = (raw > ISO_LEVEL) & ~(clean > ISO_LEVEL)
    assert removed.any() and np.array_equal(clean[~removed], raw[~removed])  # the random model leaves specks
    assert remove_specks(clean.copy(), g.occupancy, 16) == 0  # none left
    # every occupied cell keeps material (the Strict-IOU guarantee)
    assert (clean > ISO_LEVEL).reshape(4, 16, 3, 16, 5, 16).any(axis=(1, 3, 5))[g.occupancy].all()
    with pytest.raises(DetailizeError, match=r"speck_voxels must be in \[0, 16\]"):
        DecollageDetailizer(ckpt_path, device="cpu", speck_voxels=17)


def test_field_is_empty_far_from_the_shape(ckpt_path):
    det = DecollageDetailizer(ckpt_path, device="cpu")
    occ = np.zeros((7, 5, 6), dtype=bool)
    occ[1:3, 1:3, 1:3] = True  # crop = cells 0..3 on every axis
    e = np.where(occ, 0, EMPTY).astype(np.int16)
    fine = det.detailize(LabeledGrid(occ, e, e, PARTS, STYLES, 1.0)).occupancy
    assert fine[64:].max() == 0 and fine[:, 64:].max() == 0 and fine[:, :, 64:].max() == 0
    assert fine[16:48, 16:48, 16:48].mean() > 0  # the generator's output inside the crop


def test_empty_grid_gives_empty_field(ckpt_path):
    det = DecollageDetailizer(ckpt_path, device="cpu")
    z = np.zeros((2, 1, 3), dtype=bool)
    e = np.full(z.shape, EMPTY, dtype=np.int16)
    fine = det.detailize(LabeledGrid(z, e, e, PARTS, STYLES, 1.0))
    assert fine.shape == (32, 16, 48) and fine.occupancy.max() == 0.0


def test_registry_refuses_bad_checkpoint_and_missing_default(tmp_path, monkeypatch):
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"\x00" * 100)
    with pytest.raises(DetailizeError, match="not a readable decollage checkpoint"):
        pipeline_detailize.get_detailizer("decollage", str(junk), "cpu")
    with pytest.raises(DetailizeError, match="not found"):
        pipeline_detailize.get_detailizer("decollage", str(tmp_path / "missing.pt"), "cpu")
    monkeypatch.setattr("model.infer.DEFAULT_CHECKPOINT", tmp_path / "weights" / "things.pt")
    with pytest.raises(DetailizeError, match="the shipped model .* is missing") as e:
        DecollageDetailizer(None, device="cpu")
    assert "upsample" in e.value.hint
    assert DEFAULT_CHECKPOINT.name == "things.pt"


def test_registry_loads_a_good_checkpoint(ckpt_path):
    det = pipeline_detailize.get_detailizer("decollage", ckpt_path, "cpu")
    assert isinstance(det, DecollageDetailizer) and "decollage" in pipeline_detailize.known_detailizers()


def test_device_resolution():
    assert resolve_device("cpu").type == "cpu"
    assert resolve_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    with pytest.raises(DetailizeError, match="unknown device"):
        resolve_device("gpu-please")
    if not torch.cuda.is_available():
        with pytest.raises(DetailizeError, match="no CUDA GPU"):
            resolve_device("cuda")


def test_large_crops_run_blockwise_with_the_dense_result(ckpt_path, monkeypatch):
    import model.infer as infer

    det = DecollageDetailizer(ckpt_path, device="cpu")
    g = _grid((6, 3, 4))
    dense = det.detailize(g).occupancy
    monkeypatch.setattr(infer, "DENSE_MAX_CELLS", 0)
    monkeypatch.setattr(infer, "BLOCK_CELLS", 2)
    calls = []
    real = infer.blockwise_forward
    monkeypatch.setattr(infer, "blockwise_forward", lambda *a, **k: calls.append(k) or real(*a, **k))
    blocks = det.detailize(g).occupancy
    assert calls == [{"block_cells": 2}]
    np.testing.assert_allclose(blocks, dense, atol=1e-5)


def _long_grid() -> LabeledGrid:
    """(9, 4, 3): a slab along x with a post two cells square on it (columns 3–4): cut at column 4, the post's
    cells there look one cell thin along x to the part alone."""
    g = _grid((9, 4, 3))
    occ, part, style = g.occupancy.copy(), g.part.copy(), g.style.copy()
    occ[:, 2:, :] = False
    occ[3:5, 2:, 0:2] = True
    part[~occ], style[~occ] = EMPTY, EMPTY
    part[occ & (part == EMPTY)], style[occ & (style == EMPTY)] = 0, 0
    return LabeledGrid(occ, part, style, g.part_names, g.style_names, g.voxel_size_m, g.origin_m)


@pytest.mark.parametrize("blockwise", [False, True])
@pytest.mark.parametrize("specks", [16, 0])
def test_column_parts_join_into_the_whole_field(ckpt_path, monkeypatch, blockwise, specks):
    import model.infer as infer

    if blockwise:  # the columns' fine levels run in 2-cell blocks
        monkeypatch.setattr(infer, "DENSE_MAX_CELLS", 0)
        monkeypatch.setattr(infer, "BLOCK_CELLS", 2)
    det = DecollageDetailizer(ckpt_path, device="cpu", speck_voxels=specks)
    g = _long_grid()
    whole = det.detailize(g, seed=3)
    columns = det.column_detailizer(g, seed=3)
    second, first = columns(4, 9), columns(0, 4)  # any order
    joined = np.concatenate([first.occupancy, second.occupancy])
    if blockwise:  # blocks far from the shape are skipped (left 0), and the parts' blocks start at their cut
        both = (joined > 0) & (whole.occupancy > 0)
        assert np.array_equal(joined > ISO_LEVEL, whole.occupancy > ISO_LEVEL) and both.mean() > 0.1
        np.testing.assert_allclose(joined[both], whole.occupancy[both], atol=1e-5)
    else:
        np.testing.assert_allclose(joined, whole.occupancy, atol=1e-5)
    assert np.array_equal(np.concatenate([first.style, second.style]), whole.style)
    assert first.origin_m == whole.origin_m and second.origin_m == (1.0 + 4 * 0.5, 2.0, 3.0)
    assert second.shape == (5 * 16, 4 * 16, 3 * 16) and second.extras == whole.extras
    # a part's bytes depend on the grid and its columns only, not on what ran before it (a forked process)
    again = det.column_detailizer(g, seed=3)(4, 9)
    assert np.array_equal(again.occupancy, second.occupancy)


def test_column_parts_keep_the_floor_of_the_whole_grid(tmp_path):
    """The minimum-fill projection holds in column parts as on the whole grid, also on the cut."""
    cfg = dataclasses.replace(ModelConfig.lean(len(PARTS), len(STYLES)).scaled(0.125), min_cell_fill=0.3,
                              min_fill_thin_only=True)
    torch.manual_seed(1)
    gen = Generator(cfg)
    path = save_checkpoint(tmp_path / "fill.pt", Checkpoint(cfg, STYLES, PARTS, (PARTS, ("body",), PARTS),
                                                            gen.state_dict(), {"step": 0}))
    det = DecollageDetailizer(path, device="cpu")
    g = _long_grid()
    whole = det.detailize(g).occupancy
    columns = det.column_detailizer(g)
    joined = np.concatenate([columns(0, 4).occupancy, columns(4, 9).occupancy])
    np.testing.assert_allclose(joined, whole, atol=1e-5)
    above = joined.reshape(9, 16, 4, 16, 3, 16) > ISO_LEVEL
    fill = above.mean(axis=(1, 3, 5))
    assert not thin_cells(g.occupancy).any()  # the thick part's floor: every occupied cell keeps material
    assert fill[g.occupancy].min() > 0


_FORKED_HALVES = """
import sys
import numpy as np
from core.detailizer import kernel_threads
from core.grid import LabeledGrid
from model.infer import DecollageDetailizer
from pipeline.chunks import detailize_and_mesh
from pipeline.mesh import MeshSettings

det = DecollageDetailizer(sys.argv[1], device="cpu")
occ = np.zeros((10, 4, 3), bool)
occ[:, 1:3, 1] = True
grid = LabeledGrid(occ, np.where(occ, 0, -1).astype(np.int16), np.where(occ, 0, -1).astype(np.int16),
                   ("body",), ("tower",), 0.1)
with kernel_threads(2):
    det.detailize(grid)  # this process's OpenMP pool now has two threads
    columns = lambda g: det.column_detailizer(g)
    detailize_and_mesh(grid, det.detailize, MeshSettings(max_triangles=None), processes=2, columns=columns)
print("done")
"""


def test_a_forked_block_process_runs_the_model_on_one_thread(tmp_path):
    """With two threads asked for, the half in the forked child must not hang in OpenMP's broken pool."""
    import subprocess
    import sys

    cfg = dataclasses.replace(ModelConfig.lean(len(PARTS), len(STYLES)).scaled(0.125), min_cell_fill=0.5)
    torch.manual_seed(2)
    path = save_checkpoint(tmp_path / "fill.pt", Checkpoint(cfg, STYLES, PARTS, (PARTS, ("body",), PARTS),
                                                            Generator(cfg).state_dict(), {"step": 0}))
    run = subprocess.run([sys.executable, "-c", _FORKED_HALVES, str(path)], capture_output=True, text=True,
                         timeout=120, cwd=Path(__file__).resolve().parents[2])
    assert run.returncode == 0 and run.stdout.strip() == "done", run.stderr[-2000:]


@pytest.mark.e2e  # the shipped model at 256³
def test_shipped_model_loads_keeps_the_coarse_shape_and_adds_detail():
    """The committed weights: the 'things' styles, and a kept coarse structure."""
    assert DEFAULT_CHECKPOINT.is_file() and DEFAULT_CHECKPOINT.stat().st_size < 30 * 2**20
    det = pipeline_detailize.get_detailizer("decollage", None, "cpu")
    assert isinstance(det, DecollageDetailizer) and det.learned
    assert {"cottage", "pagoda", "druse", "birthday_cake", "fern"} <= set(det.style_names)
    assert {"bottom", "top", "body", "roof"} <= set(det.part_names)
    occ = np.zeros((10, 12, 10), bool)
    occ[1:9, 1:9, 1:9] = True  # an 8³ block house …
    occ[3:7, 9:11, 3:7] = True  # … with a roof (shapes of 8+ cells, like the training crops; 4-cell ones over-grow)
    part = np.where(occ, 0, EMPTY).astype(np.int16)
    part[:, 9:, :][occ[:, 9:, :]] = 1
    grid = LabeledGrid(occ, part, np.where(occ, 0, EMPTY).astype(np.int16), ("body", "roof"), ("cottage",),
                       voxel_size_m=0.1)
    fine = det.detailize(grid)
    assert fine.occupancy.shape == (160, 192, 160)
    inside = fine.occupancy >= 0.4
    pooled = inside.reshape(10, 16, 12, 16, 10, 16).any(axis=(1, 3, 5))
    strict = (pooled & occ).sum() / (pooled | occ).sum()
    assert strict >= 0.7  # the coarse structure is kept (the bar for the example assets)
    # not the upsample baseline: a blurred, thresholded block has almost no fine surface variation
    base = pipeline_detailize.get_detailizer("upsample").detailize(grid).occupancy >= 0.4
    assert (inside != base).mean() > 0.005

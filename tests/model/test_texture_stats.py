"""The placement-free style terms: fixed features, the band, the patch gather, and the trainer's G term."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from model.checkpoint import load_checkpoint, save_checkpoint
from model.config import LossConfig, ModelConfig, TextureMode
from model.texture_stats import (MIN_BAND_VOXELS, PatchContrast, TextureFeatures, TextureTerm, band_patches,
                                 bidirectional_patch_distance, nearest_style_logits)
from model.train import TrainConfig, Trainer, train
from core.errors import DetailizeError
from tests.model.test_train import EXS, _cfg, _tcfg

BASE = "warmup_centred_long_r1_fill_mismatch_offsets"
STATS = "warmup_centred_long_r1_fill_mismatch_offsets_tex"
PATCHES = "warmup_centred_long_r1_fill_mismatch_offsets_texp"
CONTRAST = "warmup_centred_long_r1_fill_mismatch_offsets_texpc"
COARSE = "warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse"


def _ridged_box(n: int = 40, shift: int = 0, ridges: bool = True) -> torch.Tensor:
    """A box filling [8, 32)³ of an n³ grid whose top face carries ridges 2 voxels high every 4 voxels along x
    (the ridges moved ``shift`` voxels along x), as (1, 1, n, n, n) float in {0, 1}."""
    g = torch.zeros(n, n, n)
    g[8:32, 8:32, 8:32] = 1
    if ridges:
        for x in range(8 + shift % 4, 32, 4):
            g[x:x + 2, 8:32, 32:34] = 1
    return g[None, None]


def _term(mode: TextureMode) -> TextureTerm:
    return TextureTerm(LossConfig(texture_weight=1.0, texture_mode=mode))


def test_the_features_are_fixed_by_the_seed_and_halve_per_strided_layer():
    a, b = TextureFeatures(), TextureFeatures()
    assert all(torch.equal(getattr(a, f"w{i}"), getattr(b, f"w{i}")) for i in range(len(a.strides)))
    assert not list(a.parameters()) and not a.state_dict()  # nothing trained, nothing saved
    grid = _ridged_box(37)
    feats, bands = a(grid), a.bands(grid, 2)
    size = 37
    for f, m, s in zip(feats, bands, a.strides):
        size = -(-size // s)
        assert f.shape[2:] == m.shape[2:] == (size,) * 3
    band = bands[0][0, 0]
    assert band[20, 20, 20] == 0 and band[0, 0, 0] == 0  # deep inside and far outside: not in the band
    assert band[8, 20, 20] == 1 and band[6, 20, 20] == 1 and band[5, 20, 20] == 0  # within 2 voxels of the face


def test_band_patches_are_the_grids_cubes_and_empty_beyond_its_edge():
    grid = torch.arange(6 ** 3, dtype=torch.float32).reshape(1, 1, 6, 6, 6)
    centres = torch.tensor([[3, 3, 3], [0, 0, 0]])
    p = band_patches(grid, centres, 4)
    assert p.shape == (2, 64)
    assert torch.equal(p[0].reshape(4, 4, 4), grid[0, 0, 1:5, 1:5, 1:5])
    corner = p[1].reshape(4, 4, 4)
    assert torch.equal(corner[2:, 2:, 2:], grid[0, 0, :2, :2, :2]) and corner[:2].abs().sum() == 0
    same = torch.eye(5, 8) * 10  # patches far apart: each one's nearest is its own shifted copy
    assert bidirectional_patch_distance(same, same) == pytest.approx(0.0, abs=1e-6)
    assert bidirectional_patch_distance(same, same + 0.5) == pytest.approx(0.5, rel=1e-4)


def _cost(mode: TextureMode, grid: torch.Tensor, window: torch.Tensor) -> float:
    styles = torch.zeros(grid.shape[2:], dtype=torch.int64)
    return float(_term(mode)(grid, styles, {0: window}, np.random.default_rng(3)))


def test_the_patch_term_prefers_the_windows_detail_wherever_it_falls_to_flat_faces():
    """Placement-free: the window's ridges moved by 1–3 voxels cost within 20 % of the window itself; the same
    box without the ridges (flat faces only, which every exemplar also has) costs at least 25 % more than any."""
    window = _ridged_box()
    own = _cost(TextureMode.PATCHES, window, window)
    moved = [_cost(TextureMode.PATCHES, _ridged_box(shift=k), window) for k in (1, 2, 3)]
    plain = _cost(TextureMode.PATCHES, _ridged_box(ridges=False), window)
    assert all(abs(m - own) < 0.2 * own for m in moved)
    assert plain > 1.25 * max([own, *moved])


@pytest.mark.parametrize("mode", list(TextureMode))
def test_the_term_passes_a_gradient_to_the_output(mode):
    out = _ridged_box(ridges=False).requires_grad_(True)
    styles = torch.zeros(40, 40, 40, dtype=torch.int64)
    _term(mode)(out, styles, {0: _ridged_box()}, np.random.default_rng(3)).backward()
    assert out.grad.abs().sum() > 0


def test_the_stats_term_is_zero_on_its_window_and_moved_by_the_ridges_phase_as_much_as_by_the_ridges():
    """What the stats term measures on a toy: it is exact (0 on the window itself) but the ridges moved by
    2 voxels against the box's edges cost more than no ridges at all: its statistics are dominated by the
    box's own edges and corners, not by the detail (measured 0.018 vs 0.011; the reason the patch term is
    the one trained in ``model/weights/things_selfrec.md``)."""
    window = _ridged_box()
    assert _cost(TextureMode.STATS, window, window) == 0.0
    plain = _cost(TextureMode.STATS, _ridged_box(ridges=False), window)
    assert 0 < plain < _cost(TextureMode.STATS, _ridged_box(shift=2), window)


def test_only_styles_with_a_window_and_enough_surface_are_charged():
    term = _term(TextureMode.STATS)
    out = _ridged_box().requires_grad_(True)
    styles = torch.ones(40, 40, 40, dtype=torch.int64)
    assert term(out, styles, {0: _ridged_box()}, np.random.default_rng(0)).item() == 0.0  # style 1: no window
    tiny = torch.zeros(1, 1, 40, 40, 40)
    tiny[0, 0, 20, 20, 20] = 1  # a single voxel: 5³ = 125 band voxels at most, ...
    assert float((TextureFeatures().bands(tiny, 1)[0]).sum()) < MIN_BAND_VOXELS  # ... 27 with a band of 1
    one = TextureTerm(LossConfig(texture_weight=1.0, texture_band=1))
    loss = one(tiny.requires_grad_(True), torch.zeros(40, 40, 40, dtype=torch.int64), {0: _ridged_box()},
               np.random.default_rng(0))
    assert float(loss) == 0.0 and loss.requires_grad  # still part of the graph
    mixed = torch.zeros(40, 40, 40, dtype=torch.int64)
    mixed[20:] = 1  # two styles, each with its window: both charged, each against its own
    both = float(term(_ridged_box(), mixed, {0: _ridged_box(), 1: _ridged_box(ridges=False)}, np.random.default_rng(0)))
    own_only = float(term(_ridged_box(), mixed, {0: _ridged_box(), 1: _ridged_box()}, np.random.default_rng(0)))
    assert both > own_only


def _contrast(out: torch.Tensor, style: int, real: dict) -> torch.Tensor:
    return PatchContrast(LossConfig(texture_contrast=1.0))(out, torch.full((40, 40, 40), style, dtype=torch.int64),
                                                           real, np.random.default_rng(0))


def test_nearest_style_logits_rank_the_library_that_holds_the_patch_first():
    rng = np.random.default_rng(1)
    libs = [torch.as_tensor(rng.random((5, 8)), dtype=torch.float32) for _ in range(3)]
    mine = libs[2][[0, 3]] + 0.01
    logits = nearest_style_logits(mine, libs, tau=0.1)
    assert logits.shape == (2, 3) and (logits.argmax(1) == 2).all()
    assert torch.allclose(logits[:, 2], torch.full((2,), -(0.01 ** 2) * 8 / (8 * 0.1)), atol=1e-5)  # float32 p²+q²−2pq


def test_the_contrast_charges_patches_nearer_another_styles_window_more():
    ridged, flat = _ridged_box(), _ridged_box(ridges=False)
    real = {0: ridged, 1: flat}
    # the ridged output is the ridged style's, the flat one the flat style's (libraries of 256 sampled patches
    # cover a window sparsely, so a patch's own kind is near, not at distance 0)
    assert float(_contrast(ridged, 0, real)) < float(_contrast(ridged, 1, real))
    assert float(_contrast(flat, 1, real)) < float(_contrast(flat, 0, real))
    out = flat.clone().requires_grad_(True)
    _contrast(out, 0, real).backward()
    assert out.grad.abs().sum() > 0  # a flat output labelled ridged is pushed
    assert float(_contrast(ridged, 0, {0: ridged})) == 0.0  # one style with a window: nothing to tell apart
    assert float(_contrast(ridged, 2, real)) == 0.0  # its style has no window


def test_config_refuses_bad_bands_and_patches_and_reads_old_files_as_off():
    cfg = _cfg()
    for field, value in (("texture_band", 0), ("texture_band", 1.5), ("texture_patch", 7), ("texture_patch", 32)):
        with pytest.raises(DetailizeError, match=field):
            dataclasses.replace(cfg, losses=dataclasses.replace(cfg.losses, **{field: value}))
    for field in ("texture_weight", "texture_contrast"):
        with pytest.raises(DetailizeError, match=field):
            dataclasses.replace(cfg, losses=dataclasses.replace(cfg.losses, **{field: -1.0}))
    old = cfg.to_dict()
    for key in ("texture_weight", "texture_mode", "texture_band", "texture_patch", "texture_contrast"):
        old["losses"].pop(key)
    assert ModelConfig.from_dict(old) == cfg and cfg.losses.texture_weight == 0
    on = dataclasses.replace(cfg, losses=dataclasses.replace(cfg.losses, texture_weight=2.0,
                                                              texture_mode=TextureMode.PATCHES))
    assert ModelConfig.from_dict(on.to_dict()) == on


@pytest.mark.parametrize("recipe", [STATS, PATCHES, CONTRAST, COARSE])
def test_an_offsets_state_branches_into_the_term_which_moves_g_deterministically(tmp_path, recipe):
    from model.recipe_move import move_state_recipe
    from model.recipes import recipe_configs

    cfg_o, t_o = recipe_configs(BASE, _cfg(), _tcfg(tmp_path, 2, recipe=BASE))
    t_o = dataclasses.replace(t_o, warmup_iters=0)
    cfg_t, _ = recipe_configs(recipe, _cfg(), _tcfg(tmp_path, 2, recipe=recipe))
    assert cfg_t.losses.texture_weight > 0 and dataclasses.replace(cfg_t, losses=cfg_o.losses) == cfg_o
    res = train(EXS, cfg_o, t_o, resume=False)
    assert "g_tex" not in Trainer(EXS, cfg_o, t_o).iteration()  # off: nothing charged or logged
    branched = move_state_recipe(load_checkpoint(res.checkpoint, training_state=True), recipe, branch=True)
    tcfg = TrainConfig.recorded(branched.training["train_config"], out_dir=str(tmp_path / "b"))
    state = save_checkpoint(tmp_path / "branched.pt", branched)
    runs = []
    for _ in range(2):
        trainer = Trainer(EXS, branched.config, tcfg)
        trainer.restore(state)
        assert trainer.bank is not None and trainer.bank.styles() == [0, 1]
        assert trainer.bank.levels == branched.config.supervised_levels[branched.config.losses.style_classifier_from:]
        losses = trainer.iteration()
        runs.append((losses, torch.cat([p.detach().flatten() for p in trainer.gen.parameters()])))
    assert runs[0][0]["g_tex"] > 0 and runs[0][0]["g_tex"] == runs[1][0]["g_tex"]
    assert ("g_texc" in runs[0][0]) == (recipe in (CONTRAST, COARSE))
    if recipe in (CONTRAST, COARSE):  # two styles: the classification's loss is near ln 2, and the same in both runs
        assert 0 < runs[0][0]["g_texc"] == runs[1][0]["g_texc"]
    # the patch gather's backward adds overlapping patches in thread order: equal to float rounding, not bit for bit
    assert torch.allclose(runs[0][1], runs[1][1], rtol=0, atol=1e-6)

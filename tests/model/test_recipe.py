"""The training-recipe switches: style-code init and learning rate, the warm-up, several windows per step,
the output mask, per-level L_up weights, the minimum-fill projection and the monitor."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from model.checkpoint import load_checkpoint
from model.config import ModelConfig
from model.finish import min_fill_projection
from model.losses import structure_losses, whole_shape_prevs
from model.monitor import Monitor, cell_fill
from model.networks import Generator
from model.train import TrainConfig, Trainer, train
from model.windows import window_forward, windows_forward
from core.errors import DetailizeError
from tests.model.test_train import EXS, _cfg, _log, _tcfg


def _inputs(gen: Generator, shape, seed=0):
    g = torch.Generator().manual_seed(seed)
    occ = torch.rand(1, *shape, generator=g) > 0.4
    parts = torch.randint(0, gen.cfg.n_parts, (1, *shape), generator=g)
    styles = torch.randint(0, gen.cfg.n_styles, (1, *shape), generator=g)
    return gen.make_inputs(occ, parts, styles)


def test_style_codes_random_init_is_seeded():
    cfg = dataclasses.replace(_cfg(), style_init_std=1.0)
    torch.manual_seed(0)
    a = Generator(cfg).style_codes.detach().clone()
    torch.manual_seed(0)
    b = Generator(cfg).style_codes.detach()
    assert torch.equal(a, b) and 0.5 < a.std() < 1.5
    assert torch.count_nonzero(Generator(_cfg()).style_codes) == 0  # the default stays the reference's zeros


def test_output_mask_zeroes_every_level_outside_the_occupied_cells():
    cfg = dataclasses.replace(_cfg(), output_mask=True)
    torch.manual_seed(0)
    gen = Generator(cfg)
    occ, parts, z = _inputs(gen, (3, 2, 4))
    with torch.no_grad():
        outs = gen(occ, parts, z)
        for j, o in enumerate(outs):
            mask = torch.nn.functional.interpolate(occ, scale_factor=2 ** (j + 1), mode="nearest")
            assert torch.count_nonzero(o * (1 - mask)) == 0 and torch.count_nonzero(o * mask) > 0
        # windows run the same mask
        win = (slice(0, 2), slice(0, 2), slice(1, 3))
        w = window_forward(gen, occ, parts, z, 2, win)[-1]
        ref = outs[-1][:, :, 0:32, 0:32, 16:48]
        torch.testing.assert_close(w, ref, rtol=1e-5, atol=1e-6)


def test_several_windows_share_one_trunk_and_equal_single_windows():
    torch.manual_seed(0)
    gen = Generator(_cfg())
    ins = _inputs(gen, (6, 4, 5))
    wins = [(slice(0, 4), slice(0, 4), slice(0, 4)), (slice(2, 6), slice(0, 4), slice(1, 5))]
    with torch.no_grad():
        many = windows_forward(gen, *ins, 2, wins)
        for w, outs in zip(wins, many):
            for a, b in zip(outs, window_forward(gen, *ins, 2, w)):
                torch.testing.assert_close(a, b)
    assert many[0][0] is many[1][0]  # the whole levels are computed once


def test_up_level_weights_scale_each_level_and_leave_down_alone():
    lc = ModelConfig.lean(1, 1).losses
    x = torch.ones(1, 1, 1, 1, 1)
    outs = [torch.ones(1, 1, 2, 2, 2) * 0.5, torch.ones(1, 1, 4, 4, 4) * 0.25]
    plain = structure_losses(outs, whole_shape_prevs(outs, x), lc)
    weighted = structure_losses(outs, whole_shape_prevs(outs, x), dataclasses.replace(lc, up_level_weights=(1.0, 0.1)))
    assert weighted["up"] == plain["up"] and weighted["down"] == plain["down"]
    expected = 10 * plain["down"] + 10 * plain["up0"] + 10 * 0.1 * plain["up1"]
    assert weighted["total"].item() == pytest.approx(expected.item())
    with pytest.raises(DetailizeError, match="up_level_weights"):
        dataclasses.replace(_cfg(), losses=dataclasses.replace(lc, up_level_weights=(1.0, 0.1)))


def test_config_reads_checkpoints_written_before_the_recipe_switches():
    data = _cfg().to_dict()
    for key in ("style_init_std", "output_mask", "min_cell_fill", "style_code_rms", "min_fill_thin_only"):
        data.pop(key)
    for key in ("up_level_weights", "gamma_fill", "fill_floor"):
        data["losses"].pop(key)
    assert ModelConfig.from_dict(data) == _cfg()
    new = dataclasses.replace(_cfg(), style_init_std=0.5, output_mask=True, min_cell_fill=0.5,
                              style_code_rms=1.0, min_fill_thin_only=True,
                              losses=dataclasses.replace(_cfg().losses, up_level_weights=(1, 1, 0.1, 0.1),
                                                         gamma_fill=10.0, fill_floor=0.4))
    assert ModelConfig.from_dict(json.loads(json.dumps(new.to_dict()))) == new
    with pytest.raises(DetailizeError, match="min_cell_fill"):
        dataclasses.replace(_cfg(), min_cell_fill=1.5)
    with pytest.raises(DetailizeError, match="fill_floor"):
        dataclasses.replace(_cfg(), losses=dataclasses.replace(_cfg().losses, fill_floor=2.0))


def test_min_fill_projection_grows_only_the_thin_cells():
    occ = np.zeros((3, 1, 1), bool)
    occ[:2] = True
    rng = np.random.default_rng(0)
    fine = np.zeros((48, 16, 16), np.float32)
    fine[:16] = rng.random((16, 16, 16)) * 0.45  # a thin cell: few voxels above 0.4
    fine[16:32] = 0.9
    before = fine.copy()
    out = min_fill_projection(fine, occ, 16, 0.5)
    fill = cell_fill(out > 0.4, occ | True, 16)
    assert fill[0] >= 0.5 and fill[1] == 1.0 and fill[2] == 0.0
    assert np.array_equal(out[16:], before[16:])  # full and empty cells untouched
    # the thin cell keeps its own order of values (a uniform raise)
    assert np.array_equal(np.argsort(out[:16].ravel(), kind="stable"), np.argsort(before[:16].ravel(), kind="stable"))
    assert min_fill_projection(before.copy(), occ, 16, 0.0) is not None


def test_warmup_lr_schedule_style_group_and_resume(tmp_path):
    cfg = dataclasses.replace(_cfg(), style_init_std=1.0)
    kw = dict(warmup_iters=2, warmup_lr=1e-3, windows_per_step=2, style_lr_mult=10.0, monitor_every=2)
    trainer = Trainer(EXS, cfg, _tcfg(tmp_path, 3, **kw))
    assert trainer.learning_rate(0) == pytest.approx(1e-3) and trainer.learning_rate(2) == pytest.approx(1e-4)
    assert 1e-4 < trainer.learning_rate(1) < 1e-3
    assert [g["lr_mult"] for g in trainer.opt_g.param_groups] == [1.0, 10.0]
    res = train(EXS, cfg, _tcfg(tmp_path, 3, **kw), resume=False)
    log = _log(res.log)
    assert [r["step"] for r in log] == [1, 2, 3]
    assert "gan" not in log[0] and "lr" in log[0] and "gan" in log[2]  # warm-up rows: reconstruction only
    mon = log[1]["monitor"]
    assert set(mon) >= {"self_iou", "upsample_self_iou", "overlap", "strict", "cell_fill_min", "cells_half_full"}
    assert 0 <= mon["self_iou"] <= 1 and 0 <= mon["overlap"] <= 1
    codes = load_checkpoint(res.model).generator["style_codes"]
    torch.manual_seed(3)
    assert not torch.equal(codes, Generator(cfg).style_codes.detach())  # the codes moved
    # resuming from step 2 ends where the unbroken run ends
    train(EXS, cfg, dataclasses.replace(_tcfg(tmp_path, 2, **kw), out_dir=str(tmp_path / "b")), resume=False)
    res_b = train(EXS, cfg, dataclasses.replace(_tcfg(tmp_path, 3, **kw), out_dir=str(tmp_path / "b")))
    a, b = load_checkpoint(res.checkpoint).generator, load_checkpoint(res_b.checkpoint).generator
    for k in a:
        torch.testing.assert_close(a[k], b[k], rtol=1e-5, atol=1e-6)


def test_monitor_upsample_baseline_is_a_fixed_reference():
    from model.train import TrainConfig

    cfg = _cfg()
    mon = Monitor(EXS, cfg, TrainConfig(out_dir="unused", steps=0, resolution=64).augment())
    assert 0 < mon.baseline_self_iou() <= 1 and mon.baseline_self_iou() == mon.baseline_self_iou()


def test_style_code_rms_fixes_the_norm_of_every_code():
    cfg = dataclasses.replace(_cfg(), style_init_std=1.0, style_code_rms=1.5)
    torch.manual_seed(0)
    gen = Generator(cfg)
    codes = gen.codes()
    torch.testing.assert_close(codes.pow(2).mean(0).sqrt(), torch.full((cfg.n_styles,), 1.5))
    # the gradient reaches the learnt codes through the normalisation
    gen.zero_grad()
    gen(*_inputs(gen, (3, 4, 3)))[-1].sum().backward()
    assert gen.style_codes.grad is not None and gen.style_codes.grad.abs().sum() > 0
    # free codes (the default) are used as learnt; the setting round-trips and rejects a negative
    assert Generator(_cfg()).codes() is not None and _cfg().style_code_rms == 0
    assert ModelConfig.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(DetailizeError):
        dataclasses.replace(cfg, style_code_rms=-1.0)


def test_style_code_rms_output_ignores_the_codes_scale():
    cfg = dataclasses.replace(_cfg(), style_init_std=1.0, style_code_rms=1.0)
    torch.manual_seed(1)
    gen = Generator(cfg)
    inputs = _inputs(gen, (3, 3, 4), seed=2)
    styles = torch.randint(0, cfg.n_styles, (1, 3, 3, 4), generator=torch.Generator().manual_seed(5))
    before = gen(inputs[0], inputs[1], gen.style_field(styles))[-1]
    with torch.no_grad():
        gen.style_codes.mul_(0.05)
    after = gen(inputs[0], inputs[1], gen.style_field(styles))[-1]
    torch.testing.assert_close(before, after)
    free = Generator(dataclasses.replace(cfg, style_code_rms=0.0))
    free.load_state_dict(gen.state_dict())
    with torch.no_grad():
        free.style_codes.mul_(20.0)
    assert not torch.allclose(free(inputs[0], inputs[1], free.style_field(styles))[-1], after)


def test_monitor_with_one_style_and_the_raw_self_iou():
    from model.train import TrainConfig

    aug = TrainConfig(out_dir="unused", steps=0, resolution=64).augment()
    one = [EXS[0]]
    cfg = dataclasses.replace(ModelConfig.lean(2, 1).scaled(0.125), min_cell_fill=0.0)
    torch.manual_seed(0)
    gen = Generator(cfg)
    fig = Monitor(one, cfg, aug).figures(gen)
    assert fig["overlap"] == 1.0  # one style: both outputs are the same style
    assert fig["self_iou_raw"] == fig["self_iou"]  # no projection: the same figure
    filled = dataclasses.replace(cfg, min_cell_fill=1.0)
    gen_f = Generator(filled)
    gen_f.load_state_dict(gen.state_dict())
    fig_f = Monitor(one, filled, aug).figures(gen_f)
    assert fig_f["self_iou_raw"] == fig["self_iou_raw"]  # the projection is inference-only
    assert fig_f["cell_fill_min"] == 1.0 and "code_rms" in fig_f
    assert "self_iou_raw_each" not in fig_f


def test_monitor_per_exemplar_lists_behind_the_means():
    from model.train import TrainConfig

    aug = TrainConfig(out_dir="unused", steps=0, resolution=64).augment()
    cfg = dataclasses.replace(ModelConfig.lean(2, 2).scaled(0.125), min_cell_fill=1.0)
    torch.manual_seed(0)
    gen = Generator(cfg)
    fig = Monitor(EXS[:2], cfg, aug).figures(gen, per_exemplar=True)
    assert len(fig["self_iou_raw_each"]) == len(fig["self_iou_each"]) == 2
    assert abs(np.mean(fig["self_iou_raw_each"]) - fig["self_iou_raw"]) < 1e-3
    assert abs(np.mean(fig["self_iou_each"]) - fig["self_iou"]) < 1e-3
    assert min(fig["self_iou_each"]) == fig["self_iou_min"]
    # a full-cell projection of an untrained field differs from the raw field
    assert fig["self_iou_each"] != fig["self_iou_raw_each"]


def test_a_warmup_state_moves_to_warmup_thin_and_resumes(tmp_path):
    from model.checkpoint import save_checkpoint
    from model.recipe_move import move_state_recipe
    from model.recipes import recipe_configs

    cfg_w, t_w = recipe_configs("warmup", _cfg(), _tcfg(tmp_path, 1, recipe="warmup"))
    res = train(EXS, cfg_w, t_w, resume=False)
    ck = load_checkpoint(res.checkpoint, training_state=True)
    moved = move_state_recipe(ck, "warmup_thin")
    assert moved.config == dataclasses.replace(ck.config, min_fill_thin_only=True)
    assert moved.training["recipe"] == "warmup_thin" and moved.training["step"] == 1
    for k in ck.generator:
        assert torch.equal(ck.generator[k], moved.generator[k])
    cfg_t, t_t = recipe_configs("warmup_thin", _cfg(), _tcfg(tmp_path, 2, recipe="warmup_thin"))
    assert cfg_t == moved.config
    save_checkpoint(tmp_path / "run" / "last.pt", moved)
    trainer = Trainer(EXS, cfg_t, t_t)
    trainer.restore(tmp_path / "run" / "last.pt")  # accepted as a warmup_thin state
    assert trainer.step == 1
    # recipes that train differently are refused
    for other in ("reference", "distill", "warmup_low"):
        with pytest.raises(ValueError, match="train differently"):
            move_state_recipe(ck, other)


def test_warmup_low_is_warmup_thin_at_a_lower_warmup_peak(tmp_path):
    from model.recipes import WARMUP_ITERS, recipe_configs

    cfg_t, t_t = recipe_configs("warmup_thin", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_thin"))
    cfg_l, t_l = recipe_configs("warmup_low", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_low"))
    assert cfg_l == cfg_t  # the same model, output mask and inference projection (thin cells only)
    assert cfg_l.min_fill_thin_only and cfg_l.output_mask and cfg_l.style_init_std == 1.0
    assert t_l.warmup_lr == pytest.approx(3e-4) and t_t.warmup_lr == pytest.approx(1e-3)
    assert t_l.warmup_iters == WARMUP_ITERS and t_l.windows_per_step == 4 and t_l.style_lr_mult == 10.0
    # nothing else of the training differs (the recipe name is the caller's, equal here)
    assert dataclasses.replace(t_l, warmup_lr=t_t.warmup_lr, recipe=t_t.recipe) == t_t
    trainer = Trainer(EXS, cfg_l, t_l)
    assert trainer.learning_rate(0) == pytest.approx(3e-4)
    assert trainer.learning_rate(WARMUP_ITERS) == pytest.approx(t_l.lr)  # the half cosine ends at the base rate


def test_warmup_centred_is_warmup_low_with_the_reference_placement(tmp_path):
    from model.recipes import recipe_configs

    cfg_l, t_l = recipe_configs("warmup_low", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_low"))
    cfg_c, t_c = recipe_configs("warmup_centred", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_centred"))
    assert cfg_c == cfg_l and t_l.style_offset is None and t_c.style_offset == "centre"
    assert dataclasses.replace(t_c, style_offset=None, recipe=t_l.recipe) == t_l  # nothing else differs
    assert t_c.augment().style_offset == "centre"


def test_warmup_centred_r4_trains_like_warmup_centred_until_its_adversarial_phase(tmp_path):
    from model.recipes import R4_UNTIL, WARMUP_ITERS, recipe_configs

    cfg_c, t_c = recipe_configs("warmup_centred", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_centred"))
    cfg_r, t_r = recipe_configs("warmup_centred_r4", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_centred_r4"))
    assert cfg_r == cfg_c  # the same model: a warmup_centred state continues under it
    assert t_c.recon_early_iters == 0 and t_r.recon_early_iters == R4_UNTIL > WARMUP_ITERS == t_r.warmup_iters
    assert t_r.recon_steps_early == 4
    # nothing else differs (the test's base config has 2 early reconstruction steps; the default is 4)
    assert dataclasses.replace(t_r, recon_early_iters=0, recon_steps_early=t_c.recon_steps_early,
                               recipe=t_c.recipe) == t_c
    # count the reconstruction steps of one iteration in the warm-up and one after it
    counts = {}
    for it in (WARMUP_ITERS - 1, WARMUP_ITERS):
        trainer = Trainer(EXS, cfg_r, t_r)
        calls = []
        trainer.reconstruction_step = lambda i, r, calls=calls: (calls.append(r), ({"recon": 0.0}, None))[1]
        trainer.adversarial_steps = lambda i, real: {}
        trainer.step = it
        trainer.iteration()
        counts[it] = len(calls)
    assert counts == {WARMUP_ITERS - 1: 1, WARMUP_ITERS: 4}


def test_the_long_recipes_stretch_the_4_to_1_phase_and_the_warmup(tmp_path):
    from model.recipes import R4_LONG_UNTIL, R4_UNTIL, WARMUP_ITERS, WARMUP_LONG_ITERS, recipe_configs

    cfg_r, t_r = recipe_configs("warmup_centred_r4", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_centred_r4"))
    cfg_rl, t_rl = recipe_configs("warmup_centred_r4_long", _cfg(),
                                  _tcfg(tmp_path, 1, recipe="warmup_centred_r4_long"))
    cfg_l, t_l = recipe_configs("warmup_centred_long", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_centred_long"))
    assert cfg_r == cfg_rl == cfg_l
    assert t_r.recon_early_iters == R4_UNTIL < R4_LONG_UNTIL == t_rl.recon_early_iters == t_l.recon_early_iters
    assert t_r.warmup_iters == t_rl.warmup_iters == WARMUP_ITERS < WARMUP_LONG_ITERS == t_l.warmup_iters
    assert dataclasses.replace(t_rl, recon_early_iters=R4_UNTIL, recipe=t_r.recipe) == t_r
    assert dataclasses.replace(t_l, warmup_iters=WARMUP_ITERS, recipe=t_rl.recipe) == t_rl
    trainer = Trainer(EXS, cfg_l, t_l)
    assert trainer.learning_rate(WARMUP_ITERS) > t_l.lr  # the cosine is stretched, not cut
    assert trainer.learning_rate(WARMUP_LONG_ITERS) == pytest.approx(t_l.lr)
    # its 1:1 variant differs only after the warm-up, so a state at its end moves to it
    cfg_1, t_1 = recipe_configs("warmup_centred_long_r1", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_centred_long_r1"))
    assert cfg_1 == cfg_l and t_1.recon_early_iters == 0
    assert dataclasses.replace(t_1, recon_early_iters=R4_LONG_UNTIL, recipe=t_l.recipe) == t_l


def test_reconstruction_steps_per_iteration_follow_the_phases(tmp_path):
    """One step in the warm-up, ``recon_steps_early`` until ``recon_early_iters``, then one."""
    t = dataclasses.replace(_tcfg(tmp_path, 1), warmup_iters=3, recon_steps_early=4, recon_early_iters=6)
    assert [t.reconstruction_steps(it) for it in range(8)] == [1, 1, 1, 4, 4, 4, 1, 1]
    assert dataclasses.replace(t, recon_early_iters=2).reconstruction_steps(4) == 1
    late = dataclasses.replace(t, recon_steps_late=2, recon_late_from=7)  # a late phase after the early one
    assert [late.reconstruction_steps(it) for it in range(9)] == [1, 1, 1, 4, 4, 4, 1, 2, 2]
    with pytest.raises(DetailizeError, match="recon_steps_late"):
        dataclasses.replace(t, recon_steps_late=9)


def test_an_offsets_state_moves_into_two_reconstruction_steps_only_at_the_recipes_step(tmp_path, monkeypatch):
    from model.recipe_move import move_state_recipe
    from model.recipes import R2_FROM, recipe_configs

    name = "warmup_centred_long_r1_fill_mismatch_offsets"
    cfg_o, t_o = recipe_configs(name, _cfg(), _tcfg(tmp_path, 1, recipe=name))
    cfg_2, t_2 = recipe_configs(name + "_r2", _cfg(), _tcfg(tmp_path, 1, recipe=name + "_r2"))
    assert cfg_2 == cfg_o and dataclasses.replace(t_2, recon_steps_late=1, recon_late_from=0, recipe=name) == t_o
    res = train(EXS, cfg_o, dataclasses.replace(t_o, warmup_iters=0), resume=False)
    ck = load_checkpoint(res.checkpoint, training_state=True)
    for step, ok in ((R2_FROM - 1, True), (R2_FROM, True), (R2_FROM + 1, False)):
        state = dataclasses.replace(ck, training={**ck.training, "step": step})
        if ok:  # every iteration before the state's step took one reconstruction step under both: a move
            moved = move_state_recipe(state, name + "_r2")
            assert moved.training["recipe_moved_from"] == {"recipe": name, "step": step}
            assert moved.training["train_config"]["recon_steps_late"] == 2
            assert moved.training["train_config"]["recon_late_from"] == R2_FROM
        else:  # iteration R2_FROM took one step under the offsets recipe and would take two here
            with pytest.raises(ValueError, match="train differently"):
                move_state_recipe(state, name + "_r2")
    trainer = Trainer(EXS, cfg_2, dataclasses.replace(t_2, warmup_iters=0, recon_late_from=1))
    calls = []
    step = trainer.reconstruction_step
    monkeypatch.setattr(trainer, "reconstruction_step", lambda it, r: calls.append((it, r)) or step(it, r))
    trainer.iteration()
    trainer.iteration()
    assert calls == [(0, 0), (1, 0), (1, 1)]


def test_a_state_moves_to_a_longer_4_to_1_phase_only_before_the_phases_part(tmp_path):
    from model.recipe_move import move_state_recipe
    from model.recipes import R4_UNTIL, recipe_configs

    cfg_r, t_r = recipe_configs("warmup_centred_r4", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_centred_r4"))
    res = train(EXS, cfg_r, dataclasses.replace(t_r, warmup_iters=0), resume=False)
    ck = load_checkpoint(res.checkpoint, training_state=True)
    for step, ok in ((4000, True), (R4_UNTIL, True), (R4_UNTIL + 1, False)):
        state = dataclasses.replace(ck, training={**ck.training, "step": step})
        if ok:  # iterations < step took 4 reconstruction steps under both recipes
            moved = move_state_recipe(state, "warmup_centred_r4_long")
            assert moved.training["recipe"] == "warmup_centred_r4_long"
            assert moved.training["train_config"]["recon_early_iters"] == 20000
            assert moved.training["recipe_moved_from"] == {"recipe": "warmup_centred_r4", "step": step}
        else:  # iteration R4_UNTIL took 1 under warmup_centred_r4 and would take 4 under the long one
            with pytest.raises(ValueError, match="train differently"):
                move_state_recipe(state, "warmup_centred_r4_long")
    with pytest.raises(ValueError, match="train differently"):  # another warm-up is another history
        move_state_recipe(dataclasses.replace(ck, training={**ck.training, "step": 10}), "warmup_centred_long")
    long_ck = dataclasses.replace(ck, training={**ck.training, "recipe": "warmup_centred_long"})
    for step, ok in ((8000, True), (8001, False)):  # 1:1 from the warm-up's end: the same warm-up history
        state = dataclasses.replace(long_ck, training={**long_ck.training, "step": step})
        if ok:
            assert move_state_recipe(state, "warmup_centred_long_r1").training["train_config"]["recon_early_iters"] == 0
        else:
            with pytest.raises(ValueError, match="train differently"):
                move_state_recipe(state, "warmup_centred_long_r1")


def test_a_long_r1_state_branches_into_the_fill_floor_only_when_asked(tmp_path):
    from model.recipe_move import move_state_recipe
    from model.recipes import FILL_GAMMA, recipe_configs

    cfg_r, t_r = recipe_configs("warmup_centred_long_r1", _cfg(), _tcfg(tmp_path, 1, recipe="warmup_centred_long_r1"))
    res = train(EXS, cfg_r, dataclasses.replace(t_r, warmup_iters=0), resume=False)
    ck = load_checkpoint(res.checkpoint, training_state=True)
    state = dataclasses.replace(ck, training={**ck.training, "step": 10320})
    with pytest.raises(ValueError, match="train differently"):  # a loss change is not a move
        move_state_recipe(state, "warmup_centred_long_r1_fill")
    branched = move_state_recipe(state, "warmup_centred_long_r1_fill", branch=True)
    assert branched.config.losses.gamma_fill == FILL_GAMMA and ck.config.losses.gamma_fill == 0
    assert branched.training["recipe_branched_from"] == {"recipe": "warmup_centred_long_r1", "step": 10320}
    assert "recipe_moved_from" not in branched.training
    for k in ck.generator:
        assert torch.equal(ck.generator[k], branched.generator[k])
    with pytest.raises(ValueError, match="train differently"):  # branching does not cover another history
        move_state_recipe(state, "warmup_centred_r4", branch=True)


def test_extra_parts_counts_the_pieces_an_output_adds_to_its_input():
    from model.monitor import pieces

    grid = np.zeros((8, 8, 8), bool)
    grid[1:3, 1:3, 1:3] = True
    assert pieces(grid) == 1
    grid[4, 4, 4] = True  # touches nothing
    assert pieces(grid) == 2
    grid[3, 3, 3] = True  # diagonal neighbours join under 26-connectivity
    assert pieces(grid) == 1 and pieces(np.zeros((2, 2, 2), bool)) == 0
    cfg = dataclasses.replace(_cfg(), min_cell_fill=1.0)
    torch.manual_seed(0)
    fig = Monitor(EXS, cfg, _tcfg(Path("x"), 1).augment()).figures(Generator(cfg))
    assert fig["extra_parts"] == 0.0  # every occupied cell filled whole: the input's pieces exactly


def test_a_fill_state_branches_into_distillation_and_keeps_its_history(tmp_path):
    from model.recipe_move import move_state_recipe
    from model.recipes import DISTILL_FRAC, recipe_configs

    name = "warmup_centred_long_r1_fill"
    cfg_f, t_f = recipe_configs(name, _cfg(), _tcfg(tmp_path, 1, recipe=name))
    cfg_d, t_d = recipe_configs(name + "_distill", _cfg(), _tcfg(tmp_path, 1, recipe=name + "_distill"))
    assert cfg_d == cfg_f and t_f.distill_frac == 0 and t_d.distill_frac == DISTILL_FRAC
    assert dataclasses.replace(t_d, distill_frac=0.0, recipe=name) == t_f  # nothing else differs
    res = train(EXS, cfg_f, dataclasses.replace(t_f, warmup_iters=0), resume=False)
    ck = load_checkpoint(res.checkpoint, training_state=True)
    state = dataclasses.replace(ck, training={**ck.training, "step": 11750})
    with pytest.raises(ValueError, match="train differently"):  # other targets are a branch, not a move
        move_state_recipe(state, name + "_distill")
    branched = move_state_recipe(state, name + "_distill", branch=True)
    assert branched.training["train_config"]["distill_frac"] == DISTILL_FRAC
    assert branched.training["recipe_branched_from"] == {"recipe": name, "step": 11750}
    assert branched.config == ck.config
    # the recorded settings restore a trainer that draws distilled steps from the branch's step on
    recorded = dict(branched.training["train_config"], out_dir=str(tmp_path / "b"), betas=tuple(t_f.betas))
    trainer = Trainer(EXS, branched.config, TrainConfig(**recorded))
    assert trainer.teacher is not None
    with pytest.raises(ValueError, match="train differently"):  # and it does not reach back into other histories
        move_state_recipe(state, "distill", branch=True)


def test_a_fill_state_branches_into_the_mismatch_term_which_the_d_step_charges_and_logs(tmp_path):
    from model.recipe_move import move_state_recipe
    from model.recipes import MISMATCH_WEIGHT, recipe_configs

    name = "warmup_centred_long_r1_fill"
    cfg_f, t_f = recipe_configs(name, _cfg(), _tcfg(tmp_path, 1, recipe=name))
    cfg_m, _ = recipe_configs(name + "_mismatch", _cfg(), _tcfg(tmp_path, 1, recipe=name + "_mismatch"))
    assert cfg_f.losses.style_mismatch == 0 and cfg_m.losses.style_mismatch == MISMATCH_WEIGHT > 0
    assert dataclasses.replace(cfg_m, losses=cfg_f.losses) == cfg_f  # only the D term differs
    res = train(EXS, cfg_f, dataclasses.replace(t_f, warmup_iters=0), resume=False)
    ck = load_checkpoint(res.checkpoint, training_state=True)
    with pytest.raises(ValueError, match="train differently"):  # other losses are a branch, not a move
        move_state_recipe(ck, name + "_mismatch")
    branched = move_state_recipe(ck, name + "_mismatch", branch=True)
    assert branched.config.losses.style_mismatch == MISMATCH_WEIGHT
    assert ModelConfig.from_dict(branched.config.to_dict()) == branched.config  # the field round-trips
    recorded = dict(branched.training["train_config"], out_dir=str(tmp_path / "b"), betas=tuple(t_f.betas))
    trainer = Trainer(EXS, branched.config, TrainConfig(**recorded))
    losses = trainer.iteration()
    assert losses["d_mismatch"] > 0  # logged, and the other heads answer something on the real shape
    assert "d_mismatch" not in Trainer(EXS, cfg_f, dataclasses.replace(t_f, warmup_iters=0)).iteration()


def test_a_centred_state_branches_into_random_offsets_whose_samples_move_with_the_draw(tmp_path):
    from model.recipe_move import move_state_recipe
    from model.recipes import recipe_configs

    name = "warmup_centred_long_r1_fill_mismatch"
    cfg_c, t_c = recipe_configs(name, _cfg(), _tcfg(tmp_path, 1, recipe=name))
    cfg_o, t_o = recipe_configs(name + "_offsets", _cfg(), _tcfg(tmp_path, 1, recipe=name + "_offsets"))
    assert cfg_o == cfg_c and t_c.style_offset == "centre" and t_o.style_offset is None
    assert dataclasses.replace(t_o, style_offset="centre", recipe=name) == t_c  # nothing else differs
    res = train(EXS, cfg_c, dataclasses.replace(t_c, warmup_iters=0), resume=False)
    ck = load_checkpoint(res.checkpoint, training_state=True)
    with pytest.raises(ValueError, match="train differently"):  # other targets are a branch, not a move
        move_state_recipe(ck, name + "_offsets")
    branched = move_state_recipe(ck, name + "_offsets", branch=True)
    assert branched.config == ck.config and branched.generator.keys() == ck.generator.keys()
    assert branched.training["recipe_branched_from"] == {"recipe": name, "step": ck.training["step"]}
    assert branched.training["train_config"]["style_offset"] is None
    recorded = dict(branched.training["train_config"], out_dir=str(tmp_path / "b"), betas=tuple(t_c.betas))
    centred = Trainer(EXS, ck.config, dataclasses.replace(t_c, warmup_iters=0))
    trainer = Trainer(EXS, branched.config, TrainConfig(**recorded))
    assert trainer.aug.style_offset is None
    # centred: one placement whatever the draw; branched: the placement follows the draw
    fixed = [centred.style_sample(0, d).fine_labels for d in (0, 1, 2)]
    assert all(np.array_equal(fixed[0], f) for f in fixed[1:])
    moved = [trainer.style_sample(0, d).fine_labels for d in (0, 1, 2)]
    assert not all(m.shape == moved[0].shape and np.array_equal(moved[0], m) for m in moved[1:])
    assert trainer.iteration()["recon"] > 0
    with pytest.raises(ValueError, match="train differently"):  # and not from a recipe with another history
        move_state_recipe(ck, "warmup", branch=True)


def test_a_mismatch_state_branches_into_wider_discriminators_which_start_afresh(tmp_path):
    from model.recipe_move import move_state_recipe
    from model.recipes import WIDE_D_MULT, recipe_configs

    name = "warmup_centred_long_r1_fill_mismatch"
    cfg_m, t_m = recipe_configs(name, _cfg(), _tcfg(tmp_path, 1, recipe=name))
    cfg_w, _ = recipe_configs(name + "_wide_d", _cfg(), _tcfg(tmp_path, 1, recipe=name + "_wide_d"))
    assert dataclasses.replace(cfg_w, discriminators=cfg_m.discriminators) == cfg_m  # only the layout of D differs
    for dm, dw in zip(cfg_m.discriminators, cfg_w.discriminators):
        assert [x.width * WIDE_D_MULT for x in dm.layers] == [x.width for x in dw.layers]
        assert dw.receptive_field() == dm.receptive_field() and dw.stride() == dm.stride()
    res = train(EXS, cfg_m, dataclasses.replace(t_m, warmup_iters=0), resume=False)
    ck = load_checkpoint(res.checkpoint, training_state=True)
    with pytest.raises(ValueError, match="train differently"):  # another D is a branch, not a move
        move_state_recipe(ck, name + "_wide_d")
    rng = torch.get_rng_state()
    branched = move_state_recipe(ck, name + "_wide_d", branch=True)
    again = move_state_recipe(ck, name + "_wide_d", branch=True)
    assert torch.equal(rng, torch.get_rng_state())  # the fresh weights leave the global RNG alone
    assert branched.config == cfg_w  # the state's own (test-sized) layout, widened
    assert branched.training["discriminators_reset_at"] == 1
    assert branched.training["recipe_branched_from"] == {"recipe": name, "step": 1}
    for k, v in ck.generator.items():  # the generator and its optimizer are kept
        assert torch.equal(v, branched.generator[k])
    assert branched.optimizers["g"] is ck.optimizers["g"] and branched.optimizers["d"]["state"] == {}
    for k, v in branched.discriminators.items():  # new, wider weights, drawn the same way twice
        assert v.shape[0] == WIDE_D_MULT * ck.discriminators[k].shape[0] or v.shape[0] == cfg_w.n_styles + 1
        assert torch.equal(v, again.discriminators[k])
    # the branch restores into a trainer of the new layout and trains on
    from model.checkpoint import save_checkpoint
    out = tmp_path / "b"
    out.mkdir()
    save_checkpoint(out / "last.pt", branched)
    recorded = dict(branched.training["train_config"], out_dir=str(out), betas=tuple(t_m.betas))
    trainer = Trainer(EXS, branched.config, TrainConfig(**recorded))
    trainer.restore(out / "last.pt")
    assert trainer.step == 1 and trainer.iteration()["d_mismatch"] > 0
    wide_state = load_checkpoint(out / "last.pt", training_state=True)
    with pytest.raises(ValueError, match="changes the discriminators itself"):  # no way back to the narrow layout
        move_state_recipe(wide_state, name, branch=True)

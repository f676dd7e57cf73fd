"""The style classification terms: the bank of real crops, the softmax loss, and the trainer's D and G terms."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch

from model.checkpoint import load_checkpoint, save_checkpoint
from model.config import ModelConfig
from model.losses import assigned_styles, real_style_targets, style_classification_loss
from model.style_bank import StyleCropBank, surface_crop
from model.train import TrainConfig, Trainer, train
from core.errors import DetailizeError
from core.grid import ISO_LEVEL
from tests.model.test_train import EXS, _cfg, _tcfg

CLS = "warmup_centred_long_r1_fill_mismatch_offsets_cls"
BASE = "warmup_centred_long_r1_fill_mismatch_offsets"
CLSK = "warmup_centred_long_r1_fill_mismatch_offsets_clsk"


def _ball(n: int, centre, radius: float) -> torch.Tensor:
    idx = np.indices((n, n, n)).transpose(1, 2, 3, 0)
    return torch.from_numpy((np.linalg.norm(idx - np.array(centre), axis=-1) <= radius).astype(np.float32))[None, None]


def test_surface_crop_is_centred_on_a_surface_voxel_inside_the_grid():
    t = _ball(30, (15, 15, 15), 6.0)
    for seed in range(5):
        c = surface_crop(t, 8, np.random.default_rng(seed))
        assert c.shape == (1, 1, 8, 8, 8)
        centre = c[0, 0, 4, 4, 4] > ISO_LEVEL
        # a surface voxel is occupied with an empty 6-neighbour: the crop holds both sides of the surface
        assert (c > ISO_LEVEL).any() and (c <= ISO_LEVEL).any()
        assert centre or (c[0, 0, 3:6, 3:6, 3:6] > ISO_LEVEL).any()


def test_surface_crop_pads_short_axes_with_empty_space_and_centres_an_empty_grid():
    t = torch.ones(1, 1, 5, 12, 12)
    c = surface_crop(t, 8, np.random.default_rng(0))
    assert c.shape == (1, 1, 8, 8, 8)
    assert c[0, 0, 5:].sum() == 0 and c[0, 0, :5].sum() > 0  # the 5-voxel axis padded at its end
    empty = surface_crop(torch.zeros(1, 1, 20, 20, 20), 8, np.random.default_rng(0))
    assert empty.shape == (1, 1, 8, 8, 8) and empty.sum() == 0


def test_classification_loss_is_ln_n_at_chance_and_falls_when_the_right_head_leads():
    n, s = 4, (2, 3, 3)
    labels = torch.tensor([0, 2])
    target = real_style_targets(torch.zeros(2, n + 1, *s), labels)
    assert target.shape == (2, *s) and (target[0] == 0).all() and (target[1] == 2).all()
    chance = style_classification_loss(torch.zeros(2, n + 1, *s), target)
    assert chance.item() == pytest.approx(math.log(n))
    right = torch.zeros(2, n + 1, *s)
    right[0, 0], right[1, 2] = 8.0, 8.0
    assert style_classification_loss(right, target).item() < 0.01
    right[:, n] = -50.0  # the global channel is not a style: it does not enter
    assert style_classification_loss(right, target).item() < 0.01
    wrong = torch.zeros(2, n + 1, *s)
    wrong[:, 1] = 8.0
    assert style_classification_loss(wrong, target).item() > 7.0


def test_assigned_styles_weights_only_the_styled_voxels():
    mask = torch.zeros(1, 3, 2, 2, 2)
    mask[0, 2, 0] = 1.0  # style 2 on the first slab, nothing styled on the second
    target, weight = assigned_styles(mask)
    assert (target[0, 0] == 2).all() and (weight[0, 0] == 1).all() and (weight[0, 1] == 0).all()
    logits = torch.zeros(1, 4, 2, 2, 2)
    logits[0, 2, 0] = 9.0  # right where styled; the unstyled slab's (uniform) answer does not count
    assert style_classification_loss(logits, target, weight).item() < 0.01
    assert style_classification_loss(logits, target, torch.zeros_like(weight)).item() == 0.0


def test_the_bank_keeps_the_latest_window_per_style_and_cuts_crops_from_the_rng_it_is_given():
    bank = StyleCropBank(levels=(2, 3), edges=(8, 10), n_styles=3)
    assert not bank.ready()
    a, b = _ball(16, (8, 8, 8), 4.0), _ball(20, (10, 10, 10), 5.0)
    bank.put(2, {2: a, 3: b})
    assert not bank.ready()  # one style: nothing to tell apart
    bank.put(0, {2: a, 3: b})
    bank.put(2, {2: torch.zeros_like(a), 3: torch.zeros_like(b)})  # style 2 drawn again: replaced
    crops, styles = bank.batch(2, np.random.default_rng(0))
    assert bank.ready() and styles.tolist() == [0, 2] and crops.shape == (2, 1, 8, 8, 8)
    assert crops[0].sum() > 0 and crops[1].sum() == 0
    # the surface the bank keeps at put gives the cut surface_crop makes of the window alone
    assert torch.equal(crops[:1], surface_crop(a, 8, np.random.default_rng(0)))
    assert bank.batch(3, np.random.default_rng(0))[0].shape == (2, 1, 10, 10, 10)
    # the same RNG state cuts the same crops; other states cut elsewhere on the surface
    same = bank.batch(2, np.random.default_rng(0))[0]
    assert torch.equal(same, crops)
    others = [bank.batch(2, np.random.default_rng(seed))[0][0] for seed in range(1, 6)]
    assert any(not torch.equal(o, crops[0]) for o in others)


def test_config_refuses_a_classified_level_outside_the_pyramid_and_reads_old_files_as_off():
    cfg = _cfg()
    on = dataclasses.replace(cfg.losses, style_classifier=1.0, style_classifier_from=len(cfg.supervised_levels))
    with pytest.raises(DetailizeError, match="style_classifier_from"):  # a ModelConfig validates when made
        dataclasses.replace(cfg, losses=on)
    old = cfg.to_dict()
    for key in ("style_classifier", "style_classifier_g", "style_classifier_from", "style_classifier_crop",
                "style_classifier_d_steps"):
        old["losses"].pop(key)
    assert ModelConfig.from_dict(old) == cfg and cfg.losses.style_classifier == 0
    assert cfg.losses.style_classifier_d_steps == 1
    for steps in (0, 2.5):
        with pytest.raises(DetailizeError, match="style_classifier_d_steps"):
            dataclasses.replace(cfg, losses=dataclasses.replace(cfg.losses, style_classifier_d_steps=steps))


def test_an_offsets_state_branches_into_the_terms_which_train_d_and_g_and_resume_exactly(tmp_path):
    from model.recipe_move import move_state_recipe
    from model.recipes import CLS_D_WEIGHT, CLS_G_WEIGHT, recipe_configs

    cfg_o, t_o = recipe_configs(BASE, _cfg(), _tcfg(tmp_path, 2, recipe=BASE))
    t_o = dataclasses.replace(t_o, warmup_iters=0)  # adversarial iterations at once
    cfg_c, _ = recipe_configs(CLS, _cfg(), _tcfg(tmp_path, 2, recipe=CLS))
    assert cfg_c.losses.style_classifier == CLS_D_WEIGHT and cfg_c.losses.style_classifier_g == CLS_G_WEIGHT
    assert dataclasses.replace(cfg_c, losses=cfg_o.losses) == cfg_o  # only the losses differ
    res = train(EXS, cfg_o, t_o, resume=False)
    base_losses = Trainer(EXS, cfg_o, t_o).iteration()
    assert not {"d_cls", "g_cls"} & set(base_losses)  # off: nothing charged or logged
    branched = move_state_recipe(load_checkpoint(res.checkpoint, training_state=True), CLS, branch=True)
    recorded = dict(branched.training["train_config"], out_dir=str(tmp_path / "b"), betas=tuple(t_o.betas))
    tcfg = TrainConfig(**recorded)
    folder = tmp_path / "b"
    folder.mkdir()
    state = save_checkpoint(folder / "last.pt", branched)
    trainer = Trainer(EXS, branched.config, tcfg)
    trainer.restore(state)
    assert trainer.step == 2 and trainer.bank is not None
    assert trainer.bank.styles() == [0, 1]  # both styles' crops replayed from the iterations before the branch
    before = {j: trainer.bank.batch(j, np.random.default_rng(0))[0].clone() for j in trainer.bank.levels}
    d_before = [p.detach().clone() for p in trainer.discs.parameters()]
    losses = trainer.iteration()
    assert losses["d_cls"] > 0 and losses["g_cls"] > 0 and 0 <= losses["d_cls_acc"] <= 1
    assert any(not torch.equal(a, b) for a, b in zip(d_before, trainer.discs.parameters()))
    # the bank is a function of (seed, step): a trainer restored at the same step holds the same crops
    again = Trainer(EXS, branched.config, tcfg)
    again.restore(state)
    for j in again.bank.levels:
        assert torch.equal(again.bank.batch(j, np.random.default_rng(0))[0], before[j])
    # and after the iteration, the crops the uninterrupted trainer holds are those a restore at step 3 makes
    next_state = trainer.checkpoint()
    assert next_state.training["recipe_branched_from"] == {"recipe": BASE, "step": 2}  # the branch stays on record
    save_checkpoint(folder / "next.pt", next_state)
    third = Trainer(EXS, branched.config, tcfg)
    third.restore(folder / "next.pt")
    for j in third.bank.levels:
        assert torch.equal(third.bank.batch(j, np.random.default_rng(0))[0],
                           trainer.bank.batch(j, np.random.default_rng(0))[0])


def test_extra_classification_steps_move_d_further_and_log_the_mean_accuracy(tmp_path):
    """With ``style_classifier_d_steps`` k > 1 the iteration takes k − 1 more classification-only steps of D's
    optimizer: from one state, D's weights end further from where they were than with one step, and the same
    iteration run twice gives the same weights (the extra steps' crops are a function of (seed, step))."""
    from model.recipe_move import move_state_recipe
    from model.recipes import CLS_D_STEPS, recipe_configs

    cfg_o, t_o = recipe_configs(BASE, _cfg(), _tcfg(tmp_path, 2, recipe=BASE))
    t_o = dataclasses.replace(t_o, warmup_iters=0)
    res = train(EXS, cfg_o, t_o, resume=False)
    cfg_k, _ = recipe_configs(CLSK, _cfg(), _tcfg(tmp_path, 2, recipe=CLSK))
    assert cfg_k.losses.style_classifier_d_steps == CLS_D_STEPS > 1
    moved = {}
    for name in (CLS, CLSK, CLSK):
        branched = move_state_recipe(load_checkpoint(res.checkpoint, training_state=True), name, branch=True)
        tcfg = TrainConfig(**dict(branched.training["train_config"], out_dir=str(tmp_path / name),
                                  betas=tuple(t_o.betas)))
        trainer = Trainer(EXS, branched.config, tcfg)
        trainer.restore(save_checkpoint(tmp_path / f"{name}.pt", branched))
        d0 = torch.cat([p.detach().flatten().clone() for p in trainer.discs.parameters()])
        losses = trainer.iteration()
        d1 = torch.cat([p.detach().flatten() for p in trainer.discs.parameters()])
        assert 0 <= losses["d_cls_acc"] <= 1
        moved.setdefault(name, []).append(d1 - d0)
    assert torch.equal(moved[CLSK][0], moved[CLSK][1])  # deterministic
    assert moved[CLSK][0].norm() > 1.5 * moved[CLS][0].norm()

"""The no-pyramid layout (``ModelConfig.pyramid = False``; Table 4 (a), DECOR-GAN*): networks, losses,
checkpoints, windows, a 2-step training run of both named rows, and their inference."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from model.ablations import ablation_configs
from model.checkpoint import Checkpoint, load_checkpoint, save_checkpoint
from model.config import ModelConfig
from model.infer import DecollageDetailizer
from model.losses import down_loss, structure_losses, up_loss, whole_shape_prevs
from model.networks import Generator, build_discriminators, count_params
from model.train import TrainConfig, Trainer, train
from model.windows import blockwise_forward, window_forward
from core.errors import DetailizeError
from core.grid import EMPTY, LabeledGrid
from tests.model.test_train import EXS, PARTS, R


def _inputs(gen: Generator, shape, seed=0):
    g = torch.Generator().manual_seed(seed)
    occ = torch.rand(1, *shape, generator=g) > 0.3
    parts = torch.randint(0, gen.cfg.n_parts, (1, *shape), generator=g)
    styles = torch.randint(0, gen.cfg.n_styles, (1, *shape), generator=g)
    return gen.make_inputs(occ, parts, styles)


def _tiny(layout=ModelConfig.lean, pyramid=True) -> ModelConfig:
    cfg = layout(2, 3).scaled(0.125)
    return cfg if pyramid else cfg.without_pyramid()


# ----------------------------------------------------------------------------- config and networks


@pytest.mark.parametrize("layout", [ModelConfig.lean, ModelConfig.paper])
@pytest.mark.parametrize("shape", [(2, 2, 2), (3, 1, 2)])
def test_no_pyramid_generator_returns_only_the_x16_level(layout, shape):
    cfg = _tiny(layout, pyramid=False)
    assert cfg.supervised_levels == (3,) and cfg.factor == 16
    torch.manual_seed(0)
    gen = Generator(cfg)
    inputs = _inputs(gen, shape)
    outs = gen(*inputs)
    assert [tuple(o.shape) for o in outs] == [(1, 1, *(16 * n for n in shape))]
    assert torch.equal(gen(*inputs, final_only=True)[0], outs[0])
    # Intermediate levels have no side head; the rest of the generator is the pyramid's.
    heads = [name for name, _ in gen.named_parameters() if ".head." in name]
    assert all(name.startswith("levels.3.") for name in heads)
    full = Generator(_tiny(layout))
    head_params = sum(p.numel() for n, p in full.named_parameters() if ".head." in n and not n.startswith("levels.3."))
    assert count_params(gen) == count_params(full) - head_params


def test_no_pyramid_has_one_discriminator_the_last_levels():
    full, cfg = _tiny(), _tiny(pyramid=False)
    discs = build_discriminators(cfg)
    assert len(discs) == 1 and len(build_discriminators(full)) == 4
    assert cfg.discriminators == (full.discriminators[-1],) and cfg.discriminator(3) == full.discriminators[3]
    assert discs[0].spec.receptive_field() == 18
    out = discs[0](torch.rand(1, 1, 48, 32, 32))
    assert tuple(out.shape) == (1, 4, 16, 8, 8)  # N+1 heads at half resolution − 8


def test_no_pyramid_with_one_discriminator_per_level_is_refused():
    with pytest.raises(DetailizeError, match="discriminators for 1 supervised") as e:
        dataclasses.replace(_tiny(), pyramid=False)
    assert e.value.field == "discriminators"


def test_config_round_trip_and_old_configs_default_to_the_pyramid():
    cfg = _tiny(pyramid=False)
    assert cfg.to_dict()["pyramid"] is False and ModelConfig.from_dict(cfg.to_dict()) == cfg
    old = _tiny().to_dict()
    del old["pyramid"]  # a config written before the switch existed
    assert ModelConfig.from_dict(old) == _tiny()
    bad = cfg.to_dict()
    bad["pyramid"] = "no"
    with pytest.raises(DetailizeError) as e:
        ModelConfig.from_dict(bad)
    assert e.value.field == "config.pyramid"


# ----------------------------------------------------------------------------- losses


def test_structure_losses_compare_the_x16_output_with_the_coarse_input():
    coarse = torch.zeros(1, 1, 2, 2, 2)
    coarse[..., 0, :, :] = 1
    exact = torch.nn.functional.interpolate(coarse, scale_factor=16, mode="nearest")
    assert up_loss(exact, coarse, factor=16) == 0 and down_loss(exact, coarse, factor=16) == 0
    st = structure_losses([exact], whole_shape_prevs([exact], coarse), _tiny(pyramid=False).losses)
    assert st["down"] == 0 and st["up"] == 0
    empty = torch.zeros_like(exact)
    assert up_loss(empty, coarse, factor=16) == pytest.approx(0.5)
    assert down_loss(empty, coarse, factor=16) > 0  # occupied coarse cells left empty cost


# ----------------------------------------------------------------------------- windows and checkpoints


def test_window_and_blockwise_forward_match_the_dense_output():
    torch.manual_seed(1)
    gen = Generator(_tiny(pyramid=False))
    inputs = _inputs(gen, (3, 2, 4), seed=2)
    with torch.no_grad():
        dense = gen(*inputs)[0]
        win = (slice(1, 3), slice(0, 2), slice(1, 3))
        (part,) = window_forward(gen, *inputs, 2, win)
        assert torch.allclose(part, dense[:, :, 16:48, 0:32, 16:48], atol=1e-5)
        block = blockwise_forward(gen, *inputs, block_cells=2, skip_empty=False)
        assert torch.allclose(block, dense, atol=1e-5)


def test_checkpoint_round_trip_and_mismatched_pyramid_refused(tmp_path):
    cfg = _tiny(pyramid=False)
    torch.manual_seed(0)
    gen, discs = Generator(cfg), build_discriminators(cfg)
    ck = Checkpoint(config=cfg, style_names=("a", "b", "c"), part_names=PARTS, style_parts=(PARTS,) * 3,
                    generator=gen.state_dict(), training={"step": 1}, discriminators=discs.state_dict())
    p = save_checkpoint(tmp_path / "m.pt", ck)
    back = load_checkpoint(p, training_state=True)
    assert back.config == cfg and set(back.discriminators) == set(discs.state_dict())
    assert all(torch.equal(back.generator[k], v) for k, v in gen.state_dict().items())
    # The same weights under a pyramid config: heads and discriminators are missing.
    raw = torch.load(p, weights_only=True)
    meta = json.loads(raw["meta"])
    meta["config"] = _tiny().to_dict()
    raw["meta"] = json.dumps(meta)
    torch.save(raw, p)
    with pytest.raises(DetailizeError, match="missing"):
        load_checkpoint(p)


# ----------------------------------------------------------------------------- training and inference


@pytest.mark.parametrize("name", ["no_pyramid", "decor_gan"])
def test_two_step_training_of_the_no_pyramid_rows(tmp_path, name):
    base = TrainConfig(out_dir=str(tmp_path / name), steps=2, resolution=R, device="cpu", seed=3,
                       recon_steps_early=1, recon_early_iters=1, checkpoint_every=2, command="pytest", ablation=name)
    cfg, tcfg = ablation_configs(name, ModelConfig.lean(2, 2).scaled(0.125), base)
    assert not cfg.pyramid and tcfg.adaptive_alpha == (name == "no_pyramid")
    res = train(EXS, cfg, tcfg, resume=False)
    rows = [json.loads(line) for line in res.log.read_text().splitlines()]
    assert [r["step"] for r in rows] == [1, 2]
    for row in rows:
        assert all(np.isfinite(row[k]) for k in ("recon", "gan", "down", "up", "g_total", "d_total"))
        assert row["recon"] > 0 and row["d_total"] > 0
    ck = load_checkpoint(res.checkpoint, training_state=True)
    assert ck.config == cfg and ck.training["ablation"] == name and ck.training["train_config"]["ablation"] == name
    assert len(ck.discriminators) == len(build_discriminators(cfg).state_dict())
    # Resuming under another ablation is refused (its settings differ from the checkpoint's).
    other = "no_pyramid" if name == "decor_gan" else "decor_gan"
    ocfg, otcfg = ablation_configs(other, ModelConfig.lean(2, 2).scaled(0.125),
                                   dataclasses.replace(tcfg, steps=3, ablation=other))
    with pytest.raises(DetailizeError, match="another config"):
        train(EXS, ocfg, otcfg)
    with pytest.raises(DetailizeError, match="another config"):  # same configs, another row's name
        Trainer(EXS, cfg, dataclasses.replace(tcfg, ablation="no_adaptive_alpha")).restore(res.checkpoint)

    occ = np.zeros((2, 3, 2), dtype=bool)
    occ[:, :2] = True
    grid = LabeledGrid(occ, np.where(occ, 0, EMPTY).astype(np.int16), np.where(occ, 1, EMPTY).astype(np.int16),
                       PARTS, ("crate", "tower"), 1.0)
    fine = DecollageDetailizer(str(res.model), "cpu").detailize(grid)
    assert fine.shape == (32, 48, 32) and np.isfinite(fine.occupancy).all()


def test_unknown_ablation_name_is_refused(tmp_path):
    with pytest.raises(DetailizeError, match="unknown ablation") as e:
        TrainConfig(out_dir=str(tmp_path), steps=1, ablation="no_such_row")
    assert e.value.field == "ablation"

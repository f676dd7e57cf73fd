"""The style modulation of the generator's levels (``ModelConfig.style_modulation``, FiLM per coarse cell)
and the branch that grows a trained state into it (``model.recipe_move``)."""

from __future__ import annotations

import dataclasses

import pytest
import torch
from torch.nn import functional as F

from model.checkpoint import load_checkpoint, save_checkpoint
from model.config import ModelConfig
from model.networks import Generator, modulate_cells
from model.train import TrainConfig, Trainer, train
from model.windows import window_forward
from core.errors import DetailizeError
from tests.model.test_recipe import _inputs
from tests.model.test_train import EXS, _cfg, _tcfg

FILM = "warmup_centred_long_r1_fill_mismatch_film"
BASE = "warmup_centred_long_r1_fill_mismatch"


def _upsampled_film(y, gamma, beta):
    f = y.shape[2] // gamma.shape[2]
    up = lambda t: F.interpolate(t, scale_factor=f, mode="nearest")  # noqa: E731
    return y * (1 + up(gamma)) + up(beta)


@pytest.mark.parametrize("fmt", [torch.contiguous_format, torch.channels_last_3d])
def test_modulate_cells_is_film_with_the_blocks_broadcast_in_either_memory_format(fmt):
    g = torch.Generator().manual_seed(1)
    y = torch.randn(2, 3, 8, 4, 12, generator=g).contiguous(memory_format=fmt)
    gamma, beta = torch.randn(2, 3, 2, 1, 3, generator=g), torch.randn(2, 3, 2, 1, 3, generator=g)
    out = modulate_cells(y, gamma, beta)
    torch.testing.assert_close(out, _upsampled_film(y, gamma, beta))
    assert out.is_contiguous(memory_format=fmt)
    assert torch.equal(modulate_cells(y, torch.zeros_like(gamma), torch.zeros_like(beta)), y)
    with pytest.raises(DetailizeError, match="whole blocks"):
        modulate_cells(y[:, :, :7], gamma, beta)


def _pair(seed=0):
    """A concatenation-only generator and the modulated one holding the same weights (maps at their zero start)."""
    torch.manual_seed(seed)
    plain = Generator(_cfg())
    film = Generator(dataclasses.replace(_cfg(), style_modulation=True))
    missing, unexpected = film.load_state_dict(plain.state_dict(), strict=False)
    assert not unexpected and missing and all(k.startswith("style_films.") for k in missing)
    return plain, film


def test_zero_maps_give_the_concatenation_only_outputs_and_parameters_keep_their_order():
    plain, film = _pair()
    names = [n for n, _ in film.named_parameters()]
    assert names[: len(list(plain.parameters()))] == [n for n, _ in plain.named_parameters()]  # the maps come last
    assert Generator(_cfg()).style_films is None  # off: no new parameters, the layout of every old checkpoint
    ins = _inputs(plain, (5, 4, 6))
    with torch.no_grad():
        for a, b in zip(plain(*ins), film(*ins)):
            assert torch.equal(a, b)


def test_the_maps_scale_features_per_style_and_windows_still_equal_the_whole_shape():
    plain, film = _pair()
    with torch.no_grad():
        film.style_codes.normal_()  # trained codes are not zero (the lean layout starts them at zero)
        plain.style_codes.copy_(film.style_codes)
        for m in film.style_films:
            m.weight.normal_(0, 0.5)
            m.bias.normal_(0, 0.2)
    ins = _inputs(film, (6, 4, 5), seed=2)
    with torch.no_grad():
        whole = film(*ins)
        w = (slice(2, 6), slice(0, 4), slice(1, 5))
        for j, part in enumerate(window_forward(film, *ins, 2, w)):
            if j >= 2:  # the windowed levels: the output restricted to the window
                f = 2 ** (j + 1)
                torch.testing.assert_close(part, whole[j][..., 2 * f:6 * f, 0:4 * f, 1 * f:5 * f])
    with torch.no_grad():  # the same weights without the maps: another output
        unmodulated = plain(*ins)
    assert all((a - b).abs().max() > 1e-6 for a, b in zip(whole, unmodulated))
    loss = film(*ins)[-1].mean()
    loss.backward()
    assert all(m.weight.grad is not None and m.weight.grad.abs().sum() > 0 for m in film.style_films)
    assert film.style_codes.grad.abs().sum() > 0


def test_config_field_round_trips_and_old_configs_read_as_off():
    cfg = dataclasses.replace(_cfg(), style_modulation=True)
    assert ModelConfig.from_dict(cfg.to_dict()) == cfg
    old = _cfg().to_dict()
    del old["style_modulation"]
    assert ModelConfig.from_dict(old).style_modulation is False


def test_the_maps_learn_in_the_style_group(tmp_path):
    from model.recipes import recipe_configs

    cfg, t = recipe_configs(FILM, _cfg(), _tcfg(tmp_path, 1, recipe=FILM))
    assert cfg.style_modulation and t.style_lr_mult > 1
    trainer = Trainer(EXS, cfg, t)
    rest, style = trainer.opt_g.param_groups
    maps = {id(p) for p in trainer.gen.style_films.parameters()}
    assert {id(p) for p in style["params"]} == {id(trainer.gen.style_codes), *maps}
    assert not maps & {id(p) for p in rest["params"]} and style["lr_mult"] == t.style_lr_mult


def test_a_mismatch_state_grows_the_modulation_keeping_its_outputs_and_trains_on(tmp_path):
    from model.recipe_move import move_state_recipe
    from model.recipes import recipe_configs

    cfg_m, t_m = recipe_configs(BASE, _cfg(), _tcfg(tmp_path, 1, recipe=BASE))
    cfg_f, _ = recipe_configs(FILM, _cfg(), _tcfg(tmp_path, 1, recipe=FILM))
    assert dataclasses.replace(cfg_f, style_modulation=False) == cfg_m  # only the modulation differs
    res = train(EXS, cfg_m, dataclasses.replace(t_m, warmup_iters=0), resume=False)
    ck = load_checkpoint(res.checkpoint, training_state=True)
    with pytest.raises(ValueError, match="train differently"):  # a new layout is a branch, not a move
        move_state_recipe(ck, FILM)
    branched = move_state_recipe(ck, FILM, branch=True)
    assert branched.config == cfg_f and branched.training["generator_grown_at"] == 1
    assert branched.training["recipe_branched_from"] == {"recipe": BASE, "step": 1}
    for k, v in ck.generator.items():  # every weight kept; the maps added at zero
        assert torch.equal(v, branched.generator[k])
    new = [k for k in branched.generator if k not in ck.generator]
    assert new and all(k.startswith("style_films.") and not branched.generator[k].any() for k in new)
    old_g, new_g = ck.optimizers["g"], branched.optimizers["g"]
    assert new_g["state"] is old_g["state"]  # the generator's Adam moments are kept as they are
    assert new_g["param_groups"][0]["params"] == old_g["param_groups"][0]["params"]
    assert new_g["param_groups"][1]["params"][: len(old_g["param_groups"][1]["params"])] == \
        old_g["param_groups"][1]["params"]
    assert branched.discriminators is ck.discriminators and branched.optimizers["d"] is ck.optimizers["d"]
    # a state with a weight average grows it the same way (its own values kept, the maps at zero), and saves
    averaged = {k: v * 0.5 if v.is_floating_point() else v for k, v in ck.generator.items()}
    with_ema = move_state_recipe(dataclasses.replace(ck, generator_ema=averaged), FILM, branch=True)
    assert all(torch.equal(v, with_ema.generator_ema[k]) for k, v in averaged.items())
    assert all(not with_ema.generator_ema[k].any() for k in new)
    save_checkpoint(tmp_path / "grown_ema.pt", with_ema)

    old_gen, grown = Generator(ck.config), Generator(branched.config)
    old_gen.load_state_dict(ck.generator)
    grown.load_state_dict(branched.generator)
    ins = _inputs(old_gen, (5, 4, 5), seed=4)
    with torch.no_grad():  # the same outputs at the branch
        for a, b in zip(old_gen(*ins), grown(*ins)):
            assert torch.equal(a, b)

    out = tmp_path / "b"
    out.mkdir()
    save_checkpoint(out / "last.pt", branched)
    recorded = dict(branched.training["train_config"], out_dir=str(out), betas=tuple(t_m.betas))
    trainer = Trainer(EXS, branched.config, TrainConfig(**recorded))
    trainer.restore(out / "last.pt")  # the grown optimizer state fits the new trainer's groups
    assert trainer.step == 1
    trainer.iteration()
    assert any(m.weight.abs().sum() > 0 for m in trainer.gen.style_films)  # the maps leave zero
    save_checkpoint(out / "grown.pt", trainer.checkpoint())
    with pytest.raises(ValueError, match="turns off"):  # no way back: it would drop the learnt maps
        move_state_recipe(load_checkpoint(out / "grown.pt", training_state=True), BASE, branch=True)

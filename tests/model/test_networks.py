"""Generator / discriminator shapes, parameter counts, receptive fields, config round-trip."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from model.config import DiscLayer, DiscriminatorSpec, DownLoss, LevelSpec, ModelConfig, Upsampler
from model.networks import (
    Discriminator,
    Generator,
    build_discriminators,
    count_params,
    leaky_clamp,
    part_onehot,
    receptive_field,
    voxel_shuffle,
)
from core.errors import DetailizeError


def _inputs(gen: Generator, shape, seed=0, batch=1):
    g = torch.Generator().manual_seed(seed)
    occ = torch.rand(batch, *shape, generator=g) > 0.4
    parts = torch.randint(0, gen.cfg.n_parts, (batch, *shape), generator=g)
    styles = torch.randint(0, gen.cfg.n_styles, (batch, *shape), generator=g)
    return gen.make_inputs(occ, parts, styles)


def _tiny_lean(**kw) -> ModelConfig:
    return ModelConfig.lean(3, 4, **kw).scaled(0.125)


# ----------------------------------------------------------------------------- generator


@pytest.mark.parametrize("shape", [(2, 2, 2), (2, 3, 1), (1, 1, 1), (3, 2, 4)])
def test_lean_output_shapes_cubic_and_non_cubic(shape):
    torch.manual_seed(0)
    gen = Generator(_tiny_lean())
    outs = gen(*_inputs(gen, shape))
    assert [tuple(o.shape) for o in outs] == [(1, 1, *(n * 2**j for n in shape)) for j in (1, 2, 3, 4)]
    for o in outs:  # leaky clamp: [0, 1] up to the 0.002 slope
        assert o.min() > -0.1 and o.max() < 1.1


def test_paper_layout_forward_at_tiny_input():
    torch.manual_seed(0)
    gen = Generator(ModelConfig.paper(2, 3))
    with torch.inference_mode():
        outs = gen(*_inputs(gen, (2, 3, 2)))
    assert [tuple(o.shape) for o in outs] == [(1, 1, 4, 6, 4), (1, 1, 8, 12, 8), (1, 1, 16, 24, 16), (1, 1, 32, 48, 32)]


def test_batch_and_final_only_and_channels_last_agree():
    torch.manual_seed(0)
    gen = Generator(_tiny_lean())
    with torch.no_grad():  # non-zero codes so that styles matter
        gen.style_codes.normal_(std=0.3)
    inp = _inputs(gen, (2, 3, 2), batch=2)
    with torch.inference_mode():
        full = gen(*inp)
        last = gen(*inp, final_only=True)
        cl = gen.to(memory_format=torch.channels_last_3d)(*inp)
    assert len(last) == 1 and torch.equal(last[0], full[-1])
    for a, b in zip(full, cl):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-5)
    # batch items are independent: item 1 alone gives the same result
    with torch.inference_mode():
        single = gen(*(t[1:] for t in inp))
    torch.testing.assert_close(single[-1], full[-1][1:], rtol=1e-4, atol=1e-5)


def test_voxel_shuffle_layout():
    x = torch.arange(16.0).view(1, 16, 1, 1, 1)  # C = 2 output channels, 8 sub-voxels each
    y = voxel_shuffle(x)
    assert y.shape == (1, 2, 2, 2, 2)
    assert y[0, 0, 1, 0, 1] == 4 + 1  # channel 8c + 4a + 2b + d
    assert y[0, 1, 0, 1, 1] == 8 + 2 + 1


def test_leaky_clamp_values():
    x = torch.tensor([-1.0, 0.0, 0.25, 1.0, 3.0])
    expected = torch.tensor([-0.002, 0.0, 0.25, 1.0, 0.002 * 3 + 0.998])
    torch.testing.assert_close(leaky_clamp(x), expected)
    torch.testing.assert_close(leaky_clamp(x, 0.1), torch.tensor([-0.1, 0.0, 0.25, 1.0, 1.2]))


def test_style_codes_zero_init_and_gradient_reaches_used_codes_only():
    torch.manual_seed(0)
    gen = Generator(_tiny_lean())
    assert gen.style_codes.shape == (8, 4) and torch.count_nonzero(gen.style_codes) == 0
    occ = torch.ones(1, 2, 2, 2, dtype=torch.bool)
    parts = torch.zeros(1, 2, 2, 2, dtype=torch.long)
    styles = torch.tensor([0, 2]).repeat_interleave(4).view(1, 2, 2, 2)  # styles 0 and 2 used
    outs = gen(*gen.make_inputs(occ, parts, styles))
    sum(o.mean() for o in outs).backward()
    used = gen.style_codes.grad.abs().sum(0)
    assert used[0] > 0 and used[2] > 0
    assert used[1] == 0 and used[3] == 0


def test_style_field_is_codes_times_onehot():
    gen = Generator(_tiny_lean())
    with torch.no_grad():
        gen.style_codes.copy_(torch.arange(32.0).view(8, 4))
    idx = torch.tensor([[[0, 3], [1, 2]]])  # (D, H, W) = (1, 2, 2)
    z = gen.style_field(idx)
    onehot = torch.nn.functional.one_hot(idx, 4).float()  # (1, 2, 2, 4)
    expected = torch.einsum("zn,dhwn->zdhw", gen.style_codes, onehot)[None]
    torch.testing.assert_close(z, expected)


def test_without_part_labels_variant():
    cfg = dataclasses.replace(_tiny_lean(), use_part_labels=False)
    gen = Generator(cfg)
    assert gen.backbone[0].in_channels == 1 + 8
    assert gen.levels[0].up.in_channels == cfg.backbone_widths[-1] + 8
    occ, parts, z = _inputs(gen, (2, 2, 2))
    assert parts is None
    assert [tuple(o.shape[2:]) for o in gen(occ, None, z)][-1] == (32, 32, 32)


def test_part_onehot_is_masked_by_occupancy():
    labels = torch.tensor([[[[0, 1], [2, 1]]]])  # (1, 1, 2, 2)
    occ = torch.tensor([[[[1.0, 0.0], [1.0, 1.0]]]])[:, None]
    oh = part_onehot(labels, occ, 3)
    assert oh.shape == (1, 3, 1, 2, 2)
    assert oh[0, :, 0, 0, 1].sum() == 0  # empty voxel: no part
    assert oh[0, 2, 0, 1, 0] == 1 and oh[0, 1, 0, 1, 1] == 1


def test_invalid_inputs_raise_detailize_error():
    gen = Generator(_tiny_lean())
    occ, parts, z = _inputs(gen, (2, 2, 2))
    with pytest.raises(DetailizeError, match="part one-hot"):
        gen(occ, parts[:, :2], z)
    with pytest.raises(DetailizeError):
        gen(occ[:, 0], parts, z)
    with pytest.raises(DetailizeError, match="style indices"):
        gen.style_field(torch.full((2, 2, 2), -1))


def test_paper_parameter_counts_match_reference():
    cfg = ModelConfig.paper(5, 32)
    with torch.device("meta"):
        gen, discs = Generator(cfg), build_discriminators(cfg)
    assert count_params(gen) == pytest.approx(18.80e6, rel=0.02)
    assert count_params(gen.backbone) == pytest.approx(4.92e6, rel=0.02)
    assert count_params(discs) == pytest.approx(10.9e6, rel=0.02)
    for d, ref in zip(discs, (0.28e6, 1.17e6, 4.72e6, 4.72e6)):
        assert count_params(d) == pytest.approx(ref, rel=0.02)
    with torch.device("meta"):
        small = Generator(ModelConfig.paper(2, 16))
    assert count_params(small) == pytest.approx(18.70e6, rel=0.02)


def test_lean_is_small():
    with torch.device("meta"):
        gen = Generator(ModelConfig.lean(5, 32))
        discs = build_discriminators(ModelConfig.lean(5, 32))
    assert count_params(gen) < 1.5e6 and count_params(discs) < 0.3e6


# ----------------------------------------------------------------------------- discriminators


def _measured_rf(disc: Discriminator, n: int) -> tuple[int, list[int]]:
    """Back-propagate from one output voxel; return the gradient's extent and start per axis."""
    x = torch.zeros(1, 1, n, n, n, dtype=torch.float64, requires_grad=True)
    y = disc(x)
    o = [s // 2 for s in y.shape[2:]]
    y[0, -1, o[0], o[1], o[2]].backward()
    nz = torch.nonzero(x.grad[0, 0])
    lo, hi = nz.min(0).values, nz.max(0).values
    extents = (hi - lo + 1).tolist()
    assert len(set(extents)) == 1
    stride = disc.spec.stride()
    assert lo.tolist() == [oi * stride for oi in o]  # output o sees inputs [o·S, o·S + RF)
    return extents[0], o


@pytest.mark.parametrize("layout", ["paper", "lean"])
def test_receptive_fields_measured_by_gradients(layout):
    cfg = getattr(ModelConfig, layout)(2, 3).scaled(0.125 if layout == "paper" else 0.5)
    torch.manual_seed(0)
    discs = build_discriminators(cfg).double()
    measured = [_measured_rf(d, n)[0] for d, n in zip(discs, (15, 17, 36, 36))]
    assert measured == [7, 9, 18, 18]
    assert [receptive_field(d) for d in discs] == measured
    assert [receptive_field(s) for s in cfg.discriminators] == measured


def test_discriminator_output_shapes_and_range():
    cfg = ModelConfig.paper(2, 3).scaled(0.125)
    discs = build_discriminators(cfg)
    sizes = [(10, 12, 14), (20, 24, 28), (40, 48, 56), (80, 96, 112)]
    expected = [(4, 6, 8), (12, 16, 20), (12, 16, 20), (32, 40, 48)]  # n−6, n−8, n/2−8, n/2−8
    for d, s, e in zip(discs, sizes, expected):
        out = d(torch.rand(1, 1, *s))
        assert tuple(out.shape) == (1, 4, *e)
        assert tuple(d.spec.output_size(n) for n in s) == e
        assert 0 < out.min() and out.max() < 1


# ----------------------------------------------------------------------------- config


@pytest.mark.parametrize("layout", ["lean", "paper"])
def test_config_json_round_trip(layout):
    cfg = getattr(ModelConfig, layout)(5, 32)
    data = json.loads(json.dumps(cfg.to_dict()))
    assert data["levels"][0]["upsampler"] == "conv_transpose"
    assert ModelConfig.from_dict(data) == cfg
    variant = dataclasses.replace(cfg, losses=dataclasses.replace(cfg.losses, down_loss=DownLoss.PAPER_MSE))
    assert ModelConfig.from_dict(variant.to_dict()).losses.down_loss is DownLoss.PAPER_MSE


def test_config_defaults_follow_method():
    cfg = ModelConfig.lean(5, 32)
    lc = cfg.losses
    assert (lc.beta_recon, lc.gamma_down, lc.gamma_up, lc.alpha_joint, lc.alpha_other) == (10, 10, 10, 0.1, 0.5)
    assert lc.stop_gradient is True and cfg.leaky_slope == 0.02 and cfg.clamp_slope == 0.002
    assert cfg.factor == 16 and cfg.style_dim == 8
    assert cfg.levels[-1].upsampler is Upsampler.VOXEL_SHUFFLE and cfg.levels[-1].head_kernel == 0
    assert all(lv.upsampler is Upsampler.CONV_TRANSPOSE for lv in ModelConfig.paper(5, 32).levels)


@pytest.mark.parametrize(
    "mutate, field",
    [
        (lambda d: d.update(n_styles=0), "config.n_styles"),
        (lambda d: d.update(extra=1), "config.extra"),
        (lambda d: d.pop("levels"), "config.levels"),
        (lambda d: d["levels"][1].update(upsampler="bicubic"), "config.levels[1].upsampler"),
        (lambda d: d["levels"][1].update(width="32"), "config.levels[1].width"),
        (lambda d: d["levels"][0].update(head_kernel=0), "config.levels[0].head_kernel"),
        (lambda d: d["losses"].update(down_loss="l1"), "config.losses.down_loss"),
        (lambda d: d["discriminators"].pop(), "config.discriminators"),
        (lambda d: d["discriminators"][0]["layers"][0].update(kernel=4), "config.discriminators[0]"),
    ],
)
def test_config_from_dict_rejects_bad_input(mutate, field):
    data = ModelConfig.lean(5, 32).to_dict()
    mutate(data)
    with pytest.raises(DetailizeError) as err:
        ModelConfig.from_dict(data)
    assert err.value.field == field and err.value.hint


def test_discriminator_spec_geometry():
    rf18 = DiscriminatorSpec((DiscLayer(8, 4), DiscLayer(8, 3, 2), DiscLayer(8), DiscLayer(8), DiscLayer(8)))
    assert (rf18.receptive_field(), rf18.stride(), rf18.mask_offset()) == (18, 2, 4)
    assert rf18.output_size(64) == 64 // 2 - 8 and rf18.output_size(5) == 0
    assert np.array_equal([rf18.output_size(n) for n in (36, 37)], [10, 10])
    level = LevelSpec(8)
    assert level.n_convs == 1 and level.head_kernel == 3


def test_last_hidden_puts_a_nonlinearity_before_the_last_level():
    base = _tiny_lean()
    cfg = dataclasses.replace(base, last_hidden=16)
    torch.manual_seed(0)
    lin, deep = Generator(base), Generator(cfg)
    last_lin, last_deep = lin.levels[-1], deep.levels[-1]
    # default: one linear 3³ conv to the 8 sub-voxels; with last_hidden: 3³ conv to H, then a 1³ conv
    assert last_lin.pre is None and last_lin.up.kernel_size == (3, 3, 3) and last_lin.up.out_channels == 8
    assert last_deep.pre.out_channels == 16 and last_deep.pre.kernel_size == (3, 3, 3)
    assert last_deep.up.in_channels == 16 and last_deep.up.kernel_size == (1, 1, 1) and last_deep.up.out_channels == 8
    assert all(a.pre is None for a in deep.levels[:-1])  # only the last level changes
    assert count_params(deep) > count_params(lin)
    # same output shapes; the level is no longer linear: negating its input does not negate its output
    inp = _inputs(deep, (2, 3, 2))
    outs = deep(*inp)
    assert [o.shape for o in outs] == [o.shape for o in lin(*_inputs(lin, (2, 3, 2)))]
    x = torch.randn(1, last_deep.pre.in_channels, 2, 2, 2)
    with torch.no_grad():
        for level in (last_lin, last_deep):
            level.up.bias.zero_()
            if level.pre is not None:
                level.pre.bias.zero_()
        assert torch.allclose(last_lin(x)[1], -last_lin(-x)[1], atol=1e-6)
        assert not torch.allclose(last_deep(x)[1], -last_deep(-x)[1], atol=1e-3)
    # JSON round trip; old checkpoints (no key) read as 0; refused on a layout without a shuffle last level
    assert ModelConfig.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg
    old = base.to_dict()
    old.pop("last_hidden")
    assert ModelConfig.from_dict(old) == base and base.last_hidden == 0
    with pytest.raises(DetailizeError, match="last_hidden"):
        ModelConfig.paper(2, 3, last_hidden=8)
    with pytest.raises(DetailizeError, match="last_hidden"):
        dataclasses.replace(base, last_hidden=-1)

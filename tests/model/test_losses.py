"""Losses on hand-made grids with known values; stop-gradient; the D fake-mask assignment fix."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from model.config import DownLoss, ModelConfig
from model.losses import (
    discriminator_loss,
    discriminator_loss_levels,
    down_loss,
    fill_floor_loss,
    generator_adversarial_loss,
    generator_gan_loss,
    reconstruction_loss,
    structure_losses,
    up_loss,
    whole_shape_alphas,
    whole_shape_masks,
    whole_shape_prevs,
)
from model.masks import DOutputMasks, StyledCoarse, align_to_d_output
from core.errors import DetailizeError


def test_reconstruction_constant_error_gives_beta_e_squared_per_level():
    outs = [torch.full((1, 1, 2, 2, 2), 0.5), torch.full((1, 1, 4, 4, 4), 0.5)]
    targets = [o - 0.2 for o in outs]
    loss = reconstruction_loss(outs, targets, beta=10.0)
    assert loss["level0"].item() == pytest.approx(0.04)
    assert loss["total"].item() == pytest.approx(10 * 0.04 * 2)
    with pytest.raises(DetailizeError):
        reconstruction_loss(outs, targets[:1])


def _masks(n_styles=2, shape=(2, 2, 2)):
    style = torch.zeros(n_styles, *shape)
    style[1, 0] = 1  # style 1 on the x = 0 half (4 voxels)
    glob = torch.zeros(1, *shape)
    glob[0, 0] = 1
    return style, glob


def test_generator_gan_loss_known_values():
    style, glob = _masks()
    perfect = torch.ones(1, 3, 2, 2, 2)
    assert generator_gan_loss(perfect, style, glob, 0.5)["total"].item() == 0.0
    d = torch.full((1, 3, 2, 2, 2), 0.5)
    d[:, :, 1] = 0.0  # outside the masks: must not count
    terms = generator_gan_loss(d, style, glob, 0.5)
    # per masked voxel: α·(0.5−1)² + (0.5−1)² = 0.125 + 0.25, normalised by 4 masked voxels
    assert terms["style"].item() == pytest.approx(0.125)
    assert terms["global"].item() == pytest.approx(0.25)
    assert terms["total"].item() == pytest.approx(0.375)
    alpha = torch.full((1, 2, 2, 2), 0.5)
    alpha[0, 0, 0] = 0.1  # two joint voxels among the four
    assert generator_gan_loss(d, style, glob, alpha)["style"].item() == pytest.approx((2 * 0.1 + 2 * 0.5) * 0.25 / 4)


def test_generator_gan_loss_normalises_per_sample_and_handles_empty_masks():
    style, glob = _masks()
    d = torch.full((2, 3, 2, 2, 2), 0.5)
    batch_style = torch.stack([style, style * 0])
    batch_glob = torch.stack([glob, glob * 0])
    terms = generator_gan_loss(d, batch_style, batch_glob, 0.5)
    assert torch.isfinite(terms["total"]) and terms["total"].item() == pytest.approx(0.375 / 2)


def test_discriminator_loss_known_values():
    style, glob = _masks()
    m = DOutputMasks(style, glob)
    real_perfect = torch.ones(1, 3, 2, 2, 2)
    fake_perfect = torch.zeros(1, 3, 2, 2, 2)
    assert discriminator_loss(real_perfect, fake_perfect, m, m)["total"].item() == 0.0
    d = torch.full((1, 3, 2, 2, 2), 0.25)
    terms = discriminator_loss(d, d, m, m)
    assert terms["real"].item() == pytest.approx(2 * 0.75**2)  # style-1 head + global head, per masked voxel
    assert terms["fake"].item() == pytest.approx(2 * 0.25**2)


def test_discriminator_mismatch_charges_only_the_other_style_heads_on_the_real_shape():
    style, glob = _masks(n_styles=3)  # the real shape is style 1 on the x = 0 half
    m = DOutputMasks(style, glob)
    d = torch.zeros(1, 4, 2, 2, 2)
    d[:, 0, 0] = 0.5  # style-0 head says 0.5 on the real shape
    d[:, 2, 1] = 0.9  # style-2 head says 0.9 only off the shape: not charged
    d[:, 1], d[:, 3] = 1.0, 1.0  # own head and global head: real and perfect
    terms = discriminator_loss(d, torch.zeros_like(d), m, m, mismatch=2.0)
    assert terms["real"].item() == pytest.approx(0.0)
    assert terms["mismatch"].item() == pytest.approx(0.5**2 / 2)  # mean over the 2 other heads, per masked voxel
    assert terms["total"].item() == pytest.approx(2.0 * 0.5**2 / 2 + terms["fake"].item())
    assert discriminator_loss(d, torch.zeros_like(d), m, m)["total"].item() == pytest.approx(terms["fake"].item())


def test_down_loss_code_hinge_zeroing_conditions():
    coarse = torch.tensor([1.0, 1.0, 0.0, 0.0]).view(1, 1, 4, 1, 1)
    fine = torch.zeros(1, 1, 8, 2, 2)
    fine[:, :, 0:2] = 0.5  # on, max 0.5 ≤ 0.6: (1 − 0.5)² = 0.25
    fine[:, :, 2:4] = 0.0
    fine[:, :, 2, 0, 0] = 0.8  # on, max 0.8 > 0.6: zeroed
    fine[:, :, 4:6] = 0.5  # off, max 0.5 ≥ 0.4: 0.5² = 0.25
    fine[:, :, 6:8] = 0.3  # off, max 0.3 < 0.4: zeroed
    loss = down_loss(fine, coarse, DownLoss.CODE_HINGE)
    assert loss.item() == pytest.approx((0.25 + 0 + 0.25 + 0) / 4)


def test_down_loss_paper_mse_and_up_loss_known_values():
    coarse = torch.tensor([1.0, 0.0]).view(1, 1, 2, 1, 1)
    fine = torch.zeros(1, 1, 4, 2, 2)
    fine[:, :, 0, 0, 0] = 0.9  # max-pool of cell 0 = 0.9 → (0.9 − 1)²
    fine[:, :, 3, 1, 1] = 0.2  # max-pool of cell 1 = 0.2 → 0.2²
    assert down_loss(fine, coarse, DownLoss.PAPER_MSE).item() == pytest.approx((0.01 + 0.04) / 2)
    # up: cell 0 upsampled is 1 everywhere in its 8 voxels: 7·1² + 0.1²; cell 1 is 0: 0.2²
    assert up_loss(fine, coarse).item() == pytest.approx((7 + 0.01 + 0.04) / 16)


@pytest.mark.parametrize("variant", [DownLoss.PAPER_MSE, DownLoss.CODE_HINGE])
@pytest.mark.parametrize("stop_gradient", [True, False])
def test_stop_gradient_blocks_the_coarse_level(variant, stop_gradient):
    g = torch.Generator().manual_seed(0)
    coarse = torch.rand(1, 1, 2, 2, 2, generator=g, requires_grad=True)
    fine = torch.rand(1, 1, 4, 4, 4, generator=g, requires_grad=True)
    (down_loss(fine, coarse, variant, stop_gradient) + up_loss(fine, coarse, stop_gradient)).backward()
    assert fine.grad is not None and fine.grad.abs().sum() > 0
    if stop_gradient:
        assert coarse.grad is None
    else:
        assert coarse.grad is not None and coarse.grad.abs().sum() > 0
    coarse.grad = None  # the hinge reads the coarse level only through a comparison
    down_loss(fine, coarse, DownLoss.CODE_HINGE, stop_gradient=False).backward()
    assert coarse.grad is None or coarse.grad.abs().sum() == 0


def test_structure_losses_cover_every_level_including_the_input():
    cfg = ModelConfig.lean(1, 1)
    x = torch.ones(1, 1, 1, 1, 1)
    outs = [torch.ones(1, 1, 2, 2, 2), torch.ones(1, 1, 4, 4, 4) * 0.5]
    st = structure_losses(outs, whole_shape_prevs(outs, x), dataclasses.replace(cfg.losses, down_loss=DownLoss.PAPER_MSE))
    assert st["down0"].item() == 0 and st["up0"].item() == 0
    assert st["down1"].item() == pytest.approx(0.25) and st["up1"].item() == pytest.approx(0.25)
    assert st["total"].item() == pytest.approx(10 * 0.25 + 10 * 0.25)


# ----------------------------------------------------------------------------- all levels


def _two_part_content():
    occ = np.ones((4, 4, 4), bool)
    labels = np.zeros((4, 4, 4), np.int64)
    labels[2:] = 1
    return occ, labels


def _d_outputs(cfg, coarse_shape, values):
    """Constant per-channel discriminator outputs of the right shape at every level."""
    outs = []
    for j, spec in enumerate(cfg.discriminators):
        shape = tuple(spec.output_size(n * 2 ** (j + 1)) for n in coarse_shape)
        outs.append(torch.tensor(values, dtype=torch.float32).view(1, -1, 1, 1, 1).expand(1, -1, *shape).clone())
    return outs


def test_discriminator_fake_masks_use_the_true_assignment_at_every_level():
    """With the reference bug (assignment replaced by the real style after level 0) this fails at levels 1–3."""
    cfg = ModelConfig.paper(2, 3)
    occ, labels = _two_part_content()
    fake = StyledCoarse(occ, labels, (0, 1))
    real = StyledCoarse.single_style(occ, 2)
    values = [0.1, 0.2, 0.3, 0.4]  # style heads 0, 1, 2 and global
    d_fake = _d_outputs(cfg, occ.shape, values)
    d_real = _d_outputs(cfg, occ.shape, [1.0, 1.0, 1.0, 1.0])
    loss = discriminator_loss_levels(d_real, d_fake, whole_shape_masks(d_real, real, cfg),
                                     whole_shape_masks(d_fake, fake, cfg), cfg)
    for j, spec in enumerate(cfg.discriminators):
        shape = tuple(d_fake[j].shape[2:])
        n0 = align_to_d_output((labels == 0) & occ, j, spec, shape).sum().item()
        n1 = align_to_d_output((labels == 1) & occ, j, spec, shape).sum().item()
        assert n0 > 0 and n1 > 0
        ng = n0 + n1
        correct = (n0 * 0.1**2 + n1 * 0.2**2 + ng * 0.4**2) / ng
        buggy = 0.3**2 + 0.4**2  # every fake part credited to the real style's channel
        assert loss[f"fake{j}"].item() == pytest.approx(correct)
        assert abs(correct - buggy) > 1e-3
        assert loss[f"real{j}"].item() == 0.0
    assert loss["total"].item() == pytest.approx(sum(loss[f"fake{j}"].item() for j in range(4)))


def test_generator_adversarial_loss_combines_gan_and_structure_terms():
    cfg = ModelConfig.paper(2, 3)
    occ, labels = _two_part_content()
    fake = StyledCoarse(occ, labels, (0, 1))
    coarse = torch.ones(1, 1, 4, 4, 4)
    outputs = [torch.ones(1, 1, *(n * 2 ** (j + 1) for n in occ.shape)) for j in range(4)]
    perfect = _d_outputs(cfg, occ.shape, [1.0, 1.0, 1.0, 1.0])
    prevs = whole_shape_prevs(outputs, coarse)
    loss = generator_adversarial_loss(perfect, outputs, prevs, whole_shape_masks(perfect, fake, cfg), None, cfg)
    assert loss["gan"].item() == 0 and loss["down"].item() == 0 and loss["total"].item() == 0
    half = _d_outputs(cfg, occ.shape, [0.5, 0.5, 0.5, 0.5])
    half_masks = whole_shape_masks(half, fake, cfg)
    uniform = generator_adversarial_loss(half, outputs, prevs, half_masks, None, cfg)
    assert uniform["gan0"].item() == pytest.approx(0.5 * 0.25 + 0.25)  # α_other = 0.5 everywhere
    joint_everywhere = torch.full((4, 4, 4), 0.1)
    adaptive = generator_adversarial_loss(half, outputs, prevs, half_masks,
                                          whole_shape_alphas(half, [joint_everywhere], cfg), cfg)
    assert adaptive["gan3"].item() == pytest.approx(0.1 * 0.25 + 0.25)


def test_fill_floor_charges_only_occupied_cells_below_the_floor():
    occ = torch.zeros(1, 1, 2, 1, 1)
    occ[0, 0, 0] = 1  # cell 0 occupied, cell 1 empty
    out = torch.zeros(1, 1, 4, 2, 2)  # factor 2
    out[0, 0, :2, :, :1] = 1.0  # cell 0 half full; cell 1 empty (not charged)
    assert fill_floor_loss([out], [occ], 0.5).item() == pytest.approx(0.0)
    assert fill_floor_loss([out], [occ], 0.75).item() == pytest.approx(0.25**2)
    out[0, 0, 2:] = 1.0  # filling the empty cell changes nothing
    assert fill_floor_loss([out], [occ], 0.75).item() == pytest.approx(0.25**2)
    empty = torch.zeros(1, 1, 4, 2, 2, requires_grad=True)  # an eroded cell: (0.5 − 0)² per level, summed
    loss = fill_floor_loss([empty, empty], [occ, occ], 0.5)
    assert loss.item() == pytest.approx(2 * 0.25)
    loss.backward()
    assert (empty.grad[0, 0, :2] < 0).all() and (empty.grad[0, 0, 2:] == 0).all()  # pushes only the occupied cell up
    assert fill_floor_loss([out], [torch.zeros_like(occ)], 0.5).item() == 0
    big = torch.ones(1, 1, 4, 1, 1)  # four occupied cells, one of them eroded: the full deficit, not a quarter of it
    wide = torch.ones(1, 1, 8, 2, 2)
    wide[0, 0, :2] = 0
    assert fill_floor_loss([wide], [big], 0.5).item() == pytest.approx(0.25)


def test_generator_adversarial_loss_adds_the_fill_floor_when_weighted():
    cfg = ModelConfig.paper(2, 3)
    occ, labels = _two_part_content()
    fake = StyledCoarse(occ, labels, (0, 1))
    coarse = torch.ones(1, 1, 4, 4, 4)
    outputs = [torch.full((1, 1, *(n * 2 ** (j + 1) for n in occ.shape)), 0.3) for j in range(4)]
    d = _d_outputs(cfg, occ.shape, [1.0, 1.0, 1.0, 1.0])
    args = (d, outputs, whole_shape_prevs(outputs, coarse), whole_shape_masks(d, fake, cfg), None)
    off = generator_adversarial_loss(*args, cfg)
    assert off["fill"].item() == 0
    on_cfg = dataclasses.replace(cfg, losses=dataclasses.replace(cfg.losses, gamma_fill=10.0, fill_floor=0.5))
    on = generator_adversarial_loss(*args, on_cfg, [coarse] * 4)
    assert on["fill"].item() == pytest.approx(4 * 0.2**2, rel=1e-5)
    assert on["total"].item() == pytest.approx(off["total"].item() + 10 * 4 * 0.2**2, rel=1e-5)
    with pytest.raises(DetailizeError, match="coarse input"):
        generator_adversarial_loss(*args, on_cfg)


def test_one_adversarial_step_end_to_end_on_a_tiny_lean_model():
    """Generator → discriminators → masked losses → gradients, as the training loop will chain them."""
    from model.masks import alpha_map, coarse_occupancy, coarse_part_labels, joint_mask
    from model.networks import Generator, build_discriminators

    torch.manual_seed(0)
    cfg = ModelConfig.lean(2, 3).scaled(0.125)
    gen, discs = Generator(cfg), build_discriminators(cfg)
    fine = np.full((64, 64, 64), -1)  # 4³ coarse cells at factor 16
    fine[8:56, 4:32, 8:56] = 0
    fine[8:56, 32:60, 20:44] = 1
    labels = coarse_part_labels(fine, 16, n_parts=2)
    occ = coarse_occupancy(fine != -1, 16)
    fake = StyledCoarse(occ, labels, (0, 2))
    style = np.asarray(fake.assignment)[labels]
    inputs = gen.make_inputs(torch.as_tensor(occ)[None], torch.as_tensor(labels)[None].long(), torch.as_tensor(style)[None])
    outputs = gen(*inputs)
    d_fake = [d(o) for d, o in zip(discs, outputs)]
    alpha = alpha_map(joint_mask(fine, 16, 2))
    loss = generator_adversarial_loss(d_fake, outputs, whole_shape_prevs(outputs, inputs[0]),
                                      whole_shape_masks(d_fake, fake, cfg), whole_shape_alphas(d_fake, alpha, cfg), cfg)
    assert torch.isfinite(loss["total"]) and loss["gan"] > 0
    loss["total"].backward()
    assert gen.style_codes.grad[:, 0].abs().sum() > 0 and gen.style_codes.grad[:, 2].abs().sum() > 0
    assert gen.style_codes.grad[:, 1].abs().sum() == 0
    d_real = [d(o.detach()) for d, o in zip(discs, outputs)]  # stand-in real shape: the same grids
    d_fake_detached = [d(o.detach()) for d, o in zip(discs, outputs)]
    d_loss = discriminator_loss_levels(d_real, d_fake_detached,
                                       whole_shape_masks(d_real, StyledCoarse.single_style(fake.occupancy, 1), cfg),
                                       whole_shape_masks(d_fake_detached, fake, cfg), cfg)
    d_loss["total"].backward()
    assert all(p.grad is not None for p in discs.parameters())


def test_gan_level_weights_scale_each_levels_gan_term_and_are_checked():
    cfg = ModelConfig.paper(2, 3)
    occ, labels = _two_part_content()
    fake = StyledCoarse(occ, labels, (0, 1))
    outputs = [torch.ones(1, 1, *(n * 2 ** (j + 1) for n in occ.shape)) for j in range(4)]
    half = _d_outputs(cfg, occ.shape, [0.5, 0.5, 0.5, 0.5])
    prevs = whole_shape_prevs(outputs, torch.ones(1, 1, 4, 4, 4))
    args = (half, outputs, prevs, whole_shape_masks(half, fake, cfg), None)
    plain = generator_adversarial_loss(*args, cfg)
    factors = (1.0, 0.0, 0.25, 2.0)
    weighted_cfg = dataclasses.replace(cfg, losses=dataclasses.replace(cfg.losses, gan_level_weights=factors))
    weighted = generator_adversarial_loss(*args, weighted_cfg)
    per_level = [plain[f"gan{j}"].item() for j in cfg.supervised_levels]
    assert min(per_level) > 0  # every level charged, so a factor of 0 or 2 shows
    assert weighted["gan"].item() == pytest.approx(sum(f * g for f, g in zip(factors, per_level)))
    rest = plain["total"].item() - plain["gan"].item()  # the structure terms are not weighted
    assert weighted["total"].item() - weighted["gan"].item() == pytest.approx(rest)
    assert ModelConfig.from_dict(weighted_cfg.to_dict()) == weighted_cfg
    old = cfg.to_dict()
    old["losses"].pop("gan_level_weights")  # a file from before the factors reads as 1 at every level
    assert ModelConfig.from_dict(old).losses.gan_level_weights == ()
    for bad_factors in ((1.0, 1.0), (1.0, -0.5, 1.0, 1.0)):
        with pytest.raises(DetailizeError, match="gan_level_weights"):
            dataclasses.replace(cfg, losses=dataclasses.replace(cfg.losses, gan_level_weights=bad_factors))

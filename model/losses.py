"""DECOLLAGE losses as pure functions returning named tensors (method.md §3, paper Eq. 1–6).

Every function returns ``dict[str, Tensor]`` with a ``"total"`` entry (what to
back-propagate) plus named, un-weighted parts for logging. Shapes: occupancy
grids are (B, 1, X, Y, Z); a discriminator output is (B, N+1, *S) with the style
heads first and the global head last; masks are (B, N, *S) / (B, 1, *S) or the
same without the batch dimension (broadcast over the batch).

Masked losses are normalised per sample by the global-mask sum (the reference,
batch 1) and averaged over the batch; an empty mask gives 0, not NaN.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor
from torch.nn import functional as F

from model.config import DownLoss, LossConfig, ModelConfig
from model.masks import DOutputMasks, StyledCoarse, align_to_d_output
from core.errors import DetailizeError
from core.grid import ISO_LEVEL


def _batched(mask: Tensor | float, like: Tensor) -> Tensor | float:
    """Masks are built on the CPU (``model.masks``): move them to the output's device/dtype, add a batch dim."""
    if not isinstance(mask, Tensor):
        return mask
    mask = mask.to(device=like.device, dtype=like.dtype)
    return mask[None] if mask.dim() == like.dim() - 1 else mask


def _per_sample_sum(x: Tensor) -> Tensor:
    return x.flatten(1).sum(1)


def reconstruction_loss(outputs: Sequence[Tensor], targets: Sequence[Tensor], beta: float = 10.0) -> dict[str, Tensor]:
    """Σ_levels β·MSE(output_j, target_j); ``level{j}`` entries are the un-weighted MSEs."""
    if len(outputs) != len(targets):
        raise DetailizeError(f"{len(outputs)} outputs but {len(targets)} targets", field="targets",
                             hint="give one target per generator level")
    out = {f"level{j}": F.mse_loss(o, t) for j, (o, t) in enumerate(zip(outputs, targets))}
    out["total"] = beta * sum(out.values())  # type: ignore[assignment]
    return out


def generator_gan_loss(
    d_fake: Tensor, style_mask: Tensor, global_mask: Tensor, alpha: Tensor | float = 0.5
) -> dict[str, Tensor]:
    """Masked LSGAN generator loss of one level.

    [Σ_s Σ_v α(v)·mask_s(v)·(D_s(v) − 1)² + Σ_v gmask(v)·(D_*(v) − 1)²] / Σ_v gmask(v)

    Args:
        d_fake: (B, N+1, *S) discriminator output on the generated level (not detached).
        style_mask: (B, N, *S) style-channel masks (``masks.d_output_masks(...).style``).
        global_mask: (B, 1, *S) global mask.
        alpha: per-voxel style-head weight (B, 1, *S) (``masks.alpha_map`` aligned) or a scalar.
    """
    n = d_fake.shape[1] - 1
    sm, gm, a = _batched(style_mask, d_fake), _batched(global_mask, d_fake), _batched(alpha, d_fake)
    denom = _per_sample_sum(gm * torch.ones_like(d_fake[:, n:])).clamp_min(1.0)
    style = _per_sample_sum((d_fake[:, :n] - 1) ** 2 * sm * a) / denom
    glob = _per_sample_sum((d_fake[:, n:] - 1) ** 2 * gm) / denom
    return {"total": (style + glob).mean(), "style": style.mean(), "global": glob.mean()}


def discriminator_loss(d_real: Tensor, d_fake: Tensor, real: DOutputMasks, fake: DOutputMasks) -> dict[str, Tensor]:
    """Masked LSGAN discriminator loss of one level (paper supplementary, Eq. L_D).

    Real: Σ_s mask_s·(D_s − 1)² + gmask·(D_* − 1)², where the real style shape's masks
    switch on only its own style channel; fake: Σ_s mask_s·D_s² + gmask·D_*², each
    style channel masked to the parts assigned to it. Each side is normalised by its
    own global-mask sum.

    Args:
        d_real: (B, N+1, *S_real) output on the (smoothed) style shape.
        d_fake: (B, N+1, *S_fake) output on the *detached* generated level.
        real, fake: masks of the matching samples (``masks.d_output_masks``).
    """
    n = d_real.shape[1] - 1
    rs, rg = _batched(real.style, d_real), _batched(real.global_, d_real)
    fs, fg = _batched(fake.style, d_fake), _batched(fake.global_, d_fake)
    r_den = _per_sample_sum(rg * torch.ones_like(d_real[:, n:])).clamp_min(1.0)
    f_den = _per_sample_sum(fg * torch.ones_like(d_fake[:, n:])).clamp_min(1.0)
    real_l = (_per_sample_sum((d_real[:, :n] - 1) ** 2 * rs) + _per_sample_sum((d_real[:, n:] - 1) ** 2 * rg)) / r_den
    fake_l = (_per_sample_sum(d_fake[:, :n] ** 2 * fs) + _per_sample_sum(d_fake[:, n:] ** 2 * fg)) / f_den
    return {"total": (real_l + fake_l).mean(), "real": real_l.mean(), "fake": fake_l.mean()}


def down_loss(
    fine: Tensor,
    coarse: Tensor,
    variant: DownLoss = DownLoss.CODE_HINGE,
    stop_gradient: bool = True,
    high: float = 0.6,
    iso: float = ISO_LEVEL,
    factor: int = 2,
) -> Tensor:
    """Structure-preserving downsampling loss between level j+1 (``fine``) and level j (``coarse``).

    - ``PAPER_MSE``: mean((maxpool₂(fine) − sg(coarse))²).
    - ``CODE_HINGE``: pool ``fine`` by 2 with avg and max; where coarse > iso the cell
      costs (1 − avg)² unless max > ``high``; elsewhere avg² unless max < iso; mean over
      cells. ``coarse`` only enters through a comparison, so no gradient reaches it
      whatever ``stop_gradient`` says.

    Args:
        fine: (B, 1, 2X, 2Y, 2Z); coarse: (B, 1, X, Y, Z) (the binary input for the first level).
        factor: resolution ratio of ``fine`` to ``coarse`` (2 in the pyramid; 16 without it, the
            ×16 output against the coarse input): the pools above are by ``factor``.
    """
    prev = coarse.detach() if stop_gradient else coarse
    mx = F.max_pool3d(fine, factor)
    if variant is DownLoss.PAPER_MSE:
        return F.mse_loss(mx, prev)
    avg = F.avg_pool3d(fine, factor)
    on = prev > iso
    fill = (1 - avg) ** 2 * (mx <= high)
    clear = avg**2 * (mx >= iso)
    return torch.where(on, fill, clear).mean()


def up_loss(fine: Tensor, coarse: Tensor, stop_gradient: bool = True, factor: int = 2) -> Tensor:
    """mean((fine − sg(nearest_f(coarse)))²); fine (B, 1, fX, fY, fZ), coarse (B, 1, X, Y, Z), f = ``factor``."""
    prev = coarse.detach() if stop_gradient else coarse
    return F.mse_loss(fine, F.interpolate(prev, scale_factor=factor, mode="nearest"))


def structure_pair(fine: Tensor, coarse: Tensor, lc: LossConfig, factor: int) -> tuple[Tensor, Tensor]:
    """(L_down, L_up) of one output ``fine`` (B, 1, fX, fY, fZ) against the grid before it, ``coarse`` (B, 1, X, Y, Z).

    ``factor`` f is their resolution ratio; variant, stop-gradient and hinge level come from ``lc``.
    """
    return (down_loss(fine, coarse, lc.down_loss, lc.stop_gradient, lc.down_hinge_high, factor=factor),
            up_loss(fine, coarse, lc.stop_gradient, factor=factor))


def structure_losses(outputs: Sequence[Tensor], coarse_input: Tensor, lc: LossConfig) -> dict[str, Tensor]:
    """L_down and L_up summed over all outputs, each against the one before, the first against the coarse input.

    ``outputs`` are the generator's (every level, or only the last without the pyramid:
    then the ×16 output is compared with the coarse input (B, 1, X, Y, Z) directly); the
    pooling factor is the resolution ratio of neighbouring grids. Returns ``down``/``up``
    (un-weighted sums), ``down{k}``/``up{k}`` per output, and ``total`` = γ_down·down + γ_up·up.
    """
    prevs = [coarse_input.to(outputs[0].dtype), *outputs[:-1]]
    out: dict[str, Tensor] = {}
    for j, (prev, cur) in enumerate(zip(prevs, outputs)):
        out[f"down{j}"], out[f"up{j}"] = structure_pair(cur, prev, lc, factor=cur.shape[-1] // prev.shape[-1])
    out["down"] = sum(out[f"down{j}"] for j in range(len(outputs)))  # type: ignore[assignment]
    out["up"] = sum(out[f"up{j}"] for j in range(len(outputs)))  # type: ignore[assignment]
    out["total"] = lc.gamma_down * out["down"] + lc.gamma_up * out["up"]
    return out


# ----------------------------------------------------------------------------- all levels


def _stack_masks(samples: Sequence[StyledCoarse], level: int, cfg: ModelConfig, shape: tuple[int, ...]) -> DOutputMasks:
    """Masks of every batch item for one level, rebuilt from each item's own assignment."""
    per = [s.masks(level, cfg.discriminator(level), shape, cfg.n_styles) for s in samples]
    return DOutputMasks(torch.stack([m.style for m in per]), torch.stack([m.global_ for m in per]))


def _as_seq(x: StyledCoarse | Sequence[StyledCoarse]) -> Sequence[StyledCoarse]:
    return [x] if isinstance(x, StyledCoarse) else x


def generator_adversarial_loss(
    d_fake: Sequence[Tensor],
    outputs: Sequence[Tensor],
    coarse_input: Tensor,
    fake: StyledCoarse | Sequence[StyledCoarse],
    cfg: ModelConfig,
    alpha_coarse: Tensor | Sequence[Tensor] | None = None,
) -> dict[str, Tensor]:
    """The adversarial G step's loss: Σ_levels GAN + γ_down·Σ L_down + γ_up·Σ L_up.

    Args:
        d_fake: per supervised level (``cfg.supervised_levels``), (B, N+1, *S_j) discriminator
            outputs on ``outputs`` (not detached).
        outputs: per supervised level, (B, 1, ...) generator outputs.
        coarse_input: (B, 1, X, Y, Z) binary coarse occupancy given to the generator.
        fake: per batch item, the coarse labels and part→style assignment of the input.
        alpha_coarse: per batch item, (X, Y, Z) style-head weights (``masks.alpha_map``);
            None = ``cfg.losses.alpha_other`` everywhere (no adaptive α).
    Returns:
        ``total``, ``gan``, ``down``, ``up`` and per-level ``gan{j}``.
    """
    lc, samples = cfg.losses, _as_seq(fake)
    alphas = None if alpha_coarse is None else ([alpha_coarse] if isinstance(alpha_coarse, Tensor) else alpha_coarse)
    out: dict[str, Tensor] = {}
    levels = cfg.supervised_levels
    for j, d in zip(levels, d_fake):
        shape = tuple(d.shape[2:])
        m = _stack_masks(samples, j, cfg, shape)
        if alphas is None:
            a: Tensor | float = lc.alpha_other
        else:
            a = torch.stack([align_to_d_output(x[None], j, cfg.discriminator(j), shape) for x in alphas])
        out[f"gan{j}"] = generator_gan_loss(d, m.style, m.global_, a)["total"]
    out["gan"] = sum(out[f"gan{j}"] for j in levels[: len(d_fake)])  # type: ignore[assignment]
    st = structure_losses(outputs, coarse_input, lc)
    out["down"], out["up"] = st["down"], st["up"]
    out["total"] = out["gan"] + st["total"]
    return out


def discriminator_loss_levels(
    d_real: Sequence[Tensor],
    d_fake: Sequence[Tensor],
    real: StyledCoarse | Sequence[StyledCoarse],
    fake: StyledCoarse | Sequence[StyledCoarse],
    cfg: ModelConfig,
) -> dict[str, Tensor]:
    """Σ_levels of ``discriminator_loss``, with every level's masks rebuilt from the true assignments.

    The reference overwrote the fake sample's assignment with the real style's one-hot
    inside this loop, so only level 0 credited fake parts to their own styles; here the
    (immutable) ``fake.assignment`` is used at every level.

    Returns:
        ``total``, ``real``, ``fake`` summed over levels and ``real{j}``/``fake{j}`` per level.
    """
    reals, fakes = _as_seq(real), _as_seq(fake)
    out: dict[str, Tensor] = {}
    levels = cfg.supervised_levels
    for j, dr, df in zip(levels, d_real, d_fake):
        rm = _stack_masks(reals, j, cfg, tuple(dr.shape[2:]))
        fm = _stack_masks(fakes, j, cfg, tuple(df.shape[2:]))
        terms = discriminator_loss(dr, df, rm, fm)
        out[f"real{j}"], out[f"fake{j}"] = terms["real"], terms["fake"]
    out["real"] = sum(out[f"real{j}"] for j in levels[: len(d_real)])  # type: ignore[assignment]
    out["fake"] = sum(out[f"fake{j}"] for j in levels[: len(d_fake)])  # type: ignore[assignment]
    out["total"] = out["real"] + out["fake"]
    return out

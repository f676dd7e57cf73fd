"""DECOLLAGE losses as pure functions returning named tensors (the DECOLLAGE paper's Eq. 1–6 and its published code).

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


def discriminator_loss(d_real: Tensor, d_fake: Tensor, real: DOutputMasks, fake: DOutputMasks,
                       mismatch: float = 0.0) -> dict[str, Tensor]:
    """Masked LSGAN discriminator loss of one level (paper supplementary, Eq. L_D).

    Real: Σ_s mask_s·(D_s − 1)² + gmask·(D_* − 1)², where the real style shape's masks
    switch on only its own style channel; fake: Σ_s mask_s·D_s² + gmask·D_*², each
    style channel masked to the parts assigned to it. Each side is normalised by its
    own global-mask sum.

    With ``mismatch`` λ > 0 (``LossConfig.style_mismatch``) the real side also charges every
    other style channel as fake where the real shape is: λ·mean_{t≠s} D_t², with mask_t =
    Σ_s mask_s − mask_t (the matching-aware discriminator: a head must tell its own style
    from the other exemplars, not only real from generated). Reported as ``mismatch``
    (un-weighted); 0 with one style.

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
    mis = d_real.new_zeros(d_real.shape[0])
    if n > 1:
        styled = rs * torch.ones_like(d_real[:, :n])  # (B, N, *S): the real masks, broadcast to the output
        others = (styled.sum(1, keepdim=True) - styled).clamp_min(0) / (n - 1)
        mis = _per_sample_sum(d_real[:, :n] ** 2 * others) / r_den
    return {"total": (real_l + fake_l + mismatch * mis).mean(), "real": real_l.mean(), "fake": fake_l.mean(),
            "mismatch": mis.mean()}


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


def structure_losses(outputs: Sequence[Tensor], prevs: Sequence[Tensor], lc: LossConfig) -> dict[str, Tensor]:
    """L_down and L_up summed over all outputs, each against the grid before it on the same cells.

    Args:
        outputs: the generator's supervised outputs (every level, or only the last without
            the pyramid), each (B, 1, ...), whole or cut to a window (``model/train.py``).
        prevs: per output, the grid before it cut to the same cells: the coarse input
            (B, 1, X, Y, Z) for the first, else the previous output (``whole_shape_prevs``
            for whole shapes). The pooling factor is their resolution ratio (2 in the
            pyramid, 16 for the ×16 output against the coarse input without it).
    Returns:
        ``down``/``up`` (un-weighted sums), ``down{k}``/``up{k}`` per output,
        ``up_weighted`` = Σ_k γ_up·w_k·up{k} (w = ``lc.up_level_weights``, 1 when empty) and
        ``total`` = γ_down·down + up_weighted.
    """
    if len(prevs) != len(outputs):
        raise DetailizeError(f"{len(outputs)} outputs but {len(prevs)} previous grids", field="prevs",
                             hint="give the grid before every output (whole_shape_prevs)")
    out: dict[str, Tensor] = {}
    for j, (prev, cur) in enumerate(zip(prevs, outputs)):
        prev = prev.to(cur.dtype)
        out[f"down{j}"], out[f"up{j}"] = structure_pair(cur, prev, lc, factor=cur.shape[-1] // prev.shape[-1])
    out["down"] = sum(out[f"down{j}"] for j in range(len(outputs)))  # type: ignore[assignment]
    out["up"] = sum(out[f"up{j}"] for j in range(len(outputs)))  # type: ignore[assignment]
    if lc.up_level_weights:
        out["up_weighted"] = sum(lc.up_weight(k) * out[f"up{k}"] for k in range(len(outputs)))  # type: ignore
    else:
        out["up_weighted"] = lc.gamma_up * out["up"]
    out["total"] = lc.gamma_down * out["down"] + out["up_weighted"]
    return out


def fill_floor_loss(outputs: Sequence[Tensor], coarse: Sequence[Tensor], floor: float) -> Tensor:
    """Σ_k mean over the occupied coarse cells below the floor of (floor − mean of output k over the cell's block)².

    The mean runs over the deficient cells only, so a few eroded cells (a stroke, a spire) weigh as
    much in a large content as in a small one: over all occupied cells the term was ~4e-4 on the
    training contents at step 10,320 (most cells full), too small against the GAN term (~2.6) to move.

    Args:
        outputs: per supervised level, (B, 1, fX, fY, fZ) generator outputs in [0, 1].
        coarse: per output, the binary coarse input cut to the same cells, (B, 1, X, Y, Z);
            f = the output's resolution ratio to it (2^(j+1) at generator level j).
        floor: the mean occupancy an occupied cell's block must keep (``LossConfig.fill_floor``).
    Returns:
        a scalar; 0 where no cell is occupied.
    """
    total = outputs[0].new_zeros(())
    for out, occ in zip(outputs, coarse):
        on = occ.to(out.dtype) > 0.5  # none occupied: an empty sum over a count clamped to 1, so 0
        mean = F.avg_pool3d(out.clamp(0, 1), out.shape[-1] // occ.shape[-1])
        deficit = F.relu(floor - mean)[on]
        total = total + (deficit**2).sum() / (deficit > 0).sum().clamp(min=1)
    return total


# ----------------------------------------------------------------------------- all levels
#
# The assembly the trainer (model/train.py) calls every step. Per supervised level k
# (``cfg.supervised_levels[k]`` = generator level j) it takes the level's tensors and
# the discriminator-output masks already aligned with ``d_fake[k]``: the trainer builds
# them on a window's cells for the windowed levels (``SampleView``), ``whole_shape_masks``
# / ``whole_shape_alphas`` / ``whole_shape_prevs`` build them for whole shapes.


def whole_shape_prevs(outputs: Sequence[Tensor], coarse_input: Tensor) -> list[Tensor]:
    """The grid before every output of a whole-shape forward: the coarse input (B, 1, X, Y, Z), then each output."""
    return [coarse_input.to(outputs[0].dtype), *outputs[:-1]]


def _as_seq(x: StyledCoarse | Sequence[StyledCoarse]) -> Sequence[StyledCoarse]:
    return [x] if isinstance(x, StyledCoarse) else x


def whole_shape_masks(d_outputs: Sequence[Tensor], samples: StyledCoarse | Sequence[StyledCoarse],
                      cfg: ModelConfig) -> list[DOutputMasks]:
    """Per supervised level, the masks of every batch item aligned with ``d_outputs[k]`` (B, N+1, *S_k).

    Each item's masks come from its own (immutable) part→style assignment at every level:
    the reference overwrote the fake sample's assignment with the real style's one-hot
    inside its level loop, so only level 0 credited fake parts to their own styles.
    """
    items, out = _as_seq(samples), []
    for j, d in zip(cfg.supervised_levels, d_outputs):
        per = [s.masks(j, cfg.discriminator(j), tuple(d.shape[2:]), cfg.n_styles) for s in items]
        out.append(DOutputMasks(torch.stack([m.style for m in per]), torch.stack([m.global_ for m in per])))
    return out


def whole_shape_alphas(d_outputs: Sequence[Tensor], alpha_coarse: Tensor | Sequence[Tensor],
                       cfg: ModelConfig) -> list[Tensor]:
    """Per supervised level, the style-head weights (B, 1, *S_k) from per-item (X, Y, Z) maps (``masks.alpha_map``)."""
    alphas = [alpha_coarse] if isinstance(alpha_coarse, Tensor) else alpha_coarse
    return [torch.stack([align_to_d_output(a[None], j, cfg.discriminator(j), tuple(d.shape[2:])) for a in alphas])
            for j, d in zip(cfg.supervised_levels, d_outputs)]


def generator_adversarial_loss(
    d_fake: Sequence[Tensor],
    outputs: Sequence[Tensor],
    prevs: Sequence[Tensor],
    masks: Sequence[DOutputMasks],
    alphas: Sequence[Tensor | float] | None,
    cfg: ModelConfig,
    coarse: Sequence[Tensor] | None = None,
) -> dict[str, Tensor]:
    """The adversarial G step's loss: Σ_levels w_gan·GAN + γ_down·Σ L_down + Σ_levels γ_up·w_k·L_up [+ γ_fill·L_fill].

    Args:
        d_fake: per supervised level (``cfg.supervised_levels``), (B, N+1, *S_k) discriminator
            outputs on ``outputs`` (not detached).
        outputs: per supervised level, (B, 1, ...) generator outputs.
        prevs: per output, the grid before it on the same cells (``structure_losses``).
        masks: per level, the fake sample's masks aligned with ``d_fake[k]``.
        alphas: per level, (B, 1, *S_k) style-head weights or a number; None =
            ``cfg.losses.alpha_other`` everywhere (no adaptive α).
        coarse: per output, the binary coarse input cut to its cells (B, 1, X, Y, Z), for the
            cell-fill floor (``fill_floor_loss``); needed when ``cfg.losses.gamma_fill`` > 0.
    Returns:
        ``total``, ``gan`` (Σ_k ``lc.gan_weight(k)``·gan{j_k}), ``down``, ``up``, ``fill`` (0 when off),
        per-level ``gan{j}`` (unweighted)
        (j = generator level) and per-output ``down{k}``/``up{k}``.
    """
    lc = cfg.losses
    levels = cfg.supervised_levels
    alphas = [lc.alpha_other] * len(d_fake) if alphas is None else alphas
    out: dict[str, Tensor] = {}
    for j, d, m, a in zip(levels, d_fake, masks, alphas):
        out[f"gan{j}"] = generator_gan_loss(d, m.style, m.global_, a)["total"]
    out["gan"] = sum(lc.gan_weight(k) * out[f"gan{j}"]  # type: ignore[assignment]
                     for k, j in enumerate(levels[: len(d_fake)]))
    st = structure_losses(outputs, prevs, lc)
    out.update({k: v for k, v in st.items() if k != "total"})
    out["fill"] = outputs[0].new_zeros(())
    if lc.gamma_fill > 0:
        if coarse is None:
            raise DetailizeError("the cell-fill floor needs the coarse input per level", field="coarse",
                                 hint="pass the coarse input cut to every output's cells")
        out["fill"] = fill_floor_loss(outputs, coarse, lc.fill_floor)
    out["total"] = out["gan"] + lc.gamma_down * out["down"] + out["up_weighted"] + lc.gamma_fill * out["fill"]
    return out


def discriminator_loss_levels(
    d_real: Sequence[Tensor],
    d_fake: Sequence[Tensor],
    real: Sequence[DOutputMasks],
    fake: Sequence[DOutputMasks],
    cfg: ModelConfig,
) -> dict[str, Tensor]:
    """Σ_levels of ``discriminator_loss``: the D step's loss.

    Args:
        d_real, d_fake: per supervised level, the outputs on the real style shape's targets
            and on the *detached* generated levels.
        real, fake: per level, their masks (the fake ones from the true per-part assignment
            at every level; ``whole_shape_masks``).
    Returns:
        ``real``, ``fake``, ``mismatch`` (un-weighted) summed over levels, ``real{j}``/``fake{j}``/``mismatch{j}``
        per level, and ``total`` = real + fake + ``style_mismatch``·mismatch.
    """
    out: dict[str, Tensor] = {}
    levels = cfg.supervised_levels
    for j, dr, df, rm, fm in zip(levels, d_real, d_fake, real, fake):
        terms = discriminator_loss(dr, df, rm, fm, cfg.losses.style_mismatch)
        out[f"real{j}"], out[f"fake{j}"], out[f"mismatch{j}"] = terms["real"], terms["fake"], terms["mismatch"]
    out["real"] = sum(out[f"real{j}"] for j in levels[: len(d_real)])  # type: ignore[assignment]
    out["fake"] = sum(out[f"fake{j}"] for j in levels[: len(d_fake)])  # type: ignore[assignment]
    out["mismatch"] = sum(out[f"mismatch{j}"] for j in levels[: len(d_real)])  # type: ignore[assignment]
    out["total"] = out["real"] + out["fake"] + cfg.losses.style_mismatch * out["mismatch"]
    return out


def style_classification_loss(logits: Tensor, target: Tensor, weight: Tensor | None = None) -> Tensor:
    """Softmax cross-entropy of the style heads read as logits (``LossConfig.style_classifier``).

    Args:
        logits: (B, N+1, *S) pre-sigmoid discriminator outputs (``Discriminator.logits``); the
            global channel N is not a style and is left out.
        target: (B, *S) int64 style of every output voxel.
        weight: (B, *S) per-voxel weight, or None (all 1).
    Returns:
        Σ weight·CE / Σ weight, a scalar (0 where the weights sum to 0; 0 with one style).
    """
    n = logits.shape[1] - 1
    ce = F.cross_entropy(logits[:, :n], target.to(logits.device), reduction="none")
    if weight is None:
        return ce.mean()
    w = weight.to(device=ce.device, dtype=ce.dtype).expand_as(ce)
    return (ce * w).sum() / w.sum().clamp_min(1e-6)


def assigned_styles(style_mask: Tensor) -> tuple[Tensor, Tensor]:
    """From a fake sample's style-channel masks (B, N, *S): the style of every output voxel (B, *S),
    the channel of largest mask, and its weight (B, *S), the masks' sum (0 where no part is styled)."""
    return style_mask.argmax(1), style_mask.sum(1)


def real_style_targets(logits: Tensor, styles: Tensor) -> Tensor:
    """The label map (B, *S) of a batch of real crops of ``styles`` (B,) for outputs ``logits`` (B, N+1, *S)."""
    return styles.to(logits.device).view(-1, *([1] * (logits.dim() - 2))).expand(logits.shape[0], *logits.shape[2:])

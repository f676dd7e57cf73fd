"""DECOLLAGE networks: the pyramid generator and the per-level PatchGAN discriminators.

Shapes use batch B and a coarse grid (D, H, W) of any size ≥ 1 per axis (the
crop need not be cubic). Level ``j`` (0-based) outputs occupancy at
``2**(j+1) × (D, H, W)``; with four levels the last is 16× (16³ → 256³).

Both networks work in either memory format; for CPU inference call
``model.to(memory_format=torch.channels_last_3d)`` and run under
``torch.inference_mode()`` (inputs are converted to the weights' format).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn
from torch.nn import functional as F

from model.config import DiscriminatorSpec, LevelSpec, ModelConfig, Upsampler
from core.errors import DetailizeError


def leaky_clamp(x: Tensor, slope: float = 0.002) -> Tensor:
    """Identity on [0, 1], slope ``slope`` outside: max(min(x, s·x + 1 − s), s·x).

    Computed as clamp(x, 0, 1) + s·(x − clamp(x, 0, 1)), the same function in two
    full-volume passes instead of four (40 vs 85 ms at 256³ on 2 cores).
    """
    return torch.lerp(x.clamp(0.0, 1.0), x, slope)


def voxel_shuffle(x: Tensor) -> Tensor:
    """(B, 8C, D, H, W) → (B, C, 2D, 2H, 2W): channel ``8c + 4a + 2b + d`` fills sub-voxel (a, b, d) of channel c."""
    b, c8, d, h, w = x.shape
    c = c8 // 8
    y = x.view(b, c, 2, 2, 2, d, h, w).permute(0, 1, 5, 2, 6, 3, 7, 4)
    return y.reshape(b, c, 2 * d, 2 * h, 2 * w)


def part_onehot(part_labels: Tensor, occupancy: Tensor, n_parts: int) -> Tensor:
    """Part one-hot masked by occupancy, the generator's part input.

    Args:
        part_labels: (B, D, H, W) int64 in [0, P); empty voxels may hold any valid label
            (e.g. the nearest-neighbour fill of ``masks.coarse_part_labels``).
        occupancy: (B, 1, D, H, W) float in {0, 1}.
    Returns:
        (B, P, D, H, W) float, zero wherever ``occupancy`` is 0.
    """
    if part_labels.min() < 0 or part_labels.max() >= n_parts:
        raise DetailizeError(
            f"part labels must lie in [0, {n_parts})", field="part", hint="fill empty voxels before building inputs"
        )
    onehot = F.one_hot(part_labels.long(), n_parts).permute(0, 4, 1, 2, 3).to(occupancy.dtype)
    return onehot * occupancy


def modulate_cells(y: Tensor, gamma: Tensor, beta: Tensor) -> Tensor:
    """FiLM per coarse cell: ``y · (1 + γ) + β`` with γ, β constant over each cell's block, never upsampled.

    Args:
        y: (B, C, f·d, f·h, f·w) features, in the standard or the ``channels_last_3d`` format.
        gamma, beta: (B, C, d, h, w), one value per channel and coarse cell.
    Returns:
        (B, C, f·d, f·h, f·w) in ``y``'s memory format. The blocks are broadcast through a
        view, so no (B, C, f·d, …) copy of γ or β is made (at 128³ with 16 channels one
        would be 134 MB per tensor for a 16³ grid).
    """
    b, c, big_d, big_h, big_w = y.shape
    d, h, w = gamma.shape[2:]
    f = big_d // d
    if (f * d, f * h, f * w) != (big_d, big_h, big_w):
        raise DetailizeError(f"features {tuple(y.shape)} are not whole blocks of the {d}×{h}×{w} modulation",
                             field="style_modulation", hint="cut features and conditioning to the same cells")
    if not y.is_contiguous() and y.is_contiguous(memory_format=torch.channels_last_3d):
        yv = y.permute(0, 2, 3, 4, 1).view(b, d, f, h, f, w, f, c)
        g, t = (v.permute(0, 2, 3, 4, 1).reshape(b, d, 1, h, 1, w, 1, c) for v in (gamma, beta))
        return torch.addcmul(t, yv, g + 1.0).view(b, big_d, big_h, big_w, c).permute(0, 4, 1, 2, 3)
    yv = y.contiguous().view(b, c, d, f, h, f, w, f)
    g, t = (v.reshape(b, c, d, 1, h, 1, w, 1) for v in (gamma, beta))
    return torch.addcmul(t, yv, g + 1.0).view(b, c, big_d, big_h, big_w)


def memory_format_of(module: nn.Module) -> torch.memory_format:
    """The format the module's 5-D weights were put in (``module.to(memory_format=...)``)."""
    for p in module.parameters():
        if p.dim() == 5 and p.shape[1] > 1 and p.shape[2] > 1:
            if p.is_contiguous(memory_format=torch.channels_last_3d) and not p.is_contiguous():
                return torch.channels_last_3d
            return torch.contiguous_format
    return torch.contiguous_format


class _Level(nn.Module):
    """One doubling level: concat(features, parts↑, z↑) → upsample → convs → 1-channel side head.

    ``supervised`` False (intermediate levels without the pyramid): no side head; the
    level only passes its features on (``forward`` returns None for the occupancy).
    ``hidden`` > 0 (voxel shuffle only; ``ModelConfig.last_hidden``): the sub-voxels are
    predicted by a 3×3×3 conv to ``hidden`` channels, LeakyReLU and a 1×1×1 conv instead of
    one linear 3×3×3 conv (``self.pre`` is None otherwise, and the weights' names are unchanged).
    """

    def __init__(self, spec: LevelSpec, in_ch: int, slope: float, supervised: bool = True, hidden: int = 0) -> None:
        super().__init__()
        w = spec.width
        self.pre: nn.Module | None = None
        if spec.upsampler is Upsampler.CONV_TRANSPOSE:
            self.up: nn.Module = nn.ConvTranspose3d(in_ch, w, kernel_size=4, stride=2, padding=1)
        elif hidden:
            # (B, in_ch, d, h, w) → 3³ conv → (B, hidden, d, h, w) → LeakyReLU → 1³ conv → (B, 8w, d, h, w)
            self.pre = nn.Conv3d(in_ch, hidden, kernel_size=3, padding=1)
            self.up = nn.Conv3d(hidden, 8 * w, kernel_size=1)
        else:
            # Sub-pixel conv: a 3×3×3 conv at the input resolution predicts the 8 sub-voxels,
            # so no conv ever runs at the (8× larger) output resolution.
            self.up = nn.Conv3d(in_ch, 8 * w, kernel_size=3, padding=1)
        self.shuffle = spec.upsampler is Upsampler.VOXEL_SHUFFLE
        self.convs = nn.ModuleList(nn.Conv3d(w, w, 3, padding=1) for _ in range(spec.n_convs))
        k = spec.head_kernel
        self.head = nn.Conv3d(w, 1, k, padding=k // 2) if k > 0 and supervised else None
        self.supervised = supervised
        self.slope = slope

    def forward(self, x: Tensor, with_head: bool = True,
                film: tuple[Tensor, Tensor] | None = None) -> tuple[Tensor, Tensor | None]:
        """x: (B, in_ch, d, h, w) → (features (B, width, 2d, 2h, 2w), pre-activation occupancy or None).

        ``film``: (γ, β), each (B, width, d', h', w') per coarse cell (``modulate_cells``), applied
        to the level's output features before its head (to the occupancy pre-activation of a
        head-less voxel-shuffle level); None: no modulation.
        """
        if self.pre is not None:
            x = F.leaky_relu(self.pre(x), self.slope, inplace=True)
        y = self.up(x)
        if self.shuffle:
            y = voxel_shuffle(y).contiguous(memory_format=_format_of(x))
        if self.head is None and self.supervised:  # the single shuffled channel is the occupancy pre-activation
            y = y if film is None else modulate_cells(y, *film)
            return y, y
        y = F.leaky_relu(y, self.slope, inplace=True)
        for conv in self.convs:
            y = F.leaky_relu(conv(y), self.slope, inplace=True)
        if film is not None:
            y = modulate_cells(y, *film)
        return y, (self.head(y) if with_head and self.head is not None else None)


def _format_of(x: Tensor) -> torch.memory_format:
    if x.dim() == 5 and not x.is_contiguous() and x.is_contiguous(memory_format=torch.channels_last_3d):
        return torch.channels_last_3d
    return torch.contiguous_format


def upsample_nearest(x: Tensor, factor: int) -> Tensor:
    """(B, C, D, H, W) → (B, C, f·D, f·H, f·W), nearest (``x`` itself for f = 1)."""
    return x if factor == 1 else F.interpolate(x, scale_factor=factor, mode="nearest")


class Generator(nn.Module):
    """Pyramid generator: coarse occupancy + parts + per-voxel style → occupancy at every supervised level.

    Inputs (coarse resolution): occupancy (1 channel), part one-hot × occupancy (P
    channels; absent in the "w/o part labels" variant), style field z (``style_dim``
    channels) built from the learnable codes by ``style_field``. The backbone
    re-concatenates z before every conv (as the reference: 14 → 32 … 512 channels
    for P=5); every level concatenates the nearest-upsampled parts and z before
    upsampling. Outputs pass through the leaky clamp to [0, 1]. Without the pyramid
    (``cfg.pyramid`` False) only the last level has a head and an output.

    Conv weights use PyTorch's default initialisation (seed with ``torch.manual_seed``
    for reproducible weights); the style codes start at zero, or random with
    ``cfg.style_init_std``. With ``cfg.output_mask`` every output is zero outside the
    occupied coarse cells. With ``cfg.style_modulation`` every level's output features are
    also scaled and shifted per coarse cell by γ, β = ``style_films[j]``(z) (a 1×1×1 conv of
    the coarse style field, zero at the start; ``modulate_cells``).
    """

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        self.cfg = cfg
        z, p = cfg.style_dim, (cfg.n_parts if cfg.use_part_labels else 0)
        # Zeros as in the reference (styles separate only as training moves them), or N(0, std²).
        codes = torch.zeros(z, cfg.n_styles)
        if cfg.style_init_std > 0:
            codes.normal_(0.0, cfg.style_init_std)
        self.style_codes = nn.Parameter(codes)
        convs, in_ch = [], 1 + p + z
        for width, dil in zip(cfg.backbone_widths, cfg.backbone_dilations):
            convs.append(nn.Conv3d(in_ch, width, 3, padding=dil, dilation=dil))
            in_ch = width + z
        self.backbone = nn.ModuleList(convs)
        levels, feat = [], cfg.backbone_widths[-1]
        for j, spec in enumerate(cfg.levels):
            hidden = cfg.last_hidden if j == cfg.n_levels - 1 else 0
            levels.append(_Level(spec, feat + p + z, cfg.leaky_slope, supervised=j in cfg.supervised_levels,
                                 hidden=hidden))
            feat = spec.width
        self.levels = nn.ModuleList(levels)
        # Registered last, so a state without them keeps its parameters' order (``model.recipe_move``).
        self.style_films: nn.ModuleList | None = None
        if cfg.style_modulation:
            self.style_films = nn.ModuleList(nn.Conv3d(z, 2 * spec.width, 1) for spec in cfg.levels)
            for film in self.style_films:  # zero: the modulation starts as the identity
                nn.init.zeros_(film.weight)
                nn.init.zeros_(film.bias)

    def codes(self) -> Tensor:
        """The (style_dim, N) codes as used: the learnt ones, or rescaled to ``cfg.style_code_rms`` per style."""
        rms = self.cfg.style_code_rms
        if rms <= 0:
            return self.style_codes
        norm = self.style_codes.pow(2).mean(0, keepdim=True).add(1e-12).sqrt()
        return self.style_codes * (rms / norm)

    def style_field(self, style_index: Tensor) -> Tensor:
        """Per-voxel style codes: codes × one-hot(style_index), differentiable w.r.t. the codes.

        Args:
            style_index: (B, D, H, W) or (D, H, W) int, in [0, N) at *every* voxel. Empty
                voxels must already carry their nearest occupied voxel's style: the caller
                fills them (``masks.fill_nearest``; with ``masks.coarse_part_labels`` labels
                and a part→style assignment this is automatic).
        Returns:
            (B, style_dim, D, H, W) float.
        """
        if style_index.dim() == 3:
            style_index = style_index[None]
        n = self.cfg.n_styles
        if style_index.numel() and (style_index.min() < 0 or style_index.max() >= n):
            raise DetailizeError(
                f"style indices must lie in [0, {n}) at every voxel",
                field="style",
                hint="fill empty voxels with the nearest occupied voxel's style (model.masks.fill_nearest)",
            )
        z = F.embedding(style_index.long(), self.codes().t())  # (B, D, H, W, z)
        return z.permute(0, 4, 1, 2, 3)

    def make_inputs(
        self, occupancy: Tensor, part_labels: Tensor, style_index: Tensor
    ) -> tuple[Tensor, Tensor | None, Tensor]:
        """(B, D, H, W) occupancy/labels/styles → the ``forward`` arguments (occ, part one-hot or None, z).

        Inputs are moved to the device of the generator's weights.
        """
        dev = self.style_codes.device
        occ = occupancy.to(device=dev, dtype=self.style_codes.dtype)[:, None]
        parts = None
        if self.cfg.use_part_labels:
            parts = part_onehot(part_labels.to(dev), occ, self.cfg.n_parts)
        return occ, parts, self.style_field(style_index.to(dev))

    @property
    def memory_format(self) -> torch.memory_format:
        """The memory format of the weights (``channels_last_3d`` after ``to(memory_format=...)``)."""
        return memory_format_of(self)

    def forward(
        self, occupancy: Tensor, part_onehot: Tensor | None, z: Tensor, *, final_only: bool = False
    ) -> list[Tensor]:
        """Run the pyramid.

        Args:
            occupancy: (B, 1, D, H, W) float in {0, 1}.
            part_onehot: (B, P, D, H, W) float (``part_onehot()``); ignored (may be None)
                when ``cfg.use_part_labels`` is False.
            z: (B, style_dim, D, H, W) from ``style_field``.
            final_only: skip the intermediate side heads (inference); the list then holds
                only the last level.
        Returns:
            Occupancy in [0, 1] (leaky clamp) of every level in ``cfg.supervised_levels``
            (level j at 2^(j+1)×): [(B, 1, 2D, 2H, 2W), …, (B, 1, 2^L D, 2^L H, 2^L W)] for the
            pyramid, [(B, 1, 2^L D, 2^L H, 2^L W)] without it.
        """
        x, cond = self.trunk(occupancy, part_onehot, z)
        return [o for _, o in self.run_levels(x, cond, 0, all_heads=not final_only, occupancy=occupancy)[1]]

    def trunk(self, occupancy: Tensor, part_onehot: Tensor | None, z: Tensor) -> tuple[Tensor, Tensor]:
        """Check the inputs and run the backbone at the coarse resolution.

        Args: as ``forward``.
        Returns:
            (features (B, backbone_widths[-1], D, H, W), conditioning (B, K, D, H, W)): the
            part one-hot and z that every level concatenates (K = P + style_dim, or style_dim
            without part labels), both in the weights' memory format.
        """
        cfg = self.cfg
        self._check(occupancy, part_onehot, z)
        fmt = memory_format_of(self)
        cond = z if not cfg.use_part_labels else torch.cat([part_onehot, z], 1)  # type: ignore[list-item]
        cond = cond.contiguous(memory_format=fmt)
        x = torch.cat([occupancy.to(z.dtype), cond], 1).contiguous(memory_format=fmt)
        zc = z.contiguous(memory_format=fmt)
        for i, conv in enumerate(self.backbone):
            if i:
                x = torch.cat([x, zc], 1)
            x = F.leaky_relu(conv(x), cfg.leaky_slope, inplace=True)
        return x, cond

    def run_levels(
        self, x: Tensor, cond: Tensor, start: int, stop: int | None = None, *, all_heads: bool = True,
        occupancy: Tensor | None = None,
    ) -> tuple[Tensor, list[tuple[int, Tensor]]]:
        """The level loop: levels ``start .. stop − 1`` (default: to the last) on features ``x``.

        The one loop behind ``forward``, the training windows and blockwise inference
        (``model/windows.py``), which cut ``x`` and ``cond`` to a window of coarse cells
        between two levels.

        Args:
            x: (B, C, 2^start·d, 2^start·h, 2^start·w) features entering level ``start``
                (the backbone's output for ``start = 0``).
            cond: (B, K, d, h, w) the conditioning of the same coarse cells (``trunk``).
            all_heads: compute every supervised level's side head; False: only the last
                level of the generator has one (inference).
            occupancy: (B, 1, d, h, w) the coarse occupancy of the same cells; needed (and
                only read) with ``cfg.output_mask``, which zeroes outputs outside it.
        Returns:
            (features leaving level ``stop − 1``, [(level j, occupancy (B, 1, 2^(j+1)·d, …) in
            [0, 1] by the leaky clamp), …] for every level run whose head was computed).
        """
        cfg = self.cfg
        stop = cfg.n_levels if stop is None else stop
        outs = []
        z = cond[:, cond.shape[1] - cfg.style_dim:]  # the style field is cond's last channels (``trunk``)
        for j in range(start, stop):
            film = None
            if self.style_films is not None:
                film = self.style_films[j](z).chunk(2, dim=1)
            x = torch.cat([x, upsample_nearest(cond, 2**j)], 1)
            x, logit = self.levels[j](x, with_head=all_heads or j == cfg.n_levels - 1, film=film)
            if logit is not None:
                out = leaky_clamp(logit, cfg.clamp_slope)
                if cfg.output_mask:
                    if occupancy is None:
                        raise DetailizeError("output_mask needs the coarse occupancy", field="occupancy",
                                             hint="pass occupancy= to run_levels")
                    out = out * upsample_nearest(occupancy.to(out.dtype), 2 ** (j + 1))
                outs.append((j, out))
        return x, outs

    def _check(self, occ: Tensor, parts: Tensor | None, z: Tensor) -> None:
        cfg = self.cfg
        if occ.dim() != 5 or occ.shape[1] != 1:
            raise DetailizeError(f"occupancy must be (B, 1, D, H, W), got {tuple(occ.shape)}", field="occupancy",
                                 hint="add batch and channel dimensions")
        spatial = occ.shape[2:]
        if tuple(z.shape) != (occ.shape[0], cfg.style_dim, *spatial):
            raise DetailizeError(f"z must be (B, {cfg.style_dim}, D, H, W) like occupancy, got {tuple(z.shape)}",
                                 field="style", hint="build z with Generator.style_field")
        if cfg.use_part_labels and (parts is None or tuple(parts.shape) != (occ.shape[0], cfg.n_parts, *spatial)):
            got = None if parts is None else tuple(parts.shape)
            raise DetailizeError(f"part one-hot must be (B, {cfg.n_parts}, D, H, W), got {got}", field="part",
                                 hint="build it with model.networks.part_onehot")


class Discriminator(nn.Module):
    """PatchGAN discriminator of one level: valid convs → 1×1×1 conv to N+1 channels → sigmoid.

    Channels 0..N−1 are the style heads, channel N the global head. Input (B, 1, X, Y, Z)
    occupancy; output (B, N+1, X', Y', Z') with ``X' = spec.output_size(X)`` (e.g. X − 6
    for RF 7, X/2 − 8 for RF 18).
    """

    def __init__(self, spec: DiscriminatorSpec, n_styles: int, slope: float = 0.02) -> None:
        super().__init__()
        self.spec = spec
        convs, in_ch = [], 1
        for layer in spec.layers:
            convs.append(nn.Conv3d(in_ch, layer.width, layer.kernel, stride=layer.stride))
            in_ch = layer.width
        self.convs = nn.ModuleList(convs)
        self.out = nn.Conv3d(in_ch, n_styles + 1, 1)
        self.slope = slope

    def logits(self, x: Tensor) -> Tensor:
        """The pre-sigmoid outputs (B, N+1, X', Y', Z'): ``forward`` is their sigmoid; the style
        classification terms read channels 0..N−1 as the logits of a softmax over the styles."""
        x = x.contiguous(memory_format=memory_format_of(self))
        for conv in self.convs:
            x = F.leaky_relu(conv(x), self.slope, inplace=True)
        return self.out(x)

    def forward(self, x: Tensor) -> Tensor:
        return torch.sigmoid(self.logits(x))


def build_discriminators(cfg: ModelConfig) -> nn.ModuleList:
    """One ``Discriminator`` per supervised generator level, in level order (separate weights)."""
    return nn.ModuleList(Discriminator(spec, cfg.n_styles, cfg.leaky_slope) for spec in cfg.discriminators)


def receptive_field(disc: Discriminator | DiscriminatorSpec) -> int:
    """Analytic receptive field (voxels per axis) from the layer spec: 1 + Σ (k−1)·Π(previous strides)."""
    spec = disc.spec if isinstance(disc, Discriminator) else disc
    return spec.receptive_field()


def count_params(module: nn.Module) -> int:
    """Number of parameter elements (works on ``meta``-device modules too)."""
    return sum(p.numel() for p in module.parameters())

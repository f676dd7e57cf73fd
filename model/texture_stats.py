"""Placement-free style terms: the generator's surface, charged against its style's exemplar surface.

Every style signal the training had so far asks *where*: reconstruction wants the exemplar's
voxels at their places (on a new content there is no place, so its mean is a blob), and the
style heads learnt to tell real from generated but not one style from another
(``model/weights/things_selfrec.md``). These terms ask *what*: the surface of the output in
the voxels assigned to style s should be made of what exemplar s's surface is made of,
wherever its windows, tiles or facets fall. Both compare the adversarial output at one level
with the style bank's latest real window of the same style at that level
(``model/style_bank.py``), per style of the output, weighted by the style's share of the
output's surface band (``LossConfig.texture_mode``):

- ``STATS`` (the texture loss of Gatys et al., CVPR 2016, in 3-D on occupancy, with fixed
  random filters as Ustyuzhaninov et al., ICLR 2017 workshop, found enough for texture): a
  fixed random 3-D conv stack (``TextureFeatures``: 8, 16, 32, 32 channels, 3³ kernels,
  strides 1, 2, 2, 2, ReLU; receptive fields 3, 7, 15, 31 voxels of the level), seeded by
  ``TEXTURE_SEED``, never trained and never saved; per layer the band-weighted mean μ (C)
  and second moment E[f fᵀ] (C × C); the loss is Σ_layers MSE of both. On a toy (a box with
  ridges on its top, ``tests/model/test_texture_stats.py``) the ridges moved 2 voxels against
  the box's edges cost more than no ridges at all: the statistics follow the box's edges and
  corners more than the detail. On crops of the 20 exemplars, the nearest crop by this distance
  is of the same style for 0.18 (256³) to 0.23 (128³) of them, chance 0.04.
- ``PATCHES`` (bidirectional similarity, Simakov et al., CVPR 2008): up to ``PATCHES_OUT``
  e³ patches centred in the output's band and up to ``PATCHES_REAL`` in the window's band;
  the mean over output patches of the squared distance (per voxel) to the nearest window
  patch (every patch of the output is one of the exemplar's) plus the mean over window
  patches of the distance to the nearest output patch (every kind of the exemplar's patches
  appears). The first half alone is met by flat faces, which every exemplar has; the second
  asks for the detail.

``PatchContrast`` (``LossConfig.texture_contrast``), beside either: every output band patch of
style s is classified among the styles with a window by its nearest patch in each style's window
(softmax of −distance / ``CONTRAST_TAU``), with cross-entropy towards s. The patch term made the
output of exemplar patches, but of patches every style has: at 17,603 it raised LP-detail and
lowered style specificity (``model/weights/things_selfrec.md``); this term pays only for patches
nearer the assigned style's than every other's. A flat face is equally near in every window:
its loss is ln N whatever G does, so it carries almost no gradient.

The band of a grid is the voxels within ``texture_band`` voxels of its own (detached)
iso-surface: inside and outside voxels are constant and would weigh the term by the crop's fill.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import torch
from torch import Tensor, nn
from torch.nn import functional as F

from core.grid import ISO_LEVEL
from model.config import LossConfig, TextureMode

#: Seed of the fixed random filters (a state does not store them: every run rebuilds the same ones).
TEXTURE_SEED = 15_000
#: (channels, stride) of each feature layer.
TEXTURE_LAYERS = ((8, 1), (16, 2), (32, 2), (32, 2))
#: A style must hold at least this many band voxels of the output to be charged (fewer: no statistics).
MIN_BAND_VOXELS = 64
#: ``PATCHES``: most patches drawn from the output's band of one style, and from the real window's band.
PATCHES_OUT = 256
PATCHES_REAL = 1024
#: ``PatchContrast``: band patches drawn from each style's window for its library, and the softmax temperature
#: (per-voxel squared distance). See ``scripts/patch_contrast_tau.py`` for how it was chosen.
CONTRAST_REAL = 256
CONTRAST_TAU = 0.02


class TextureFeatures(nn.Module):
    """Fixed random conv features of an occupancy grid, and the surface band pooled to each layer.

    ``forward``: (B, 1, X, Y, Z) occupancy in [0, 1] → per layer (B, C_l, X_l, Y_l, Z_l), with
    X_l = ⌈X / Π strides⌉. The weights are buffers (He-scaled normal, zero bias), not parameters.
    """

    def __init__(self, seed: int = TEXTURE_SEED) -> None:
        super().__init__()
        gen = torch.Generator().manual_seed(seed)
        in_ch, self.strides = 1, tuple(s for _, s in TEXTURE_LAYERS)
        for i, (ch, _) in enumerate(TEXTURE_LAYERS):
            w = torch.randn(ch, in_ch, 3, 3, 3, generator=gen) * (2.0 / (in_ch * 27)) ** 0.5
            self.register_buffer(f"w{i}", w, persistent=False)
            in_ch = ch

    def forward(self, occupancy: Tensor) -> list[Tensor]:
        x, feats = occupancy.float() * 2.0 - 1.0, []
        for i, s in enumerate(self.strides):
            x = F.relu(F.conv3d(x, getattr(self, f"w{i}").to(x.device), stride=s, padding=1))
            feats.append(x)
        return feats

    def bands(self, occupancy: Tensor, band: int) -> list[Tensor]:
        """``surface_band`` of ``occupancy`` (B, 1, X, Y, Z) at every layer's resolution."""
        m, out = surface_band(occupancy, band), []
        for s in self.strides:
            if s > 1:
                m = F.max_pool3d(m, s, s, ceil_mode=True)
            out.append(m)
        return out


def surface_band(occupancy: Tensor, band: int) -> Tensor:
    """The surface band of ``occupancy`` (B, 1, X, Y, Z), detached, same shape: voxels within ``band``
    voxels of a voxel on the other side of ``ISO_LEVEL``, as {0, 1} floats."""
    occ = (occupancy.detach() > ISO_LEVEL).float()
    k = 2 * band + 1
    return F.max_pool3d(occ, k, 1, band) * F.max_pool3d(1.0 - occ, k, 1, band)


def weighted_stats(feats: list[Tensor], weights: list[Tensor]) -> list[tuple[Tensor, Tensor]]:
    """Per layer, the weighted mean (C,) and second moment (C, C) of features (1, C, *S) over weights (1, 1, *S)."""
    out = []
    for f, w in zip(feats, weights):
        f2 = f.flatten(2)[0]                       # (C, V)
        w2 = w.flatten(2)[0, 0].to(f2.dtype)       # (V,)
        total = w2.sum().clamp_min(1.0)
        mean = (f2 * w2).sum(1) / total
        second = (f2 * w2) @ f2.t() / total
        out.append((mean, second))
    return out


def stats_distance(a: list[tuple[Tensor, Tensor]], b: list[tuple[Tensor, Tensor]]) -> Tensor:
    """Σ_layers MSE of the means + MSE of the second moments."""
    terms = [F.mse_loss(ma, mb) + F.mse_loss(ga, gb) for (ma, ga), (mb, gb) in zip(a, b)]
    return torch.stack(terms).sum()


def band_patches(grid: Tensor, centres: Tensor, edge: int) -> Tensor:
    """The ``edge``³ patches of ``grid`` (1, 1, X, Y, Z) whose corner-before-centre is ``centres`` (P, 3) int64,
    zero outside the grid, as (P, edge³) (differentiable w.r.t. ``grid``)."""
    h = edge // 2
    padded = F.pad(grid[0, 0], (h, h) * 3)
    r = torch.arange(edge, device=grid.device)
    off = torch.stack(torch.meshgrid(r, r, r, indexing="ij"), -1).reshape(-1, 3)  # (e³, 3)
    idx = centres[:, None, :] + off[None]                                           # (P, e³, 3), padded coords
    return padded[idx[..., 0], idx[..., 1], idx[..., 2]]


def squared_distances(mine: Tensor, real: Tensor) -> Tensor:
    """(P, Q) |p − q|² between the patches (P, D) and (Q, D)."""
    return (mine.pow(2).sum(1, keepdim=True) + real.pow(2).sum(1)[None] - 2.0 * mine @ real.t()).clamp_min(0.0)


def bidirectional_patch_distance(mine: Tensor, real: Tensor) -> Tensor:
    """mean_p min_q |p − q|² + mean_q min_p |p − q|², per voxel, of patches (P, D) and (Q, D)."""
    d = squared_distances(mine, real)
    return (d.min(1).values.mean() + d.min(0).values.mean()) / mine.shape[1]


def nearest_style_logits(mine: Tensor, libraries: Sequence[Tensor], tau: float = CONTRAST_TAU) -> Tensor:
    """(P, N) logits −min_q |p − q|² / (D · tau) of every patch (P, D) against each library (Q_n, D)."""
    d = torch.stack([squared_distances(mine, lib).min(1).values for lib in libraries], 1)
    return -d / (mine.shape[1] * tau)


def _pick(mask: Tensor, most: int, rng: np.random.Generator) -> Tensor:
    """Up to ``most`` of the True voxels of ``mask`` (X, Y, Z), drawn with ``rng`` without replacement, (P, 3)."""
    where = mask.nonzero()
    if len(where) > most:
        where = where[torch.as_tensor(np.sort(rng.choice(len(where), most, replace=False)), device=where.device)]
    return where


def share_weighted(output: Tensor, per_style: list[Tensor], shares: list[float]) -> Tensor:
    """Σ_s share_s · term_s with shares normalised to sum 1 (each style's band voxels); 0, still a tensor of
    ``output``'s graph, when no style was charged."""
    if not per_style:
        return output.sum() * 0.0
    total = sum(shares)
    return sum(d * (n / total) for d, n in zip(per_style, shares))  # type: ignore[return-value]


def window_band_patches(real: Tensor, band: int, edge: int, most: int, rng: np.random.Generator) -> Tensor:
    """Up to ``most`` ``edge``³ patches (P, edge³) centred in the surface band of a real window (1, 1, …)."""
    return band_patches(real, _pick(surface_band(real, band)[0, 0] > 0, most, rng), edge)


class TextureTerm(nn.Module):
    """``LossConfig.texture_mode``'s term of one generated level (``forward``), with its fixed features."""

    def __init__(self, lc: LossConfig) -> None:
        super().__init__()
        self.mode, self.band, self.edge = lc.texture_mode, lc.texture_band, lc.texture_patch
        self.features = TextureFeatures()

    def forward(self, output: Tensor, styles: Tensor, real: Mapping[int, Tensor], rng: np.random.Generator) -> Tensor:
        """The term of one level.

        Args:
            output: (1, 1, X, Y, Z) the generator's occupancy at this level (differentiable).
            styles: (X, Y, Z) int64, the style assigned to every output voxel.
            real: style → (1, 1, X', Y', Z') a real window of that style at the same level (any size).
            rng: draws the patches (``PATCHES``).
        Returns:
            A scalar: Σ_s share_s · distance(output in s's voxels, s's window), over the styles with a window
            and at least ``MIN_BAND_VOXELS`` band voxels; 0 (still a tensor of the graph) when none has.
        """
        f = self.features
        bands = f.bands(output, self.band)
        feats = f(output) if self.mode is TextureMode.STATS else None
        per_style, shares = [], []
        for s in torch.unique(styles).tolist():
            if s not in real:
                continue
            mine = (styles == s).to(output.dtype)[None, None]
            n = float((bands[0] * mine).sum())
            if n < MIN_BAND_VOXELS:
                continue
            if feats is not None:
                weights, m = [], mine
                for b, stride in zip(bands, f.strides):
                    if stride > 1:
                        m = F.max_pool3d(m, stride, stride, ceil_mode=True)
                    weights.append(b * m)
                with torch.no_grad():
                    target = weighted_stats(f(real[s]), f.bands(real[s], self.band))
                per_style.append(stats_distance(weighted_stats(feats, weights), target))
            else:
                with torch.no_grad():
                    library = window_band_patches(real[s], self.band, self.edge, PATCHES_REAL, rng)
                at = _pick((bands[0] * mine)[0, 0] > 0, PATCHES_OUT, rng)
                per_style.append(bidirectional_patch_distance(band_patches(output, at, self.edge), library))
            shares.append(n)
        return share_weighted(output, per_style, shares)


class PatchContrast(nn.Module):
    """``LossConfig.texture_contrast``'s term of one generated level: each style's band patches
    classified among the styles by their nearest window patch (the module docstring)."""

    def __init__(self, lc: LossConfig) -> None:
        super().__init__()
        self.band, self.edge = lc.texture_band, lc.texture_patch

    def forward(self, output: Tensor, styles: Tensor, real: Mapping[int, Tensor], rng: np.random.Generator) -> Tensor:
        """The term of one level; arguments as ``TextureTerm.forward``.

        Returns:
            A scalar: Σ_s share_s · mean cross-entropy of s's output patches towards s among the styles of
            ``real`` (ln N at no preference), over the styles with a window and at least ``MIN_BAND_VOXELS``
            band voxels; 0 (still in the graph) when none has or fewer than two styles have a window.
        """
        order = sorted(real)
        band = surface_band(output, self.band)[0, 0]
        masks = {s: band * (styles == s) for s in torch.unique(styles).tolist() if s in real}
        charged = {s: m for s, m in masks.items() if float(m.sum()) >= MIN_BAND_VOXELS}
        if len(order) < 2 or not charged:
            return output.sum() * 0.0
        with torch.no_grad():
            libraries = [window_band_patches(real[t], self.band, self.edge, CONTRAST_REAL, rng) for t in order]
        per_style, shares = [], []
        for s, mine in charged.items():
            n = float(mine.sum())
            at = _pick(mine > 0, PATCHES_OUT, rng)
            logits = nearest_style_logits(band_patches(output, at, self.edge), libraries)
            target = torch.full((len(at),), order.index(s), dtype=torch.int64, device=output.device)
            per_style.append(F.cross_entropy(logits, target))
            shares.append(n)
        return share_weighted(output, per_style, shares)

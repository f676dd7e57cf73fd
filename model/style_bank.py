"""The latest real crop of every style at the classified levels: the style classification terms' real batch.

The adversarial D step sees one real style shape per iteration, so each style head's
LSGAN term is trained on its own style against generated shapes only, never against the
other styles in the same step; measured on the committed state, the heads did not tell the
20 exemplars apart (own head top for 2 of 20 exemplars at every level). A softmax over the
style heads needs several styles per step: this bank keeps, per style and per classified
generator level j, the real target of the last reconstruction step that drew that style,
and gives one surface-centred crop of each as one batch (B ≤ N crops, labels = styles).

Crops are cut when a batch is asked for, with the caller's RNG (``rng_for(seed, it, 400 + k)``
for the k-th classification step of iteration ``it`` in ``model/train.py``), so that several
classification steps per iteration (``LossConfig.style_classifier_d_steps``) see different
crops of the same windows. (Until 2026-12-07 one crop per style was cut when the style's window
arrived and reused until it was replaced, every ~N iterations; the cls/clsw arms of
``model/weights/things_selfrec.md`` ran that way.) The bank is a function of the run's
(seed, step): a resumed run rebuilds it by replaying the iterations before its step
(``Trainer.rebuild_style_bank``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor
from torch.nn import functional as F

from core.grid import ISO_LEVEL


def surface_voxels(target: Tensor) -> Tensor:
    """The surface of ``target`` (1, 1, X, Y, Z): every voxel above ``ISO_LEVEL`` with a 6-neighbour at or
    below it, as (S, 3) int64 indices."""
    occ = target[0, 0] > ISO_LEVEL
    inner = occ.clone()
    for axis in range(3):
        for shift in (1, -1):
            inner &= torch.roll(occ, shift, axis)
    return (occ & ~inner).nonzero()


def surface_crop(target: Tensor, edge: int, rng: np.random.Generator, surface: Tensor | None = None) -> Tensor:
    """An ``edge``³ cut of ``target`` (1, 1, X, Y, Z) around a random voxel of its surface
    (``surface_voxels``, or the caller's ``surface`` of the same target, made once for many cuts).

    The crop's centre is the grid's when there is no surface. The cut stays inside the grid; an
    axis shorter than ``edge`` is zero-padded at its end (empty space). Returns (1, 1, edge, edge, edge).
    """
    surface = surface_voxels(target) if surface is None else surface
    size = np.array(target.shape[2:])
    centre = size // 2 if len(surface) == 0 else surface[int(rng.integers(len(surface)))].cpu().numpy()
    lo = np.clip(centre - edge // 2, 0, np.maximum(size - edge, 0))
    cut = target[..., lo[0]:lo[0] + edge, lo[1]:lo[1] + edge, lo[2]:lo[2] + edge]
    pad = [p for n in reversed(cut.shape[2:]) for p in (0, edge - n)]
    return F.pad(cut, pad) if any(pad) else cut


def crop_edge(crop: int, j: int, window_cells: int, whole_levels: int) -> int:
    """The bank's crop edge at generator level j: ``crop``, at most the window (``window_cells`` coarse cells of
    2^(j+1) voxels) where level j is windowed (``j ≥ whole_levels``; ``window_cells`` 0: no windows)."""
    return min(crop, window_cells * 2 ** (j + 1)) if window_cells and j >= whole_levels else crop


class StyleCropBank:
    """Per classified generator level j, style → its latest real target (1, 1, X, Y, Z), cut to crops of e_j³.

    Memory: one window per style and level (at R = 256 with 4-cell windows, ≤ 20 × (8 + 1) MiB).
    """

    def __init__(self, levels: Sequence[int], edges: Sequence[int], n_styles: int) -> None:
        self.levels, self.edges, self.n_styles = tuple(levels), dict(zip(levels, edges)), n_styles
        self.targets: dict[int, dict[int, Tensor]] = {j: {} for j in self.levels}
        self.surfaces: dict[int, dict[int, Tensor]] = {j: {} for j in self.levels}  # their surface_voxels

    def put(self, style: int, targets: dict[int, Tensor]) -> None:
        """Replace ``style``'s windows with ``targets`` (level j → (1, 1, X, Y, Z) real target; kept, not copied:
        the caller does not write to them)."""
        for j in self.levels:
            self.targets[j][style] = targets[j].detach()
            self.surfaces[j][style] = surface_voxels(self.targets[j][style])  # once, not at every batch

    def styles(self) -> list[int]:
        """The styles that have windows, in index order."""
        return sorted(self.targets[self.levels[0]]) if self.levels else []

    def ready(self) -> bool:
        """At least two styles to tell apart."""
        return len(self.styles()) >= 2

    def batch(self, j: int, rng: np.random.Generator) -> tuple[Tensor, Tensor]:
        """Level j: one ``surface_crop`` of every style's window, cut with ``rng`` in style order
        (B, 1, e, e, e), and their styles (B,) int64."""
        styles = self.styles()
        crops = [surface_crop(self.targets[j][s], self.edges[j], rng, self.surfaces[j][s]) for s in styles]
        return torch.cat(crops), torch.tensor(styles, dtype=torch.int64)

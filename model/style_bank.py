"""The latest real crop of every style at the classified levels: the style classification terms' real batch.

The adversarial D step sees one real style shape per iteration, so each style head's
LSGAN term is trained on its own style against generated shapes only, never against the
other styles in the same step; measured on the committed state, the heads did not tell the
20 exemplars apart (own head top for 2 of 20 exemplars at every level). A softmax over the
style heads needs several styles per step: this bank keeps, per style and per classified
generator level j, one surface-centred crop of the real target of the last reconstruction
step that drew that style, and gives them as one batch (B ≤ N crops, labels = styles).

Crops are cut with the caller's RNG (``rng_for(seed, it, 400 + r)`` in ``model/train.py``),
so the bank is a function of the run's (seed, step): a resumed run rebuilds it by replaying
the iterations before its step (``Trainer.rebuild_style_bank``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor
from torch.nn import functional as F

from core.grid import ISO_LEVEL


def surface_crop(target: Tensor, edge: int, rng: np.random.Generator) -> Tensor:
    """An ``edge``³ cut of ``target`` (1, 1, X, Y, Z) around a random surface voxel.

    The surface is every voxel above ``ISO_LEVEL`` with a 6-neighbour at or below it (the
    crop's centre when there is none). The cut stays inside the grid; an axis shorter than
    ``edge`` is zero-padded at its end (empty space). Returns (1, 1, edge, edge, edge).
    """
    occ = target[0, 0] > ISO_LEVEL
    inner = occ.clone()
    for axis in range(3):
        for shift in (1, -1):
            inner &= torch.roll(occ, shift, axis)
    surface = (occ & ~inner).nonzero()
    size = np.array(occ.shape)
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
    """Per classified generator level j, style → its latest real crop (1, 1, e_j, e_j, e_j)."""

    def __init__(self, levels: Sequence[int], edges: Sequence[int], n_styles: int) -> None:
        self.levels, self.edges, self.n_styles = tuple(levels), dict(zip(levels, edges)), n_styles
        self.crops: dict[int, dict[int, Tensor]] = {j: {} for j in self.levels}

    def put(self, style: int, targets: dict[int, Tensor], rng: np.random.Generator) -> None:
        """Replace ``style``'s crops with cuts of ``targets`` (level j → (1, 1, X, Y, Z) real target)."""
        for j in self.levels:
            self.crops[j][style] = surface_crop(targets[j], self.edges[j], rng).detach().clone()

    def styles(self) -> list[int]:
        """The styles that have crops, in index order."""
        return sorted(self.crops[self.levels[0]]) if self.levels else []

    def ready(self) -> bool:
        """At least two styles to tell apart."""
        return len(self.styles()) >= 2

    def batch(self, j: int) -> tuple[Tensor, Tensor]:
        """Level j's crops (B, 1, e, e, e) in style order and their styles (B,) int64."""
        styles = self.styles()
        return torch.cat([self.crops[j][s] for s in styles]), torch.tensor(styles, dtype=torch.int64)

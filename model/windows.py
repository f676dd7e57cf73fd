"""Running the generator's fine levels on parts of the grid: exact windows and blockwise inference.

The generator is fully convolutional and its fine levels only see local context,
so levels ``≥ j0`` can be evaluated on a window of coarse cells from the features
that level ``j0`` receives, cut to the window plus a halo of ``halo_cells`` cells:
the result on the window equals the whole-grid result (up to float rounding).

- Training (``window_forward``) runs the coarse levels on the whole shape and the
  fine ones on one random window around the surface.
- Inference (``blockwise_forward``) covers the grid with blocks of
  ``block_cells``³ coarse cells, so the fine levels' memory is bounded by the block
  (long text grids), and may skip blocks whose cells and halo are all empty: the
  generator's output there is whatever it makes of empty space, which the pipeline
  binarises at 0.4 to nothing, so skipped blocks are written as 0.
- Column ranges (``TrunkFeatures``): the trunk once, then the fine levels block by block
  on any x range of columns; ``blockwise_forward`` is the whole range.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from model.config import ModelConfig, Upsampler

if TYPE_CHECKING:  # torch stays out of this module's import: model/infer.py must load without it
    from torch import Tensor

    from model.networks import Generator

#: A window of coarse cells (x, y, z slices).
Window = tuple[slice, slice, slice]


def halo_cells(cfg: ModelConfig, whole_levels: int) -> int:
    """Coarse cells of context around a window that make the windowed levels exact.

    Cutting the features at level ``whole_levels``'s input treats everything outside
    the cut as zero; that error spreads inwards by (conservatively) 2c + 2 voxels per
    transposed conv (2(c + 1) per voxel-shuffle conv), +1 per 3³ conv, +1 for the head.
    The halo is the largest such depth over the windowed levels that have an output
    (``cfg.supervised_levels``), in coarse cells (1 for the lean layout cut at level 2,
    3 when every level is windowed).
    """
    c, need = 0, 0
    for j in range(whole_levels, cfg.n_levels):
        lv = cfg.levels[j]
        c = (2 * c + 2 if lv.upsampler is Upsampler.CONV_TRANSPOSE else 2 * (c + 1)) + lv.n_convs
        if j in cfg.supervised_levels:
            need = max(need, math.ceil((c + lv.head_kernel // 2) / 2 ** (j + 1)))
    return need


def _trunk(gen: "Generator", occupancy: "Tensor", part_onehot: "Tensor | None", z: "Tensor", whole_levels: int,
           keep: bool) -> "tuple[Tensor, Tensor, list[Tensor]]":
    """Backbone + levels ``< whole_levels`` on the whole grid (``Generator.trunk`` and ``run_levels``).

    Returns (features entering level ``whole_levels`` (1, C, 2^w·X, …), conditioning
    (1, K, X, Y, Z), outputs of the supervised whole levels if ``keep`` else []).
    """
    x, cond = gen.trunk(occupancy, part_onehot, z)
    x, outs = gen.run_levels(x, cond, 0, whole_levels, all_heads=keep, occupancy=occupancy)
    return x, cond, [o for _, o in outs]


def fine_on_window(gen: "Generator", x: "Tensor", cond: "Tensor", occupancy: "Tensor", whole_levels: int,
                   window: Window, halo: int, keep: bool) -> "list[Tensor]":
    """Levels ``≥ whole_levels`` on ``window`` (+ halo, clamped to the grid); outputs cropped to the window.

    Args:
        x, cond: the whole grid's features entering level ``whole_levels`` and its
            conditioning (``_trunk``); several windows may share them (one trunk forward).
        occupancy: (1, 1, X, Y, Z) the whole coarse occupancy (``cfg.output_mask``).
        halo: ``halo_cells(gen.cfg, whole_levels)``.
        keep: every windowed supervised level's output; False: only the last level's
            (a one-element list).
    Returns:
        per output level j, (1, 1, 2^(j+1)·w, …) for the window's w cells per axis.
    """
    fmt = gen.memory_format
    shape = cond.shape[2:]
    lo = [max(0, w.start - halo) for w in window]
    hi = [min(n, w.stop + halo) for w, n in zip(window, shape)]
    r = 2**whole_levels
    x = x[:, :, lo[0] * r : hi[0] * r, lo[1] * r : hi[1] * r, lo[2] * r : hi[2] * r].contiguous(memory_format=fmt)
    cond = cond[:, :, lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]].contiguous(memory_format=fmt)
    occ = occupancy[:, :, lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]
    _, outs = gen.run_levels(x, cond, whole_levels, all_heads=keep, occupancy=occ)
    return [out[:, :, *(slice((w.start - a) * 2 ** (j + 1), (w.stop - a) * 2 ** (j + 1)) for w, a in zip(window, lo))]
            for j, out in outs]


def window_forward(gen: "Generator", occupancy: "Tensor", part_onehot: "Tensor | None", z: "Tensor",
                   whole_levels: int, window: Window | None) -> "list[Tensor]":
    """The generator's forward with levels ``≥ whole_levels`` evaluated only on a coarse window.

    Levels ``< whole_levels`` see the whole grid. At the first windowed level the
    features are cut to the window plus ``halo_cells`` coarse cells (clamped to the
    grid), and every windowed output is cropped back to the window, so output j of a
    windowed level equals the whole-shape output restricted to the window (up to
    float rounding). ``window=None`` is ``gen(...)``.

    Returns:
        per supervised level j (``cfg.supervised_levels``), (1, 1, 2^(j+1)·w, …) where w is
        the whole grid (``j < whole_levels``) or the window (otherwise).
    """
    if window is None:
        return gen(occupancy, part_onehot, z)
    return windows_forward(gen, occupancy, part_onehot, z, whole_levels, [window])[0]


def windows_forward(gen: "Generator", occupancy: "Tensor", part_onehot: "Tensor | None", z: "Tensor",
                    whole_levels: int, windows: "list[Window]") -> "list[list[Tensor]]":
    """``window_forward`` for several windows of one shape sharing one trunk forward.

    The backbone and levels ``< whole_levels`` run once on the whole grid; the finer
    levels run once per window. Returns, per window, the list ``window_forward`` gives
    (the whole levels' output tensors are the same objects in every list).
    """
    x, cond, outs = _trunk(gen, occupancy, part_onehot, z, whole_levels, keep=True)
    halo = halo_cells(gen.cfg, whole_levels)
    return [outs + fine_on_window(gen, x, cond, occupancy, whole_levels, w, halo, keep=True) for w in windows]


def blockwise_forward(gen: "Generator", occupancy: "Tensor", part_onehot: "Tensor | None", z: "Tensor", *,
                      block_cells: int = 8, whole_levels: int = 2, skip_empty: bool = True) -> "Tensor":
    """The last level's output (1, 1, f·X, f·Y, f·Z), its fine levels run block by block.

    Args:
        occupancy, part_onehot, z: the generator's inputs for one shape (batch 1).
        block_cells: block edge in coarse cells (8 → 128³ fine voxels a block).
        whole_levels: levels run on the whole grid before the blocks (2: 32³ and 64³).
        skip_empty: blocks whose cells and halo hold no occupied cell are not run (left 0).
    Equal to ``gen(..., final_only=True)[-1]`` up to float rounding when ``skip_empty`` is False.
    """
    trunk = TrunkFeatures.run(gen, occupancy, part_onehot, z, whole_levels)
    return trunk.columns(0, occupancy.shape[2], block_cells=block_cells, skip_empty=skip_empty)


class TrunkFeatures:
    """The coarse part of one forward (backbone and levels ``< whole_levels`` on the whole grid), from which
    the fine levels are run on any range of x columns (``columns``), block by block.

    Split this way, a shape's fine levels can be run in parts — in two processes, say — that share one trunk:
    the columns of each part equal the whole forward's there (up to float rounding), and a part's bytes do not
    depend on which other parts are run, or where.
    """

    def __init__(self, gen: "Generator", x: "Tensor", cond: "Tensor", occupancy: "Tensor", whole_levels: int) -> None:
        self.gen, self.x, self.cond, self.occupancy, self.whole_levels = gen, x, cond, occupancy, whole_levels

    @classmethod
    def run(cls, gen: "Generator", occupancy: "Tensor", part_onehot: "Tensor | None", z: "Tensor",
            whole_levels: int = 2) -> "TrunkFeatures":
        """Run the trunk on one shape's inputs (batch 1); ``whole_levels`` is clamped to [0, levels − 1]."""
        whole_levels = min(max(whole_levels, 0), gen.cfg.n_levels - 1)
        x, cond, _ = _trunk(gen, occupancy, part_onehot, z, whole_levels, keep=False)
        return cls(gen, x, cond, occupancy, whole_levels)

    def columns(self, x0: int, x1: int, *, block_cells: int = 8, skip_empty: bool = True) -> "Tensor":
        """The last level's output on coarse columns ``[x0, x1)``: (1, 1, f·(x1 − x0), f·Y, f·Z).

        The columns are covered by blocks of ``block_cells``³ coarse cells (from ``x0``); with ``skip_empty``,
        blocks whose cells and halo hold no occupied cell are not run (left 0).
        """
        import torch

        gen, x, cond, occupancy, whole = self.gen, self.x, self.cond, self.occupancy, self.whole_levels
        halo = halo_cells(gen.cfg, whole)
        shape = tuple(occupancy.shape[2:])
        f = gen.cfg.factor
        out = torch.zeros((1, 1, (x1 - x0) * f, shape[1] * f, shape[2] * f), dtype=x.dtype, device=x.device)
        occ = occupancy[0, 0] > 0
        for bx in range(x0, x1, block_cells):
            for by in range(0, shape[1], block_cells):
                for bz in range(0, shape[2], block_cells):
                    window = (slice(bx, min(bx + block_cells, x1)), slice(by, min(by + block_cells, shape[1])),
                              slice(bz, min(bz + block_cells, shape[2])))
                    if skip_empty:
                        near = tuple(slice(max(0, w.start - halo), w.stop + halo) for w in window)
                        if not bool(occ[near].any()):
                            continue
                    block = fine_on_window(gen, x, cond, occupancy, whole, window, halo, keep=False)[0]
                    out[:, :, *(slice((w.start - o) * f, (w.stop - o) * f) for w, o in zip(window, (x0, 0, 0)))] = block
        return out

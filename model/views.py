"""What the losses see of a training sample: fine-level windows and per-level crops.

Levels ``< whole_levels`` of the generator run on the whole sample, the finer ones
on windows of coarse cells around the surface (``model/windows.py`` runs them
exactly). ``SampleView`` gives, for one window, every loss input of a level —
target, discriminator-output masks, adaptive-α map, the previous level's grid —
cut to the cells that level covers, so ``model/losses.py``'s assembly sees whole
levels and windowed levels alike.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.ndimage import binary_erosion

from model.config import ModelConfig
from model.data import Sample
from model.masks import DOutputMasks, StyledCoarse, align_to_d_output, alpha_map, joint_mask
from model.windows import Window
from core.errors import DetailizeError


def surface_window(coarse_occ: np.ndarray, cells: int, rng: np.random.Generator) -> Window:
    """A ``cells``³ window of coarse cells (whole axis where the grid is smaller) around a random surface cell.

    Surface cells are occupied cells with an empty 6-neighbour (all occupied cells if none).
    """
    surface = coarse_occ & ~binary_erosion(coarse_occ, border_value=0)
    cand = np.argwhere(surface if surface.any() else coarse_occ)
    centre = cand[int(rng.integers(len(cand)))]
    out = []
    for c, n in zip(centre, coarse_occ.shape):
        w = min(cells, n)
        lo = int(np.clip(c - w // 2, 0, n - w))
        out.append(slice(lo, lo + w))
    return tuple(out)  # type: ignore[return-value]


def check_window(cfg: ModelConfig, whole_levels: int, cells: int) -> None:
    """Refuse a window too small for the windowed levels' discriminators."""
    for j, d in zip(cfg.supervised_levels, cfg.discriminators):
        if j >= whole_levels and d.output_size(cells * 2 ** (j + 1)) < 1:
            raise DetailizeError(f"a window of {cells} coarse cells is too small for the level-{j} discriminator",
                                 field="window_cells", hint="use a larger window_cells, or 0 for whole shapes")


class SampleView:
    """A sample as the losses see it: whole grid for levels ``< whole_levels``, the window for finer ones.

    Gives per level the (1, 1, …) target tensor, the discriminator-output masks, the
    adaptive-α map and the crop of the previous level, all on the same cells.
    """

    def __init__(self, sample: Sample, window: Window | None, whole_levels: int, device) -> None:
        self.sample, self.window, self.device = sample, window, device
        self.whole_levels = whole_levels if window is not None else 10**6
        self._joints = None

    def _cells(self, j: int) -> Window | None:
        return self.window if j >= self.whole_levels else None

    def _crop(self, arr: np.ndarray, j: int, factor: int) -> np.ndarray:
        w = self._cells(j)
        return arr if w is None else arr[tuple(slice(s.start * factor, s.stop * factor) for s in w)]

    def target(self, j: int):
        t = self.sample.target(j, self._cells(j))
        return torch.from_numpy(np.ascontiguousarray(t))[None, None].to(self.device)

    def styled(self, j: int) -> StyledCoarse:
        s = self.sample
        return StyledCoarse(self._crop(s.coarse_occupancy, j, 1), self._crop(s.coarse_labels, j, 1).astype(np.int64),
                            s.assignment)

    def output_styles(self, j: int) -> torch.Tensor:
        """The style of every voxel of level j's output on these cells, (X, Y, Z) int64 at 2^(j+1)× the cells
        (every cell's part's assigned style; empty cells carry their nearest part's, as the labels do)."""
        st = self.styled(j)
        cells = torch.as_tensor(np.asarray(st.assignment, dtype=np.int64)[st.labels])
        f = 2 ** (j + 1)
        return cells.repeat_interleave(f, 0).repeat_interleave(f, 1).repeat_interleave(f, 2).to(self.device)

    def masks(self, j: int, d_shape: tuple[int, ...], cfg: ModelConfig) -> DOutputMasks:
        m = self.styled(j).masks(j, cfg.discriminator(j), d_shape, cfg.n_styles)
        return DOutputMasks(m.style[None], m.global_[None])

    def alpha(self, j: int, d_shape: tuple[int, ...], cfg: ModelConfig):
        lc = cfg.losses
        if self._joints is None:
            self._joints = joint_mask(self.sample.fine_labels, cfg.factor, lc.joint_radius)
        a = alpha_map(self._crop(self._joints, j, 1), lc.alpha_joint, lc.alpha_other)
        return align_to_d_output(a[None], j, cfg.discriminator(j), d_shape)[None]

    def crop_prev(self, prev, j: int, j_prev: int | None = None):
        """Level ``j_prev``'s output (default j−1; −1 = the coarse input) cut to the cells level j covers."""
        j_prev = j - 1 if j_prev is None else j_prev
        if self._cells(j) is None or self._cells(j_prev) is not None:
            return prev
        r = 2 ** (j_prev + 1)  # prev is at 2^(j_prev+1) × coarse
        return prev[:, :, *(slice(s.start * r, s.stop * r) for s in self.window)]

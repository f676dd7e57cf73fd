"""Self-reconstruction: can a detailizer give back its own style shapes from their coarse versions?

Cases (``self_cases``), for every exemplar e of the style set:

* ``self/<name>``: the exemplar itself (its labels at the set's resolution,
  placed at a seeded sub-cell offset with one empty coarse cell a side);
* ``aug<k>/<name>``: ``N_AUG`` held-out augmentations of it (``model.data``'s
  ``augment_exemplar``: anisotropic scale, rotation about +Y), drawn with
  ``HELD_OUT_SEED``, a seed no training run uses.

Each case's coarse grid is the ×16 max-pool of its fine shape with the
majority part per cell, every part in the exemplar's own style. Figures per
case (``case_figures`` and the LP search of ``evaluation/detail.py`` with
the exemplar as every patch's owner):

* IOU at full resolution between the detailized output (binarised at
  ISO_LEVEL) and the true fine shape;
* LP-detail and LP-IOU against the own exemplar;
* Chamfer distance between the two surfaces, in fine voxels: the mean of the
  two directed mean nearest-neighbour distances between ``CHAMFER_POINTS``
  seeded samples of each surface's voxels.

The augmented cases are also the shape-matched Cls's real shapes (their true
fine shapes) and fake shapes (the detailizer's outputs from their coarse
grids): only detail tells them apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.grid import EMPTY, LabeledGrid
from evaluation.render_eval import exposed_voxels

#: Held-out augmentations per exemplar.
N_AUG: int = 2
#: Surface voxels sampled a side for the Chamfer distance.
CHAMFER_POINTS: int = 20_000
#: Stream of the case draws under the held-out seed (the protocol's augmentations use 1000 + k).
_CASE_STREAM = 3000


@dataclass(frozen=True, eq=False)
class SelfCase:
    """One self-reconstruction case.

    Attributes:
        id: ``self/<exemplar>`` or ``aug<k>/<exemplar>``.
        exemplar: index of the exemplar in the set (its style).
        name: the exemplar's name.
        held_out: True for an augmentation.
        labels: (16·X, 16·Y, 16·Z) int16 true fine shape, ``EMPTY`` or a part index.
    """

    id: str
    exemplar: int
    name: str
    held_out: bool
    labels: np.ndarray

    @property
    def fine(self) -> np.ndarray:
        """(16·X, 16·Y, 16·Z) bool true occupancy."""
        return self.labels != EMPTY

    def grid(self, part_names: tuple[str, ...], factor: int = 16, voxel_size_m: float = 0.1) -> LabeledGrid:
        """The coarse LabeledGrid: max-pooled occupancy, majority part, every cell in the exemplar's style."""
        from model.masks import coarse_part_labels

        occ = self.fine
        x, y, z = (n // factor for n in occ.shape)
        coarse = occ.reshape(x, factor, y, factor, z, factor).any(axis=(1, 3, 5))
        part = np.where(coarse, coarse_part_labels(self.labels, factor, len(part_names)), EMPTY).astype(np.int16)
        style = np.where(coarse, 0, EMPTY).astype(np.int16)
        return LabeledGrid(occupancy=coarse, part=part, style=style, part_names=tuple(part_names),
                           style_names=(self.name,), voxel_size_m=voxel_size_m)


def self_cases(style_set, seed: int | None = None, n_aug: int = N_AUG, factor: int = 16) -> list[SelfCase]:
    """Every exemplar as itself, then ``n_aug`` held-out augmentations of each (see the module docstring)."""
    from evaluation.protocol import HELD_OUT_SEED
    from model.data import AugmentConfig, augment_exemplar, crop_to_bbox, exemplars_from_set, place_in_crop

    seed = HELD_OUT_SEED if seed is None else seed
    exemplars = exemplars_from_set(style_set)
    aug = AugmentConfig(resolution=style_set.resolution)
    cases = []
    for e, ex in enumerate(exemplars):
        rng = np.random.default_rng([seed, _CASE_STREAM, e])
        cases.append(SelfCase(f"self/{ex.name}", e, ex.name, False,
                              place_in_crop(crop_to_bbox(ex.labels), rng, factor, margin=1)))
    for k in range(n_aug):
        for e, ex in enumerate(exemplars):
            rng = np.random.default_rng([seed, _CASE_STREAM + 1 + k, e])
            shape = augment_exemplar(ex, rng, aug)
            cases.append(SelfCase(f"aug{k}/{ex.name}", e, ex.name, True, place_in_crop(shape, rng, factor, margin=1)))
    return cases


def fine_iou(output: np.ndarray, truth: np.ndarray) -> float:
    """|O ∧ T| / |O ∨ T| of two same-shape bool grids (1.0 when both are empty)."""
    if output.shape != truth.shape:
        raise ValueError(f"output {output.shape} and truth {truth.shape} differ in shape")
    union = int(np.count_nonzero(output | truth))
    return 1.0 if union == 0 else int(np.count_nonzero(output & truth)) / union


def surface_points(occ: np.ndarray) -> np.ndarray:
    """(n, 3) int coordinates of the occupied voxels with an empty (or outside) 6-neighbour."""
    return np.argwhere(exposed_voxels(np.pad(occ, 1)))


def chamfer(output: np.ndarray, truth: np.ndarray, n: int = CHAMFER_POINTS, seed: int = 0) -> float | None:
    """Symmetric Chamfer distance between the surfaces of two bool grids, in voxels (None if one is empty).

    (mean over the sampled surface voxels of O of the distance to the nearest sampled surface
    voxel of T, plus the same from T to O) / 2; up to ``n`` voxels sampled a side, seeded (with
    fewer surface voxels than ``n`` it is exact; sampling adds at most the samples' spacing).
    """
    from scipy.spatial import cKDTree

    a, b = surface_points(output), surface_points(truth)
    if len(a) == 0 or len(b) == 0:
        return None
    rng = np.random.default_rng(seed)
    pick = (lambda pts: pts if len(pts) <= n else pts[rng.choice(len(pts), n, replace=False)])
    sa, sb = pick(a), pick(b)
    d_ab, _ = cKDTree(sb).query(sa, k=1, workers=1)
    d_ba, _ = cKDTree(sa).query(sb, k=1, workers=1)
    return float((d_ab.mean() + d_ba.mean()) / 2)


def case_figures(output: np.ndarray, case: SelfCase) -> dict:
    """IOU at full resolution and Chamfer distance of one detailized case (LP figures come from the search)."""
    truth = case.fine
    return {"iou": fine_iou(output, truth), "chamfer": chamfer(output, truth, seed=case.exemplar)}

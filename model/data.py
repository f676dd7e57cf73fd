"""Training data for DECOLLAGE: exemplars in memory and seeded on-the-fly augmentation (the published DECOLLAGE code's, with its issues fixed).

Role: turn a list of part-labelled style exemplars into training samples — a
coarse input (occupancy + part labels + per-part style assignment) and one
smoothed occupancy target per generator level — with every random choice drawn
from ``numpy.random.Generator`` seeded by ``(seed, step, stream)`` (no global RNG),
so sample ``step`` of a run is the same whenever it is drawn (also after a resume).

This module does not read dataset files: ``Exemplar`` is a minimal in-memory type
that a loader (``stylesets/format.py``'s sets) converts into.

Label convention: ``labels`` arrays are int16, ``EMPTY`` (−1) where unoccupied,
else an index into the *set-level* part vocabulary shared by all exemplars
(e.g. ``("bottom", "top")``). Style index s = position of exemplar s in the list.

Augmentation of one exemplar (``augment_exemplar``), fixing the reference's issues:

1. crop to the bounding box;
2. scale each axis by ``base · U(0.7, 2.0)``, where ``base`` = resolution /
   exemplar resolution (1 at 256³; lets training run at reduced resolution);
3. if the largest side exceeds ``0.7 · R``, shrink uniformly to fit;
4. resample: geometry = trilinear interpolation of the 0/1 occupancy, kept where
   > 0.3 (the reference's threshold); labels are resampled by *nearest* and
   voxels the trilinear geometry adds get the label of the nearest labelled voxel
   (never interpolated, so no intermediate label can appear at a part border, and
   every label comes from the source);
5. a random multiple of 90° about the vertical (Y) axis.

``augmented_sample`` then, with probability 0.5, combines two *different*
exemplars (the second shifted along x and z by ``[0, u·extent)``, u ~ U(0.3, 0.7),
bottoms aligned in y; where both are occupied the first keeps its label), refits
the union to ``0.7 · R`` by nearest and rotates it again by k·90°. Each part then
gets a random style among the exemplars that have that part.

Cropping (``place_in_crop``): the shape is put at a random sub-cell offset in
[0, factor) per axis inside its coarse bounding box, plus a margin of one empty
coarse cell per side, so the fine crop is ``(cells + 2) · factor`` per axis (more
empty cells where that is below ``min_coarse_cells``, the smallest extent every
discriminator can see) and the coarse input is its ×factor max-pool. Level j's target (j = 0 … L−1, at
``2^(j+1)`` × coarse) is the max-pool of the fine crop by ``factor / 2^(j+1)``,
smoothed by a Gaussian of σ = 1 (+ the reference's progressive residual passes
when ``ModelConfig.losses.target_smoothing`` says so).

Cost (2 shared cores, box exemplars): ≈ 2 s per augmented sample at R = 256
(≈ 0.6 s per exemplar resample, mostly the nearest-label fill; ≈ 0.85 s for the
smoothed targets), ≈ 0.8 s at R = 128; a style sample ≈ 0.7–1.5 s / 0.25 s.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from model.config import LossConfig, ModelConfig, TargetSmoothing
from model.masks import StyledCoarse, coarse_part_labels, fill_nearest
from core.errors import DetailizeError
from core.grid import EMPTY, ISO_LEVEL


@dataclass(frozen=True, eq=False)
class Exemplar:
    """One style exemplar in memory.

    Attributes:
        name: style name (unique within a set).
        category: e.g. ``"building"``.
        labels: (X, Y, Z) int16, ``EMPTY`` where unoccupied, else an index into ``part_names``;
            each side ≤ ``resolution``. +Y is up.
        part_names: the set-level part vocabulary (same tuple for every exemplar of a set).
        resolution: edge of the cube the exemplar was voxelized in (256 for the datasets).
    """

    name: str
    category: str
    labels: np.ndarray
    part_names: tuple[str, ...]
    resolution: int = 256

    def __post_init__(self) -> None:
        lab = self.labels
        if lab.ndim != 3 or not np.issubdtype(lab.dtype, np.integer):
            raise DetailizeError(f"exemplar {self.name!r}: labels must be a 3-D integer array, got {lab.dtype} "
                                 f"{lab.shape}", field="labels", hint="use int16 with -1 for empty voxels")
        if not (lab != EMPTY).any():
            raise DetailizeError(f"exemplar {self.name!r} is empty", field="labels", hint="voxelize it again")
        if lab.min() < EMPTY or lab.max() >= len(self.part_names):
            raise DetailizeError(f"exemplar {self.name!r}: labels outside [-1, {len(self.part_names)})",
                                 field="labels", hint="labels index the set's part vocabulary")

    @functools.cached_property
    def parts(self) -> tuple[int, ...]:
        """Part indices this exemplar has (sorted; computed once: a 256³ ``np.unique`` costs ~15 ms)."""
        return tuple(int(p) for p in np.unique(self.labels) if p != EMPTY)


@dataclass(frozen=True)
class AugmentConfig:
    """Augmentation settings (defaults are the published code's).

    Attributes:
        resolution: R, the fine grid edge the shapes are sized for (256; smaller for cheap training).
        scale_range: per-axis random scale.
        max_side_frac: largest allowed side, as a fraction of R.
        threshold: trilinear occupancy kept above this.
        rotate: random k·90° about +Y.
        combine_prob: probability of combining two different exemplars.
        offset_range: range of u, the second shape's x/z shift as a fraction of the first's extent.
        style_offset: where every style sample (``style_sample``: reconstruction steps, D's
            "real", the monitor's exemplars) sits relative to the coarse cells. None = a random
            sub-cell offset per sample (this project's first choice, not the reference's);
            ``CENTRE`` = the reference's placement: the exemplar centre-padded in an R³ grid
            (offset ((R − n) // 2) mod f per axis, n its extent in fine voxels), one fixed
            offset per exemplar; 3 ints in [0, factor) = that one offset for every exemplar
            (the overfit diagnostic). With a fixed placement, each reconstruction of an
            exemplar is the same input and target, so its fine detail is a function of its
            coarse grid that a local network can fit; with a random one the same coarse grid
            has targets shifted by up to f − 1 voxels, whose mean is a blur.
    """

    resolution: int = 256
    scale_range: tuple[float, float] = (0.7, 2.0)
    max_side_frac: float = 0.7
    threshold: float = 0.3
    rotate: bool = True
    combine_prob: float = 0.5
    offset_range: tuple[float, float] = (0.3, 0.7)
    style_offset: tuple[int, int, int] | str | None = None

    @property
    def max_side(self) -> int:
        return max(1, int(self.max_side_frac * self.resolution))


@dataclass(frozen=True, eq=False)
class Sample:
    """One training sample (a cropped shape with a per-part style assignment).

    Attributes:
        fine_labels: (f·X, f·Y, f·Z) int16 fine crop, ``EMPTY`` where unoccupied.
        coarse_occupancy: (X, Y, Z) bool, the ×f max-pool of the crop (margin cells empty).
        coarse_labels: (X, Y, Z) int16 part per coarse cell (majority; empty cells nearest-filled).
        assignment: (P,) style index of every part.
        sources: names of the exemplars the shape was made of.
        loss_config, n_levels, factor: how targets are made (``targets``, ``target``).
    """

    fine_labels: np.ndarray
    coarse_occupancy: np.ndarray
    coarse_labels: np.ndarray
    assignment: tuple[int, ...]
    sources: tuple[str, ...]
    loss_config: LossConfig
    n_levels: int
    factor: int

    @property
    def targets(self) -> tuple[np.ndarray, ...]:
        """Per level j, (2^(j+1)·X, …) float32 smoothed occupancy in [0, 1] of the whole crop."""
        return tuple(self.target(j) for j in range(self.n_levels))

    def target(self, j: int, cells: "tuple[slice, slice, slice] | None" = None) -> np.ndarray:
        """Level j's target, or only its part over the coarse ``cells`` (equal to cutting ``target(j)``).

        Whole-crop targets are computed once per level and kept. Training windows the
        fine levels, and smoothing a whole 256³ crop for a 64³ window wastes ~20× the
        work: a window is smoothed with a halo of the filter's reach (4σ per pass, every
        residual pass adds one), clipped to the crop, whose border is zero-padded in
        both cases, so the values are the same.
        """
        whole = self.__dict__.setdefault("_whole_targets", {})
        if cells is None or j in whole:
            if j not in whole:
                whole[j] = smooth_target(max_pool(self.fine_labels != EMPTY, self.factor // 2 ** (j + 1)),
                                         self.loss_config)
            r = 2 ** (j + 1)
            return whole[j] if cells is None else whole[j][tuple(slice(c.start * r, c.stop * r) for c in cells)]
        lc, r = self.loss_config, 2 ** (j + 1)
        k = self.factor // r
        passes = lc.smoothing_passes if lc.target_smoothing is TargetSmoothing.PROGRESSIVE else 0
        halo = int(4.0 * lc.smoothing_sigma + 0.5) * (passes + 1)  # scipy's truncate = 4 radius, per pass
        size = [n * r for n in self.coarse_occupancy.shape]
        lo = [max(0, c.start * r - halo) for c in cells]
        hi = [min(n, c.stop * r + halo) for c, n in zip(cells, size)]
        fine = self.fine_labels[tuple(slice(a * k, b * k) for a, b in zip(lo, hi))] != EMPTY
        t = smooth_target(max_pool(fine, k), lc)
        return t[tuple(slice(c.start * r - a, c.stop * r - a) for c, a in zip(cells, lo))]

    def keep_targets(self, levels: Sequence[int]) -> "Sample":
        """Compute and keep the whole-crop targets of ``levels`` (later ``target`` calls cut them; they
        travel with the sample when pickled). Returns the sample."""
        for j in levels:
            self.target(j)
        return self

    def style_index(self) -> np.ndarray:
        """(X, Y, Z) int64 style of every coarse cell (through its part), the generator's style input."""
        return np.asarray(self.assignment, dtype=np.int64)[self.coarse_labels]

    def styled(self) -> StyledCoarse:
        """The masks' view of this sample (``model.masks.StyledCoarse``)."""
        return StyledCoarse(self.coarse_occupancy, self.coarse_labels.astype(np.int64), self.assignment)


# ----------------------------------------------------------------------------- RNG


def rng_for(seed: int, step: int, stream: int = 0) -> np.random.Generator:
    """Independent generator for (run seed, step, stream): the same triple always gives the same draws."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(step), int(stream)]))


# ----------------------------------------------------------------------------- geometry helpers


def crop_to_bbox(labels: np.ndarray) -> np.ndarray:
    """The occupied bounding box of ``labels`` (a view)."""
    occ = labels != EMPTY
    box = []
    for axis in range(3):
        idx = np.flatnonzero(occ.any(axis=tuple(a for a in range(3) if a != axis)))
        box.append(slice(int(idx[0]), int(idx[-1]) + 1))
    return labels[tuple(box)]


def resample_labels(labels: np.ndarray, size: Sequence[int], threshold: float = 0.3) -> np.ndarray:
    """Resample a label grid to ``size``: trilinear geometry (> threshold), nearest labels.

    Voxels that the trilinear geometry adds beyond the nearest-resampled labels take
    the label of the nearest labelled voxel; so every output label exists in the input
    and part borders never get intermediate values.

    Args:
        labels: (X, Y, Z) int, ``EMPTY`` where unoccupied.
        size: output (X', Y', Z'), each ≥ 1.
    Returns:
        (X', Y', Z') int16.
    """
    import torch
    from torch.nn import functional as F

    size = tuple(max(1, int(n)) for n in size)
    if size == labels.shape:
        return labels.astype(np.int16, copy=True)
    lab = torch.from_numpy(np.ascontiguousarray(labels, dtype=np.float32))[None, None]
    occ = (lab >= 0).float()
    geom = F.interpolate(occ, size=size, mode="trilinear", align_corners=False)[0, 0].numpy() > threshold
    # 'nearest-exact' samples at voxel centres, the same alignment as trilinear with align_corners=False.
    near = F.interpolate(lab, size=size, mode="nearest-exact")[0, 0].numpy().astype(np.int16)
    labelled = near != EMPTY
    if not geom.any():  # a thin shape shrunk below the threshold: keep what nearest sampling found
        geom = labelled
    if not labelled.any():  # nothing survived at all (tiny output): one voxel of the most common part
        vals, counts = np.unique(labels[labels != EMPTY], return_counts=True)
        out = np.full(size, EMPTY, dtype=np.int16)
        out[tuple(n // 2 for n in size)] = vals[np.argmax(counts)]
        return out
    if (geom & ~labelled).any():
        near = fill_nearest(near, labelled)
    return np.where(geom, near, EMPTY).astype(np.int16)


def fit_max_side(labels: np.ndarray, max_side: int) -> np.ndarray:
    """Shrink uniformly (nearest labels, no interpolation) so that no side exceeds ``max_side``."""
    m = max(labels.shape)
    if m <= max_side:
        return labels
    import torch
    from torch.nn import functional as F

    size = tuple(max(1, int(round(n * max_side / m))) for n in labels.shape)
    lab = torch.from_numpy(np.ascontiguousarray(labels, dtype=np.float32))[None, None]
    out = F.interpolate(lab, size=size, mode="nearest-exact")[0, 0].numpy().astype(np.int16)
    return out if (out != EMPTY).any() else resample_labels(labels, size)


def rotate_y(labels: np.ndarray, k: int) -> np.ndarray:
    """Rotate by k·90° about the vertical (Y) axis, i.e. in the x–z plane."""
    return np.ascontiguousarray(np.rot90(labels, k % 4, axes=(0, 2)))


def augment_exemplar(ex: Exemplar, rng: np.random.Generator, aug: AugmentConfig) -> np.ndarray:
    """Crop, anisotropic scale, fit to 0.7·R, resample (nearest labels), random rotation about Y.

    Returns:
        (X, Y, Z) int16 labels cropped to their bounding box.
    """
    lab = crop_to_bbox(ex.labels)
    base = aug.resolution / ex.resolution
    lo, hi = aug.scale_range
    scale = base * rng.uniform(lo, hi, size=3)
    size = np.maximum(1, np.round(np.asarray(lab.shape) * scale)).astype(int)
    if size.max() > aug.max_side:  # shrink uniformly, keeping the drawn aspect ratio
        size = np.maximum(1, np.floor(size * aug.max_side / size.max())).astype(int)
    out = crop_to_bbox(resample_labels(lab, size, aug.threshold))
    if aug.rotate:
        out = rotate_y(out, int(rng.integers(4)))
    return out


def combine(a: np.ndarray, b: np.ndarray, rng: np.random.Generator, aug: AugmentConfig) -> np.ndarray:
    """Union of two shapes: ``b`` shifted along x and z by ``[0, u·extent of a)``, bottoms aligned in y.

    Where both are occupied ``a`` keeps its label (a choice, not an average). The union
    is refit to ``0.7·R`` (nearest) and rotated by a random k·90° about Y.
    """
    u = rng.uniform(*aug.offset_range)
    dx = int(rng.integers(0, max(1, int(u * a.shape[0]))))
    dz = int(rng.integers(0, max(1, int(u * a.shape[2]))))
    shape = (max(a.shape[0], dx + b.shape[0]), max(a.shape[1], b.shape[1]), max(a.shape[2], dz + b.shape[2]))
    out = np.full(shape, EMPTY, dtype=np.int16)
    out[dx : dx + b.shape[0], : b.shape[1], dz : dz + b.shape[2]] = b
    occ_a = a != EMPTY
    region = out[: a.shape[0], : a.shape[1], : a.shape[2]]
    region[occ_a] = a[occ_a]
    out = fit_max_side(out, aug.max_side)
    if aug.rotate:
        out = rotate_y(out, int(rng.integers(4)))
    return crop_to_bbox(out)


def place_in_crop(labels: np.ndarray, rng: np.random.Generator, factor: int, margin: int = 1,
                  min_cells: int = 1) -> np.ndarray:
    """Put a bbox-cropped shape at a random sub-cell offset inside its coarse bbox plus ``margin`` empty cells.

    Axes with fewer than ``min_cells`` coarse cells (bbox + margins) get extra empty
    cells, split evenly before/after, so every discriminator has at least one output.

    Returns:
        (f·cells_x, …) int16 fine crop; its ×f max-pool is the coarse bbox with a margin.
    """
    return place_at(labels, rng.integers(0, factor, size=3), factor, margin, min_cells)


#: ``AugmentConfig.style_offset`` value for the reference's placement of a style shape (centre-padded in R³).
CENTRE = "centre"


def parse_style_offset(value: object) -> tuple[int, int, int] | str | None:
    """A ``style_offset`` as read from JSON or a checkpoint: None, ``CENTRE``, or a list of 3 ints → tuple."""
    if value is None or value == CENTRE:
        return value  # type: ignore[return-value]
    if isinstance(value, str):
        raise DetailizeError(f"style_offset {value!r} is not known", field="style_offset",
                             hint=f'use "{CENTRE}", 3 sub-cell offsets such as [5, 6, 5], or null (random)')
    return tuple(int(o) for o in value)  # type: ignore[union-attr]


def centre_offset(extent: Sequence[int], resolution: int, factor: int) -> tuple[int, int, int]:
    """The sub-cell offset of a shape of ``extent`` fine voxels centre-padded in a ``resolution``³ grid.

    The reference pads every style shape to R³ around its centre (start (R − n) // 2 per axis);
    relative to the ×f coarse cells that start is ((R − n) // 2) mod f. Extents above R use 0.
    """
    return tuple(max(0, (resolution - int(n)) // 2) % factor for n in extent)  # type: ignore[return-value]


def place_at(labels: np.ndarray, offset: Sequence[int], factor: int, margin: int = 1,
             min_cells: int = 1) -> np.ndarray:
    """``place_in_crop`` at a given sub-cell ``offset`` (3 ints in [0, factor)) instead of a random one."""
    bbox_cells = [math.ceil((int(o) + n) / factor) for o, n in zip(offset, labels.shape)]
    pad_before = [margin + max(0, min_cells - c - 2 * margin) // 2 for c in bbox_cells]
    cells = [max(c + 2 * margin, min_cells) for c in bbox_cells]
    out = np.full(tuple(c * factor for c in cells), EMPTY, dtype=np.int16)
    start = [p * factor + int(o) for p, o in zip(pad_before, offset)]
    out[start[0] : start[0] + labels.shape[0], start[1] : start[1] + labels.shape[1],
        start[2] : start[2] + labels.shape[2]] = labels
    return out


def min_coarse_cells(cfg: ModelConfig) -> int:
    """Smallest coarse extent (≥ 3: one bbox cell + margins) for which every level's discriminator has an output."""
    c = 3
    while any(d.output_size(c * 2 ** (j + 1)) < 1 for j, d in zip(cfg.supervised_levels, cfg.discriminators)):
        c += 1
    return c


# ----------------------------------------------------------------------------- targets


def max_pool(binary: np.ndarray, k: int) -> np.ndarray:
    """(X, Y, Z) bool → (X/k, Y/k, Z/k) bool (any)."""
    if k == 1:
        return binary
    x, y, z = (n // k for n in binary.shape)
    return binary.reshape(x, k, y, k, z, k).any(axis=(1, 3, 5))


def smooth_target(binary: np.ndarray, lc: LossConfig) -> np.ndarray:
    """Gaussian σ of a binary grid; PROGRESSIVE adds ``passes`` Gaussians of the residual at the 0.4 iso.

    The residual passes (the reference code) pull the 0.4 iso-surface of the smoothed
    grid back onto the binary shape, so thin parts survive the blur. Zero outside
    the grid. Returns float32 in [0, 1].
    """
    from scipy.ndimage import gaussian_filter

    b = binary.astype(np.float32)
    s = gaussian_filter(b, lc.smoothing_sigma, mode="constant")
    if lc.target_smoothing is TargetSmoothing.PROGRESSIVE:
        for _ in range(lc.smoothing_passes):
            resid = b - (s > ISO_LEVEL).astype(np.float32)
            s += gaussian_filter(resid, lc.smoothing_sigma, mode="constant")
    return np.clip(s, 0.0, 1.0).astype(np.float32)


# ----------------------------------------------------------------------------- samples


def random_assignment(exemplars: Sequence[Exemplar], n_parts: int, rng: np.random.Generator) -> tuple[int, ...]:
    """Per part, a uniform pick among the exemplars (styles) that have that part (0 if none has it)."""
    out = []
    for p in range(n_parts):
        having = [i for i, ex in enumerate(exemplars) if p in ex.parts]
        out.append(int(rng.choice(having)) if having else 0)
    return tuple(out)


def _finish(fine: np.ndarray, assignment: tuple[int, ...], sources: tuple[str, ...], cfg: ModelConfig) -> Sample:
    f = cfg.factor
    binary = fine != EMPTY
    return Sample(
        fine_labels=fine,
        coarse_occupancy=max_pool(binary, f),
        coarse_labels=coarse_part_labels(fine, f, cfg.n_parts),
        assignment=assignment,
        sources=sources,
        loss_config=cfg.losses,
        n_levels=cfg.n_levels,
        factor=f,
    )


def _check_set(exemplars: Sequence[Exemplar], cfg: ModelConfig) -> None:
    if not exemplars:
        raise DetailizeError("no exemplars", field="exemplars", hint="give at least one style exemplar")
    vocab = exemplars[0].part_names
    if any(ex.part_names != vocab for ex in exemplars) or len(vocab) != cfg.n_parts:
        raise DetailizeError(f"exemplars must share one part vocabulary of {cfg.n_parts} names",
                             field="exemplars", hint="convert the set to its set-level vocabulary")
    if len(exemplars) != cfg.n_styles:
        raise DetailizeError(f"{len(exemplars)} exemplars for a model of {cfg.n_styles} styles",
                             field="exemplars", hint="build the config with n_styles = number of exemplars")


def augmented_sample(exemplars: Sequence[Exemplar], cfg: ModelConfig, aug: AugmentConfig, seed: int,
                     step: int, stream: int = 1) -> Sample:
    """The adversarial step's content: an augmented (possibly combined) shape with random per-part styles.

    Drawn from (seed, step, stream); ``stream`` 1 is the adversarial step's, others serve
    other consumers (``model.distill``'s contents) without repeating its draws.
    """
    _check_set(exemplars, cfg)
    rng = rng_for(seed, step, stream)
    i = int(rng.integers(len(exemplars)))
    shape = augment_exemplar(exemplars[i], rng, aug)
    sources = (exemplars[i].name,)
    if len(exemplars) > 1 and rng.random() < aug.combine_prob:
        j = int(rng.integers(len(exemplars) - 1))
        j += j >= i  # a *different* exemplar
        shape = combine(shape, augment_exemplar(exemplars[j], rng, aug), rng, aug)
        sources = (exemplars[i].name, exemplars[j].name)
    shape = fit_max_side(shape, aug.max_side)
    fine = place_in_crop(shape, rng, cfg.factor, min_cells=min_coarse_cells(cfg))
    return _finish(fine, random_assignment(exemplars, cfg.n_parts, rng), sources, cfg)


def style_sample(exemplars: Sequence[Exemplar], style: int, cfg: ModelConfig, aug: AugmentConfig, seed: int,
                 step: int) -> Sample:
    """A style shape as itself (the reconstruction step's input and D's "real"): every part in style ``style``.

    Only the base scale (R / exemplar resolution) and a random sub-cell offset are applied
    (``aug.style_offset`` instead, when set).
    """
    _check_set(exemplars, cfg)
    ex = exemplars[style]
    rng = rng_for(seed, step, 2)
    lab = crop_to_bbox(ex.labels)
    base = aug.resolution / ex.resolution
    if base != 1:
        lab = crop_to_bbox(resample_labels(lab, np.maximum(1, np.round(np.asarray(lab.shape) * base)), aug.threshold))
    if aug.style_offset is None:
        fine = place_in_crop(lab, rng, cfg.factor, min_cells=min_coarse_cells(cfg))
    elif aug.style_offset == CENTRE:
        fine = place_at(lab, centre_offset(lab.shape, aug.resolution, cfg.factor), cfg.factor,
                        min_cells=min_coarse_cells(cfg))
    elif (isinstance(aug.style_offset, str) or len(aug.style_offset) != 3
          or not all(0 <= int(o) < cfg.factor for o in aug.style_offset)):
        raise DetailizeError(f"style_offset {aug.style_offset!r} must be 3 sub-cell offsets in [0, {cfg.factor})",
                             field="style_offset",
                             hint=f'e.g. [5, 6, 5], "{CENTRE}" (the reference\'s centre padding), or null for random')
    else:
        fine = place_at(lab, aug.style_offset, cfg.factor, min_cells=min_coarse_cells(cfg))
    return _finish(fine, (int(style),) * cfg.n_parts, (ex.name,), cfg)


# ----------------------------------------------------------------------------- dataset files


def exemplars_from_set(style_set) -> list[Exemplar]:
    """A loaded ``stylesets.format.StyleSet`` → training exemplars, in the set's order.

    The set stores uint8 labels (0 empty, ``i + 1`` = vocabulary part ``i``) cropped
    to each exemplar's box; here they become int16 (``EMPTY``, part index) and the
    part vocabulary is the set's (e.g. ``("bottom", "top")`` for "things"), so style
    index s is exemplar s of the set.
    """
    parts = tuple(style_set.vocabulary.parts)
    return [
        Exemplar(name=ex.name, category=ex.category, labels=ex.labels.astype(np.int16) - 1, part_names=parts,
                 resolution=int(style_set.resolution))
        for ex in style_set.exemplars
    ]

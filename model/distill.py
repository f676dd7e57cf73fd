"""Distillation from ``quilt``: reconstruction targets made by the example-based detailizer.

The learned model is asked to reproduce its exemplars; that alone teaches it what its
20 exemplars look like, never what a *new* shape looks like in one of their styles.
``quilt`` (``model/quilt/``) already puts an exemplar's real fine blocks on any coarse
shape. With ``TrainConfig.distill_frac`` = p > 0, a fraction p of the reconstruction
steps (drawn per step from (seed, it, ``STREAM_CHOICE`` + r)) take as input an augmented
training content (``model.data.augmented_sample``: possibly two exemplars combined,
anisotropically scaled, rotated, with a random style per part) and as target quilt's
R-voxel output on that content's coarse grid, instead of an exemplar as itself.

Every draw is a pure function of (seed, it, r): the content is
``augmented_sample(..., step=it·8 + r, stream=STREAM_CONTENT)`` (never the adversarial
step's content, which is stream 1) and quilt's seed comes from
(seed, it, ``STREAM_QUILT`` + r); quilt is deterministic for a (grid, set, seed), so a
resumed run draws exactly the targets an unbroken run would.

Shapes: the content's coarse grid is (X, Y, Z) cells (bounding box + one empty cell per
side, ≤ 0.7·R/16 + 2 per axis); quilt's output and the target's ``fine_labels`` are
(16X, 16Y, 16Z) voxels. Quilt copies blocks at 16 fine voxels per coarse cell, the
exemplars' own scale when R = 256; at a smaller R the shapes are smaller but the copied
detail keeps the 256³ scale (fine for smoke tests; distil at R = 256).

The discriminators' "real" input is the last reconstruction step's sample, so after the
warm-up a distilled step also shows them quilt's output as a real shape in its per-part
styles (the issue's other distillation option, "extra real shapes").

Cost: one quilt detailization per distilled step, about 0.5–0.9 s CPU for a training
content at R = 256 on 2 cores (the library of the set is built once per run, ~8 s).
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Sequence

import numpy as np

from model.config import ModelConfig
from model.data import AugmentConfig, Exemplar, Sample, augmented_sample, rng_for
from model.quilt import QuiltDetailizer
from core.grid import EMPTY, ISO_LEVEL, LabeledGrid
from stylesets.format import Exemplar as SetExemplar
from stylesets.format import StyleSet, Vocabulary

#: rng streams of a distilled reconstruction step r of iteration it (0 ≤ r < 8).
STREAM_CHOICE = 400
STREAM_QUILT = 500
#: ``augmented_sample``'s stream for distillation contents (the adversarial step uses 1).
STREAM_CONTENT = 5


def style_set_of(exemplars: Sequence[Exemplar]) -> StyleSet:
    """An in-memory ``StyleSet`` holding exactly the training exemplars (for a run given no set).

    Each exemplar's labels are cropped to their box and placed at their offset inside
    the exemplar's grid, as a built set stores them; the vocabulary is the exemplars'
    part names. Its digest is a hash of names and label bytes (quilt does not cache the
    stats of an in-memory set on disk).
    """
    digest = hashlib.sha256()
    out = []
    for ex in exemplars:
        occ = ex.labels != EMPTY
        box = [np.flatnonzero(occ.any(axis=tuple(b for b in range(3) if b != a))) for a in range(3)]
        sl = tuple(slice(int(i[0]), int(i[-1]) + 1) for i in box)
        crop = (ex.labels[sl] + 1).astype(np.uint8)
        digest.update(ex.name.encode() + crop.tobytes())
        out.append(SetExemplar(labels=crop, offset=tuple(int(i[0]) for i in box),
                               meta={"name": ex.name, "category": ex.category, "shape": list(crop.shape),
                                     "offset": [int(i[0]) for i in box]}))
    parts = exemplars[0].part_names
    return StyleSet(name="training", vocabulary=Vocabulary("training", tuple(parts)),
                    resolution=int(exemplars[0].resolution), inputs_hash=digest.hexdigest(), exemplars=tuple(out))


class QuiltTeacher:
    """Quilt's outputs on training contents, as reconstruction targets.

    Args:
        exemplars: the run's exemplars (style index s = exemplar s).
        style_set: the set they were read from (its quilt stats are cached on disk); None:
            ``style_set_of(exemplars)``. Its exemplar names must be the exemplars' names in order.
    Raises:
        ValueError: a set whose exemplars are not the run's.
    """

    def __init__(self, exemplars: Sequence[Exemplar], style_set: StyleSet | None = None) -> None:
        sset = style_set if style_set is not None else style_set_of(exemplars)
        names = tuple(e.name for e in exemplars)
        if tuple(e.name for e in sset.exemplars) != names:
            raise ValueError(f"the distillation set '{sset.name}' does not hold the run's exemplars {names}")
        self.exemplars = list(exemplars)
        self.style_names = names
        self.part_names = tuple(exemplars[0].part_names)
        self.quilt = QuiltDetailizer(style_set=sset)

    def grid(self, sample: Sample) -> LabeledGrid:
        """The sample's coarse input as quilt's ``LabeledGrid``: (X, Y, Z) occupancy, part and style per cell."""
        occ = sample.coarse_occupancy
        part = np.where(occ, sample.coarse_labels, EMPTY).astype(np.int16)
        style = np.where(occ, sample.style_index(), EMPTY).astype(np.int16)
        return LabeledGrid(occupancy=occ, part=part, style=style, part_names=self.part_names,
                           style_names=self.style_names, voxel_size_m=1.0)

    def target(self, sample: Sample, seed: int) -> Sample:
        """``sample`` with its fine shape replaced by quilt's output (seeded) on its coarse grid.

        The coarse input (occupancy, part labels, per-part styles) is unchanged; the new
        ``fine_labels`` (16X, 16Y, 16Z) int16 are quilt's occupancy above the 0.4 iso level,
        each voxel labelled with its coarse cell's part (``EMPTY`` elsewhere).
        """
        fine = self.quilt.detailize(self.grid(sample), seed=seed).occupancy > ISO_LEVEL
        f = sample.factor
        labels = np.repeat(np.repeat(np.repeat(sample.coarse_labels, f, 0), f, 1), f, 2)
        return dataclasses.replace(sample, fine_labels=np.where(fine, labels, EMPTY).astype(np.int16),
                                   sources=sample.sources + ("quilt",))


def is_distilled(seed: int, it: int, r: int, frac: float) -> bool:
    """Whether reconstruction step r of iteration ``it`` is a distilled one (probability ``frac``)."""
    return frac > 0 and bool(rng_for(seed, it, STREAM_CHOICE + r).random() < frac)


def distill_sample(teacher: QuiltTeacher, cfg: ModelConfig, aug: AugmentConfig, seed: int, it: int,
                   r: int) -> Sample:
    """Reconstruction step r of iteration ``it``'s distilled sample: an augmented content, quilt's target."""
    content = augmented_sample(teacher.exemplars, cfg, aug, seed, it * 8 + r, stream=STREAM_CONTENT)
    quilt_seed = int(rng_for(seed, it, STREAM_QUILT + r).integers(2**31 - 1))
    return teacher.target(content, quilt_seed)

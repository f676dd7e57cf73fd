"""Quick figures of a generator during training: does it reproduce its exemplars, do its styles differ,
do thin parts survive.

Not the evaluation (``evaluation/`` has the protocol and its metrics): a cheap, fixed
check that a training run logs every ``TrainConfig.monitor_every`` iterations and that
the recipe's A/B runs are compared by. All inputs are drawn once from ``MONITOR_SEED``
(never a training seed's draws: its own stream of steps), at the run's resolution R,
and every output is made the way ``model/infer.py`` makes it (final level only, clamped
to [0, 1], then ``min_fill_projection`` when the config asks for it), binarised above
the 0.4 iso level.

Figures (``Monitor.figures``):

- ``self_iou``: mean over the exemplars of IOU(output, exemplar) at R³, each exemplar's
  ×16 max-pooled coarse grid detailized in its own style (``self_iou_min``: the worst);
  ``upsample_self_iou``: the same for the non-learned baseline (``model/upsample.py``),
  the bar to clear.
- ``self_iou_raw``: ``self_iou`` without the ``min_cell_fill`` projection (the raw field above
  0.4; equal to ``self_iou`` when the config has no projection). The projection fills every
  occupied coarse cell to at least ``min_cell_fill``, which an exemplar's own boundary cells
  often are not (``scripts/selfrec_ceiling.py``), so it caps ``self_iou``.
- ``code_rms``: root mean square of the style codes as used (``Generator.codes``; free codes start at
  ``style_init_std``).
- ``overlap``: mean IOU between two outputs of the same augmented content in two
  different styles (1 = style makes no difference).
- ``strict``: mean Strict-IOU (output ×16 max-pooled against the coarse input) of
  those contents; ``cell_fill_min``: the least occupied fraction of any occupied coarse
  cell's 16³ block over all outputs; ``cells_half_full``: the fraction of occupied cells
  whose block is at least half occupied.
- ``extra_parts``: mean over those outputs of how many more connected pieces (26-connected
  fine voxels) the output has than its coarse input (26-connected cells), floored at 0: a roof
  that floats above its trunk, or a cap torn into shards, counts here where Strict-IOU,
  measured per coarse cell, does not see it.
- ``quilt_iou`` (only for a run that distils, given its ``model.distill.QuiltTeacher``): mean
  IOU between each of those outputs and quilt's output for the same content and style,
  made once (quilt seed 0): how far the model has come towards its teacher on shapes
  that are not exemplars; ``upsample_quilt_iou``: the same for the upsample baseline
  (style-blind, so the same output for both styles).

Cost at R = 128 on 2 cores: about 10 s for the 20 'things' exemplars and 4 contents
(inputs prepared once per run).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from model.config import ModelConfig
from model.data import AugmentConfig, Exemplar, Sample, augmented_sample, rng_for, style_sample
from model.finish import min_fill_projection
from model.networks import Generator
from model.upsample import SIGMA_FINE_VOXELS, smooth_upsample
from core.grid import EMPTY, ISO_LEVEL

#: Seed of the monitor's inputs.
MONITOR_SEED = 90_211
#: Augmented contents for the style-overlap figure.
OVERLAP_CONTENTS = 4


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 1.0


def detailize_field(gen: Generator, sample: Sample, style_index: np.ndarray | None = None) -> np.ndarray:
    """The generator's final level on ``sample``'s coarse grid, clamped to [0, 1], *before* the fill projection."""
    styles = sample.style_index() if style_index is None else style_index
    with torch.inference_mode():
        inputs = gen.make_inputs(torch.from_numpy(sample.coarse_occupancy)[None],
                                 torch.from_numpy(sample.coarse_labels.astype(np.int64))[None],
                                 torch.from_numpy(np.ascontiguousarray(styles))[None])
        return gen(*inputs, final_only=True)[-1][0, 0].float().clamp_(0.0, 1.0).cpu().numpy()


def detailize_sample(gen: Generator, sample: Sample, style_index: np.ndarray | None = None) -> np.ndarray:
    """The generator's final level on ``sample``'s coarse grid, as inference makes it: (f·X, f·Y, f·Z) bool.

    ``style_index``: (X, Y, Z) style per coarse cell (default: the sample's own).
    """
    cfg = gen.cfg
    out = detailize_field(gen, sample, style_index)
    return min_fill_projection(out, sample.coarse_occupancy, cfg.factor, cfg.min_cell_fill,
                               thin_only=cfg.min_fill_thin_only) > ISO_LEVEL


def pieces(binary: np.ndarray) -> int:
    """Number of 26-connected components of a 3-D bool grid."""
    import cc3d

    return int(cc3d.connected_components(np.ascontiguousarray(binary, dtype=np.uint8), connectivity=26,
                                         return_N=True)[1])


def cell_fill(fine: np.ndarray, coarse: np.ndarray, factor: int) -> np.ndarray:
    """Occupied fraction of every occupied coarse cell's block: (n_occupied,) float."""
    x, y, z = coarse.shape
    fill = fine.reshape(x, factor, y, factor, z, factor).mean(axis=(1, 3, 5))
    return fill[coarse]


class Monitor:
    """The fixed monitor inputs of one run (drawn on first use) and the figures of a generator on them."""

    def __init__(self, exemplars: Sequence[Exemplar], cfg: ModelConfig, aug: AugmentConfig,
                 teacher: Any = None) -> None:
        self.exemplars, self.cfg, self.aug = list(exemplars), cfg, aug
        self.teacher = teacher  # a model.distill.QuiltTeacher, or None (no quilt_iou)
        self._quilt: dict[tuple[int, int], np.ndarray] = {}
        self._styles: list[Sample] | None = None
        self._contents: list[tuple[Sample, int, int]] | None = None
        self._baseline: float | None = None

    def _inputs(self) -> tuple[list[Sample], list[tuple[Sample, int, int]]]:
        if self._styles is None or self._contents is None:
            ex, cfg, aug = self.exemplars, self.cfg, self.aug
            self._styles = [style_sample(ex, s, cfg, aug, MONITOR_SEED, s) for s in range(len(ex))]
            contents = []
            for i in range(OVERLAP_CONTENTS):
                c = augmented_sample(ex, cfg, aug, MONITOR_SEED, 1000 + i)
                # one style (an overfit diagnostic): both "styles" are style 0, the overlap is 1 by definition
                a, b = rng_for(MONITOR_SEED, 1000 + i, 7).choice(len(ex), size=2, replace=False) if len(ex) > 1 \
                    else (0, 0)
                contents.append((c, int(a), int(b)))
            self._contents = contents
        return self._styles, self._contents

    def baseline_self_iou(self) -> float:
        """Mean self-reconstruction IOU of the upsample baseline on the same inputs."""
        if self._baseline is None:
            styles, _ = self._inputs()
            f = self.cfg.factor
            self._baseline = float(np.mean([
                _iou(smooth_upsample(s.coarse_occupancy, f, SIGMA_FINE_VOXELS) > ISO_LEVEL, s.fine_labels != EMPTY)
                for s in styles]))
        return self._baseline

    def quilt_output(self, k: int, style: int) -> np.ndarray:
        """Quilt's (f·X, f·Y, f·Z) bool output on overlap content k, every cell in ``style`` (made once)."""
        if (k, style) not in self._quilt:
            c = self._inputs()[1][k][0]
            one = dataclasses.replace(c, assignment=(style,) * len(c.assignment))
            self._quilt[(k, style)] = self.teacher.target(one, 0).fine_labels != EMPTY
        return self._quilt[(k, style)]

    def self_reconstruction(self, gen: Generator) -> list[tuple[float, float]]:
        """Per exemplar (in order): (IOU without projection, IOU with the config's projection) at R³.

        Each exemplar's ×16 max-pooled coarse grid at its monitor offset, detailized in its own style
        and binarised above 0.4, against the exemplar's fine voxels. ``gen`` should be in eval mode.
        """
        styles, _ = self._inputs()
        f, out = self.cfg.factor, []
        for s in styles:
            field = detailize_field(gen, s)
            truth = s.fine_labels != EMPTY
            raw = _iou(field > ISO_LEVEL, truth)  # before the projection, which works in place
            projected = min_fill_projection(field, s.coarse_occupancy, f, self.cfg.min_cell_fill,
                                            thin_only=self.cfg.min_fill_thin_only) > ISO_LEVEL
            out.append((raw, _iou(projected, truth)))
        return out

    def figures(self, gen: Generator, per_exemplar: bool = False) -> dict[str, Any]:
        """The figures of the module docstring for ``gen`` (left in the mode it was in).

        ``per_exemplar``: also ``self_iou_raw_each`` / ``self_iou_each``, the per-exemplar lists
        (exemplar order) behind ``self_iou_raw`` / ``self_iou``.
        """
        styles, contents = self._inputs()
        f = self.cfg.factor
        was_training = gen.training
        gen.eval()
        try:
            per = self.self_reconstruction(gen)
            self_ious, raw_ious = [p for _, p in per], [r for r, _ in per]
            overlaps, stricts, fills, quilt, extra_parts = [], [], [], [], []
            for k, (c, a, b) in enumerate(contents):
                outs = [detailize_sample(gen, c, np.full(c.coarse_occupancy.shape, st, dtype=np.int64))
                        for st in (a, b)]
                overlaps.append(_iou(*outs))
                if self.teacher is not None:
                    quilt += [_iou(out, self.quilt_output(k, st)) for out, st in zip(outs, (a, b))]
                for out in outs:
                    x, y, z = c.coarse_occupancy.shape
                    pooled = out.reshape(x, f, y, f, z, f).any(axis=(1, 3, 5))
                    stricts.append(_iou(pooled, c.coarse_occupancy))
                    fills.append(cell_fill(out, c.coarse_occupancy, f))
                    extra_parts.append(max(0, pieces(out) - pieces(c.coarse_occupancy)))
        finally:
            gen.train(was_training)
        all_fills = np.concatenate(fills)
        extra = {}
        if quilt:
            up = [_iou(smooth_upsample(c.coarse_occupancy, f, SIGMA_FINE_VOXELS) > ISO_LEVEL, self.quilt_output(k, st))
                  for k, (c, a, b) in enumerate(contents) for st in (a, b)]
            extra = {"quilt_iou": round(float(np.mean(quilt)), 4), "upsample_quilt_iou": round(float(np.mean(up)), 4)}
        return {
            "self_iou": round(float(np.mean(self_ious)), 4),
            "self_iou_min": round(float(np.min(self_ious)), 4),
            "self_iou_raw": round(float(np.mean(raw_ious)), 4),
            "upsample_self_iou": round(self.baseline_self_iou(), 4),
            "code_rms": round(float(gen.codes().detach().pow(2).mean().sqrt()), 4),
            "overlap": round(float(np.mean(overlaps)), 4),
            "strict": round(float(np.mean(stricts)), 4),
            "cell_fill_min": round(float(all_fills.min()), 4),
            "cells_half_full": round(float(np.mean(all_fills >= 0.5)), 4),
            "extra_parts": round(float(np.mean(extra_parts)), 4),
            **extra,
            **({"self_iou_raw_each": [round(x, 4) for x in raw_ious],
                "self_iou_each": [round(x, 4) for x in self_ious]} if per_exemplar else {}),
        }

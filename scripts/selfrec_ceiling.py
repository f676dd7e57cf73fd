"""Self-reconstruction ceilings on the monitor's inputs: the sub-cell offset bound, the target round trip,
the fill projection, and quilt (the example-based detailizer) as a reference.

    .venv/bin/python scripts/selfrec_ceiling.py [--set things] [--resolution 256] [--quilt] [--json out.json]

Per exemplar, at the offset ``model/monitor.py`` draws for it: ``model.selfrec_bound.offset_bound``
(the best any function of the coarse grid can score, and the offset group size); IOU of the smoothed
training target above the 0.4 iso against the exemplar (``target_rt``); IOU of the exemplar after the
``min_cell_fill`` 0.5 projection, applied to its binary occupancy (``proj``, the worst case: an empty
voxel of a thin cell is raised to the iso level, so the whole block fills) and to its smoothed training
target (``proj_smooth``: what a generator that fits its target exactly scores; ``proj_smooth_thin``: the
same with the projection on one-cell-thick cells only, ``thin_only``); with ``--quilt``, IOU of quilt's output on the same
coarse grid and style (``quilt``; seed 0), the monitor's ``self_iou`` figure for quilt.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from core.grid import EMPTY, ISO_LEVEL
from model.config import ModelConfig
from model.finish import min_fill_projection
from model.data import AugmentConfig, crop_to_bbox, exemplars_from_set, rng_for, smooth_target, style_sample
from model.monitor import MONITOR_SEED
from model.selfrec_bound import offset_bound, offset_groups
from stylesets.registry import resolve_style_set


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--set", default="things")
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--quilt", action="store_true")
    ap.add_argument("--json", default="")
    a = ap.parse_args()
    sset = resolve_style_set(a.set)
    ex = exemplars_from_set(sset)
    cfg = ModelConfig.lean(len(sset.vocabulary.parts), len(ex))
    aug = AugmentConfig(resolution=a.resolution)
    f = cfg.factor
    teacher = None
    if a.quilt:
        from model.distill import QuiltTeacher
        teacher = QuiltTeacher(ex, sset)
    rows = []
    for s, e in enumerate(ex):
        t0 = time.time()
        sample = style_sample(ex, s, cfg, aug, MONITOR_SEED, s)  # exactly the monitor's input
        truth = sample.fine_labels != EMPTY
        offset = tuple(int(o) for o in rng_for(MONITOR_SEED, s, 2).integers(0, f, size=3))
        binary = crop_to_bbox(truth.astype(np.int16) - 1) != EMPTY  # the placed shape, bbox-cropped again
        b = offset_bound(binary, offset, f, groups=offset_groups(binary, f))
        union = np.count_nonzero(truth)
        smooth = smooth_target(truth, cfg.losses)
        rt = smooth > ISO_LEVEL
        # a generator that fits its training target exactly outputs ``smooth``: the projection's cost on it
        proj = min_fill_projection(smooth.copy(), sample.coarse_occupancy, f, cfg.min_cell_fill or 0.5) > ISO_LEVEL
        thin = min_fill_projection(smooth.copy(), sample.coarse_occupancy, f, cfg.min_cell_fill or 0.5,
                                   thin_only=True) > ISO_LEVEL
        row = {"exemplar": e.name, "voxels": int(union), "offset": offset, "group": b.group_size,
               "bound": round(b.iou_expected, 4), "bound_at_offset": round(b.iou_at_offset, 4),
               "threshold": b.threshold, "proj": round(b.projection_iou, 4),
               "proj_smooth": round(float(np.count_nonzero(proj & truth) / np.count_nonzero(proj | truth)), 4),
               "proj_smooth_thin": round(float(np.count_nonzero(thin & truth) / np.count_nonzero(thin | truth)), 4),
               "target_rt": round(float(np.count_nonzero(rt & truth) / np.count_nonzero(rt | truth)), 4)}
        if teacher is not None:
            q = teacher.target(sample, 0).fine_labels != EMPTY
            row["quilt"] = round(float(np.count_nonzero(q & truth) / np.count_nonzero(q | truth)), 4)
        row["s"] = round(time.time() - t0, 1)
        rows.append(row)
        print(json.dumps(row), flush=True)
    keys = [k for k in ("bound", "bound_at_offset", "proj", "proj_smooth", "proj_smooth_thin", "target_rt", "quilt") if k in rows[0]]
    summary = {k: {"mean": round(float(np.mean([r[k] for r in rows])), 4),
                   "min": round(float(np.min([r[k] for r in rows])), 4)} for k in keys}
    summary["group_mean"] = float(np.mean([r["group"] for r in rows]))
    print("summary", json.dumps(summary), flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"rows": rows, "summary": summary}, fh, indent=1)


if __name__ == "__main__":
    main()

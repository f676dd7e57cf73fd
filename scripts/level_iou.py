"""Per-level IOU of a one-exemplar checkpoint (an overfit run of ``scripts/ab_recipe.py --exemplars I``).

    .venv/bin/python scripts/level_iou.py RUN/last.pt [--set things]

On the monitor's input for the checkpoint's first exemplar (``MONITOR_SEED``; the run's fixed
``style_offset`` if it had one), one forward with every side head. Prints one JSON line: per
level j, ``iou_own_target`` (output > 0.4 against the level's own smoothed target > 0.4, at
2^(j+1)× the coarse grid) and ``iou_vs_exemplar_at_R`` (output > 0.4 nearest-upsampled to R,
against the exemplar's fine voxels), and ``best_threshold_R`` ([IOU, threshold], the final
level binarised at the best of 0.2–0.6). Tells at which level a fit is lost: a final level no
better than its upsampled predecessor adds nothing. A few seconds at R = 256 on 2 cores.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import torch

from model.checkpoint import load_checkpoint
from model.data import AugmentConfig, exemplars_from_set, parse_style_offset, style_sample
from model.monitor import MONITOR_SEED
from model.networks import Generator
from stylesets.registry import resolve_style_set
from core.grid import EMPTY, ISO_LEVEL


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return round(float((a & b).sum() / max(1, (a | b).sum())), 4)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("checkpoint")
    ap.add_argument("--set", default="things")
    a = ap.parse_args()
    ck = load_checkpoint(a.checkpoint)
    cfg = ck.config
    by_name = {e.name: e for e in exemplars_from_set(resolve_style_set(a.set))}
    ex = [by_name[n] for n in ck.style_names]
    tc = ck.training["train_config"]
    offset = tc.get("style_offset")
    aug = AugmentConfig(resolution=int(tc["resolution"]), style_offset=parse_style_offset(offset))
    s = style_sample(ex, 0, cfg, aug, MONITOR_SEED, 0)  # the monitor's input for exemplar 0
    gen = Generator(cfg)
    gen.load_state_dict(ck.generator)
    gen.eval()
    truth = s.fine_labels != EMPTY
    with torch.inference_mode():
        outs = gen(*gen.make_inputs(torch.from_numpy(s.coarse_occupancy)[None],
                                    torch.from_numpy(s.coarse_labels.astype(np.int64))[None],
                                    torch.from_numpy(s.style_index())[None]))
    res: dict = {}
    for k, (j, o) in enumerate(zip(cfg.supervised_levels, outs)):
        grid = o[0, 0].numpy() > ISO_LEVEL
        f = cfg.factor // 2 ** (j + 1)
        up = grid.repeat(f, 0).repeat(f, 1).repeat(f, 2)
        res[f"level{j}"] = {"iou_own_target": _iou(grid, s.target(j) > ISO_LEVEL),
                            "iou_vs_exemplar_at_R": _iou(up, truth)}
    last = outs[-1][0, 0].numpy()
    res["best_threshold_R"] = max((_iou(last > th, truth), th) for th in (0.2, 0.3, 0.4, 0.5, 0.6))
    print(json.dumps({"checkpoint": a.checkpoint, "step": ck.training.get("step"), **res}), flush=True)


if __name__ == "__main__":
    main()

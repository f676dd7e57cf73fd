"""What distillation asks and what a checkpoint gives: quilt's targets beside the generator's outputs.

    .venv/bin/python scripts/distill_sheet.py CHECKPOINT [CHECKPOINT ...] --set SET.npz --out sheet.png
                                              [--iters 50000,50040,...]

For each listed iteration it, the distilled sample of reconstruction step 0 (``model.distill.distill_sample``
with the first checkpoint's seed, placement and resolution: an augmented content, a style per part) is
made; the top row shows quilt's output on its coarse grid (the target, binary), each further row a
checkpoint's generator on the same coarse input (its final level, no inference projection), in the order
given; the bottom line names the sample's sources and the IOU of each checkpoint's output with the target. All tiles are grey meshes at the iso level 0.4 (``model.previews``' renderer). The
iterations need not be distilled ones: the sample is drawn as if they were. Prints every IOU.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from model.checkpoint import load_checkpoint
from model.data import exemplars_from_set
from model.distill import QuiltTeacher, distill_sample
from model.networks import Generator
from model.previews import _tile
from model.train import TrainConfig
from core.grid import EMPTY, ISO_LEVEL
from stylesets.format import load_set


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("checkpoints", type=Path, nargs="+")
    ap.add_argument("--set", type=Path, required=True, help="the style set's .npz file")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--iters", default="50000,50040,50080,50120,50160",
                    help="iterations whose draws to show (the default: beyond any run so far, so never trained on)")
    ap.add_argument("--tile", type=int, default=224)
    a = ap.parse_args()
    from PIL import Image, ImageDraw

    cks = [load_checkpoint(p, training_state=True) for p in a.checkpoints]
    tcfg = TrainConfig.recorded(cks[0].training["train_config"])
    sset = load_set(a.set)
    teacher = QuiltTeacher(exemplars_from_set(sset), sset)
    gens = []
    for ck in cks:
        gen = Generator(ck.config)
        gen.load_state_dict(ck.generator)
        gens.append(gen.eval())
    iters = [int(i) for i in a.iters.split(",")]
    t, rows = a.tile, 1 + len(gens)
    sheet = Image.new("RGB", (len(iters) * t, rows * t + 16), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for c, it in enumerate(iters):
        s = distill_sample(teacher, cks[0].config, tcfg.augment(), tcfg.seed, it, 0)
        target = (s.fine_labels != EMPTY).astype(np.float32)
        sheet.paste(_tile(target, t), (c * t, 0))
        ious = []
        for row, gen in enumerate(gens, start=1):
            with torch.inference_mode():
                inputs = gen.make_inputs(torch.from_numpy(s.coarse_occupancy)[None],
                                         torch.from_numpy(s.coarse_labels.astype(np.int64))[None],
                                         torch.from_numpy(s.style_index())[None])
                out = gen(*inputs, final_only=True)[-1][0, 0].float().numpy()
            a_, b_ = target > ISO_LEVEL, out > ISO_LEVEL
            ious.append(float((a_ & b_).sum() / max(1, (a_ | b_).sum())))
            sheet.paste(_tile(out, t), (c * t, row * t))
        label = "+".join(s.sources[:-1])
        print(f"it {it}: {label} IOU " + " ".join(f"{v:.3f}" for v in ious), flush=True)
        draw.text((c * t + 4, rows * t + 2), f"{label[:20]} " + "/".join(f"{v:.2f}" for v in ious), fill=(0, 0, 0))
    a.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(a.out)
    print(a.out)


if __name__ == "__main__":
    main()

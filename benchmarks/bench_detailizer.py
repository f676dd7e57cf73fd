"""Detailizer cost: one 16³ → 256³ detailization, time and peak memory (not a test; prints a table).

Run from the repository root::

    .venv/bin/python benchmarks/bench_detailizer.py [--checkpoint model/weights/things.pt] [--device cpu]

Content: a full 16³ cube of coarse voxels would be the worst case but is not a
shape; the benchmark uses a house-like 16³ grid (a 12×9×12 body, a stepped
roof, 1 empty cell of margin) with two parts and two styles, the size a recipe
asset fills. Each measurement runs in a fresh child process, so the peak RSS
(``ru_maxrss``) is that of loading the model and detailizing, not of this
script; time = median of ``REPEATS`` calls after one warm-up. On CUDA the time
per shape is also given for a batch of shapes run back to back.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import platform
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

REPEATS = 5


def house_grid(style_names: tuple[str, str], part_names: tuple[str, str]):
    """A 16³ LabeledGrid: a box body (part 0, style 0) under a stepped roof (part 1, style 1)."""
    import numpy as np

    from pipeline.grid import EMPTY, LabeledGrid

    occ = np.zeros((16, 16, 16), bool)
    part = np.full(occ.shape, EMPTY, np.int16)
    occ[2:14, 1:10, 2:14] = True
    part[2:14, 1:10, 2:14] = 0
    for k, y in enumerate(range(10, 15)):
        occ[2 + k:14 - k, y, 2:14] = True
        part[2 + k:14 - k, y, 2:14] = 1
    style = np.where(occ, part, EMPTY).astype(np.int16)
    return LabeledGrid(occupancy=occ, part=part, style=style, part_names=part_names, style_names=style_names,
                       voxel_size_m=0.5)


def _measure(checkpoint: str | None, device: str, queue) -> None:
    import resource

    from pipeline.detailize import get_detailizer

    t0 = time.perf_counter()
    det = get_detailizer("decollage" if checkpoint != "upsample" else "upsample",
                         None if checkpoint in (None, "upsample") else checkpoint, device)
    load_s = time.perf_counter() - t0
    styles = tuple(det.style_names[:2]) if getattr(det, "style_names", None) else ("a", "b")
    parts = tuple(det.part_names[:2]) if getattr(det, "part_names", None) else ("bottom", "top")
    grid = house_grid(styles if len(styles) == 2 else styles * 2, parts)
    det.detailize(grid)  # warm-up
    times = []
    for seed in range(REPEATS):
        t = time.perf_counter()
        det.detailize(grid, seed=seed)
        times.append(time.perf_counter() - t)
    rss_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2
    queue.put({"load_s": load_s, "median_s": statistics.median(times), "min_s": min(times), "peak_rss_gb": rss_gb,
               "device": str(getattr(det, "device", "cpu")), "describe": {
                   k: v for k, v in det.describe().items() if k in ("name", "generator_params", "checkpoint")}})


def run(checkpoint: str | None, device: str) -> dict:
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_measure, args=(checkpoint, device, queue))
    proc.start()
    result = queue.get()
    proc.join()
    return result


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=None, help="checkpoint file; default the shipped model")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--baseline", action="store_true", help="also measure the upsample baseline")
    args = ap.parse_args(argv)
    import torch

    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}, "
          f"threads {torch.get_num_threads()}, device {args.device}")
    print(f"one 16³ → 256³ detailization of a house-like grid; median of {REPEATS} after a warm-up\n")
    rows = [("decollage", run(args.checkpoint, args.device))]
    if args.baseline:
        rows.append(("upsample", run("upsample", "cpu")))
    print("| detailizer | device | load s | median s | min s | peak RSS GB | params |")
    print("|---|---|---|---|---|---|---|")
    for name, r in rows:
        print(f"| {name} | {r['device']} | {r['load_s']:.2f} | {r['median_s']:.3f} | {r['min_s']:.3f} | "
              f"{r['peak_rss_gb']:.2f} | {r['describe'].get('generator_params', '-')} |")
    print("\n" + json.dumps(rows[0][1]["describe"]))


if __name__ == "__main__":
    main(sys.argv[1:])

"""Time per training iteration (from a run's log) and per 16³ → 256³ shape on the GPU (from its model).

    python scripts/gpu_timing.py RUN_DIR

Prints the median seconds of the log's last 200 iterations and the median of 10 timed forwards
of one 16³ input (a 16 × 10 × 16 box with a 10 × 4 × 10 box on top, all part 0, style 0) to
256³, final level only, after 3 warm-ups; with the peak GPU memory. Used by ``train_gpu.sh``.
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from pathlib import Path

import torch

from model.checkpoint import load_checkpoint
from model.networks import Generator


def main() -> None:
    run = Path(sys.argv[1])
    rows = [json.loads(line) for line in open(run / "log.jsonl")]
    recent = [r["seconds"] for r in rows[-200:]]
    print(f"{run.name}: step {rows[-1]['step']}; s/iteration (median of the last {len(recent)}): "
          f"{statistics.median(recent):.4f}")
    ck = load_checkpoint(run / "last.pt")
    gen = Generator(ck.config).cuda().eval()
    gen.load_state_dict(ck.generator)
    occ = torch.zeros(1, 18, 18, 18, device="cuda")
    occ[0, 1:17, 1:11, 1:17] = 1
    occ[0, 4:14, 11:15, 4:14] = 1
    lab = torch.zeros(1, 18, 18, 18, dtype=torch.long, device="cuda")
    with torch.inference_mode():
        ins = gen.make_inputs(occ, lab, lab)
        for _ in range(3):
            gen(*ins, final_only=True)
        torch.cuda.synchronize()
        times = []
        for _ in range(10):
            t = time.perf_counter()
            gen(*ins, final_only=True)
            torch.cuda.synchronize()
            times.append(time.perf_counter() - t)
    print(f"16³ → 256³ forward on the GPU: {statistics.median(times) * 1000:.1f} ms median of 10; "
          f"peak {torch.cuda.max_memory_allocated() / 2**30:.2f} GiB")


if __name__ == "__main__":
    main()

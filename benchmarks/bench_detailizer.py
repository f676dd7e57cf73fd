"""Detailizer cost: one 16³ → 256³ detailization, time and peak memory (not a test; prints a table).

Run from the repository root::

    .venv/bin/python benchmarks/bench_detailizer.py [--checkpoint model/weights/things.pt] [--device cpu]

The measurement itself lives in ``evaluation.benchmarking.measure_detailizer``
(also used by ``decollage bench``, which writes docs/benchmarks.md): a
house-like 16³ grid (a 12×9×12 body, a stepped roof, 1 empty cell of margin,
two parts and two styles), each detailizer in a fresh child process so the
peak RSS is that of loading the model and detailizing; time = median of
``--repeats`` calls after one warm-up.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from evaluation.benchmarking import measure_detailizer  # noqa: E402


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=None, help="checkpoint file; default the shipped model "
                    "(or 'random-lean': the lean layout with random weights)")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--baseline", action="store_true", help="also measure the upsample baseline")
    args = ap.parse_args(argv)
    import torch

    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}, "
          f"threads {torch.get_num_threads()}, device {args.device}")
    print(f"one 16³ → 256³ detailization of a house-like grid; median of {args.repeats} after a warm-up\n")
    rows = [("decollage", measure_detailizer(args.checkpoint or "shipped", args.device, args.repeats))]
    if args.baseline:
        rows.append(("upsample", measure_detailizer("upsample", "cpu", args.repeats)))
    print("| detailizer | device | load s | median s | min s | peak RSS GB | params |")
    print("|---|---|---|---|---|---|---|")
    for name, r in rows:
        print(f"| {name} | {r['device']} | {r['load_s']:.2f} | {r['median_s']:.3f} | {r['min_s']:.3f} | "
              f"{r['peak_rss_gb']:.2f} | {r['params'] or '-'} |")
    print("\n" + json.dumps(rows[0][1]))


if __name__ == "__main__":
    main(sys.argv[1:])

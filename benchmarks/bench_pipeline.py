"""End-to-end timings per example asset: source → GLB + preview (not a test; prints a table).

Run from the repository root:  ``.venv/bin/python benchmarks/bench_pipeline.py [recipe ...]``

Every asset is built once to warm up imports and caches (build123d alone takes
seconds to import), then ``REPEATS`` more times; the table gives the median of
those, per stage and in total, in seconds. Outputs go to a temporary folder.
The measurement lives in ``evaluation.benchmarking.bench_assets`` (also used by
``decollage bench``).
"""

from __future__ import annotations

import os
import platform
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from evaluation.benchmarking import STAGES, bench_assets  # noqa: E402

REPEATS = 3


def main(argv: list[str]) -> None:
    recipes = [Path(a) for a in argv] or [REPO / "recipes" / "showcase.yaml"]
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    print(f"median of {REPEATS} runs after one warm-up, seconds\n")
    header = ["asset", *STAGES, "total", "triangles", "reference s", "× ref"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for row in bench_assets(recipes, REPEATS):
        t = row["stages_s"]
        cells = [f"{t[s]:.2f}" for s in STAGES] + [f"{row['total_s']:.2f}", str(row["triangles"]),
                                                   f"{row['reference_s']:.3f}", f"{row['total_s'] / row['reference_s']:.1f}"]
        print(f"| {row['asset']} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])

"""End-to-end timings per example asset: source → GLB + preview (not a test; prints a table).

Run from the repository root:  ``.venv/bin/python benchmarks/bench_pipeline.py [recipe ...]``

Every asset is built once to warm up imports and caches (build123d alone takes
seconds to import), then ``REPEATS`` more times; the table gives the median of
those, per stage and in total, in seconds. Outputs go to a temporary folder.
"""

from __future__ import annotations

import os
import platform
import statistics
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from pipeline.build import Progress, build_asset, check_recipe  # noqa: E402
from pipeline.recipe import load_recipe  # noqa: E402

REPEATS = 3
STAGES = ("source", "voxelize", "regions", "detailize", "mesh", "export")


def bench(recipe_path: Path, out_dir: Path) -> list[tuple[str, dict[str, float], int]]:
    loaded = load_recipe(recipe_path)
    check_recipe(loaded)
    rows = []
    for index, asset in enumerate(loaded.recipe.assets):
        build_asset(loaded, index, out_dir, Progress())  # warm-up: imports, first-call costs
        runs = [build_asset(loaded, index, out_dir, Progress()) for _ in range(REPEATS)]
        if any(r.status != "built" for r in runs):
            raise SystemExit(f"{asset.name} failed: {runs[0].error}")
        medians = {s: statistics.median(r.timings_s[s] for r in runs) for s in STAGES}
        rows.append((asset.name, medians, runs[0].info["mesh"]["triangles"]))
    return rows


def main(argv: list[str]) -> None:
    recipes = [Path(a) for a in argv] or [REPO / "recipes" / "showcase.yaml"]
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    print(f"median of {REPEATS} runs after one warm-up, seconds\n")
    header = ["asset", *STAGES, "total", "triangles"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    with tempfile.TemporaryDirectory() as tmp:
        for recipe in recipes:
            for name, t, tris in bench(recipe, Path(tmp)):
                cells = [f"{t[s]:.2f}" for s in STAGES] + [f"{sum(t.values()):.2f}", str(tris)]
                print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])

"""Batch figures: a whole batch with --jobs 1 and --jobs 2, and the cached second run (not a test).

Run from the repository root:
    .venv/bin/python benchmarks/bench_batch.py [recipe]     (default: recipes/batch_showcase.yaml)

Each build runs the real CLI in a fresh process into a fresh temporary folder,
so the figures include imports and worker start-up, as a user would see them.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def build(recipe: Path, out: Path, *extra: str) -> dict:
    cmd = [sys.executable, "-m", "pipeline.cli", "build", str(recipe), "-o", str(out), "--json", "--quiet", *extra]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SystemExit(proc.stderr[-2000:])
    return json.loads(proc.stdout)


def main() -> None:
    recipe = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / "recipes" / "batch_showcase.yaml"
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    with tempfile.TemporaryDirectory() as tmp:
        one = build(recipe, Path(tmp) / "j1", "--jobs", "1")
        two = build(recipe, Path(tmp) / "j2", "--jobs", "2")
        cached = build(recipe, Path(tmp) / "j2", "--jobs", "2")
        same = all((Path(tmp) / "j1" / f"{a['name']}.glb").read_bytes() == (Path(tmp) / "j2" / f"{a['name']}.glb").read_bytes()
                   for a in one["assets"])
    n = one["summary"]["assets"]
    print(f"| run | assets | wall time (s) |\n|---|---|---|")
    print(f"| --jobs 1 | {n} | {one['wall_time_s']:.1f} |")
    print(f"| --jobs 2 | {n} | {two['wall_time_s']:.1f} |")
    print(f"| second run (cached) | {cached['summary']['cached']} cached | {cached['wall_time_s']:.2f} |")
    print(f"\nspeed-up of --jobs 2 over --jobs 1: {one['wall_time_s'] / two['wall_time_s']:.2f}x; "
          f"cached run: {100 * cached['wall_time_s'] / two['wall_time_s']:.1f} % of the first; "
          f"GLBs byte-identical across --jobs: {same}")


if __name__ == "__main__":
    main()

"""Batch figures: a whole batch with --jobs 1 and --jobs 2, and the cached second run (not a test).

Run from the repository root:
    .venv/bin/python benchmarks/bench_batch.py [recipe]     (default: recipes/batch_showcase.yaml)

Each build runs the real CLI in a fresh process into a fresh temporary folder,
so the figures include imports and worker start-up, as a user would see them.
Peak memory: the CLI process's own peak RSS (it builds in-process with --jobs 1)
and the peak RSS of its largest worker process (--jobs 2), from getrusage.
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


#: Runs the CLI and, at exit, records the peak RSS of this process (its own, ``VmHWM``: ``ru_maxrss`` would
#: carry this script's across exec) and of its largest worker process (``RUSAGE_CHILDREN``: forked workers
#: count the pages they share with the main process, so an upper bound).
_WRAPPER = """
import atexit, json, os, resource, sys
from core.processes import own_peak_rss_mb
def _rss():
    with open(os.environ["DECOLLAGE_BENCH_RSS"], "w") as f:
        json.dump({"main_mb": own_peak_rss_mb(),
                   "worker_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}, f)
atexit.register(_rss)
sys.argv = ["decollage", *sys.argv[1:]]
from cli.app import main
main()
"""


def build(recipe: Path, out: Path, *extra: str) -> dict:
    rss = out.parent / f"{out.name}.rss.json"
    cmd = [sys.executable, "-c", _WRAPPER, "build", str(recipe), "-o", str(out), "--json", "--quiet", *extra]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, check=False,
                          env={**os.environ, "DECOLLAGE_BENCH_RSS": str(rss)})
    if proc.returncode != 0:
        raise SystemExit(proc.stderr[-2000:])
    summary = json.loads(proc.stdout)
    summary["rss"] = json.loads(rss.read_text())
    return summary


def main() -> None:
    recipe = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / "recipes" / "batch_showcase.yaml"
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    sys.path.insert(0, str(REPO))
    from evaluation.benchmarking import reference_workload_seconds

    refs = []
    with tempfile.TemporaryDirectory() as tmp:
        refs.append(reference_workload_seconds(3)["median_s"])
        one = build(recipe, Path(tmp) / "j1", "--jobs", "1")
        refs.append(reference_workload_seconds(3)["median_s"])
        two = build(recipe, Path(tmp) / "j2", "--jobs", "2")
        refs.append(reference_workload_seconds(3)["median_s"])
        cached = build(recipe, Path(tmp) / "j2", "--jobs", "2")
        same = all((Path(tmp) / "j1" / f"{a['name']}.glb").read_bytes() == (Path(tmp) / "j2" / f"{a['name']}.glb").read_bytes()
                   for a in one["assets"])
    n = one["summary"]["assets"]
    def mb(run: dict) -> str:
        return f"{run['rss']['main_mb']:.0f} | {run['rss']['worker_mb']:.0f}"

    def ratio(run: dict, before: float, after: float) -> str:
        return f"{run['wall_time_s'] / ((before + after) / 2):.0f}"

    print(f"reference workload before, between and after the builds: {', '.join(f'{r:.3f} s' for r in refs)}")
    print("| run | assets | wall time (s) | × ref | peak RSS main process (MB) | peak RSS largest worker (MB) |")
    print("|---|---|---|---|---|---|")
    print(f"| --jobs 1 | {n} | {one['wall_time_s']:.1f} | {ratio(one, refs[0], refs[1])} | {mb(one)} |")
    print(f"| --jobs 2 | {n} | {two['wall_time_s']:.1f} | {ratio(two, refs[1], refs[2])} | {mb(two)} |")
    print(f"| second run (cached) | {cached['summary']['cached']} cached | {cached['wall_time_s']:.2f} | | {mb(cached)} |")
    print(f"\nspeed-up of --jobs 2 over --jobs 1: {one['wall_time_s'] / two['wall_time_s']:.2f}x; "
          f"cached run: {100 * cached['wall_time_s'] / two['wall_time_s']:.1f} % of the first; "
          f"GLBs byte-identical across --jobs: {same}")


if __name__ == "__main__":
    main()

"""Benchmark: long words with default settings, in several fonts (prints a markdown table; not a test).

Each row builds one text asset (``size_m`` 0.5, depth 0.12, two styles, the default detailizer and every
default setting) through the real CLI in a fresh process, and reports the wall time, the stage times
from the manifest, the time per letter, the blocks the asset was cut into (``pipeline/chunks.py``) and
the peak RSS of the process plus its block process's (an upper bound: pages they share count twice). The reference workload (``evaluation/benchmarking.py``) is
timed in the same run.

    .venv/bin/python benchmarks/bench_long_text.py [--lengths 5 10 20] [--fonts A.ttf B.ttf]

Fonts: the bundled DejaVu Sans Bold, and the system's Liberation Serif Bold and DejaVu Sans Mono when
they are installed (``fc-list``); rows of missing fonts are skipped with a note.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from evaluation.benchmarking import reference_workload_seconds  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
WORD = "ABCDEFGHIJKLMNOPQRST"
FONTS = [None, Path("/usr/share/fonts/truetype/liberation/LiberationSerif-Bold.ttf"),
         Path("/usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf")]

_WRAPPER = """
import atexit, json, os, sys
# own peak (ru_maxrss would carry the runner's) + the block process's (pipeline/forked.py; counts shared pages twice)
from core.processes import children_peak_rss_mb, own_peak_rss_mb
def _rss():
    with open(os.environ["DECOLLAGE_BENCH_RSS"], "w") as f:
        json.dump({"peak_mb": own_peak_rss_mb() + children_peak_rss_mb()}, f)
atexit.register(_rss)
sys.argv = ["decollage", *sys.argv[1:]]
from cli.app import main
main()
"""


def build(text: str, font: Path | None, folder: Path) -> dict:
    recipe = folder / "word.yaml"
    font_line = f", font: {json.dumps(str(font))}" if font else ""
    recipe.write_text(f"""version: 1
assets:
  - name: word
    source: {{kind: text, text: {text}, size_m: 0.5, depth_m: 0.12{font_line}}}
    regions:
      - {{parts: ["*"], part: bottom, style: tower}}
      - {{band: {{from: 0.65}}, part: top, style: druse}}
""")
    out, rss = folder / "out", folder / "rss.json"
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _WRAPPER, "build", str(recipe), "-o", str(out), "--quiet"],
                          cwd=REPO, capture_output=True, text=True, env={**os.environ, "DECOLLAGE_BENCH_RSS": str(rss)})
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(proc.stderr[-2000:])
    entry = json.loads((out / "manifest.json").read_text())["assets"][0]
    return {"wall_s": wall, "timings": entry["timings_s"], "chunks": entry.get("chunks", 1),
            "coarse": entry["coarse_grid"]["shape"], "triangles": entry["mesh"]["triangles"],
            "glb_kb": entry["outputs"]["glb"]["bytes"] / 1024, "peak_mb": json.loads(rss.read_text())["peak_mb"],
            "strict": entry["structure"]["strict_iou"]}


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", nargs="*", type=int, default=[20])
    parser.add_argument("--fonts", nargs="*", type=Path, default=None)
    args = parser.parse_args(argv)
    fonts = args.fonts if args.fonts is not None else FONTS
    ref = reference_workload_seconds()
    print(f"reference workload {ref['median_s']:.3f} s; load average {os.getloadavg()} at the start")
    print("\n| font | letters | coarse grid | blocks | detailize s | mesh s | wall s | s / letter | × ref | "
          "peak RSS MB | triangles | GLB KB | Strict-IOU |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for font in fonts:
        label = font.name if font else "DejaVuSans-Bold (bundled)"
        if font is not None and not font.is_file():
            print(f"| {label} | – | not installed here | | | | | | | | | | |")
            continue
        for n in args.lengths:
            with tempfile.TemporaryDirectory() as tmp:
                r = build(WORD[:n] if n <= len(WORD) else (WORD * (n // len(WORD) + 1))[:n], font, Path(tmp))
            t = r["timings"]
            print(f"| {label} | {n} | {'×'.join(map(str, r['coarse']))} | {r['chunks']} | {t['detailize']:.1f} | "
                  f"{t['mesh']:.1f} | {r['wall_s']:.1f} | {r['wall_s'] / n:.2f} | {r['wall_s'] / ref['median_s']:.0f} | "
                  f"{r['peak_mb']:.0f} | {r['triangles']} | {r['glb_kb']:.0f} | {r['strict']:.3f} |", flush=True)
    print(f"\nload average at the end {os.getloadavg()}")


if __name__ == "__main__":
    main(sys.argv[1:])

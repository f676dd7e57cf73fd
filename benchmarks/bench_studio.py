"""Paint-to-preview latency of ``decollage paint``, measured in the page itself (not a test).

Run from the repository root (needs Debian's chromium, as the browser tests do):
    .venv/bin/python benchmarks/bench_studio.py [--edits 5] [--learned] [--json out.json]

For each asset of ``recipes/showcase.yaml`` (copied to a temporary folder, so
nothing is saved into the repo) the painter page is opened in headless
Chromium, the fast detailizer ``upsample`` is chosen, one detailize warms up,
then ``--edits`` times a part's style is changed in the parts panel with *live*
on. The page records, from the edit's change event: ``preview_ms`` (the
half-resolution preview mesh drawn) and ``exact_ms`` (the exact GLB that
``decollage build`` writes, hashed and drawn). ``--learned`` adds one detailize
per asset with the learned ``decollage`` model. The machine's core count and
load average are printed with the figures: the machine may be shared.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from studio.http import make_server, url_of  # noqa: E402
from studio.painter import PaintSession, painter_app  # noqa: E402

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]
ASSETS = ("watchtower", "cottage", "mushroom", "castle_word")


def wait(page, expression: str, timeout_s: float = 300.0):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        value = page.evaluate(expression)
        if value:
            return value
        time.sleep(0.05)
    raise TimeoutError(f"{expression} (page error: {page.evaluate('window.studio.error')})")


def measure(page, url: str, asset: str, edits: int, learned: bool) -> dict:
    page.goto(url)
    wait(page, "window.studio.ready && window.studio.state.asset")
    page.select_option("#asset", asset)
    wait(page, f"window.studio.state.asset && window.studio.state.asset.name === {asset!r}")
    page.select_option("#detailizer", "upsample")
    # Choosing a fast detailizer turns live on by itself (after it asked the server what it accepts).
    wait(page, "!window.studio.state.vocab.learned && document.getElementById('live').checked")
    page.click("#detailize")
    wait(page, "window.studio.timings.length >= 1")
    part = page.evaluate("window.studio.state.partNames[window.studio.state.part[window.studio.state.count - 1]]")
    styles = page.evaluate(f"Array.from(document.querySelector('select[data-part=\"{part}\"]').options)"
                           ".map(o => o.value).filter(Boolean)")
    if len(styles) < 2:  # one style only: add another through the page, as a user would
        page.fill("#new-name", "barn")
        page.click("#add-style")
        styles = [*styles, "barn"]
    rows = []
    for n in range(edits):
        done = page.evaluate("window.studio.timings.length")
        select = f"select[data-part={part!r}]"
        page.select_option(select, styles[(n + 1) % len(styles)])
        wait(page, f"window.studio.timings.length > {done}")
        rows.append(page.evaluate("window.studio.timings[window.studio.timings.length - 1]"))
    result = {"asset": asset, "grid": page.evaluate("window.studio.state.asset.shape"),
              "preview_ms": [r["preview_ms"] for r in rows], "exact_ms": [r["exact_ms"] for r in rows],
              "server_preview_s": rows[-1]["server_preview_s"],
              "page_steps_ms": {k: rows[-1].get(k) for k in ("posted_ms", "seen_ms", "loaded_ms", "preview_ms")}}
    if learned:
        page.uncheck("#live")
        page.select_option("#detailizer", "decollage")
        wait(page, "window.studio.state.vocab.learned")
        done = page.evaluate("window.studio.timings.length")
        page.click("#detailize")
        wait(page, f"window.studio.timings.length > {done}")
        last = page.evaluate("window.studio.timings[window.studio.timings.length - 1]")
        result["learned"] = {"preview_ms": last["preview_ms"], "exact_ms": last["exact_ms"]}
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--edits", type=int, default=5)
    parser.add_argument("--learned", action="store_true")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        recipes = Path(tmp) / "recipes"
        shutil.copytree(REPO / "recipes", recipes)
        session = PaintSession(recipes / "showcase.yaml")
        server = make_server(painter_app(session), "127.0.0.1", 0)
        threading.Thread(target=server.serve_forever, daemon=True).start()
        results = []
        try:
            with sync_playwright() as p, tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as profile:
                context = p.chromium.launch_persistent_context(profile, executable_path="/usr/bin/chromium",
                                                               headless=True, args=FLAGS,
                                                               viewport={"width": 1400, "height": 860})
                page = context.new_page()
                for asset in ASSETS:
                    results.append(measure(page, url_of(server), asset, args.edits, args.learned))
                    print(json.dumps(results[-1]), flush=True)
                context.close()
        finally:
            server.shutdown()
            server.server_close()
            session.close()
    machine = {"cpus": os.cpu_count(), "platform": platform.platform(), "load_before": load_before,
               "load_after": os.getloadavg()}
    print(f"\nmachine: {machine['cpus']} cores, load average before {load_before[0]:.1f}, "
          f"after {machine['load_after'][0]:.1f}")
    print("| asset | coarse grid | paint → preview, median (max) | paint → exact GLB, median (max) |")
    print("|---|---|---|---|")
    for r in results:
        print(f"| {r['asset']} | {'×'.join(map(str, r['grid']))} | {statistics.median(r['preview_ms']) / 1000:.2f} s "
              f"({max(r['preview_ms']) / 1000:.2f}) | {statistics.median(r['exact_ms']) / 1000:.2f} s "
              f"({max(r['exact_ms']) / 1000:.2f}) |")
    if args.json:
        args.json.write_text(json.dumps({"machine": machine, "results": results}, indent=2) + "\n")


if __name__ == "__main__":
    main()

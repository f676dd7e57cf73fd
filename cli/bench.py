"""``decollage bench``: inference, end-to-end and training timings with the machine, into docs/benchmarks.md.

Role: run ``evaluation.benchmarking`` (each detailizer timed in a fresh process),
format one markdown section (machine, detailize 16³ → 256³ on CPU and CUDA when
present, peak memory, per-asset build times, training seconds per iteration)
and put it into the marked ``bench`` section of ``--out`` (the evaluation
tables live in their own sections of the same file). Errors are
``DecollageError`` subclasses; ``cli.app`` maps them to exit code 2.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Optional

import typer

from cli.console import fail, stderr
from core.errors import DecollageError, DetailizeError
from core.files import ensure_writable_dir
from evaluation.benchmarking import (
    REPO,
    bench_assets,
    measure_detailizer,
    reference_workload_seconds,
    train_iteration_seconds,
    write_doc_section,
)
from evaluation.evaluate import machine_info
from model.infer import DEFAULT_CHECKPOINT, cpu_threads
from stylesets.registry import resolve_style_set


def bench_command(
    checkpoint: Optional[Path] = typer.Option(None, "--checkpoint", help="Trained model to time (default: the "
                                              "shipped one, else the lean layout with random weights)."),
    out: Path = typer.Option(Path("docs/benchmarks.md"), "--out", "-o", help="Markdown file; its 'bench' section "
                             "is replaced."),
    recipes: Optional[list[Path]] = typer.Option(None, "--recipe", help="Recipes for the end-to-end times "
                                                 "(default: recipes/showcase.yaml); repeatable."),
    repeats: int = typer.Option(3, "--repeats", min=1, help="Timed runs per measurement (medians)."),
    train_iterations: int = typer.Option(2, "--train-iterations", min=0,
                                         help="Timed training iterations per schedule (0: skip training)."),
    assets: bool = typer.Option(True, "--assets/--no-assets", help="Time the example assets end to end."),
    threads: Optional[int] = typer.Option(None, "--threads", min=1, help="CPU threads (default: every core)."),
    quiet: bool = typer.Option(False, "--quiet", "-q"),
) -> None:
    """Time detailization (CPU, CUDA when present), example assets and training; write docs/benchmarks.md."""

    try:
        _bench(checkpoint, out, recipes, repeats, train_iterations, assets, threads, quiet)
    except DecollageError as exc:
        fail(exc)


def _bench(checkpoint, out, recipes, repeats, train_iterations, assets, threads, quiet) -> None:
    import torch


    console = stderr()
    say = (lambda line: None) if quiet else (lambda line: console.print(line, markup=False, highlight=False))
    if checkpoint is not None and not Path(checkpoint).is_file():
        raise DetailizeError("checkpoint not found", file=checkpoint, hint="check the path")
    ensure_writable_dir(Path(out).parent)
    if threads:
        os.environ["OMP_NUM_THREADS"] = str(threads)
    torch.set_num_threads(threads or cpu_threads())
    learned = str(checkpoint) if checkpoint else ("shipped" if DEFAULT_CHECKPOINT.exists() else "random-lean")
    machine = machine_info("cpu")
    rows = []
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    for which, device in [("quilt", "cpu")] + [(learned, d) for d in devices] + [("upsample", "cpu")]:
        say(f"detailize 16³ → 256³: {which} on {device} …")
        try:
            rows.append(measure_detailizer(which, device, repeats=max(repeats, 3), threads=threads))
        except RuntimeError as exc:
            raise DetailizeError(f"timing {which} on {device} failed: {exc}") from None
    asset_rows, reference = [], None
    if assets:
        say("example assets end to end …")
        reference = reference_workload_seconds()
        asset_rows = bench_assets(recipes or [REPO / "recipes" / "showcase.yaml"], repeats, progress=say)
    train = None
    if train_iterations:

        say(f"training: {train_iterations} + 1 iterations per schedule on the 'things' set …")
        train = train_iteration_seconds(resolve_style_set("things"), iterations=train_iterations,
                                        device="cuda" if torch.cuda.is_available() else "cpu")
    text = bench_markdown(machine, rows, asset_rows, train, learned, reference)
    write_doc_section(out, "bench", text)
    typer.echo(text)
    say(f"wrote the 'bench' section of {out}")


def bench_markdown(machine: dict, rows: list[dict], asset_rows: list[dict], train: dict | None,
                   learned: str, reference: dict | None = None) -> str:
    """The bench section as markdown; ``reference`` (``reference_workload_seconds``) turns asset times into ratios."""
    from datetime import datetime, timezone

    label = {"random-lean": "decollage, lean layout, random weights (timing only; no trained model yet)",
             "shipped": "decollage (shipped model)", "upsample": "upsample (baseline)",
             "quilt": "quilt (default; non-learned, example-based)"}
    lines = [
        "## Speed and memory (`decollage bench`)",
        "",
        f"Measured {datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')} on {machine.get('processor')}, "
        f"{machine.get('cpu_count')} cores, {machine.get('memory_gb', '?')} GB, torch {machine.get('torch')}"
        + (f", GPU {machine['cuda']}" if machine.get("cuda") else ", no GPU")
        + f"; load average {machine.get('load_average')} when it started (other jobs share the cores: "
          "figures are upper bounds).",
        "",
        "### Detailize one 16³ grid → 256³",
        "",
        "House-like grid (12×9×12 body under a stepped roof), fresh process per row; median after a warm-up.",
        "",
        "| detailizer | device | threads | load s | median s | min s | median CPU s | peak RSS GB | peak GPU GB | "
        "parameters |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        name = label.get(r["detailizer"], f"decollage ({Path(r['detailizer']).name})")
        lines.append(f"| {name} | {r['device']} | {r['threads']} | {r['load_s']:.2f} | {r['median_s']:.3f} | "
                     f"{r['min_s']:.3f} | {r['median_cpu_s']:.3f} | {r['peak_rss_gb']:.2f} | "
                     f"{'–' if r['peak_gpu_gb'] is None else format(r['peak_gpu_gb'], '.2f')} | "
                     f"{r['params'] or '–'} |")
    if asset_rows:
        ref = reference["median_s"] if reference else None
        stages = ("source", "voxelize", "regions", "detailize", "mesh", "engine", "export")
        lines += ["", "### Example assets end to end (source → GLB + preview)", "",
                  f"Median of {asset_rows[0]['repeats']} builds after a warm-up, seconds; each asset with its "
                  "recipe's detailizer."
                  + (f" Reference workload (marching cubes of a 256³ sphere field, scikit-image) in the same run: "
                     f"{ref:.3f} s (load average {reference['load_average']}); × ref = total / the reference timed "
                     "just before and after that asset's builds (the machine's speed drifts)."
                     if ref else "")
                  + f" `decollage build` uses {asset_rows[0].get('block_processes', 1)} process(es) per asset here "
                    "(a long asset's blocks in two halves, `pipeline/chunks.py`).", "",
                  "| recipe | asset | detailizer | fine grid | " + " | ".join(stages)
                  + " | total | × ref | triangles | GLB KB |",
                  "|---|---|---|---|" + "---|" * (len(stages) + 4)]
        for a in asset_rows:
            st = a["stages_s"]
            glb = a.get("glb_bytes")
            own_ref = a.get("reference_s", ref)
            ratio = f"{a['total_s'] / own_ref:.1f}" if own_ref else "–"
            size = f"{glb / 1024:.0f}" if glb else "–"
            lines.append(f"| {a['recipe']} | {a['asset']} | {a['detailizer']} | {'×'.join(map(str, a['fine_grid']))} | "
                         + " | ".join(f"{st.get(s, 0.0):.2f}" for s in stages)
                         + f" | {a['total_s']:.2f} | {ratio} | {a['triangles']} | {size} |")
    if train:
        lines += ["", "### Training", "",
                  f"`model.train.Trainer` on the 'things' set, {train['layout']} layout, R = {train['resolution']}, "
                  f"{train['device']} ({train['threads']} threads); median of {train['iterations']} iterations "
                  "after a warm-up.", "",
                  "| schedule | s / iteration |", "|---|---|",
                  f"| early (4 reconstruction steps + 1 adversarial) | {train['early_s']:.2f} |",
                  f"| later (1 + 1) | {train['later_s']:.2f} |"]
    return "\n".join(lines) + "\n"

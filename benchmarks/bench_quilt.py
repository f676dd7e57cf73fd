"""Benchmark of the ``quilt`` detailizer beside ``upsample`` and the shipped model (not a test; prints tables).

Run from the repository root::

    .venv/bin/python benchmarks/bench_quilt.py seams [--limit 16] [--detailizers quilt,upsample,decollage]
    .venv/bin/python benchmarks/bench_quilt.py speed [--repeats 5]
    .venv/bin/python benchmarks/bench_quilt.py long [--word ...]
    .venv/bin/python benchmarks/bench_quilt.py import

The detail figures (LP-detail, style specificity, self-reconstruction, shape-matched Cls, with
intervals and paired differences) are ``decollage eval``'s (``scripts/eval_detail.sh``); this
benchmark adds what is particular to quilt and its cost.

``seams`` runs outputs of the evaluation protocol (``--limit`` spread evenly, or ``--split test``)
through each detailizer and reports per output and on average:

* Strict/Loose-IOU (``core.structure.strict_loose_iou``, the evaluation's definition);
* the seam measure (quilt only): the fraction of 6-neighbouring pairs of
  surface cells (occupied cells with an empty 26-neighbour; interior cells are
  solid and have no source) whose sources continue each other (adjacent in
  the same exemplar, same symmetry);
* floating components: 6-connected components of the binarised output beyond
  one per 6-connected coarse component that has material; and enclosed
  cavities (empty components not connected to the outside).

``speed`` times one 16³ → 256³ detailization (the house-like grid of
``evaluation.benchmarking`` and protocol contents) and the library build, each
detailizer in a fresh child process for its peak RSS. ``long`` runs a long
word (bounded memory). ``import`` times ``decollage styles import`` of a
folder of meshes to the first detailed asset.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


# --------------------------------------------------------------------------- measures


def structure(binary: np.ndarray, coarse: np.ndarray) -> dict:
    """Floating components and enclosed cavities of a binarised output (see module docstring)."""
    from scipy import ndimage

    six = ndimage.generate_binary_structure(3, 1)
    _, n_fine = ndimage.label(binary, structure=six)
    lab_c, n_coarse = ndimage.label(coarse, structure=six)
    f = binary.shape[0] // coarse.shape[0]
    pooled = binary.reshape(coarse.shape[0], f, coarse.shape[1], f, coarse.shape[2], f).any(axis=(1, 3, 5))
    with_material = len(np.unique(lab_c[pooled & coarse]))
    empty_lab, n_empty = ndimage.label(np.pad(~binary, 1, constant_values=True), structure=six)
    return {"floating": int(n_fine - with_material), "cavities": int(n_empty - 1)}


# --------------------------------------------------------------------------- quality


def _detailizer(name: str, style_set):
    if name == "quilt":
        from model.quilt import QuiltDetailizer

        return QuiltDetailizer(style_set=style_set)
    from core.detailizer import get_detailizer

    return get_detailizer(name, None, "cpu")


def seams(args) -> None:
    from core.structure import strict_loose_iou
    from evaluation.evaluate import pick_outputs
    from evaluation.protocol import load_protocol, resolve_protocol_set

    protocol = load_protocol()
    style_set = resolve_protocol_set(protocol)
    outputs = list(protocol.outputs)
    if args.ids:
        outputs = [o for o in outputs if o.id in args.ids.split(",")]
    elif args.split:
        outputs = list(protocol.outputs_of(args.split))
    outputs = pick_outputs(outputs, args.limit)
    names = args.detailizers.split(",")
    dets = {n: _detailizer(n, style_set) for n in names}
    rows = []
    print(f"{len(outputs)} outputs; detailizers {names}; load {os.getloadavg()[0]:.2f}", flush=True)
    for out in outputs:
        grid = protocol.grid(out)
        for n, det in dets.items():
            t = time.perf_counter()
            fine = det.detailize(grid, seed=0)
            seconds = time.perf_counter() - t
            binary = np.asarray(fine.occupancy) > 0.4
            strict, loose = strict_loose_iou(binary, grid.occupancy)
            row = {"id": out.id, "detailizer": n, "seconds": round(seconds, 3), "strict": strict, "loose": loose,
                   **structure(binary, grid.occupancy)}
            if n == "quilt":
                content, lib, res = det.source_field(grid, 0)
                row["continuation"] = res.continuation
                row.update({k: v for k, v in fine.extras.items() if k in ("fragments_removed", "bridges")})
            rows.append(row)
            print(json.dumps(row), flush=True)
    print("\n| detailizer | n | s/output | Strict | Loose | continuation | floating | cavities |")
    print("|---|---|---|---|---|---|---|---|")
    for n in names:
        rs = [r for r in rows if r["detailizer"] == n]
        m = {k: float(np.mean([r[k] for r in rs])) for k in rs[0] if isinstance(rs[0][k], (int, float))}
        cont = f"{m['continuation']:.3f}" if "continuation" in m else "-"
        print(f"| {n} | {len(rs)} | {m['seconds']:.2f} | {m['strict']:.3f} | {m['loose']:.3f} | {cont} | "
              f"{sum(r['floating'] for r in rs)} | {sum(r['cavities'] for r in rs)} |")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


# --------------------------------------------------------------------------- long word

LONG_RECIPE = """version: 1
assets:
  - name: long_word
    source: {{kind: text, text: {text}, size_m: 0.5, depth_m: 0.12}}
    grid: {{resolution: {resolution}, max_cells: 512}}
    regions:
      - {{parts: ["*"], part: bottom, style: {bottom}}}
      - {{band: {{from: 0.65}}, part: top, style: {top}}}
"""


def long_grid(text: str, resolution: int, bottom: str, top: str):
    """The coarse grid of a line of text, voxelized by the pipeline itself."""
    import tempfile

    from core.recipe_loader import load_recipe
    from geometry.voxelize import voxelize
    from pipeline.regions import apply_regions
    from sources import load_source

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "long.yaml"
        path.write_text(LONG_RECIPE.format(text=text, resolution=resolution, bottom=bottom, top=top))
        loaded = load_recipe(path)
        asset = loaded.recipe.assets[0]
        grid, _ = apply_regions(voxelize(load_source(asset.source, loaded.base_dir), asset.grid, asset.fit),
                                asset.regions)
    return grid


def _long_child(name: str, text: str, resolution: int, queue) -> None:
    import resource

    grid = long_grid(text, resolution, "tower", "druse")
    det = _detailizer(name, _protocol_set())
    det.detailize(long_grid("AB", resolution, "tower", "druse"), seed=0)  # warm-up: library, sources
    t = time.perf_counter()
    fine = det.detailize(grid, seed=0)
    seconds = time.perf_counter() - t
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2  # before the measures' own arrays
    binary = np.asarray(fine.occupancy) > 0.4
    from core.structure import strict_loose_iou

    strict, loose = strict_loose_iou(binary, grid.occupancy)
    queue.put({"detailizer": name, "coarse": list(grid.shape), "occupied": grid.count, "seconds": round(seconds, 2),
               "peak_rss_gb": round(peak, 2),
               "strict": strict, "loose": loose, **structure(binary, grid.occupancy),
               **{k: v for k, v in fine.extras.items() if k in ("continuation", "fragments_removed", "bridges")}})


def _protocol_set():
    from evaluation.protocol import load_protocol, resolve_protocol_set

    return resolve_protocol_set(load_protocol())


def _in_child(target, *args) -> dict:
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=target, args=(*args, queue))
    proc.start()
    result = queue.get()
    proc.join()
    return result


def long_word(args) -> None:
    for name in args.detailizers.split(","):
        print(json.dumps(_in_child(_long_child, name, args.text, args.resolution)), flush=True)


# --------------------------------------------------------------------------- speed


def _speed_child(name: str, repeats: int, ids: list[str], queue) -> None:
    import resource
    import statistics

    from evaluation.benchmarking import house_grid
    from evaluation.protocol import load_protocol

    out = {"detailizer": name}
    t = time.perf_counter()
    if name == "quilt":
        from model.quilt import QuiltDetailizer

        det = QuiltDetailizer()  # the default set, as a recipe gets it
        out["load_s"] = round(time.perf_counter() - t, 2)
        out.update(library_build(det))
    else:
        from core.detailizer import get_detailizer

        det = get_detailizer(name, None, "cpu")
        out["load_s"] = round(time.perf_counter() - t, 2)
    styles = ("cottage", "pagoda") if name != "upsample" else ("a", "b")
    protocol = load_protocol()
    grids = {"house": house_grid(styles, ("bottom", "top"))}
    grids.update({i: protocol.grid(next(o for o in protocol.outputs if o.id == i)) for i in ids})
    for key, grid in grids.items():
        det.detailize(grid, seed=0)  # warm-up: the styles' sources and tables
        wall, cpu = [], []
        for seed in range(repeats):
            t, c = time.perf_counter(), time.process_time()
            det.detailize(grid, seed=seed)
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        out[key] = {"median_s": round(statistics.median(wall), 3), "min_s": round(min(wall), 3),
                    "cpu_s": round(statistics.median(cpu), 3), "cells": int(grid.count)}
    out["peak_rss_gb"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2, 2)
    out["load_average"] = [round(x, 2) for x in os.getloadavg()]
    queue.put(out)


def library_build(det) -> dict:
    """Seconds to build everything quilt derives from the set, uncached: the per-exemplar stats (what
    the disk cache holds), the 8-symmetry tables and the smoothed sources of every exemplar."""
    from model.quilt import assemble as asm
    from model.quilt import library as libm

    s = det.style_set
    t0 = time.perf_counter()
    stats = libm.load_stats(s, use_cache=False)
    t1 = time.perf_counter()
    tables = [libm.build_table(st) for st in stats]
    t2 = time.perf_counter()
    for ex in s.exemplars:
        asm.smooth_source(ex.labels, ex.offset, s.resolution)
    t3 = time.perf_counter()
    t4 = time.perf_counter()
    libm.load_stats(s)  # from the disk cache
    t5 = time.perf_counter()
    return {"set": s.name, "exemplars": len(s.exemplars), "entries": int(sum(len(t) for t in tables)),
            "stats_s": round(t1 - t0, 2), "tables_s": round(t2 - t1, 2), "sources_s": round(t3 - t2, 2),
            "library_build_s": round(t3 - t0, 2), "stats_from_cache_s": round(t5 - t4, 2)}


def speed(args) -> None:
    ids = [i for i in args.ids.split(",") if i]
    for name in args.detailizers.split(","):
        print(json.dumps(_in_child(_speed_child, name, args.repeats, ids)), flush=True)


# --------------------------------------------------------------------------- a user's own style

IMPORT_RECIPE = """version: 1
defaults:
  detailize: {{detailizer: quilt, style_set: {set_name}, seed: 0}}
assets:
  - name: hi_{style}
    source: {{kind: text, text: HI, size_m: 0.5, depth_m: 0.15}}
    regions:
      - {{parts: ["*"], part: body, style: {style}}}
      - {{band: top, part: roof, style: {style}}}
"""


def user_meshes(folder: Path) -> None:
    """Two exemplars a user might export: a colonnade hall and a ribbed tower, parts body/roof as GLB nodes."""
    import trimesh

    def moved(mesh, offset):
        mesh.apply_translation(offset)
        return mesh

    hall = [moved(trimesh.creation.box((2.0, 0.2, 1.2)), (0, 0.1, 0))]
    hall += [moved(trimesh.creation.cylinder(0.07, 1.0, sections=24), (x, 0.7, z))
             for x in np.linspace(-0.9, 0.9, 8) for z in (-0.5, 0.5)]
    hall += [moved(trimesh.creation.box((1.6, 0.9, 0.8)), (0, 0.65, 0))]
    roof = [moved(trimesh.creation.box((2.1, 0.12, 1.3)), (0, 1.26, 0)),
            moved(trimesh.creation.cone(0.9, 0.5, sections=4), (0, 1.32, 0))]
    tower = [moved(trimesh.creation.cylinder(0.35, 2.0, sections=32), (0, 1.0, 0))]
    tower += [moved(trimesh.creation.annulus(0.34, 0.42, 0.06, sections=32), (0, y, 0))
              for y in np.arange(0.2, 2.0, 0.25)]
    spire = [moved(trimesh.creation.cone(0.45, 0.8, sections=32), (0, 2.0, 0))]
    for name, parts in (("hall", {"body": hall, "roof": roof}), ("ribbed_tower", {"body": tower, "roof": spire})):
        scene = trimesh.Scene()
        for part, meshes in parts.items():
            for i, mesh in enumerate(meshes):
                scene.add_geometry(mesh, node_name=f"{part}_{i}", geom_name=f"{part}_{i}_g")
        scene.export(folder / f"{name}.glb")


def import_to_asset(args) -> None:
    """Wall time from ``decollage styles import`` of a mesh folder to the first asset built with quilt."""
    import tempfile

    exe = str(Path(sys.executable).with_name("decollage"))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        meshes = tmp / "meshes"
        meshes.mkdir()
        user_meshes(meshes)
        env = {**os.environ, "DECOLLAGE_STYLES_DIR": str(tmp / "styles")}
        (tmp / "recipe.yaml").write_text(IMPORT_RECIPE.format(set_name="mine", style="hall"))
        t0 = time.perf_counter()
        subprocess.run([exe, "styles", "import", str(meshes), "--name", "mine", "--vocab", "things"], env=env,
                       check=True, capture_output=True)
        t1 = time.perf_counter()
        subprocess.run([exe, "build", str(tmp / "recipe.yaml"), "-o", str(tmp / "out")], env=env, check=True,
                       capture_output=True)
        t2 = time.perf_counter()
        manifest = json.loads((tmp / "out" / "manifest.json").read_text())
        timings = manifest["assets"][0].get("timings_s")
        print(json.dumps({"import_s": round(t1 - t0, 1), "build_s": round(t2 - t1, 1), "total_s": round(t2 - t0, 1),
                          "asset_timings_s": timings, "load": os.getloadavg()[0]}))
        if args.keep:
            import shutil

            Path(args.keep).mkdir(parents=True, exist_ok=True)
            for f in (tmp / "out").glob("*.png"):
                shutil.copy(f, Path(args.keep) / f.name)


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    q = sub.add_parser("seams")
    q.add_argument("--limit", type=int, default=16)
    q.add_argument("--ids", default="")
    q.add_argument("--split", default="", help="a split of the protocol (dev or test)")
    q.add_argument("--detailizers", default="quilt,upsample")
    q.add_argument("--json", default="")
    lw = sub.add_parser("long")
    lw.add_argument("--text", default="QUILTEDLETTERSINAROW")
    lw.add_argument("--resolution", type=int, default=17)
    lw.add_argument("--detailizers", default="quilt,upsample")
    sp = sub.add_parser("speed")
    sp.add_argument("--repeats", type=int, default=5)
    sp.add_argument("--ids", default="text_A/00,cad_mushroom/08,mesh_cottage/00")
    sp.add_argument("--detailizers", default="quilt,upsample,decollage")
    im = sub.add_parser("import")
    im.add_argument("--keep", default="", help="copy the built previews here")
    args = ap.parse_args(argv)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}")
    {"seams": seams, "long": long_word, "import": import_to_asset, "speed": speed}[args.cmd](args)


if __name__ == "__main__":
    main(sys.argv[1:])

"""Shared benchmark code: detailizer cost, end-to-end asset builds, training iterations, the benchmarks doc.

Used by ``decollage bench`` (``cli/bench.py``) and by the scripts
``benchmarks/bench_detailizer.py`` and ``benchmarks/bench_pipeline.py``.

* ``measure_detailizer`` — one 16³ → 256³ detailization of a house-like grid
  (``house_grid``) in a fresh child process (spawn), so the peak RSS
  (``ru_maxrss``) is that of loading the model and detailizing, not of the
  caller; time = median of ``repeats`` calls after one warm-up; on CUDA also
  the peak allocated GPU memory. ``"random-lean"`` times the lean layout with
  random weights (the cost does not depend on the weights) when no trained
  model exists.
* ``bench_assets`` — every asset of recipes built once to warm up, then
  ``repeats`` times; medians per stage.
* ``train_iteration_seconds`` — a few ``model.train.Trainer`` iterations on a
  style set, after one warm-up, with the early (4 reconstruction steps) and
  the later (1 step) schedules.
* ``reference_workload_seconds`` — the fixed reference workload (marching cubes of a 256³
  sphere field), timed in the same run as the other figures so that they can be read as ratios.
* ``write_doc_section`` — replace or append a marked section of a markdown
  file (``<!-- decollage:KEY:begin -->`` … ``<!-- decollage:KEY:end -->``), so
  the bench figures and the evaluation tables share ``docs/benchmarks.md``.
"""

from __future__ import annotations

import multiprocessing as mp
import statistics
import tempfile
import time
from pathlib import Path
from typing import Callable, Sequence

REPO = Path(__file__).resolve().parents[1]
STAGES = ("source", "voxelize", "regions", "detailize", "mesh", "engine", "export")

#: The reference workload's grid side and sphere radius (voxels): a fixed task that readers on other
#: machines can time to compare ratios rather than seconds.
REFERENCE_SIDE, REFERENCE_RADIUS = 256, 100.0


def reference_workload_seconds(repeats: int = 5) -> dict:
    """The reference workload: scikit-image marching cubes (Lewiner, level = radius) of a 256³ float32
    field of distance from the centre, median of ``repeats`` runs after a warm-up.

    Returns ``{"median_s", "min_s", "median_cpu_s", "faces", "repeats", "load_average"}`` (the load average
    when it started; other jobs on the machine slow every figure of the same run alike, which the ratios
    cancel).
    """
    import os

    import numpy as np
    from skimage import measure

    load = [round(v, 2) for v in os.getloadavg()] if hasattr(os, "getloadavg") else None
    axis = np.arange(REFERENCE_SIDE, dtype=np.float32) - (REFERENCE_SIDE - 1) / 2
    field = np.sqrt(axis[:, None, None] ** 2 + axis[None, :, None] ** 2 + axis[None, None, :] ** 2)
    times, cpu_times, faces = [], [], 0  # wall, and this process's CPU time
    for run in range(repeats + 1):
        start, cpu = time.perf_counter(), time.process_time()
        _verts, tris, _n, _v = measure.marching_cubes(field, level=REFERENCE_RADIUS, method="lewiner")
        if run:  # the first run warms caches up
            times.append(time.perf_counter() - start)
            cpu_times.append(time.process_time() - cpu)
        faces = len(tris)
    return {"median_s": statistics.median(times), "min_s": min(times),
            "median_cpu_s": statistics.median(cpu_times), "faces": faces, "repeats": repeats,
            "load_average": load}


def house_grid(style_names: tuple[str, str], part_names: tuple[str, str]):
    """A 16³ LabeledGrid: a box body (part 0, style 0) under a stepped roof (part 1, style 1)."""
    import numpy as np

    from core.grid import EMPTY, LabeledGrid

    occ = np.zeros((16, 16, 16), bool)
    part = np.full(occ.shape, EMPTY, np.int16)
    occ[2:14, 1:10, 2:14] = True
    part[2:14, 1:10, 2:14] = 0
    for k, y in enumerate(range(10, 15)):
        occ[2 + k:14 - k, y, 2:14] = True
        part[2 + k:14 - k, y, 2:14] = 1
    style = np.where(occ, part, EMPTY).astype(np.int16)
    return LabeledGrid(occupancy=occ, part=part, style=style, part_names=part_names, style_names=style_names,
                       voxel_size_m=0.5)


def _random_lean_checkpoint(folder: Path) -> str:
    import torch

    from model.checkpoint import Checkpoint, save_checkpoint
    from model.config import ModelConfig
    from model.networks import Generator

    styles = tuple(f"style{i}" for i in range(20))
    cfg = ModelConfig.lean(2, len(styles))
    torch.manual_seed(0)
    gen = Generator(cfg)
    ck = Checkpoint(cfg, styles, ("bottom", "top"), (("bottom", "top"),) * len(styles), gen.state_dict(),
                    {"step": 0})
    return str(save_checkpoint(folder / "random_lean.pt", ck))


def _measure(which: str, device: str, repeats: int, threads: int | None, queue) -> None:
    import os

    from core.processes import own_peak_rss_mb  # the child's own peak (ru_maxrss carries the parent's)

    if threads:
        os.environ["OMP_NUM_THREADS"] = str(threads)
    import torch

    from core.detailizer import get_detailizer

    try:
        with tempfile.TemporaryDirectory() as tmp:
            non_learned = which in ("upsample", "quilt")  # CPU only; quilt copies from its default set
            checkpoint = None if non_learned or which == "shipped" else which
            if which == "random-lean":
                checkpoint = _random_lean_checkpoint(Path(tmp))
            t0 = time.perf_counter()
            det = get_detailizer(which if non_learned else "decollage", checkpoint, "cpu" if non_learned else device)
            load_s = time.perf_counter() - t0
            styles = tuple(det.style_names[:2]) if getattr(det, "style_names", None) else ("a", "b")
            parts = tuple(det.part_names[:2]) if getattr(det, "part_names", None) else ("bottom", "top")
            grid = house_grid(styles if len(styles) == 2 else styles * 2, parts)
            det.detailize(grid)  # warm-up
            on_cuda = str(getattr(det, "device", "cpu")).startswith("cuda")
            if on_cuda:
                torch.cuda.synchronize()
                torch.cuda.reset_peak_memory_stats()
            times, cpu_times = [], []  # wall, and this process's CPU time (what other jobs on the cores do not inflate)
            for seed in range(repeats):
                t, c = time.perf_counter(), time.process_time()
                det.detailize(grid, seed=seed)
                if on_cuda:
                    torch.cuda.synchronize()
                times.append(time.perf_counter() - t)
                cpu_times.append(time.process_time() - c)
            info = det.describe()
            queue.put({
                "detailizer": which, "load_s": load_s, "median_s": statistics.median(times), "min_s": min(times),
                "median_cpu_s": statistics.median(cpu_times),
                "peak_rss_gb": own_peak_rss_mb() / 1024,
                "peak_gpu_gb": torch.cuda.max_memory_allocated() / 1024**3 if on_cuda else None,
                "device": str(getattr(det, "device", "cpu")), "threads": torch.get_num_threads(),
                "params": info.get("generator_params"), "repeats": repeats})
    except Exception as exc:  # noqa: BLE001 - reported to the parent, which raises a clear error
        queue.put({"error": f"{type(exc).__name__}: {getattr(exc, 'one_line', lambda: str(exc))()}"})


def measure_detailizer(which: str, device: str = "cpu", repeats: int = 5, threads: int | None = None) -> dict:
    """Time one 16³ → 256³ detailization in a fresh process.

    Args:
        which: "upsample", "quilt", "shipped" (the default checkpoint), "random-lean", or a checkpoint path.
        device: "cpu" or "cuda" (the non-learned detailizers always run on the CPU).
        threads: CPU threads in the child (default: every core).
    Raises:
        RuntimeError: the child failed (its message).
    """
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_measure, args=(which, device, repeats, threads, queue))
    proc.start()
    result = queue.get()
    proc.join()
    if "error" in result:
        raise RuntimeError(result["error"])
    return result


def bench_assets(recipes: Sequence[Path], repeats: int = 3,
                 progress: Callable[[str], None] | None = None, reference: bool = True) -> list[dict]:
    """End-to-end build time per asset (source → GLB + preview): median of ``repeats`` after a warm-up.

    Each asset is built as ``decollage build`` (``--jobs 1``) builds it: with a block process when the
    machine has a second core (``pipeline/executors.py``'s ``LocalExecutor``). With ``reference``, each
    row also holds ``reference_s``: the reference workload timed just before and just after that asset's
    builds (the mean of the two medians), so that its ratio compares figures of the same minutes even
    when the machine's speed drifts (shared virtual machines: other guests' load shows as steal time).
    """
    from core.recipe_loader import load_recipe
    from pipeline.build import Progress, build_asset, check_recipe
    from pipeline.executors import LocalExecutor

    processes = LocalExecutor().block_processes
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for recipe in recipes:
            loaded = load_recipe(recipe)
            check_recipe(loaded)
            for index, asset in enumerate(loaded.recipe.assets):
                build_asset(loaded, index, Path(tmp), Progress(), block_processes=processes)  # warm-up: imports, caches
                before = reference_workload_seconds(3)["median_s"] if reference else None
                runs = [build_asset(loaded, index, Path(tmp), Progress(), block_processes=processes)
                        for _ in range(repeats)]
                after = reference_workload_seconds(3)["median_s"] if reference else None
                if any(r.status != "built" for r in runs):
                    raise RuntimeError(f"{asset.name} failed: {next(r.error for r in runs if r.status != 'built')}")
                medians = {s: statistics.median(r.timings_s.get(s, 0.0) for r in runs) for s in STAGES}
                rows.append({"recipe": Path(recipe).name, "asset": asset.name, "stages_s": medians,
                             "total_s": sum(medians.values()),
                             "glb_bytes": runs[0].outputs.get("glb", {}).get("bytes"),
                             "detailizer": runs[0].info["detailizer"]["name"],
                             "fine_grid": runs[0].info["fine_grid_shape"],
                             "triangles": runs[0].info["mesh"]["triangles"], "repeats": repeats,
                             "block_processes": processes,
                             **({"reference_s": (before + after) / 2} if reference else {})})
                if progress:
                    progress(f"{asset.name}: {rows[-1]['total_s']:.2f} s")
    return rows


def train_iteration_seconds(style_set, iterations: int = 2, resolution: int = 256, device: str = "cpu",
                            seed: int = 0) -> dict:
    """Seconds per ``Trainer.iteration`` (lean layout) on a style set, early and later schedules.

    Early = the first ``recon_early_iters`` iterations (4 reconstruction steps
    each), later = 1 reconstruction step. Each: one warm-up, then the median of
    ``iterations``.
    """
    import torch

    from model.config import ModelConfig
    from model.data import exemplars_from_set
    from model.train import TrainConfig, Trainer

    exemplars = exemplars_from_set(style_set)
    cfg = ModelConfig.lean(n_parts=len(style_set.vocabulary.parts), n_styles=len(exemplars))
    out = {"iterations": iterations, "resolution": resolution, "layout": "lean"}
    with tempfile.TemporaryDirectory() as tmp:
        for name, early in (("early_s", 10**9), ("later_s", 0)):
            tcfg = TrainConfig(out_dir=tmp, steps=iterations + 1, seed=seed, device=device, resolution=resolution,
                               recon_early_iters=early)
            trainer = Trainer(exemplars, cfg, tcfg, part_aliases=style_set.vocabulary.alias_map())
            times = []
            for _ in range(iterations + 1):
                t = time.perf_counter()
                trainer.iteration()
                if trainer.device.type == "cuda":
                    torch.cuda.synchronize()
                times.append(time.perf_counter() - t)
            out[name] = statistics.median(times[1:])
            out["device"] = str(trainer.device)
    out["threads"] = torch.get_num_threads()
    return out


def write_doc_section(path: Path, key: str, text: str, title: str = "# Benchmarks\n") -> Path:
    """Put ``text`` between the markers of section ``key`` in a markdown file (replacing the old text).

    The file is created with ``title`` if missing; a missing section is appended.
    """
    from core.files import write_bytes_atomic

    path = Path(path)
    begin, end = f"<!-- decollage:{key}:begin -->", f"<!-- decollage:{key}:end -->"
    block = f"{begin}\n{text.rstrip()}\n{end}\n"
    old = path.read_text(encoding="utf-8") if path.exists() else title
    if begin in old and end in old:
        head, rest = old.split(begin, 1)
        tail = rest.split(end, 1)[1].lstrip("\n")
        new = head + block + ("\n" + tail if tail else "")
    else:
        new = old.rstrip("\n") + "\n\n" + block
    write_bytes_atomic(path, new.encode())
    return path

"""Benchmark: 256³ fine field → mesh → GLB → preview (prints a table; not a test).

The field is a chair made of boxes (legs, seat, cushion, back, arm rests) with
a seeded surface texture, Gaussian-smoothed to float32 like a detailizer's
output, ~10–15 % occupied. Each step is timed as the median of ``--repeats``
runs. Run from the repository root::

    python benchmarks/bench_mesh_export.py [--repeats 3] [--size 256]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.export import ENCODERS, export_mesh  # noqa: E402
from core.grid import ISO_LEVEL, FineGrid  # noqa: E402
from pipeline.mesh import MeshSettings, crop_padded, marching_cubes, mesh_fine_grid  # noqa: E402
from pipeline.simplify import decimate  # noqa: E402
from geometry.preview import render_preview  # noqa: E402
from core.recipe import ExportFormat, Pivot  # noqa: E402


def chair_field(n: int = 256, seed: int = 0) -> FineGrid:
    """A chair-like (n, n, n) float32 occupancy with three style regions (legs, seat, back)."""
    from scipy import ndimage

    s = n / 256.0  # box coordinates below are for n = 256

    def box(lo: tuple[int, int, int], hi: tuple[int, int, int]) -> tuple[slice, ...]:
        return tuple(slice(int(a * s), int(b * s)) for a, b in zip(lo, hi))

    occ = np.zeros((n, n, n), dtype=np.float32)
    for x in (40, 196):
        for z in (40, 196):
            occ[box((x, 8, z), (x + 20, 110, z + 20))] = 1  # legs
    occ[box((36, 110, 36), (220, 130, 220))] = 1  # seat
    occ[box((48, 130, 48), (208, 142, 208))] = 1  # cushion
    occ[box((36, 130, 36), (220, 248, 62))] = 1  # back
    occ[box((60, 160, 44), (196, 230, 64))] = 0  # opening in the back
    for x in (36, 200):
        occ[box((x, 170, 62), (x + 20, 184, 210))] = 1  # arm rests
        occ[box((x, 130, 190), (x + 20, 170, 206))] = 1  # arm posts
    texture = np.random.default_rng(seed).standard_normal(occ.shape).astype(np.float32)
    texture = ndimage.gaussian_filter(texture, 2.0)
    occ = ndimage.gaussian_filter(occ + 4.0 * texture * (occ > 0), 1.5).astype(np.float32)
    np.clip(occ, 0.0, 1.0, out=occ)
    y = np.arange(n)[None, :, None]
    style = np.broadcast_to(np.where(y < 110 * s, 0, np.where(y < 142 * s, 1, 2)), occ.shape).astype(np.int16)
    return FineGrid(occ, np.ascontiguousarray(style), ("oak", "fabric", "wicker"), 1.0 / n, (-0.5, 0.0, -0.5))


def timed(fn, repeats: int):
    """(median seconds, last result)."""
    times, result = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--size", type=int, default=256)
    args = parser.parse_args()
    r = args.repeats

    t0 = time.perf_counter()
    fine = chair_field(args.size)
    build_s = time.perf_counter() - t0
    occupied = float((fine.occupancy >= ISO_LEVEL).mean())
    # Warm the lazy imports so that they do not count against the first step.
    mesh_fine_grid(chair_field(32), MeshSettings(max_triangles=1000))

    rows: list[tuple[str, float, str]] = []
    t, (crop, start) = timed(lambda: crop_padded(fine.occupancy, ISO_LEVEL), r)
    rows.append(("bbox crop + pad", t, f"crop {crop.shape}"))
    t, (verts, faces) = timed(lambda: marching_cubes(crop, ISO_LEVEL), r)
    rows.append(("marching cubes (lewiner)", t, f"{len(faces):,} faces"))
    for target in (150_000, 20_000):
        t, (_v, f) = timed(lambda: decimate(verts, faces, target), r)
        rows.append((f"decimate → {target:,}", t, f"{len(f):,} faces"))
    t, full = timed(lambda: mesh_fine_grid(fine, MeshSettings(max_triangles=None)), r)
    rows.append(("mesh_fine_grid, no decimation", t, f"{len(full.faces):,} faces, watertight={full.is_watertight}"))
    t, mesh = timed(lambda: mesh_fine_grid(fine, MeshSettings(max_triangles=150_000)), r)
    rows.append(("mesh_fine_grid → 150k (all steps)", t, f"watertight={mesh.is_watertight}"))
    mesh_total = t
    t, small = timed(lambda: mesh_fine_grid(fine, MeshSettings(max_triangles=20_000)), r)
    rows.append(("mesh_fine_grid → 20k (all steps)", t, f"watertight={small.is_watertight}"))
    t, smooth = timed(lambda: mesh_fine_grid(fine, MeshSettings(max_triangles=150_000, taubin_iterations=5)), r)
    rows.append(("… with 5 Taubin passes", t, ""))
    for fmt in ExportFormat:
        t, data = timed(lambda: ENCODERS[fmt](mesh, "chair"), r)
        rows.append((f"encode {fmt.value.upper()} (150k)", t, f"{len(data) / 2**20:.1f} MiB"))
    with tempfile.TemporaryDirectory() as tmp:
        t, _ = timed(lambda: export_mesh(mesh, Path(tmp), "chair", [ExportFormat.GLB], Pivot.BOTTOM_CENTER), r)
    rows.append(("export_mesh GLB (pivot + atomic write)", t, ""))
    glb_total = t
    for target_mesh, label in ((mesh, "150k"), (small, "20k")):
        t, _ = timed(lambda: render_preview(target_mesh, 512), r)
        rows.append((f"preview 512² ({label}, 2× supersampled)", t, ""))
        t, _ = timed(lambda: render_preview(target_mesh, 512, supersample=1), r)
        rows.append((f"preview 512² ({label}, no supersampling)", t, ""))

    print(f"field {fine.shape}, {occupied:.1%} occupied (built in {build_s:.1f} s, not timed); "
          f"median of {r} runs")
    print(f"{'step':<44} {'seconds':>8}  note")
    print("-" * 90)
    for name, seconds, note in rows:
        print(f"{name:<44} {seconds:8.3f}  {note}")
    print("-" * 90)
    print(f"{'MC + decimation(150k) + colours + GLB':<44} {mesh_total + glb_total:8.3f}  target ≤ 1.5 s")


if __name__ == "__main__":
    main()

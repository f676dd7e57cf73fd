"""Timings of the paper metrics at 256³ (not a test; prints a small report).

Run: ``python benchmarks/bench_metrics.py [--styles 16] [--outputs 4] [--res 256]``
from the repository root. Shapes are smooth solids (rounded boxes, tori,
spheres) with low-frequency surface noise, so that patches are realistic:
mostly distinct, some close to style patches. The dictionary is built from
``--styles`` such shapes; the outputs are other shapes of the same families
with other noise seeds, and for each output the script times Strict/Loose-IOU
(against its own 16³ max-pool, shifted by a cell so that it is not trivially 1)
and LP-IOU + LP-F (1000 patches), then extrapolates to 320 outputs; it also
times the Cls renderer (exposed-voxel extraction once, then per view).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core.structure import strict_loose_iou  # noqa: E402
from evaluation.lp import lp_scores  # noqa: E402
from evaluation.patch_index import style_patch_dictionary  # noqa: E402
from evaluation.render_eval import render_views  # noqa: E402


def noisy_shape(kind: int, seed: int, res: int, rough: bool = False) -> np.ndarray:
    """(res, res, res) bool: a smooth solid of family ``kind % 3`` with surface noise (voxels).

    ``rough``: high-frequency noise (64³ field, amplitude 3 voxels) instead of
    low-frequency noise, so that few patches resemble any style patch: the
    slow case of the search, where most queries must be proven dissimilar.
    """
    from scipy.ndimage import gaussian_filter, zoom

    rng = np.random.default_rng(seed)
    c = (np.arange(res) + 0.5) / res - 0.5
    x, y, z = np.meshgrid(c, c, c, indexing="ij", sparse=True)
    fam = kind % 3
    if fam == 0:  # rounded box with random extents
        h = rng.uniform(0.2, 0.38, size=3)
        q = np.maximum(np.abs(x) - h[0], 0) ** 2 + np.maximum(np.abs(y) - h[1], 0) ** 2 \
            + np.maximum(np.abs(z) - h[2], 0) ** 2
        sdf = np.sqrt(q) - 0.04
    elif fam == 1:  # torus
        big, small = rng.uniform(0.22, 0.3), rng.uniform(0.08, 0.14)
        sdf = np.sqrt((np.sqrt(x**2 + z**2) - big) ** 2 + y**2) - small
    else:  # sphere
        sdf = np.sqrt(x**2 + y**2 + z**2) - rng.uniform(0.3, 0.42)
    # low-frequency noise: a 32³ field smoothed and upsampled, amplitude ~2 voxels
    n_field, amp = (64, 3.0) if rough else (32, 2.0)
    coarse = gaussian_filter(rng.standard_normal((n_field,) * 3), 1.0 if rough else 1.5)
    noise = zoom(coarse / coarse.std(), res / n_field, order=1)
    return (sdf * res + amp * noise) < 0


def main() -> None:
    import torch

    parser = argparse.ArgumentParser()
    parser.add_argument("--styles", type=int, default=16)
    parser.add_argument("--outputs", type=int, default=4)
    parser.add_argument("--rough", type=int, default=2, help="extra outputs with rough surfaces")
    parser.add_argument("--res", type=int, default=256)
    parser.add_argument("--views", type=int, default=24, help="Cls renders to time (0: skip)")
    args = parser.parse_args()
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}, res {args.res}³")

    t = time.perf_counter()
    styles = [noisy_shape(k, 1000 + k, args.res) for k in range(args.styles)]
    print(f"made {args.styles} style shapes in {time.perf_counter() - t:.1f} s")
    t = time.perf_counter()
    dictionary = style_patch_dictionary(styles)
    build_s = time.perf_counter() - t
    mib = dictionary.nbytes / 2**20
    print(f"dictionary: {len(dictionary.occ_count)} occupancy patches, {len(dictionary.surf_count)} "
          f"surface patches, {mib:.0f} MiB, built in {build_s:.1f} s")

    times = []
    for n in range(args.outputs + args.rough):
        rough = n >= args.outputs
        out = noisy_shape(n, 5000 + n, args.res, rough=rough)
        factor = args.res // 16
        coarse = out.reshape(16, factor, 16, factor, 16, factor).any(axis=(1, 3, 5))
        t = time.perf_counter()
        strict, loose = strict_loose_iou(out, np.roll(coarse, 1, axis=0), factor=factor)
        t_iou = time.perf_counter() - t
        t = time.perf_counter()
        lp_iou, lp_f = lp_scores(out, dictionary, n=1000, seed=n)
        t_lp = time.perf_counter() - t
        times.append(t_iou + t_lp)
        print(f"output {n}{' (rough)' if rough else ''}: strict {strict:.3f} loose {loose:.3f} ({t_iou:.2f} s)  "
              f"LP-IOU {lp_iou:.3f} LP-F {lp_f:.3f} ({t_lp:.2f} s)")
    if args.views:
        from evaluation.render_eval import surface_voxels

        t = time.perf_counter()
        voxels = surface_voxels(styles[0])
        prep = time.perf_counter() - t
        t = time.perf_counter()
        render_views(voxels, n_views=args.views, seed=0)
        per_view = (time.perf_counter() - t) / args.views
        print(f"render (evaluation/render_eval.py): exposed voxels {len(voxels)} in {prep * 1e3:.0f} ms, then "
              f"{per_view * 1e3:.1f} ms per view → 24 views of 320 outputs ≈ "
              f"{(prep + 24 * per_view) * 320 / 60:.1f} min")
    for label, sel in (("smooth", times[: args.outputs]), ("rough", times[args.outputs :])):
        if sel:
            mean = float(np.mean(sel))
            print(f"{label}: mean {mean:.2f} s per output → 320 outputs ≈ {320 * mean / 60:.1f} min "
                  f"+ dictionary {build_s:.0f} s once")


if __name__ == "__main__":
    main()

"""Before/after pictures of the mesh smoothing on real detailizer output (writes PNGs; not a test).

For each showcase asset and detailizer given, the asset goes through the real flow (source → voxelize
→ regions → detailize) once, and is then meshed under each smoothing setting at its ``auto`` triangle
budget; the pictures (one row of settings per asset) go to ``--out``, with Strict-IOU of the fine grid
and the triangle count in the printed table. Look at them for exemplar detail (the quilt detailizer's
window frames and tiles) that a setting erases.

    .venv/bin/python benchmarks/smoothing_previews.py --out docs/previews/smoothing
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core.detailizer import get_detailizer, kernel_threads  # noqa: E402
from core.grid import UPSAMPLE_FACTOR  # noqa: E402
from core.structure import strict_loose_iou  # noqa: E402
from core.recipe_loader import load_recipe  # noqa: E402
from geometry.preview import render_preview  # noqa: E402
from geometry.voxelize import solid_occupancy, voxelize  # noqa: E402
from pipeline.chunks import detailize_and_mesh  # noqa: E402
from pipeline.mesh import MeshSettings, triangle_budget  # noqa: E402
from pipeline.regions import apply_regions  # noqa: E402
from sources import load_source  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
#: (label, Taubin passes, largest vertex shift in fine voxels)
SETTINGS = [("none", 0, None), ("Taubin x8, <= 0.5 voxel (default)", 8, 0.5), ("Taubin x16, free", 16, None)]


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "previews" / "smoothing")
    parser.add_argument("--assets", nargs="*", default=["cottage", "watchtower"])
    parser.add_argument("--detailizers", nargs="*", default=["quilt", "decollage"])
    parser.add_argument("--size", type=int, default=640)
    parser.add_argument("--zoom", type=float, default=1.0, help="crop the middle 1/zoom of each picture")
    args = parser.parse_args(argv)
    from PIL import Image

    loaded = load_recipe(REPO / "recipes" / "showcase.yaml")
    args.out.mkdir(parents=True, exist_ok=True)
    print("| asset | detailizer | smoothing | triangles | Strict-IOU of the fine grid | Strict-IOU of the "
          "re-voxelized mesh |")
    print("|---|---|---|---|---|---|")
    for asset in (a for a in loaded.recipe.assets if a.name in args.assets):
        grid, _ = apply_regions(voxelize(load_source(asset.source, loaded.base_dir), asset.grid, asset.fit),
                                asset.regions, field="regions")
        budget = triangle_budget("auto", asset.export.use, grid.occupancy)
        for name in args.detailizers:
            detailizer = get_detailizer(name, None, "cpu")
            fine = None
            tiles = []
            for label, passes, shift in SETTINGS:
                settings = MeshSettings(max_triangles=budget, taubin_iterations=passes, taubin_max_shift=shift)
                if fine is None:
                    with kernel_threads(2):
                        fine = detailizer.detailize(grid, seed=0)
                result = detailize_and_mesh(grid, lambda g: fine, settings)
                image = render_preview(result.mesh, args.size)
                if args.zoom > 1:
                    side = int(args.size / args.zoom)
                    lo = (args.size - side) // 2
                    image = image.crop((lo, lo, lo + side, lo + side)).resize((args.size, args.size))
                tiles.append(np.asarray(image))
                revoxelized = solid_occupancy(result.mesh, result.fine_shape, grid.origin_m,
                                              grid.voxel_size_m / UPSAMPLE_FACTOR) >= 0.5
                strict, _ = strict_loose_iou(revoxelized, grid.occupancy)
                print(f"| {asset.name} | {name} | {label} | {len(result.mesh.faces)} | "
                      f"{result.structure['strict_iou']:.4f} | {strict:.4f} |")
            path = args.out / f"{asset.name}_{name}.png"
            # 256 colours: the pictures are shaded single-colour surfaces, and the docs stay small
            Image.fromarray(np.concatenate(tiles, axis=1)).quantize(256).save(path, optimize=True)
            print(f"wrote {path} (left to right: {', '.join(s[0] for s in SETTINGS)})")


if __name__ == "__main__":
    main(sys.argv[1:])

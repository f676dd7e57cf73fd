"""Benchmark: what meshing costs the coarse structure (prints a markdown table; not a test).

For each asset: the default detailizer's fine grid is meshed twice through ``pipeline/chunks.py`` (block
by block, as a build does) at the asset's own triangle budget:

* reference: full resolution, no smoothing (what marching cubes and decimation alone give);
* default: the asset's ``export`` settings (``mesh_resolution: auto``, Taubin smoothing with inner creases
  held and vertices kept in the occupied cells, ``pipeline/mesh.py``).

Each mesh is re-voxelized at the fine resolution (``geometry.voxelize.solid_occupancy``) and compared with
the coarse grid: Strict-IOU, coarse cells the mesh puts material in that the grid leaves empty ("extra"),
and occupied cells left without material ("missing"). The issue's bar: the default's Strict-IOU at most
0.01 below the reference's.

    .venv/bin/python benchmarks/bench_mesh_structure.py [--recipe R --assets A B ...]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from core.detailizer import get_detailizer  # noqa: E402
from core.grid import UPSAMPLE_FACTOR  # noqa: E402
from core.recipe_loader import load_recipe  # noqa: E402
from core.structure import strict_loose_iou  # noqa: E402
from geometry.voxelize import solid_occupancy, voxelize  # noqa: E402
from pipeline.chunks import detailize_and_mesh  # noqa: E402
from pipeline.mesh import MeshSettings  # noqa: E402
from pipeline.regions import apply_regions  # noqa: E402
from sources import load_source  # noqa: E402

DEFAULT_ASSETS = {
    "recipes/showcase.yaml": ["castle_word", "watchtower", "cottage", "mushroom"],
    "recipes/batch_showcase.yaml": ["sign_ORC_tower_druse", "sign_ELF_tower_druse", "sign_DWARF_tower_druse",
                                    "sign_TROLL_tower_druse"],
}


def structure_of(mesh, grid, fine_shape) -> tuple[float, int, int]:
    """(Strict-IOU, extra cells, missing cells) of a mesh re-voxelized against the coarse grid."""
    f = UPSAMPLE_FACTOR
    solid = solid_occupancy(mesh, fine_shape, grid.origin_m, grid.voxel_size_m / f) >= 0.5
    strict, _ = strict_loose_iou(solid, grid.occupancy)
    x, y, z = grid.shape
    cells = solid.reshape(x, f, y, f, z, f).any(axis=(1, 3, 5))
    return strict, int((cells & ~grid.occupancy).sum()), int((~cells & grid.occupancy).sum())


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recipe", type=Path)
    parser.add_argument("--assets", nargs="*")
    args = parser.parse_args(argv)
    plan = {str(args.recipe): args.assets} if args.recipe else DEFAULT_ASSETS
    print("| asset | coarse grid | triangles | resolution | reference Strict (extra / missing) | "
          "default Strict (extra / missing) | Δ |")
    print("|---|---|---|---|---|---|---|")
    for recipe, names in plan.items():
        loaded = load_recipe(REPO / recipe)
        for asset in (a for a in loaded.recipe.assets if not names or a.name in names):
            grid, _ = apply_regions(voxelize(load_source(asset.source, loaded.base_dir), asset.grid, asset.fit),
                                    asset.regions, field="regions")
            detailizer = get_detailizer(asset.detailize.detailizer, None, "cpu")
            default = MeshSettings.from_export(asset.export, grid.occupancy)
            reference = replace(default, sample_step=1, taubin_iterations=0)
            rows = []
            for settings in (reference, default):
                start = time.perf_counter()
                result = detailize_and_mesh(grid, lambda g: detailizer.detailize(g, seed=asset.detailize.seed),
                                            settings)
                rows.append((structure_of(result.mesh, grid, result.fine_shape), len(result.mesh.faces),
                             time.perf_counter() - start))
            (rs, re_, rm), _, _ = rows[0]
            (ds, de, dm), tris, _ = rows[1]
            print(f"| {asset.name} | {'×'.join(map(str, grid.shape))} | {tris} | "
                  f"{'half' if default.sample_step == 2 else 'full'} | {rs:.4f} ({re_} / {rm}) | "
                  f"{ds:.4f} ({de} / {dm}) | {ds - rs:+.4f} |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])

"""Voxelizer timings on large watertight meshes (not a test; prints a small table).

Run: ``python benchmarks/bench_voxelize.py`` from the repository root. Each row
is the best of ``REPEATS`` runs of ``geometry.voxelize.solid_occupancy`` (the
fill itself) and of ``voxelize`` (fill + labels + grid sizing), in milliseconds.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core.recipe import FitMode, GridSettings  # noqa: E402
from geometry.voxelize import solid_occupancy, voxelize  # noqa: E402
from sources.base import PartMeshes  # noqa: E402

REPEATS = 5


def _meshes():
    import trimesh

    return {
        "torus 2k": trimesh.creation.torus(1.0, 0.3, major_sections=64, minor_sections=16),
        "icosphere(6)": trimesh.creation.icosphere(subdivisions=6, radius=1.0),
        "torus 100k": trimesh.creation.torus(1.0, 0.3, major_sections=320, minor_sections=160),
    }


def _best_ms(fn) -> float:
    best = float("inf")
    for _ in range(REPEATS):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best * 1000.0


def main() -> None:
    rows = []
    for name, mesh in _meshes().items():
        lo, hi = mesh.bounds
        for resolution, supersample in ((256, 1), (64, 1), (16, 4)):
            voxel = float((hi - lo).max()) / resolution
            shape = tuple(int(np.ceil(e / voxel - 1e-9)) for e in hi - lo)
            fill_ms = _best_ms(lambda: solid_occupancy(mesh, shape, lo, voxel, supersample))
            # GridSettings caps resolution at 64 for recipes; the exemplar library builds it unvalidated.
            settings = GridSettings.model_construct(**{**GridSettings().model_dump(), "resolution": resolution,
                                                        "max_cells": max(512, resolution)})
            source = PartMeshes({"shape": mesh})
            full_ms = _best_ms(lambda: voxelize(source, settings, FitMode.LONGEST, supersample=supersample))
            rows.append((name, len(mesh.faces), f"{resolution}³", supersample, fill_ms, full_ms))
    print(f"{'mesh':<14}{'faces':>8}{'grid':>7}{'ss':>4}{'fill ms':>10}{'voxelize ms':>13}")
    for name, faces, grid, ss, fill_ms, full_ms in rows:
        print(f"{name:<14}{faces:>8}{grid:>7}{ss:>4}{fill_ms:>10.1f}{full_ms:>13.1f}")


if __name__ == "__main__":
    main()

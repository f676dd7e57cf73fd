"""Benchmark: terraces and decimation quality of the meshing step (prints markdown tables; not a test).

Terraces are the stair steps marching cubes leaves on a near-binary 256³ field. Two fields with a
known answer, binary like the output of a copying or a sharp learned detailizer:

* a sphere of radius 100 voxels in a 256³ grid: the mean and the spread (standard deviation: the
  terraces) of the vertices' distance to the centre, against the analytic radius, and the RMS angle
  between face normals and the sphere's normal;
* a flat wall tilted by 20° about z (and 10° about x): the spread (RMS angle) of its face normals
  around the wall's normal; a terrace-free wall has 0°.

Each row meshes the field with ``pipeline/mesh.py`` (decimated to 60 000 triangles, the budget of a
prop) under one smoothing setting. ``benchmarks/smoothing_previews.py`` shows the same settings on real
detailizer output, with Strict-IOU of the re-voxelized mesh.

    .venv/bin/python benchmarks/bench_mesh_quality.py
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core.grid import FineGrid  # noqa: E402
from evaluation.benchmarking import reference_workload_seconds  # noqa: E402
from pipeline.mesh import MeshSettings, mesh_fine_grid  # noqa: E402

N, RADIUS, BUDGET = 256, 100.0, 60_000
SETTINGS = [("none", 0, None), ("Taubin ×8, ≤ 0.5 voxel (default)", 8, 0.5), ("Taubin ×12, ≤ 0.5 voxel", 12, 0.5),
            ("Taubin ×16, ≤ 0.5 voxel", 16, 0.5), ("Taubin ×16, free", 16, None), ("Taubin ×32, ≤ 0.5 voxel", 32, 0.5)]


def sphere_field() -> FineGrid:
    axis = np.arange(N, dtype=np.float32) - (N - 1) / 2
    r = np.sqrt(axis[:, None, None] ** 2 + axis[None, :, None] ** 2 + axis[None, None, :] ** 2)
    return FineGrid((r <= RADIUS).astype(np.float32), np.zeros((N, N, N), np.int16), ("stone",), 1.0)


def wall_normal() -> np.ndarray:
    a, b = np.radians(20.0), np.radians(10.0)
    n = np.array([np.sin(a), np.cos(a), 0.0])
    n = np.array([n[0], n[1] * np.cos(b) - n[2] * np.sin(b), n[1] * np.sin(b) + n[2] * np.cos(b)])
    return n / np.linalg.norm(n)


def wall_field() -> FineGrid:
    """A slab below a tilted plane through the centre, 160 voxels wide: only its top face is measured."""
    idx = np.indices((160, 160, 160), dtype=np.float32) - 79.5
    height = np.einsum("i,ixyz->xyz", wall_normal().astype(np.float32), idx)
    occ = (height <= 0).astype(np.float32)
    return FineGrid(occ, np.zeros(occ.shape, np.int16), ("stone",), 1.0)


def face_normals(mesh) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(mesh.face_normals), np.asarray(mesh.area_faces)


def rms_angle_deg(normals: np.ndarray, reference: np.ndarray, weights: np.ndarray) -> float:
    cos = np.clip(np.einsum("ij,ij->i", normals, reference), -1.0, 1.0)
    return float(np.degrees(np.sqrt(np.average(np.arccos(cos) ** 2, weights=weights))))


def sphere_row(iterations: int, max_shift: float | None) -> dict:
    fine = sphere_field()
    start = time.perf_counter()
    mesh = mesh_fine_grid(fine, MeshSettings(max_triangles=BUDGET, taubin_iterations=iterations,
                                             taubin_max_shift=max_shift, vertex_colors=False))
    seconds = time.perf_counter() - start
    centre = (N - 1) / 2
    r = np.linalg.norm(mesh.vertices - centre, axis=1)
    normals, areas = face_normals(mesh)
    radial = mesh.triangles_center - centre
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    return {"bias": float(np.mean(r - RADIUS)), "rough": float(np.std(r)),
            "angle": rms_angle_deg(normals, radial, areas), "seconds": seconds, "faces": len(mesh.faces)}


def wall_row(iterations: int, max_shift: float | None) -> dict:
    fine = wall_field()
    mesh = mesh_fine_grid(fine, MeshSettings(max_triangles=BUDGET, taubin_iterations=iterations,
                                             taubin_max_shift=max_shift, vertex_colors=False))
    n = wall_normal()
    normals, areas = face_normals(mesh)
    centres = mesh.triangles_center - 79.5
    # the tilted top face, away from the slab's rim (20 voxels in from the box's sides)
    top = (np.abs(np.einsum("ij,j->i", centres, n)) < 3) & (np.abs(centres).max(axis=1) < 60)
    return {"angle": rms_angle_deg(normals[top], np.broadcast_to(n, normals[top].shape), areas[top])}


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    import os

    ref = reference_workload_seconds()
    print(f"reference workload {ref['median_s']:.3f} s, load average {os.getloadavg()}")
    sphere_row(0, None)  # warm-up: imports and first calls
    print("\n| smoothing | sphere: radius − 100 (voxels) | sphere: radius spread (voxels) | sphere: normal RMS "
          "angle | tilted wall: normal spread | mesh time s (× ref) | triangles |")
    print("|---|---|---|---|---|---|---|")
    for label, iterations, shift in SETTINGS:
        s, w = sphere_row(iterations, shift), wall_row(iterations, shift)
        print(f"| {label} | {s['bias']:+.3f} | {s['rough']:.3f} | {s['angle']:.1f}° | {w['angle']:.1f}° | "
              f"{s['seconds']:.2f} ({s['seconds'] / ref['median_s']:.1f}) | {s['faces']} |")


if __name__ == "__main__":
    main(sys.argv[1:])

"""Detailize and mesh an asset block by block along x, so that long assets (a 20-letter word) keep to
bounded memory and take time in proportion to their length.

A coarse grid at most ``WHOLE_MAX_CELLS`` columns long (every 16³ shape, a 3-letter word) is one
block: the detailizer sees it whole. A longer one is cut into blocks of ``CHUNK_CELLS`` columns.
Each block is detailized on its columns plus ``HALO_CELLS`` columns of context on either side (the
detailizer sees its neighbours' shapes there; only the block's own columns are kept), then meshed
(``pipeline/mesh.py``'s ``mesh_piece``) from its own fine columns plus the first fine column of the
next block (the first two when meshed at half resolution: one sample's box), so that two neighbouring
pieces are cut from the same samples on the plane they share:
their boundary vertices are equal bit for bit, kept in place by smoothing and decimation, and welded
when the pieces are joined. At most two blocks' fine fields are held at once; the whole fine grid
never exists.

The triangle budget (``max_triangles``) is shared among the blocks in proportion to their coarse
surface (occupied cells' faces that touch an empty cell), so that the joined mesh stays within it.
Strict- and Loose-IOU are summed over the blocks' own columns (``core/structure.py``'s counts);
the blocks' provenance extras are merged (``merge_extras``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core.grid import ISO_LEVEL, UPSAMPLE_FACTOR, FineGrid, LabeledGrid
from core.structure import iou_from_counts, structure_counts
from pipeline.mesh import MeshSettings, Piece, coarse_surface_faces, mesh_piece, to_trimesh

if TYPE_CHECKING:
    import trimesh

#: Grids of at most this many coarse columns along x are detailized and meshed as one block.
WHOLE_MAX_CELLS = 64
#: Own coarse columns of a block when a grid is longer.
CHUNK_CELLS = 32
#: Coarse columns of context the detailizer sees on either side of a block (cut away after).
HALO_CELLS = 2


@dataclass(frozen=True)
class Chunk:
    """One block: its own coarse columns ``[start, stop)`` and the columns ``[lo, hi)`` it is detailized on."""

    start: int
    stop: int
    lo: int
    hi: int


@dataclass
class DetailedMesh:
    """What ``detailize_and_mesh`` returns.

    Attributes:
        mesh: the joined mesh in metres (``pipeline/mesh.py``).
        fine_shape: (3,) the whole fine grid's shape (16 × the coarse grid's).
        structure: ``{"strict_iou", "loose_iou"}`` of the fine output against the coarse grid.
        extras: the blocks' ``FineGrid.extras``, merged.
        chunks: how many blocks the asset was cut into.
    """

    mesh: "trimesh.Trimesh"
    fine_shape: tuple[int, int, int]
    structure: dict
    extras: dict
    chunks: int


def plan_chunks(n_x: int) -> list[Chunk]:
    """The blocks of a grid ``n_x`` coarse columns long (one block when ``n_x ≤ WHOLE_MAX_CELLS``)."""
    if n_x <= WHOLE_MAX_CELLS:
        return [Chunk(0, n_x, 0, n_x)]
    return [Chunk(a, min(a + CHUNK_CELLS, n_x), max(a - HALO_CELLS, 0), min(a + CHUNK_CELLS + HALO_CELLS, n_x))
            for a in range(0, n_x, CHUNK_CELLS)]


def detail_shape(coarse_shape: tuple[int, int, int]) -> tuple[int, int, int]:
    """(3,) the largest coarse grid the detailizer is given at once for a grid of ``coarse_shape`` (the memory
    estimate's size, ``core/budget.py``)."""
    widest = max(c.hi - c.lo for c in plan_chunks(int(coarse_shape[0])))
    return (widest, int(coarse_shape[1]), int(coarse_shape[2]))


def chunk_grid(grid: LabeledGrid, lo: int, hi: int) -> LabeledGrid:
    """Coarse columns ``[lo, hi)`` of ``grid`` as a grid of their own (its origin moved to column ``lo``)."""
    origin = (grid.origin_m[0] + lo * grid.voxel_size_m, grid.origin_m[1], grid.origin_m[2])
    return LabeledGrid(grid.occupancy[lo:hi], grid.part[lo:hi], grid.style[lo:hi], grid.part_names,
                       grid.style_names, grid.voxel_size_m, origin)


def budget_shares(occupancy: np.ndarray, chunks: list[Chunk], total: int | None) -> list[int | None]:
    """Each block's share of ``total`` triangles, in proportion to its coarse surface (None: no budget)."""
    if total is None or len(chunks) == 1:
        return [total] * len(chunks)
    per_column = coarse_surface_faces(occupancy).sum(axis=(1, 2))
    surface = np.array([per_column[c.start:c.stop].sum() for c in chunks], dtype=np.float64)
    weights = surface / max(surface.sum(), 1.0)
    return [max(4, int(total * w)) for w in weights]


def merge_extras(extras: list[dict]) -> dict:
    """One ``FineGrid.extras`` for the blocks: list values joined (each entry once, first seen first),
    other values the first block's."""
    merged: dict = {}
    for block in extras:
        for key, value in block.items():
            if isinstance(value, list):
                seen = merged.setdefault(key, [])
                seen.extend(v for v in value if v not in seen)
            else:
                merged.setdefault(key, value)
    return merged


def detailize_and_mesh(grid: LabeledGrid, detailize: Callable[[LabeledGrid], FineGrid], settings: MeshSettings,
                       timings: dict[str, float] | None = None, iso: float = ISO_LEVEL,
                       on_block: Callable[[int, np.ndarray, np.ndarray], None] | None = None) -> DetailedMesh:
    """Detailize ``grid`` and mesh the result, block by block along x (see the module docstring).

    Args:
        detailize: LabeledGrid → FineGrid (the asset's detailizer, seed bound).
        timings: seconds spent in ``"detailize"`` and ``"mesh"`` are added here.
        on_block: called with (first fine column, (W, Y, Z) float32 occupancy, int16 style) of each block's own
            columns, in order (e.g. ``pipeline/vox_export.py``'s ``FineVox.add``).
    Raises:
        MeshingError: nothing to mesh, or a meshing step failed; a detailizer's own errors.
    """
    timings = timings if timings is not None else {}
    f = UPSAMPLE_FACTOR
    chunks = plan_chunks(grid.shape[0])
    shares = budget_shares(grid.occupancy, chunks, settings.max_triangles)
    counts = np.zeros(3, dtype=np.int64)
    extras: list[dict] = []
    pieces: list[Piece] = []
    held = None  # (index, own field, own styles) of the block waiting for its right neighbour's first column

    def add(seconds_key: str, start: float) -> None:
        timings[seconds_key] = timings.get(seconds_key, 0.0) + time.perf_counter() - start

    def mesh_held(next_field: np.ndarray | None, next_style: np.ndarray | None) -> None:
        k, field, style = held
        start = time.perf_counter()
        last = next_field is None
        if not last:
            shared = settings.sample_step  # the samples on the shared plane average this many fine columns
            field = np.concatenate([field, next_field[:shared]])
            style = np.concatenate([style, next_style[:shared]])
        piece = mesh_piece(field, style if settings.vertex_colors else None, grid.style_names, settings, shares[k],
                           x_offset=chunks[k].start * f, open_x=(k > 0, not last), iso=iso)
        if piece is not None:
            pieces.append(piece)
        add("mesh", start)

    for k, chunk in enumerate(chunks):
        start = time.perf_counter()
        fine = detailize(chunk_grid(grid, chunk.lo, chunk.hi) if len(chunks) > 1 else grid)
        own = slice((chunk.start - chunk.lo) * f, (chunk.stop - chunk.lo) * f)
        field, style = fine.occupancy[own], fine.style[own]
        extras.append(fine.extras)
        if on_block is not None:
            on_block(chunk.start * f, field, style)
        coarse = grid.occupancy[chunk.start:chunk.stop]
        counts += structure_counts(field > iso, coarse, f)
        del fine
        add("detailize", start)
        if held is not None:
            mesh_held(field, style)
        held = (k, field, style)
    mesh_held(None, None)

    start = time.perf_counter()
    mesh = to_trimesh(pieces, grid.origin_m, grid.voxel_size_m / f, settings.vertex_colors)
    add("mesh", start)
    strict, loose = iou_from_counts(*(int(c) for c in counts))
    return DetailedMesh(mesh=mesh, fine_shape=tuple(n * f for n in grid.shape),
                        structure={"strict_iou": round(strict, 4), "loose_iou": round(loose, 4)},
                        extras=merge_extras(extras), chunks=len(chunks))

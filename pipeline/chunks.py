"""Detailize and mesh an asset block by block along x, so that long assets (a 20-letter word) keep to
bounded memory and take time in proportion to their length.

A coarse grid at most ``WHOLE_MAX_CELLS`` columns long (every 16³ shape, a 3-letter word) is one
block: the detailizer sees it whole (from ``MESH_SPLIT_MIN_CELLS`` columns on, that block is meshed as
two pieces of its one field, which two processes can mesh at once; a detailizer that can give its field
column range by column range — ``column_detailizer``, the learned model — also detailizes the two pieces
apart, after the work they share). A longer one is cut into as few blocks as memory allows (each
block at most ``CHUNK_CELLS`` columns, or more while its box holds at most ``CHUNK_MAX_CELLS`` coarse
cells), an even number, cut where they hold equal
shares of the occupied cells (``plan_chunks``).
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

from core.errors import MeshingError
from core.grid import ISO_LEVEL, UPSAMPLE_FACTOR, FineGrid, LabeledGrid
from core.structure import iou_from_counts, structure_counts
from pipeline.forked import CAN_FORK, ChildDied, run_with_child
from pipeline.mesh import MeshSettings, Piece, coarse_surface_faces, mesh_piece, to_trimesh

if TYPE_CHECKING:
    import trimesh

#: Grids of at most this many coarse columns along x are detailized and meshed as one block.
WHOLE_MAX_CELLS = 64
#: Own coarse columns a block of a longer grid may always have (as many as before ``CHUNK_MAX_CELLS``)...
CHUNK_CELLS = 32
#: ... and more while the box of its own columns (columns × Y × Z) holds at most this many coarse cells: a
#: thin cross-section gets fewer, longer blocks (a word's 17 × 6: 80 columns), a fine field of at most ~33 M
#: voxels, as 32 columns of a 16 × 16 cross-section.
CHUNK_MAX_CELLS = 32 * 16 * 16
#: Coarse columns of context the detailizer sees on either side of a block (cut away after).
HALO_CELLS = 2
#: A grid of one block at least this many columns long is detailized whole and meshed as two pieces, split
#: where the coarse surface balances (``mesh_halves``), so that a second process can mesh one while this one
#: meshes the other. Every such grid is meshed so whatever the number of processes: outputs stay the same
#: bit for bit across ``--jobs``.
MESH_SPLIT_MIN_CELLS = 8


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


def block_columns(coarse_shape: tuple[int, int, int]) -> int:
    """Most own columns of a block of a grid longer than ``WHOLE_MAX_CELLS``: ``CHUNK_CELLS``, or
    ``CHUNK_MAX_CELLS`` / (Y·Z) where that is more."""
    return max(CHUNK_CELLS, CHUNK_MAX_CELLS // max(1, int(coarse_shape[1]) * int(coarse_shape[2])))


def plan_chunks(occupancy: np.ndarray) -> list[Chunk]:
    """The blocks of a coarse grid (X, Y, Z) bool (one block when X ≤ ``WHOLE_MAX_CELLS``).

    A longer grid gets the fewest blocks that keep each within ``block_columns`` columns — an even number, at
    least two, so that two processes (``detailize_and_mesh``) take halves — cut where each holds an equal share
    of the occupied cells: the detailizer's work follows them, so the halves finish together. Fewer blocks
    cost less: every block also detailizes ``HALO_CELLS`` columns of context on each side and has its own
    fixed work (castle_word, 99 columns: 2 blocks take 2.9–3.2 s of CPU where 4 took 3.5–3.8 s). Where the
    shares would make a block too wide or empty, the blocks are equal in columns instead (the first
    ``X mod count`` one column longer). The plan does not depend on the number of processes.
    """
    n_x = int(occupancy.shape[0])
    if n_x <= WHOLE_MAX_CELLS:
        return [Chunk(0, n_x, 0, n_x)]
    widest = block_columns(occupancy.shape)
    count = max(2, -(-n_x // widest))
    count += count % 2
    work = np.cumsum(occupancy.sum(axis=(1, 2)))
    stops = np.append(np.searchsorted(work, work[-1] * np.arange(1, count) / count) + 1, n_x)
    widths = np.diff(stops, prepend=0)
    if work[-1] == 0 or widths.min() < 1 or widths.max() > widest:
        base, extra = divmod(n_x, count)
        stops = np.cumsum([base + (i < extra) for i in range(count)])
    return [Chunk(int(a), int(b), max(int(a) - HALO_CELLS, 0), min(int(b) + HALO_CELLS, n_x))
            for a, b in zip([0, *stops[:-1]], stops)]


def detail_shape(coarse_shape: tuple[int, int, int]) -> tuple[int, int, int]:
    """(3,) the largest coarse grid the detailizer is given at once for a grid of ``coarse_shape`` (the memory
    estimate's size, ``core/budget.py``): the grid itself, or the widest block ``plan_chunks`` may cut, with its
    context columns."""
    n_x = int(coarse_shape[0])
    if n_x > WHOLE_MAX_CELLS:
        n_x = min(n_x, block_columns(coarse_shape) + 2 * HALO_CELLS)
    return (n_x, int(coarse_shape[1]), int(coarse_shape[2]))


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


@dataclass
class BlockJob:
    """Everything a run over some of an asset's blocks needs (the same in both processes of a split run)."""

    grid: LabeledGrid
    detailize: Callable[[Chunk], FineGrid]  # a block → the fine field of its columns [lo, hi)
    settings: MeshSettings
    chunks: list[Chunk]
    shares: list[int | None]
    iso: float
    on_block: Callable[[int, np.ndarray, np.ndarray], None] | None


@dataclass
class BlockResult:
    """What a run over a range of blocks gives: their pieces, Strict/Loose counts, extras and seconds."""

    pieces: list[Piece]
    counts: np.ndarray
    extras: list[dict]
    timings: dict[str, float]


def run_blocks(job: BlockJob, blocks: range,
               send_head: Callable[[tuple[np.ndarray, np.ndarray]], None] | None = None,
               receive_next_head: Callable[[], tuple[np.ndarray, np.ndarray]] | None = None) -> BlockResult:
    """Detailize and mesh ``blocks`` (consecutive indices into ``job.chunks``), in order.

    A block is meshed once the next block's first fine columns are known. The first block's
    first columns go to ``send_head`` (its left neighbour's mesh needs them, in another process); the
    last block's right neighbour, when it lies outside ``blocks``, gives its columns through
    ``receive_next_head``.
    """
    f = UPSAMPLE_FACTOR
    grid, chunks, settings = job.grid, job.chunks, job.settings
    shared = settings.sample_step  # the samples on a shared plane average this many fine columns
    out = BlockResult([], np.zeros(3, dtype=np.int64), [], {})
    held = None  # (index, field, styles (own columns + right context), own width, confined) of the block waiting
    #             for its right neighbour's columns

    def add(key: str, start: float) -> None:
        out.timings[key] = out.timings.get(key, 0.0) + time.perf_counter() - start

    def mesh_held(head: tuple[np.ndarray, np.ndarray] | None) -> None:
        k, field, style, width, confined = held
        start = time.perf_counter()
        if head is None:
            field, style = field[:width], style[:width]
        elif len(field) >= width + shared and field.flags.writeable and style.flags.writeable:
            # the block's own right context has room: no copy of the block
            field[width:width + shared], style[width:width + shared] = head[0][:shared], head[1][:shared]
            field, style = field[:width + shared], style[:width + shared]
        else:
            field = np.concatenate([field[:width], head[0][:shared]])
            style = np.concatenate([style[:width], head[1][:shared]])
        lo, hi = max(chunks[k].start - 1, 0), min(chunks[k].stop + 1, grid.shape[0])  # a column of context
        piece = mesh_piece(field, style if settings.vertex_colors else None, grid.style_names, settings,
                           job.shares[k], x_offset=chunks[k].start * f, open_x=(k > 0, head is not None),
                           iso=job.iso, coarse=grid.occupancy[lo:hi], coarse_x0=(lo - chunks[k].start) * f,
                           confined=confined)
        if piece is not None:
            out.pieces.append(piece)
        add("mesh", start)

    for k in blocks:
        chunk = chunks[k]
        start = time.perf_counter()
        fine = job.detailize(chunk)
        own = slice((chunk.start - chunk.lo) * f, (chunk.stop - chunk.lo) * f)
        field, style = fine.occupancy[own], fine.style[own]
        out.extras.append(fine.extras)
        if job.on_block is not None:
            job.on_block(chunk.start * f, field, style)
        counts = structure_counts(field > job.iso, grid.occupancy[chunk.start:chunk.stop], f)
        out.counts += counts
        # the held block keeps its right context columns (views), overwritten by its neighbour's first ones
        room = slice(own.start, own.stop + shared)
        kept = (fine.occupancy[room], fine.style[room], own.stop - own.start)
        del fine
        add("detailize", start)
        if k == blocks[0] and send_head is not None:
            send_head((field[:shared].copy(), style[:shared].copy()))
        if held is not None:
            mesh_held((field, style))
        held = (k, *kept, counts[1] == counts[2])  # confined: no fine voxel in an empty coarse cell
    last = blocks[-1]
    mesh_held(None if last == len(chunks) - 1 else receive_next_head())
    return out


def mesh_halves(occupancy: np.ndarray) -> list[Chunk]:
    """Two pieces of one detailized block (both detailized on all columns): the split column balances the
    coarse surface (the meshing work) on its two sides."""
    n_x = occupancy.shape[0]
    split = split_blocks(occupancy, [Chunk(i, i + 1, i, i + 1) for i in range(n_x)])  # columns as blocks
    return [Chunk(0, split, 0, n_x), Chunk(split, n_x, 0, n_x)]


def split_blocks(occupancy: np.ndarray, chunks: list[Chunk]) -> int:
    """The first block of the second process: the split that best balances the coarse surface (the work)."""
    per_column = coarse_surface_faces(occupancy).sum(axis=(1, 2))
    work = np.array([per_column[c.start:c.stop].sum() for c in chunks], dtype=np.float64)
    before = np.cumsum(work)[:-1]
    return int(np.argmin(np.maximum(before, work.sum() - before))) + 1


def detailize_and_mesh(grid: LabeledGrid, detailize: Callable[[LabeledGrid], FineGrid], settings: MeshSettings,
                       timings: dict[str, float] | None = None, iso: float = ISO_LEVEL,
                       on_block: Callable[[int, np.ndarray, np.ndarray], None] | None = None,
                       processes: int = 1,
                       columns: Callable[[LabeledGrid], Callable[[int, int], FineGrid]] | None = None) -> DetailedMesh:
    """Detailize ``grid`` and mesh the result, block by block along x (see the module docstring).

    Args:
        detailize: LabeledGrid → FineGrid (the asset's detailizer, seed bound).
        timings: seconds spent in ``"detailize"`` and ``"mesh"`` are added here. With two processes the
            stages overlap: ``"detailize"`` is this process's own, ``"mesh"`` the rest of the wall time.
        on_block: called with (first fine column, (W, Y, Z) float32 occupancy, int16 style) of each block's own
            columns, in order (e.g. ``pipeline/vox_export.py``'s ``FineVox.add``); it runs in this process, so
            a build with it uses one.
        processes: 2 lets a grid of several blocks (or pieces) detailize and mesh its second half in a forked
            child (``pipeline/forked.py``) while this process does the first. The output is the same bit for bit
            (every block is computed alike; only the first columns of the child's first block cross over).
        columns: the detailizer's ``column_detailizer`` (seed bound), or None: a grid of one block meshed as two
            pieces is then detailized piece by piece, after the work the pieces share (done before any fork).
    Raises:
        MeshingError: nothing to mesh, a meshing step failed, the block process died; a detailizer's own errors.
    """
    timings = timings if timings is not None else {}
    chunks = plan_chunks(grid.occupancy)
    blocks = len(chunks)  # detailized apart

    def block_field(chunk: Chunk) -> FineGrid:
        return detailize(chunk_grid(grid, chunk.lo, chunk.hi) if len(chunks) > 1 else grid)
    if len(chunks) == 1 and grid.shape[0] >= MESH_SPLIT_MIN_CELLS:
        start = time.perf_counter()
        if columns is not None:  # each piece detailized on its own columns
            part = columns(grid)
            chunks = [Chunk(c.start, c.stop, c.start, c.stop) for c in mesh_halves(grid.occupancy)]
            blocks = 2

            def block_field(chunk: Chunk) -> FineGrid:
                return part(chunk.lo, chunk.hi)
        else:  # both pieces are columns of the one field
            whole = detailize(grid)
            chunks = mesh_halves(grid.occupancy)

            def block_field(chunk: Chunk) -> FineGrid:
                return whole
        timings["detailize"] = timings.get("detailize", 0.0) + time.perf_counter() - start
    job = BlockJob(grid, block_field, settings, chunks,
                   budget_shares(grid.occupancy, chunks, settings.max_triangles), iso, on_block)
    if processes >= 2 and len(chunks) >= 2 and on_block is None and CAN_FORK:
        split = split_blocks(grid.occupancy, chunks)
        start = time.perf_counter()
        try:
            first, second = run_with_child(
                lambda send: run_blocks(job, range(split, len(chunks)), send_head=send),
                lambda receive: run_blocks(job, range(split), receive_next_head=receive))
        except ChildDied as exc:
            raise MeshingError(f"detailizing and meshing the second half of the asset's blocks failed: {exc}",
                               hint="the machine may be short of memory: close other programs or lower "
                                    "DECOLLAGE_MEMORY_BUDGET_GB (a build then uses one process per asset)") from exc
        wall = time.perf_counter() - start
        own = first.timings.get("detailize", 0.0)
        timings["detailize"] = timings.get("detailize", 0.0) + own
        timings["mesh"] = timings.get("mesh", 0.0) + wall - own
        runs = [first, second]
    else:
        runs = [run_blocks(job, range(len(chunks)))]
        for key, seconds in runs[0].timings.items():
            timings[key] = timings.get(key, 0.0) + seconds

    start = time.perf_counter()
    mesh = to_trimesh([p for r in runs for p in r.pieces], grid.origin_m, grid.voxel_size_m / UPSAMPLE_FACTOR,
                      settings.vertex_colors)
    timings["mesh"] = timings.get("mesh", 0.0) + time.perf_counter() - start
    strict, loose = iou_from_counts(*(int(c) for c in sum(r.counts for r in runs)))
    return DetailedMesh(mesh=mesh, fine_shape=tuple(n * UPSAMPLE_FACTOR for n in grid.shape),
                        structure={"strict_iou": round(strict, 4), "loose_iou": round(loose, 4)},
                        extras=merge_extras([e for r in runs for e in r.extras]), chunks=blocks)

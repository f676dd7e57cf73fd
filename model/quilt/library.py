"""The quilt library: every usable coarse cell of every exemplar, in the 8 symmetries that keep +Y up.

Role: turn a style set's exemplars into tables the search (``model.quilt.search``)
and the assembly (``model.quilt.assemble``) work on, and cache what is costly
to compute on disk.

Per exemplar (``ExemplarStats``, cached on disk per set, see ``load_stats``):

* ``counts``: (n, n, n) occupied fine voxels per coarse cell (n = R / 16; a
  256³ exemplar has a 16³ coarse grid, cells aligned with the ×16 max-pool
  the evaluation uses);
* ``part``: (n, n, n) majority part (vocabulary index) per cell, −1 empty;
* ``mid``: (R/2)³ occupied voxels per 2³ fine voxels (0..8), the source of the
  face slabs.

Per exemplar and symmetry s (``ExemplarTable``, built in memory on first use):
one *entry* per transformed cell whose fill is at least ``MIN_FILL`` with

* ``desc``: its 5³ coarse neighbourhood as soft occupancy 0..8
  (``soft_occupancy``: fill ≤ 0.2 → 0, ≥ 0.6 → 8, linear between), so a cell
  the content voxelizer would call occupied (coverage ≥ 0.5) reads nearly
  full and a sliver of a roof overhang reads nearly empty;
* ``slabs``: per face (−x, +x, −y, +y, −z, +z) the ``SLAB``×``SLAB`` voxel
  counts of the 2-voxel layer just inside the face and of the layer just
  outside it (the exemplar's neighbouring cell): the seam cost of two blocks
  compares one's outside layer with the other's inside layer;
* ``shift``: the entry of the neighbouring source cell in each face
  direction (same exemplar, same symmetry), −1 if that cell is not an entry —
  what "continuing" a neighbour means;
* ``face``: the material fraction of each face's inside layer (0..``FACE_Q``): a
  content cell whose neighbour there is empty cuts that material flat;
  ``unfilled``: the empty fraction of both layers (0..2·``FACE_Q``): the seam
  against a solid interior neighbour;
* its source position (transformed and original cell), part and fill.

Symmetries: s = 0..7, mirror x when s ≥ 4, then ``s % 4`` quarter turns about
+Y (``apply_sym``): the same operation applies to coarse, mid and fine arrays
(cells map to cells because R is a multiple of 16), so a fine block of a
transformed cell is the transformed block of its original cell.
"""

from __future__ import annotations

import hashlib
import io
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from core.grid import UPSAMPLE_FACTOR
from stylesets.format import StyleSet, set_path

#: Bumped whenever the cached arrays or their meaning change (part of the cache key).
CODE_VERSION = 1
#: Fine voxels per coarse cell edge.
CELL = UPSAMPLE_FACTOR
#: Symmetries that keep +Y up: 4 quarter turns about Y × mirror.
N_SYM = 8
#: Neighbourhood radius of the descriptor (5³ cells).
DESC_RADIUS = 2
#: Cells with less than this fraction of their fine voxels occupied are not library entries (near-empty
#: blocks would leave an occupied content cell without material).
MIN_FILL = 0.08
#: Face slab resolution (values per face edge); each value counts (CELL/SLAB)² × 2 fine voxels.
SLAB = 4
#: Soft occupancy ramp: fill at or below LO reads empty, at or above HI full.
SOFT_LO, SOFT_HI = 0.2, 0.6
#: Quantisation of ``face`` (the material fraction of a cell face's inside layer).
FACE_Q = 64
#: Face directions: index d ↔ axis d // 2, sign −1 for even d; the opposite face is d ^ 1.
DIRS = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], dtype=np.int64)


def apply_sym(a: np.ndarray, s: int) -> np.ndarray:
    """Symmetry ``s`` of a 3-D array (a view): mirror x if s ≥ 4, then s % 4 quarter turns about +Y."""
    if s >= 4:
        a = a[::-1]
    return np.rot90(a, s % 4, axes=(0, 2))


def desc_weights() -> np.ndarray:
    """(125,) int32 weights of the 5³ descriptor: 24 at the centre, 16 on the faces, falling with distance."""
    return _WEIGHTS


def _desc_weights() -> np.ndarray:
    r = np.arange(-DESC_RADIUS, DESC_RADIUS + 1)
    d2 = (r[:, None, None] ** 2 + r[None, :, None] ** 2 + r[None, None, :] ** 2).astype(np.float64)
    w = np.maximum(1.0, np.round(16.0 * np.exp(-(d2 - 1.0) / 2.2)))
    w[DESC_RADIUS, DESC_RADIUS, DESC_RADIUS] = 24.0
    return w.reshape(-1).astype(np.int32)


_WEIGHTS = _desc_weights()
_WEIGHTS.flags.writeable = False


def soft_occupancy(counts: np.ndarray) -> np.ndarray:
    """Fine-voxel counts per cell → soft occupancy 0..8 (uint8), see the module docstring."""
    fill = counts.astype(np.float32) / CELL**3
    return np.clip(np.round(8.0 * (fill - SOFT_LO) / (SOFT_HI - SOFT_LO)), 0, 8).astype(np.uint8)


# --------------------------------------------------------------------------- per exemplar


@dataclass(frozen=True, eq=False)
class ExemplarStats:
    """Cell counts, majority parts and the 2³-pooled grid of one exemplar (see module docstring)."""

    counts: np.ndarray  # (n, n, n) uint16
    part: np.ndarray  # (n, n, n) int8, -1 empty
    mid: np.ndarray  # (R/2,)*3 uint8 0..8


def exemplar_stats(labels_full: np.ndarray, n_parts: int) -> ExemplarStats:
    """Stats of one exemplar from its uint8 labels (0 empty, i + 1 = part i) on a grid of whole cells."""
    a, b, c = (s // CELL for s in labels_full.shape)
    occ = labels_full > 0
    counts = occ.reshape(a, CELL, b, CELL, c, CELL).sum(axis=(1, 3, 5), dtype=np.int32).astype(np.uint16)
    per_part = np.stack([(labels_full == i + 1).reshape(a, CELL, b, CELL, c, CELL).sum(axis=(1, 3, 5),
                                                                                     dtype=np.int32)
                         for i in range(n_parts)])
    part = np.where(counts > 0, per_part.argmax(axis=0), -1).astype(np.int8)
    h = [s // 2 for s in labels_full.shape]
    mid = occ.reshape(h[0], 2, h[1], 2, h[2], 2).sum(axis=(1, 3, 5), dtype=np.uint8)
    return ExemplarStats(counts=counts, part=part, mid=mid)


def exemplar_stats_of(labels: np.ndarray, offset, resolution: int, n_parts: int) -> ExemplarStats:
    """``exemplar_stats`` of an exemplar stored as its occupied box at ``offset``: computed on the box
    rounded out to whole cells only, then placed in the R³ grid (the same arrays, a third faster)."""
    offset = np.asarray(offset, dtype=np.int64)
    lo = offset // CELL * CELL
    hi = -(-(offset + labels.shape) // CELL) * CELL
    box = np.zeros(tuple(hi - lo), dtype=np.uint8)
    box[tuple(slice(a, a + n) for a, n in zip(offset - lo, labels.shape))] = labels
    sub = exemplar_stats(box, n_parts)
    n = resolution // CELL
    counts = np.zeros((n,) * 3, dtype=np.uint16)
    part = np.full((n,) * 3, -1, dtype=np.int8)
    mid = np.zeros((resolution // 2,) * 3, dtype=np.uint8)
    cell = tuple(slice(a // CELL, b // CELL) for a, b in zip(lo, hi))
    counts[cell], part[cell] = sub.counts, sub.part
    mid[tuple(slice(a // 2, b // 2) for a, b in zip(lo, hi))] = sub.mid
    return ExemplarStats(counts=counts, part=part, mid=mid)


def _cache_file(style_set: StyleSet) -> Path | None:
    """Where a set's stats are cached: ``<styles dir>/quilt/<set>-<digest>-v<CODE_VERSION>.npz``."""
    if style_set.path is None:
        return None  # an in-memory set (tests): its digest does not identify its arrays
    folder = Path(os.environ.get("DECOLLAGE_QUILT_CACHE") or set_path(style_set.name).parent / "quilt")
    key = hashlib.sha256(f"{style_set.inputs_hash}|{style_set.resolution}|{CODE_VERSION}".encode()).hexdigest()
    return folder / f"{style_set.name}-{key[:20]}.npz"


def load_stats(style_set: StyleSet, use_cache: bool = True) -> list[ExemplarStats]:
    """Every exemplar's stats, from the disk cache when it holds this set's digest, else computed and cached.

    The cache is written atomically (a temporary file renamed into place); an unreadable
    or unwritable cache is ignored (the stats are recomputed, ~0.1 s an exemplar).
    """
    path = _cache_file(style_set) if use_cache else None
    n_parts = len(style_set.vocabulary.parts)
    if path is not None and path.is_file():
        try:
            with np.load(path, allow_pickle=False) as data:
                stats = [ExemplarStats(data[f"counts_{i}"], data[f"part_{i}"], data[f"mid_{i}"])
                         for i in range(len(style_set.exemplars))]
            if all(s.counts.shape == (style_set.resolution // CELL,) * 3 for s in stats):
                return stats
        except (OSError, KeyError, ValueError, zipfile.BadZipFile, EOFError):
            pass
    stats = [exemplar_stats_of(ex.labels, ex.offset, style_set.resolution, n_parts) for ex in style_set.exemplars]
    if path is not None:
        _write_stats(path, stats)
    return stats


def _write_stats(path: Path, stats: list[ExemplarStats]) -> None:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **{f"{k}_{i}": getattr(s, k) for i, s in enumerate(stats)
                                   for k in ("counts", "part", "mid")})
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_bytes(buffer.getvalue())
        os.replace(tmp, path)
    except OSError:
        pass  # a read-only cache folder only costs the recomputation next time


# --------------------------------------------------------------------------- per exemplar × symmetry


@dataclass(frozen=True, eq=False)
class ExemplarTable:
    """All entries of one exemplar in its 8 symmetries (see module docstring); local entry ids 0..m-1."""

    sym: np.ndarray  # (m,) int8
    pos: np.ndarray  # (m, 3) int16 transformed cell
    orig: np.ndarray  # (m, 3) int16 original cell
    part: np.ndarray  # (m,) int8
    fill: np.ndarray  # (m,) float32
    desc: np.ndarray  # (m, 125) uint8 0..8
    slabs: np.ndarray  # (m, 6, 2, SLAB*SLAB) uint8: [face, inside/outside]
    face: np.ndarray  # (m, 6) uint8 0..FACE_Q: how much of each face's inside layer is material
    unfilled: np.ndarray  # (m, 6) uint8 0..2·FACE_Q: how much of both face layers is empty
    shift: np.ndarray  # (m, 6) int32 local ids, -1 none
    index_map: np.ndarray  # (N_SYM, n, n, n) int32 local id or -1

    def __len__(self) -> int:
        return len(self.sym)


def _inner_faces(mid_t: np.ndarray, n: int) -> np.ndarray:
    """(6, n, n, n, SLAB, SLAB) counts of the 2-voxel layer inside each face of every cell."""
    m = mid_t.reshape(n, 8, n, 8, n, 8).astype(np.uint16)
    faces = [
        m[:, 0].transpose(0, 1, 3, 2, 4), m[:, 7].transpose(0, 1, 3, 2, 4),  # (i,j,a,k,b) → (i,j,k,a,b)
        m[:, :, :, 0].transpose(0, 2, 3, 1, 4), m[:, :, :, 7].transpose(0, 2, 3, 1, 4),  # (i,a,j,k,b)
        m[..., 0].transpose(0, 2, 4, 1, 3), m[..., 7].transpose(0, 2, 4, 1, 3),  # (i,a,j,b,k)
    ]
    g = 8 // SLAB
    out = np.stack(faces).reshape(6, n, n, n, SLAB, g, SLAB, g).sum(axis=(5, 7))
    return out.astype(np.uint8)


def build_table(stats: ExemplarStats) -> ExemplarTable:
    """The entries of one exemplar over the 8 symmetries (≈ 20–60 ms for a 256³ exemplar)."""
    n = stats.counts.shape[0]
    r = DESC_RADIUS
    coords = np.indices((n, n, n), dtype=np.int16)
    parts = {k: [] for k in ("sym", "pos", "orig", "part", "fill", "desc", "slabs")}
    index_map = np.full((N_SYM, n, n, n), -1, dtype=np.int32)
    local_pos = []
    start = 0
    # a thin exemplar (a wire, a leaf) may have no cell that full: then every cell with material counts
    threshold = MIN_FILL * CELL**3 if (stats.counts >= MIN_FILL * CELL**3).any() else 1
    for s in range(N_SYM):
        counts = np.ascontiguousarray(apply_sym(stats.counts, s))
        valid = counts >= threshold
        pos = np.argwhere(valid)
        m = len(pos)
        index_map[s][valid] = np.arange(start, start + m, dtype=np.int32)
        start += m
        soft = np.pad(soft_occupancy(counts), r)
        win = sliding_window_view(soft, (2 * r + 1,) * 3)  # (n, n, n, 5, 5, 5)
        inner = _inner_faces(np.ascontiguousarray(apply_sym(stats.mid, s)), n)  # (6, n, n, n, S, S)
        padded = np.pad(inner, ((0, 0), (1, 1), (1, 1), (1, 1), (0, 0), (0, 0)))
        outer = np.empty_like(inner)
        for d in range(6):
            o = 1 + DIRS[d]  # outside face d of cell p = inside face d^1 of cell p + dir(d)
            outer[d] = padded[d ^ 1, o[0]:o[0] + n, o[1]:o[1] + n, o[2]:o[2] + n]
        pi, pj, pk = pos.T
        parts["sym"].append(np.full(m, s, dtype=np.int8))
        parts["pos"].append(pos.astype(np.int16))
        parts["orig"].append(np.stack([apply_sym(c, s)[pi, pj, pk] for c in coords], axis=1).astype(np.int16))
        parts["part"].append(np.ascontiguousarray(apply_sym(stats.part, s))[pi, pj, pk])
        parts["fill"].append(counts[pi, pj, pk].astype(np.float32) / CELL**3)
        parts["desc"].append(win[pi, pj, pk].reshape(m, (2 * r + 1) ** 3))
        slabs = np.stack([inner[:, pi, pj, pk], outer[:, pi, pj, pk]], axis=2)  # (6, m, 2, S, S)
        parts["slabs"].append(slabs.transpose(1, 0, 2, 3, 4).reshape(m, 6, 2, SLAB * SLAB))
        local_pos.append((s, pos))
    table = {k: np.concatenate(v) for k, v in parts.items()}
    inside = table["slabs"][:, :, 0, :].sum(axis=2, dtype=np.int64)  # (m, 6) of at most SLAB² · 2·(CELL/SLAB)²
    table["face"] = np.round(inside * FACE_Q / (2 * CELL * CELL)).astype(np.uint8)
    both = table["slabs"].sum(axis=(2, 3), dtype=np.int64)  # inside + outside layers
    table["unfilled"] = np.round((4 * CELL * CELL - both) * FACE_Q / (2 * CELL * CELL)).astype(np.uint8)
    shift = np.full((start, 6), -1, dtype=np.int32)
    for s, pos in local_pos:
        ids = index_map[s][tuple(pos.T)]
        for d in range(6):
            q = pos + DIRS[d]
            inside = ((q >= 0) & (q < n)).all(axis=1)
            shift[ids[inside], d] = index_map[s][tuple(q[inside].T)]
    return ExemplarTable(shift=shift, index_map=index_map, **table)


# --------------------------------------------------------------------------- a search library


@dataclass(frozen=True, eq=False)
class Library:
    """The entries of several exemplars as one table with global ids (``base[t] + local id``).

    ``style`` (per entry) is the index of the exemplar table in ``exemplars``, which is the
    content style it may serve; ``fine`` holds each exemplar's occupancy padded by ``halo``
    voxels, the source of the blocks the assembly copies.
    """

    exemplars: tuple[int, ...]  # set indices of the exemplars, in table order
    base: np.ndarray  # (T + 1,) int64 first global id of each table, then the total
    style: np.ndarray  # (M,) int16 table index
    sym: np.ndarray
    pos: np.ndarray
    orig: np.ndarray
    part: np.ndarray
    fill: np.ndarray
    desc: np.ndarray
    slabs: np.ndarray
    face: np.ndarray
    unfilled: np.ndarray
    shift: np.ndarray  # (M, 6) global ids, -1 none
    index_maps: tuple[np.ndarray, ...]  # per table (N_SYM, n, n, n) global id or -1

    def __len__(self) -> int:
        return len(self.style)

    def lookup(self, table: np.ndarray, sym: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """Global ids of (table, symmetry, transformed cell) triples; −1 where there is no entry."""
        out = np.full(len(table), -1, dtype=np.int64)
        for t, imap in enumerate(self.index_maps):
            sel = table == t
            if not sel.any():
                continue
            n = imap.shape[1]
            p = pos[sel]
            inside = ((p >= 0) & (p < n)).all(axis=1)
            ids = np.full(int(sel.sum()), -1, dtype=np.int64)
            q = p[inside]
            ids[inside] = imap[sym[sel][inside], q[:, 0], q[:, 1], q[:, 2]]
            out[sel] = ids
        return out


def combine(tables: list[ExemplarTable], exemplars: list[int]) -> Library:
    """One ``Library`` over the tables of ``exemplars`` (in that order)."""
    sizes = [len(t) for t in tables]
    base = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    shift = np.concatenate([np.where(t.shift >= 0, t.shift + b, -1) for t, b in zip(tables, base)])
    maps = tuple(np.where(t.index_map >= 0, t.index_map + b, -1) for t, b in zip(tables, base))
    cat = {k: np.concatenate([getattr(t, k) for t in tables]) for k in
           ("sym", "pos", "orig", "part", "fill", "desc", "slabs", "face", "unfilled")}
    style = np.concatenate([np.full(s, i, dtype=np.int16) for i, s in enumerate(sizes)])
    cat["slabs"] = cat["slabs"].astype(np.int16)  # the seam cost subtracts them
    return Library(exemplars=tuple(exemplars), base=base, style=style, shift=shift.astype(np.int64),
                   index_maps=maps, **cat)

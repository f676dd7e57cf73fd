"""Coherent search: which exemplar cell each surface cell of the content copies.

Role: the energy of a source field. For every *surface* cell q of the content (occupied, with an empty
26-neighbour; interior cells are solid, see ``Content``) choose a source entry
L(q) (exemplar, symmetry, source cell; ``model.quilt.library``) of q's own
style, minimising

    E = Σ_q U(q, L(q)) + Σ_{q ~ r} V(L(q), L(r))

over 6-neighbouring surface cells q ~ r, where

* U = Σ_i w_i |8·c_i − o_i| over the 5³ coarse neighbourhood (c = content
  occupancy 0/1, o = the entry's soft occupancy 0..8, w = ``desc_weights``)
  + ``CUT_WEIGHT`` × the material fraction of the entry's face layer on each
  face whose content neighbour is empty (the mask would cut that material into
  a flat face) + the seam cost against each solid interior neighbour (a block
  of ones) + ``PART_PENALTY`` when the entry's part is not q's part +
  ``SYM_PENALTY`` when its symmetry is not the identity (the content's front
  stays the exemplar's front when that fits as well);
* V = 0 when L(r) continues L(q) (the entry next to L(q) in the same exemplar
  and symmetry, in the direction of r), else ``SEAM_BREAK`` + ``SEAM_WEIGHT``
  × the disagreement (0..1) of the two blocks over the 4-voxel band around
  their shared face (each one's outside layer against the other's inside
  layer, the library's slabs).

Costs are integers in 1/``UNIT`` units (``UNIT`` = one fully mismatched face
neighbour), so every comparison is exact and nothing depends on BLAS threads.
The weights were chosen on 16 protocol outputs (``benchmarks/bench_quilt.py``):
large seam and cut costs against the neighbourhood term raised LP-detail
from 0.19 to 0.27 and continuation from 0.69 to 0.76.

The optimisation that minimises E is ``model/quilt/field.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy import ndimage

from model.quilt.library import CELL, DESC_RADIUS, DIRS, FACE_Q, SLAB, Library, desc_weights

#: Cost unit: one face neighbour fully mismatched (weight 16 × occupancy 8).
UNIT = 128
#: Penalty per fully cut face (see U), in units; the per-quantum integer is derived from it.
CUT_WEIGHT = 20.0
#: Penalty for a symmetry other than the identity, in units.
SYM_PENALTY = 4.0
#: Penalty for an entry of another part than the cell's, in 1/UNIT (parts are the user's semantics).
PART_PENALTY = 16 * UNIT
#: Seam cost of a non-continuing neighbour pair: a constant plus the weighted band disagreement (0..1).
SEAM_BREAK = 16.0
SEAM_WEIGHT = 3.0
#: Nearest entries kept per distinct neighbourhood, proposals per cell and sweeps.
K_NEAREST = 48
RANDOM_KNN = 4
RANDOM_LOCAL = 2
ITERATIONS = 2
#: Run graph-cut expansion moves (``model.quilt.graphcut``) before the sweeps.
EXPANSIONS = True
#: Queries per distance-matrix chunk (bounds memory on long grids).
QUERY_CHUNK = 512


#: ``Content.nb`` value of a face neighbour that is empty or beyond the grid, and of one inside the shape.
OPEN, SOLID = -1, -2


@dataclass(frozen=True, eq=False)
class Content:
    """The cells of a coarse grid that the search chooses sources for: its *surface* cells.

    An occupied cell whose 26 neighbours are all occupied is inside the shape: nothing of it can be
    seen, the assembly fills it solid, and the search does not choose a source for it (it is a
    fixed solid neighbour, see ``unary``). ``occ`` is the whole coarse occupancy; ``cells`` (N, 3)
    the surface cells in C order; ``nb`` (N, 6) the neighbouring surface cell's id per face
    direction, or ``OPEN`` / ``SOLID``; ``desc`` (N, 125) 0/1 coarse neighbourhoods; ``table`` (N,)
    the cell's style table in the library; ``part`` (N,) its vocabulary part.
    """

    occ: np.ndarray
    cells: np.ndarray
    ids: np.ndarray  # (X, Y, Z) int64 surface cell id or -1
    nb: np.ndarray
    desc: np.ndarray
    table: np.ndarray
    part: np.ndarray

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(self.occ.shape)  # type: ignore[return-value]

    @property
    def open_faces(self) -> np.ndarray:
        """(N, 6) int64: 1 where the face neighbour is empty (or beyond the grid)."""
        return (self.nb == OPEN).astype(np.int64)

    @property
    def solid_faces(self) -> np.ndarray:
        """(N, 6) int64: 1 where the face neighbour is a solid interior cell."""
        return (self.nb == SOLID).astype(np.int64)

    def __len__(self) -> int:
        return len(self.cells)


def interior_cells(occ: np.ndarray) -> np.ndarray:
    """(X, Y, Z) bool: occupied cells whose 26 neighbours are all occupied (beyond the grid is empty)."""
    return ndimage.binary_erosion(occ, structure=np.ones((3, 3, 3), bool), border_value=0)


def make_content(occ: np.ndarray, table: np.ndarray, part: np.ndarray) -> Content:
    """``Content`` of a coarse occupancy with per-cell style-table and part indices ((X, Y, Z) arrays)."""
    surface = occ & ~interior_cells(occ)
    cells = np.argwhere(surface)
    ids = np.full(occ.shape, -1, dtype=np.int64)
    ids[surface] = np.arange(len(cells))
    padded_ids = np.pad(np.where(occ & ~surface, SOLID, np.where(surface, ids, OPEN)), 1, constant_values=OPEN)
    nb = np.stack([padded_ids[tuple((cells + 1 + DIRS[d]).T)] for d in range(6)], axis=1)
    r = DESC_RADIUS
    win = sliding_window_view(np.pad(occ, r).astype(np.uint8), (2 * r + 1,) * 3)
    desc = win[tuple(cells.T)].reshape(len(cells), -1)
    return Content(occ=occ, cells=cells, ids=ids, nb=nb, desc=np.ascontiguousarray(desc),
                   table=table[surface].astype(np.int64), part=part[surface].astype(np.int64))


def nearest_entries(content: Content, lib: Library, rng: np.random.Generator, k: int = K_NEAREST) -> np.ndarray:
    """(N, k) global entry ids: each cell's k lowest-U entries of its style (ties in a seeded random order).

    Cells with the same (style, part, neighbourhood) share one row. U minus its row constant
    (8·Σw·c) is one matrix product of [−2·w∘c, open faces, 1] and [o, cut cost per face, Σw·o + entry
    costs]; all terms are integers scaled by ``_RANK_SCALE`` plus a seeded integer jitter below it,
    so float32 holds them exactly (< 2²⁴) and the ranking does not depend on BLAS threads. Only
    entries of the cell's part are ranked when the style has at least k of them.
    """
    w = desc_weights().astype(np.float32)
    out = np.zeros((len(content), k), dtype=np.int64)
    # the neighbourhood fixes the open faces but not which occupied neighbours are solid: key on both
    key = np.concatenate([content.table[:, None], content.part[:, None], content.desc, content.solid_faces],
                         axis=1)
    groups, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    open_g = content.open_faces[first].astype(np.float32)  # open faces follow from the neighbourhood
    solid_g = content.solid_faces[first].astype(np.float32)  # and solid ones
    sc = float(_RANK_SCALE)
    for t, part in np.unique(groups[:, :2], axis=0):
        lo, hi = int(lib.base[t]), int(lib.base[t + 1])
        cols = lo + np.flatnonzero(lib.part[lo:hi] == part)
        if len(cols) < k:
            cols = np.arange(lo, hi)
        o = lib.desc[cols].astype(np.float32)
        col_cost = (o @ w + PART_PENALTY * (lib.part[cols] != part) + np.where(lib.sym[cols] > 0, _sym_q(), 0)) * sc
        col_cost += rng.integers(0, _RANK_SCALE, size=len(cols))
        right = np.concatenate([o, lib.face[cols].astype(np.float32), lib.unfilled[cols].astype(np.float32),
                                col_cost[:, None].astype(np.float32)], axis=1).T  # (125 + 6 + 6 + 1, m)
        kk = min(k, len(cols))
        g_all = np.flatnonzero((groups[:, 0] == t) & (groups[:, 1] == part))
        for s in range(0, len(g_all), QUERY_CHUNK):
            g = g_all[s:s + QUERY_CHUNK]
            left = np.concatenate([-2.0 * sc * groups[g, 2:-6].astype(np.float32) * w, open_g[g] * (_cut_q() * sc),
                                   solid_g[g] * (_solid_q() * sc), np.ones((len(g), 1), np.float32)], axis=1)
            dist = left @ right
            best = np.argpartition(dist, kk - 1, axis=1)[:, :kk] if kk < len(cols) else \
                np.broadcast_to(np.arange(len(cols)), (len(g), len(cols)))
            order = np.take_along_axis(dist, best, axis=1).argsort(axis=1, kind="stable")
            rows = cols[np.take_along_axis(best, order, axis=1)]
            if kk < k:  # a tiny style: repeat its entries
                rows = rows[:, np.arange(k) % kk]
            row_of_group = np.full(len(groups), -1)
            row_of_group[g] = np.arange(len(g))
            sel = np.flatnonzero(row_of_group[inverse] >= 0)
            out[sel] = rows[row_of_group[inverse[sel]]]
    return out


#: Integer scale of ranked costs; the tie-breaking jitter lies below one unit of it.
_RANK_SCALE = 64


def _cut_q() -> int:
    return int(round(CUT_WEIGHT * UNIT / FACE_Q))


def _solid_q() -> int:
    """Seam cost per quantum of ``Library.unfilled`` (a face against a solid interior neighbour)."""
    return int(round(SEAM_WEIGHT * UNIT / (2 * FACE_Q)))


def _sym_q() -> int:
    return int(round(SYM_PENALTY * UNIT))


def unary(content: Content, lib: Library, q: np.ndarray, cand: np.ndarray) -> np.ndarray:
    """(n, k) int64 U of candidates ``cand`` (n, k) at cells ``q`` (n,); invalid candidates → huge."""
    w = desc_weights()
    valid = cand >= 0
    safe = np.where(valid, cand, 0)
    o = lib.desc[safe].astype(np.int16)  # (n, k, 125)
    c8 = (content.desc[q].astype(np.int16) * 8)[:, None, :]
    cost = (np.abs(c8 - o) * w).sum(axis=2, dtype=np.int64)
    cost += PART_PENALTY * (lib.part[safe] != content.part[q][:, None])
    cost += _cut_q() * (lib.face[safe].astype(np.int64) * content.open_faces[q][:, None, :]).sum(axis=2)
    cost += _solid_q() * (lib.unfilled[safe].astype(np.int64) * content.solid_faces[q][:, None, :]).sum(axis=2)
    cost += np.where(lib.sym[safe] > 0, _sym_q(), 0)
    valid &= lib.style[safe] == content.table[q][:, None]
    return np.where(valid, cost, np.iinfo(np.int64).max // 4)


_SEAM_NORM = 2 * SLAB * SLAB * 2 * (CELL // SLAB) ** 2  # both layers, all values, max count each


def seam(lib: Library, x: np.ndarray, y: np.ndarray, d) -> np.ndarray:
    """int64 V between entries ``x`` at cells q and ``y`` at q + dir(d) (arrays broadcast together with d)."""
    x, y, d = np.broadcast_arrays(np.maximum(x, 0), np.maximum(y, 0), np.asarray(d))
    cont = lib.shift[x, d] == y
    a = lib.slabs[x, d]  # (..., 2, S²) int16: inside, outside of face d
    b = lib.slabs[y, d ^ 1]  # the neighbour's face towards q
    diff = np.abs(a[..., 1, :] - b[..., 0, :]).sum(axis=-1) + np.abs(a[..., 0, :] - b[..., 1, :]).sum(axis=-1)
    cost = np.round((SEAM_BREAK + SEAM_WEIGHT * diff / _SEAM_NORM) * UNIT).astype(np.int64)
    return np.where(cont, 0, cost)


def pair_cost(lib: Library, cand: np.ndarray, other: np.ndarray, d: int) -> np.ndarray:
    """(n, k) int64 V between candidates ``cand`` (n, k) and the neighbour entries ``other`` (n,) across face d."""
    return seam(lib, cand, other[:, None], d)


def local_energy(content: Content, lib: Library, field: np.ndarray, q: np.ndarray, cand: np.ndarray) -> np.ndarray:
    """(n, k) U + Σ V with the current entries of the 6 neighbours, for candidates at cells q."""
    energy = unary(content, lib, q, cand)
    for d in range(6):
        r = content.nb[q, d]
        has = r >= 0
        if not has.any():
            continue
        energy[has] += pair_cost(lib, cand[has], field[r[has]], d)
    return energy


@dataclass
class SearchResult:
    field: np.ndarray  # (N,) global entry id per content cell
    energies: list[float]  # total energy after init, each expansion round and each sweep
    continuation: float  # fraction of 6-neighbour occupied pairs whose entries continue each other


def total_energy(content: Content, lib: Library, field: np.ndarray) -> float:
    q = np.arange(len(content))
    u = int(unary(content, lib, q, field[:, None])[:, 0].sum())
    v = 0
    for d in (1, 3, 5):  # each pair once
        r = content.nb[:, d]
        has = r >= 0
        v += int(seam(lib, field[has], field[r[has]], d).sum())
    return float(u + v)


def continuation(content: Content, lib: Library, field: np.ndarray) -> float:
    """Fraction of 6-neighbouring occupied cell pairs (each counted once) whose sources continue each other."""
    pairs = cont = 0
    for d in (1, 3, 5):
        r = content.nb[:, d]
        has = r >= 0
        pairs += int(has.sum())
        cont += int((lib.shift[field[has], d] == field[r[has]]).sum())
    return cont / pairs if pairs else 1.0

"""Structure repair: no floating fragments, no enclosed cavities, and material in every occupied coarse cell.

Role: after assembly, make the binarised output (field ≥ ISO_LEVEL) one
6-connected body per 6-connected component of the coarse content, touching
every occupied coarse cell, while changing as little as possible.

Components are found without labelling the whole fine grid (a 64-column
grid's output has ~10⁸ voxels): each occupied cell's block is labelled on its
own (16³; ``BATCH_CELLS`` blocks per ``ndimage.label`` call, stacked with an
empty layer between them), blocks are joined where their voxels touch across
a shared face, and the graph's connected components are the fine components
(``scipy.sparse.csgraph``). Per coarse component the largest fine component
is the *main body*. Then:

* a fragment (another component) is removed when every cell it touches also
  holds main material; otherwise it is the only material of some cell and is
  kept and *bridged*;
* enclosed cavities (empty voxels not connected to the outside through the
  empty space of the cells and the empty coarse cells) are filled;
* a cell without main material (a kept fragment, or no material at all) is
  joined to the main body by a tube (radius ``TUBE_RADIUS`` voxels) along the
  shortest path of occupied cells to a cell holding main material: from its
  own material through the cell centres of the path to the main material of
  the last cell. The path only crosses occupied cells, so the tube never
  leaves the coarse shape.

Thin content (a 1-cell rod, a single cell, a 1-cell wall) keeps its material:
a cell can lose material only to removal of fragments that other main
material replaces. ``repair`` reports what it did (fragments removed, tubes).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import cc3d
import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from core.grid import ISO_LEVEL
from model.quilt.library import CELL, DIRS

#: Tube radius of a bridge, fine voxels.
TUBE_RADIUS = 2.5
_SIX = ndimage.generate_binary_structure(3, 1)


@dataclass(frozen=True, eq=False)
class Cells:
    """Every occupied coarse cell (C order) with its face neighbours' ids (−1 empty or beyond the grid)."""

    occ: np.ndarray
    cells: np.ndarray
    ids: np.ndarray  # (X, Y, Z) cell id or -1
    nb: np.ndarray

    def __len__(self) -> int:
        return len(self.cells)


def cell_graph(occ: np.ndarray) -> Cells:
    cells = np.argwhere(occ)
    ids = np.full(np.add(occ.shape, 2), -1, dtype=np.int64)
    ids[1:-1, 1:-1, 1:-1][occ] = np.arange(len(cells))
    nb = np.stack([ids[tuple((cells + 1 + DIRS[d]).T)] for d in range(6)], axis=1)
    return Cells(occ=occ, cells=cells, ids=ids[1:-1, 1:-1, 1:-1], nb=nb)


def _block(fine: np.ndarray, cell: np.ndarray) -> np.ndarray:
    i, j, k = (int(c) * CELL for c in cell)
    return fine[i:i + CELL, j:j + CELL, k:k + CELL]


#: Occupied cells whose blocks are labelled in one ``ndimage.label`` call (``fine_components``): bounds the
#: label array (BATCH_CELLS × 17 × 16² int32 ≈ 4.5 MB).
BATCH_CELLS = 256


@dataclass(frozen=True, eq=False)
class MixedLabels:
    """The 6-connected components of some cells' blocks (``label_blocks``), labelled only where it takes work.

    ``full`` (n,) bool: the block lies wholly in the mask (one component); ``mixed`` (m,) the indices of the
    blocks partly in it; ``stacked`` (m, CELL, CELL, CELL) int32 their labels (0 outside the mask), numbered
    on from one mixed block to the next, so mixed block i's own labels are ``first[i]`` + 1 … + count;
    ``count`` (n,) int64 components per block (0 for a block with no voxel in the mask).
    """

    full: np.ndarray
    mixed: np.ndarray
    stacked: np.ndarray
    first: np.ndarray
    count: np.ndarray


def label_blocks(fine: np.ndarray, cells: np.ndarray, empty: bool = False) -> MixedLabels:
    """6-connected components of the blocks of ``cells`` (n, 3), each block labelled on its own, in the mask
    (voxels ≥ ``ISO_LEVEL``, or < it with ``empty``). Within a block, components are numbered in raster order
    of their first voxel, as ``ndimage.label`` numbers one block alone. The mixed blocks are stacked with an
    empty layer between them, so one call labels them all without joining any two."""
    n = len(cells)
    blocks = fine.reshape(fine.shape[0] // CELL, CELL, fine.shape[1] // CELL, CELL, fine.shape[2] // CELL, CELL)
    blocks = blocks[cells[:, 0], :, cells[:, 1], :, cells[:, 2], :]  # (n, CELL, CELL, CELL), axes as in the grid
    mask = blocks < ISO_LEVEL if empty else blocks >= ISO_LEVEL
    flat = mask.reshape(n, -1)
    full, some = flat.all(axis=1), flat.any(axis=1)
    mixed = np.flatnonzero(some & ~full)
    stack = np.zeros((len(mixed), CELL + 1, CELL, CELL), dtype=bool)
    stack[:, :CELL] = mask[mixed]
    # cc3d numbers components in raster order of their first voxel, as ndimage.label does (3-5x faster)
    stacked = cc3d.connected_components(stack.reshape(-1, CELL, CELL), connectivity=6,
                                        out_dtype=np.uint32).view(np.int32)
    stacked = stacked.reshape(len(mixed), CELL + 1, CELL, CELL)[:, :CELL]
    # per block: how many components, and the stacked labels' first one (they rise block after block)
    count = full.astype(np.int64)
    top = stacked.reshape(len(mixed), CELL**3).max(axis=1, initial=0).astype(np.int64)
    first = np.concatenate([[0], top[:-1]])
    count[mixed] = top - first
    return MixedLabels(full, mixed, stacked, first, count)


def block_labels(fine: np.ndarray, cells: np.ndarray, empty: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(n, CELL, CELL, CELL) int32 labels of the blocks of ``cells`` (``label_blocks``) and (n,) int64 how
    many components each block has: 0 outside the mask, else 1 + the component's index, numbered block
    after block and, within a block, in raster order."""
    lab = label_blocks(fine, cells, empty)
    offset = np.concatenate([[0], np.cumsum(lab.count)[:-1]])
    labels = np.zeros((len(cells), CELL, CELL, CELL), dtype=np.int32)
    labels[lab.full] = (offset[lab.full] + 1).astype(np.int32)[:, None, None, None]
    shift = (offset[lab.mixed] - lab.first).astype(np.int32)[:, None, None, None]
    labels[lab.mixed] = np.where(lab.stacked > 0, lab.stacked + shift, 0)
    return labels, lab.count


_FACE_INDEX = [(slice(None), 0), (slice(None), -1), (slice(None), slice(None), 0), (slice(None), slice(None), -1),
               (Ellipsis, 0), (Ellipsis, -1)]


@dataclass(eq=False)
class BlockParts:
    """Each occupied cell's block split into its 6-connected components (``block_labels``), kept per cell.

    ``count`` (n,) int64 components per cell; ``faces`` (n, 6, CELL, CELL) int32 the six face layers' local
    labels (1 … count, 0 outside the mask; faces in ``DIRS`` order); ``sizes`` per cell its components'
    voxel counts. ``refresh`` relabels only the cells a repair round changed, so later rounds cost what
    they changed, not the whole grid.
    """

    count: np.ndarray
    faces: np.ndarray
    sizes: list[np.ndarray]
    empty: bool

    @classmethod
    def of(cls, fine: np.ndarray, content: Cells, empty: bool = False) -> "BlockParts":
        n = len(content)
        parts = cls(np.zeros(n, dtype=np.int64), np.zeros((n, 6, CELL, CELL), dtype=np.int32), [None] * n, empty)
        parts.refresh(fine, content, np.arange(n))
        return parts

    def refresh(self, fine: np.ndarray, content: Cells, cells: np.ndarray) -> None:
        """Relabel the blocks of ``cells`` (ids into ``content``), ``BATCH_CELLS`` blocks per labelling call."""
        for a in range(0, len(cells), BATCH_CELLS):
            batch = cells[a:a + BATCH_CELLS]
            lab = label_blocks(fine, content.cells[batch], self.empty)
            faces = np.zeros((len(batch), 6, CELL, CELL), dtype=np.int32)
            faces[lab.full] = 1
            first = lab.first.astype(np.int32)[:, None, None]
            for d in range(6):
                face = lab.stacked[_FACE_INDEX[d]]
                faces[lab.mixed, d] = np.where(face > 0, face - first, 0)
            self.faces[batch] = faces
            self.count[batch] = lab.count
            mixed_sizes = np.bincount(lab.stacked.reshape(-1), minlength=int(lab.count[lab.mixed].sum()) + 1)[1:]
            split = iter(np.split(mixed_sizes, np.cumsum(lab.count[lab.mixed])[:-1]) if len(lab.mixed) else [])
            kind = np.where(lab.full, 1, 0)
            kind[lab.mixed] = 2
            for q, k in zip(batch, kind):
                self.sizes[q] = _FULL_SIZE if k == 1 else next(split) if k == 2 else _NO_SIZE


_FULL_SIZE = np.array([CELL**3], dtype=np.int64)  # the one component of a block wholly in the mask
_NO_SIZE = np.zeros(0, dtype=np.int64)


def fine_components(fine: np.ndarray, content: Cells, empty: bool = False, parts: BlockParts | None = None):
    """(node offsets per cell, node sizes, node → component id, n components) of the binarised output.

    Node ``offsets[q] + l - 1`` is local component l of cell q's block (6-connected, ``block_labels``). With
    ``empty`` the components are those of the empty voxels inside occupied cells, and one more node (the
    last, id ``offsets[-1]``) stands for the outside: every local component that touches a face whose coarse
    neighbour is empty or beyond the grid is joined to it. ``parts``: the blocks' components when already
    labelled (``BlockParts``, up to date with ``fine``); else they are labelled here.
    """
    parts = parts if parts is not None else BlockParts.of(fine, content, empty)
    n = len(content)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(parts.count, out=offsets[1:])
    total = int(offsets[-1])
    rows, cols = [], []
    for d in range(6):
        r = content.nb[:, d]
        if empty:  # open faces: their empty voxels are outside
            q = np.flatnonzero(r < 0)
            a = parts.faces[q, d]
            block, i, j = np.nonzero(a)
            hit = np.unique(offsets[q[block]] + a[block, i, j] - 1)
            rows.append(hit)
            cols.append(np.full(len(hit), total))
        if d % 2 == 0:
            continue  # each pair of cells once, from its lower cell
        q = np.flatnonzero(r >= 0)
        a, b = parts.faces[q, d], parts.faces[r[q], d ^ 1]
        touch = (a > 0) & (b > 0)
        # two blocks of one component each: one edge when they touch anywhere (most pairs)
        single = (parts.count[q] == 1) & (parts.count[r[q]] == 1)
        joined = single & touch.any(axis=(1, 2))
        rows.append(offsets[q[joined]])
        cols.append(offsets[r[q[joined]]])
        block, i, j = np.nonzero(touch & ~single[:, None, None])  # the others voxel by voxel
        rows.append(offsets[q[block]] + a[block, i, j] - 1)
        cols.append(offsets[r[q[block]]] + b[block, i, j] - 1)
    size_n = total + (1 if empty else 0)
    r_ = np.concatenate(rows).astype(np.int64) if rows else np.zeros(0, dtype=np.int64)
    c_ = np.concatenate(cols).astype(np.int64) if cols else np.zeros(0, dtype=np.int64)
    graph = coo_matrix((np.ones(len(r_)), (r_, c_)), shape=(size_n, size_n))
    n_comp, comp = connected_components(graph, directed=False) if size_n else (0, np.zeros(0, dtype=np.int64))
    size = np.concatenate(parts.sizes).astype(np.int64) if total else np.zeros(0, dtype=np.int64)
    return offsets, size, comp, n_comp


def fill_cavities(fine: np.ndarray, content: Cells) -> int:
    """Fill empty pockets enclosed by material (not connected to the outside) in place; returns how many."""
    offsets, _, comp, _ = fine_components(fine, content, empty=True)
    total = int(offsets[-1])
    if total == 0:
        return 0
    enclosed = comp[:total] != comp[total]
    node_cell = np.repeat(np.arange(len(content)), np.diff(offsets))
    cells = np.unique(node_cell[enclosed])
    for a in range(0, len(cells), BATCH_CELLS):
        batch = cells[a:a + BATCH_CELLS]
        labels, counts = block_labels(fine, content.cells[batch], empty=True)
        # a batch's labels are numbered from 1 block after block; node offsets[q] + l − 1 is label base + l
        base = np.concatenate([[0], np.cumsum(counts)[:-1]]) - offsets[batch]
        for i, q in enumerate(batch):
            nodes = offsets[q] + np.flatnonzero(enclosed[offsets[q]:offsets[q + 1]])
            block = _block(fine, content.cells[q])
            block[np.isin(labels[i], nodes + base[i] + 1)] = 1.0
    return len(np.unique(comp[:total][enclosed]))


def _tube(fine: np.ndarray, content: Cells, points: list[np.ndarray], radius: float = TUBE_RADIUS) -> set[int]:
    """Raise ``fine`` to a smooth tube profile along the polyline ``points`` (fine voxel coordinates),
    only inside occupied coarse cells (a tube that ends at a cell face must not bulge into an empty one).
    Returns the ids of the cells whose blocks it may have changed."""
    occ = content.occ
    touched: set[int] = set()
    for a, b in zip(points[:-1], points[1:]):
        a, b = a.astype(np.float64), b.astype(np.float64)
        lo = np.maximum(np.floor(np.minimum(a, b) - radius - 1).astype(int), 0)
        hi = np.minimum(np.ceil(np.maximum(a, b) + radius + 2).astype(int), fine.shape)
        grid = np.stack(np.meshgrid(*[np.arange(l, h) + 0.5 for l, h in zip(lo, hi)], indexing="ij"), axis=-1)
        ab = b - a
        t = np.clip(((grid - a) @ ab) / max(float(ab @ ab), 1e-9), 0.0, 1.0)
        dist = np.linalg.norm(grid - (a + t[..., None] * ab), axis=-1)
        value = np.clip(radius + 0.5 - dist, 0.0, 1.0).astype(np.float32)
        cell = [np.arange(l, h) // CELL for l, h in zip(lo, hi)]
        value *= occ[np.ix_(*cell)]
        region = fine[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
        np.maximum(region, value, out=region)
        ids = content.ids[tuple(slice(l // CELL, (h - 1) // CELL + 1) for l, h in zip(lo, hi))]
        touched.update(int(i) for i in ids[ids >= 0])
    return touched


def _nearest_voxel(mask: np.ndarray, cell: np.ndarray) -> np.ndarray:
    """Fine coordinates (voxel centre) of the voxel of ``mask`` (a cell block) nearest the cell centre."""
    idx = np.argwhere(mask)
    centre = (CELL - 1) / 2.0
    best = idx[np.argmin(((idx - centre) ** 2).sum(axis=1))]
    return cell * CELL + best + 0.5


#: Rounds of fragment removal and bridging (a cell bridged in one round lets the next remove the
#: other fragments it held).
ROUNDS = 3


def repair(fine: np.ndarray, occ: np.ndarray) -> dict:
    """Remove or bridge fragments and fill cavities in place (see module docstring); returns counts."""
    content = cell_graph(occ)
    coarse_lab, n_coarse = ndimage.label(occ, structure=_SIX)
    cell_comp = coarse_lab[tuple(content.cells.T)]
    removed = tubes = 0
    parts = BlockParts.of(fine, content)
    for round_ in range(ROUNDS):
        offsets, size, comp, n_comp = fine_components(fine, content, parts=parts)
        if n_comp <= n_coarse:
            break
        r, t, changed = _repair_round(fine, content, cell_comp, offsets, size, comp)
        removed, tubes = removed + r, tubes + t
        if t == 0:
            break  # removing whole fragments cannot split what is left: one body per coarse component
        if round_ < ROUNDS - 1:
            parts.refresh(fine, content, np.array(sorted(changed), dtype=np.int64))
    return {"fragments_removed": removed, "bridges": tubes, "cavities_filled": fill_cavities(fine, content)}


def _repair_round(fine, content, cell_comp, offsets, size, comp) -> tuple[int, int, set[int]]:
    """One round: remove fragments whose cells all hold main material, bridge cells that hold none.
    Returns (fragments removed, tubes, ids of the cells whose blocks changed)."""
    node_cell = np.repeat(np.arange(len(content)), np.diff(offsets))
    # main fine component per coarse component: the largest by voxels
    main_of = {}
    comp_size = np.bincount(comp, weights=size) if len(comp) else np.zeros(0)
    for cc in np.unique(cell_comp):
        nodes = np.flatnonzero(cell_comp[node_cell] == cc)
        if len(nodes):
            comps = np.unique(comp[nodes])
            main_of[int(cc)] = int(comps[np.argmax(comp_size[comps])])
    main_lut = np.full(int(cell_comp.max()) + 1, -1, dtype=np.int64)
    for cc, m in main_of.items():
        main_lut[cc] = m
    node_main = comp == main_lut[cell_comp[node_cell]]
    has_main = np.zeros(len(content), dtype=bool)
    has_main[node_cell[node_main]] = True
    # fragments: removable when every cell they touch holds main material
    frag_cells: dict[int, set[int]] = {}
    for i in np.flatnonzero(~node_main):
        frag_cells.setdefault(int(comp[i]), set()).add(int(node_cell[i]))
    removable = {c for c, cells in frag_cells.items() if all(has_main[q] for q in cells)}
    removed, changed = 0, set()
    touched = np.array(sorted({q for c in removable for q in frag_cells[c]}), dtype=np.int64)
    for a in range(0, len(touched), BATCH_CELLS):  # their blocks labelled in batches (each block on its own)
        batch = touched[a:a + BATCH_CELLS]
        labels, counts = block_labels(fine, content.cells[batch])
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])  # block i's local label l is first[i] + l
        for i, q in enumerate(batch):
            nodes = offsets[q] + np.arange(offsets[q + 1] - offsets[q])
            drop = [first[i] + l + 1 for l, node in enumerate(nodes) if int(comp[node]) in removable]
            if drop:
                _block(fine, content.cells[q])[np.isin(labels[i], drop)] = 0.0
                removed += len(drop)
                changed.add(int(q))
    # bridges for cells without main material
    tubes = 0
    for q in np.flatnonzero(~has_main):
        if has_main[q]:
            continue  # reached by an earlier tube
        path = _path_to_main(content, has_main, q)
        if path is None:
            continue  # a coarse component whose main body is this cell's own material
        cell = content.cells[q]
        own = _block(fine, cell) >= ISO_LEVEL
        start = [_nearest_voxel(own, cell)] if own.any() else []
        centres = [content.cells[p] * CELL + CELL / 2.0 for p in path]
        last = content.cells[path[-1]]
        main_mask = _main_mask(fine, content, offsets, node_main, path[-1])
        end = [_nearest_voxel(main_mask, last)] if main_mask.any() else []  # else a tube's cell: its centre
        changed |= _tube(fine, content, start + centres + end)
        has_main[path[:-1]] = True
        tubes += 1
    return removed, tubes, changed


def _main_mask(fine, content, offsets, node_main, q) -> np.ndarray:
    block = _block(fine, content.cells[q])
    lab, _ = ndimage.label(block >= ISO_LEVEL, structure=_SIX)
    keep = [l + 1 for l in range(offsets[q + 1] - offsets[q]) if node_main[offsets[q] + l]]
    return np.isin(lab, keep)


def _path_to_main(content: Cells, has_main: np.ndarray, start: int) -> list[int] | None:
    """Cells from ``start`` to the nearest cell holding main material (breadth-first, fixed order), or None."""
    parent = {start: -1}
    queue = deque([start])
    while queue:
        q = queue.popleft()
        if has_main[q] and q != start:
            path = [q]
            while parent[path[-1]] != -1:
                path.append(parent[path[-1]])
            return path[::-1]
        for d in range(6):
            r = int(content.nb[q, d])
            if r >= 0 and r not in parent:
                parent[r] = q
                queue.append(r)
    return None

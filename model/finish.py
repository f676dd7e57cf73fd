"""From the learned generator's field to the detailizer's output: specks removed, then the cell-fill floor.

Role: the post-processing of every learned output (``model.infer``), the same on a whole grid and on column
ranges (``finish_columns``), and the floor the training monitor applies (``model.monitor``).

* ``remove_specks``: pieces of at most ``SPECK_VOXELS`` fine voxels go (floating triangles in a game mesh).
* ``min_fill_projection``: every occupied coarse cell keeps material; the ``thin_cells`` (strokes, spires,
  limbs one cell wide) keep at least ``min_fill`` of their block, so they cannot vanish.
"""

from __future__ import annotations

from collections.abc import Callable

import cc3d
import numpy as np

from core.grid import ISO_LEVEL, pool_blocks

#: Pieces of the output (26-connected voxels above ``ISO_LEVEL``) of at most this many fine voxels are removed
#: (``remove_specks``): the learned model leaves specks of 1–8 voxels beside its surface (the thin check counted
#: 18–60 a shape, 0.01 % of the output), which become floating triangles in a game mesh. At most the factor, so
#: that a column range decides its specks exactly with one coarse column of halo; 0 keeps them.
SPECK_VOXELS = 16


def thin_cells(occupancy: np.ndarray) -> np.ndarray:
    """Occupied coarse cells one cell thick along some axis (both neighbours on that axis empty): (X, Y, Z) bool.

    These are the cells of strokes, spires and limbs one cell wide; a cell on the boundary of
    a thicker part has an occupied neighbour inward along every axis and is not one of them.
    """
    occ = np.pad(occupancy.astype(bool), 1)
    thin = np.zeros(occupancy.shape, dtype=bool)
    core = occ[1:-1, 1:-1, 1:-1]
    for axis in range(3):
        before = np.take(occ, range(0, occ.shape[axis] - 2), axis=axis)
        after = np.take(occ, range(2, occ.shape[axis]), axis=axis)
        sl = [slice(1, -1)] * 3
        sl[axis] = slice(None)
        thin |= ~before[tuple(sl)] & ~after[tuple(sl)]
    return thin & core


def min_fill_projection(fine: np.ndarray, occupancy: np.ndarray, factor: int, min_fill: float,
                        iso: float = ISO_LEVEL, thin_only: bool = False, thin: np.ndarray | None = None,
                        island_voxels: int = 0) -> np.ndarray:
    """Raise the field of every occupied coarse cell whose block is less than ``min_fill`` occupied.

    For such a cell, the field of its ``factor``³ block is raised uniformly by the
    smallest amount (+1e-4) that puts ``ceil(min_fill · factor³)`` of its voxels above
    ``iso``, and clipped to 1: the block keeps the generator's own shape, only grown
    (a block the generator left empty becomes a solid block). Other cells are untouched.
    So every occupied input cell is at least ``min_fill`` occupied in the output, and a
    stroke or spire one coarse cell wide cannot vanish.

    Args:
        fine: (f·X, f·Y, f·Z) float32 field in [0, 1]; modified in place and returned.
        occupancy: (X, Y, Z) bool coarse cells.
        thin_only: raise only the ``thin_cells`` of the input (one cell thick along some
            axis) to ``min_fill``; every other occupied cell only to one voxel above ``iso`` (so
            Strict-IOU stays 1), leaving the boundary cells of thicker parts as the generator made
            them. That voxel is the block's highest among those face-adjacent to material of the
            neighbouring blocks (as the field was before this projection), so it joins the surface
            instead of floating; when no neighbour has material at the shared faces, the cell gets the
            thin cells' floor (``min_fill`` of its block) instead of a voxel that would float.
        thin: (X, Y, Z) bool, the ``thin_cells`` to use instead of those of ``occupancy`` (columns cut from a
            larger grid: a cell on the cut is thin or not by its neighbours in the whole grid).
        island_voxels: a raised block's new pieces of at most this many voxels, joined neither to the
            block's largest piece nor to the neighbours' material, are dropped and the block raised again
            (``ISLAND_ROUNDS`` times at most; what the last raise leaves stays, so the floor holds).
            Raising a noisy field puts scattered voxels above ``iso``; 0 keeps them.
    """
    if min_fill <= 0 or not occupancy.any():
        return fine
    x, y, z = occupancy.shape
    f, n = factor, factor**3
    k = int(np.ceil(min_fill * n))
    binary = fine > iso  # before any cell is raised: the attachments depend on no cell order
    above = pool_blocks(binary, f, np.add, dtype=np.int32)
    need = np.where(thin_cells(occupancy) if thin is None else thin, k, 1) if thin_only else np.full(occupancy.shape, k)
    for cx, cy, cz in np.argwhere(occupancy & (above < need)):
        kc = int(need[cx, cy, cz])
        block = (slice(cx * f, cx * f + f), slice(cy * f, cy * f + f), slice(cz * f, cz * f + f))
        values = fine[block]
        touch = _touching_neighbours(binary, (cx, cy, cz), f) if kc == 1 or island_voxels > 0 else None
        if kc == 1:  # the thin-only floor: one voxel, joined to the neighbours' material
            if touch.any():
                values[np.unravel_index(int(np.argmax(np.where(touch, values, -np.inf))), values.shape)] = iso + 1e-4
                continue
            kc = k  # no neighbour has material at its faces: one voxel would float; the thin cells' floor
        _raise_block(values, kc, iso, touch, island_voxels)
    return fine


#: Rounds of ``min_fill_projection``'s island removal in a raised block (each drops islands, then raises again).
ISLAND_ROUNDS = 3


def _raise_block(values: np.ndarray, kc: int, iso: float, touch: np.ndarray | None, island_voxels: int) -> None:
    """Raise the (f, f, f) block ``values`` in place until ``kc`` voxels are above ``iso`` (clipped to 1),
    dropping small islands between raises (``min_fill_projection``'s ``island_voxels``)."""
    n = values.size
    for round_ in range(ISLAND_ROUNDS + 1):
        kth = float(np.partition(values.ravel(), n - kc)[n - kc])  # the kc-th largest value
        np.minimum(values + (iso - kth + 1e-4), 1.0, out=values)
        if island_voxels <= 0 or round_ == ISLAND_ROUNDS:
            return
        labels = cc3d.connected_components((values > iso).view(np.uint8), connectivity=26)
        sizes = np.bincount(labels.ravel())
        small = sizes <= island_voxels
        small[0] = False
        small[1 + int(np.argmax(sizes[1:]))] = False  # the block's main piece (the raise left one at least)
        small[np.unique(labels[touch])] = False  # joined to the neighbours' material
        if not small.any():
            return
        values[small[labels]] = 0.0


def _touching_neighbours(binary: np.ndarray, cell: tuple[int, int, int], f: int) -> np.ndarray:
    """(f, f, f) bool: the cell's block voxels face-adjacent to ``binary`` material of a neighbouring block."""
    origin = [int(c) * f for c in cell]
    touch = np.zeros((f, f, f), dtype=bool)
    for axis in range(3):
        for inner, outer in ((0, origin[axis] - 1), (f - 1, origin[axis] + f)):
            if 0 <= outer < binary.shape[axis]:
                plane = [slice(o, o + f) for o in origin]
                plane[axis] = outer
                face = [slice(None)] * 3
                face[axis] = inner
                touch[tuple(face)] |= binary[tuple(plane)]
    return touch


def remove_specks(fine: np.ndarray, occupancy: np.ndarray, factor: int, max_voxels: int = SPECK_VOXELS,
                  iso: float = ISO_LEVEL, keep_sole: bool = True) -> int:
    """Zero every speck: a 26-connected piece of ``fine > iso`` of at most ``max_voxels`` voxels.

    With ``keep_sole``, a speck that is the only material of an occupied coarse cell it touches is
    kept (the cell stays occupied: Strict-IOU cannot fall); without it, it goes too, for a fill floor
    (``min_fill_projection``, run after this) to put material back there, joined to the surface.

    Args:
        fine: (f·X, f·Y, f·Z) float32 field; modified in place.
        occupancy: (X, Y, Z) bool coarse cells.
        factor: f, fine voxels per coarse cell edge.
        max_voxels: the largest speck, voxels; 0 removes nothing.
        keep_sole: keep the specks that alone occupy an occupied cell.
    Returns:
        the number of specks removed.
    """
    if max_voxels <= 0:
        return 0
    binary = fine > iso
    labels = cc3d.connected_components(binary.view(np.uint8), connectivity=26)
    sizes = np.bincount(labels.ravel())
    small = sizes <= max_voxels
    small[0] = False  # the background
    if not small.any():
        return 0
    speck = small[labels]
    comp = labels[speck]
    where = np.argwhere(speck)
    cells = where // factor
    cell_id = np.ravel_multi_index(cells.T, occupancy.shape)
    material = pool_blocks(binary, factor, np.add, dtype=np.int32).ravel()
    pairs, in_cell = np.unique(np.stack([comp, cell_id]), axis=1, return_counts=True)
    sole = occupancy.ravel()[pairs[1]] & (material[pairs[1]] <= in_cell)  # the cell has nothing else
    keep = np.unique(pairs[0][sole]) if keep_sole else np.zeros(0, dtype=comp.dtype)
    drop = ~np.isin(comp, keep)
    fine[tuple(where[drop].T)] = 0.0
    return int(len(np.unique(comp[drop])))


def finish(fine: np.ndarray, occupancy: np.ndarray, factor: int, speck_voxels: int, min_fill: float,
           thin_only: bool, thin: np.ndarray | None = None) -> np.ndarray:
    """The generator's field → the output: ``remove_specks``, then ``min_fill_projection`` (in place).

    With a fill floor (``min_fill`` > 0) the specks that alone occupy a cell go too, and the floor puts
    material back there; without one they stay, so every occupied cell keeps material either way.

    Args:
        fine: (f·X, f·Y, f·Z) float32 field in [0, 1]; modified in place and returned.
        occupancy: (X, Y, Z) bool coarse cells; ``thin`` as ``min_fill_projection``'s.
    """
    remove_specks(fine, occupancy, factor, speck_voxels, keep_sole=min_fill <= 0)
    return min_fill_projection(fine, occupancy, factor, min_fill, thin_only=thin_only, thin=thin,
                               island_voxels=speck_voxels)


def finish_columns(field: Callable[[int, int], np.ndarray], occupancy: np.ndarray, thin: np.ndarray, start: int,
                   stop: int, factor: int, speck_voxels: int, min_fill: float, thin_only: bool) -> np.ndarray:
    """Columns [start, stop) of the field, ``finish``ed as on the whole grid: (f·(stop − start), f·Y, f·Z).

    ``field(lo, hi)`` gives the (f·(hi − lo), f·Y, f·Z) field of columns [lo, hi); ``thin`` is the whole grid's
    ``thin_cells``. One column of halo each side decides both steps exactly (``speck_voxels`` ≤ f): a speck
    that reaches into [start, stop) lies within one column of it, a piece that reaches the halo's far side from
    inside has more than f voxels, and the floor of a cell reads only its block and its neighbours' faces.
    """
    if speck_voxels > factor:
        raise ValueError(f"speck_voxels {speck_voxels} > factor {factor}: one column of halo would not decide it")
    halo = int(speck_voxels > 0 or min_fill > 0)
    lo, hi = max(start - halo, 0), min(stop + halo, occupancy.shape[0])
    fine = finish(field(lo, hi), occupancy[lo:hi], factor, speck_voxels, min_fill, thin_only, thin=thin[lo:hi])
    return np.ascontiguousarray(fine[(start - lo) * factor:(stop - lo) * factor])

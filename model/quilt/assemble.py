"""Assembly: copy each content cell's source block with a halo, blend the overlaps, confine to the coarse cells.

Role: given the search's source field (one library entry per surface cell),
write the fine occupancy field (16X, 16Y, 16Z) float32 in [0, 1].

* Blocks: each surface cell copies its source cell's fine voxels plus a halo
  of ``HALO`` voxels on every side, from the exemplar in the entry's
  symmetry ((16 + 2·HALO)³ voxels). The exemplar is smoothed once by a
  Gaussian of ``SIGMA`` voxels (``smooth_source``), so the mesh is smooth
  rather than voxel steps; 0.6 keeps the binarised copy equal to the
  exemplar's own voxels almost everywhere (measured: LP-detail of the
  smoothed exemplars against themselves 0.68–0.99, as unsmoothed), where 0.8
  already rounds off corners and one-voxel plates (0.26–0.81).
  Interior cells (all 26 neighbours occupied) get a solid block: nothing of
  them can be seen.
* Joining: overlapping blocks are averaged with separable linear ramps that
  sum to 1 over the 2·HALO-voxel band around each face (a feathered blend).
  Where neighbours continue each other in the exemplar (the search's goal)
  both blocks hold the same voxels, so the join is exact; elsewhere the
  surface crosses over within the band. Blending across a style or part
  boundary is the same operation: joints blend over 2·HALO voxels.
* Confinement: the field is zero outside occupied coarse cells, so the ×16
  max-pool of the output never exceeds the coarse input (Strict-IOU).
* Normalisation: the weights of the occupied cells around a cell sum to 1
  except in bands towards empty neighbours; the sum there depends only on the
  cell's 3×3×3 neighbourhood, so it is computed once per neighbourhood
  pattern (``den_blocks``) instead of accumulated voxel by voxel. The same
  function gives what the (all-ones) interior blocks add to a cell, so only
  surface cells copy blocks.
* Memory: the grid is assembled in slabs of ``SLAB_CELLS`` coarse cells along
  x; only one slab's buffer exists at a time (a 364-cell word needs ~40 MB
  besides its output).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from core.grid import ISO_LEVEL
from model.quilt.library import CELL, Library, apply_sym
from model.quilt.search import Content

#: Halo of a copied block, fine voxels (the blend band is twice this).
HALO = 4
#: Gaussian smoothing of the exemplars before copying, fine voxels (see the module docstring).
SIGMA = 0.6
#: Coarse cells along x assembled at once.
SLAB_CELLS = 16


def ramp_1d(halo: int = HALO) -> np.ndarray:
    """(B,) float32 blend weight along one axis of a block, B = CELL + 2·halo: 1 inside, linear ramps.

    clip((t + 0.5) / (2·halo)) from the low edge and the same from the high edge, so the weights of
    two overlapping neighbours sum to 1 at every voxel of their shared band.
    """
    b = CELL + 2 * halo
    t = np.arange(b, dtype=np.float32)
    return np.minimum(1.0, np.minimum((t + 0.5) / (2 * halo), (b - t - 0.5) / (2 * halo))).astype(np.float32)


def ramp_weights(halo: int = HALO) -> np.ndarray:
    """(B, B, B) float32 separable blend weights of a block (``ramp_1d`` along each axis)."""
    w = ramp_1d(halo)
    return w[:, None, None] * w[None, :, None] * w[None, None, :]


def neighbour_ramps(halo: int = HALO) -> np.ndarray:
    """(3, CELL) float32: at a cell's own fine coordinates, the ramp of the block of its neighbour at
    offset −1, 0, +1 along one axis (only the halo bands of the neighbours reach into the cell)."""
    w = ramp_1d(halo)
    u = np.zeros((3, CELL), dtype=np.float32)
    t = np.arange(CELL)
    for a in (-1, 0, 1):
        s = t - CELL * a + halo
        ok = (s >= 0) & (s < len(w))
        u[a + 1, ok] = w[s[ok]]
    return u


def neighbourhood_codes(occ: np.ndarray) -> np.ndarray:
    """(X, Y, Z) int64: the 3×3×3 occupancy around each cell as 27 bits (beyond the grid is empty)."""
    padded = np.pad(occ, 1)
    code = np.zeros(occ.shape, dtype=np.int64)
    X, Y, Z = occ.shape
    for bit, (a, b, c) in enumerate(np.ndindex(3, 3, 3)):
        code |= padded[a:a + X, b:b + Y, c:c + Z].astype(np.int64) << bit
    return code


FULL_CODE = (1 << 27) - 1


def den_blocks(codes: np.ndarray, halo: int = HALO) -> tuple[np.ndarray, np.ndarray]:
    """The distinct 3×3×3 neighbourhood ``codes`` (m,) and, per code, (m, CELL, CELL, CELL) float32 the sum
    of the blend weights of its occupied cells over the middle cell — what the blended sum there is divided
    by (1 when all 27 are occupied; below 1 in bands towards empty neighbours).

    All of them in one product: every weight is a multiple of 1/(4·halo) (``ramp_1d``), so the products
    and sums are exact in float32 and do not depend on the order they are taken in (one code alone gives
    the same bits).
    """
    uniq = np.unique(np.asarray(codes, dtype=np.int64))
    pattern = ((uniq[:, None] >> np.arange(27)) & 1).astype(np.float32)  # bit = a·9 + b·3 + c
    u = neighbour_ramps(halo)
    weights = np.einsum("ax,by,cz->abcxyz", u, u, u).reshape(27, CELL**3)  # each neighbour's weight over the cell
    return uniq, (pattern @ weights).reshape(-1, CELL, CELL, CELL)


def smooth_source(labels: np.ndarray, offset=(0, 0, 0), resolution: int | None = None,
                  halo: int = HALO) -> np.ndarray:
    """An exemplar's labels → (R + 2·halo)³ uint8 smoothed occupancy (0..255).

    ``labels`` is the exemplar's occupied box placed at ``offset`` in its R³ grid (or the whole
    grid). Gaussian of ``SIGMA`` voxels over the binary occupancy, computed on the box plus the
    kernel's reach only (the rest is exactly 0), padded by ``halo`` empty voxels so a block's
    halo never leaves the array (≈ 0.2 s for a 256³ exemplar; kept by the detailizer).
    """
    r = resolution or labels.shape[0]
    reach = int(2.5 * SIGMA + 0.5) + 1 if SIGMA > 0 else 0
    occ = np.pad(labels > 0, reach).astype(np.float32)
    if SIGMA > 0:
        occ = ndimage.gaussian_filter(occ, SIGMA, truncate=2.5, mode="constant")
    occ *= 255.0
    occ += 0.5
    out = np.zeros((r + 2 * halo,) * 3, dtype=np.uint8)
    lo = np.asarray(offset) + halo - reach  # the box's place in the padded array (≥ 0: halo ≥ reach)
    out[tuple(slice(a, a + n) for a, n in zip(lo, occ.shape))] = occ.astype(np.uint8)
    return out


def source_block(lib: Library, fine: list[np.ndarray], entry: int, halo: int = HALO) -> np.ndarray:
    """The (B, B, B) uint8 smoothed block of library entry ``entry`` (its cell plus the halo), in its symmetry."""
    t, s = int(lib.style[entry]), int(lib.sym[entry])
    o = lib.orig[entry].astype(np.int64) * CELL  # padded array: fine x − halo lands at index x
    block = fine[t][o[0]:o[0] + CELL + 2 * halo, o[1]:o[1] + CELL + 2 * halo, o[2]:o[2] + CELL + 2 * halo]
    return apply_sym(block, s)


def assemble(content: Content, lib: Library, fine: list[np.ndarray], field: np.ndarray,
             out: np.ndarray | None = None, halo: int = HALO) -> np.ndarray:
    """The confined, blended fine field (16X, 16Y, 16Z) float32 of a source field (see module docstring).

    Per slab: the surface cells add their weighted source blocks to ``num``; the interior cells'
    blocks are all ones, so what they add over a cell is the sum of their weights there, which
    depends only on which of the cell's 27 neighbourhood cells are interior (``den_blocks`` of that
    pattern); each occupied cell is then divided by the sum of all weights over it (``den_blocks`` of
    its occupancy pattern; 1 when all 27 are occupied). Empty cells stay 0.
    """
    X, Y, Z = content.shape
    occ = content.occ
    if out is None:
        out = np.zeros((X * CELL, Y * CELL, Z * CELL), dtype=np.float32)
    codes = neighbourhood_codes(occ)
    inner = neighbourhood_codes(occ & (content.ids < 0))  # the interior cells around each cell
    weights_u8 = ramp_weights(halo) / np.float32(255.0)
    b = CELL + 2 * halo
    tmp = np.empty((b, b, b), dtype=np.float32)
    all_cells = np.argwhere(occ)
    cell_codes, cell_inner = codes[occ], inner[occ]  # per cell of all_cells (both C order)
    uniq, dens = den_blocks(np.concatenate([cell_codes, cell_inner]), halo)
    code_at, inner_at = np.searchsorted(uniq, cell_codes), np.searchsorted(uniq, cell_inner)
    for x0 in range(0, X, SLAB_CELLS):
        x1 = min(X, x0 + SLAB_CELLS)
        length = (x1 - x0) * CELL + 2 * halo
        num = np.zeros((length, Y * CELL + 2 * halo, Z * CELL + 2 * halo), dtype=np.float32)
        near = content.cells[(content.cells[:, 0] >= x0 - 1) & (content.cells[:, 0] < x1 + 1)]
        for i, j, k in near:
            bx = (i - x0) * CELL  # buffer origin is fine x = x0·CELL − halo
            lo, hi = max(0, bx), min(length, bx + b)
            np.multiply(weights_u8, source_block(lib, fine, int(field[content.ids[i, j, k]]), halo), out=tmp)
            num[lo:hi, j * CELL:j * CELL + b, k * CELL:k * CELL + b] += tmp[lo - bx:hi - bx]
        core = num[halo:halo + (x1 - x0) * CELL, halo:halo + Y * CELL, halo:halo + Z * CELL]
        for c in np.flatnonzero((all_cells[:, 0] >= x0) & (all_cells[:, 0] < x1)):
            i, j, k = all_cells[c]
            target = out[i * CELL:(i + 1) * CELL, j * CELL:(j + 1) * CELL, k * CELL:(k + 1) * CELL]
            code, icode = int(cell_codes[c]), int(cell_inner[c])
            if code == FULL_CODE and icode == FULL_CODE:
                target.fill(1.0)  # deep inside: only blocks of ones reach it
                continue
            region = core[(i - x0) * CELL:(i - x0 + 1) * CELL, j * CELL:(j + 1) * CELL, k * CELL:(k + 1) * CELL]
            if icode:
                region += dens[inner_at[c]]
            if code != FULL_CODE:
                region /= dens[code_at[c]]
            region[np.abs(region - np.float32(ISO_LEVEL)) < 1e-4] = np.float32(ISO_LEVEL - 1e-3)  # never on the iso
            target[...] = region  # weighted means of values in [0, 1]; empty cells are never written
    return out

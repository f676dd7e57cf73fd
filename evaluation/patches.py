"""Local patches of fine shapes: the paper's 12³ surface patches, their sampling and extraction.

Definitions follow ``reference/method.md`` §5 (DECOR-GAN's evaluation, used by
DECOLLAGE): a *surface position* (i, j, k) is one whose 2×2×2 cell
``[i, i+2)³`` holds both 0 and 1; its patch is ``[i-5, i+7)`` per axis, so
valid positions are ``5 <= i <= dim-7`` (every patch that fits, no padding).
The surface of a shape is its occupied voxels with an empty voxel in their
3×3×3 box (outside the grid is not empty); its dilation is the 3×3×3 max-pool
(the LP-F tolerance of one voxel). All functions accept numpy arrays or torch
tensors; volume work runs on the tensor's device.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core.grid import ISO_LEVEL

if TYPE_CHECKING:  # pragma: no cover
    import torch

#: Edge of a local patch in fine voxels, and its extent around the candidate position.
PATCH_SIZE: int = 12
PATCH_BEFORE: int = 5
PATCH_AFTER: int = 7
#: Voxels in one patch.
PATCH_VOXELS: int = PATCH_SIZE**3
#: Number of output patches sampled per shape (paper: 1000).
N_PATCHES: int = 1000
#: "Similar" thresholds as exact fractions: IOU > 19/20 and F > 19/20.
_T_NUM, _T_DEN = 19, 20
IOU_THRESHOLD: float = _T_NUM / _T_DEN
F_THRESHOLD: float = _T_NUM / _T_DEN


# --------------------------------------------------------------------------- helpers


def as_bool_tensor(volume, what: str) -> "torch.Tensor":
    """A 3-D bool tensor from a bool/float array or tensor (floats binarised at ISO_LEVEL)."""
    import torch

    t = volume if isinstance(volume, torch.Tensor) else torch.from_numpy(np.ascontiguousarray(volume))
    if t.ndim != 3:
        raise ValueError(f"{what} must be a 3-D grid, got shape {tuple(t.shape)}")
    if t.dtype != torch.bool:
        t = t > ISO_LEVEL if t.is_floating_point() else t != 0
    return t


def _shift_reduce(x: "torch.Tensor", op: str) -> "torch.Tensor":
    """3×3×3 box OR ('or', dilation) or AND ('and', erosion) of a bool volume, same shape.

    Separable in-place shifts; voxels outside the grid are ignored (neither
    occupied for the OR nor empty for the AND), i.e. border padding does not count.
    """
    out = x.clone()
    for axis in range(3):
        src = out.clone()
        n = src.shape[axis]
        if n < 2:
            continue
        lo, hi = src.narrow(axis, 0, n - 1), src.narrow(axis, 1, n - 1)
        dst_hi, dst_lo = out.narrow(axis, 1, n - 1), out.narrow(axis, 0, n - 1)
        if op == "or":
            dst_hi |= lo
            dst_lo |= hi
        else:
            dst_hi &= lo
            dst_lo &= hi
    return out


def surface_and_dilation(shape) -> tuple["torch.Tensor", "torch.Tensor"]:
    """Surface voxels and their 3×3×3 dilation, computed on the whole shape.

    Args:
        shape: (X, Y, Z) bool (or float, binarised at ISO_LEVEL).
    Returns:
        (surface, dilated), both (X, Y, Z) bool: surface = occupied voxels with
        an empty voxel in their 3×3×3 box (outside the grid is not empty);
        dilated = 3×3×3 max-pool of surface (1-voxel Chebyshev tolerance).
    """
    occ = as_bool_tensor(shape, "shape")
    surface = occ & ~_shift_reduce(occ, "and")
    return surface, _shift_reduce(surface, "or")


# --------------------------------------------------------------------------- patches


def surface_candidates(shape) -> np.ndarray:
    """All surface positions of a shape whose 12³ patch fits in the grid.

    Args:
        shape: (X, Y, Z) bool.
    Returns:
        (m, 3) int64 positions (i, j, k), lexicographically sorted, where the
        2×2×2 cell starting at (i, j, k) holds both 0 and 1 and
        5 <= i <= X-7 (same for j, k). m = 0 for grids smaller than 12 per axis.
    """
    import torch

    occ = as_bool_tensor(shape, "shape")
    if min(occ.shape) < PATCH_SIZE:
        return np.zeros((0, 3), dtype=np.int64)
    any_, all_ = occ, occ
    for axis in range(3):
        n = any_.shape[axis]
        any_ = any_.narrow(axis, 0, n - 1) | any_.narrow(axis, 1, n - 1)
        all_ = all_.narrow(axis, 0, n - 1) & all_.narrow(axis, 1, n - 1)
    mixed = any_ & ~all_  # cell index (i, j, k) = cell starting at voxel (i, j, k)
    X, Y, Z = occ.shape
    # positions 5 .. dim-7 inclusive: [i-5, i+7) stays inside [0, dim)
    window = mixed[PATCH_BEFORE : X - PATCH_AFTER + 1, PATCH_BEFORE : Y - PATCH_AFTER + 1,
                   PATCH_BEFORE : Z - PATCH_AFTER + 1]
    pos = torch.nonzero(window).cpu().numpy().astype(np.int64) + PATCH_BEFORE
    return pos


def sample_surface_patches(shape, n: int = N_PATCHES, seed: int = 0) -> np.ndarray:
    """Sample up to ``n`` surface positions without replacement (all of them if fewer).

    Args:
        shape: (X, Y, Z) bool.
        n: number of positions wanted.
        seed: seed of the numpy Generator (same seed, same shape → same sample).
    Returns:
        (min(n, m), 3) int64 positions, in the sampled order.
    """
    pos = surface_candidates(shape)
    if len(pos) <= n:
        return pos
    rng = np.random.default_rng(seed)
    return pos[rng.choice(len(pos), size=n, replace=False)]


def _patch_offsets(shape: tuple[int, int, int]) -> np.ndarray:
    """(1728,) flat-index offsets of the voxels of a patch relative to its min corner."""
    _, Y, Z = shape
    r = np.arange(PATCH_SIZE, dtype=np.int64)
    return (r[:, None, None] * (Y * Z) + r[None, :, None] * Z + r[None, None, :]).reshape(-1)


def extract_patches(volume, positions: np.ndarray, chunk: int = 8192) -> "torch.Tensor":
    """Gather 12³ patches of a volume as flat int8 rows.

    Args:
        volume: (X, Y, Z) bool tensor/array.
        positions: (m, 3) int candidate positions; the patch is [p-5, p+7) per axis.
    Returns:
        (m, 1728) int8 tensor of 0/1 on the volume's device, voxel order (a, b, c)
        row-major inside the patch.
    """
    import torch

    vol = as_bool_tensor(volume, "volume")
    flat = vol.reshape(-1)
    offsets = torch.from_numpy(_patch_offsets(tuple(vol.shape))).to(vol.device)
    _, Y, Z = vol.shape
    corners = np.asarray(positions, dtype=np.int64).reshape(-1, 3) - PATCH_BEFORE
    start = torch.from_numpy(corners[:, 0] * (Y * Z) + corners[:, 1] * Z + corners[:, 2]).to(vol.device)
    out = torch.empty((len(corners), PATCH_VOXELS), dtype=torch.int8, device=vol.device)
    for s in range(0, len(corners), chunk):
        idx = start[s : s + chunk, None] + offsets[None, :]
        out[s : s + chunk] = flat[idx].to(torch.int8)
    return out


@dataclass(frozen=True, eq=False)
class PatchSet:
    """Patches of one shape, as dense 0/1 int8 rows of 1728 voxels (device tensors).

    Attributes:
        occ: (m, 1728) occupancy.
        surf: (m, 1728) surface voxels (surface computed on the whole shape).
        dil: (m, 1728) dilated surface (3×3×3, whole shape).
    """

    occ: "torch.Tensor"
    surf: "torch.Tensor"
    dil: "torch.Tensor"

    def __len__(self) -> int:
        return int(self.occ.shape[0])


def patch_set(shape, positions: np.ndarray) -> PatchSet:
    """Occupancy, surface and dilated-surface patches of ``shape`` at ``positions``."""
    occ = as_bool_tensor(shape, "shape")
    surf, dil = surface_and_dilation(occ)
    return PatchSet(extract_patches(occ, positions), extract_patches(surf, positions),
                    extract_patches(dil, positions))

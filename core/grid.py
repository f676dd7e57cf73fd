"""Voxel grids: the one contract between the pipeline and the detailizer.

Axes convention (everywhere in this project): array index ``[i, j, k]`` is
voxel (x, y, z) in the canonical frame, +Y up, front +Z, units metres. Voxel
``(i, j, k)`` covers the box ``origin_m + [i, i+1) * voxel_size_m`` (same for
j, k); its centre is ``origin_m + (i + 0.5) * voxel_size_m``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Binarisation / iso level used everywhere the paper uses one.
ISO_LEVEL: float = 0.4

#: Total upsampling factor of the detailizer (16³ → 256³).
UPSAMPLE_FACTOR: int = 16

#: Index stored in ``part`` / ``style`` arrays for empty voxels.
EMPTY: int = -1


def pool_blocks(array: np.ndarray, factor: int, ufunc: np.ufunc = np.maximum, dtype=None) -> np.ndarray:
    """(X, Y, Z) ``ufunc`` over each factor³ block of an (X·f, Y·f, Z·f) array (trailing voxels beyond whole
    blocks are ignored), e.g. ``np.maximum`` (max-pool), ``np.logical_or`` (any), ``np.add`` with ``dtype``.

    The block's axes are reduced one at a time, outermost first, so the first two passes combine whole
    contiguous rows (about 7× faster than one reduction over axes (1, 3, 5) on a 12 M voxel field). Exact
    for max, any and integer sums; a float sum adds in a different order than one multi-axis reduction.
    """
    x, y, z = (n // factor for n in array.shape)
    view = array[:x * factor, :y * factor, :z * factor].reshape(x, factor, y, factor, z, factor)
    view = ufunc.reduce(view, axis=1, dtype=dtype)  # (x, y, f, z, f)
    view = ufunc.reduce(view, axis=2, dtype=dtype)  # (x, y, z, f)
    return ufunc.reduce(view, axis=3, dtype=dtype)


def _check_names(names: tuple[str, ...], what: str) -> None:
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate {what} names: {names}")


@dataclass(frozen=True, eq=False)
class LabeledGrid:
    """A coarse (or exemplar) voxel grid where every occupied voxel has a part and a style.

    Attributes:
        occupancy: (X, Y, Z) bool.
        part: (X, Y, Z) int16, index into ``part_names``; ``EMPTY`` where unoccupied.
        style: (X, Y, Z) int16, index into ``style_names``; ``EMPTY`` where unoccupied.
        part_names: semantic part labels (e.g. ``("body", "roof")``).
        style_names: style names (exemplar names for the learned model).
        voxel_size_m: edge length of one voxel in metres.
        origin_m: (3,) world position of the min corner of voxel (0, 0, 0), metres.
    """

    occupancy: np.ndarray
    part: np.ndarray
    style: np.ndarray
    part_names: tuple[str, ...]
    style_names: tuple[str, ...]
    voxel_size_m: float
    origin_m: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        occ = np.asarray(self.occupancy)
        if occ.ndim != 3 or occ.dtype != np.bool_:
            raise ValueError(f"occupancy must be a 3-D bool array, got {occ.dtype} {occ.shape}")
        for name in ("part", "style"):
            arr = getattr(self, name)
            if arr.shape != occ.shape:
                raise ValueError(f"{name} shape {arr.shape} != occupancy shape {occ.shape}")
            if not np.issubdtype(arr.dtype, np.integer):
                raise ValueError(f"{name} must be an integer array, got {arr.dtype}")
        _check_names(self.part_names, "part")
        _check_names(self.style_names, "style")
        if occ.any():
            for name, names in (("part", self.part_names), ("style", self.style_names)):
                values = getattr(self, name)[occ]
                if values.min() < 0 or values.max() >= len(names):
                    raise ValueError(f"occupied voxels need a valid {name} index in [0, {len(names)})")
        if np.any(self.part[~occ] != EMPTY) or np.any(self.style[~occ] != EMPTY):
            raise ValueError("empty voxels must have part and style EMPTY (-1)")
        if not self.voxel_size_m > 0:
            raise ValueError("voxel_size_m must be positive")

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(self.occupancy.shape)  # type: ignore[return-value]

    @property
    def count(self) -> int:
        """Number of occupied voxels."""
        return int(self.occupancy.sum())

    def bounds_m(self) -> np.ndarray:
        """(2, 3) min/max corner of the whole grid box in metres."""
        lo = np.asarray(self.origin_m, dtype=np.float64)
        return np.stack([lo, lo + np.asarray(self.shape) * self.voxel_size_m])


@dataclass(frozen=True, eq=False)
class FineGrid:
    """What a detailizer returns: a 16× finer occupancy field with a style per voxel.

    Attributes:
        occupancy: (X·f, Y·f, Z·f) float32 in [0, 1]; the surface is ``ISO_LEVEL``.
        style: (X·f, Y·f, Z·f) int16 style index for *every* voxel (also empty ones,
            filled from the nearest occupied region) so that any surface point has a style.
        style_names: names behind ``style`` indices (same as the input grid's).
        voxel_size_m: fine voxel edge, = coarse voxel size / factor.
        origin_m: same world origin as the coarse grid.
        detailizer: name of the detailizer that produced it (e.g. ``"upsample"``).
    """

    occupancy: np.ndarray
    style: np.ndarray
    style_names: tuple[str, ...]
    voxel_size_m: float
    origin_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    detailizer: str = ""
    extras: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.occupancy.ndim != 3 or self.occupancy.dtype != np.float32:
            raise ValueError(f"occupancy must be 3-D float32, got {self.occupancy.dtype} {self.occupancy.shape}")
        if self.style.shape != self.occupancy.shape:
            raise ValueError("style and occupancy shapes differ")

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(self.occupancy.shape)  # type: ignore[return-value]

    def binary(self, iso: float = ISO_LEVEL) -> np.ndarray:
        """(X, Y, Z) bool: voxels at or above the iso level."""
        return self.occupancy >= iso

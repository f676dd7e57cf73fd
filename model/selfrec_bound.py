"""How well can *any* detailizer reproduce an exemplar from its coarse grid? The sub-cell offset bound.

A style sample (``model.data.style_sample``, the monitor's self-reconstruction inputs, and
``evaluation/selfrec.py``'s cases) puts the exemplar at a random sub-cell offset
``o ∈ [0, f)³`` inside its coarse cells; the coarse input is the ×f max-pool. Offsets
whose max-pools are identical give the detailizer the *same* input, yet their targets
are the exemplar shifted by up to f − 1 fine voxels. A function of the coarse grid
can therefore at best output the voxel-wise posterior of the exemplar over those
offsets (uniform prior), thresholded; its self-reconstruction IOU, averaged over the
offsets of that group, is the ceiling computed here (``offset_bound``). The model also
sees the part labels and the style, both fixed for one exemplar, so they add nothing.

``offset_groups`` finds every offset's coarse grid in one separable pass (any-pool
along x for each x offset, then y, then z), a few seconds for a 256³ exemplar.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.grid import ISO_LEVEL
from model.finish import min_fill_projection


def _pool_axis(a: np.ndarray, axis: int, offset: int, factor: int) -> np.ndarray:
    """Any-pool ``a`` along ``axis`` by ``factor`` after ``offset`` empty voxels before it (zero-padded after)."""
    n = a.shape[axis]
    cells = -(-(offset + n) // factor)
    pad = [(0, 0)] * a.ndim
    pad[axis] = (offset, cells * factor - offset - n)
    p = np.pad(a, pad)
    shape = list(p.shape)
    shape[axis : axis + 1] = [cells, factor]
    return p.reshape(shape).any(axis=axis + 1)


def offset_groups(binary: np.ndarray, factor: int) -> dict[tuple[int, int, int], bytes]:
    """Per sub-cell offset (ox, oy, oz), a key of the coarse grid it gives (equal keys = equal coarse inputs).

    ``binary``: the exemplar's bbox-cropped occupancy. The key is the coarse grid of the
    shape placed at that offset with no margin (the margin and the ``min_cells`` padding
    of ``place_in_crop`` follow from the grid's shape, so they add no information).
    """
    out = {}
    for ox in range(factor):
        ax = _pool_axis(binary, 0, ox, factor)
        for oy in range(factor):
            axy = _pool_axis(ax, 1, oy, factor)
            for oz in range(factor):
                c = _pool_axis(axy, 2, oz, factor)
                out[(ox, oy, oz)] = repr(c.shape).encode() + np.packbits(c).tobytes()
    return out


def _placed(binary: np.ndarray, offset: tuple[int, int, int], factor: int) -> np.ndarray:
    """The shape at ``offset`` in a frame of ``shape + factor − 1`` voxels per axis."""
    out = np.zeros(tuple(n + factor - 1 for n in binary.shape), dtype=bool)
    ox, oy, oz = offset
    x, y, z = binary.shape
    out[ox : ox + x, oy : oy + y, oz : oz + z] = binary
    return out


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 1.0


@dataclass(frozen=True)
class OffsetBound:
    """The bound for one exemplar at one offset (see the module docstring).

    Attributes:
        group_size: offsets giving the same coarse grid as ``offset`` (1 = the offset is known).
        iou_at_offset: IOU of the thresholded posterior against the exemplar at ``offset``.
        iou_expected: the same averaged over (up to ``max_members``) offsets of the group:
            what the best deterministic detailizer scores on this input, in expectation.
        threshold: the posterior threshold that maximised ``iou_expected``.
        projection_iou: IOU of the exemplar itself after ``min_fill_projection`` (at
            ``min_fill``) against the exemplar: what the inference projection alone costs a
            perfect output.
    """

    group_size: int
    iou_at_offset: float
    iou_expected: float
    threshold: float
    projection_iou: float


def offset_bound(binary: np.ndarray, offset: tuple[int, int, int], factor: int, min_fill: float = 0.5,
                 thresholds: tuple[float, ...] = (0.3, 0.4, 0.5, 0.6, 0.7), max_members: int = 16,
                 groups: dict[tuple[int, int, int], bytes] | None = None, seed: int = 0) -> OffsetBound:
    """The self-reconstruction ceiling of ``binary`` (bbox-cropped bool) placed at ``offset``."""
    from scipy.signal import fftconvolve

    groups = offset_groups(binary, factor) if groups is None else groups
    key = groups[tuple(int(o) for o in offset)]
    members = [o for o, k in groups.items() if k == key]
    kernel = np.zeros((factor,) * 3, dtype=np.float32)
    for o in members:
        kernel[o] = 1.0
    posterior = fftconvolve(binary.astype(np.float32), kernel, mode="full") / len(members)
    rng = np.random.default_rng(seed)
    pick = [members[i] for i in rng.choice(len(members), size=min(max_members, len(members)), replace=False)]
    truths = [_placed(binary, o, factor) for o in pick]
    best_t, best = thresholds[0], -1.0
    for t in thresholds:
        pred = posterior > t
        mean = float(np.mean([_iou(pred, tr) for tr in truths]))
        if mean > best:
            best_t, best = t, mean
    own = _placed(binary, tuple(int(o) for o in offset), factor)
    at = _iou(posterior > best_t, own)
    # the projection needs the frame to be whole cells: pad the placed exemplar to a multiple of factor
    cells = [-(-n // factor) for n in own.shape]
    frame = np.zeros(tuple(c * factor for c in cells), dtype=np.float32)
    frame[: own.shape[0], : own.shape[1], : own.shape[2]] = own
    coarse = frame.reshape(cells[0], factor, cells[1], factor, cells[2], factor).max(axis=(1, 3, 5)) > 0
    projected = min_fill_projection(frame.copy(), coarse, factor, min_fill) > ISO_LEVEL
    return OffsetBound(len(members), at, best, best_t, _iou(projected, frame > 0))

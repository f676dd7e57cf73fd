"""Structure kept by a detailizer: Strict-IOU and Loose-IOU of a fine output against its coarse input.

The paper's definition (DECOR-GAN's evaluation code, used by DECOLLAGE): max-pool the binarised
fine output by the total upsampling factor (kernel = stride) and compare the
result D with the coarse input C. Used by the content flow (every asset's
manifest) and by the evaluation.
"""

from __future__ import annotations

import numpy as np

from core.grid import ISO_LEVEL, UPSAMPLE_FACTOR, pool_blocks


def as_bool_array(volume, what: str) -> np.ndarray:
    """A 3-D bool numpy array from a bool/float array or a CPU tensor (floats binarised > ISO_LEVEL)."""
    arr = np.asarray(volume.cpu() if hasattr(volume, "cpu") else volume)
    if arr.ndim != 3:
        raise ValueError(f"{what} must be a 3-D grid, got shape {tuple(arr.shape)}")
    if arr.dtype != np.bool_:
        arr = arr > ISO_LEVEL if np.issubdtype(arr.dtype, np.floating) else arr != 0
    return arr


def coarse_of(output: np.ndarray, factor: int) -> np.ndarray:
    """(x, y, z) bool max-pool of an (x·f, y·f, z·f) bool grid by ``factor`` (kernel = stride)."""
    return pool_blocks(output, factor, np.logical_or)


def strict_loose_iou(output, coarse, factor: int = UPSAMPLE_FACTOR) -> tuple[float, float]:
    """Strict-IOU and Loose-IOU of a fine output against its coarse input.

    Args:
        output: (factor·x, factor·y, factor·z) fine occupancy, bool (floats
            are binarised at ISO_LEVEL), numpy array or CPU tensor.
        coarse: (x, y, z) coarse occupancy, bool.
        factor: total upsampling factor (16 for 16³ → 256³).
    Returns:
        (strict, loose) with D = max-pool(output, factor), C = coarse:
        strict = |D∧C| / |D∨C|, loose = |D∧C| / |C|.
        Empty cases: both empty → (1.0, 1.0); C empty but D not → strict 0.0,
        loose 0.0 (the output invents cells the input does not have); an empty
        output with a non-empty C gives (0.0, 0.0) from the formulas.
    Raises:
        ValueError: if output's shape is not factor × coarse's shape.
    """
    out = as_bool_array(output, "output")
    c = as_bool_array(coarse, "coarse")
    if factor < 1:
        raise ValueError(f"factor must be >= 1, got {factor}")
    expected = tuple(int(s) * factor for s in c.shape)
    if tuple(out.shape) != expected:
        raise ValueError(
            f"output shape {tuple(out.shape)} must be factor {factor} × coarse shape "
            f"{tuple(c.shape)} = {expected}"
        )
    return iou_from_counts(*structure_counts(out, c, factor))


def structure_counts(output: np.ndarray, coarse: np.ndarray, factor: int) -> tuple[int, int, int]:
    """(|D∧C|, |D∨C|, |C|) of a bool fine ``output`` (factor × ``coarse``'s shape) against bool ``coarse``.

    Counts add up over disjoint blocks of a grid (an asset detailized block by block).
    """
    d = coarse_of(output, factor)
    return int((d & coarse).sum()), int((d | coarse).sum()), int(coarse.sum())


def iou_from_counts(inter: int, union: int, n_c: int) -> tuple[float, float]:
    """(strict, loose) from ``structure_counts`` (see ``strict_loose_iou`` for the empty cases)."""
    if union == 0:
        return 1.0, 1.0
    loose = inter / n_c if n_c else 0.0
    return inter / union, loose

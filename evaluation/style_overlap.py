"""Style overlap: do a detailizer's outputs of one content differ when only the style differs?

For every content of the evaluated split, its single-style outputs (the protocol's
``N_SINGLE`` assignments, every part in one style, a different style each) are kept
bit-packed until the content's last one is detailized; each of them then gets the
mean IOU between it and each of the content's other single-style outputs. The mean
over a content's outputs is the mean over its pairs, so a bootstrap over contents
(``evaluation.intervals``) gives the figure's interval. 1 = style changes nothing
(upsample, which is style-blind, scores exactly 1); issue 15 asks for ≤ 0.85.

Memory: one bit per fine voxel of each kept output (2 MB for a 256³ grid), for one
content at a time when the outputs come content by content, as the protocol lists them.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Iterable

import numpy as np


class StyleOverlap:
    """Collects single-style outputs per content and sets each one's ``style_overlap`` once its content is complete.

    Args:
        outputs: the protocol outputs that will be added (``OutputSpec``: ``content``, ``mixed``), to know
            how many single-style outputs each content has.
    """

    def __init__(self, outputs: Iterable) -> None:
        self.expected = Counter(o.content for o in outputs if not o.mixed)
        self._kept: dict[str, list[tuple[dict, tuple[tuple[int, ...], np.ndarray]]]] = defaultdict(list)

    def add(self, output, binary: np.ndarray, row: dict) -> None:
        """Record one output: ``binary`` (X, Y, Z) bool; ``row`` is the output's report row, which gets the figure.

        Mixed-style outputs are skipped (their row gets no figure). A content with a single
        single-style output has no pair: its row gets None.
        """
        if output.mixed:
            return
        kept = self._kept[output.content]
        kept.append((row, pack(binary)))
        if len(kept) < self.expected[output.content]:
            return
        del self._kept[output.content]
        for (row_i, _), value in zip(kept, pairwise_overlap([p for _, p in kept])):
            row_i["style_overlap"] = value


def pack(binary: np.ndarray) -> tuple[tuple[int, ...], np.ndarray]:
    """(shape, bits) of a bool grid: one bit per voxel, what ``pairwise_overlap`` takes."""
    return binary.shape, np.packbits(binary, axis=None)


def pairwise_overlap(packed: list[tuple[tuple[int, ...], np.ndarray]]) -> list[float | None]:
    """Per output, the mean IOU with every other output of the list; ``pack(binary)`` each.

    Two empty outputs count as identical (IOU 1). Returns None for every entry of a list of one.
    """
    n = len(packed)
    if n < 2:
        return [None] * n
    if len({shape for shape, _ in packed}) != 1:
        raise ValueError("outputs of one content must have the same shape")
    bits = [p for _, p in packed]
    counts = [int(np.bitwise_count(p).sum()) for p in bits]
    iou = np.ones((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            inter = int(np.bitwise_count(bits[i] & bits[j]).sum())
            union = counts[i] + counts[j] - inter
            iou[i, j] = iou[j, i] = inter / union if union else 1.0
    return [float((iou[i].sum() - 1.0) / (n - 1)) for i in range(n)]

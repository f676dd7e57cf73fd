"""The style-overlap figure (``evaluation/style_overlap.py``): per single-style output, the mean IOU with its
content's other single-style outputs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from evaluation.style_overlap import StyleOverlap, pack as _packed, pairwise_overlap


@dataclass(frozen=True)
class _Out:
    content: str
    mixed: bool


def test_pairwise_overlap_known_values():
    a = np.zeros((4, 4, 4), bool)
    a[:2] = True  # 32 voxels
    b = np.zeros_like(a)
    b[1:3] = True  # 32 voxels, 16 shared with a
    c = np.zeros_like(a)  # empty
    # IOU(a, b) = 16 / 48; IOU(a, c) = IOU(b, c) = 0
    got = pairwise_overlap([_packed(a), _packed(b), _packed(c)])
    assert got == pytest.approx([(1 / 3 + 0) / 2, (1 / 3 + 0) / 2, 0.0])
    assert pairwise_overlap([_packed(a), _packed(a.copy())]) == [1.0, 1.0]
    assert pairwise_overlap([_packed(c), _packed(c)]) == [1.0, 1.0]  # two empty outputs are the same output
    assert pairwise_overlap([_packed(a)]) == [None]
    with pytest.raises(ValueError, match="same shape"):
        pairwise_overlap([_packed(a), _packed(a[:3])])


def test_rows_get_the_figure_when_their_content_is_complete_and_mixed_ones_never():
    outs = [_Out("c0", False), _Out("c0", False), _Out("c0", True), _Out("c1", False), _Out("c0", False)]
    ov = StyleOverlap(outs)
    rng = np.random.default_rng(0)
    grids = [rng.random((8, 8, 8)) > 0.5 for _ in outs]
    rows = [{} for _ in outs]
    for k, (o, g, r) in enumerate(zip(outs, grids, rows)):
        ov.add(o, g, r)
        if k == 1:
            assert "style_overlap" not in rows[0]  # c0 has a third single-style output still to come
    assert "style_overlap" not in rows[2]  # mixed
    assert rows[3]["style_overlap"] is None  # c1 has one single-style output: no pair
    want = pairwise_overlap([_packed(grids[i]) for i in (0, 1, 4)])
    assert [rows[i]["style_overlap"] for i in (0, 1, 4)] == want
    assert 0.0 < want[0] < 1.0

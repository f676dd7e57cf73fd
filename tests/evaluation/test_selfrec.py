"""Self-reconstruction (evaluation/selfrec.py): cases, IOU at full resolution, Chamfer."""

from __future__ import annotations

import numpy as np
import pytest

from core.detailizer import get_detailizer
from core.grid import EMPTY, ISO_LEVEL, LabeledGrid
from evaluation.selfrec import SelfCase, case_figures, chamfer, fine_iou, self_cases


def _upsampled(coarse: np.ndarray) -> np.ndarray:
    """The upsample detailizer's own output for a coarse occupancy (bool, ×16)."""
    g = LabeledGrid(occupancy=coarse, part=np.where(coarse, 0, EMPTY).astype(np.int16),
                    style=np.where(coarse, 0, EMPTY).astype(np.int16), part_names=("bottom", "top"),
                    style_names=("s",), voxel_size_m=0.1)
    return np.asarray(get_detailizer("upsample").detailize(g, seed=0).occupancy) > ISO_LEVEL


def test_self_reconstruction_of_the_upsample_of_an_exemplar_has_its_known_iou():
    coarse = np.zeros((4, 4, 4), bool)
    coarse[1:3, 1:3, 1:3] = True
    coarse[1, 3, 1] = True
    fine = _upsampled(coarse)
    hole = np.zeros_like(fine)
    hole[20:30, 20:30, 20:30] = True  # deep inside the 2×2×2 block: the max-pool does not change
    assert fine[hole].all()
    truth = fine & ~hole
    case = SelfCase("self/s", 0, "s", False, np.where(truth, 0, EMPTY).astype(np.int16))
    assert np.array_equal(case.grid(("bottom", "top")).occupancy, coarse)
    out = _upsampled(case.grid(("bottom", "top")).occupancy)
    figures = case_figures(out, case)
    known = (fine.sum() - hole.sum()) / fine.sum()  # the output is `fine` again; the truth lacks the hole
    assert figures["iou"] == pytest.approx(known, abs=1e-12) and known < 0.99
    exact = SelfCase("self/s", 0, "s", False, np.where(fine, 0, EMPTY).astype(np.int16))
    again = case_figures(out, exact)
    assert again["iou"] == 1.0 and again["chamfer"] == 0.0


def test_chamfer_of_a_shifted_box_is_the_shift():
    a = np.zeros((40, 40, 40), bool)
    a[10:30, 10:30, 10:30] = True
    b = np.roll(a, 2, axis=0)
    d = chamfer(a, b)
    assert 0.5 < d <= 2.0  # faces ⟂ x move by 2, the others do not move at all
    assert chamfer(a, a) == 0.0 and chamfer(a, np.zeros_like(a)) is None
    assert fine_iou(a, b) == pytest.approx(18 / 22)


def test_cases_are_every_exemplar_then_held_out_augmentations_and_are_reproducible():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from test_eval import TINY_STYLES, _exemplar
    from stylesets.format import THINGS, StyleSet

    sset = StyleSet("tiny", THINGS, 64, "h", tuple(_exemplar(i, n, c) for i, (n, c) in enumerate(TINY_STYLES)))
    cases = self_cases(sset, n_aug=2)
    assert [c.id for c in cases[:3]] == ["self/blocky", "self/ridged", "self/stepped"]
    assert [c.held_out for c in cases] == [False] * 3 + [True] * 6
    again = self_cases(sset, n_aug=2)
    assert all(np.array_equal(a.labels, b.labels) for a, b in zip(cases, again))
    assert not np.array_equal(cases[3].labels, self_cases(sset, seed=1, n_aug=1)[3].labels)
    for c in cases:
        assert all(n % 16 == 0 for n in c.labels.shape)
        g = c.grid(("bottom", "top"))
        assert g.style_names == (c.name,) and g.occupancy.sum() > 0
        assert not g.occupancy[0].any() and not g.occupancy[-1].any()  # one empty cell a side
    # the exemplar as itself keeps its voxels exactly
    ex = sset.exemplars[0]
    assert cases[0].fine.sum() == (ex.labels > 0).sum()

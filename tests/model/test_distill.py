"""Distillation from quilt (``model/distill.py``): the targets are quilt's outputs on the drawn contents,
every draw is a function of (seed, it, r), and a resumed distilled run ends where an unbroken one does."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from model.checkpoint import load_checkpoint
from model.config import ModelConfig
from model.data import AugmentConfig, augmented_sample, max_pool, rng_for, style_sample
from model.distill import STREAM_CONTENT, STREAM_QUILT, QuiltTeacher, distill_sample, is_distilled, style_set_of
from model.quilt import QuiltDetailizer
from model.recipes import DISTILL_FRAC, recipe_configs
from model.train import Trainer, TrainConfig, train
from core.grid import EMPTY, ISO_LEVEL
from tests.model.test_train import EXS, R, _cfg, _log, _tcfg

AUG = AugmentConfig(resolution=R)


@pytest.fixture(scope="module")
def teacher() -> QuiltTeacher:
    return QuiltTeacher(EXS)


def test_style_set_of_holds_the_exemplars(teacher):
    sset = style_set_of(EXS)
    assert [e.name for e in sset.exemplars] == ["crate", "tower"] and sset.vocabulary.parts == ("bottom", "top")
    for ex, sx in zip(EXS, sset.exemplars):
        np.testing.assert_array_equal(sx.full(R).astype(np.int16) - 1, ex.labels)
    other = style_set_of([EXS[1], EXS[0]])
    assert other.inputs_hash != sset.inputs_hash
    with pytest.raises(ValueError, match="does not hold the run's exemplars"):
        QuiltTeacher(EXS, other)


def test_distill_target_is_quilts_output_on_the_drawn_content(teacher):
    cfg = _cfg()
    for it, r in ((0, 0), (5, 1)):
        s = distill_sample(teacher, cfg, AUG, 3, it, r)
        content = augmented_sample(EXS, cfg, AUG, 3, it * 8 + r, stream=STREAM_CONTENT)
        # the input is the drawn content's coarse grid, unchanged
        np.testing.assert_array_equal(s.coarse_occupancy, content.coarse_occupancy)
        np.testing.assert_array_equal(s.coarse_labels, content.coarse_labels)
        assert s.assignment == content.assignment and s.sources[-1] == "quilt"
        # the target is a separately made quilt's output on that grid, with the drawn seed
        seed = int(rng_for(3, it, STREAM_QUILT + r).integers(2**31 - 1))
        quilt = QuiltDetailizer(style_set=style_set_of(EXS))
        expected = quilt.detailize(teacher.grid(content), seed=seed).occupancy > ISO_LEVEL
        np.testing.assert_array_equal(s.fine_labels != EMPTY, expected)
        assert expected.any() and not np.array_equal(expected, content.fine_labels != EMPTY)
        # labelled by the coarse cells' parts; every occupied cell keeps material, none outside
        f = cfg.factor
        up = np.repeat(np.repeat(np.repeat(content.coarse_labels, f, 0), f, 1), f, 2)
        np.testing.assert_array_equal(s.fine_labels[expected], up[expected])
        np.testing.assert_array_equal(max_pool(expected, f), s.coarse_occupancy)
        # targets are made from the new fine shape
        assert not np.array_equal(s.target(cfg.n_levels - 1), content.target(cfg.n_levels - 1))


def test_distill_draws_are_a_function_of_seed_step_and_substep(teacher):
    cfg = _cfg()
    a = distill_sample(teacher, cfg, AUG, 3, 7, 2)
    b = distill_sample(QuiltTeacher(EXS), cfg, AUG, 3, 7, 2)  # a fresh teacher: nothing kept between draws
    np.testing.assert_array_equal(a.fine_labels, b.fine_labels)
    assert a.assignment == b.assignment
    others = [distill_sample(teacher, cfg, AUG, *k) for k in ((4, 7, 2), (3, 8, 2), (3, 7, 3))]
    assert all(not np.array_equal(a.fine_labels, o.fine_labels) or a.assignment != o.assignment for o in others)
    # never the adversarial step's content of the same iteration
    adv = augmented_sample(EXS, cfg, AUG, 3, 7 * 8 + 2)
    assert adv.coarse_occupancy.shape != a.coarse_occupancy.shape or not np.array_equal(
        adv.coarse_occupancy, a.coarse_occupancy)


def test_is_distilled_draws_the_fraction():
    draws = [is_distilled(0, it, 0, 0.5) for it in range(400)]
    assert 0.4 < np.mean(draws) < 0.6
    assert draws == [is_distilled(0, it, 0, 0.5) for it in range(400)]
    assert not any(is_distilled(0, it, 0, 0.0) for it in range(50))
    assert all(is_distilled(0, it, 1, 1.0) for it in range(50))


def test_trainer_uses_distilled_targets_at_the_drawn_steps(tmp_path):
    cfg = _cfg()
    tcfg = _tcfg(tmp_path, 1, distill_frac=0.5)
    tr = Trainer(EXS, cfg, tcfg)
    for it in range(6):
        s, distilled = tr.reconstruction_sample(it, 0)
        assert distilled == is_distilled(3, it, 0, 0.5)
        if distilled:
            ref = distill_sample(tr.teacher, cfg, tr.aug, 3, it, 0)
            np.testing.assert_array_equal(s.fine_labels, ref.fine_labels)
            assert s.sources[-1] == "quilt"
        else:
            style = int(rng_for(3, it, 100).integers(cfg.n_styles))
            np.testing.assert_array_equal(s.fine_labels, style_sample(EXS, style, cfg, tr.aug, 3, it * 8).fine_labels)
    assert Trainer(EXS, cfg, _tcfg(tmp_path, 1)).teacher is None  # no quilt without distillation
    assert 0 < sum(is_distilled(3, it, 0, 0.5) for it in range(6)) < 6  # both kinds were exercised


def test_distilled_run_resumes_exactly(tmp_path):
    kw = dict(distill_frac=1.0, warmup_iters=1, recon_steps_early=1)
    res = train(EXS, _cfg(), _tcfg(tmp_path, 2, **kw), resume=False)
    log = _log(res.log)
    assert [row["distilled"] for row in log] == [1.0, 1.0] and all(np.isfinite(row["recon"]) for row in log)
    assert "gan" in log[1] and "gan" not in log[0]  # a warm-up iteration, then a full one
    res3 = train(EXS, _cfg(), _tcfg(tmp_path, 3, **kw))
    ref = train(EXS, _cfg(), dataclasses.replace(_tcfg(tmp_path, 3, **kw), out_dir=str(tmp_path / "ref")),
                resume=False)
    assert [r["recon"] for r in _log(res3.log)] == [r["recon"] for r in _log(ref.log)]
    a, b = load_checkpoint(res3.checkpoint).generator, load_checkpoint(ref.checkpoint).generator
    for k in a:
        torch.testing.assert_close(a[k], b[k], rtol=1e-5, atol=1e-6)


def test_distill_recipe_is_warmup_plus_distillation():
    cfg, tcfg = ModelConfig.lean(2, 2), TrainConfig(out_dir="x", steps=1, recipe="distill")
    wm, wt = recipe_configs("warmup", cfg, tcfg)
    dm, dt = recipe_configs("distill", cfg, tcfg)
    assert dm == wm and dt == dataclasses.replace(wt, distill_frac=DISTILL_FRAC) and 0 < DISTILL_FRAC < 1
    assert wt.distill_frac == 0
    with pytest.raises(Exception, match="distill_frac"):
        TrainConfig(out_dir="x", steps=1, distill_frac=1.5)


def test_monitor_quilt_iou_compares_with_quilts_output_in_the_same_style(teacher):
    from model.monitor import Monitor, detailize_sample
    from model.networks import Generator

    cfg = _cfg()
    torch.manual_seed(0)
    gen = Generator(cfg)
    plain = Monitor(EXS, cfg, AUG).figures(gen)
    mon = Monitor(EXS, cfg, AUG, teacher)
    fig = mon.figures(gen)
    assert "quilt_iou" not in plain and {k: v for k, v in fig.items() if "quilt" not in k} == plain
    assert 0 < fig["upsample_quilt_iou"] < 1
    c, a, b = mon._inputs()[1][0]
    grid = teacher.grid(c)
    style = np.where(grid.occupancy, a, EMPTY).astype(np.int16)
    quilt = QuiltDetailizer(style_set=style_set_of(EXS)).detailize(dataclasses.replace(grid, style=style), seed=0)
    np.testing.assert_array_equal(mon.quilt_output(0, a), quilt.occupancy > ISO_LEVEL)
    ious = []
    for k, (c, a, b) in enumerate(mon._inputs()[1]):
        for st in (a, b):
            out = detailize_sample(gen, c, np.full(c.coarse_occupancy.shape, st, dtype=np.int64))
            q = mon.quilt_output(k, st)
            ious.append(np.count_nonzero(out & q) / np.count_nonzero(out | q))
    assert fig["quilt_iou"] == round(float(np.mean(ious)), 4) and 0 < fig["quilt_iou"] < 1

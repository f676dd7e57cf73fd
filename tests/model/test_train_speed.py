"""The training speed-ups that must not change a run: fixed-placement style samples made once, and
adversarial contents made ahead in worker processes (``model.prefetch``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from model.data import augmented_sample, rng_for, style_sample
from model.prefetch import ContentPrefetcher
from model.train import Trainer, train
from model.views import surface_window
from tests.model.test_train import EXS, _cfg, _log, _tcfg

LOSS_KEYS = ("recon", "gan", "down", "up", "g_total", "d_real", "d_fake", "d_total")


def test_a_fixed_placement_makes_each_style_sample_once_with_the_same_window_targets(tmp_path):
    cfg = _cfg()
    trainer = Trainer(EXS, cfg, _tcfg(tmp_path, 1, style_offset="centre"))
    kept = trainer.style_sample(1, 5)
    assert trainer.style_sample(1, 77) is kept  # another draw, the same sample
    fresh = style_sample(EXS, 1, cfg, trainer.aug, 3, 77)
    np.testing.assert_array_equal(kept.fine_labels, fresh.fine_labels)
    rng = rng_for(0, 0, 9)
    for _ in range(3):
        w = surface_window(fresh.coarse_occupancy, 2, rng)
        for j in cfg.supervised_levels:  # a cut of the kept whole target = a window smoothed with its halo
            np.testing.assert_array_equal(kept.target(j, w), fresh.target(j, w))
    # a random placement draws a new sample every time
    random = Trainer(EXS, cfg, _tcfg(tmp_path, 1))
    assert random.style_sample(1, 5) is not random.style_sample(1, 5)


def test_prefetched_contents_are_the_samples_of_their_iterations():
    cfg = _cfg()
    aug = _tcfg(Path("unused"), 1).augment()
    with ContentPrefetcher(EXS, cfg, aug, seed=3, workers=2, ahead=3) as pre:
        for it in (0, 1, 2, 6):  # 6: a jump forgets what was queued for 3-5
            got = pre.get(it, stop=8)
            ref = augmented_sample(EXS, cfg, aug, 3, it)
            np.testing.assert_array_equal(got.fine_labels, ref.fine_labels)
            assert got.assignment == ref.assignment and got.sources == ref.sources
            assert max(pre._pending, default=it) <= min(7, it + 3)  # bounded, never past stop
        # a fixed placement's style samples, made by the workers with their whole targets
        fixed = _tcfg(Path("unused"), 1, style_offset="centre").augment()
    with ContentPrefetcher(EXS, cfg, fixed, seed=3, workers=2) as pre:
        made = pre.style_samples([1, 0])
    for style, s in zip([1, 0], made):
        ref = style_sample(EXS, style, cfg, fixed, 3, 0)
        np.testing.assert_array_equal(s.fine_labels, ref.fine_labels)
        for j in cfg.supervised_levels:
            assert j in s.__dict__["_whole_targets"]  # travelled with the sample
            np.testing.assert_array_equal(s.target(j), ref.target(j))


def test_a_run_with_data_workers_logs_the_same_losses(tmp_path):
    logs = []
    for workers in (0, 2):
        res = train(EXS, _cfg(), _tcfg(tmp_path / str(workers), 3, data_workers=workers, style_offset="centre"),
                    resume=False)
        logs.append(_log(res.log))
    assert [r["step"] for r in logs[1]] == [1, 2, 3]
    for a, b in zip(*logs):
        assert {k: a[k] for k in LOSS_KEYS} == {k: b[k] for k in LOSS_KEYS}


def test_distilled_samples_made_by_the_workers_are_the_trainers_own(tmp_path):
    from model.distill import distill_sample, is_distilled

    tr = Trainer(EXS, _cfg(), _tcfg(tmp_path, 6, distill_frac=0.5, data_workers=1, warmup_iters=0,
                                    recon_steps_early=2, recon_early_iters=6))
    assert tr.distilled_steps(2) == [r for r in range(2) if is_distilled(3, 2, r, 0.5)]
    tr.start_workers()
    try:
        assert tr.prefetch is not None
        seen = 0
        for it in range(4):
            tr.adversarial_content(it)  # queues the distilled samples of the iterations ahead
            for r in tr.distilled_steps(it):
                made = tr.reconstruction_sample(it, r)[0]
                ref = distill_sample(tr.teacher, tr.cfg, tr.aug, 3, it, r)
                np.testing.assert_array_equal(made.fine_labels, ref.fine_labels)
                np.testing.assert_array_equal(made.coarse_labels, ref.coarse_labels)
                seen += 1
        assert seen > 0  # the draw exercised at least one distilled step
    finally:
        tr.prefetch.close()
    assert Trainer(EXS, _cfg(), _tcfg(tmp_path, 1)).distilled_steps(0) == []


def test_a_distilled_run_with_data_workers_logs_the_same_losses(tmp_path):
    logs = []
    for workers in (0, 1):
        kw = dict(data_workers=workers, distill_frac=1.0, warmup_iters=0, recon_steps_early=1)
        logs.append(_log(train(EXS, _cfg(), _tcfg(tmp_path / str(workers), 2, **kw), resume=False).log))
    assert [r["distilled"] for r in logs[1]] == [1.0, 1.0]
    for a, b in zip(*logs):
        assert {k: a[k] for k in LOSS_KEYS} == {k: b[k] for k in LOSS_KEYS}

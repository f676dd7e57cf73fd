"""The generator's weight average (``TrainConfig.ema_decay``): it observes a run, resumes exactly, ships beside it."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from core.errors import DetailizeError
from model.checkpoint import load_checkpoint
from model.train import Trainer, train
from tests.model.test_train import EXS, _cfg, _tcfg

BETA = 0.9


def _weights(module: torch.nn.Module) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone() for k, v in module.state_dict().items()}


def _same(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_the_average_follows_its_recurrence_and_leaves_the_run_unchanged(tmp_path):
    plain = Trainer(EXS, _cfg(), _tcfg(tmp_path, 3))
    averaged = Trainer(EXS, _cfg(), _tcfg(tmp_path, 3, ema_decay=BETA))
    assert plain.gen_ema is None and averaged.gen_ema is not None
    expected = _weights(averaged.gen)  # the average starts at the initial weights
    for _ in range(3):
        plain.iteration()
        averaged.iteration()
        now = _weights(averaged.gen)
        expected = {k: BETA * expected[k] + (1 - BETA) * now[k] for k in now}
    assert _same(_weights(plain.gen), _weights(averaged.gen))  # the same steps: the average only observes
    ema = _weights(averaged.gen_ema)
    for k in ema:
        torch.testing.assert_close(ema[k], expected[k], rtol=1e-5, atol=1e-6)
    assert not _same(ema, _weights(averaged.gen))  # and it is not the last weights


def test_a_resumed_average_equals_the_unbroken_one_and_ships_as_model_ema(tmp_path):
    whole = train(EXS, _cfg(), _tcfg(tmp_path / "a", 3, ema_decay=BETA), resume=False)
    train(EXS, _cfg(), _tcfg(tmp_path / "b", 2, ema_decay=BETA), resume=False)
    resumed = train(EXS, _cfg(), _tcfg(tmp_path / "b", 3, ema_decay=BETA))
    a = load_checkpoint(whole.checkpoint, training_state=True)
    b = load_checkpoint(resumed.checkpoint, training_state=True)
    assert a.generator_ema is not None and _same(a.generator_ema, b.generator_ema)
    assert a.training["ema_started_at"] == b.training["ema_started_at"] == 0
    shipped = load_checkpoint(resumed.model_ema)  # an inference file like model.pt, of the average
    assert _same(shipped.generator, b.generator_ema) and not _same(shipped.generator, b.generator)
    assert shipped.training["weights"] == {"ema_decay": BETA, "ema_started_at": 0}
    assert load_checkpoint(resumed.model).generator_ema is None  # model.pt stays the last weights
    assert train(EXS, _cfg(), _tcfg(tmp_path / "c", 1), resume=False).model_ema is None


def test_a_state_without_an_average_starts_one_at_its_own_step(tmp_path):
    first = train(EXS, _cfg(), _tcfg(tmp_path, 2), resume=False)  # no average kept
    w2 = load_checkpoint(first.checkpoint, training_state=True)
    assert w2.generator_ema is None and "ema_started_at" not in w2.training
    w2 = w2.generator
    res = train(EXS, _cfg(), _tcfg(tmp_path, 3, ema_decay=BETA))
    ck = load_checkpoint(res.checkpoint, training_state=True)
    assert ck.training["ema_started_at"] == 2
    for k, w3 in ck.generator.items():  # one update from the step-2 weights: β·w2 + (1 − β)·w3
        torch.testing.assert_close(ck.generator_ema[k], BETA * w2[k] + (1 - BETA) * w3, rtol=1e-5, atol=1e-6)
    restored = Trainer(EXS, _cfg(), _tcfg(tmp_path, 3))
    restored.restore(res.checkpoint)
    assert restored.gen_ema is None  # resumed without an average: the kept one is not carried
    off = train(EXS, _cfg(), _tcfg(tmp_path, 4))
    assert load_checkpoint(off.checkpoint, training_state=True).generator_ema is None
    with pytest.raises(ValueError, match="EMA checkpoint"):
        restored.checkpoint(full=False, ema=True)


@pytest.mark.parametrize("bad", [1.0, -0.1])
def test_a_decay_outside_zero_to_one_is_refused(tmp_path, bad):
    with pytest.raises(DetailizeError, match="ema_decay"):
        _tcfg(tmp_path, 1, ema_decay=bad)
    assert dataclasses.replace(_tcfg(tmp_path, 1), ema_decay=0.5).ema_decay == 0.5

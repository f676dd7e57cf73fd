"""Adversarial contents made ahead in worker processes: the same samples, sooner.

The adversarial step's content is a pure function of (seed, iteration)
(``model.data.augmented_sample``): augmenting, combining and resampling a 256³ exemplar
takes 0.1–1.2 s of numpy per iteration (Intel Xeon, one core), which on a GPU is most of
an iteration. ``ContentPrefetcher`` computes the contents of the next iterations in a
pool of worker processes while the trainer works; each result is the sample the trainer
would have made itself, so a run with workers draws exactly what a run without them does.

The pool uses the ``spawn`` start method (a CUDA context must not be forked); workers
receive the exemplars and configs once. At most ``ahead`` contents are queued or held,
so memory stays bounded (one content is at most ~R³ int16, 32 MiB at R = 256).
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Sequence
from multiprocessing.pool import AsyncResult
from typing import Any

from model.config import ModelConfig
from model.data import AugmentConfig, Exemplar, Sample, augmented_sample, style_sample

_WORKER: dict[str, Any] = {}


def _init(exemplars: Sequence[Exemplar], cfg: ModelConfig, aug: AugmentConfig, seed: int) -> None:
    _WORKER.update(exemplars=list(exemplars), cfg=cfg, aug=aug, seed=seed)


def _content(it: int) -> Sample:
    w = _WORKER
    return augmented_sample(w["exemplars"], w["cfg"], w["aug"], w["seed"], it)


def _style_with_targets(style: int) -> Sample:
    w = _WORKER
    s = style_sample(w["exemplars"], style, w["cfg"], w["aug"], w["seed"], 0)
    return s.keep_targets(w["cfg"].supervised_levels)


class ContentPrefetcher:
    """Iteration ``it``'s adversarial content (``augmented_sample(…, seed, it)``), made ahead by worker processes.

    ``get(it, stop)`` returns the content of ``it`` and queues those of ``it + 1`` … up to
    ``it + ahead`` (never ``stop`` or beyond). Use as a context manager, or ``close()``.
    """

    def __init__(self, exemplars: Sequence[Exemplar], cfg: ModelConfig, aug: AugmentConfig, seed: int,
                 workers: int, ahead: int | None = None) -> None:
        if workers < 1:
            raise ValueError("a prefetcher needs at least one worker")
        self.ahead = ahead if ahead is not None else 2 * workers
        self._pool = mp.get_context("spawn").Pool(workers, initializer=_init,
                                                  initargs=(list(exemplars), cfg, aug, seed))
        self._pending: dict[int, AsyncResult] = {}

    def get(self, it: int, stop: int) -> Sample:
        for stale in [k for k in self._pending if k < it]:  # a jump (not in a normal run): forget older ones
            del self._pending[stale]
        for k in range(it, max(it + 1, min(stop, it + self.ahead + 1))):
            if k not in self._pending:
                self._pending[k] = self._pool.apply_async(_content, (k,))
        return self._pending.pop(it).get()

    def style_samples(self, styles: Sequence[int]) -> list[Sample]:
        """``style_sample`` of each style at draw 0 with its whole targets of every supervised level, in parallel.

        Only for a fixed placement (``aug.style_offset`` set), where the draw does not matter:
        ``Trainer.style_sample``'s kept samples, made at once instead of one per new style
        (about 3 s each at R = 256 on one core).
        """
        return self._pool.map(_style_with_targets, list(styles), chunksize=1)

    def close(self) -> None:
        self._pool.terminate()
        self._pool.join()
        self._pending.clear()

    def __enter__(self) -> "ContentPrefetcher":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

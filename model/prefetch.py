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

With distillation (``TrainConfig.distill_frac`` > 0) the workers also make the distilled
reconstruction samples of the coming iterations (``model.distill.distill_sample``: an
augmented content and quilt's output on it, 0.5–0.9 s of CPU each at R = 256), which in the
training process would leave a GPU idle for most of an iteration. Each worker builds its own
``QuiltTeacher`` once (about 8 s at R = 256; the set's quilt statistics are cached on disk).
Which (iteration, step) pairs are distilled is the trainer's to say (``distilled_steps``);
the samples are the ones it would have made itself.
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Callable, Sequence
from multiprocessing.pool import AsyncResult
from typing import Any

from model.config import ModelConfig
from model.data import AugmentConfig, Exemplar, Sample, augmented_sample, style_sample
from model.distill import QuiltTeacher, distill_sample
from stylesets.format import StyleSet

_WORKER: dict[str, Any] = {}


def _init(exemplars: Sequence[Exemplar], cfg: ModelConfig, aug: AugmentConfig, seed: int, distill: bool,
          teacher_set: StyleSet | None) -> None:
    _WORKER.update(exemplars=list(exemplars), cfg=cfg, aug=aug, seed=seed,
                   teacher=QuiltTeacher(exemplars, teacher_set) if distill else None)


def _content(it: int) -> Sample:
    w = _WORKER
    return augmented_sample(w["exemplars"], w["cfg"], w["aug"], w["seed"], it)


def _distilled(it: int, r: int) -> Sample:
    w = _WORKER
    return distill_sample(w["teacher"], w["cfg"], w["aug"], w["seed"], it, r)


def _style_with_targets(style: int) -> Sample:
    w = _WORKER
    s = style_sample(w["exemplars"], style, w["cfg"], w["aug"], w["seed"], 0)
    return s.keep_targets(w["cfg"].supervised_levels)


class ContentPrefetcher:
    """Iteration ``it``'s adversarial content (``augmented_sample(…, seed, it)``), made ahead by worker processes.

    ``get(it, stop)`` returns the content of ``it`` and queues those of ``it + 1`` … up to
    ``it + ahead`` (never ``stop`` or beyond), with the distilled samples of those iterations
    when ``distilled_steps`` is given (it → the reconstruction steps r of iteration it that are
    distilled); ``distilled(it, r)`` returns one. Use as a context manager, or ``close()``.
    """

    def __init__(self, exemplars: Sequence[Exemplar], cfg: ModelConfig, aug: AugmentConfig, seed: int,
                 workers: int, ahead: int | None = None,
                 distilled_steps: Callable[[int], Sequence[int]] | None = None,
                 teacher_set: StyleSet | None = None) -> None:
        if workers < 1:
            raise ValueError("a prefetcher needs at least one worker")
        self.ahead = ahead if ahead is not None else 2 * workers
        self._distilled_steps = distilled_steps
        self._pool = mp.get_context("spawn").Pool(
            workers, initializer=_init,
            initargs=(list(exemplars), cfg, aug, seed, distilled_steps is not None, teacher_set))
        self._pending: dict[int, AsyncResult] = {}
        self._pending_distilled: dict[tuple[int, int], AsyncResult] = {}

    def get(self, it: int, stop: int) -> Sample:
        for stale in [k for k in self._pending if k < it]:  # a jump (not in a normal run): forget older ones
            del self._pending[stale]
        for stale in [k for k in self._pending_distilled if k[0] < it]:
            del self._pending_distilled[stale]
        for k in range(it, max(it + 1, min(stop, it + self.ahead + 1))):
            if k not in self._pending:
                self._pending[k] = self._pool.apply_async(_content, (k,))
                for r in self._distilled_steps(k) if self._distilled_steps is not None else ():
                    self._pending_distilled[(k, r)] = self._pool.apply_async(_distilled, (k, r))
        return self._pending.pop(it).get()

    def distilled(self, it: int, r: int) -> Sample:
        """``distill_sample(…, seed, it, r)`` made by a worker (queued by ``get``; made now if it was not)."""
        if self._distilled_steps is None:
            raise ValueError("this prefetcher makes no distilled samples (no distilled_steps given)")
        pending = self._pending_distilled.pop((it, r), None)
        return (pending if pending is not None else self._pool.apply_async(_distilled, (it, r))).get()

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

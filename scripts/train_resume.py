"""Continue a training run from its ``last.pt`` with only the budget changed (device, steps, time box).

    python scripts/train_resume.py RUN_DIR --set SET.npz --steps N [--device cuda] [--minutes 9]
                                   [--checkpoint-every 50] [--data-workers 8] [--monitor-every 250]
                                   [--ema-decay 0.995]

Everything that defines the run — model config, recipe and ablation labels, seed,
resolution, windows, learning rates — is read from ``RUN_DIR/last.pt``'s training meta,
so the run continues exactly as ``decollage train`` would (iteration i draws its data
from (seed, i); weights, optimizers and RNG are restored). Only ``--steps``,
``--device``, ``--checkpoint-every``, ``--data-workers`` (processes that make the adversarial
contents ahead: the same samples; not read from the state, whose value was another machine's),
``--monitor-every`` (the log's quick figures), ``--ema-decay`` (the generator's weight average,
``TrainConfig.ema_decay``: it observes the run and changes none of its steps; the state's own value
when not given) and the time box change. It imports only torch,
numpy, scipy and this repo's ``model``/``stylesets``/``core`` code, so it runs on a
machine that has those (a lent GPU's image) from a plain checkout with
``PYTHONPATH=.``; the set is read from its ``.npz`` file (``decollage styles build``
makes it where the full install is). ``scripts/train_gpu.sh`` wraps it for a lent GPU.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

from model.checkpoint import load_checkpoint
from model.data import exemplars_from_set
from model.train import TrainConfig, train
from stylesets.format import load_set


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--set", type=Path, required=True, help="the style set's .npz file")
    ap.add_argument("--steps", type=int, required=True)
    ap.add_argument("--device", default="auto")
    ap.add_argument("--minutes", type=float, default=None, help="stop (saving last.pt) after this long")
    ap.add_argument("--checkpoint-every", type=int, default=None)
    ap.add_argument("--data-workers", type=int, default=0,
                    help="processes making contents ahead (default 0: none; a machine's budget, not the run's)")
    ap.add_argument("--monitor-every", type=int, default=None, help="iterations between the monitor's figures")
    ap.add_argument("--ema-decay", type=float, default=None,
                    help="keep a moving average of the generator's weights with this β (0: none; default: the state's)")
    a = ap.parse_args()
    ck = load_checkpoint(a.run / "last.pt", training_state=True)
    tcfg = TrainConfig.recorded(ck.training["train_config"])
    tcfg = dataclasses.replace(tcfg, out_dir=str(a.run), steps=a.steps, device=a.device,
                               checkpoint_every=a.checkpoint_every or tcfg.checkpoint_every, preview_every=0,
                               data_workers=a.data_workers,
                               monitor_every=tcfg.monitor_every if a.monitor_every is None else a.monitor_every,
                               ema_decay=tcfg.ema_decay if a.ema_decay is None else a.ema_decay)
    sset = load_set(a.set)
    exemplars = exemplars_from_set(sset)
    t0 = time.time()

    def progress(step: int, total: int, losses: dict[str, float]) -> None:
        if step % 10 == 0 or step == total:
            print(f"step {step}/{total} {time.time() - t0:.0f}s "
                  + " ".join(f"{k} {v:.4f}" for k, v in losses.items()), flush=True)

    res = train(exemplars, ck.config, tcfg, part_aliases=dict(ck.part_aliases), progress=progress,
                style_set=ck.training.get("style_set"), stop_after_s=None if a.minutes is None else 60 * a.minutes,
                teacher_set=sset)
    print(f"stopped at step {res.step}; {res.seconds_per_iteration:.3f} s/iteration this session; "
          f"{res.checkpoint}, {res.model}, {res.model_ema or 'no EMA'}, {res.log}", flush=True)


if __name__ == "__main__":
    main()

"""Can the generator descend the nearest-patch style classification at all? An overfit probe of the term alone.

    .venv/bin/python scripts/contrast_overfit.py runs/R/last.pt [--set things] [--steps 150] [--lr 1e-4]

Restores a training state whose recipe has ``texture_contrast`` > 0 and takes the adversarial content of its
next iteration, one view of it. Then, on that fixed view, it runs ``--steps`` Adam steps of the generator on
``PatchContrast`` alone (summed over the state's texture levels). Every step uses a fresh random generator
seeded 0, so the library draws are the same each time; the output patches are drawn from the output's own band
with that stream, so they move only as the band moves with G. It prints the loss every 10 steps,
with chance (levels × ln N) for reference. No discriminator, no structure terms: if the loss does not fall
below chance here, the term cannot teach the style in training either. Nothing is saved.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch

from model.checkpoint import load_checkpoint
from model.data import exemplars_from_set
from model.texture_stats import PatchContrast
from model.train import TrainConfig, Trainer
from stylesets.registry import resolve_style_set


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("state")
    ap.add_argument("--set", default="things", help="style set name or .npz file")
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--lr", type=float, default=1e-4)
    a = ap.parse_args()
    torch.set_num_threads(1)
    ck = load_checkpoint(a.state, training_state=True)
    tcfg = TrainConfig.recorded(ck.training["train_config"], out_dir="/tmp/contrast_overfit", preview_every=0,
                                monitor_every=0, data_workers=0, device="cpu")
    sset = resolve_style_set(a.set)
    trainer = Trainer(exemplars_from_set(sset), ck.config, tcfg, dict(ck.part_aliases), sset)
    trainer.restore(a.state)
    lc, levels = ck.config.losses, ck.config.supervised_levels
    if lc.texture_contrast <= 0:
        raise SystemExit(f"{a.state}: its recipe has no texture_contrast")
    it = trainer.step
    (view,) = trainer._views(trainer.adversarial_content(it), it, 300)
    term, charged = PatchContrast(lc), range(lc.style_classifier_from, len(levels))
    real = {k: trainer.bank.targets[levels[k]] for k in charged}
    chance = len(charged) * math.log(len(real[charged[0]]))
    opt = torch.optim.Adam([p for p in trainer.gen.parameters() if p.requires_grad], lr=a.lr, betas=tcfg.betas)
    t0 = time.time()
    for step in range(a.steps + 1):
        rng = np.random.default_rng(0)
        (outs,) = trainer._forward([view])
        loss = sum(term(outs[k], view.output_styles(levels[k]), real[k], rng) for k in charged)
        if step % 10 == 0:
            print(f"step {step}: contrast {float(loss.detach()):.3f} (chance {chance:.3f}) {time.time() - t0:.0f}s",
                  flush=True)
        if step < a.steps:
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()


if __name__ == "__main__":
    main()

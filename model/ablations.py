"""Named ablation configs matching the rows of the DECOLLAGE paper's Table 4, for ``decollage eval``.

Each entry changes the full model's ``ModelConfig`` / ``TrainConfig`` in one
way; ``ablation_configs(name, cfg, tcfg)`` returns the pair to train with.
Training them is not done here: ``scripts/train_ablations.sh`` trains every row
at one reduced budget (``decollage train --ablation NAME``, which records the
name in the checkpoint's training meta) and ``benchmarks/eval_ablations.py``
evaluates and tabulates them; docs/benchmarks.md has the rows at 150
iterations, R = 128.

The pyramid rows (``ModelConfig.pyramid``; paper Table 4 (a) vs (b)–(i)):

- ``no_pyramid``: only the pyramid removed, as every other entry removes one
  thing: the generator still doubles four times but only the ×16 level has a
  head, is reconstructed and is judged, by one discriminator (the last level's,
  RF 18). L_down/L_up are kept, comparing the ×16 output with the coarse input
  (max-pool ×16 / nearest ×16), and so is adaptive α: the row measures the
  pyramid alone.
- ``decor_gan``: the DECOR-GAN* baseline as the paper ran it (Table 4 (a) is
  labelled "P ✗ (DECOR-GAN*)"; DECOR-GAN's published code): the same single ×16
  generator and one discriminator, no structure-preserving losses (they are
  defined between pyramid levels; γ_down = γ_up = 0), one style-head weight
  α2 everywhere (DECOR-GAN's α, no adaptive α), and per-region styles through
  the same random per-part style assignment, data and budget as the full model.
  Not reproduced: DECOR-GAN's own generator widths and its hard output mask
  (dilated coarse occupancy), its near-surface style D-mask and its D-first
  step order; the shared generator layout keeps the comparison about the
  pyramid and the losses.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Callable

from model.config import DownLoss, ModelConfig, TargetSmoothing

if TYPE_CHECKING:  # the names are read by the CLI at start-up: keep this module light
    from model.train_config import TrainConfig

#: name → (Table 4 row, change). The change takes and returns (ModelConfig, TrainConfig).
ABLATIONS: dict[str, tuple[str, Callable[[ModelConfig, TrainConfig], tuple[ModelConfig, TrainConfig]]]] = {
    "full": ("full model (code-variant losses)", lambda m, t: (m, t)),
    "no_down": ("w/o L_down (γ_down = 0)",
                lambda m, t: (dataclasses.replace(m, losses=dataclasses.replace(m.losses, gamma_down=0.0)), t)),
    "no_up": ("w/o L_up (γ_up = 0)",
              lambda m, t: (dataclasses.replace(m, losses=dataclasses.replace(m.losses, gamma_up=0.0)), t)),
    "no_adaptive_alpha": ("w/o adaptive α (α2 everywhere)",
                          lambda m, t: (m, dataclasses.replace(t, adaptive_alpha=False))),
    "paper_losses": ("paper-variant losses (MSE L_down, β = 1, one Gaussian target)",
                     lambda m, t: (dataclasses.replace(m, losses=dataclasses.replace(
                         m.losses, down_loss=DownLoss.PAPER_MSE, beta_recon=1.0,
                         target_smoothing=TargetSmoothing.GAUSSIAN)), t)),
    "no_part_labels": ("w/o part labels (no part one-hot inputs)",
                       lambda m, t: (dataclasses.replace(m, use_part_labels=False), t)),
    "no_pyramid": ("w/o pyramid (one ×16 level and one D; L_down/L_up against the coarse input)",
                   lambda m, t: (m.without_pyramid(), t)),
    "decor_gan": ("DECOR-GAN* baseline (no pyramid, no L_down/L_up, no adaptive α)",
                  lambda m, t: (dataclasses.replace(m.without_pyramid(), losses=dataclasses.replace(
                      m.losses, gamma_down=0.0, gamma_up=0.0)), dataclasses.replace(t, adaptive_alpha=False))),
}


def ablation_configs(name: str, cfg: ModelConfig, tcfg: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    """The (ModelConfig, TrainConfig) of ablation ``name`` built from the full model's; KeyError if unknown."""
    if name not in ABLATIONS:
        raise KeyError(f"unknown ablation {name!r}; known: {', '.join(ABLATIONS)}")
    return ABLATIONS[name][1](cfg, tcfg)

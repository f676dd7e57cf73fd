"""Named ablation configs matching the rows of the paper's Table 4 (method.md §7), for ``decollage eval``.

Each entry changes the full model's ``ModelConfig`` / ``TrainConfig`` in one
way; ``ablation_configs(name, cfg, tcfg)`` returns the pair to train with.
Training them is not done here (CPU budget); train each at the same reduced
budget and evaluate with ``decollage eval --checkpoint``.

Not expressible as a config yet: the "no pyramid" row (a single ×16
generator level with one discriminator needs a generator and a loss loop
without intermediate levels; it is the DECOR-GAN* baseline's layout).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

from model.config import DownLoss, ModelConfig, TargetSmoothing
from model.train import TrainConfig

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
}


def ablation_configs(name: str, cfg: ModelConfig, tcfg: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    """The (ModelConfig, TrainConfig) of ablation ``name`` built from the full model's; KeyError if unknown."""
    if name not in ABLATIONS:
        raise KeyError(f"unknown ablation {name!r}; known: {', '.join(ABLATIONS)}")
    return ABLATIONS[name][1](cfg, tcfg)

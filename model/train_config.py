"""The run settings of ``model.train`` (``TrainConfig``, validated where they are made) and what a run returns
(``TrainResult``). Model sizes and loss weights are ``model.config``'s; named recipes and ablations
(``model.recipes``, ``model.ablations``) build both.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from model.ablations import ABLATIONS
from model.data import CENTRE, AugmentConfig, parse_style_offset
from model.recipes import RECIPES
from core.errors import DetailizeError
from core.recipe import Device


@dataclass(frozen=True)
class TrainConfig:
    """Run settings (model sizes live in ``ModelConfig``).

    Attributes:
        out_dir: where checkpoints and the log go.
        steps: total iterations to reach (a resumed run continues up to this).
        seed: weights init + every data draw.
        lr, betas: Adam settings for G and D.
        recon_steps_early, recon_early_iters: reconstruction steps per iteration (4)
            during the first iterations (5000), then 1.
        recon_steps_late, recon_late_from: reconstruction steps per iteration from iteration
            ``recon_late_from`` on (0 = never; after the warm-up and the early phase). A schedule is a
            function of the iteration, so a state may take more reconstruction steps from its own
            step on without changing its history (``model.recipe_move``).
        checkpoint_every: iterations between ``last.pt`` saves.
        preview_every: iterations between sample previews (``previews/step_NNNNNN.png``,
            ``model.previews``; 0 = none, else also one at the end).
        resolution: R, fine grid edge the shapes are sized for (see ``model.train``'s docstring).
        whole_levels, window_cells: levels ``< whole_levels`` run on the whole shape, the
            finer ones on a random window of ``window_cells``³ coarse cells around the
            surface (``window_cells = 0``: every level on the whole shape).
        adaptive_alpha: α1 in part-joint cells (else α2 everywhere).
        device: a ``Device`` (its value, or ``"cuda:N"``, is accepted: ``infer.resolve_device``).
        style_lr_mult: the style codes' learning rate as a multiple of the generator's
            (their own Adam parameter group when ≠ 1): codes that start at zero and learn
            at 1e-4 hardly move, and styles separate only through them.
        warmup_iters: the first iterations are a supervised reconstruction warm-up: one
            reconstruction step each, no adversarial or discriminator step.
        warmup_lr: the generator's learning rate at the start of the warm-up, decayed to
            ``lr`` along a half cosine over ``warmup_iters`` (``lr`` afterwards).
        windows_per_step: fine-level windows per reconstruction step, sharing one trunk
            forward (``windows.windows_forward``); the loss is their mean.
        style_offset: where every exemplar sits relative to the coarse cells in its reconstruction
            steps, D's "real" and the monitor (``AugmentConfig.style_offset``): None = a random
            sub-cell offset per step (this project's first choice), ``"centre"`` = the
            reference's centre padding (one offset per exemplar), or 3 ints in [0, 16) (one
            offset for all: the overfit diagnostic).
        distill_frac: the fraction of reconstruction steps whose target is ``quilt``'s output on
            an augmented training content instead of an exemplar as itself
            (``model.distill``); 0 = none (the reference).
        data_workers: worker processes that make the adversarial contents of the next
            iterations ahead (``model.prefetch``); 0 = in the training process. The samples
            are the same either way, so it changes the time per iteration, not the run.
        ema_decay: β of an exponential moving average of the generator's weights, updated after
            every iteration (ema ← β·ema + (1 − β)·weights; 0 = none). It only observes the run:
            the steps and data are the same with or without it, so a resume may turn it on or
            off. Kept in ``last.pt`` and written as ``model_ema.pt`` beside ``model.pt``; a run
            resumed without one starts it at that step's weights (``ema_started_at`` in the meta).
            GAN generators oscillate from step to step (the monitor's raw self-reconstruction IOU
            of the fill run swung 0.78 → 0.81 in the 27 iterations 12,973 → 13,000, and the thin
            check's share of half-full cells 1.000 → 0.824 over the 960 after): an average over
            the last ~1/(1 − β) iterations is the usual remedy (the progressive GAN's and
            StyleGAN's generator averages).
        monitor_every: iterations between the quick figures of ``model.monitor``
            (self-reconstruction IOU, style overlap, coarse-cell fill) written to the log
            row of that step; 0 = never.
        command: the command line that started the run (recorded in checkpoints).
        ablation: name of the ``model.ablations`` row this run trains (``full`` = the model),
            recorded in the checkpoints' training meta; a resume must name the same one.
            It is a label: the caller builds the configs with ``ablation_configs``.
        recipe: name of the ``model.recipes`` recipe (a label recorded like ``ablation``; the
            caller builds the configs with ``recipe_configs``); a resume must name the same one.
    """

    out_dir: str
    steps: int
    seed: int = 0
    lr: float = 1e-4
    betas: tuple[float, float] = (0.9, 0.999)
    recon_steps_early: int = 4
    recon_early_iters: int = 5000
    recon_steps_late: int = 1
    recon_late_from: int = 0
    checkpoint_every: int = 100
    preview_every: int = 0
    resolution: int = 256
    whole_levels: int = 2
    window_cells: int = 4
    adaptive_alpha: bool = True
    device: Device | str = Device.AUTO
    command: str = ""
    ablation: str = "full"
    recipe: str = "reference"
    style_lr_mult: float = 1.0
    warmup_iters: int = 0
    warmup_lr: float = 1e-4
    windows_per_step: int = 1
    monitor_every: int = 0
    distill_frac: float = 0.0
    style_offset: tuple[int, int, int] | str | None = None
    data_workers: int = 0
    ema_decay: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "style_offset", parse_style_offset(self.style_offset))  # JSON gives a list
        if isinstance(self.device, str) and not isinstance(self.device, Device) and self.device in set(Device):
            object.__setattr__(self, "device", Device(self.device))
        checks = (
            (self.steps >= 0, "steps", "use 0 or more iterations"),
            # style-sample draws are indexed it·8 + r, so at most 8 reconstruction steps
            (1 <= self.recon_steps_early <= 8, "recon_steps_early", "use 1 to 8 (the reference: 4)"),
            (self.recon_early_iters >= 0, "recon_early_iters", "use 0 or more"),
            (1 <= self.recon_steps_late <= 8, "recon_steps_late", "use 1 to 8"),
            (self.recon_late_from >= 0, "recon_late_from", "use 0 (never) or the first iteration of the late phase"),
            (self.checkpoint_every >= 1, "checkpoint_every", "use 1 or more"),
            (self.preview_every >= 0, "preview_every", "use 0 (no previews) or more"),
            (self.resolution >= 16, "resolution", "use 256 (the paper) or 128"),
            (self.window_cells >= 0 and self.whole_levels >= 0, "window_cells", "use 0 (no windows) or ≥ 2"),
            (self.lr > 0, "lr", "the reference uses 1e-4"),
            (self.style_lr_mult > 0, "style_lr_mult", "1 = the generator's rate"),
            (self.warmup_iters >= 0, "warmup_iters", "use 0 (no warm-up) or more"),
            (self.warmup_lr > 0, "warmup_lr", "e.g. 1e-3"),
            (1 <= self.windows_per_step <= 16, "windows_per_step", "use 1 to 16"),
            (self.monitor_every >= 0, "monitor_every", "use 0 (never) or more"),
            (0 <= self.data_workers <= 64, "data_workers", "use 0 (in-process) to the machine's cores"),
            (0.0 <= self.distill_frac <= 1.0, "distill_frac", "a fraction: 0 (no distillation) to 1"),
            (0.0 <= self.ema_decay < 1.0, "ema_decay", "0 (no average) or e.g. 0.995 (about 200 iterations)"),
            (self.style_offset is None or self.style_offset == CENTRE
             or (len(self.style_offset) == 3 and min(self.style_offset) >= 0),
             "style_offset", f'"{CENTRE}", 3 sub-cell offsets in [0, 16), or None (random)'),
        )
        for ok, name, hint in checks:
            if not ok:
                raise DetailizeError(f"bad training setting {name} = {getattr(self, name)!r}", field=name, hint=hint)
        if self.recipe not in RECIPES:
            raise DetailizeError(f"unknown recipe {self.recipe!r}", field="recipe",
                                 hint="use one of: " + ", ".join(RECIPES))
        if self.ablation not in ABLATIONS:
            raise DetailizeError(f"unknown ablation {self.ablation!r}", field="ablation",
                                 hint="use one of: " + ", ".join(ABLATIONS))

    @classmethod
    def recorded(cls, settings: Mapping[str, Any], **changes: Any) -> TrainConfig:
        """The settings a training state recorded (``Checkpoint.training["train_config"]``, JSON: ``betas`` a list),
        then ``changes`` applied as ``dataclasses.replace`` would (each validated)."""
        tcfg = cls(**dict(settings, betas=tuple(settings["betas"])))
        return dataclasses.replace(tcfg, **changes) if changes else tcfg

    def reconstruction_steps(self, it: int) -> int:
        """Reconstruction steps of iteration ``it``: 1 in the warm-up, ``recon_steps_early`` until
        ``recon_early_iters``, ``recon_steps_late`` from ``recon_late_from`` (when > 0), else 1
        (``Trainer.iteration``; ``model.recipe_move`` compares recipes by it)."""
        if it < self.warmup_iters:
            return 1
        if it < self.recon_early_iters:
            return self.recon_steps_early
        if 0 < self.recon_late_from <= it:
            return self.recon_steps_late
        return 1

    def augment(self) -> AugmentConfig:
        return AugmentConfig(resolution=self.resolution, style_offset=self.style_offset)


@dataclass(frozen=True)
class TrainResult:
    """What ``train`` did: the final step, the files, the last losses and the mean time per iteration."""

    step: int
    checkpoint: Path
    model: Path
    log: Path
    last_losses: dict[str, float]
    seconds_per_iteration: float
    model_ema: Path | None = None

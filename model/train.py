"""DECOLLAGE training: one readable loop (the published code's iteration), resumable, seeded, CPU- or CUDA-feasible.

One iteration (``Trainer.iteration``):

1. **Reconstruction** — ``recon_steps_early`` (4) steps per iteration for the first
   ``recon_early_iters`` iterations, then 1 (``recon_steps_late`` from ``recon_late_from``
   on; ``TrainConfig.reconstruction_steps``): a random style shape as itself, every
   part in its own style; loss Σ_levels β·MSE(output, smoothed target); a G step.
   The last of these samples is the discriminators' "real" input. With
   ``distill_frac`` > 0 a step is, with that probability, an augmented content with
   quilt's output as its target instead (``model/distill.py``).
2. **Adversarial G step** — an augmented (maybe combined) content with a random
   per-part style assignment; masked LSGAN over all levels with adaptive α (0.1 in
   part-joint cells, 0.5 elsewhere) + γ_down·L_down + γ_up·L_up; a G step (the
   discriminators are frozen for it).
3. **D step** — per level, masked LSGAN on the real style shape's smoothed targets
   and the detached generated levels, with the fake masks built from the true
   per-part assignment at every level (the reference's bug fixed in ``losses``).

With the style classification terms on (``LossConfig.style_classifier`` / ``_g``, off in
the paper) the style heads of the levels from ``style_classifier_from`` on are also read
as softmax logits: step 2 charges G's output for each part's assigned style, step 3
trains D on a batch of real crops, one per style, cut from the windows that
``model/style_bank.py`` keeps from the reconstruction steps (a function of (seed, step): a
resume replays it), and ``style_classifier_d_steps`` − 1 classification-only D steps on
fresh crops follow it. With ``texture_weight`` > 0 step 2 also charges the same levels' surface
in each style against that style's bank window, placement-free (``model/texture_stats.py``).

Every loss comes from ``model/losses.py``'s assembly (``reconstruction_loss``,
``generator_adversarial_loss``, ``discriminator_loss_levels``), given the per-level
masks, α maps and previous grids that ``SampleView`` cuts to each level's cells.

Adam (lr 1e-4, betas 0.9/0.999) for G and one for all Ds; batch 1; variable,
non-cubic crops (bounding box + one empty coarse cell, ``model.data``).

**Cost: fine levels on windows.** Levels ``< whole_levels`` (32³/64³) run on the
whole shape; the finer ones (128³/256³) only on a random window of
``window_cells``³ coarse cells (4 → 64³ fine voxels) around a surface cell, their
features cut at the first windowed level with an exact halo (``window_forward``,
equal to the whole-shape run on the window) and every loss of those levels —
reconstruction targets, D inputs, D masks, α, L_down/L_up — cut to the same
cells (``SampleView``). The discriminators' "real" input is windowed the same way.
The output resolution is a setting too: ``TrainConfig.resolution`` R (256 = the
paper; 128 halves every side: shapes of at most 0.7·128 ≈ 90 fine voxels). The
network is fully convolutional and the factor stays 16, so a model trained at
R = 128 runs on any coarse grid; it has learnt detail at half the scale.

Measured on this 2-core CPU (lean layout, P = 2, N = 3, box exemplars; other jobs
shared the cores, load average 1–2), seconds per iteration after the early phase
(1 reconstruction step), sample preparation included:

====================  ==========  ==========
                      R = 128     R = 256
====================  ==========  ==========
whole shape, no crop  3.9–4.8     16–20
windows (default)     2.0–6.0     5.6–12.9
====================  ==========  ==========

At R = 256 with windows about 3 s of that is data (resampling's nearest-label fill,
target smoothing), i.e. worth a prefetch process or caching where cores allow.

**Files** in ``out_dir``: ``last.pt`` (full training state, every
``checkpoint_every`` iterations and at the end, written atomically),
``model.pt`` (generator only, for inference/shipping, at the end) and
``log.jsonl`` (one JSON object per iteration: step, seconds, every loss term).
Resuming (``resume=True`` and ``last.pt`` present) restores the step, all weights,
both optimizers and the torch RNG; the data of iteration ``i`` is a pure function
of (seed, i), so a resumed run draws exactly the samples an unbroken run would.

The CLI (``cli/train.py``)::

    decollage train --set things --out runs/things --steps 3000 [--resolution 128]
                    [--seed 0] [--device auto|cpu|cuda] [--layout lean|paper]
                    [--checkpoint-every 100] [--recon-early-iters 5000] [--no-resume]
                    [--ablation full|no_pyramid|decor_gan|...]
"""

from __future__ import annotations

import copy
import json
import math
import os
import platform
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from model.checkpoint import Checkpoint, load_checkpoint, save_checkpoint
from model.config import ModelConfig
from model.data import Exemplar, Sample, augmented_sample, rng_for, style_sample
from model.distill import QuiltTeacher, distill_sample, is_distilled
from model.infer import cpu_threads, resolve_device
from model.losses import (assigned_styles, discriminator_loss_levels, generator_adversarial_loss, real_style_targets,
                          reconstruction_loss, style_classification_loss)
from model.monitor import Monitor
from model.prefetch import ContentPrefetcher
from model.networks import Generator, build_discriminators
from model.previews import preview_samples, write_preview
from model.strict_json import to_plain
from model.style_bank import StyleCropBank, crop_edge
from model.texture_stats import PatchContrast, TextureTerm
from model.train_config import TrainConfig, TrainResult  # noqa: F401 - this module's API
from model.views import SampleView, check_window, surface_window
from model.windows import Window, halo_cells, window_forward, windows_forward  # noqa: F401 - this module's API
from core.errors import DetailizeError


def is_style_parameter(name: str) -> bool:
    """Whether a generator parameter belongs to the style pathway: the codes and the modulation maps."""
    return name == "style_codes" or name.startswith("style_films.")


def generator_param_groups(gen: Generator, style_lr_mult: float) -> list[dict[str, Any]]:
    """The generator's two Adam groups: every other parameter (lr × 1), then the style pathway (× ``style_lr_mult``).

    In the order of ``named_parameters``, the codes first in the second group, so a state written
    before the modulation maps existed keeps every index (``model.recipe_move`` appends the maps).
    """
    named = list(gen.named_parameters())
    return [{"params": [p for n, p in named if not is_style_parameter(n)], "lr_mult": 1.0},
            {"params": [p for n, p in named if is_style_parameter(n)], "lr_mult": style_lr_mult}]


#: Training-meta entries that record what was done to a state between runs (``model/recipe_move.py``,
#: ``scripts/style_heads.py warm``): a resumed run keeps them in its checkpoints.
HISTORY_KEYS = ("recipe_moved_from", "recipe_branched_from", "discriminators_reset_at", "generator_grown_at",
                "style_classifier_warmed")


class Trainer:
    """Networks, optimizers and the three steps of an iteration, on one device."""

    def __init__(self, exemplars: Sequence[Exemplar], cfg: ModelConfig, tcfg: TrainConfig,
                 part_aliases: dict[str, str] | None = None, teacher_set: Any = None) -> None:
        self.exemplars, self.cfg, self.tcfg, self.aug = list(exemplars), cfg, tcfg, tcfg.augment()
        # distillation's quilt over the run's set (teacher_set: its StyleSet; None: made from the exemplars)
        self.teacher = QuiltTeacher(self.exemplars, teacher_set) if tcfg.distill_frac > 0 else None
        self.teacher_set = teacher_set  # the prefetcher's workers build their own teacher from it
        self.part_aliases = dict(part_aliases or {})
        self.style_set: dict | None = None  # the set's provenance record, stored in checkpoints
        self.device = resolve_device(tcfg.device)
        if self.device.type == "cpu":
            torch.set_num_threads(cpu_threads())
        torch.manual_seed(tcfg.seed)
        self.gen = Generator(cfg).to(self.device)
        self.discs = build_discriminators(cfg).to(self.device)
        if self.device.type == "cpu":  # measured 1.3–2× faster convolutions on CPU
            self.gen.to(memory_format=torch.channels_last_3d)
            self.discs.to(memory_format=torch.channels_last_3d)
        if tcfg.style_lr_mult == 1.0:
            groups: Any = self.gen.parameters()
        else:  # the style pathway in its own group; "lr_mult" is kept in the group (and its saved state)
            groups = generator_param_groups(self.gen, tcfg.style_lr_mult)
        self.opt_g = torch.optim.Adam(groups, lr=tcfg.lr, betas=tcfg.betas)
        self.opt_d = torch.optim.Adam(self.discs.parameters(), lr=tcfg.lr, betas=tcfg.betas)
        self.gen_ema: Generator | None = None  # the weights' moving average (``ema_decay`` > 0)
        self.ema_started_at = 0
        self.history: dict[str, Any] = {}  # the restored state's ``HISTORY_KEYS``, carried into every checkpoint
        if tcfg.ema_decay > 0:
            self.gen_ema = copy.deepcopy(self.gen).requires_grad_(False).eval()
        self.whole_levels = min(max(tcfg.whole_levels, 0), cfg.n_levels) if tcfg.window_cells else cfg.n_levels
        check_window(cfg, self.whole_levels, tcfg.window_cells)
        self.step = 0
        self.wall_s = 0.0
        self._fixed_styles: dict[int, Sample] = {}  # style → its sample, when the placement is fixed
        self.prefetch: ContentPrefetcher | None = None  # set by ``train`` when ``data_workers`` > 0
        self.bank = self._style_bank()  # the style classification terms' real crops, or None (off)
        self.texture = TextureTerm(cfg.losses).to(self.device) if cfg.losses.texture_weight > 0 else None
        self.contrast = PatchContrast(cfg.losses).to(self.device) if cfg.losses.texture_contrast > 0 else None

    # ------------------------------------------------------------------ tensors

    def _inputs(self, s: Sample):
        occ = torch.from_numpy(s.coarse_occupancy)[None]
        parts = torch.from_numpy(s.coarse_labels.astype(np.int64))[None]
        styles = torch.from_numpy(s.style_index())[None]
        return self.gen.make_inputs(occ, parts, styles)

    def _views(self, s: Sample, it: int, stream: int, n: int = 1) -> list[SampleView]:
        """``n`` views of one sample, each with its own random surface window (one view, no window, when dense)."""
        if not (self.tcfg.window_cells and self.whole_levels < self.cfg.n_levels):
            return [SampleView(s, None, self.whole_levels, self.device)]
        rng = rng_for(self.tcfg.seed, it, stream)
        return [SampleView(s, surface_window(s.coarse_occupancy, self.tcfg.window_cells, rng), self.whole_levels,
                           self.device) for _ in range(n)]

    def _forward(self, views: Sequence[SampleView]) -> list[list[torch.Tensor]]:
        """Per view, the generator's supervised outputs (one trunk forward for all views of the sample)."""
        inputs = self._inputs(views[0].sample)
        if views[0].window is None:
            return [self.gen(*inputs)]
        return windows_forward(self.gen, *inputs, self.whole_levels, [v.window for v in views])

    def learning_rate(self, it: int) -> float:
        """The generator's learning rate at iteration ``it``: the warm-up's half-cosine decay, then ``lr``."""
        t = self.tcfg
        if it >= t.warmup_iters:
            return t.lr
        return t.lr + (t.warmup_lr - t.lr) * 0.5 * (1.0 + math.cos(math.pi * it / t.warmup_iters))

    def _set_lr(self, it: int) -> float:
        lr = self.learning_rate(it)
        for group in self.opt_g.param_groups:
            group["lr"] = lr * group.get("lr_mult", 1.0)
        return lr

    def _style_bank(self) -> StyleCropBank | None:
        """The bank of the classified levels, or None with both classification weights at 0.

        A crop's edge is ``style_classifier_crop`` at most the level's window (``window_cells``
        coarse cells at 2^(j+1) voxels each) where the level is windowed.
        """
        lc, t = self.cfg.losses, self.tcfg
        if max(lc.style_classifier, lc.style_classifier_g, lc.texture_weight, lc.texture_contrast) <= 0:
            return None
        levels = self.cfg.supervised_levels[lc.style_classifier_from:]
        cells = t.window_cells if self.whole_levels < self.cfg.n_levels else 0
        edges = [crop_edge(lc.style_classifier_crop, j, cells, self.whole_levels) for j in levels]
        return StyleCropBank(levels, edges, self.cfg.n_styles)

    def _bank_put(self, style: int, targets: dict[int, torch.Tensor]) -> None:
        """A reconstruction step drew ``style``: its first view's real targets (level j → (1, 1, …)) replace the
        style's windows in the bank."""
        if self.bank is not None:
            self.bank.put(style, targets)

    def _classification_d_loss(self, it: int, k: int) -> tuple[torch.Tensor, float]:
        """The k-th classification step of iteration ``it``: the classified levels' summed softmax cross-entropy
        of D's style heads on one real crop per style (cut with ``rng_for(seed, it, 400 + k)``), and the
        mean accuracy of their per-position argmax."""
        levels = self.cfg.supervised_levels
        classified = range(self.cfg.losses.style_classifier_from, len(levels))
        rng, loss, acc = rng_for(self.tcfg.seed, it, 400 + k), 0.0, 0.0
        for i in classified:
            crops, styles = self.bank.batch(levels[i], rng)
            logits = self.discs[i].logits(crops)
            labels = real_style_targets(logits, styles)
            loss = loss + style_classification_loss(logits, labels)
            acc += (logits[:, :self.cfg.n_styles].argmax(1) == labels).float().mean().item() / len(classified)
        return loss, acc

    def rebuild_style_bank(self) -> None:
        """Remake the bank at ``self.step`` by replaying the iterations before it, latest first, until
        every style has its window (the same windows the uninterrupted run holds: they are a function of
        (seed, it, r)). Also fills it at once for a state branched from a run without the terms."""
        if self.bank is None:
            return
        t, missing = self.tcfg, set(range(self.cfg.n_styles))
        for it in range(self.step - 1, -1, -1):
            for r in reversed(range(t.reconstruction_steps(it))):
                style = self.reconstruction_style(it, r)
                if style in missing:
                    missing.discard(style)
                    view = self._views(self.style_sample(style, it * 8 + r), it, 200 + r, t.windows_per_step)[0]
                    self._bank_put(style, {j: view.target(j) for j in self.bank.levels})
            if not missing:
                return

    # ------------------------------------------------------------------ steps

    def reconstruction_style(self, it: int, r: int) -> int | None:
        """The style whose exemplar reconstruction step r of iteration ``it`` reproduces (None: a distilled step)."""
        t = self.tcfg
        if self.teacher is not None and is_distilled(t.seed, it, r, t.distill_frac):
            return None
        return int(rng_for(t.seed, it, 100 + r).integers(self.cfg.n_styles))

    def reconstruction_sample(self, it: int, r: int) -> tuple[Sample, bool]:
        """Reconstruction step r of iteration ``it``'s sample, and whether it is a distilled one.

        An exemplar as itself (its style drawn from (seed, it, 100 + r)), or, with
        probability ``distill_frac``, an augmented content with quilt's output as its fine
        shape (``model.distill.distill_sample``). A function of (seed, it, r) only.
        """
        t = self.tcfg
        style = self.reconstruction_style(it, r)
        if style is None:
            if self.prefetch is not None:  # made ahead by the workers (the same sample)
                return self.prefetch.distilled(it, r), True
            return distill_sample(self.teacher, self.cfg, self.aug, t.seed, it, r), True
        return self.style_sample(style, it * 8 + r), False

    def distilled_steps(self, it: int) -> list[int]:
        """The reconstruction steps r of iteration ``it`` that are distilled ones (none without distillation)."""
        t = self.tcfg
        if self.teacher is None:
            return []
        return [r for r in range(t.reconstruction_steps(it)) if is_distilled(t.seed, it, r, t.distill_frac)]

    def style_sample(self, style: int, draw: int) -> Sample:
        """``model.data.style_sample`` of ``style`` for draw index ``draw`` (it·8 + r).

        With a fixed placement (``style_offset`` set: centred or one offset) the sample does
        not depend on the draw: it is made once per style and kept with its whole-crop
        targets of every supervised level, so a window's target is a cut of those instead of
        a new smoothing (the same values: ``Sample.target``). That saves ~0.5 s of numpy per
        reconstruction step at R = 256 (4 windows; Intel Xeon) for ~30 MiB per style.
        """
        if self.aug.style_offset is None:
            return style_sample(self.exemplars, style, self.cfg, self.aug, self.tcfg.seed, draw)
        if style not in self._fixed_styles:
            s = style_sample(self.exemplars, style, self.cfg, self.aug, self.tcfg.seed, draw)
            self._fixed_styles[style] = s.keep_targets(self.cfg.supervised_levels)
        return self._fixed_styles[style]

    def start_workers(self) -> None:
        """With ``data_workers`` and adversarial iterations ahead: the prefetcher, and the kept style samples
        of a fixed placement made by its workers at once (``train`` closes it)."""
        t = self.tcfg
        if not t.data_workers or t.steps <= max(self.step, t.warmup_iters):
            return
        distilled = None if self.teacher is None else self.distilled_steps
        self.prefetch = ContentPrefetcher(self.exemplars, self.cfg, self.aug, t.seed, t.data_workers,
                                          distilled_steps=distilled, teacher_set=self.teacher_set)
        if self.aug.style_offset is not None:
            styles = range(len(self.exemplars))
            self._fixed_styles.update(zip(styles, self.prefetch.style_samples(styles)))

    def adversarial_content(self, it: int) -> Sample:
        """Iteration ``it``'s adversarial content: ``augmented_sample`` of (seed, it), from the prefetcher if any."""
        if self.prefetch is not None:
            return self.prefetch.get(it, self.tcfg.steps)
        return augmented_sample(self.exemplars, self.cfg, self.aug, self.tcfg.seed, it)

    def reconstruction_step(self, it: int, r: int) -> tuple[dict[str, float], SampleView]:
        """One G step reproducing a style shape in its own style; returns losses and the sample's first view.

        With ``distill_frac`` > 0 the step is, with that probability, a distilled one instead:
        an augmented content with quilt's output as target (``model.distill``).

        With ``windows_per_step`` K > 1 the fine levels run on K windows of the sample
        after one trunk forward, and the loss is the mean of the K windows' losses (the
        whole levels' terms count once).
        """
        s, distilled = self.reconstruction_sample(it, r)
        views = self._views(s, it, 200 + r, self.tcfg.windows_per_step)
        levels, beta = self.cfg.supervised_levels, self.cfg.losses.beta_recon
        targets = [[v.target(j) for j in levels] for v in views]
        per_view = [reconstruction_loss(outs, tg, beta)["total"] for tg, outs in zip(targets, self._forward(views))]
        loss = per_view[0] if len(per_view) == 1 else sum(per_view) / len(per_view)
        self.opt_g.zero_grad(set_to_none=True)
        loss.backward()
        self.opt_g.step()
        if not distilled:  # the first view's targets, already made for the loss
            self._bank_put(int(self.reconstruction_style(it, r)), dict(zip(levels, targets[0])))
        out = {"recon": loss.item()}
        if self.teacher is not None:
            out["distilled"] = float(distilled)
        return out, views[0]

    def adversarial_steps(self, it: int, real: "SampleView") -> dict[str, float]:
        """The G adversarial step, then the D step, on one augmented content.

        Per supervised level j (every level; only the last without the pyramid), with
        the k-th supervised level's discriminator: masked LSGAN
        (``losses.generator_gan_loss`` / ``discriminator_loss``) with masks built from the
        level's coarse cells (the window's for windowed levels) and the true per-part
        assignment; L_down/L_up against the previous supervised level's output (the coarse
        input for the first, pooled by the resolution ratio: 2, or 16 without the
        pyramid), cropped to the window where level j is windowed.
        """
        cfg = self.cfg
        content = self.adversarial_content(it)
        (v,) = self._views(content, it, 300)
        occ = self._inputs(content)[0]

        # G: the discriminators judge but do not learn here.
        self.discs.requires_grad_(False)
        (outs,) = self._forward([v])
        levels = cfg.supervised_levels
        d_logits = [d.logits(o) for d, o in zip(self.discs, outs)]
        d_fake = [torch.sigmoid(x) for x in d_logits]
        fake_masks = [v.masks(j, tuple(df.shape[2:]), cfg) for j, df in zip(levels, d_fake)]
        alphas = ([v.alpha(j, tuple(df.shape[2:]), cfg) for j, df in zip(levels, d_fake)]
                  if self.tcfg.adaptive_alpha else None)
        prevs = [v.crop_prev(outs[k - 1] if k else occ, j, levels[k - 1] if k else -1) for k, j in enumerate(levels)]
        coarse = [v.crop_prev(occ, j, -1) for j in levels]
        g = generator_adversarial_loss(d_fake, outs, prevs, fake_masks, alphas, cfg, coarse)
        lc, classified = cfg.losses, range(cfg.losses.style_classifier_from, len(levels))
        if lc.style_classifier_g > 0:  # every part's output classified as its assigned style
            g["cls"] = sum(style_classification_loss(d_logits[k], *assigned_styles(fake_masks[k].style))
                           for k in classified)
            g["total"] = g["total"] + lc.style_classifier_g * g["cls"]
        # each style's surface against its latest real window (texture_mode), and its patches nearer that window
        # than any other style's (texture_contrast); each term draws its patches from its own stream
        for key, term, weight, stream in (("tex", self.texture, lc.texture_weight, 500),
                                          ("texc", self.contrast, lc.texture_contrast, 501)):
            if term is not None:
                rng = rng_for(self.tcfg.seed, it, stream)
                g[key] = sum(term(outs[k], v.output_styles(levels[k]), self.bank.targets[levels[k]], rng)
                             for k in classified)
                g["total"] = g["total"] + weight * g[key]
        self.opt_g.zero_grad(set_to_none=True)
        g["total"].backward()
        self.opt_g.step()
        self.discs.requires_grad_(True)

        # D: real = the smoothed style shape of the last reconstruction step; fake = detached outputs.
        d_real = [d(real.target(j)) for j, d in zip(levels, self.discs)]
        d_fake = [d(o.detach()) for d, o in zip(self.discs, outs)]
        real_masks = [real.masks(j, tuple(dr.shape[2:]), cfg) for j, dr in zip(levels, d_real)]
        dl = discriminator_loss_levels(d_real, d_fake, real_masks, fake_masks, cfg)
        classify = lc.style_classifier > 0 and self.bank is not None and self.bank.ready()
        if classify:  # one real crop per style
            dl["cls"], dl["cls_acc"] = self._classification_d_loss(it, 0)
            dl["total"] = dl["total"] + lc.style_classifier * dl["cls"]
        self.opt_d.zero_grad(set_to_none=True)
        dl["total"].backward()
        self.opt_d.step()
        for k in range(1, lc.style_classifier_d_steps if classify else 1):  # D's classification at its own pace
            extra, acc = self._classification_d_loss(it, k)
            self.opt_d.zero_grad(set_to_none=True)
            (lc.style_classifier * extra).backward()
            self.opt_d.step()
            dl["cls_acc"] += (acc - dl["cls_acc"]) / (k + 1)  # the mean over the iteration's classification steps
        return {
            "g_total": g["total"].item(), "gan": g["gan"].item(), "down": g["down"].item(), "up": g["up"].item(),
            **({"fill": g["fill"].item()} if cfg.losses.gamma_fill > 0 else {}),
            "d_total": dl["total"].item(), "d_real": dl["real"].item(), "d_fake": dl["fake"].item(),
            **({"d_mismatch": dl["mismatch"].item()} if cfg.losses.style_mismatch > 0 else {}),
            **({k: g[n].item() for k, n in (("g_cls", "cls"), ("g_tex", "tex"), ("g_texc", "texc")) if n in g}),
            **({"d_cls": dl["cls"].item(), "d_cls_acc": round(dl["cls_acc"], 4)} if "cls" in dl else {}),
        }

    def iteration(self) -> dict[str, float]:
        """One full iteration at ``self.step``; advances the step.

        Warm-up iterations (``it < warmup_iters``) are one reconstruction step; the others
        are ``tcfg.reconstruction_steps(it)`` reconstruction steps, the adversarial G step and
        the D step.
        """
        it = self.step
        lr = self._set_lr(it)
        if it < self.tcfg.warmup_iters:
            losses, _ = self.reconstruction_step(it, 0)
            self.step += 1
            self.update_ema()
            return {**losses, "lr": lr}
        n_rec = self.tcfg.reconstruction_steps(it)
        recon, distilled, real = [], 0.0, None
        for r in range(n_rec):
            losses, real = self.reconstruction_step(it, r)
            recon.append(losses["recon"])
            distilled += losses.get("distilled", 0.0)
        out = {"recon": float(np.mean(recon))}
        if self.teacher is not None:
            out["distilled"] = distilled  # how many of this iteration's reconstruction steps were distilled
        out.update(self.adversarial_steps(it, real))
        self.step += 1
        self.update_ema()
        return out

    def update_ema(self) -> None:
        """ema ← β·ema + (1 − β)·weights for every generator parameter (buffers copied); nothing without an EMA."""
        if self.gen_ema is None:
            return
        with torch.no_grad():
            for mine, theirs in zip(self.gen_ema.parameters(), self.gen.parameters()):
                mine.lerp_(theirs, 1.0 - self.tcfg.ema_decay)
            for mine, theirs in zip(self.gen_ema.buffers(), self.gen.buffers()):
                mine.copy_(theirs)

    # ------------------------------------------------------------------ checkpoints

    def _meta(self) -> dict[str, Any]:
        return {
            "step": self.step,
            "seed": self.tcfg.seed,
            "command": self.tcfg.command,
            "ablation": self.tcfg.ablation,
            "recipe": self.tcfg.recipe,
            "wall_time_s": round(self.wall_s, 3),
            "machine": f"{platform.machine()} {os.cpu_count()} cpus, {self.device.type}"
                       + (f" ({torch.cuda.get_device_name(self.device)})" if self.device.type == "cuda" else ""),
            "torch": torch.__version__,
            "train_config": to_plain(self.tcfg),
            "augment": to_plain(self.aug),
            **({"style_set": self.style_set} if self.style_set else {}),
            **({"ema_started_at": self.ema_started_at} if self.gen_ema is not None else {}),
            **self.history,
        }

    def checkpoint(self, full: bool = True, ema: bool = False) -> Checkpoint:
        """The training state (``full``), or an inference file of the generator (or, with ``ema``, of its average)."""
        ex = self.exemplars
        vocab = ex[0].part_names
        if ema and (full or self.gen_ema is None):
            raise ValueError("an EMA checkpoint is an inference file of a run that keeps an average")
        meta = self._meta()
        if ema:
            meta["weights"] = {"ema_decay": self.tcfg.ema_decay, "ema_started_at": self.ema_started_at}
        return Checkpoint(
            config=self.cfg,
            style_names=tuple(e.name for e in ex),
            part_names=vocab,
            style_parts=tuple(tuple(vocab[p] for p in e.parts) for e in ex),
            generator=(self.gen_ema if ema else self.gen).state_dict(),
            training=meta,
            discriminators=self.discs.state_dict() if full else None,
            optimizers={"g": self.opt_g.state_dict(), "d": self.opt_d.state_dict()} if full else None,
            rng={"torch": torch.get_rng_state()} if full else None,
            generator_ema=self.gen_ema.state_dict() if full and self.gen_ema is not None else None,
            part_aliases=self.part_aliases,
            style_categories=tuple(e.category for e in ex),
        )

    def restore(self, path: Path) -> None:
        """Continue from a full checkpoint written by this trainer's configuration."""
        ck = load_checkpoint(path, training_state=True)
        same_ablation = ck.training.get("ablation", "full") == self.tcfg.ablation  # absent: written before the key
        same_ablation &= ck.training.get("recipe", "reference") == self.tcfg.recipe
        if ck.config != self.cfg or ck.style_names != tuple(e.name for e in self.exemplars) or not same_ablation:
            raise DetailizeError("the checkpoint to resume was trained with another config or exemplar set",
                                 file=path, hint="use a new --out folder, or the same settings as that run")
        if ck.discriminators is None or not ck.optimizers or set(ck.optimizers) != {"g", "d"}:
            raise DetailizeError("the checkpoint holds no training state to resume from", file=path,
                                 hint="resume from last.pt, not from an inference-only model.pt")
        self.gen.load_state_dict(ck.generator)
        self.discs.load_state_dict(ck.discriminators)
        try:
            self.opt_g.load_state_dict(ck.optimizers["g"])
            self.opt_d.load_state_dict(ck.optimizers["d"])
        except (ValueError, KeyError) as exc:
            raise DetailizeError(f"optimizer state does not fit the model: {exc}", file=path,
                                 hint="use a new --out folder") from None
        if ck.rng and "torch" in ck.rng:
            torch.set_rng_state(ck.rng["torch"])
        self.step = int(ck.training.get("step", 0))
        self.history = {k: ck.training[k] for k in HISTORY_KEYS if k in ck.training}
        self.wall_s = float(ck.training.get("wall_time_s", 0.0))
        if self.gen_ema is not None:  # the state's average, or one that starts at this step's weights
            self.gen_ema.load_state_dict(ck.generator_ema if ck.generator_ema is not None else ck.generator)
            self.ema_started_at = int(ck.training.get("ema_started_at", self.step)) \
                if ck.generator_ema is not None else self.step
        self.rebuild_style_bank()


class _Previews:
    """Writes ``model.previews`` sheets of fixed inputs (drawn once, on first use) into ``folder``."""

    def __init__(self, trainer: Trainer, folder: Path) -> None:
        self.trainer, self.folder, self.samples = trainer, folder, None

    def write(self, step: int) -> Path:
        t = self.trainer
        if self.samples is None:
            self.samples = preview_samples(t.exemplars, t.cfg, t.aug, n=4)
        return write_preview(t.gen, self.samples, self.folder / f"step_{step:06d}.png")


def _cut_log(log_path: Path, step: int) -> None:
    """Drop the log's rows after ``step``: a run stopped between checkpoints logged iterations it redoes."""
    if not log_path.exists():
        return
    lines = log_path.read_text(encoding="utf-8").splitlines(keepends=True)
    kept = [line for line in lines if line.strip() and json.loads(line).get("step", 0) <= step]
    if len(kept) != len(lines):
        tmp = log_path.with_suffix(".jsonl.tmp")
        tmp.write_text("".join(kept), encoding="utf-8")
        tmp.replace(log_path)


def train(
    exemplars: Sequence[Exemplar],
    cfg: ModelConfig,
    tcfg: TrainConfig,
    *,
    resume: bool = True,
    part_aliases: dict[str, str] | None = None,
    progress: Callable[[int, int, dict[str, float]], None] | None = None,
    style_set: dict | None = None,
    stop_after_s: float | None = None,
    teacher_set: Any = None,
) -> TrainResult:
    """Train (or continue training) up to ``tcfg.steps`` iterations; see the module docstring.

    Args:
        exemplars: the style set (``n_styles`` exemplars sharing ``n_parts`` part names).
        part_aliases: other accepted part names (alias → part), recorded in the checkpoints.
        progress: called after every iteration with (step, total, losses) — the CLI's progress bar.
        style_set: the set's provenance (``stylesets.provenance.StyleSetRecord.to_json()``: name, digest,
            each exemplar's licence), recorded in the checkpoints so built assets can credit exemplars.
        stop_after_s: stop after the first iteration that ends this many seconds after this call
            began, set-up (restoring, worker start, kept style samples) included (a time-boxed
            session, e.g. ``scripts/train_resume.py`` on a lent GPU); the state is saved to ``last.pt`` and ``model.pt`` as at the end, and the same call
            continues later.
        teacher_set: the ``stylesets.format.StyleSet`` the exemplars were read from, quilt's source
            when ``tcfg.distill_frac`` > 0 (None: a set made from the exemplars themselves).
    Raises:
        DetailizeError: inconsistent set/config, unusable resume checkpoint, unwritable folder,
            or a loss that became NaN/inf (training diverged; the last checkpoint is kept).
    """
    start = time.perf_counter()
    out = Path(tcfg.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    last, model_path, log_path = out / "last.pt", out / "model.pt", out / "log.jsonl"
    trainer = Trainer(exemplars, cfg, tcfg, part_aliases, teacher_set)
    trainer.style_set = style_set
    if resume and last.exists():
        trainer.restore(last)
        _cut_log(log_path, trainer.step)
    elif log_path.exists():
        log_path.unlink()  # a fresh run starts a fresh log
    losses: dict[str, float] = {}
    times = []
    previews = _Previews(trainer, out / "previews") if tcfg.preview_every else None
    monitor = Monitor(trainer.exemplars, cfg, trainer.aug, trainer.teacher)
    trainer.start_workers()
    try:
        with open(log_path, "a", encoding="utf-8") as log:
            while trainer.step < tcfg.steps:
                t0 = time.perf_counter()
                losses = trainer.iteration()
                dt = time.perf_counter() - t0
                trainer.wall_s += dt
                times.append(dt)
                if not all(np.isfinite(v) for v in losses.values()):
                    raise DetailizeError(f"training diverged at step {trainer.step}: {losses}", file=log_path,
                                         hint="resume from last.pt with a lower learning rate")
                row = {"step": trainer.step, "seconds": round(dt, 4), **{k: round(v, 6) for k, v in losses.items()}}
                if tcfg.monitor_every and (trainer.step % tcfg.monitor_every == 0 or trainer.step == tcfg.steps):
                    row["monitor"] = monitor.figures(trainer.gen)
                log.write(json.dumps(row) + "\n")
                log.flush()
                out_of_time = stop_after_s is not None and time.perf_counter() - start >= stop_after_s
                if trainer.step % tcfg.checkpoint_every == 0 or trainer.step == tcfg.steps or out_of_time:
                    save_checkpoint(last, trainer.checkpoint(full=True))
                if previews and (trainer.step % tcfg.preview_every == 0 or trainer.step == tcfg.steps):
                    previews.write(trainer.step)
                if progress is not None:
                    progress(trainer.step, tcfg.steps, losses)
                if out_of_time:
                    break
    finally:
        if trainer.prefetch is not None:
            trainer.prefetch.close()
            trainer.prefetch = None
    save_checkpoint(model_path, trainer.checkpoint(full=False))
    ema_path = None
    if trainer.gen_ema is not None:
        ema_path = save_checkpoint(out / "model_ema.pt", trainer.checkpoint(full=False, ema=True))
    return TrainResult(trainer.step, last, model_path, log_path, losses,
                       float(np.mean(times)) if times else 0.0, ema_path)

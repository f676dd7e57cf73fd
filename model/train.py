"""DECOLLAGE training: one readable loop (the published code's iteration), resumable, seeded, CPU- or CUDA-feasible.

One iteration (``Trainer.iteration``):

1. **Reconstruction** — ``recon_steps_early`` (4) steps per iteration for the first
   ``recon_early_iters`` iterations, then 1: a random style shape as itself, every
   part in its own style; loss Σ_levels β·MSE(output, smoothed target); a G step.
   The last of these samples is the discriminators' "real" input.
2. **Adversarial G step** — an augmented (maybe combined) content with a random
   per-part style assignment; masked LSGAN over all levels with adaptive α (0.1 in
   part-joint cells, 0.5 elsewhere) + γ_down·L_down + γ_up·L_up; a G step (the
   discriminators are frozen for it).
3. **D step** — per level, masked LSGAN on the real style shape's smoothed targets
   and the detached generated levels, with the fake masks built from the true
   per-part assignment at every level (the reference's bug fixed in ``losses``).

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

import dataclasses
import json
import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from scipy.ndimage import binary_erosion

from model.ablations import ABLATIONS
from model.checkpoint import Checkpoint, load_checkpoint, save_checkpoint
from model.config import ModelConfig
from model.data import AugmentConfig, Exemplar, Sample, augmented_sample, rng_for, style_sample
from model.infer import cpu_threads, resolve_device
from model.losses import discriminator_loss_levels, generator_adversarial_loss, reconstruction_loss
from model.masks import DOutputMasks, StyledCoarse, align_to_d_output, alpha_map, joint_mask
from model.networks import Generator, build_discriminators
from model.previews import preview_samples, write_preview
from model.windows import Window, halo_cells, window_forward  # noqa: F401 - part of this module's API
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
        checkpoint_every: iterations between ``last.pt`` saves.
        preview_every: iterations between sample previews (``previews/step_NNNNNN.png``,
            ``model.previews``; 0 = none, else also one at the end).
        resolution: R, fine grid edge the shapes are sized for (see module docstring).
        whole_levels, window_cells: levels ``< whole_levels`` run on the whole shape, the
            finer ones on a random window of ``window_cells``³ coarse cells around the
            surface (``window_cells = 0``: every level on the whole shape).
        adaptive_alpha: α1 in part-joint cells (else α2 everywhere).
        device: a ``Device`` (its value, or ``"cuda:N"``, is accepted: ``infer.resolve_device``).
        command: the command line that started the run (recorded in checkpoints).
        ablation: name of the ``model.ablations`` row this run trains (``full`` = the model),
            recorded in the checkpoints' training meta; a resume must name the same one.
            It is a label: the caller builds the configs with ``ablation_configs``.
    """

    out_dir: str
    steps: int
    seed: int = 0
    lr: float = 1e-4
    betas: tuple[float, float] = (0.9, 0.999)
    recon_steps_early: int = 4
    recon_early_iters: int = 5000
    checkpoint_every: int = 100
    preview_every: int = 0
    resolution: int = 256
    whole_levels: int = 2
    window_cells: int = 4
    adaptive_alpha: bool = True
    device: Device | str = Device.AUTO
    command: str = ""
    ablation: str = "full"

    def __post_init__(self) -> None:
        if isinstance(self.device, str) and not isinstance(self.device, Device) and self.device in set(Device):
            object.__setattr__(self, "device", Device(self.device))
        checks = (
            (self.steps >= 0, "steps", "use 0 or more iterations"),
            # style-sample draws are indexed it·8 + r, so at most 8 reconstruction steps
            (1 <= self.recon_steps_early <= 8, "recon_steps_early", "use 1 to 8 (the reference: 4)"),
            (self.recon_early_iters >= 0, "recon_early_iters", "use 0 or more"),
            (self.checkpoint_every >= 1, "checkpoint_every", "use 1 or more"),
            (self.preview_every >= 0, "preview_every", "use 0 (no previews) or more"),
            (self.resolution >= 16, "resolution", "use 256 (the paper) or 128"),
            (self.window_cells >= 0 and self.whole_levels >= 0, "window_cells", "use 0 (no windows) or ≥ 2"),
            (self.lr > 0, "lr", "the reference uses 1e-4"),
        )
        for ok, name, hint in checks:
            if not ok:
                raise DetailizeError(f"bad training setting {name} = {getattr(self, name)!r}", field=name, hint=hint)
        if self.ablation not in ABLATIONS:
            raise DetailizeError(f"unknown ablation {self.ablation!r}", field="ablation",
                                 hint="use one of: " + ", ".join(ABLATIONS))

    def augment(self) -> AugmentConfig:
        return AugmentConfig(resolution=self.resolution)


@dataclass(frozen=True)
class TrainResult:
    """What ``train`` did: the final step, the files, the last losses and the mean time per iteration."""

    step: int
    checkpoint: Path
    model: Path
    log: Path
    last_losses: dict[str, float]
    seconds_per_iteration: float


# ----------------------------------------------------------------------------- fine-level windows


def surface_window(coarse_occ: np.ndarray, cells: int, rng: np.random.Generator) -> Window:
    """A ``cells``³ window of coarse cells (whole axis where the grid is smaller) around a random surface cell.

    Surface cells are occupied cells with an empty 6-neighbour (all occupied cells if none).
    """
    surface = coarse_occ & ~binary_erosion(coarse_occ, border_value=0)
    cand = np.argwhere(surface if surface.any() else coarse_occ)
    centre = cand[int(rng.integers(len(cand)))]
    out = []
    for c, n in zip(centre, coarse_occ.shape):
        w = min(cells, n)
        lo = int(np.clip(c - w // 2, 0, n - w))
        out.append(slice(lo, lo + w))
    return tuple(out)  # type: ignore[return-value]


def check_window(cfg: ModelConfig, whole_levels: int, cells: int) -> None:
    """Refuse a window too small for the windowed levels' discriminators."""
    for j, d in zip(cfg.supervised_levels, cfg.discriminators):
        if j >= whole_levels and d.output_size(cells * 2 ** (j + 1)) < 1:
            raise DetailizeError(f"a window of {cells} coarse cells is too small for the level-{j} discriminator",
                                 field="window_cells", hint="use a larger window_cells, or 0 for whole shapes")


class SampleView:
    """A sample as the losses see it: whole grid for levels ``< whole_levels``, the window for finer ones.

    Gives per level the (1, 1, …) target tensor, the discriminator-output masks, the
    adaptive-α map and the crop of the previous level, all on the same cells.
    """

    def __init__(self, sample: Sample, window: Window | None, whole_levels: int, device) -> None:
        self.sample, self.window, self.device = sample, window, device
        self.whole_levels = whole_levels if window is not None else 10**6
        self._joints = None

    def _cells(self, j: int) -> Window | None:
        return self.window if j >= self.whole_levels else None

    def _crop(self, arr: np.ndarray, j: int, factor: int) -> np.ndarray:
        w = self._cells(j)
        return arr if w is None else arr[tuple(slice(s.start * factor, s.stop * factor) for s in w)]

    def target(self, j: int):
        t = self.sample.target(j, self._cells(j))
        return torch.from_numpy(np.ascontiguousarray(t))[None, None].to(self.device)

    def styled(self, j: int) -> StyledCoarse:
        s = self.sample
        return StyledCoarse(self._crop(s.coarse_occupancy, j, 1), self._crop(s.coarse_labels, j, 1).astype(np.int64),
                            s.assignment)

    def masks(self, j: int, d_shape: tuple[int, ...], cfg: ModelConfig) -> DOutputMasks:
        m = self.styled(j).masks(j, cfg.discriminator(j), d_shape, cfg.n_styles)
        return DOutputMasks(m.style[None], m.global_[None])

    def alpha(self, j: int, d_shape: tuple[int, ...], cfg: ModelConfig):
        lc = cfg.losses
        if self._joints is None:
            self._joints = joint_mask(self.sample.fine_labels, cfg.factor, lc.joint_radius)
        a = alpha_map(self._crop(self._joints, j, 1), lc.alpha_joint, lc.alpha_other)
        return align_to_d_output(a[None], j, cfg.discriminator(j), d_shape)[None]

    def crop_prev(self, prev, j: int, j_prev: int | None = None):
        """Level ``j_prev``'s output (default j−1; −1 = the coarse input) cut to the cells level j covers."""
        j_prev = j - 1 if j_prev is None else j_prev
        if self._cells(j) is None or self._cells(j_prev) is not None:
            return prev
        r = 2 ** (j_prev + 1)  # prev is at 2^(j_prev+1) × coarse
        return prev[:, :, *(slice(s.start * r, s.stop * r) for s in self.window)]


class Trainer:
    """Networks, optimizers and the three steps of an iteration, on one device."""

    def __init__(self, exemplars: Sequence[Exemplar], cfg: ModelConfig, tcfg: TrainConfig,
                 part_aliases: dict[str, str] | None = None) -> None:
        self.exemplars, self.cfg, self.tcfg, self.aug = list(exemplars), cfg, tcfg, tcfg.augment()
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
        self.opt_g = torch.optim.Adam(self.gen.parameters(), lr=tcfg.lr, betas=tcfg.betas)
        self.opt_d = torch.optim.Adam(self.discs.parameters(), lr=tcfg.lr, betas=tcfg.betas)
        self.whole_levels = min(max(tcfg.whole_levels, 0), cfg.n_levels) if tcfg.window_cells else cfg.n_levels
        check_window(cfg, self.whole_levels, tcfg.window_cells)
        self.step = 0
        self.wall_s = 0.0

    # ------------------------------------------------------------------ tensors

    def _inputs(self, s: Sample):
        occ = torch.from_numpy(s.coarse_occupancy)[None]
        parts = torch.from_numpy(s.coarse_labels.astype(np.int64))[None]
        styles = torch.from_numpy(s.style_index())[None]
        return self.gen.make_inputs(occ, parts, styles)

    def _view(self, s: Sample, it: int, stream: int) -> "SampleView":
        window = None
        if self.tcfg.window_cells and self.whole_levels < self.cfg.n_levels:
            window = surface_window(s.coarse_occupancy, self.tcfg.window_cells, rng_for(self.tcfg.seed, it, stream))
        return SampleView(s, window, self.whole_levels, self.device)

    def _forward(self, v: "SampleView"):
        return window_forward(self.gen, *self._inputs(v.sample), v.whole_levels, v.window)

    # ------------------------------------------------------------------ steps

    def reconstruction_step(self, it: int, r: int) -> tuple[dict[str, float], "SampleView"]:
        """One G step reproducing a style shape in its own style; returns losses and the sample's view."""
        style = int(rng_for(self.tcfg.seed, it, 100 + r).integers(self.cfg.n_styles))
        s = style_sample(self.exemplars, style, self.cfg, self.aug, self.tcfg.seed, it * 8 + r)
        v = self._view(s, it, 200 + r)
        outs = self._forward(v)
        targets = [v.target(j) for j in self.cfg.supervised_levels]
        loss = reconstruction_loss(outs, targets, self.cfg.losses.beta_recon)["total"]
        self.opt_g.zero_grad(set_to_none=True)
        loss.backward()
        self.opt_g.step()
        return {"recon": loss.item()}, v

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
        content = augmented_sample(self.exemplars, cfg, self.aug, self.tcfg.seed, it)
        v = self._view(content, it, 300)
        occ = self._inputs(content)[0]

        # G: the discriminators judge but do not learn here.
        self.discs.requires_grad_(False)
        outs = self._forward(v)
        levels = cfg.supervised_levels
        d_fake = [d(o) for d, o in zip(self.discs, outs)]
        fake_masks = [v.masks(j, tuple(df.shape[2:]), cfg) for j, df in zip(levels, d_fake)]
        alphas = ([v.alpha(j, tuple(df.shape[2:]), cfg) for j, df in zip(levels, d_fake)]
                  if self.tcfg.adaptive_alpha else None)
        prevs = [v.crop_prev(outs[k - 1] if k else occ, j, levels[k - 1] if k else -1) for k, j in enumerate(levels)]
        g = generator_adversarial_loss(d_fake, outs, prevs, fake_masks, alphas, cfg)
        self.opt_g.zero_grad(set_to_none=True)
        g["total"].backward()
        self.opt_g.step()
        self.discs.requires_grad_(True)

        # D: real = the smoothed style shape of the last reconstruction step; fake = detached outputs.
        d_real = [d(real.target(j)) for j, d in zip(levels, self.discs)]
        d_fake = [d(o.detach()) for d, o in zip(self.discs, outs)]
        real_masks = [real.masks(j, tuple(dr.shape[2:]), cfg) for j, dr in zip(levels, d_real)]
        dl = discriminator_loss_levels(d_real, d_fake, real_masks, fake_masks, cfg)
        self.opt_d.zero_grad(set_to_none=True)
        dl["total"].backward()
        self.opt_d.step()
        return {
            "g_total": g["total"].item(), "gan": g["gan"].item(), "down": g["down"].item(), "up": g["up"].item(),
            "d_total": dl["total"].item(), "d_real": dl["real"].item(), "d_fake": dl["fake"].item(),
        }

    def iteration(self) -> dict[str, float]:
        """One full iteration at ``self.step``; advances the step."""
        it = self.step
        n_rec = self.tcfg.recon_steps_early if it < self.tcfg.recon_early_iters else 1
        recon, real = [], None
        for r in range(max(1, n_rec)):
            losses, real = self.reconstruction_step(it, r)
            recon.append(losses["recon"])
        out = {"recon": float(np.mean(recon))}
        out.update(self.adversarial_steps(it, real))
        self.step += 1
        return out

    # ------------------------------------------------------------------ checkpoints

    def _meta(self) -> dict[str, Any]:
        return {
            "step": self.step,
            "seed": self.tcfg.seed,
            "command": self.tcfg.command,
            "ablation": self.tcfg.ablation,
            "wall_time_s": round(self.wall_s, 3),
            "machine": f"{platform.machine()} {os.cpu_count()} cpus, {self.device.type}"
                       + (f" ({torch.cuda.get_device_name(self.device)})" if self.device.type == "cuda" else ""),
            "torch": torch.__version__,
            "train_config": _plain(dataclasses.asdict(self.tcfg)),
            "augment": _plain(dataclasses.asdict(self.aug)),
            **({"style_set": self.style_set} if self.style_set else {}),
        }

    def checkpoint(self, full: bool = True) -> Checkpoint:
        ex = self.exemplars
        vocab = ex[0].part_names
        return Checkpoint(
            config=self.cfg,
            style_names=tuple(e.name for e in ex),
            part_names=vocab,
            style_parts=tuple(tuple(vocab[p] for p in e.parts) for e in ex),
            generator=self.gen.state_dict(),
            training=self._meta(),
            discriminators=self.discs.state_dict() if full else None,
            optimizers={"g": self.opt_g.state_dict(), "d": self.opt_d.state_dict()} if full else None,
            rng={"torch": torch.get_rng_state()} if full else None,
            part_aliases=self.part_aliases,
            style_categories=tuple(e.category for e in ex),
        )

    def restore(self, path: Path) -> None:
        """Continue from a full checkpoint written by this trainer's configuration."""
        ck = load_checkpoint(path, training_state=True)
        same_ablation = ck.training.get("ablation", "full") == self.tcfg.ablation  # absent: written before the key
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
        self.wall_s = float(ck.training.get("wall_time_s", 0.0))


class _Previews:
    """Writes ``model.previews`` sheets of fixed inputs (drawn once, on first use) into ``folder``."""

    def __init__(self, trainer: Trainer, folder: Path) -> None:
        self.trainer, self.folder, self.samples = trainer, folder, None

    def write(self, step: int) -> Path:
        t = self.trainer
        if self.samples is None:
            self.samples = preview_samples(t.exemplars, t.cfg, t.aug, n=4)
        return write_preview(t.gen, self.samples, self.folder / f"step_{step:06d}.png")


def _plain(obj: Any) -> Any:
    """Dataclass dicts → JSON types (tuples → lists)."""
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, (tuple, list)):
        return [_plain(v) for v in obj]
    return obj


def train(
    exemplars: Sequence[Exemplar],
    cfg: ModelConfig,
    tcfg: TrainConfig,
    *,
    resume: bool = True,
    part_aliases: dict[str, str] | None = None,
    progress: Callable[[int, int, dict[str, float]], None] | None = None,
    style_set: dict | None = None,
) -> TrainResult:
    """Train (or continue training) up to ``tcfg.steps`` iterations; see the module docstring.

    Args:
        exemplars: the style set (``n_styles`` exemplars sharing ``n_parts`` part names).
        part_aliases: other accepted part names (alias → part), recorded in the checkpoints.
        progress: called after every iteration with (step, total, losses) — the CLI's progress bar.
        style_set: the set's provenance (``stylesets.provenance.StyleSetRecord.to_json()``: name, digest,
            each exemplar's licence), recorded in the checkpoints so built assets can credit exemplars.
    Raises:
        DetailizeError: inconsistent set/config, unusable resume checkpoint, unwritable folder,
            or a loss that became NaN/inf (training diverged; the last checkpoint is kept).
    """
    out = Path(tcfg.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    last, model_path, log_path = out / "last.pt", out / "model.pt", out / "log.jsonl"
    trainer = Trainer(exemplars, cfg, tcfg, part_aliases)
    trainer.style_set = style_set
    if resume and last.exists():
        trainer.restore(last)
    elif log_path.exists():
        log_path.unlink()  # a fresh run starts a fresh log
    losses: dict[str, float] = {}
    times = []
    previews = _Previews(trainer, out / "previews") if tcfg.preview_every else None
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
            log.write(json.dumps({"step": trainer.step, "seconds": round(dt, 4),
                                  **{k: round(v, 6) for k, v in losses.items()}}) + "\n")
            log.flush()
            if trainer.step % tcfg.checkpoint_every == 0 or trainer.step == tcfg.steps:
                save_checkpoint(last, trainer.checkpoint(full=True))
            if previews and (trainer.step % tcfg.preview_every == 0 or trainer.step == tcfg.steps):
                previews.write(trainer.step)
            if progress is not None:
                progress(trainer.step, tcfg.steps, losses)
    save_checkpoint(model_path, trainer.checkpoint(full=False))
    return TrainResult(trainer.step, last, model_path, log_path, losses,
                       float(np.mean(times)) if times else 0.0)

"""``decollage train``: train the DECOLLAGE detailizer on a style set.

Role: resolve the style set (a built-in name, built on first use and cached, or a
``.npz`` set file), build the model config, run ``model.train.train`` with a
progress bar, and print where the model, log and previews went. Errors are
``DecollageError`` subclasses; ``cli.app`` maps them to exit code 2.
"""

from __future__ import annotations

import shlex
import sys
from enum import Enum
from pathlib import Path

import typer
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from cli.console import fail, stderr
from core.errors import DecollageError
from core.files import ensure_writable_dir
from core.recipe import Device
from model.ablations import ABLATIONS, ablation_configs
from model.config import ModelConfig
from model.data import exemplars_from_set
from model.recipes import RECIPES, recipe_configs
from stylesets.provenance import record_of_set
from stylesets.registry import resolve_style_set


class Layout(str, Enum):
    """Generator/discriminator sizes (``model.config.ModelConfig``)."""

    LEAN = "lean"  # CPU default (measured: ~1 M parameters, ~1 s per 16³ → 256³ on 2 cores)
    PAPER = "paper"  # the published widths (19 M + 11 M parameters)


#: ``--ablation`` choices: the named rows of ``model.ablations`` (``full`` = the model itself).
Ablation = Enum("Ablation", {name: name for name in ABLATIONS}, type=str)
#: ``--recipe`` choices: the named recipes of ``model.recipes``.
Recipe = Enum("Recipe", {name: name for name in RECIPES}, type=str)


def train_command(
    style_set: str = typer.Option("things", "--set", help="Built-in style set name or a .npz set file."),
    out: Path = typer.Option(..., "--out", "-o", help="Run folder: last.pt, model.pt, log.jsonl, previews/."),
    steps: int = typer.Option(..., "--steps", help="Iterations to reach (a resumed run continues up to this)."),
    resolution: int = typer.Option(256, "--resolution", help="Fine grid edge shapes are sized for (256 or 128)."),
    layout: Layout = typer.Option(Layout.LEAN, "--layout", help="Model sizes."),
    ablation: Ablation = typer.Option("full", "--ablation",
                                      help="Train a Table 4 ablation or baseline of the layout instead of the full "
                                           "model (model.ablations; e.g. no_pyramid, decor_gan); recorded in "
                                           "the checkpoint."),
    recipe: Recipe = typer.Option("reference", "--recipe",
                                  help="Training recipe (model.recipes): reference (the shipped model's), warmup "
                                       "(issue 15's), warmup_thin (warmup; the inference fill projection on "
                                       "one-cell-thick cells only), warmup_low (warmup_thin at a warm-up peak rate "
                                       "of 3e-4, not 1e-3), warmup_centred (warmup_low, each exemplar at the "
                                       "reference's centred placement, not a random offset), warmup_centred_r4 "
                                       "(warmup_centred, 4 reconstruction steps per adversarial step until iteration "
                                       "5000), warmup_centred_r4_long (the same until 20000), warmup_centred_long "
                                       "(warmup_centred_r4_long with an 8000-iteration warm-up), "
                                       "warmup_centred_long_r1 (its adversarial phase 1:1) or distill (warmup + "
                                       "quilt's outputs as half the targets); recorded in the checkpoint, a resume "
                                       "must name the same."),
    seed: int = typer.Option(0, "--seed"),
    device: str = typer.Option(Device.AUTO.value, "--device", help="auto, cpu, cuda or cuda:N."),
    checkpoint_every: int = typer.Option(100, "--checkpoint-every", help="Iterations between last.pt saves."),
    preview_every: int = typer.Option(100, "--preview-every", help="Iterations between preview PNGs (0: none)."),
    recon_early_iters: int = typer.Option(5000, "--recon-early-iters",
                                          help="Iterations with 4 reconstruction steps each (then 1)."),
    resume: bool = typer.Option(True, "--resume/--no-resume", help="Continue from OUT/last.pt if present."),
    ema_decay: float = typer.Option(0.0, "--ema-decay", help="Also keep a moving average of the generator's weights "
                                    "with this beta (e.g. 0.995), written as OUT/model_ema.pt (0: none)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Train the DECOLLAGE detailizer on a style exemplar set (resumable; CPU or CUDA)."""

    try:
        _train(style_set, out, steps, resolution, layout, seed, device, checkpoint_every, preview_every,
               recon_early_iters, resume, quiet, ablation.value, recipe.value, ema_decay)
    except DecollageError as exc:
        fail(exc)
    except KeyboardInterrupt:
        stderr().print(f"interrupted; resume with the same command (from {out / 'last.pt'})")
        raise typer.Exit(130)


def _train(style_set, out, steps, resolution, layout, seed, device, checkpoint_every, preview_every,
           recon_early_iters, resume, quiet, ablation="full", recipe="reference", ema_decay=0.0) -> None:
    from model.train import TrainConfig, train  # torch: imported when training, not at every CLI start

    console = stderr()
    ensure_writable_dir(out)
    sset = resolve_style_set(style_set, progress=None if quiet else lambda n: console.print(f"  voxelized {n}"))
    exemplars = exemplars_from_set(sset)
    make = ModelConfig.lean if layout == Layout.LEAN else ModelConfig.paper
    cfg = make(n_parts=len(sset.vocabulary.parts), n_styles=len(exemplars))
    tcfg = TrainConfig(out_dir=str(out), steps=steps, seed=seed, device=device, resolution=resolution,
                       checkpoint_every=checkpoint_every, preview_every=preview_every,
                       recon_early_iters=recon_early_iters, ablation=ablation, recipe=recipe, ema_decay=ema_decay,
                       command="decollage " + " ".join(shlex.quote(a) for a in sys.argv[1:]))
    cfg, tcfg = ablation_configs(ablation, *recipe_configs(recipe, cfg, tcfg))
    if not quiet:
        console.print(f"training on set '{sset.name}' ({len(exemplars)} styles, parts "
                      f"{', '.join(sset.vocabulary.parts)}), layout {layout.value}, R = {resolution}"
                      + ("" if ablation == "full" else f", ablation {ablation} ({ABLATIONS[ablation][0]})")
                      + f", recipe {recipe}")
    bar = Progress(TextColumn("train"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[losses]}"),
                   TimeElapsedColumn(), TimeRemainingColumn(), console=console, disable=quiet or not console.is_terminal)
    lines = not quiet and not console.is_terminal

    def progress(step: int, total: int, losses: dict[str, float]) -> None:
        text = f"recon {losses.get('recon', 0):.4f} G {losses.get('g_total', 0):.3f} D {losses.get('d_total', 0):.3f}"
        bar.update(task, completed=step, losses=text)
        if lines and (step % 10 == 0 or step == total):
            console.print(f"step {step}/{total}: {text}")

    with bar:
        task = bar.add_task("train", total=steps, losses="")
        result = train(exemplars, cfg, tcfg, resume=resume, part_aliases=sset.vocabulary.alias_map(),
                       progress=progress, style_set=record_of_set(sset).to_json(), teacher_set=sset)
    if not quiet:
        console.print(f"done: step {result.step}, {result.seconds_per_iteration:.2f} s/iteration; "
                      f"model {result.model}, " + (f"average {result.model_ema}, " if result.model_ema else "")
                      + f"log {result.log}")

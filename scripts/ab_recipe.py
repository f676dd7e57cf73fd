"""One arm of a training-recipe A/B: train a lean model on a style set with config overrides, log monitor figures.

    .venv/bin/python scripts/ab_recipe.py OUT_DIR --steps 300 --resolution 128 \
        --model '{"style_init_std": 1.0, "output_mask": true}' \
        --train '{"warmup_iters": 300, "warmup_lr": 1e-3, "windows_per_step": 4, "monitor_every": 100}' \
        [--losses '{"up_level_weights": [1, 1, 0.1, 0.1]}'] [--levels '[...]'] [--set things] [--seed 0]
        [--exemplars 0,1,2,3] [--recipe warmup]

The overrides are the fields of ``model.config.ModelConfig`` / ``LossConfig`` and
``model.train.TrainConfig`` (JSON values; ``--levels`` replaces the generator levels
with ``LevelSpec`` dicts). ``--exemplars`` trains on a subset of the set (indices; the
model then has that many styles: the overfit diagnostic). ``--recipe`` starts from a named
recipe of ``model/recipes.py`` (default: none, the plain configs) and applies the overrides
on top. Resumable like ``decollage train`` (same command continues
from OUT_DIR/last.pt). Prints one line per monitor row; the full log is OUT_DIR/log.jsonl.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
import sys
import time

from model.config import LevelSpec, ModelConfig, Upsampler
from model.data import exemplars_from_set
from model.recipes import recipe_configs
from model.train import TrainConfig, train
from stylesets.registry import resolve_style_set


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--steps", type=int, required=True)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--set", default="things")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--model", default="{}")
    ap.add_argument("--losses", default="{}")
    ap.add_argument("--train", default="{}")
    ap.add_argument("--levels", default="")
    ap.add_argument("--exemplars", default="", help="comma-separated exemplar indices (default: all)")
    ap.add_argument("--recipe", default="", help="a model/recipes.py recipe applied before the overrides")
    a = ap.parse_args()
    sset = resolve_style_set(a.set)
    exemplars = exemplars_from_set(sset)
    if a.exemplars:
        exemplars = [exemplars[int(i)] for i in a.exemplars.split(",")]
    cfg = ModelConfig.lean(len(sset.vocabulary.parts), len(exemplars))
    if a.levels:
        levels = tuple(LevelSpec(d["width"], Upsampler(d.get("upsampler", "conv_transpose")), d.get("n_convs", 1),
                                 d.get("head_kernel", 3)) for d in json.loads(a.levels))
        cfg = dataclasses.replace(cfg, levels=levels)
    losses = json.loads(a.losses)
    if "up_level_weights" in losses:
        losses["up_level_weights"] = tuple(losses["up_level_weights"])
    tcfg = TrainConfig(out_dir=a.out, steps=a.steps, seed=a.seed, resolution=a.resolution, device="cpu",
                       checkpoint_every=50, command=" ".join(shlex.quote(x) for x in sys.argv),
                       **({"recipe": a.recipe} if a.recipe else {}))
    if a.recipe:
        cfg, tcfg = recipe_configs(a.recipe, cfg, tcfg)
    cfg = dataclasses.replace(cfg, **json.loads(a.model), losses=dataclasses.replace(cfg.losses, **losses))
    tcfg = dataclasses.replace(tcfg, **json.loads(a.train))
    t0 = time.time()

    def progress(step: int, total: int, losses: dict[str, float]) -> None:
        if step % 25 == 0 or step == total:
            print(f"step {step}/{total} {time.time() - t0:.0f}s " + " ".join(f"{k} {v:.4f}" for k, v in losses.items()),
                  flush=True)

    res = train(exemplars, cfg, tcfg, part_aliases=sset.vocabulary.alias_map(), progress=progress,
                teacher_set=sset if not a.exemplars else None)
    rows = [json.loads(line) for line in open(res.log)]
    for r in rows:
        if "monitor" in r:
            print("monitor", r["step"], json.dumps(r["monitor"]), flush=True)
    print(f"done {res.step} steps, {res.seconds_per_iteration:.2f} s/it mean this session", flush=True)


if __name__ == "__main__":
    main()

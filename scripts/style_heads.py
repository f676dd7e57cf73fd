"""Can the discriminators tell the styles apart? Two readings of the style heads on the real exemplars.

    # a training state's own heads on every exemplar (MONITOR_SEED placement), per level
    .venv/bin/python scripts/style_heads.py heads runs/R/last.pt [--set things]
    # a fresh discriminator of the state's layout trained as a softmax style classifier
    .venv/bin/python scripts/style_heads.py probe runs/R/last.pt --level 2 --steps 300 [--one-style-per-step]
    # the state's own discriminators at the classified levels trained so, written as a new state
    .venv/bin/python scripts/style_heads.py warm runs/R/last.pt --out runs/W/last.pt --steps 600

``heads``: per supervised level, the mean of every style head (sigmoid) over the real exemplar's
global mask; "own" is the exemplar's own head, "other" the mean of the rest, then how often the
own head is the largest and its mean rank (0 = top; chance (N − 1)/2). The softmax reading
(``--logits``) takes the pre-sigmoid outputs' mean instead, what the classification terms train.

``probe``: a discriminator of level k's layout, new weights, trained with softmax cross-entropy
(Adam 1e-3) on surface crops (``model.style_bank.surface_crop``, ``--crop`` voxels) of the
exemplars' level targets at 4 random placements per style, tested on crops of 2 other placements:
per step one crop of every style (a batch of N), or with ``--one-style-per-step`` the crops of one
style (N of them), as the LSGAN heads are trained. Prints the loss every 50 steps, then per split
the position accuracy and the top-1 of the mean over 8 crops. Single thread by default.

``warm``: the same training, applied to the state's own discriminators at every level the state's
recipe classifies (``LossConfig.style_classifier_from`` on), from their weights, with a fresh Adam
(the state's D moments are kept for the run); writes ``--out`` with the meta entry
``style_classifier_warmed`` (steps, learning rate, crop, step). In the run, one classification step
of D's learning rate (1e-4) per iteration teaches the heads ~10× slower than this.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import torch
from torch.nn import functional as F

from model.checkpoint import load_checkpoint, save_checkpoint
from model.data import AugmentConfig, exemplars_from_set, style_sample
from model.monitor import MONITOR_SEED
from model.losses import real_style_targets, style_classification_loss
from model.networks import build_discriminators
from model.style_bank import crop_edge, surface_crop
from model.views import SampleView
from stylesets.registry import resolve_style_set


def _exemplars(ck, set_name: str):
    by = {e.name: e for e in exemplars_from_set(resolve_style_set(set_name))}
    return [by[n] for n in ck.style_names]


def _whole_view(exemplars, style: int, cfg, seed: int, draw: int) -> SampleView:
    sample = style_sample(exemplars, style, cfg, AugmentConfig(resolution=256), seed, draw)
    return SampleView(sample, None, len(cfg.levels), "cpu")


def heads(ck, exemplars, logits: bool) -> None:
    cfg, n = ck.config, len(exemplars)
    discs = build_discriminators(cfg)
    discs.load_state_dict(ck.discriminators)
    levels = cfg.supervised_levels
    score = np.zeros((len(levels), n, n + 1))
    with torch.inference_mode():
        for s in range(n):
            view = _whole_view(exemplars, s, cfg, MONITOR_SEED, s)
            for k, (j, d) in enumerate(zip(levels, discs)):
                out = d.logits(view.target(j)) if logits else d(view.target(j))
                m = torch.as_tensor(view.masks(j, tuple(out.shape[2:]), cfg).global_).float().expand_as(out[:, :1])
                score[k, s] = ((out * m).sum((0, 2, 3, 4)) / m.sum().clamp_min(1)).numpy()
    for k, j in enumerate(levels):
        c = score[k, :, :n]
        own = np.diag(c)
        other = (c.sum(1) - own) / max(n - 1, 1)
        rank = np.array([(c[s] > c[s, s]).sum() for s in range(n)])
        print(f"level {j}: own head {own.mean():.3f}, other heads {other.mean():.3f}, global {score[k, :, n].mean():.3f};"
              f" own head top for {(rank == 0).sum()}/{n}, mean rank {rank.mean():.1f} (chance {(n - 1) / 2:.1f})")


def _splits(exemplars, cfg, j: int) -> dict[str, list[list[torch.Tensor]]]:
    """Per split, per style, level j's whole targets (1, 1, …) at 4 training / 2 test placements."""
    return {name: [[_whole_view(exemplars, s, cfg, 7, d).target(j) for d in draws] for s in range(len(exemplars))]
            for name, draws in (("train", range(4)), ("test", range(100, 102)))}


def train_classifier(disc, split, steps: int, crop: int, one_style: bool, lr: float = 1e-3) -> None:
    """Softmax cross-entropy on the style heads of ``disc`` over crops of ``split["train"]``; then both splits' accuracy."""
    n, t0 = len(split["train"]), time.time()
    opt = torch.optim.Adam(disc.parameters(), lr)
    rng = np.random.default_rng(0)
    for it in range(steps):
        if one_style:
            s = int(rng.integers(n))
            styles = [s] * n
        else:
            styles = list(range(n))
        x = torch.cat([surface_crop(split["train"][s][rng.integers(4)], crop, rng) for s in styles])
        logits = disc.logits(x)
        loss = style_classification_loss(logits, real_style_targets(logits, torch.tensor(styles)))
        opt.zero_grad()
        loss.backward()
        opt.step()
        if it % 50 == 0 or it == steps - 1:
            print(f"step {it}: cross-entropy {loss.item():.3f} (chance {np.log(n):.3f}), {time.time() - t0:.0f} s",
                  flush=True)
    check = np.random.default_rng(1)
    with torch.no_grad():
        for name, per_style in split.items():
            top, pos = [], []
            for s in range(n):
                for t in per_style[s]:
                    p = F.softmax(disc.logits(torch.cat([surface_crop(t, crop, check) for _ in range(8)]))[:, :n], 1)
                    pos.append(float((p.argmax(1) == s).float().mean()))
                    top.append(int(p.mean((0, 2, 3, 4)).argmax() == s))
            print(f"{name}: position accuracy {np.mean(pos):.3f}, top-1 of 8 crops {np.mean(top):.3f} "
                  f"(chance {1 / n:.3f})", flush=True)


def probe(ck, exemplars, k: int, steps: int, crop: int, one_style: bool) -> None:
    j = ck.config.supervised_levels[k]
    t0 = time.time()
    split = _splits(exemplars, ck.config, j)
    print(f"level {j}: {len(exemplars)} styles, crops of {crop}, data {time.time() - t0:.0f} s", flush=True)
    torch.manual_seed(0)
    train_classifier(build_discriminators(ck.config)[k], split, steps, crop, one_style)


def warm(ck, exemplars, steps: int, out: str, lr: float = 1e-3) -> None:
    cfg, lc = ck.config, ck.config.losses
    if lc.style_classifier <= 0:
        raise SystemExit("the state's recipe has no style classification term: branch it into one first")
    discs = build_discriminators(cfg)
    discs.load_state_dict(ck.discriminators)
    run = ck.training.get("train_config") or {}
    for k in range(lc.style_classifier_from, len(cfg.supervised_levels)):
        j = cfg.supervised_levels[k]
        print(f"level {j}: warming the state's discriminator", flush=True)  # on the run's crop edge
        edge = crop_edge(lc.style_classifier_crop, j, int(run.get("window_cells", 4)), int(run.get("whole_levels", 2)))
        train_classifier(discs[k], _splits(exemplars, cfg, j), steps, edge, False, lr)
    step = int(ck.training.get("step", 0))
    training = {**ck.training, "style_classifier_warmed": {"steps": steps, "lr": lr,
                                                           "crop": lc.style_classifier_crop, "step": step}}
    save_checkpoint(out, dataclasses.replace(ck, discriminators=discs.state_dict(), training=training))
    print(f"{out}: step {step}, discriminators warmed {steps} steps per classified level")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=("heads", "probe", "warm"))
    ap.add_argument("checkpoint")
    ap.add_argument("--set", default="things", help="the style set the state was trained on")
    ap.add_argument("--logits", action="store_true", help="heads: read the pre-sigmoid outputs")
    ap.add_argument("--level", type=int, default=2, help="probe: index into the supervised levels")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--crop", type=int, default=40)
    ap.add_argument("--one-style-per-step", action="store_true")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", help="warm: the state to write")
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    ck = load_checkpoint(a.checkpoint, training_state=a.what != "probe")
    exemplars = _exemplars(ck, a.set)
    if a.what == "heads":
        heads(ck, exemplars, a.logits)
    elif a.what == "probe":
        probe(ck, exemplars, a.level, a.steps, a.crop, a.one_style_per_step)
    else:
        if not a.out:
            raise SystemExit("warm needs --out")
        warm(ck, exemplars, a.steps, a.out)


if __name__ == "__main__":
    main()

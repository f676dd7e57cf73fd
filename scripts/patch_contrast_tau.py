"""How well does a nearest window patch tell the styles apart, and at which softmax temperature?

    .venv/bin/python scripts/patch_contrast_tau.py runs/R/last.pt [--set things] [--taus 0.005 0.01 0.02 0.05 0.1]

For each style, the real targets of two placements of its exemplar at each level the state's recipe
classifies (``LossConfig.style_classifier_from`` on): ``CONTRAST_REAL`` band patches of the first
placement form the style's library, ``PATCHES_OUT`` band patches of the second are classified by
``nearest_style_logits`` against every style's library. Prints per level the top-1 accuracy (chance
1/N), the share of queries whose nearest distance ties across all styles (flat faces), and the mean
cross-entropy at each temperature: ``CONTRAST_TAU`` is the temperature of least cross-entropy on real
shapes, i.e. the one under which real patches are classified as confidently as they deserve.
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from torch.nn import functional as F

from model.checkpoint import load_checkpoint
from model.data import AugmentConfig, exemplars_from_set, style_sample
from model.texture_stats import (CONTRAST_REAL, PATCHES_OUT, window_band_patches, nearest_style_logits)
from model.views import SampleView
from stylesets.registry import resolve_style_set


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("state")
    ap.add_argument("--set", default="things")
    ap.add_argument("--taus", type=float, nargs="+", default=[0.005, 0.01, 0.02, 0.05, 0.1])
    a = ap.parse_args()
    torch.set_num_threads(1)
    ck = load_checkpoint(a.state, training_state=False)
    cfg, lc = ck.config, ck.config.losses
    by = {e.name: e for e in exemplars_from_set(resolve_style_set(a.set))}
    exemplars = [by[n] for n in ck.style_names]
    levels = cfg.supervised_levels[lc.style_classifier_from:]
    rng = np.random.default_rng(0)
    n = len(exemplars)
    views = [[SampleView(style_sample(exemplars, s, cfg, AugmentConfig(resolution=256), 7, d), None,
                         cfg.n_levels, "cpu") for d in (0, 1)] for s in range(n)]
    with torch.no_grad():
        for j in levels:
            libs = [window_band_patches(views[s][0].target(j), lc.texture_band, lc.texture_patch, CONTRAST_REAL, rng)
                    for s in range(n)]
            logits, labels = [], []
            for s in range(n):
                q = window_band_patches(views[s][1].target(j), lc.texture_band, lc.texture_patch, PATCHES_OUT, rng)
                logits.append(nearest_style_logits(q, libs, 1.0))
                labels.append(torch.full((len(q),), s, dtype=torch.int64))
            lg, lb = torch.cat(logits), torch.cat(labels)
            acc = float((lg.argmax(1) == lb).float().mean())
            ties = float((lg.max(1).values - lg.min(1).values < 1e-6).float().mean())
            ces = "  ".join(f"τ {t:g}: {float(F.cross_entropy(lg / t, lb)):.3f}" for t in a.taus)
            print(f"level {j} ({views[0][0].target(j).shape[2]}³-scale): top-1 {acc:.3f} (chance {1 / n:.3f}), "
                  f"ties {ties:.3f}; cross-entropy (ln N = {np.log(n):.3f}) {ces}", flush=True)


if __name__ == "__main__":
    main()

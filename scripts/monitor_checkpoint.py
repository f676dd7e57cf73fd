"""The training monitor's figures (``model/monitor.py``) for a saved checkpoint, with quilt's figure too.

    .venv/bin/python scripts/monitor_checkpoint.py RUN/last.pt [--set things] [--no-quilt] [--per-exemplar]

Prints one JSON line: the checkpoint's step and recipe and ``Monitor.figures`` of its
generator on the run's own monitor inputs (the run's resolution, ``MONITOR_SEED``), plus
``quilt_iou`` (IOU with quilt's output on the same contents and styles) unless
``--no-quilt``: so a run that does not distil can be compared with one that does on that
figure. The exemplars are the set's exemplars the checkpoint was trained on, by name (all of
the set, or the one or few of an overfit run of ``scripts/ab_recipe.py --exemplars``).
``--style-offset centre`` measures at the reference's placement whatever the run trained with
(so a random-offset run compares with a ``"centre"`` one on the same inputs). ``--per-exemplar``
adds ``self_iou_raw_by_exemplar`` / ``self_iou_by_exemplar`` (name → IOU
without / with the config's projection). Cost at R = 256 on 2 cores: about a minute (eight
quilt detailizations once).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from model.checkpoint import load_checkpoint
from model.data import AugmentConfig, exemplars_from_set, parse_style_offset
from model.distill import QuiltTeacher
from model.monitor import Monitor
from model.networks import Generator
from stylesets.registry import resolve_style_set


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("checkpoint", type=Path)
    ap.add_argument("--set", default="things")
    ap.add_argument("--no-quilt", action="store_true")
    ap.add_argument("--min-cell-fill", type=float, default=None, help="override the config's projection (0 = off)")
    ap.add_argument("--thin-only", action="store_true", help="project one-cell-thick cells only (min_fill_thin_only)")
    ap.add_argument("--style-offset", default=None,
                    help='place the exemplars as "centre" (the reference) or "random", instead of as the run did')
    ap.add_argument("--per-exemplar", action="store_true", help="also each exemplar's self-reconstruction IOU")
    a = ap.parse_args()
    ck = load_checkpoint(a.checkpoint)
    sset = resolve_style_set(a.set)
    by_name = {e.name: e for e in exemplars_from_set(sset)}
    missing = [n for n in ck.style_names if n not in by_name]
    if missing:
        raise SystemExit(f"{a.checkpoint}: styles {missing} are not in the set {a.set!r}")
    exemplars = [by_name[n] for n in ck.style_names]  # the checkpoint's style order
    cfg = ck.config if a.min_cell_fill is None else dataclasses.replace(ck.config, min_cell_fill=a.min_cell_fill)
    if a.thin_only:
        cfg = dataclasses.replace(cfg, min_fill_thin_only=True)
    gen = Generator(cfg)
    gen.load_state_dict(ck.generator)
    offset = ck.training["train_config"].get("style_offset")  # a fixed-offset run: its placement
    if a.style_offset is not None:  # e.g. a random-offset run measured at the reference's placement
        offset = None if a.style_offset == "random" else a.style_offset
    aug = AugmentConfig(resolution=int(ck.training["train_config"]["resolution"]),
                        style_offset=parse_style_offset(offset))
    teacher = None if a.no_quilt else QuiltTeacher(exemplars, sset)
    figures = Monitor(exemplars, cfg, aug, teacher).figures(gen, per_exemplar=a.per_exemplar)
    if a.per_exemplar:
        for key in ("self_iou_raw", "self_iou"):
            figures[f"{key}_by_exemplar"] = dict(zip((e.name for e in exemplars), figures.pop(f"{key}_each")))
    print(json.dumps({"checkpoint": str(a.checkpoint), "step": ck.training.get("step"),
                      "recipe": ck.training.get("recipe"), **figures}), flush=True)


if __name__ == "__main__":
    main()

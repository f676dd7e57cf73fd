"""Mean and per-exemplar self-reconstruction IOU of checkpoints under three projections: raw, thin cells only, and
every occupied cell raised to half full (the `warmup` recipe's), on the monitor's own inputs.

    .venv/bin/python scripts/selfrec_projections.py CKPT [CKPT ...]   # one JSON line each

A `warmup_low` checkpoint logs the thin-only figure, the `warmup` run logged the all-cells one: this puts both
on one footing (model/weights/things_selfrec.md, 2026-12-03 afternoon). About 1 min a checkpoint on 2 cores."""
import json, sys
import numpy as np
from model.checkpoint import load_checkpoint
from model.data import AugmentConfig, exemplars_from_set
from model.finish import min_fill_projection
from model.monitor import Monitor, detailize_field, _iou, ISO_LEVEL
from model.networks import Generator
from model.data import EMPTY
from stylesets.registry import resolve_style_set

sset = resolve_style_set("things")
by_name = {e.name: e for e in exemplars_from_set(sset)}
mon = None
for p in sys.argv[1:]:
    ck = load_checkpoint(p)
    cfg = ck.config
    gen = Generator(cfg); gen.load_state_dict(ck.generator); gen.eval()
    names = list(ck.style_names)
    if mon is None:
        mon = Monitor([by_name[n] for n in names], cfg, AugmentConfig(resolution=int(ck.training["train_config"]["resolution"])))
    styles, _ = mon._inputs()
    f = cfg.factor
    raw, thin, allc = [], [], []
    for s in styles:
        field = detailize_field(gen, s)
        truth = s.fine_labels != EMPTY
        raw.append(_iou(field > ISO_LEVEL, truth))
        thin.append(_iou(min_fill_projection(field.copy(), s.coarse_occupancy, f, 0.5, thin_only=True) > ISO_LEVEL, truth))
        allc.append(_iou(min_fill_projection(field.copy(), s.coarse_occupancy, f, 0.5, thin_only=False) > ISO_LEVEL, truth))
    r = lambda v: round(float(v), 4)
    print(json.dumps({"checkpoint": p, "step": ck.training.get("step"), "recipe": ck.training.get("recipe"),
                      "raw": r(np.mean(raw)), "thin": r(np.mean(thin)), "all": r(np.mean(allc)),
                      "raw_min": r(min(raw)), "all_min": r(min(allc)),
                      "raw_by": {n: r(x) for n, x in zip(names, raw)},
                      "all_by": {n: r(x) for n, x in zip(names, allc)}}), flush=True)

"""Do thin features survive? Issue 15's check on the protocol's texts and CAD contents.

    .venv/bin/python scripts/check_thin.py [--checkpoint model/weights/things.pt] [--min-cell-fill 0.5] [--thin-only]
                                           [--kinds text,cad] [--style cottage] [--speck-voxels 16]

For each content of those kinds, one output (every part in ``--style``): the occupied
fraction of every occupied input cell's 16³ block (the worst cell, and the share of
cells at ≥ 50 %), the output's extent along each axis against the input's (fine voxels;
the worst ratio), Strict- and Loose-IOU (×16 max-pool against the input), and the pieces the
output adds (26-connected components of the output minus those of the input: loose cubes, specks).
``--min-cell-fill`` overrides the checkpoint's ``min_cell_fill`` (the inference
projection of ``model/infer.py``), to see what it changes on the same weights; ``--speck-voxels``
the size of the specks inference removes (0 keeps them; default ``model.finish.SPECK_VOXELS``).
Acceptance (issue 15): every cell ≥ 50 % occupied and every extent within 5 %.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from evaluation.protocol import load_protocol
from model.finish import SPECK_VOXELS
from model.infer import DecollageDetailizer
from model.monitor import cell_fill, pieces
from core.grid import EMPTY, ISO_LEVEL, LabeledGrid


def _extent(mask: np.ndarray) -> np.ndarray:
    idx = np.argwhere(mask)
    return idx.max(axis=0) - idx.min(axis=0) + 1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--checkpoint", default=None)
    ap.add_argument("--min-cell-fill", type=float, default=None)
    ap.add_argument("--kinds", default="text,cad")
    ap.add_argument("--style", default="cottage")
    ap.add_argument("--speck-voxels", type=int, default=SPECK_VOXELS)
    ap.add_argument("--thin-only", action="store_true", help="project one-cell-thick cells only (min_fill_thin_only)")
    a = ap.parse_args()
    det = DecollageDetailizer(a.checkpoint, device="cpu", speck_voxels=a.speck_voxels)
    if a.min_cell_fill is not None:
        det.ckpt = dataclasses.replace(det.ckpt, config=dataclasses.replace(det.ckpt.config,
                                                                          min_cell_fill=a.min_cell_fill))
    if a.thin_only:
        det.ckpt = dataclasses.replace(det.ckpt, config=dataclasses.replace(det.ckpt.config, min_fill_thin_only=True))
    proto = load_protocol()
    kinds = set(a.kinds.split(","))
    f = det.ckpt.config.factor
    rows = []
    for cid, labels in proto.contents.items():
        if proto.content_info[cid].get("kind") not in kinds:
            continue
        occ = labels >= 0
        part = np.where(occ, labels, EMPTY).astype(np.int16)
        style = np.where(occ, 0, EMPTY).astype(np.int16)
        grid = LabeledGrid(occ, part, style, proto.parts, (a.style,), voxel_size_m=0.1)
        t = time.perf_counter()
        out = det.detailize(grid).occupancy > ISO_LEVEL
        dt = time.perf_counter() - t
        fills = cell_fill(out, occ, f)
        x, y, z = occ.shape
        pooled = out.reshape(x, f, y, f, z, f).any(axis=(1, 3, 5))
        ext = _extent(out) / (_extent(occ) * f) if out.any() else np.zeros(3)
        rows.append((cid, fills.min(), float(np.mean(fills >= 0.5)), float(np.abs(ext - 1).max()),
                     (pooled & occ).sum() / (pooled | occ).sum(), (pooled & occ).sum() / occ.sum(),
                     pieces(out) - pieces(occ), dt))
    print(f"checkpoint {det.checkpoint_path}, specks ≤ {det.speck_voxels} voxels removed, "
          f"min_cell_fill {det.ckpt.config.min_cell_fill}, "
          f"thin only {det.ckpt.config.min_fill_thin_only}, style {a.style}")
    print("| content | worst cell fill | cells ≥ 50 % | worst extent error | Strict | Loose | added pieces | s |")
    print("|---|---|---|---|---|---|---|---|")
    for cid, fmin, half, ext, strict, loose, added, dt in rows:
        print(f"| {cid} | {fmin:.3f} | {half:.3f} | {ext:.3f} | {strict:.3f} | {loose:.3f} | {added} | {dt:.1f} |")
    arr = np.array([r[1:7] for r in rows], dtype=float)
    print(f"| all {len(rows)} | {arr[:, 0].min():.3f} | {arr[:, 1].mean():.3f} | {arr[:, 2].max():.3f} | "
          f"{arr[:, 3].mean():.3f} | {arr[:, 4].mean():.3f} | {arr[:, 5].mean():.1f} mean | |")


if __name__ == "__main__":
    main()

"""One content in every single style, per detailizer: does the style change the output, and how?

    .venv/bin/python scripts/style_sheet.py OUT.png CKPT.pt [CKPT.pt ...] [--content ID ...] [--quilt]

For each content (default: the test split's first CAD content and first augmented exemplar),
one block of rows: the exemplar of each style (the target look), quilt's output (with
``--quilt``), then every checkpoint's output; one column per single-style assignment of that
content in the protocol (things_v2). Each row's label gives its style overlap on that content
(mean IOU between its outputs in two styles; ``evaluation.style_overlap``; 1 = style-blind).
Cells are the evaluation contact sheet's depth-shaded renders from its fixed view, 192 px.
Cost on 2 cores: about 2 s per learned output, 1 s per quilt output, plus the renders.
"""

from __future__ import annotations

import argparse
import io
from pathlib import Path

import numpy as np

CELL = 192
LABEL_W = 260


def _render(binary: np.ndarray) -> np.ndarray:
    from evaluation.contact_sheet import VIEW
    from evaluation.render_eval import render_depth_shaded

    return render_depth_shaded(binary, [VIEW[0]], [VIEW[1]], size=CELL)[0]


def _label(path: Path) -> str:
    """A checkpoint's row label: its file name, with its run folder for a run's own files
    (``model.pt``, ``model_ema.pt``, ``last.pt``)."""
    return f"{path.parent.name}/{path.name}" if path.stem in ("model", "model_ema", "last") else path.stem


def main() -> None:
    from PIL import Image, ImageDraw

    from core.detailizer import get_detailizer
    from core.files import write_bytes_atomic
    from core.grid import ISO_LEVEL
    from evaluation.protocol import DEFAULT_PROTOCOL, load_protocol, resolve_protocol_set
    from evaluation.style_overlap import pack, pairwise_overlap

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("checkpoints", type=Path, nargs="+")
    ap.add_argument("--content", action="append", default=None, help="protocol content id (repeatable)")
    ap.add_argument("--quilt", action="store_true", help="add a row of quilt's outputs")
    a = ap.parse_args()

    protocol = load_protocol(DEFAULT_PROTOCOL)
    style_set = resolve_protocol_set(protocol)
    test = list(protocol.split["test"])
    contents = a.content or [next(c for c in test if protocol.content_info[c].get("kind") == k)
                             for k in ("cad", "augmented_exemplar")]
    dets = ([("quilt", get_detailizer("quilt", None, "cpu"))] if a.quilt else []) + [
        (_label(p), get_detailizer("decollage", str(p), "cpu")) for p in a.checkpoints]
    names = [e.name for e in style_set.exemplars]
    rows: list[tuple[str, list[np.ndarray]]] = []
    n_cols = 0
    for content in contents:
        outs = [o for o in protocol.outputs if o.content == content and not o.mixed]
        styles = [next(iter(o.styles.values())) for o in outs]
        n_cols = max(n_cols, len(outs))
        rows.append((f"{content}\nthe styles' exemplars:\n" + "\n".join(styles),
                     [_render(style_set.exemplars[names.index(s)].full(style_set.resolution) > 0) for s in styles]))
        for label, det in dets:
            binaries = [np.asarray(det.detailize(protocol.grid(o), seed=0).occupancy) > ISO_LEVEL for o in outs]
            ov = pairwise_overlap([pack(b) for b in binaries])
            mean = float(np.mean(ov)) if ov and ov[0] is not None else float("nan")
            rows.append((f"{label}\nstyle overlap {mean:.3f}", [_render(b) for b in binaries]))
            print(f"{content} {label}: style overlap {mean:.3f}", flush=True)
    img = Image.new("L", (LABEL_W + CELL * n_cols, CELL * len(rows)), 255)
    draw = ImageDraw.Draw(img)
    for i, (label, cells) in enumerate(rows):
        y = i * CELL
        draw.line([(0, y), (img.width, y)], fill=200)
        draw.multiline_text((8, y + 8), label, fill=0, spacing=4)
        for j, cell in enumerate(cells):
            img.paste(Image.fromarray(cell), (LABEL_W + j * CELL, y))
    buf = io.BytesIO()
    img.save(buf, format="PNG", optimize=True)
    write_bytes_atomic(a.out, buf.getvalue())
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()

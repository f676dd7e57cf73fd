"""The fixed evaluation contact sheet: the same outputs and views every time, one column per detailizer.

Rows (``sheet_rows``): 8 outputs of the protocol's test split — 4 single-style
and 4 mixed, each from a different content, spread over the split's
contents — then 4 self-reconstructions (the first held-out augmentation of
the first exemplar of 4 categories). Columns: one per detailizer in the order
given (upsample | quilt | decollage), then the true fine shape for the
self-reconstruction rows. Every cell is a depth-shaded render
(``evaluation.render_eval``) from the fixed view ``VIEW``, 256² pixels;
the PNG is written atomically.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from core.grid import ISO_LEVEL

#: (azimuth, elevation) of every cell, radians: front-right, slightly from above.
VIEW = (0.7, 0.45)
CELL = 256
LABEL_W = 230
HEADER_H = 28
N_SINGLE_ROWS, N_MIXED_ROWS, N_SELF_ROWS = 4, 4, 4


def sheet_rows(protocol, style_set) -> tuple[list, list]:
    """(protocol outputs, self-reconstruction cases) drawn on the sheet (see the module docstring)."""
    from evaluation.selfrec import self_cases

    contents = list(protocol.split["test"]) if protocol.split else list(protocol.contents)
    n = len(contents)
    outputs = []
    for k in range(N_SINGLE_ROWS + N_MIXED_ROWS):
        mixed = k >= N_SINGLE_ROWS
        content = contents[(k * n) // (N_SINGLE_ROWS + N_MIXED_ROWS) % n]
        outputs.append(next(o for o in protocol.outputs if o.content == content and o.mixed == mixed))
    cases, seen = [], set()
    for case in self_cases(style_set, n_aug=1):
        cat = style_set.exemplars[case.exemplar].category
        if case.held_out and cat not in seen and len(cases) < N_SELF_ROWS:
            seen.add(cat)
            cases.append(case)
    return outputs, cases


def _render(binary: np.ndarray) -> np.ndarray:
    from evaluation.render_eval import render_depth_shaded

    return render_depth_shaded(binary, [VIEW[0]], [VIEW[1]], size=CELL)[0]


def contact_sheet(protocol, detailizers: Sequence, style_set, path: Path,
                  progress: Callable[[str], None] | None = None) -> Path:
    """Draw the sheet of ``detailizers`` (one column each, plus the truth for self-reconstructions) to ``path``."""
    from PIL import Image, ImageDraw

    from core.files import write_bytes_atomic

    say = progress or (lambda line: None)
    outputs, cases = sheet_rows(protocol, style_set)
    parts = tuple(style_set.vocabulary.parts)
    cols = [d.name for d in detailizers] + ["true shape"]
    rows: list[tuple[str, list[np.ndarray | None]]] = []
    for o in outputs:
        grid = protocol.grid(o)
        styles = " / ".join(dict.fromkeys(o.styles[p] for p in protocol.parts))
        cells = [_render(np.asarray(d.detailize(grid, seed=0).occupancy) > ISO_LEVEL) for d in detailizers]
        rows.append((f"{o.id}\n{'mixed' if o.mixed else 'single'}: {styles}", cells + [None]))
        say(f"sheet: {o.id}")
    for c in cases:
        grid = c.grid(parts)
        cells = [_render(np.asarray(d.detailize(grid, seed=0).occupancy) > ISO_LEVEL) for d in detailizers]
        rows.append((f"{c.id}\nself-reconstruction", cells + [_render(c.fine)]))
        say(f"sheet: {c.id}")
    width, height = LABEL_W + CELL * len(cols), HEADER_H + CELL * len(rows)
    img = Image.new("L", (width, height), 255)
    draw = ImageDraw.Draw(img)
    for j, name in enumerate(cols):
        draw.text((LABEL_W + j * CELL + 8, 8), name, fill=0)
    for i, (label, cells) in enumerate(rows):
        y = HEADER_H + i * CELL
        draw.line([(0, y), (width, y)], fill=200)
        draw.multiline_text((8, y + 8), label, fill=0, spacing=4)
        for j, cell in enumerate(cells):
            if cell is not None:
                img.paste(Image.fromarray(cell), (LABEL_W + j * CELL, y))
    import io

    buf = io.BytesIO()
    img.save(buf, format="PNG", optimize=True)
    write_bytes_atomic(Path(path), buf.getvalue())
    return Path(path)

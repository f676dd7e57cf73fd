"""Style colours: one fixed RGBA colour per style, used for vertex colours and previews.

Colours are assigned by a style's *index* in the grid's ``style_names`` (not by
its name), so an asset's first style is always brick red, its second slate
blue, and so on; the same recipe therefore always gives the same colours. The
twelve colours are muted enough to look pleasant on a game asset preview and
far enough apart (hue and lightness) to tell regions apart at a glance. With
more than twelve styles the palette repeats.
"""

from __future__ import annotations

import numpy as np

#: (name, RGB) in assignment order. Neighbours differ strongly in hue so that
#: the first few styles of an asset (the usual case) are the most distinct.
PALETTE: tuple[tuple[str, tuple[int, int, int]], ...] = (
    ("brick", (193, 80, 62)),
    ("slate", (78, 121, 167)),
    ("ochre", (226, 176, 62)),
    ("moss", (96, 153, 79)),
    ("plum", (151, 95, 158)),
    ("teal", (62, 160, 158)),
    ("orange", (232, 126, 46)),
    ("stone", (168, 160, 150)),
    ("rose", (232, 142, 170)),
    ("walnut", (139, 100, 72)),
    ("navy", (52, 64, 110)),
    ("lime", (176, 200, 80)),
)

#: Colour for voxels without a valid style (e.g. EMPTY = -1): a neutral light grey.
NEUTRAL_RGBA: tuple[int, int, int, int] = (190, 190, 190, 255)


def style_color(name: str, index: int) -> tuple[int, int, int, int]:
    """RGBA (uint8 values) of the style at ``index`` in ``style_names``.

    ``name`` is accepted for readability at call sites and future use; the
    colour depends on ``index`` only (deterministic, independent of naming).
    A negative index (no style) gives ``NEUTRAL_RGBA``.
    """
    del name  # the colour is defined by position, see the module docstring
    if index < 0:
        return NEUTRAL_RGBA
    r, g, b = PALETTE[index % len(PALETTE)][1]
    return (r, g, b, 255)


def palette_rgba(style_names: tuple[str, ...] | list[str]) -> np.ndarray:
    """(N + 1, 4) uint8 lookup table: rows 0..N-1 are the styles, row N is neutral.

    Index it with ``np.where(valid, style, N)`` to colour style arrays that may
    hold EMPTY or out-of-range values.
    """
    rows = [style_color(name, i) for i, name in enumerate(style_names)]
    rows.append(NEUTRAL_RGBA)
    return np.asarray(rows, dtype=np.uint8)

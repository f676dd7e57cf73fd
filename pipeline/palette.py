"""Style colours: one fixed RGBA colour per style, used for vertex colours and previews.

Colours follow the style's *name*: a stable hash of the name picks its palette
slot, so "moss" has the same colour in every asset of a batch. Within one asset,
a style whose slot an earlier style already took moves to the next free slot,
so an asset's styles always differ while it has at most twelve. The twelve
colours are muted enough to look pleasant on a game asset preview and far
enough apart (hue and lightness) to tell regions apart at a glance.
"""

from __future__ import annotations

import hashlib

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
    """RGBA (uint8 values) of palette slot ``index`` (wrapping); a negative index gives ``NEUTRAL_RGBA``.

    ``name`` is kept for call-site readability; ``palette_rgba`` decides slots from names.
    """
    del name
    if index < 0:
        return NEUTRAL_RGBA
    r, g, b = PALETTE[index % len(PALETTE)][1]
    return (r, g, b, 255)


def preferred_slot(name: str) -> int:
    """The palette slot a style name asks for: a stable hash (not Python's salted ``hash``)."""
    return int.from_bytes(hashlib.sha256(name.encode("utf-8")).digest()[:4], "little") % len(PALETTE)


def palette_rgba(style_names: tuple[str, ...] | list[str]) -> np.ndarray:
    """(N + 1, 4) uint8 lookup table: rows 0..N-1 are the styles, row N is neutral.

    Index it with ``np.where(valid, style, N)`` to colour style arrays that may
    hold EMPTY or out-of-range values.
    """
    taken: set[int] = set()
    rows = []
    for name in style_names:
        slot = preferred_slot(name)
        for step in range(len(PALETTE)):
            if (slot + step) % len(PALETTE) not in taken:
                slot = (slot + step) % len(PALETTE)
                break
        taken.add(slot)
        rows.append(style_color(name, slot))
    rows.append(NEUTRAL_RGBA)
    return np.asarray(rows, dtype=np.uint8)

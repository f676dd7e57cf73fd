"""Text shaping for the lines of a ``text`` source that need it: HarfBuzz, with right-to-left runs.

Role: ``sources/text.py`` sets simple lines itself (one glyph per character from
the cmap, ``kern``-table pairs). A line that contains any character for which
that would give wrong text is shaped here instead, with HarfBuzz (the
``uharfbuzz`` binding): a right-to-left letter (bidi class R or AL: Hebrew,
Arabic, Syriac, Thaana, N'Ko...), an Arabic-Indic digit (AN), a combining mark
(Mn, Mc, Me: Indic vowel signs and viramas, Thai vowels, accents the font has
no precomposed glyph for), a format control (Cf: ZWJ, ZWNJ, bidi marks), or a
character of a block whose script HarfBuzz shapes with a complex shaper
(``_COMPLEX_BLOCKS``: Indic, Sinhala, Thai, Lao, Tibetan, Myanmar, Khmer,
Hangul jamo, Mongolian...). HarfBuzz applies the font's OpenType features
(joining forms, ligatures, conjuncts, reordering, mark positioning, kerning).

Direction (``bidi_runs``): a line with a right-to-left letter is a
right-to-left paragraph; in it, numbers (European or Arabic-Indic digits, with
the separators and signs between or around them) are left-to-right runs, all
else (letters, spaces, punctuation) right-to-left, and the runs are laid out
from right to left; this is what the Unicode bidi algorithm gives for such a
line. A line without one is left to right. A line that mixes left-to-right
letters (Latin, Cyrillic...) with right-to-left ones is refused with a clear
message rather than laid out wrongly: the full bidi algorithm is not applied.

``shape_line`` returns the glyphs of one line in visual order (left to right)
with their pen positions, in font units, each with the index of the first
character of its cluster in the line. Without ``uharfbuzz`` such lines are
refused (``SourceError``), never set unshaped.
"""

from __future__ import annotations

import unicodedata
from dataclasses import dataclass

from core.errors import SourceError

#: Blocks (first, last code point) of scripts that need a complex shaper even without combining marks.
_COMPLEX_BLOCKS: tuple[tuple[int, int], ...] = (
    (0x0590, 0x08FF),  # Hebrew, Arabic, Syriac, Arabic Supplement, Thaana, N'Ko, Samaritan, Mandaic...
    (0x0900, 0x0DFF),  # Devanagari, Bengali, Gurmukhi, Gujarati, Oriya, Tamil, Telugu, Kannada, Malayalam, Sinhala
    (0x0E00, 0x0FFF),  # Thai, Lao, Tibetan
    (0x1000, 0x109F),  # Myanmar
    (0x1100, 0x11FF),  # Hangul Jamo (conjoining)
    (0x1780, 0x18AF),  # Khmer, Mongolian
    (0x1A00, 0x1AAF),  # Buginese, Tai Tham
    (0x1B00, 0x1BFF),  # Balinese, Sundanese, Batak
    (0xA800, 0xA8FF),  # Syloti Nagri, Phags-pa, Saurashtra, Devanagari Extended
    (0xA980, 0xAAFF),  # Javanese, Myanmar Extended, Cham, Tai Viet
    (0xFB1D, 0xFDFF),  # Hebrew and Arabic presentation forms A
    (0xFE70, 0xFEFF),  # Arabic presentation forms B
    (0x10A00, 0x10A5F),  # Kharoshthi
    (0x11000, 0x11FFF),  # Brahmi and the other historic Indic scripts
)
_RTL = {"R", "AL"}
_NUMBER = {"EN", "AN"}
_NUMBER_JOINERS = {"ES", "ET", "CS"}  # + - % , . : between or around digits
#: Scripts whose letters join: letter spacing would break them apart.
_JOINING = {"AL"}
_HINT_MIXED = "put the right-to-left and the left-to-right words on separate lines ('\\n')"


def needs_shaping(line: str) -> bool:
    """True when setting ``line`` glyph by glyph from the cmap would be wrong (see the module docstring)."""
    for ch in line:
        code = ord(ch)
        if code < 0x0300:
            continue
        if unicodedata.bidirectional(ch) in _RTL | {"AN"} or unicodedata.category(ch) in ("Mn", "Mc", "Me", "Cf"):
            return True
        if any(lo <= code <= hi for lo, hi in _COMPLEX_BLOCKS):
            return True
    return False


def is_joining(line: str) -> bool:
    """True when the line holds letters of a joining script (Arabic, Syriac, N'Ko...)."""
    return any(unicodedata.bidirectional(ch) in _JOINING for ch in line)


def bidi_runs(line: str) -> list[tuple[int, int, bool]]:
    """``(start, end, right_to_left)`` runs of ``line`` in visual order (left to right).

    Raises SourceError (field ``text``) for a line mixing left-to-right and right-to-left letters.
    """
    classes = [unicodedata.bidirectional(ch) for ch in line]
    has_rtl = any(c in _RTL for c in classes)
    if not has_rtl:
        return [(0, len(line), False)] if line else []
    ltr_letters = sorted({ch for ch, c in zip(line, classes) if c == "L"})
    if ltr_letters:
        shown = "".join(ltr_letters[:8])
        raise SourceError(f"a line mixes right-to-left letters with left-to-right ones ({shown!r}), which this "
                          "text layout does not support", field="text", hint=_HINT_MIXED)
    in_number = [c in _NUMBER for c in classes]
    # Separators and signs join a number when a digit is next to them (1,000.5  +5%  12:30).
    for i, c in enumerate(classes):
        if c in _NUMBER_JOINERS and ((i > 0 and classes[i - 1] in _NUMBER) or
                                     (i + 1 < len(classes) and classes[i + 1] in _NUMBER)):
            in_number[i] = True
    runs: list[tuple[int, int, bool]] = []
    start = 0
    for i in range(1, len(line) + 1):
        if i == len(line) or in_number[i] != in_number[start]:
            runs.append((start, i, not in_number[start]))
            start = i
    return list(reversed(runs))  # a right-to-left paragraph shows its first run rightmost


@dataclass(frozen=True)
class ShapedGlyph:
    """One glyph of a shaped line (font units): glyph id, the line index of its cluster's first character,
    the pen position before it, its offset from the pen (marks), and its advance."""

    gid: int
    cluster: int
    pen_x: float
    x_offset: float
    y_offset: float
    advance: float

    @property
    def x(self) -> float:
        """Where the glyph's origin goes: the pen plus the offset."""
        return self.pen_x + self.x_offset


class Shaper:
    """HarfBuzz on one font file (``data``: its bytes; ``index``: the font in a collection)."""

    def __init__(self, data: bytes, index: int = 0) -> None:
        try:
            import uharfbuzz as hb
        except ImportError:
            raise SourceError("this text needs shaping (right-to-left or complex script), but the shaping "
                              "engine uharfbuzz is not installed", field="text",
                              hint="install it (pip install uharfbuzz; bash scripts/install.sh does) or use "
                                   "text in a simple script") from None
        self._hb = hb
        self._font = hb.Font(hb.Face(data, index))

    def shape_line(self, line: str) -> list[ShapedGlyph]:
        """Glyphs of ``line`` in visual order, pen x from 0 (font units, y = 0 on the baseline)."""
        hb = self._hb
        out: list[ShapedGlyph] = []
        x = 0.0
        for start, end, rtl in bidi_runs(line):
            buffer = hb.Buffer()
            buffer.add_str(line[start:end])
            buffer.guess_segment_properties()
            buffer.direction = "rtl" if rtl else "ltr"
            hb.shape(self._font, buffer, {})
            for info, pos in zip(buffer.glyph_infos, buffer.glyph_positions):
                out.append(ShapedGlyph(int(info.codepoint), start + int(info.cluster), x, float(pos.x_offset),
                                       float(pos.y_offset), float(pos.x_advance)))
                x += pos.x_advance
        return out

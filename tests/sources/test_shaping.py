"""Text in scripts that need shaping: HarfBuzz joins, reorders and ligates; right-to-left lines run right to left."""

from __future__ import annotations

from pathlib import Path

import pytest

from core.errors import SourceError
from core.recipe import TextSource
from sources import text
from sources.shaping import bidi_runs, needs_shaping

KA, VIRAMA, SSA = "\u0915", "\u094d", "\u0937"


def spec(value: str, **fields) -> TextSource:
    return TextSource(kind="text", text=value, **fields)


def xs(placed) -> list[float]:
    return [x for char, _, x, _ in placed if not char.isspace()]


@pytest.mark.parametrize("line, shaped", [
    ("HELLO", False), ("Größe", False), ("ΑΒΓ абв", False), ("漢字", False), ("سلام", True), ("שלום", True),
    (KA + VIRAMA + SSA, True), ("e\u0301", True), ("a\u200db", True), ("١٢٣", True), ("ไทย", True),
])
def test_which_lines_need_shaping(line, shaped):
    assert needs_shaping(line) is shaped


def test_arabic_is_joined_and_runs_right_to_left():
    placed = text.layout(spec("سلام"), Path("."))
    chars = [c for c, *_ in placed]
    assert chars == ["س", "ل", "م"]  # لا became one lam-alef ligature: 3 glyphs for 4 letters
    assert xs(placed) == sorted(xs(placed), reverse=True)  # the first letter is the rightmost
    font = text._Font(text.DEFAULT_FONT, [])
    glyphs = {c: g for c, g, _, _ in placed}
    assert glyphs["س"] != font.cmap[ord("س")]  # its initial (joining) form, not the isolated letter
    assert glyphs["ل"] not in (font.cmap[ord("ل")], font.cmap[ord("ا")])  # the lam-alef ligature
    assert glyphs["م"] == font.cmap[ord("م")]  # after alef (which never joins forward) meem stands alone


def test_numbers_inside_right_to_left_text_read_left_to_right():
    placed = text.layout(spec("سلام 123"), Path("."))
    digits = [(c, x) for c, _, x, _ in placed if c.isdigit()]
    letters = [x for c, _, x, _ in placed if "\u0600" <= c <= "\u06ff"]
    assert [c for c, _ in digits] == ["1", "2", "3"]
    assert [x for _, x in digits] == sorted(x for _, x in digits)  # 1 2 3 from left to right
    assert max(x for _, x in digits) < min(letters)  # the number comes after (left of) the word
    assert bidi_runs("سلام 1,000.5%") == [(5, 13, False), (0, 5, True)]


def test_hebrew_runs_right_to_left():
    placed = text.layout(spec("שלום"), Path("."))
    assert [c for c, *_ in placed] == list("שלום") and xs(placed) == sorted(xs(placed), reverse=True)


def test_a_line_mixing_directions_is_refused_not_set_wrongly():
    with pytest.raises(SourceError, match="mixes right-to-left letters with left-to-right ones") as info:
        text.layout(spec("Hello سلام"), Path("."))
    assert info.value.field == "text" and "separate lines" in info.value.hint
    assert [c for c, *_ in text.layout(spec("Hello\nسلام"), Path(".")) if not c.isspace()]  # on two lines: fine


def test_letter_spacing_does_not_tear_joined_letters_apart():
    plain = xs(text.layout(spec("سلام", letter_spacing=0.0), Path(".")))
    spaced = xs(text.layout(spec("سلام", letter_spacing=1.0), Path(".")))
    assert spaced == plain
    warnings: list[str] = []
    font = text._Font(text.DEFAULT_FONT, [])
    text._layout("سلام", font, spec("سلام", letter_spacing=0.5), warnings)
    assert warnings and "joining script" in warnings[0]


def test_simple_lines_keep_their_layout_without_ligatures():
    placed = text.layout(spec("fi"), Path("."))
    assert [c for c, *_ in placed] == ["f", "i"]  # no 'fi' ligature: simple lines are set glyph by glyph


def test_shaped_text_the_font_lacks_is_refused_with_the_characters():
    with pytest.raises(SourceError, match="has no glyph for") as info:
        text.layout(spec(KA + VIRAMA + SSA), Path("."))
    assert "U+0915" in info.value.message and info.value.field == "text"


def _devanagari_font(path: Path) -> Path:
    """A tiny font made here: क ् ष and the conjunct क्ष, which its GSUB 'akhn' feature forms."""
    from fontTools.feaLib.builder import addOpenTypeFeaturesFromString
    from fontTools.fontBuilder import FontBuilder
    from fontTools.pens.ttGlyphPen import TTGlyphPen

    names = [".notdef", "space", "ka", "virama", "ssa", "k_ssa"]
    builder = FontBuilder(1000, isTTF=True)
    builder.setupGlyphOrder(names)
    builder.setupCharacterMap({0x20: "space", 0x0915: "ka", 0x094D: "virama", 0x0937: "ssa"})
    glyphs, widths = {}, {".notdef": 500, "space": 250, "ka": 500, "virama": 0, "ssa": 500, "k_ssa": 800}
    for name in names:
        pen = TTGlyphPen(None)
        if name not in ("space", ".notdef"):
            width = widths[name] or 100
            left = -100 if name == "virama" else 50
            pen.moveTo((left, 0))
            pen.lineTo((left, 700))
            pen.lineTo((left + width - 100, 700))
            pen.lineTo((left + width - 100, 0))
            pen.closePath()
        glyphs[name] = pen.glyph()
    builder.setupGlyf(glyphs)
    builder.setupHorizontalMetrics({n: (widths[n], 50) for n in names})
    builder.setupHorizontalHeader(ascent=800, descent=-200)
    builder.setupNameTable({"familyName": "Test Deva", "styleName": "Regular"})
    builder.setupOS2(sTypoAscender=800, sTypoDescender=-200, usWinAscent=800, usWinDescent=200)
    builder.setupPost()
    addOpenTypeFeaturesFromString(builder.font, """
        languagesystem DFLT dflt;
        languagesystem dev2 dflt;
        feature akhn { sub ka virama ssa by k_ssa; } akhn;
    """)
    builder.save(str(path))
    return path


def test_an_indic_conjunct_is_formed_by_the_fonts_features(tmp_path):
    font = _devanagari_font(tmp_path / "deva.ttf")
    placed = text.layout(spec(KA + VIRAMA + SSA, font=font.name), tmp_path)
    assert [(c, g) for c, g, *_ in placed] == [(KA, "k_ssa")]  # one conjunct, no bare virama
    result = text.load(spec(KA + VIRAMA + SSA + " " + KA, font=font.name), tmp_path)
    assert list(result.parts) == ["glyph_00_u0915", "glyph_01_u0915"]

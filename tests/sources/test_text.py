"""Tests for sources/text.py: fonts, nonzero fill, layout, bevel, errors.

Synthetic fonts (TrueType glyf and OpenType CFF) are built in code with
fontTools' FontBuilder, so fill-rule and outline-format cases have exact answers.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from core.errors import SourceError
from core.recipe import NAME_PATTERN, TextSource
from sources import text as text_source
from sources.text import DEFAULT_FONT, load

SERIF = Path("/usr/share/fonts/truetype/dejavu/DejaVuSerif.ttf")
UPEM = 1000  # synthetic fonts
ADVANCE = 700


def spec(text: str, **kw) -> TextSource:
    return TextSource(kind="text", text=text, **kw)


def parts_of(text: str, base_dir: Path = Path("."), **kw):
    return load(spec(text, **kw), base_dir)


@pytest.fixture(scope="module")
def dejavu():
    from fontTools.ttLib import TTFont

    return TTFont(str(DEFAULT_FONT))


# --------------------------------------------------------------------------- synthetic fonts


def _square(pen, x0, y0, x1, y1, clockwise=True):
    pts = [(x0, y0), (x0, y1), (x1, y1), (x1, y0)]  # clockwise in y-up coordinates
    if not clockwise:
        pts.reverse()
    pen.moveTo(pts[0])
    for p in pts[1:]:
        pen.lineTo(p)
    pen.closePath()


def _circle(pen, cx, cy, r, clockwise=False):
    """A circle as four cubic Béziers (the usual kappa approximation)."""
    k = 0.5522847498 * r
    if clockwise:
        pen.moveTo((cx, cy + r))
        pen.curveTo((cx + k, cy + r), (cx + r, cy + k), (cx + r, cy))
        pen.curveTo((cx + r, cy - k), (cx + k, cy - r), (cx, cy - r))
        pen.curveTo((cx - k, cy - r), (cx - r, cy - k), (cx - r, cy))
        pen.curveTo((cx - r, cy + k), (cx - k, cy + r), (cx, cy + r))
    else:
        pen.moveTo((cx, cy + r))
        pen.curveTo((cx - k, cy + r), (cx - r, cy + k), (cx - r, cy))
        pen.curveTo((cx - r, cy - k), (cx - k, cy - r), (cx, cy - r))
        pen.curveTo((cx + k, cy - r), (cx + r, cy - k), (cx + r, cy))
        pen.curveTo((cx + r, cy + k), (cx + k, cy + r), (cx, cy + r))
    pen.closePath()


#: char → (glyph name, exact filled area in font units², number of islands)
SYNTHETIC = {
    "A": ("overlap", 2 * 400**2 - 200**2, 1),  # two same-wound overlapping squares: union
    "B": ("hole", 600**2 - 400**2, 1),  # counter-wound inner square: a hole
    "C": ("samewind", 600**2, 1),  # same-wound nested square: nonzero keeps it filled
    "D": ("island", 600**2 - 400**2 + 200**2, 2),  # island inside a hole
    "E": ("flipped", 600**2 - 400**2, 1),  # 'hole' as a mirrored component (reversed winding)
}


def _finish(fb, glyph_order, family):
    fb.setupCharacterMap({ord(c): g for c, (g, _, _) in SYNTHETIC.items()} | {0x20: "space"})
    fb.setupHorizontalMetrics({g: (ADVANCE if g not in (".notdef", "space") else 250, 0) for g in glyph_order})
    fb.setupHorizontalHeader(ascent=800, descent=-200)
    fb.setupNameTable({"familyName": family, "styleName": "Regular"})
    fb.setupOS2(sTypoAscender=800, usWinAscent=800, usWinDescent=200)
    fb.setupPost()


@pytest.fixture(scope="module")
def ttf_font(tmp_path_factory) -> Path:
    """A TrueType (glyf) font whose glyphs exercise the nonzero winding rule."""
    from fontTools.fontBuilder import FontBuilder
    from fontTools.pens.ttGlyphPen import TTGlyphPen

    order = [".notdef", "space", "overlap", "hole", "samewind", "island", "flipped"]
    fb = FontBuilder(UPEM, isTTF=True)
    fb.setupGlyphOrder(order)
    glyphs = {}
    drawings = {
        ".notdef": [],
        "space": [],
        "overlap": [(0, 0, 400, 400, True), (200, 200, 600, 600, True)],
        "hole": [(0, 0, 600, 600, True), (100, 100, 500, 500, False)],
        "samewind": [(0, 0, 600, 600, True), (100, 100, 500, 500, True)],
        "island": [(0, 0, 600, 600, True), (100, 100, 500, 500, False), (200, 200, 400, 400, True)],
    }
    for name, squares in drawings.items():
        pen = TTGlyphPen(None)
        for sq in squares:
            _square(pen, *sq[:4], clockwise=sq[4])
        glyphs[name] = pen.glyph()
    pen = TTGlyphPen(glyphs)
    pen.addComponent("hole", (-1, 0, 0, 1, 600, 0))  # mirror in x: contour directions flip
    glyphs["flipped"] = pen.glyph()
    fb.setupGlyf(glyphs)
    _finish(fb, order, "SynthTT")
    path = tmp_path_factory.mktemp("fonts") / "synth.ttf"
    fb.save(str(path))
    return path


@pytest.fixture(scope="module")
def otf_font(tmp_path_factory) -> Path:
    """An OpenType CFF font (cubic outlines, CFF's counter-clockwise outer contours)."""
    from fontTools.fontBuilder import FontBuilder
    from fontTools.pens.t2CharStringPen import T2CharStringPen

    order = [".notdef", "space", "ring", "overlap"]
    fb = FontBuilder(UPEM, isTTF=False)
    fb.setupGlyphOrder(order)
    charstrings = {}
    for name in order:
        pen = T2CharStringPen(ADVANCE, None)
        if name == "ring":
            _circle(pen, 350, 350, 300, clockwise=False)
            _circle(pen, 350, 350, 150, clockwise=True)
        elif name == "overlap":
            _square(pen, 0, 0, 400, 400, clockwise=False)
            _square(pen, 200, 200, 600, 600, clockwise=False)
        charstrings[name] = pen.getCharString()
    fb.setupCFF("SynthCFF-Regular", {"FullName": "SynthCFF"}, charstrings, {})
    fb.setupCharacterMap({ord("O"): "ring", ord("A"): "overlap", 0x20: "space"})
    fb.setupHorizontalMetrics({g: (ADVANCE, 0) for g in order})
    fb.setupHorizontalHeader(ascent=800, descent=-200)
    fb.setupNameTable({"familyName": "SynthCFF", "styleName": "Regular"})
    fb.setupOS2(sTypoAscender=800, usWinAscent=800, usWinDescent=200)
    fb.setupPost()
    path = tmp_path_factory.mktemp("fonts") / "synth.otf"
    fb.save(str(path))
    return path


# --------------------------------------------------------------------------- parts and names


def test_hi_gives_three_named_watertight_glyphs():
    result = parts_of("Hi!")
    assert list(result.parts) == ["glyph_00_H", "glyph_01_i", "glyph_02_u0021"]
    assert result.input_files == [DEFAULT_FONT]
    assert result.warnings == []
    for mesh in result.parts.values():
        assert mesh.is_watertight
        assert mesh.volume > 0
        assert mesh.vertices.dtype == np.float64


def test_whitespace_advances_but_makes_no_part_and_names_are_valid():
    result = parts_of("Ünïcødé & 100% ®")
    names = list(result.parts)
    assert len(names) == 13  # 7 + '&' + '100%' + '®'; spaces make no part
    assert names[0] == "glyph_00_u00DC" and names[8] == "glyph_08_1" and names[12] == "glyph_12_u00AE"
    assert all(re.match(NAME_PATTERN, n) for n in names)
    assert all(m.is_watertight and m.volume > 0 for m in result.parts.values())


def test_decomposed_accents_are_merged_by_nfc():
    assert list(parts_of("U\u0308").parts) == ["glyph_00_u00DC"]


def test_index_is_two_digits_and_grows_past_99():
    names = list(parts_of("x" * 101).parts)
    assert names[0] == "glyph_00_x" and names[99] == "glyph_99_x" and names[100] == "glyph_100_x"


def test_output_is_deterministic():
    a, b = parts_of("GOB", bevel_m=0.005), parts_of("GOB", bevel_m=0.005)
    for name in a.parts:
        assert np.array_equal(a.parts[name].vertices, b.parts[name].vertices)
        assert np.array_equal(a.parts[name].faces, b.parts[name].faces)


# --------------------------------------------------------------------------- fill rule


def test_letter_o_has_a_hole(dejavu):
    rings = text_source.flattening_pen(dejavu.getGlyphSet())
    dejavu.getGlyphSet()["O"].draw(rings)
    region = text_source.region_from_rings(rings.rings)
    outer = max(text_source.region_from_rings([r]).area() for r in rings.rings)
    assert region.num_contour() == 2 and len(region.decompose()) == 1
    assert region.area() < 0.75 * outer

    size, depth = 0.2, 0.06
    mesh = parts_of("O", size_m=size, depth_m=depth).parts["glyph_00_O"]
    scale = size / dejavu["head"].unitsPerEm
    assert mesh.volume == pytest.approx(region.area() * scale**2 * depth, rel=1e-6)


@pytest.mark.parametrize("char", list(SYNTHETIC))
def test_nonzero_winding_on_truetype_contours(ttf_font, char):
    _, area, islands = SYNTHETIC[char]
    size, depth = 1.0, 0.1  # 1 m em: font units / 1000 = metres
    result = load(spec(char, font=str(ttf_font), size_m=size, depth_m=depth, align="left"), Path("/"))
    mesh = next(iter(result.parts.values()))
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(area / UPEM**2 * depth, rel=1e-9)
    assert len(mesh.split(only_watertight=False)) == islands


def test_cff_font_with_cubic_outlines(otf_font):
    result = load(spec("OA", font=otf_font.name, size_m=1.0, depth_m=0.1, align="left"), otf_font.parent)
    ring, overlap = result.parts["glyph_00_O"], result.parts["glyph_01_A"]
    assert ring.is_watertight and overlap.is_watertight
    annulus = math.pi * (0.3**2 - 0.15**2) * 0.1
    assert ring.volume == pytest.approx(annulus, rel=0.01)  # 48-gon flattening loses ≈0.3 %
    assert ring.volume < 0.9 * math.pi * 0.3**2 * 0.1  # the counter is a hole
    assert overlap.volume == pytest.approx((2 * 0.4**2 - 0.2**2) * 0.1, rel=1e-9)
    assert result.input_files == [otf_font]


def test_pen_flattens_cubic_and_implied_quadratic_curves():
    pen = text_source.flattening_pen()
    _circle(pen, 0, 0, 100)
    (ring,) = pen.rings
    assert ring.shape == (4 * text_source.CUBIC_STEPS, 2)
    radii = np.hypot(ring[:, 0], ring[:, 1])
    assert np.all(np.abs(radii - 100) < 0.03)  # kappa cubics stay within 0.027 % of the circle

    # TrueType contour with only off-curve points (None = implied on-curve points).
    pen = text_source.flattening_pen()
    pen.qCurveTo((100, 0), (0, 100), (-100, 0), (0, -100), None)
    pen.closePath()
    (ring,) = pen.rings
    assert ring.shape == (4 * text_source.QUAD_STEPS, 2)
    assert text_source.region_from_rings([ring]).area() > 0.9 * 2 * 50**2 * 2  # bigger than the on-curve diamond


# --------------------------------------------------------------------------- layout


def test_left_align_starts_at_left_sidebearing(dejavu):
    size = 0.2
    mesh = parts_of("H", size_m=size, align="left").parts["glyph_00_H"]
    _, lsb = dejavu["hmtx"]["H"]
    assert lsb >= 0
    assert mesh.bounds[0, 0] == pytest.approx(lsb * size / 2048, abs=1e-9)
    assert mesh.bounds[0, 1] == pytest.approx(0.0, abs=1e-9)  # baseline at y = 0


def test_right_align_ends_the_advance_at_zero(dejavu):
    size = 0.2
    mesh = parts_of("H", size_m=size, align="right").parts["glyph_00_H"]
    advance, _ = dejavu["hmtx"]["H"]
    x_max = dejavu["glyf"]["H"].xMax
    assert mesh.bounds[1, 0] == pytest.approx((x_max - advance) * size / 2048, abs=1e-9)


def test_center_align_centres_each_line():
    result = parts_of("GOBLIN\nHI")
    meshes = list(result.parts.values())
    top, bottom = meshes[:6], meshes[6:]
    for line in (top, bottom):
        lo = min(m.bounds[0, 0] for m in line)
        hi = max(m.bounds[1, 0] for m in line)
        assert abs(lo + hi) / 2 < 0.02 * (hi - lo)


def test_advance_letter_spacing_and_kerning(dejavu):
    size, em = 1.0, 2048
    advance, lsb = dejavu["hmtx"]["H"]
    for spacing in (0.0, 0.25):
        meshes = list(parts_of("HH", size_m=size, align="left", letter_spacing=spacing).parts.values())
        gap = meshes[1].bounds[0, 0] - meshes[0].bounds[0, 0]
        assert gap == pytest.approx((advance + spacing * em) / em, abs=1e-9)

    kern = dejavu["kern"].kernTables[0].kernTable[("A", "V")]
    assert kern < 0
    a_adv, _ = dejavu["hmtx"]["A"]
    _, v_lsb = dejavu["hmtx"]["V"]
    v = parts_of("AV", size_m=size, align="left", letter_spacing=0.0).parts["glyph_01_V"]
    assert v.bounds[0, 0] == pytest.approx((a_adv + kern + v_lsb) / em, abs=1e-9)


def test_second_line_is_one_line_spacing_lower():
    size = 0.2
    result = parts_of("H\nH", size_m=size, line_spacing=1.5)
    first, second = result.parts["glyph_00_H"], result.parts["glyph_01_H"]
    assert second.bounds[1, 1] < first.bounds[0, 1]
    assert np.allclose(second.bounds - first.bounds, [[0, -1.5 * size, 0]] * 2, atol=1e-9)


def test_size_scales_everything_and_depth_is_honoured():
    small = parts_of("GOB", size_m=0.1).bounds_m()
    large = parts_of("GOB", size_m=0.2).bounds_m()
    assert np.allclose(large, 2 * small, atol=1e-9)
    assert small[:, 2] == pytest.approx([-0.015, 0.015])  # default depth 0.3 × size, centred on z=0
    deep = parts_of("GOB", size_m=0.1, depth_m=0.05).bounds_m()
    assert deep[:, 2] == pytest.approx([-0.025, 0.025])


# --------------------------------------------------------------------------- bevel


def _face_area_at(mesh, z: float, normal_z: float) -> float:
    centres = mesh.triangles_center[:, 2]
    keep = np.isclose(centres, z) & np.isclose(mesh.face_normals[:, 2], normal_z)
    return float(mesh.area_faces[keep].sum())


def test_bevel_is_watertight_and_shrinks_the_front_face():
    flat = parts_of("O", depth_m=0.06).parts["glyph_00_O"]
    bevelled = parts_of("O", depth_m=0.06, bevel_m=0.008)
    mesh = bevelled.parts["glyph_00_O"]
    assert bevelled.warnings == []
    assert mesh.is_watertight and mesh.volume > 0
    assert np.allclose(mesh.bounds[:, 2], [-0.03, 0.03])
    front, back = _face_area_at(mesh, 0.03, 1.0), _face_area_at(mesh, -0.03, -1.0)
    assert 0 < front < 0.8 * back
    assert back == pytest.approx(_face_area_at(flat, -0.03, -1.0), rel=1e-6)
    assert mesh.volume < flat.volume


def test_too_large_bevel_is_clamped_with_a_warning():
    result = parts_of("li", size_m=0.2, depth_m=0.1, bevel_m=0.05)
    assert any("clamped" in w for w in result.warnings)
    assert all(m.is_watertight for m in result.parts.values())
    assert len(result.parts["glyph_01_i"].split(only_watertight=False)) == 2  # the dot survived


def test_bevel_deeper_than_half_the_depth_is_clamped():
    result = parts_of("O", size_m=0.2, depth_m=0.02, bevel_m=0.015)
    assert any("half the depth" in w for w in result.warnings)
    mesh = result.parts["glyph_00_O"]
    assert mesh.is_watertight and np.allclose(mesh.bounds[:, 2], [-0.01, 0.01])


# --------------------------------------------------------------------------- other fonts


@pytest.mark.skipif(not SERIF.is_file(), reason="system DejaVu Serif not installed")
def test_system_serif_font():
    result = parts_of("Agx®", font=str(SERIF))
    assert list(result.parts) == ["glyph_00_A", "glyph_01_g", "glyph_02_x", "glyph_03_u00AE"]
    assert all(m.is_watertight and m.volume > 0 for m in result.parts.values())
    assert result.input_files == [SERIF]


def test_font_collection_uses_its_first_font(ttf_font, otf_font, tmp_path):
    from fontTools.ttLib import TTCollection, TTFont

    collection = TTCollection()
    collection.fonts = [TTFont(str(ttf_font)), TTFont(str(otf_font))]
    path = tmp_path / "pair.ttc"
    collection.save(str(path))
    result = load(spec("B", font="pair.ttc", size_m=1.0, depth_m=0.1), tmp_path)
    assert result.parts["glyph_00_B"].volume == pytest.approx(SYNTHETIC["B"][1] / UPEM**2 * 0.1)
    assert any("collection" in w for w in result.warnings)


# --------------------------------------------------------------------------- errors


def test_missing_font_names_the_resolved_path(tmp_path):
    with pytest.raises(SourceError) as info:
        load(spec("Hi", font="fonts/nope.ttf"), tmp_path)
    assert info.value.field == "font"
    assert str(tmp_path / "fonts" / "nope.ttf") in info.value.message


def test_font_path_expands_home(tmp_path, monkeypatch, ttf_font):
    monkeypatch.setenv("HOME", str(ttf_font.parent))
    assert list(load(spec("A", font="~/synth.ttf"), tmp_path).parts) == ["glyph_00_A"]


@pytest.mark.parametrize("content", ["garbage", "empty", "truncated", "directory"])
def test_unreadable_font_is_refused(tmp_path, content):
    path = tmp_path / "bad.ttf"
    if content == "garbage":
        path.write_bytes(np.random.default_rng(0).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    elif content == "empty":
        path.write_bytes(b"")
    elif content == "truncated":
        path.write_bytes(DEFAULT_FONT.read_bytes()[:3000])
    else:
        path.mkdir()
    with pytest.raises(SourceError) as info:
        load(spec("Hi", font="bad.ttf"), tmp_path)
    assert info.value.field == "font"
    if content != "directory":
        assert "not a readable TrueType/OpenType font" in info.value.message


def test_characters_missing_from_the_font_are_listed():
    with pytest.raises(SourceError) as info:
        parts_of("Hi \U0001F47E \u4E2D!")  # DejaVu has a few emoji (U+1F600) but not these
    err = info.value
    assert err.field == "text"
    assert "'\U0001F47E' (U+1F47E)" in err.message and "'\u4E2D' (U+4E2D)" in err.message
    assert "'H'" not in err.message
    assert "font" in err.hint


def test_text_without_visible_glyphs_is_refused():
    with pytest.raises(SourceError) as info:
        parts_of("\u200b")  # zero-width space: in the font, but no outline
    assert info.value.field == "text"
    blank = TextSource.model_construct(kind="text", text=" \n\t ", font=None, size_m=0.2, depth_m=None,
                                       letter_spacing=0.08, line_spacing=1.2, align="center", bevel_m=0.0)
    with pytest.raises(SourceError) as info:
        load(blank, Path("."))
    assert info.value.field == "text"


def test_capitals_get_the_same_voxel_size_whatever_the_string():
    """fit: height uses the cap height, so accents, descenders and extra lines do not shrink the letters."""
    from core.recipe import FitMode, GridSettings
    from geometry.voxelize import voxelize

    grids = {}
    for text in ("HELL", "Ünïcødé gypsy", "TWO\nLINES"):
        parts = load(TextSource(kind="text", text=text, size_m=0.5), Path("."))
        assert parts.fit_height_m == pytest.approx(0.5 * 1493 / 2048)  # DejaVu Sans Bold: capHeight 1493 / 2048 em
        grids[text] = voxelize(parts, GridSettings(resolution=16), FitMode.HEIGHT)
    sizes = {g.voxel_size_m for g in grids.values()}
    assert len(sizes) == 1
    assert grids["HELL"].shape[1] == 16  # (round letters overshoot the cap height a little)
    assert grids["Ünïcødé gypsy"].shape[1] > 16 and grids["TWO\nLINES"].shape[1] > 32

"""Text source: a string set in a TrueType/OpenType font, extruded into one solid per glyph.

Role: ``load(spec, base_dir)`` turns a ``TextSource`` into ``PartMeshes`` with one
watertight ``trimesh.Trimesh`` per visible glyph, named ``glyph_<NN>_<c>``, in the
canonical frame (metres, +Y up, glyphs advance along +X, front face at +Z).

How it works:

1. Outlines come from fontTools: a pen flattens quadratic (TrueType ``glyf``) and
   cubic (OpenType ``CFF``/``CFF2``) curves into polylines with a *fixed* number of
   steps per curve, so the result never depends on anything but the font.
2. Each glyph's filled region is built with the **nonzero winding rule** by
   manifold3d's ``CrossSection`` (Clipper2 underneath). This gets every case
   right whatever the contour direction convention of the font: overlapping
   contours (variable fonts) union, counter-wound contours are holes ('O', 'A',
   '8'), islands inside holes ('®') are kept, and same-direction nested contours
   stay filled (where even-odd would punch a hole).
3. The region is extruded with ``Manifold.extrude``; a front chamfer (``bevel_m``)
   is a stack of ``BEVEL_STEPS`` progressively inset (mitre-joined) prisms unioned
   with the body by manifold's boolean union, so the result is watertight by
   construction. Geometry is built in font units and scaled once to metres;
   identical glyphs are built once and translated.

Layout: ``size_m`` is the em size. A line in a simple script is set glyph by
glyph: advances come from ``hmtx``; ``letter_spacing`` (em) is added to every
advance; pair kerning comes from the legacy ``kern`` table (format 0
subtables) when the font has one (GPOS kerning and ligatures are not applied,
so such lines look the same in every release). A line that needs shaping
(right-to-left letters, combining marks, Indic and other complex scripts: see
``sources/shaping.py``) is shaped by HarfBuzz with the font's OpenType
features and laid out right to left where its script is; ``letter_spacing``
is added between clusters, except in joining scripts (Arabic...), whose
letters it would tear apart. A line mixing left-to-right and right-to-left
letters is refused. Text is NFC-normalised first when the font covers the
normalised form. Lines are
``line_spacing`` em apart downwards; the first baseline is at y=0. Alignment uses
each line's advance box (pen start to the end of the last advance, without the
trailing letter spacing): ``left`` starts it at x=0, ``right`` ends it at x=0,
``center`` centres it on x=0. The solid spans z ∈ [-depth/2, +depth/2].

Fonts: ``spec.font`` is resolved against ``base_dir`` (``~`` expanded); ``None``
means the bundled DejaVu Sans Bold. There is never a silent fallback to another
font. A TrueType/OpenType *collection* (``.ttc``/``.otc``) is accepted, its
first font is used and a warning says so (the recipe has no field to pick another).

Grid fit: the parts carry ``fit_height_m`` = the font's cap height, so with
``fit: height`` (the default for text) capitals get ``grid.resolution`` voxels of
height on every line, whatever accents, descenders or line count the text has.

Part names: ``NN`` is the index among visible glyphs, formatted ``{:02d}`` (so it
stays the same when the text grows past 100 glyphs); ``c`` is the character when it
is an ASCII letter or digit, else ``u`` + its upper-case hex code point (4+ digits).
Whitespace and glyphs without an outline advance the pen but make no part.
"""

from __future__ import annotations

import unicodedata
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from core.errors import SourceError
from core.files import InputKind, input_file, read_input_bytes
from core.recipe import TextAlign, TextSource
from sources.base import PartMeshes
from sources.shaping import Shaper, is_joining, needs_shaping

if TYPE_CHECKING:
    import manifold3d
    import trimesh

#: The font used when a recipe names none (shipped with the package, OFL-style licence beside it).
DEFAULT_FONT = Path(__file__).parent / "fonts" / "DejaVuSans-Bold.ttf"

#: Polyline steps per quadratic / cubic Bézier segment. Fixed, so output is deterministic;
#: TrueType curves are short (≈1/8 circle), CFF curves long (≈1/4 circle), hence more steps.
QUAD_STEPS = 8
CUBIC_STEPS = 12

#: Number of stacked, progressively inset prisms that approximate a 45° front chamfer.
BEVEL_STEPS = 3

#: The chamfer may take at most this fraction of the depth (the rest is the straight body).
MAX_BEVEL_FRACTION = 0.5

_NOT_A_FONT = "not a readable TrueType/OpenType font"
_FONT_HINT = "give the path of a .ttf or .otf file, or leave 'font' out for the bundled DejaVu Sans Bold"


# --------------------------------------------------------------------------- outlines


def _bezier_basis(degree: int, steps: int) -> np.ndarray:
    """(steps, degree+1) Bernstein weights at t = 1/steps … 1 (t=0 is the current point)."""
    t = np.arange(1, steps + 1, dtype=np.float64) / steps
    if degree == 2:
        return np.stack([(1 - t) ** 2, 2 * t * (1 - t), t**2], axis=1)
    return np.stack([(1 - t) ** 3, 3 * t * (1 - t) ** 2, 3 * t**2 * (1 - t), t**3], axis=1)


_QUAD_BASIS = _bezier_basis(2, QUAD_STEPS)
_CUBIC_BASIS = _bezier_basis(3, CUBIC_STEPS)


def _make_pen_class():
    """Build the pen class lazily so importing this module does not import fontTools."""
    from fontTools.pens.basePen import BasePen

    class FlatteningPen(BasePen):
        """A fontTools pen that records closed contours as (N, 2) float64 polylines (font units).

        Quadratic segments get ``QUAD_STEPS`` points, cubic ones ``CUBIC_STEPS``.
        Components are decomposed through ``glyph_set``. Open paths are closed, as
        rasterisers do when filling. ``rings`` holds the result, in drawing order.
        """

        def __init__(self, glyph_set=None) -> None:
            super().__init__(glyph_set)
            self.rings: list[np.ndarray] = []
            self._points: list[tuple[float, float]] = []

        def _moveTo(self, pt) -> None:
            self._finish()
            self._points = [(float(pt[0]), float(pt[1]))]

        def _lineTo(self, pt) -> None:
            self._points.append((float(pt[0]), float(pt[1])))

        def _curve(self, basis: np.ndarray, *pts) -> None:
            ctrl = np.array([self._getCurrentPoint(), *pts], dtype=np.float64)
            self._points.extend(map(tuple, (basis @ ctrl).tolist()))

        def _qCurveToOne(self, pt1, pt2) -> None:
            self._curve(_QUAD_BASIS, pt1, pt2)

        def _curveToOne(self, pt1, pt2, pt3) -> None:
            self._curve(_CUBIC_BASIS, pt1, pt2, pt3)

        def _closePath(self) -> None:
            self._finish()

        def _endPath(self) -> None:
            self._finish()

        def _finish(self) -> None:
            pts = self._points
            self._points = []
            if len(pts) > 1 and pts[0] == pts[-1]:
                pts = pts[:-1]
            if len(pts) >= 3:
                self.rings.append(np.asarray(pts, dtype=np.float64))

    return FlatteningPen


_PEN_CLASS = None


def flattening_pen(glyph_set=None):
    """A new ``FlatteningPen`` (see ``_make_pen_class``); draw a glyph into it, read ``.rings``."""
    global _PEN_CLASS
    if _PEN_CLASS is None:
        _PEN_CLASS = _make_pen_class()
    return _PEN_CLASS(glyph_set)


def region_from_rings(rings: Sequence[np.ndarray]) -> "manifold3d.CrossSection":
    """The filled 2-D region of closed polylines (each (N, 2)) under the nonzero winding rule."""
    from manifold3d import CrossSection, FillRule

    if not rings:
        return CrossSection()
    return CrossSection([np.ascontiguousarray(r, dtype=np.float64) for r in rings], FillRule.NonZero)


# --------------------------------------------------------------------------- font access


class _Font:
    """What the layout needs from one font file, read eagerly so corrupt data fails here.

    Everything is in font units (``units_per_em`` per em).
    """

    def __init__(self, path: Path, warnings: list[str]) -> None:
        from fontTools.ttLib import TTFont

        self.path = path
        try:
            with path.open("rb") as fh:
                is_collection = fh.read(4) == b"ttcf"
            # lazy=None: tables are decompiled on first access, below, inside this try.
            font = TTFont(str(path), fontNumber=0 if is_collection else -1, lazy=None)
            self.units_per_em = int(font["head"].unitsPerEm)
            if not 16 <= self.units_per_em <= 16384:
                raise ValueError(f"unitsPerEm {self.units_per_em} out of range")
            self.cmap: dict[int, str] = font.getBestCmap() or {}
            self.glyph_order: list[str] = font.getGlyphOrder()
            self.glyph_set = font.getGlyphSet()
            self.metrics: dict[str, tuple[int, int]] = dict(font["hmtx"].metrics)
            self.kerning = _legacy_kerning(font)
            self.cap_height = self._cap_height(font)
        except OSError as exc:
            raise SourceError(f"{_NOT_A_FONT}: cannot read {path} ({exc.strerror or exc})",
                              field="font", hint=_FONT_HINT) from None
        except Exception as exc:  # noqa: BLE001 - fontTools raises many types on bad data
            raise SourceError(f"{_NOT_A_FONT}: {path} ({type(exc).__name__}: {exc})",
                              field="font", hint=_FONT_HINT) from None
        if is_collection:
            warnings.append(f"font {path.name} is a collection; its first font was used")
        self._font = font
        self._shaper: Shaper | None = None

    def shaper(self) -> Shaper:
        """HarfBuzz on this font's bytes (read on first use, within the font size limit)."""
        if self._shaper is None:
            data = read_input_bytes(self.path, InputKind.FONT, field="font")
            self._shaper = Shaper(data, 0)
        return self._shaper

    def _cap_height(self, font) -> float:
        """Height of capitals in font units: OS/2 sCapHeight, else the 'H' outline's top, else 0.7 em."""
        os2 = font["OS/2"] if "OS/2" in font else None
        if os2 is not None and getattr(os2, "version", 0) >= 2 and getattr(os2, "sCapHeight", 0) > 0:
            return float(os2.sCapHeight)
        glyph = self.cmap.get(ord("H"))
        if glyph is not None:
            rings = self.rings(glyph)
            if rings:
                return float(max(r[:, 1].max() for r in rings))
        return 0.7 * self.units_per_em

    def advance(self, glyph: str) -> int:
        return self.metrics.get(glyph, (0, 0))[0]

    def rings(self, glyph: str) -> list[np.ndarray]:
        """Flattened closed contours of one glyph, (N, 2) float64 each, font units."""
        pen = flattening_pen(self.glyph_set)
        try:
            self.glyph_set[glyph].draw(pen)
        except Exception as exc:  # noqa: BLE001 - corrupt glyph programs fail in many ways
            raise SourceError(f"{_NOT_A_FONT}: outline of glyph {glyph!r} in {self.path} is broken "
                              f"({type(exc).__name__}: {exc})", field="font", hint=_FONT_HINT) from None
        return pen.rings


def _legacy_kerning(font) -> dict[tuple[str, str], int]:
    """Horizontal pair kerning from the ``kern`` table's format-0 subtables (empty if none)."""
    if "kern" not in font:
        return {}
    pairs: dict[tuple[str, str], int] = {}
    for sub in font["kern"].kernTables:
        if getattr(sub, "format", None) != 0 or not hasattr(sub, "kernTable"):
            continue
        cov = int(getattr(sub, "coverage", 1))
        if getattr(sub, "apple", False):
            horizontal, override = not cov & 0xE0, False  # vertical / cross-stream / variation bits
        else:
            horizontal, override = bool(cov & 1) and not cov & 0x6, bool(cov & 0x8)
        if not horizontal:
            continue
        for key, value in sub.kernTable.items():
            pairs[key] = int(value) if override else pairs.get(key, 0) + int(value)
    return pairs


def preflight(spec: TextSource, base_dir: Path) -> None:
    """Checks before building: the font exists and is readable within its size limit, and covers the text
    (layout included: shaping, direction), without building any glyph."""
    layout(spec, base_dir)


def layout(spec: TextSource, base_dir: Path) -> list[tuple[str, str, float, float]]:
    """The text laid out, without building solids: ``(character, glyph name, x, y)`` per glyph, in reading
    order, pen origins in em (x to the right, y up; the first baseline at 0). Whitespace is included.

    Raises SourceError like ``load`` (font, missing glyphs, mixed directions).
    """
    font = _cached_font(_resolve_font(spec.font, base_dir))
    em = float(font.units_per_em)
    return [(p.char, p.glyph, p.x / em, p.y / em) for p in _layout(_choose_text(spec.text, font.cmap), font, spec)]


_FONTS: dict[tuple, _Font] = {}


def _cached_font(path: Path) -> _Font:
    """``_Font(path)``, kept per (path, size, mtime) for the checks of a batch (at most 8 fonts)."""
    info = path.stat()
    key = (str(path), info.st_size, info.st_mtime_ns)
    if key not in _FONTS:
        if len(_FONTS) >= 8:
            _FONTS.pop(next(iter(_FONTS)))
        _FONTS[key] = _Font(path, [])
    return _FONTS[key]


def _resolve_font(font: str | None, base_dir: Path) -> Path:
    if font is None:
        return DEFAULT_FONT
    return input_file(font, base_dir, field="font", noun="font file", hint="name a .ttf or .otf font file",
                      kind=InputKind.FONT)


# --------------------------------------------------------------------------- layout


@dataclass(frozen=True)
class _Placed:
    """One character on the page: pen origin (font units) and its glyph."""

    char: str
    glyph: str
    x: float
    y: float


def _choose_text(text: str, cmap: dict[int, str]) -> str:
    """NFC-normalised text if the font covers it (merges 'U'+'¨' into 'Ü'), else the raw text."""
    text = text.replace("\r\n", "\n")
    nfc = unicodedata.normalize("NFC", text)
    covered = all(ch in "\n" or ch.isspace() or ord(ch) in cmap for ch in nfc)
    return nfc if covered else text


def _layout(text: str, font: _Font, spec: TextSource, warnings: list[str] | None = None) -> list[_Placed]:
    """Pen origins of every glyph (whitespace included), aligned per line; font units.

    Glyphs are listed line by line in reading (logical) order, whatever their direction.
    """
    em = font.units_per_em
    lines = text.split("\n")
    shaped = [needs_shaping(line) for line in lines]
    simple_chars = {ch for line, s in zip(lines, shaped) if not s for ch in line}
    missing = sorted({ch for ch in simple_chars if not ch.isspace() and ord(ch) not in font.cmap})
    _refuse_missing(missing, font)
    placed: list[_Placed] = []
    for line_no, line in enumerate(lines):
        y = -line_no * spec.line_spacing * em
        row, end = (_shaped_row(line, y, font, spec, warnings) if shaped[line_no]
                    else _simple_row(line, y, font, spec))
        shift = {TextAlign.LEFT: 0.0, TextAlign.CENTER: -end / 2, TextAlign.RIGHT: -end}[TextAlign(spec.align)]
        placed.extend(_Placed(p.char, p.glyph, p.x + shift, p.y) for p in row)
    return placed


def _refuse_missing(missing: list[str], font: _Font) -> None:
    if missing:
        listed = ", ".join(f"{ch!r} (U+{ord(ch):04X})" for ch in missing)
        raise SourceError(f"the font {font.path.name} has no glyph for {listed}",
                          field="text", hint="use a font that covers them, or remove those characters")


def _simple_row(line: str, y: float, font: _Font, spec: TextSource) -> tuple[list[_Placed], float]:
    """One glyph per character from the cmap, legacy kerning; (row, end of the last advance)."""
    em = font.units_per_em
    spacing = spec.letter_spacing * em
    space_glyph = font.cmap.get(0x20)
    space_advance = font.advance(space_glyph) if space_glyph else em // 4
    row: list[_Placed] = []
    x = end = 0.0
    prev: str | None = None
    for ch in line:
        glyph = font.cmap.get(ord(ch), "")  # "" = whitespace the font lacks: advance only
        advance = font.advance(glyph) if glyph else space_advance
        if prev is not None:
            x += spacing + font.kerning.get((prev, glyph), 0)
        row.append(_Placed(ch, glyph, x, y))
        end = x + advance
        x = end
        prev = glyph
    return row, end


def _shaped_row(line: str, y: float, font: _Font, spec: TextSource,
                warnings: list[str] | None) -> tuple[list[_Placed], float]:
    """A line shaped by HarfBuzz (``sources/shaping.py``); glyphs in logical order, positions visual."""
    glyphs = font.shaper().shape_line(line)
    missing = sorted({line[g.cluster] for g in glyphs if g.gid == 0 and not line[g.cluster].isspace()})
    _refuse_missing(missing, font)
    spacing = spec.letter_spacing * font.units_per_em
    if is_joining(line):
        if spacing and warnings is not None and "letter_spacing" in spec.model_fields_set:
            warnings.append("letter_spacing is not applied to lines in a joining script (Arabic...): "
                            "it would separate letters that join")
        spacing = 0.0
    row: list[tuple[int, int, _Placed]] = []
    shift = 0.0
    end = 0.0
    previous_cluster: int | None = None
    for order, g in enumerate(glyphs):  # visual order, left to right
        if previous_cluster is not None and g.cluster != previous_cluster:
            shift += spacing
        previous_cluster = g.cluster
        name = font.glyph_order[g.gid] if 0 < g.gid < len(font.glyph_order) else ""
        row.append((g.cluster, order, _Placed(line[g.cluster], name, g.x + shift, y + g.y_offset)))
        end = g.pen_x + shift + g.advance
    row.sort(key=lambda item: (item[0], item[1]))  # reading order, for part names
    return [p for _, _, p in row], end


def part_name(index: int, char: str) -> str:
    """``glyph_<NN>_<c>``: c is an ASCII letter/digit itself, else ``u`` + hex code point."""
    tag = char if char.isascii() and char.isalnum() else f"u{ord(char):04X}"
    return f"glyph_{index:02d}_{tag}"


# --------------------------------------------------------------------------- solids


def _inset(region: "manifold3d.CrossSection", distance: float) -> "manifold3d.CrossSection":
    from manifold3d import JoinType

    return region.offset(-distance, JoinType.Miter, 2.0)


def _bevel_survives(regions: Sequence["manifold3d.CrossSection"], bevel: float) -> bool:
    """True when insetting by ``bevel`` leaves some area of every island of every region."""
    return all(not _inset(island, bevel).is_empty() for r in regions for island in r.decompose())


def _fit_bevel(regions: Sequence["manifold3d.CrossSection"], bevel: float) -> float:
    """The requested bevel, or the largest (within 1 %, by bisection) that keeps every island."""
    if _bevel_survives(regions, bevel):
        return bevel
    lo, hi = 0.0, bevel
    while hi - lo > 0.01 * bevel:
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if _bevel_survives(regions, mid) else (lo, mid)
    return lo


def _glyph_solid(region: "manifold3d.CrossSection", depth: float, bevel: float,
                 char: str) -> tuple[np.ndarray, np.ndarray]:
    """Extrude a region to z ∈ [-depth/2, depth/2] with an optional front chamfer.

    ``depth`` and ``bevel`` are in font units; ``char`` only names the glyph in errors.
    Returns vertices (V, 3) float64 and faces (F, 3) int64, font units.
    """
    from manifold3d import Error, Manifold, OpType

    body = Manifold.extrude(region, depth - bevel)
    if bevel > 0:
        step = bevel / BEVEL_STEPS
        pieces = [body]
        for i in range(1, BEVEL_STEPS + 1):
            inset = _inset(region, bevel * i / BEVEL_STEPS)
            if not inset.is_empty():
                pieces.append(Manifold.extrude(inset, step).translate((0.0, 0.0, depth - bevel + (i - 1) * step)))
        body = Manifold.batch_boolean(pieces, OpType.Add)
    if body.status() != Error.NoError or body.is_empty():
        # Not expected for a valid cross-section; say which glyph rather than return a hole-y mesh.
        raise SourceError(f"could not build a solid for {char!r} ({body.status().name})", field="text",
                          hint="try another font, or bevel_m: 0")
    mesh = body.translate((0.0, 0.0, -depth / 2)).to_mesh64()
    vertices = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    return vertices, np.asarray(mesh.tri_verts, dtype=np.int64)


# --------------------------------------------------------------------------- entry point


def load(spec: TextSource, base_dir: Path) -> PartMeshes:
    """Set ``spec.text`` in its font and extrude it: one watertight mesh per visible glyph.

    Raises ``SourceError`` (field ``font``) for a missing or unreadable font, and
    (field ``text``) for characters the font lacks or text with nothing visible.
    """
    import trimesh

    warnings: list[str] = []
    font_path = _resolve_font(spec.font, base_dir)
    font = _Font(font_path, warnings)
    placed = _layout(_choose_text(spec.text, font.cmap), font, spec, warnings)

    regions: dict[str, "manifold3d.CrossSection"] = {}
    for p in placed:
        if p.glyph and not p.char.isspace() and p.glyph not in regions:
            regions[p.glyph] = region_from_rings(font.rings(p.glyph))
    regions = {g: r for g, r in regions.items() if not r.is_empty()}
    visible = [p for p in placed if p.glyph in regions]
    if not visible:
        raise SourceError("the text has no visible glyph (only whitespace or empty outlines)", field="text",
                          hint="give at least one letter, digit or symbol the font draws")

    scale = spec.size_m / font.units_per_em  # metres per font unit
    depth_m = spec.depth_m if spec.depth_m is not None else 0.3 * spec.size_m
    bevel_m = spec.bevel_m
    if bevel_m > MAX_BEVEL_FRACTION * depth_m:
        warnings.append(f"bevel_m {bevel_m:g} exceeds half the depth; clamped to {MAX_BEVEL_FRACTION * depth_m:g} m")
        bevel_m = MAX_BEVEL_FRACTION * depth_m
    if bevel_m > 0:
        fitted = _fit_bevel(list(regions.values()), bevel_m / scale) * scale
        if fitted < bevel_m:
            warnings.append(f"bevel_m {bevel_m:g} would make thin glyph parts vanish; clamped to {fitted:.3g} m")
            bevel_m = fitted

    first_char = {p.glyph: p.char for p in reversed(visible)}
    solids = {g: _glyph_solid(r, depth_m / scale, bevel_m / scale, first_char[g]) for g, r in regions.items()}
    parts: dict[str, trimesh.Trimesh] = {}
    for index, p in enumerate(visible):
        vertices, faces = solids[p.glyph]
        moved = (vertices + np.array([p.x, p.y, 0.0])) * scale
        parts[part_name(index, p.char)] = trimesh.Trimesh(vertices=moved, faces=faces.copy(), process=False)
    return PartMeshes(parts=parts, warnings=warnings, input_files=[font_path], fit_height_m=font.cap_height * scale)

"""Procedural chairs and tables for the ``furniture`` style set (parts: back, seat, leg, armrest, stretcher).

Role: each exemplar is a ``ChairDesign`` / ``TableDesign`` (a few named style
choices plus proportions) turned into part meshes by ``chair_parts`` /
``table_parts``. Designs differ in their *detail* (leg turning, back slats or
spindles or lattice, stretchers, aprons, edge profiles), not only in size.
Tables use ``seat`` for the tabletop (with its edge profile), ``leg`` for legs,
aprons and pedestals, ``stretcher`` for stretchers and low shelves.

Units: metres, +Y up, front +Z. Seat heights ~0.45 m, so at 256³ one voxel is
~4 mm and the thinnest pieces (slats, spindles) are made ≥ 12 mm (3 voxels).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stylesets.catalogues.prims import bar, box, hull, lathe, ring_of, rod, sphere, torus


@dataclass(frozen=True)
class ChairDesign:
    """One chair: style choices (strings) and proportions (metres)."""

    leg: str = "square"        # square | tapered | turned | round | splayed | cabriole | pedestal | sled
    back: str = "slats_v"      # slats_v | rails_h | spindles | lattice | panel | windsor | splat | xback | ladder
    seat: str = "slab"         # slab | round | padded | woven
    stretcher: str = "none"    # none | h | box | double | ring
    arms: str = "none"         # none | plank | spindle
    width: float = 0.46
    depth: float = 0.44
    seat_h: float = 0.45
    back_h: float = 0.45       # above the seat
    slats: int = 4
    post: float = 0.035        # leg / back-post thickness


@dataclass(frozen=True)
class TableDesign:
    """One table: style choices and proportions (metres)."""

    top: str = "rect"          # rect | round | oval
    edge: str = "square"       # square | bevel | bullnose | ogee | breadboard
    legs: str = "square"       # square | tapered | turned | pedestal | trestle | xframe | splayed | cabriole
    apron: str = "plain"       # none | plain | scalloped | drawers
    stretcher: str = "none"    # none | h | box | shelf | cross
    width: float = 1.2
    depth: float = 0.75
    height: float = 0.75
    top_t: float = 0.035
    leg_t: float = 0.06


# --------------------------------------------------------------------------- legs


def _turned_profile(r: float, h: float, beads: int = 3) -> list[tuple[float, float]]:
    """Turned-leg (radius, height) profile from the floor up: foot, vase, beads, square-ish top."""
    prof = [(r * 0.7, 0.0), (r * 0.8, 0.03 * h)]
    for i in range(beads):
        y = h * (0.18 + 0.5 * i / max(beads, 1))
        prof += [(r * 0.55, y), (r * 1.05, y + 0.03 * h), (r * 0.55, y + 0.06 * h)]
    prof += [(r * 0.8, 0.78 * h), (r * 0.5, 0.82 * h), (r * 1.0, 0.86 * h), (r * 1.0, h)]
    return prof


def _leg(style: str, x: float, z: float, top_y: float, t: float, splay: float = 0.0) -> list:
    """One leg from the floor to ``top_y`` at (x, z); ``t`` its thickness."""
    if style == "square":
        return [box((t, top_y, t), (x, top_y / 2, z))]
    if style == "tapered":
        return [bar((x, 0, z), (x, top_y, z), t * 0.5, t * 0.5), bar((x, top_y * 0.5, z), (x, top_y, z), t, t),
                bar((x, top_y * 0.25, z), (x, top_y * 0.6, z), t * 0.75, t * 0.75)]
    if style == "turned":
        return [lathe(_turned_profile(t * 0.6, top_y), (x, 0, z), sections=16)]
    if style == "round":
        return [rod((x, 0, z), (x, top_y, z), t / 2, 16), sphere((x, 0.015, z), t * 0.6, (1, 0.5, 1))]
    if style == "splayed":
        sx, sz = math.copysign(splay, x), math.copysign(splay, z)
        return [rod((x + sx, 0, z + sz), (x, top_y, z), t / 2, 14)]
    if style == "cabriole":
        # An S-curve: knee out, ankle in, foot out, as a chain of tapering bars.
        pts, out = [], []
        for i in range(9):
            s = i / 8
            bulge = 0.35 * t * math.sin(math.pi * s * 1.5) * (1 if s > 0.2 else -0.5)
            pts.append((x + math.copysign(bulge, x), top_y * s, z + math.copysign(bulge, z)))
        for i in range(8):
            w = t * (0.55 + 0.45 * i / 7)
            out.append(bar(pts[i], pts[i + 1], w, w))
        out.append(sphere((pts[0][0], 0.02, pts[0][2]), t * 0.55, (1, 0.6, 1)))
        return out
    raise ValueError(f"unknown leg style {style!r}")


# --------------------------------------------------------------------------- chairs


def chair_parts(d: ChairDesign) -> dict[str, list]:
    """Part name → list of closed meshes for chair design ``d``."""
    w, dp, sh, t = d.width, d.depth, d.seat_h, d.post
    seat_t = 0.04 if d.seat != "padded" else 0.07
    seat_y = sh - seat_t
    parts: dict[str, list] = {"back": [], "seat": [], "leg": [], "armrest": [], "stretcher": []}
    xs, zs = w / 2 - t / 2, dp / 2 - t / 2
    # A round seat's legs sit on a circle inside it, not at the square's corners.
    k = 0.5 if d.seat == "round" else 1.0
    corners = [(sx * xs * k, sz * zs * k) for sx in (-1, 1) for sz in (-1, 1)]

    # Seat.
    if d.seat == "round":
        parts["seat"].append(lathe([(w / 2, seat_y), (w / 2 + 0.01, seat_y + seat_t * 0.5), (w / 2, sh)], sections=32))
    elif d.seat == "padded":
        parts["seat"] += [box((w, seat_t * 0.5, dp), (0, seat_y + seat_t * 0.25, 0)),
                          box((w - 0.03, seat_t * 0.5, dp - 0.03), (0, seat_y + seat_t * 0.7, 0))]
        # Buttons of the upholstery.
        parts["seat"] += [sphere((bx, sh - 0.004, bz), 0.012, (1, 0.6, 1))
                          for bx in (-w / 4, 0, w / 4) for bz in (-dp / 4, dp / 4)]
    elif d.seat == "woven":
        frame = 0.03
        parts["seat"] += [box((w, frame, frame), (0, sh - frame / 2, s * (dp / 2 - frame / 2))) for s in (-1, 1)]
        parts["seat"] += [box((frame, frame, dp), (s * (w / 2 - frame / 2), sh - frame / 2, 0)) for s in (-1, 1)]
        n = 7
        for i in range(n):
            f = (i + 0.5) / n - 0.5
            parts["seat"].append(box((0.035, 0.012, dp - 0.02), (f * (w - 0.06), sh - 0.012 - (i % 2) * 0.008, 0)))
            parts["seat"].append(box((w - 0.02, 0.012, 0.035), (0, sh - 0.018 + (i % 2) * 0.008, f * (dp - 0.06))))
    else:
        parts["seat"].append(box((w, seat_t, dp), (0, seat_y + seat_t / 2, 0)))

    # Legs.
    if d.leg == "pedestal":
        parts["leg"].append(lathe([(0.03, 0.06), (0.03, seat_y - 0.04), (0.06, seat_y - 0.02), (0.06, seat_y)]))
        parts["leg"].append(lathe([(0.05, 0.06), (0.07, 0.1), (0.04, 0.13)]))
        for i in range(5):
            a = math.radians(90 + 72 * i)
            end = (0.3 * math.cos(a), 0.06, 0.3 * math.sin(a))
            parts["leg"].append(bar((0, 0.08, 0), end, 0.04, 0.03))
            parts["leg"].append(sphere((end[0], 0.025, end[2]), 0.025))  # castors
    elif d.leg == "sled":
        for sx in (-1, 1):
            x = sx * xs
            parts["leg"] += [bar((x, 0.015, -dp / 2), (x, 0.015, dp / 2), 0.03, 0.03),
                             bar((x, 0.015, dp / 2 - 0.02), (x, seat_y, zs), 0.03, 0.03),
                             bar((x, 0.015, -dp / 2 + 0.02), (x, seat_y, -zs), 0.03, 0.03)]
    else:
        for x, z in corners:
            parts["leg"] += _leg(d.leg, x, z, seat_y, t, splay=0.05)

    # Stretchers between the legs.
    sy = 0.15
    rt = max(0.018, t * 0.5)
    if d.stretcher in ("h", "double"):
        for s in (-1, 1):
            parts["stretcher"].append(rod((s * xs, sy, -zs), (s * xs, sy, zs), rt / 2))
        parts["stretcher"].append(rod((-xs, sy, 0), (xs, sy, 0), rt / 2))
    if d.stretcher in ("box", "double"):
        y2 = sy if d.stretcher == "box" else sy + 0.1
        for s in (-1, 1):
            parts["stretcher"].append(box((w - t, rt, rt), (0, y2 + (0.02 if s > 0 else 0), s * zs)))
            parts["stretcher"].append(box((rt, rt, dp - t), (s * xs, y2 + 0.04, 0)))
    if d.stretcher == "ring":
        r = min(xs, zs) * 1.25
        parts["stretcher"].append(torus((0, sy + 0.05, 0), r, rt * 0.6, 32))

    # Back: two posts plus the style's infill.
    top = sh + d.back_h
    bz = -zs
    post_w = t
    parts["back"] += [box((post_w, top - sh, post_w), (s * xs, (top + sh) / 2, bz)) for s in (-1, 1)]
    parts["back"].append(box((w, 0.06, post_w), (0, top - 0.03, bz)))  # crest rail
    inner = w - 2 * post_w
    lo, hi = sh + 0.06, top - 0.06
    if d.back == "slats_v":
        for i in range(d.slats):
            x = (i + 0.5) / d.slats * inner - inner / 2
            parts["back"].append(box((inner / d.slats * 0.5, hi - lo, 0.016), (x, (lo + hi) / 2, bz)))
        parts["back"].append(box((w, 0.04, post_w * 0.8), (0, lo, bz)))
    elif d.back in ("rails_h", "ladder"):
        n = d.slats
        for i in range(n):
            y = lo + (i + 0.5) / n * (hi - lo)
            hgt = (hi - lo) / n * (0.45 if d.back == "rails_h" else 0.3)
            parts["back"].append(box((inner + 0.01, hgt, 0.018), (0, y, bz)))
    elif d.back == "spindles":
        for i in range(d.slats):
            x = (i + 0.5) / d.slats * inner - inner / 2
            parts["back"].append(lathe([(0.008, 0), (0.013, 0.1 * (hi - lo)), (0.007, 0.3 * (hi - lo)),
                                        (0.014, 0.6 * (hi - lo)), (0.008, hi - lo)], (x, lo, bz), sections=12))
        parts["back"].append(box((w, 0.035, post_w * 0.8), (0, lo, bz)))
    elif d.back == "lattice":
        n = d.slats
        for i in range(n):
            x = (i + 0.5) / n * inner - inner / 2
            parts["back"].append(box((0.014, hi - lo, 0.014), (x, (lo + hi) / 2, bz)))
            y = lo + (i + 0.5) / n * (hi - lo)
            parts["back"].append(box((inner, 0.014, 0.014), (0, y, bz + 0.006)))
    elif d.back == "panel":
        parts["back"].append(box((inner, hi - lo, 0.02), (0, (lo + hi) / 2, bz)))
        # Raised moulding frame on the panel.
        m = 0.035
        for y in (lo + m, hi - m):
            parts["back"].append(box((inner - 2 * m, 0.014, 0.014), (0, y, bz + 0.015)))
        for x in (-inner / 2 + m, inner / 2 - m):
            parts["back"].append(box((0.014, hi - lo - 2 * m, 0.014), (x, (lo + hi) / 2, bz + 0.015)))
    elif d.back == "windsor":
        # A fan of spindles into a curved bow.
        n = d.slats
        bow = [(math.sin(math.pi * (i / 12 - 0.5)) * inner / 2, hi - 0.05 * math.cos(math.pi * (i / 12 - 0.5)) ** 2)
               for i in range(13)]
        for (x0, y0), (x1, y1) in zip(bow[:-1], bow[1:]):
            parts["back"].append(bar((x0, y0, bz), (x1, y1, bz), 0.028, 0.028))
        for i in range(n):
            x = (i + 0.5) / n * inner * 0.9 - inner * 0.45
            parts["back"].append(rod((x * 0.8, sh, bz + 0.02), (x, hi - 0.02, bz), 0.007, 10))
    elif d.back == "splat":
        # Vase-shaped central splat (stacked boxes of varying width) with a pierced slot.
        n = 12
        for i in range(n):
            f = (i + 0.5) / n
            width = inner * (0.25 + 0.2 * math.sin(math.pi * f * 1.3))
            y = lo + f * (hi - lo)
            if 0.4 < f < 0.7:
                for s in (-1, 1):
                    parts["back"].append(box((width * 0.3, (hi - lo) / n + 0.001, 0.02), (s * width * 0.35, y, bz)))
            else:
                parts["back"].append(box((width, (hi - lo) / n + 0.001, 0.02), (0, y, bz)))
    elif d.back == "xback":
        parts["back"].append(bar((-inner / 2, lo, bz), (inner / 2, hi, bz), 0.03, 0.02))
        parts["back"].append(bar((inner / 2, lo, bz), (-inner / 2, hi, bz), 0.03, 0.02))
        parts["back"].append(box((w, 0.035, post_w * 0.8), (0, lo, bz)))
    else:
        raise ValueError(f"unknown back style {d.back!r}")

    # Armrests.
    if d.arms != "none":
        ay = sh + 0.22
        for s in (-1, 1):
            x = s * (w / 2 + 0.02)
            parts["armrest"].append(box((0.05, 0.03, dp * 0.95), (x, ay, 0)))
            parts["armrest"].append(sphere((x, ay, dp * 0.47), 0.03, (1, 0.7, 1)))
            if d.arms == "plank":
                parts["armrest"].append(box((0.035, ay - sh, 0.035), (x, (ay + sh) / 2, zs - 0.03)))
            else:
                for k in range(4):
                    z = zs - 0.03 - k * (dp * 0.7) / 3
                    parts["armrest"].append(rod((x, sh - 0.02, z), (x, ay, z), 0.009, 10))
    return {k: v for k, v in parts.items() if v}


# --------------------------------------------------------------------------- tables


def _top_outline(d: TableDesign, shrink: float, n: int = 48) -> list[tuple[float, float]]:
    """(x, z) outline of the tabletop, ``shrink`` metres inside the edge."""
    if d.top == "rect":
        hw, hd = d.width / 2 - shrink, d.depth / 2 - shrink
        return [(-hw, -hd), (hw, -hd), (hw, hd), (-hw, hd)]
    a, b = d.width / 2 - shrink, d.depth / 2 - shrink
    return [(a * math.cos(2 * math.pi * i / n), b * math.sin(2 * math.pi * i / n)) for i in range(n)]


def _slab(outline, y0: float, y1: float):

    pts = [(x, y, z) for x, z in outline for y in (y0, y1)]
    return hull(np.array(pts))


def table_parts(d: TableDesign) -> dict[str, list]:
    """Part name → list of closed meshes for table design ``d``."""
    h, tt, lt = d.height, d.top_t, d.leg_t
    parts: dict[str, list] = {"seat": [], "leg": [], "stretcher": []}
    top0 = h - tt
    # Tabletop with its edge profile, built from stacked slabs (a stepped moulding).
    if d.edge == "square":
        parts["seat"].append(_slab(_top_outline(d, 0), top0, h))
    elif d.edge == "bevel":
        parts["seat"] += [_slab(_top_outline(d, 0.0), top0 + tt * 0.4, h - tt * 0.3),
                          _slab(_top_outline(d, 0.015), h - tt * 0.3, h), _slab(_top_outline(d, 0.02), top0, top0 + tt * 0.4)]
    elif d.edge == "ogee":
        steps = [(0.025, 0.0, 0.2), (0.012, 0.2, 0.4), (0.0, 0.4, 0.65), (0.008, 0.65, 0.85), (0.018, 0.85, 1.0)]
        parts["seat"] += [_slab(_top_outline(d, s), top0 + a * tt, top0 + b * tt) for s, a, b in steps]
    elif d.edge == "bullnose":
        parts["seat"].append(_slab(_top_outline(d, 0.012), top0, h))
        outline = _top_outline(d, 0.012)
        for (x0, z0), (x1, z1) in zip(outline, outline[1:] + outline[:1]):
            parts["seat"].append(rod((x0, top0 + tt / 2, z0), (x1, top0 + tt / 2, z1), tt / 2, 12))
    elif d.edge == "breadboard":
        parts["seat"].append(_slab(_top_outline(d, 0), top0, h))
        for s in (-1, 1):  # end caps and plank grooves
            parts["seat"].append(box((0.06, tt * 1.3, d.depth + 0.02), (s * (d.width / 2 - 0.02), h - tt * 0.6, 0)))
        for i in range(1, 5):
            z = -d.depth / 2 + i * d.depth / 5
            parts["seat"].append(box((d.width - 0.1, 0.006, 0.008), (0, h + 0.002, z)))
    else:
        raise ValueError(f"unknown edge {d.edge!r}")

    # Leg positions.
    inset = 0.06 + lt / 2
    if d.top == "rect":
        lx, lz = d.width / 2 - inset, d.depth / 2 - inset
    else:
        lx, lz = (d.width / 2 - inset) * 0.72, (d.depth / 2 - inset) * 0.72
    corners = [(sx * lx, sz * lz) for sx in (-1, 1) for sz in (-1, 1)]
    apron_h = 0.1

    if d.legs == "pedestal":
        parts["leg"].append(lathe([(0.05, 0.08), (0.09, 0.14), (0.05, 0.2), (0.07, 0.3), (0.04, 0.45),
                                   (0.06, 0.55), (0.045, top0 - 0.08), (0.1, top0 - 0.03), (0.1, top0)]))
        for i in range(4):
            a = math.radians(45 + 90 * i)
            r = min(d.width, d.depth) * 0.38
            end = (r * math.cos(a), 0.0, r * math.sin(a))
            parts["leg"].append(bar((0, 0.12, 0), (end[0], 0.03, end[2]), 0.05, 0.05))
            parts["leg"].append(sphere((end[0], 0.025, end[2]), 0.03, (1, 0.8, 1)))
    elif d.legs == "trestle":
        for s in (-1, 1):
            x = s * (d.width / 2 - 0.15)
            parts["leg"] += [box((0.07, 0.06, d.depth * 0.8), (x, 0.03, 0)),
                             box((0.07, 0.05, d.depth * 0.7), (x, top0 - 0.025, 0)),
                             box((0.06, top0 - 0.1, 0.1), (x, top0 / 2, 0))]
            parts["leg"] += [sphere((x, 0.005, zz), 0.03, (1, 0.5, 1)) for zz in (-d.depth * 0.35, d.depth * 0.35)]
    elif d.legs == "xframe":
        for s in (-1, 1):
            x = s * (d.width / 2 - 0.12)
            parts["leg"] += [bar((x, 0.0, -d.depth * 0.4), (x, top0, d.depth * 0.4), 0.05, 0.05),
                             bar((x, 0.0, d.depth * 0.4), (x, top0, -d.depth * 0.4), 0.05, 0.05)]
    else:
        for x, z in corners:
            parts["leg"] += _leg(d.legs, x, z, top0, lt, splay=0.08)

    # Apron under the top, between the legs.
    if d.apron != "none" and d.top == "rect" and d.legs not in ("pedestal", "trestle", "xframe"):
        ay = top0 - apron_h / 2
        for s in (-1, 1):
            parts["leg"].append(box((2 * lx, apron_h, 0.022), (0, ay, s * lz)))
            parts["leg"].append(box((0.022, apron_h, 2 * lz), (s * lx, ay, 0)))
        if d.apron == "scalloped":
            for s in (-1, 1):
                for i in range(5):
                    x = -lx + (i + 0.5) * 2 * lx / 5
                    parts["leg"].append(sphere((x, top0 - apron_h, s * lz), 0.035, (1, 0.6, 0.35)))
        if d.apron == "drawers":
            for i in (-1, 1):
                x = i * lx / 2
                parts["leg"].append(box((lx * 0.8, apron_h * 0.7, 0.01), (x, ay, lz + 0.012)))
                parts["leg"].append(sphere((x, ay, lz + 0.03), 0.015))
    elif d.apron != "none" and d.top != "rect":
        # A round apron: a ring of short tangential boards (hollow, unlike a lathe solid).
        r = min(lx, lz) * 1.3
        n = 32
        seg = 2 * math.pi * r / n * 1.08
        parts["leg"] += ring_of(n, r, lambda x, z, a: box((seg, apron_h, 0.022), (x, top0 - apron_h / 2, z),
                                                          rot_y_deg=-(a + 90)))

    # Stretchers / shelf.
    sy = 0.12 if d.legs != "trestle" else 0.3
    if d.legs == "trestle":
        parts["stretcher"].append(box((d.width - 0.3, 0.06, 0.05), (0, sy, 0)))
        parts["stretcher"] += [box((0.04, 0.1, 0.08), (s * (d.width / 2 - 0.15 + s * 0.045), sy, 0)) for s in (-1, 1)]
    elif d.stretcher == "h":
        for s in (-1, 1):
            parts["stretcher"].append(box((0.035, 0.035, 2 * lz), (s * lx, sy, 0)))
        parts["stretcher"].append(rod((-lx, sy, 0), (lx, sy, 0), 0.018))
    elif d.stretcher == "box":
        for s in (-1, 1):
            parts["stretcher"].append(box((2 * lx, 0.03, 0.03), (0, sy, s * lz)))
            parts["stretcher"].append(box((0.03, 0.03, 2 * lz), (s * lx, sy + 0.03, 0)))
    elif d.stretcher == "shelf":
        parts["stretcher"].append(box((2 * lx + lt, 0.025, 2 * lz + lt), (0, sy, 0)))
        parts["stretcher"] += [box((2 * lx, 0.05, 0.015), (0, sy + 0.035, -lz)),
                               box((0.015, 0.05, 2 * lz), (lx, sy + 0.035, 0))]
    elif d.stretcher == "cross":
        parts["stretcher"].append(bar((-lx, sy, -lz), (lx, sy, lz), 0.035, 0.035))
        parts["stretcher"].append(bar((lx, sy, -lz), (-lx, sy, lz), 0.035, 0.035))
        parts["stretcher"].append(sphere((0, sy + 0.03, 0), 0.04))
    return {k: v for k, v in parts.items() if v}


# --------------------------------------------------------------------------- the catalogue

CHAIRS: dict[str, ChairDesign] = {
    "chair_ladderback": ChairDesign(leg="turned", back="ladder", stretcher="double", slats=4, back_h=0.55),
    "chair_slat_square": ChairDesign(leg="square", back="slats_v", stretcher="h", slats=5),
    "chair_spindle_arm": ChairDesign(leg="round", back="spindles", stretcher="box", arms="spindle", slats=7,
                                     width=0.55),
    "chair_windsor": ChairDesign(leg="splayed", back="windsor", seat="round", stretcher="h", slats=9,
                                 back_h=0.5, width=0.5),
    "chair_lattice": ChairDesign(leg="square", back="lattice", stretcher="box", slats=5, back_h=0.5),
    "chair_panel_padded": ChairDesign(leg="tapered", back="panel", seat="padded", back_h=0.5),
    "chair_splat_cabriole": ChairDesign(leg="cabriole", back="splat", seat="padded", back_h=0.52, post=0.04),
    "chair_xback": ChairDesign(leg="square", back="xback", stretcher="h", back_h=0.42, post=0.04),
    "chair_office": ChairDesign(leg="pedestal", back="panel", seat="padded", arms="plank", width=0.5,
                                back_h=0.5),
    "chair_sled_rails": ChairDesign(leg="sled", back="rails_h", slats=3, back_h=0.38),
    "chair_woven_ladder": ChairDesign(leg="round", back="ladder", seat="woven", stretcher="double", slats=3),
    "chair_armchair_slats": ChairDesign(leg="tapered", back="slats_v", seat="padded", arms="plank", slats=3,
                                        width=0.6, depth=0.55, back_h=0.4, post=0.045),
    "chair_bar_stool": ChairDesign(leg="splayed", back="spindles", seat="round", stretcher="ring", slats=4,
                                   seat_h=0.72, back_h=0.28, width=0.42, depth=0.42),
    "chair_turned_lattice": ChairDesign(leg="turned", back="lattice", seat="woven", stretcher="h", slats=3,
                                        back_h=0.5),
    "chair_tall_slats": ChairDesign(leg="square", back="slats_v", stretcher="box", slats=2, back_h=0.7,
                                    post=0.03),
    "chair_cabriole_arm": ChairDesign(leg="cabriole", back="windsor", arms="spindle", slats=7, width=0.56,
                                      back_h=0.5, post=0.04),
}

TABLES: dict[str, TableDesign] = {
    "table_farmhouse": TableDesign(edge="breadboard", legs="turned", apron="plain", width=1.6, depth=0.85),
    "table_pedestal_round": TableDesign(top="round", edge="ogee", legs="pedestal", apron="none", width=1.0, depth=1.0),
    "table_trestle": TableDesign(edge="bevel", legs="trestle", apron="none", width=1.8, depth=0.8),
    "table_tapered_drawers": TableDesign(edge="square", legs="tapered", apron="drawers", width=1.2),
    "table_cabriole_scallop": TableDesign(edge="ogee", legs="cabriole", apron="scalloped", width=1.1, depth=0.7),
    "table_coffee_shelf": TableDesign(edge="bullnose", legs="square", apron="plain", stretcher="shelf", width=1.1,
                                      depth=0.6, height=0.45),
    "table_round_splayed": TableDesign(top="round", edge="bullnose", legs="splayed", apron="plain",
                                       stretcher="cross", width=0.9, depth=0.9),
    "table_xframe": TableDesign(edge="bevel", legs="xframe", apron="none", width=1.4, depth=0.8),
    "table_oval_turned": TableDesign(top="oval", edge="ogee", legs="turned", apron="plain", stretcher="h",
                                     width=1.5, depth=0.9),
    "table_desk_box": TableDesign(edge="square", legs="square", apron="drawers", stretcher="box", width=1.3,
                                  depth=0.65),
    "table_side_round": TableDesign(top="round", edge="bevel", legs="turned", apron="plain", stretcher="shelf",
                                    width=0.55, depth=0.55, height=0.6, leg_t=0.045),
    "table_bar_tall": TableDesign(edge="bullnose", legs="round", apron="none", stretcher="box", width=0.8,
                                  depth=0.8, height=1.05, leg_t=0.05),
    "table_console": TableDesign(edge="ogee", legs="tapered", apron="scalloped", width=1.2, depth=0.4, height=0.8,
                                 leg_t=0.05),
    "table_square_h": TableDesign(edge="square", legs="turned", apron="plain", stretcher="h", width=0.9, depth=0.9),
    "table_oval_pedestal": TableDesign(top="oval", edge="bullnose", legs="pedestal", apron="none", width=1.4,
                                       depth=0.85),
    "table_low_cross": TableDesign(edge="breadboard", legs="square", apron="none", stretcher="cross", width=1.0,
                                   depth=1.0, height=0.4, leg_t=0.07),
}

"""Procedural cakes for the ``things`` style set: parts ``bottom`` (lowest tier) and ``top`` (upper
tiers and decorations). Metres, +Y up, front +Z; each about 1–2 m on its longest side.
"""

from __future__ import annotations

import math

import numpy as np

from stylesets.catalogues.prims import box, hull, lathe, lens_leaf, ring_of, rod, sphere, torus


def _beads(y: float, radius: float, size: float, count: int | None = None) -> list:
    """A piped bead border: a ring of small balls."""
    n = count or max(12, int(2 * math.pi * radius / (size * 1.7)))
    return ring_of(n, radius, lambda x, z, a: sphere((x, y, z), size, subdivisions=1))


def _rosette(x: float, y: float, z: float, size: float) -> list:
    """A piped cream rosette: stacked shrinking rings with a peak."""
    return [torus((x, y + size * 0.3 * i, z), size * (0.9 - 0.25 * i), size * 0.35, 12) for i in range(3)] + \
        [sphere((x, y + size, z), size * 0.35, subdivisions=1)]


def _strawberry(x: float, y: float, z: float, size: float, tilt: float = 0.0) -> list:
    """A strawberry: a rounded cone (point down) with a leafy calyx."""
    pts = [(size * 0.1, 0), (size * 0.45, size * 0.4), (size * 0.5, size * 0.75), (size * 0.3, size), (0, size)]
    out = [lathe(pts, (x, y, z), sections=12)]
    out += ring_of(5, size * 0.25, lambda cx, cz, a: sphere((x + cx, y + size, z + cz), size * 0.18,
                                                           (1.3, 0.35, 1.3), subdivisions=1))
    return out


def _stand(radius: float, height: float) -> list:
    """Cake stand: a thin plate with a beaded edge on a turned stem and foot; the cake sits at ``height``."""
    r, h = radius, height
    out = [lathe([(r, h - 0.025), (r, h)], sections=48),
           lathe([(r * 0.45, 0), (r * 0.45, 0.02), (0.06, 0.05), (0.04, h * 0.4), (0.07, h * 0.5), (0.04, h * 0.6),
                  (0.05, h - 0.02)], sections=24)]
    out += _beads(h - 0.02, r, 0.016)
    return out


def birthday_cake(radius: float = 0.45, seed: int = 21) -> dict:
    """Birthday cake: two tiers with bead borders, icing drips round the top tier's edge, candles with flames."""
    r = radius
    rng_s = np.random.default_rng(seed + 100)
    bottom = [lathe([(r, 0), (r, 0.3)], sections=48)]
    bottom += _beads(0.01, r + 0.005, 0.025)
    # Vertical piped ridges all round the sides of both tiers.
    bottom += ring_of(44, r + 0.02, lambda x, z, a: rod((x, 0.03, z), (x, 0.28, z), 0.016, 8))
    top = _beads(0.3, r * 0.98, 0.022)
    r2 = r * 0.65
    top.append(lathe([(r2, 0.3), (r2, 0.55)], sections=48))
    top += _beads(0.31, r2 + 0.005, 0.02)
    top += ring_of(30, r2 + 0.02, lambda x, z, a: rod((x, 0.33, z), (x, 0.45, z), 0.014, 8))
    # Sprinkles on both tops.
    for _ in range(160):
        rr, aa = rng_s.uniform(0, 1), rng_s.uniform(0, 2 * math.pi)
        lower = rr > 0.45
        rad = (r2 + 0.03 + (r - r2 - 0.06) * rng_s.uniform()) if lower else r2 * 0.9 * math.sqrt(rr / 0.45)
        y = 0.305 if lower else 0.585
        x, z = rad * math.cos(aa), rad * math.sin(aa)
        b = rng_s.uniform(0, math.pi)
        top.append(rod((x, y, z), (x + 0.03 * math.cos(b), y + 0.004, z + 0.03 * math.sin(b)), 0.007, 5))
    top.append(lathe([(r2 + 0.015, 0.53), (r2 + 0.015, 0.57), (0, 0.58)], sections=48))  # icing cap
    # Drips.
    rng = np.random.default_rng(seed)
    for i in range(22):
        a = 2 * math.pi * i / 22
        ln = rng.uniform(0.05, 0.14)
        x, z = (r2 + 0.012) * math.cos(a), (r2 + 0.012) * math.sin(a)
        top.append(rod((x, 0.56, z), (x, 0.56 - ln, z), 0.013, 8))
        top.append(sphere((x, 0.56 - ln, z), 0.018, subdivisions=1))
    # Candles: striped sticks with a wick and a flame.
    for x, z, a in ring_of(9, r2 * 0.65, lambda x, z, a: (x, z, a)):
        top.append(rod((x, 0.57, z), (x, 0.85, z), 0.016, 10))
        top += [torus((x, 0.6 + 0.045 * k, z), 0.017, 0.005, 10) for k in range(6)]
        top.append(sphere((x, 0.9, z), 0.02, (0.8, 1.7, 0.8)))
    # Raise everything onto a cake stand (part of the bottom).
    for m in bottom + top:
        m.apply_translation([0, 0.3, 0])
    bottom += _stand(r + 0.06, 0.3)
    return {"bottom": bottom, "top": top}


def wedding_cake(tiers: int = 3, radius: float = 0.5, seed: int = 22) -> dict:
    """Wedding cake: three stacked tiers, pearl borders, scalloped swags of beads round each tier, sugar roses
    and a topper of two hearts on the top."""
    bottom, top = [], []
    y = 0.0
    r = radius
    th = 0.26
    for k in range(tiers):
        part = bottom if k == 0 else top
        part.append(lathe([(r, y), (r, y + th)], sections=48))
        # Ruffles: stacked thin rings round the tier's lower half.
        part += [torus((0, y + 0.035 + 0.034 * i, 0), r + 0.016, 0.012, 40) for i in range(int((th - 0.06) / 0.034))]
        part += ring_of(40, r + 0.004, lambda x, z, a, y=y, th=th: rod((x, y + th * 0.85, z), (x, y + th, z), 0.008, 5))
        part += _beads(y + 0.015, r + 0.005, 0.018)
        top_border = _beads(y + th, r - 0.005, 0.016)
        top += top_border
        # Swags: arcs of small beads hanging between points on the tier's side.
        n = 8
        for i in range(n):
            for j in range(9):
                f = j / 8
                a = 2 * math.pi * (i + f) / n
                yy = y + th * 0.8 - th * 0.35 * math.sin(math.pi * f)
                part.append(sphere(((r + 0.006) * math.cos(a), yy, (r + 0.006) * math.sin(a)), 0.012, subdivisions=1))
            a = 2 * math.pi * i / n
            part.append(sphere(((r + 0.01) * math.cos(a), y + th * 0.82, (r + 0.01) * math.sin(a)), 0.025,
                               subdivisions=1))
            # A string of pearls hanging straight down from each swag point, clear of the side.
            part += [sphere(((r + 0.03) * math.cos(a), y + th * 0.74 - 0.032 * q, (r + 0.03) * math.sin(a)), 0.013,
                            subdivisions=1) for q in range(int(th * 0.7 / 0.032))]
        y += th
        if k < tiers - 1:
            # Separator plate on pillars: the next tier floats above this one.
            top += ring_of(6, r * 0.45, lambda x, z, a, y=y: lathe([(0.02, 0), (0.014, 0.03), (0.012, 0.12),
                                                                    (0.02, 0.15)], (x, y, z), sections=12))
            top.append(lathe([(r * 0.62, y + 0.15), (r * 0.62, y + 0.165)], sections=40))
            y += 0.165
        r *= 0.68
        th *= 0.92
    # Sugar roses on the top and a heart topper.
    top += [torus((x, y + 0.015 * i + 0.01, z), 0.04 - 0.012 * i, 0.014, 12)
              for x, z, _ in ring_of(5, r * 0.9, lambda x, z, a: (x, z, a)) for i in range(3)]
    for s in (-1, 1):
        cx = s * 0.05
        top.append(rod((cx, y, 0), (cx, y + 0.15, 0), 0.008, 6))
        top += [sphere((cx + e * 0.025, y + 0.2, 0), 0.035, (1, 1, 0.4), subdivisions=1) for e in (-1, 1)]
        top.append(hull(np.array([[cx + e * 0.055, y + 0.2, q] for e in (-1, 1) for q in (-0.012, 0.012)]
                                 + [[cx, y + 0.12, q] for q in (-0.012, 0.012)])))
    return {"bottom": bottom, "top": top}


def shortcake(radius: float = 0.5, seed: int = 23) -> dict:
    """Strawberry shortcake: a tall sponge with visible cream layers (protruding bands), cream rosettes each
    carrying a strawberry round the top, and halved berries pressed into the side."""
    r = radius
    bottom = [lathe([(r, 0), (r, 0.4)], sections=48)]
    bottom += [torus((0, y, 0), r, 0.016, 48) for y in (0.13, 0.26)]
    bottom += ring_of(14, r, lambda x, z, a: sphere((x, 0.195, z), 0.035, (1, 1.3, 1), subdivisions=1))
    # Ladyfinger biscuits standing round the side (a charlotte), with gaps between them.
    bottom += ring_of(40, r + 0.025, lambda x, z, a: sphere((x, 0.24, z), 0.026, (1, 9.5, 1), subdivisions=1))
    bottom += [torus((0, 0.12, 0), r + 0.055, 0.01, 48)]  # ribbon
    top = [lathe([(r + 0.005, 0.39), (r + 0.005, 0.42), (0, 0.425)], sections=48)]
    for x, z, _ in ring_of(10, r * 0.78, lambda x, z, a: (x, z, a)):
        top += _rosette(x, 0.42, z, 0.05)
        top += _strawberry(x, 0.46, z, 0.07)
    top += _strawberry(0, 0.42, 0, 0.12)
    rng = np.random.default_rng(seed)
    for _ in range(40):  # blueberries
        rr, aa = r * 0.62 * math.sqrt(rng.uniform(0.1, 1)), rng.uniform(0, 2 * math.pi)
        top.append(sphere((rr * math.cos(aa), 0.445, rr * math.sin(aa)), 0.022, subdivisions=1))
    top += [sphere((x, 0.43, z), 0.03, (1, 0.5, 1), subdivisions=1) for x, z, _ in
            ring_of(6, r * 0.35, lambda x, z, a: (x, z, a), start_deg=30)]
    return {"bottom": bottom, "top": top}


def bundt_cake(radius: float = 0.5, flutes: int = 26, seed: int = 24) -> dict:
    """Bundt cake: a fluted ring (lathe body with rounded ridges) on a plate; thick glaze with long drips and
    cherries with stems on top."""
    rng = np.random.default_rng(seed)
    r = radius
    bottom = [lathe([(r + 0.1, 0), (r + 0.1, 0.02), (0, 0.02)], sections=48)]  # plate
    prof = [(r * 0.3, 0.02), (r * 0.9, 0.02), (r * 0.9, 0.12), (r * 0.78, 0.3), (r * 0.55, 0.36), (r * 0.3, 0.3)]
    bottom.append(lathe(prof, sections=48))
    for i in range(flutes):
        a = 2 * math.pi * i / flutes
        c, s = math.cos(a), math.sin(a)
        # Deep flutes: round ribs on a slimmer core, with grooves between them.
        bottom.append(rod((r * 0.97 * c, 0.03, r * 0.97 * s), (r * 0.97 * c, 0.13, r * 0.97 * s), 0.035, 10))
        bottom.append(rod((r * 0.97 * c, 0.13, r * 0.97 * s), (r * 0.8 * c, 0.31, r * 0.8 * s), 0.03, 10))
    bottom += _beads(0.035, r + 0.085, 0.014)
    top = [torus((0, 0.33, 0), r * 0.68, 0.06, 48)]
    for i in range(flutes * 2):
        a = 2 * math.pi * (i + 0.5) / (flutes * 2)
        c, s = math.cos(a), math.sin(a)
        ln = rng.uniform(0.3, 0.9)
        p0 = np.array([r * 0.8 * c, 0.34, r * 0.8 * s])
        p1 = np.array([r * (0.85 + 0.1 * ln) * c, 0.3 - 0.15 * ln, r * (0.85 + 0.1 * ln) * s])
        top.append(rod(p0, p1, 0.02, 8))
        top.append(sphere(p1, 0.026, subdivisions=1))
    # Zig-zag drizzle across the ring.
    for i in range(40):
        a0, a1 = 2 * math.pi * i / 40, 2 * math.pi * (i + 1) / 40
        r0, r1 = r * (0.52 if i % 2 else 0.84), r * (0.84 if i % 2 else 0.52)
        top.append(rod((r0 * math.cos(a0), 0.4, r0 * math.sin(a0)), (r1 * math.cos(a1), 0.4, r1 * math.sin(a1)),
                       0.01, 5))
    for _ in range(120):  # chopped nuts scattered on the glaze
        rr, aa, b = rng.uniform(r * 0.5, r * 0.86), rng.uniform(0, 2 * math.pi), rng.uniform(0, math.pi)
        x, z = rr * math.cos(aa), rr * math.sin(aa)
        top.append(box((0.03, 0.012, 0.018), (x, 0.405, z), rot_y_deg=math.degrees(b)))
    for x, z, a in ring_of(6, r * 0.68, lambda x, z, a: (x, z, a)):
        top.append(sphere((x, 0.44, z), 0.05))
        top.append(rod((x, 0.48, z), (x + 0.03, 0.58, z + 0.02), 0.006, 6))
        top.append(lens_leaf((x + 0.03, 0.57, z + 0.02), [1, 0.3, 0.2], 0.05, 0.025, 0.006))
    for m in bottom + top:
        m.apply_translation([0, 0.32, 0])
    bottom += _stand(r + 0.12, 0.32)
    return {"bottom": bottom, "top": top}

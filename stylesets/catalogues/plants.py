"""Procedural plants for the ``things`` style set: parts ``pot`` (pot, soil) and ``leaf`` (stems,
branches, leaves, flowers). Metres, +Y up, front +Z; each about 1–2 m on its longest side.
"""

from __future__ import annotations

import math

import numpy as np

from stylesets.catalogues.prims import box, hull, lathe, lens_leaf, oriented_frame, ring_of, rod, sphere, torus


def _pot(radius: float, height: float, style: str = "banded") -> list:
    """Flower pot with rolled rim, bands (``banded``) or a flared bowl (``bowl``), plus soil."""
    r, h = radius, height
    out = []
    if style == "bowl":
        out.append(lathe([(r * 0.55, 0), (r * 0.6, h * 0.08), (r * 0.95, h * 0.5), (r * 1.05, h * 0.9),
                          (r * 1.1, h)]))
        out.append(lathe([(r * 0.5, -0.02), (r * 0.6, -0.02), (r * 0.6, 0.01), (r * 0.5, 0.01)]))
        out += ring_of(16, r * 1.06, lambda x, z, a: sphere((x, h * 0.75, z), h * 0.06))
    else:
        out.append(lathe([(r * 0.7, 0), (r * 0.72, h * 0.05), (r * 0.92, h * 0.85), (r * 0.95, h)]))
        out.append(torus((0, h * 0.2, 0), r * 0.76, h * 0.035))
        out.append(torus((0, h * 0.45, 0), r * 0.83, h * 0.035))
    # Rim and soil.
    out.append(lathe([(r * 0.9, h * 0.85), (r * 1.08, h * 0.86), (r * 1.1, h * 1.02), (r * 0.9, h * 1.02)]))
    out.append(lathe([(r * 0.92, h * 0.9), (r * 0.92, h * 0.97)]))
    return out


def fern(fronds: int = 9, length: float = 0.75, pinnae: int = 12, seed: int = 11) -> dict:
    """Fern / palm: arching fronds (chains of thin rods) with paired leaflets along them, in a banded pot."""
    rng = np.random.default_rng(seed)
    pot = _pot(0.2, 0.35)
    leaf = []
    y0 = 0.33
    for f in range(fronds):
        a = 2 * math.pi * f / fronds + rng.uniform(-0.2, 0.2)
        lift = rng.uniform(0.9, 1.5)
        pts = []
        for i in range(11):
            t = i / 10
            rad = length * t * 0.85
            y = y0 + length * (lift * t - 1.2 * t * t) * 0.9
            pts.append(np.array([rad * math.cos(a), y, rad * math.sin(a)]))
        for p, q in zip(pts[:-1], pts[1:]):
            leaf.append(rod(p, q, 0.008, 6))
        side = np.array([-math.sin(a), 0, math.cos(a)])
        for i in range(pinnae):
            t = 0.15 + 0.8 * i / pinnae
            k = t * 10
            j = min(int(k), 9)
            p = pts[j] + (pts[j + 1] - pts[j]) * (k - j)
            tang = pts[j + 1] - pts[j]
            tang /= np.linalg.norm(tang)
            size = 0.16 * (1 - 0.7 * (t - 0.15))
            for s in (-1, 1):
                dirn = side * s + tang * 0.6 + np.array([0, -0.15, 0])
                leaf.append(lens_leaf(p, dirn, size, size * 0.28, 0.008))
    return {"pot": pot, "leaf": leaf}


def bush(radius: float = 0.38, leaves: int = 220, seed: int = 12) -> dict:
    """Bushy plant: a few branching stems carrying a dense round cluster of small oval leaves, in a bowl pot."""
    rng = np.random.default_rng(seed)
    pot = _pot(0.24, 0.28, "bowl")
    leaf = []
    c = np.array([0, 0.28 + radius * 0.95, 0])
    base = np.array([0, 0.26, 0])
    tips = []
    for i in range(6):
        a = 2 * math.pi * i / 6
        mid = c + np.array([math.cos(a) * radius * 0.3, -radius * 0.3, math.sin(a) * radius * 0.3])
        tip = c + np.array([math.cos(a) * radius * 0.65, rng.uniform(-0.1, 0.3) * radius, math.sin(a) * radius * 0.65])
        leaf += [rod(base, mid, 0.015, 8), rod(mid, tip, 0.01, 8)]
        tips.append(tip)
    for _ in range(leaves):
        v = rng.normal(size=3)
        v /= np.linalg.norm(v)
        if v[1] < -0.6:
            v[1] = -v[1]
        p = c + v * radius * rng.uniform(0.75, 1.0) * np.array([1.1, 0.85, 1.1])
        out = v + rng.normal(size=3) * 0.5
        leaf.append(lens_leaf(p - out / np.linalg.norm(out) * 0.02, out, 0.1, 0.06, 0.01, curl=0.15))
    return {"pot": pot, "leaf": leaf}


def cactus(height: float = 0.8, ribs: int = 10, arms: int = 2, seed: int = 13) -> dict:
    """Saguaro-like cactus: a column with vertical ribs, bent arms, rows of spines along the ribs, a top flower."""
    rng = np.random.default_rng(seed)
    pot = _pot(0.2, 0.25)
    leaf = []
    r = 0.09
    y0 = 0.22

    def column(p0, p1, radius, n_spines):
        out = [rod(p0, p1, radius, 16), sphere(p1, radius)]
        d, s, n = oriented_frame(np.asarray(p1) - np.asarray(p0))
        for k in range(ribs):
            a = 2 * math.pi * k / ribs
            off = (s * math.cos(a) + n * math.sin(a)) * radius * 0.92
            out.append(rod(np.asarray(p0) + off, np.asarray(p1) + off, radius * 0.2, 6))
            if True:
                for j in range(n_spines):
                    t = (j + 0.5) / n_spines
                    q = np.asarray(p0) + (np.asarray(p1) - np.asarray(p0)) * t + off * 1.15
                    out.append(rod(q, q + off / np.linalg.norm(off) * 0.045 + d * 0.015, 0.0055, 4))
        return out

    top = np.array([0, y0 + height, 0])
    leaf += column((0, y0, 0), top, r, 10)
    for k in range(arms):
        a = math.pi * k + rng.uniform(-0.3, 0.3)
        hy = y0 + height * (0.35 + 0.15 * k)
        dirn = np.array([math.cos(a), 0, math.sin(a)])
        elbow = np.array([0, hy, 0]) + dirn * 0.22
        leaf += column(np.array([0, hy, 0]), elbow, r * 0.65, 3)
        leaf += column(elbow, elbow + np.array([0, 0.28 - 0.08 * k, 0]), r * 0.65, 5)
    # Flower on top.
    leaf += ring_of(8, 0.03, lambda x, z, a: lens_leaf(top + [0, r * 0.9, 0], [x, 0.5 * 0.03, z], 0.07, 0.035, 0.008))
    leaf.append(sphere(top + [0, r + 0.01, 0], 0.02))
    return {"pot": pot, "leaf": leaf}


def tree(height: float = 0.9, depth: int = 3, seed: int = 14) -> dict:
    """Bonsai-like tree: a trunk forking into branches (recursive rods), leaf clusters at the twig tips,
    in a shallow rectangular tray with feet."""
    rng = np.random.default_rng(seed)
    pot = [box((0.6, 0.1, 0.42), (0, 0.07, 0)), box((0.64, 0.025, 0.46), (0, 0.13, 0)),
           box((0.56, 0.02, 0.38), (0, 0.145, 0))]
    pot += [box((0.08, 0.03, 0.06), (sx * 0.24, 0.015, sz * 0.15)) for sx in (-1, 1) for sz in (-1, 1)]
    leaf = []

    def grow(p, d, length, radius, level):
        q = p + d * length
        leaf.append(rod(p, q, radius, 10))
        leaf.append(sphere(q, radius))
        if level == 0:
            for _ in range(30):
                v = rng.normal(size=3) * np.array([1, 0.4, 1])
                leaf.append(lens_leaf(q + v / np.linalg.norm(v) * 0.07 * rng.uniform(0.3, 1), v + [0, 0.6, 0], 0.07,
                                  0.04, 0.01))
            return
        for k in range(2 if level < depth else 3):
            a = rng.uniform(0, 2 * math.pi)
            nd = d * 0.55 + np.array([math.cos(a), 0.35, math.sin(a)]) * 0.8
            nd /= np.linalg.norm(nd)
            grow(q, nd, length * rng.uniform(0.6, 0.75), radius * 0.62, level - 1)

    grow(np.array([0, 0.14, 0]), np.array([0.15, 1, 0]) / 1.011, height * 0.4, 0.045, depth)
    # Surface roots.
    leaf += ring_of(5, 0.09, lambda x, z, a: rod((0, 0.17, 0), (x, 0.15, z), 0.018, 6))
    return {"pot": pot, "leaf": leaf}


def succulent(rings: int = 5, per_ring: int = 9, seed: int = 15) -> dict:
    """Succulent rosette (echeveria): concentric whorls of thick pointed leaves, spiralling and opening outwards,
    in a banded pot."""
    pot = _pot(0.26, 0.3)
    leaf = []
    c = np.array([0, 0.3, 0])
    golden = 137.5
    for k in range(rings):
        t = k / max(rings - 1, 1)
        length = 0.32 * (1 - 0.6 * t)
        tilt = 0.15 + 1.1 * t  # outer leaves lie flat, inner ones stand up
        for i in range(per_ring):
            a = math.radians(i * 360 / per_ring + k * golden)
            d = np.array([math.cos(a), tilt, math.sin(a)])
            d /= np.linalg.norm(d)
            dd, s, n = oriented_frame(d)
            b = c + np.array([0, 0.01 + 0.02 * k, 0])
            pts = []
            for j in range(6):
                u = j / 6
                w = length * 0.22 * math.sin(math.pi * min(u * 1.2, 0.95)) ** 0.7 + 0.004
                for e in (-1, 1):
                    p = b + dd * length * u + s * e * w + n * abs(e) * w * 0.25
                    pts += [p + n * 0.014 * (1 - 0.6 * u), p - n * 0.014 * (1 - 0.6 * u)]
            pts.append(b + dd * length * 1.05 + n * 0.01)
            leaf.append(hull(np.array(pts)))
    leaf.append(sphere(c + [0, 0.1, 0], 0.03))
    return {"pot": pot, "leaf": leaf}


def flowers(stems: int = 7, seed: int = 16) -> dict:
    """Flowering plant: stems with alternating leaves, each topped by a daisy-like flower (ring of petals round
    a domed centre), in a bowl pot."""
    rng = np.random.default_rng(seed)
    pot = _pot(0.22, 0.3, "bowl")
    leaf = []
    for k in range(stems):
        a = 2 * math.pi * k / stems + rng.uniform(-0.3, 0.3)
        lean = rng.uniform(0.1, 0.35)
        top = np.array([math.cos(a) * lean * 0.8, 0.3 + rng.uniform(0.55, 0.85), math.sin(a) * lean * 0.8])
        base = np.array([math.cos(a) * 0.05, 0.28, math.sin(a) * 0.05])
        mid = (base + top) / 2 + np.array([0, 0, 0])
        leaf += [rod(base, mid, 0.009, 6), rod(mid, top, 0.008, 6)]
        for j in range(3):
            t = 0.2 + 0.25 * j
            p = base + (top - base) * t
            b = a + math.pi / 2 * (1 if j % 2 else -1)
            leaf.append(lens_leaf(p, [math.cos(b), 0.5, math.sin(b)], 0.12, 0.045, 0.008, curl=0.2))
        d = top - mid
        d /= np.linalg.norm(d)
        _, s, n = oriented_frame(d)
        for i in range(12):
            ang = 2 * math.pi * i / 12
            pd = s * math.cos(ang) + n * math.sin(ang) + d * 0.15
            leaf.append(lens_leaf(top, pd, 0.085, 0.032, 0.01))
            leaf.append(lens_leaf(top - d * 0.01, pd * 0.8 + d * 0.5, 0.06, 0.025, 0.01))
        leaf.append(sphere(top + d * 0.01, 0.03, (1, 0.7, 1)))
    # Basal clump of long strap leaves arching out of the pot.
    for i in range(14):
        a = 2 * math.pi * i / 14 + rng.uniform(-0.2, 0.2)
        p0 = np.array([0.06 * math.cos(a), 0.28, 0.06 * math.sin(a)])
        p1 = p0 + np.array([0.12 * math.cos(a), 0.2, 0.12 * math.sin(a)])
        leaf.append(lens_leaf(p0, p1 - p0, 0.24, 0.05, 0.01, curl=0.15))
        leaf.append(lens_leaf(p1, [math.cos(a), -0.2, math.sin(a)], 0.14, 0.045, 0.01, curl=0.15))
    return {"pot": pot, "leaf": leaf}

"""Procedural buildings, plants, cakes and crystals for the ``things`` style set.

Role: ``THINGS_CATALOGUE`` maps exemplar name → (category, function, kwargs);
``stylesets.registry.things_specs`` turns it into ``ExemplarSpec`` s. Each
function returns {part name: list of closed meshes}, with the category's own
part names (vocabulary ``THINGS``):

* building → ``body`` (walls, windows, doors, columns), ``roof`` (roofs, tiles, eaves, chimneys)
* plant    → ``pot`` (pot, soil), ``leaf`` (stems, branches, leaves, flowers)
* cake     → ``bottom`` (lowest tier), ``top`` (upper tiers and decorations)
* crystal  → ``bottom`` (rocky base), ``top`` (crystals)

Exemplars within a category differ in their *detail* (tiles vs flared eaves vs
crenellations; fronds vs round leaves vs ribs and spines; beads vs drips vs
fruit; long prisms vs druse vs cubes), not only in proportions.

Units: metres, +Y up, front +Z. Every shape is about 1–2 m on its longest side
(aspect ≤ ~2.5:1), so one voxel at 256³ is ~4–8 mm and the thinnest pieces are
made ≥ ~2.5 voxels. Randomness uses ``np.random.default_rng(seed)``: builds are
deterministic.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from stylesets.catalogues.prims import bar, box, hull, lathe, ring_of, rod, sphere, torus

# --------------------------------------------------------------------------- helpers


def _frame(direction) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal (d, side, normal) frame with d along ``direction``."""
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    ref = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    s = np.cross(d, ref)
    s /= np.linalg.norm(s)
    n = np.cross(s, d)
    return d, s, n


def _slab(center, u, v, su: float, sv: float, sn: float):
    """Oriented box: ``su`` along unit-ish vector ``u``, ``sv`` along ``v``, ``sn`` along u×v."""
    c = np.asarray(center, float)
    u = np.asarray(u, float) / np.linalg.norm(u)
    v = np.asarray(v, float)
    v = v - u * (v @ u)
    v /= np.linalg.norm(v)
    n = np.cross(u, v)
    pts = [c + a * su / 2 * u + b * sv / 2 * v + e * sn / 2 * n
           for a in (-1, 1) for b in (-1, 1) for e in (-1, 1)]
    return hull(np.array(pts))


def _leaf(base, direction, length: float, width: float, thick: float, curl: float = 0.0):
    """Lens-shaped leaf (convex hull) from ``base`` along ``direction``; ``curl`` lifts its edges (cupped)."""
    d, s, n = _frame(direction)
    b = np.asarray(base, float)
    pts = []
    for i in range(9):
        t = i / 8
        w = width / 2 * math.sin(math.pi * t) ** 0.8
        for side in (-1, 1):
            p = b + d * length * t + s * side * w + n * curl * w
            pts += [p + n * thick / 2, p - n * thick / 2]
    return hull(np.array(pts))


def _square_lathe(profile, base=(0, 0, 0)):
    """Square-plan turned solid: ``profile`` radii are half-widths of the square (flared roofs, plinths)."""
    import trimesh

    m = lathe([(r * math.sqrt(2), h) for r, h in profile], base=(0, 0, 0), sections=4)
    m.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 4, [0, 1, 0]))
    m.apply_translation(np.asarray(base, float))
    return m


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


def _window(x: float, y: float, z: float, w: float, h: float, face: str, t: float = 0.02,
            mullions: tuple[int, int] = (2, 2), sill: bool = True) -> list:
    """Window frame (protruding ``t``) with mullions and a sill on a wall; ``face`` "z" (front) or "x" (side).

    (x, y, z) is the window centre on the wall surface; ``w`` × ``h`` its size.
    """
    out = []
    nx, ny = mullions

    def piece(cx, cy, sx, sy, depth, off=0.0):
        if face == "z":
            return box((sx, sy, depth), (x + cx, y + cy, z + math.copysign(depth / 2 + off, z)))
        return box((depth, sy, sx), (x + math.copysign(depth / 2 + off, x), y + cy, z + cx))

    f = t * 1.2
    out += [piece(0, s * (h / 2 - f / 2), w, f, t) for s in (-1, 1)]
    out += [piece(s * (w / 2 - f / 2), 0, f, h, t) for s in (-1, 1)]
    for i in range(1, nx):
        out.append(piece(-w / 2 + w * i / nx, 0, f * 0.6, h, t * 0.7))
    for j in range(1, ny):
        out.append(piece(0, -h / 2 + h * j / ny, w, f * 0.6, t * 0.7))
    if sill:
        out.append(piece(0, -h / 2 - f * 0.6, w * 1.2, f, t * 2))
        out.append(piece(0, h / 2 + f * 0.7, w * 1.1, f * 1.2, t * 1.5))  # lintel
    return out


def _tiles_gable(w: float, d: float, y0: float, rise: float, over: float, rows: int, t: float) -> list:
    """Roof tiles on a gable roof (ridge along x): rows of overlapping tilted thin slabs per side, staggered."""
    out = []
    half = d / 2 + over
    for side in (-1, 1):
        # Slope from the eave (z = side*half, y0) up to the ridge (z = 0, y0 + rise).
        eave = np.array([0.0, y0, side * half])
        ridge = np.array([0.0, y0 + rise, 0.0])
        up = ridge - eave
        slope_len = float(np.linalg.norm(up))
        u = up / slope_len
        normal = np.cross(np.array([1.0, 0, 0]), u) * (-side)  # outward
        if normal[1] < 0:
            normal = -normal
        step = slope_len / rows
        n_tiles = max(4, int((w + 2 * over) / (step * 1.1)))
        tw = (w + 2 * over) / n_tiles
        for r in range(rows):
            c0 = eave + u * (step * (r + 0.55)) + normal * (t * 0.9)
            shift = (tw / 2) if r % 2 else 0.0
            for k in range(n_tiles):
                x = -w / 2 - over + tw * (k + 0.5) + shift
                if x > w / 2 + over - tw * 0.3:
                    continue
                out.append(_slab(c0 + np.array([x, 0, 0]) + normal * (t * 0.3) * (k % 2 == 0),
                                 u, [1, 0, 0], step * 1.15, tw * 0.92, t))
    return out


def _gable_roof(w: float, d: float, y0: float, rise: float, over: float, t: float) -> list:
    """Solid gable roof (ridge along x) with overhang ``over``; a triangular gable infill under it."""
    hw, hd = w / 2 + over, d / 2 + over
    slab = hull(np.array([[sx * hw, y0 - t, sz * hd] for sx in (-1, 1) for sz in (-1, 1)]
                         + [[sx * hw, y0 + rise, 0] for sx in (-1, 1)]
                         + [[sx * hw, y0 + rise + t, 0] for sx in (-1, 1)]))
    return [slab, bar((-hw - 0.01, y0 + rise + t, 0), (hw + 0.01, y0 + rise + t, 0), t * 2.5, t * 2.5)]


# --------------------------------------------------------------------------- buildings


def cottage(width: float = 1.1, depth: float = 0.8, wall_h: float = 0.6, seed: int = 1) -> dict:
    """Cottage: stone plinth, quoins, framed windows, a door with frame, a steep tiled gable roof and a chimney."""
    rng = np.random.default_rng(seed)
    body, roof = [], []
    w, d, h = width, depth, wall_h
    body.append(box((w + 0.06, 0.08, d + 0.06), (0, 0.04, 0)))  # plinth
    body.append(box((w, h, d), (0, h / 2, 0)))
    # Corner quoins: alternating blocks at the corners.
    for sx in (-1, 1):
        for sz in (-1, 1):
            for i in range(6):
                y = 0.1 + i * (h - 0.1) / 6 + 0.04
                long = 0.1 if i % 2 else 0.06
                body.append(box((long, 0.06, 0.06 if i % 2 else 0.1),
                                (sx * (w / 2 - long / 2 + 0.015), y, sz * (d / 2 - (0.03 if i % 2 else 0.05) + 0.015))))
    # Door with frame and step.
    body.append(box((0.18, 0.34, 0.03), (0, 0.08 + 0.17, d / 2)))
    body += [box((0.03, 0.37, 0.05), (s * 0.105, 0.08 + 0.185, d / 2)) for s in (-1, 1)]
    body.append(box((0.26, 0.04, 0.05), (0, 0.08 + 0.37, d / 2)))
    body.append(box((0.3, 0.04, 0.12), (0, 0.02, d / 2 + 0.05)))
    for s in (-1, 1):
        body += _window(s * 0.32, h * 0.55, d / 2, 0.18, 0.2, "z", mullions=(2, 2))
        body += _window(w / 2, h * 0.55, s * 0.18, 0.16, 0.2, "x", mullions=(2, 2))
        # Flower boxes under the front windows.
        body.append(box((0.2, 0.04, 0.05), (s * 0.32, h * 0.55 - 0.15, d / 2 + 0.04)))
    # Half-timbering: posts, a mid rail and diagonal braces on every wall.
    tt = 0.025
    for zf in (-1, 1):
        zz = zf * (d / 2 + tt / 2)
        for xf in np.linspace(-w / 2 + 0.02, w / 2 - 0.02, 7):
            body.append(box((tt, h - 0.08, tt), (xf, 0.08 + (h - 0.08) / 2, zz)))
        body.append(box((w, tt, tt), (0, h * 0.35, zz)))
        body.append(box((w, tt, tt), (0, h - tt / 2, zz)))
        for x0 in (-w / 2 + 0.02, w / 2 - 0.02):
            x1 = x0 * 0.68
            body.append(bar((x0, h * 0.36, zz), (x1, h - 0.02, zz), tt, tt))
    for xf in (-1, 1):
        xx = xf * (w / 2 + tt / 2)
        for zc in np.linspace(-d / 2 + 0.02, d / 2 - 0.02, 5):
            body.append(box((tt, h - 0.08, tt), (xx, 0.08 + (h - 0.08) / 2, zc)))
        body.append(box((tt, tt, d), (xx, h * 0.35, 0)))
    rise = 0.45
    roof += _gable_roof(w, d, h, rise, 0.08, 0.03)
    roof += _tiles_gable(w, d, h, rise, 0.08, 9, 0.022)
    # Chimney with cap.
    cx, cz = w * 0.28, -d * 0.18
    roof.append(box((0.12, 0.5, 0.12), (cx, h + 0.4, cz)))
    roof.append(box((0.16, 0.04, 0.16), (cx, h + 0.66, cz)))
    roof += [rod((cx + s * 0.03, h + 0.66, cz), (cx + s * 0.03, h + 0.72, cz), 0.018) for s in (-1, 1)]
    del rng
    return {"body": body, "roof": roof}


def pagoda(tiers: int = 3, base: float = 1.1, seed: int = 2) -> dict:
    """Pagoda: stacked shrinking storeys with corner columns and railings, flared upturned eaves, a ringed spire."""
    body, roof = [], []
    body.append(_square_lathe([(base * 0.62, 0), (base * 0.62, 0.05), (base * 0.57, 0.05), (base * 0.57, 0.1)]))
    y = 0.1
    storey = 0.34
    for k in range(tiers):
        s = base * (0.5 - 0.08 * k)
        body.append(box((s * 2 * 0.8, storey, s * 2 * 0.8), (0, y + storey / 2, 0)))
        # Columns round the storey and a railing on each side.
        n = 5
        for i in range(n):
            f = -s * 0.9 + 1.8 * s * i / (n - 1)
            for px, pz in ((f, s * 0.9), (f, -s * 0.9), (s * 0.9, f), (-s * 0.9, f)):
                body.append(rod((px, y, pz), (px, y + storey, pz), 0.022, 10))
        for sx, sz, lx, lz in ((0, 1, 1, 0), (0, -1, 1, 0), (1, 0, 0, 1), (-1, 0, 0, 1)):
            c = (sx * s * 0.9, y + 0.1, sz * s * 0.9)
            body.append(box((lx * s * 1.8 + 0.03, 0.025, lz * s * 1.8 + 0.03), c))
        y += storey
        # Flared roof: a concave profile gives the upturned eaves; ridges to the corners.
        r = s * 1.45
        prof = [(r, -0.02), (r * 1.02, 0.02), (r * 0.82, 0.03), (r * 0.6, 0.07), (s * 0.7, 0.15), (s * 0.6, 0.17)]
        roof.append(_square_lathe(prof, (0, y, 0)))
        for cx, cz in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            roof.append(bar((cx * s * 0.7, y + 0.15, cz * s * 0.7), (cx * r * 1.04, y + 0.05, cz * r * 1.04),
                            0.035, 0.035))
            roof.append(bar((cx * r * 1.0, y + 0.03, cz * r * 1.0), (cx * r * 1.08, y + 0.11, cz * r * 1.08),
                            0.03, 0.03))
        # Rafter ends under the eave.
        for i in range(9):
            f = -r * 0.8 + 1.6 * r * i / 8
            for px, pz in ((f, r * 0.85), (f, -r * 0.85), (r * 0.85, f), (-r * 0.85, f)):
                roof.append(box((0.025, 0.025, 0.025), (px, y - 0.01, pz)))
        y += 0.15
    # Spire with rings.
    roof.append(rod((0, y, 0), (0, y + 0.4, 0), 0.025))
    roof += [torus((0, y + 0.06 + 0.055 * i, 0), 0.05, 0.013, 16) for i in range(6)]
    roof.append(sphere((0, y + 0.42, 0), 0.04))
    return {"body": body, "roof": roof}


def tower(radius: float = 0.4, height: float = 1.0, merlons: int = 16, seed: int = 3) -> dict:
    """Round castle tower: battered base, string courses, arrow-slit windows, machicolations, crenellations,
    and a conical roof with a finial."""
    body, roof = [], []
    r, h = radius, height
    body.append(lathe([(r * 1.15, 0), (r, h * 0.15), (r, h)]))
    body += [torus((0, h * f, 0), r * 1.0, 0.018) for f in (0.15, 0.45, 0.75)]
    # Masonry courses: thin rings every few centimetres, staggered vertical joints between them.
    body += [torus((0, h * 0.15 + 0.05 * i, 0), r * 0.995, 0.008, 32) for i in range(int(h * 0.85 / 0.05))]
    body += [torus((0, 0.03 + 0.045 * i, 0), r * 1.15 - 0.15 * r * (0.03 + 0.045 * i) / (h * 0.15), 0.009, 32)
             for i in range(int(h * 0.15 / 0.045))]
    # Arrow slits: protruding frames around narrow slits.
    for k, yf in enumerate((0.3, 0.5, 0.7)):
        for a in range(4):
            ang = math.radians(45 * (a * 2 + k))
            cx, cz = r * math.cos(ang), r * math.sin(ang)
            d = np.array([math.cos(ang), 0, math.sin(ang)])
            side = np.array([-math.sin(ang), 0, math.cos(ang)])
            for sgn in (-1, 1):
                body.append(_slab((cx + side[0] * 0.035 * sgn + d[0] * 0.01, h * yf,
                                   cz + side[2] * 0.035 * sgn + d[2] * 0.01), [0, 1, 0], side, 0.18, 0.025, 0.04))
            body.append(_slab((cx + d[0] * 0.01, h * yf + 0.1, cz + d[2] * 0.01), [0, 1, 0], side, 0.03, 0.1, 0.05))
    # Buttresses: thin radial fins stepping in towards the top.
    for i in range(8):
        a = math.radians(22.5 + 45 * i)
        c, s_ = math.cos(a), math.sin(a)
        body.append(hull(np.array([[rr * c + e * -s_ * 0.02, y, rr * s_ + e * c * 0.02] for e in (-1, 1)
                                   for rr, y in ((r * 0.9, 0), (r * 1.35, 0), (r * 1.05, h * 0.4), (r * 0.9, h * 0.45))])))
    # Door.
    body.append(_slab((0, 0.16, r * 1.1), [0, 1, 0], [1, 0, 0], 0.3, 0.2, 0.04))
    body += [_slab((s * 0.11, 0.17, r * 1.1), [0, 1, 0], [1, 0, 0], 0.34, 0.03, 0.07) for s in (-1, 1)]
    # Corbels and a projecting parapet with crenellations.
    body += ring_of(merlons * 2, r * 1.02, lambda x, z, a: box((0.04, 0.08, 0.04), (x, h + 0.0, z), -a))
    body.append(lathe([(r * 1.1, h + 0.04), (r * 1.1, h + 0.1)]))
    body += ring_of(merlons, r * 1.05, lambda x, z, a: box((0.08, 0.12, 0.06), (x, h + 0.16, z), -a))
    # Conical roof rising from inside the parapet, with a band and a finial.
    roof.append(lathe([(r * 0.92, h + 0.05), (r * 0.88, h + 0.1), (0.02, h + 0.75)]))
    roof += [torus((0, h + 0.1 + 0.055 * i, 0), (r * 0.88 - 0.02) * (1 - 0.0846 * i) + 0.012, 0.012, 32)
             for i in range(11)]
    roof.append(rod((0, h + 0.7, 0), (0, h + 0.9, 0), 0.015))
    roof.append(sphere((0, h + 0.9, 0), 0.03))
    return {"body": body, "roof": roof}


def townhouse(width: float = 1.0, depth: float = 0.6, floors: int = 3, bays: int = 3, seed: int = 4) -> dict:
    """Townhouse: rusticated ground floor, window grid with sills and lintels, string courses, a dentil cornice,
    door with steps, and a mansard roof with dormers."""
    body, roof = [], []
    w, d = width, depth
    fh = 0.32
    h = fh * floors + 0.1
    body.append(box((w, h, d), (0, h / 2, 0)))
    # Rustication on the ground floor: horizontal bands.
    for i in range(5):
        body.append(box((w + 0.02, 0.035, d + 0.02), (0, 0.03 + i * 0.07, 0)))
    for f in range(floors):
        y = 0.1 + fh * f + fh * 0.5
        body.append(box((w + 0.03, 0.025, d + 0.03), (0, 0.1 + fh * f, 0)))  # string course
        for b in range(bays):
            x = -w / 2 + w * (b + 0.5) / bays
            if f == 0 and b == bays // 2:
                continue
            body += _window(x, y, d / 2, 0.16, 0.22 if f else 0.18, "z", mullions=(2, 3))
            if f == 1:  # balconettes
                body.append(box((0.22, 0.02, 0.07), (x, y - 0.15, d / 2 + 0.035)))
                body += [rod((x + 0.1 * k / 2, y - 0.15, d / 2 + 0.06), (x + 0.1 * k / 2, y - 0.06, d / 2 + 0.06),
                             0.007, 6) for k in range(-2, 3)]
        body += _window(w / 2, y, 0, 0.16, 0.2, "x", mullions=(2, 2))
        body += _window(-w / 2, y, 0, 0.16, 0.2, "x", mullions=(2, 2))
    # Pilasters between the bays and quoins at the corners.
    for b in range(bays + 1):
        x = -w / 2 + w * b / bays
        x = float(np.clip(x, -w / 2 + 0.025, w / 2 - 0.025))
        body.append(box((0.05, h - 0.1, 0.025), (x, 0.1 + (h - 0.1) / 2, d / 2 + 0.012)))
        body.append(box((0.07, 0.03, 0.04), (x, h - 0.05, d / 2 + 0.02)))
    for sx in (-1, 1):
        for sz in (-1, 1):
            for i in range(int(h / 0.08)):
                body.append(box((0.06 if i % 2 else 0.035, 0.05, 0.035 if i % 2 else 0.06),
                                (sx * (w / 2 - 0.01), 0.04 + 0.08 * i, sz * (d / 2 - 0.01))))
    # Iron railings along the front area, with spear-head finials.
    for s in (-1, 1):
        x0, x1 = s * 0.2, s * (w / 2)
        body.append(bar((x0, 0.2, d / 2 + 0.12), (x1, 0.2, d / 2 + 0.12), 0.012, 0.012))
        for i in range(9):
            x = x0 + (x1 - x0) * i / 8
            body.append(rod((x, 0, d / 2 + 0.12), (x, 0.22, d / 2 + 0.12), 0.006, 6))
            body.append(sphere((x, 0.23, d / 2 + 0.12), 0.011, (1, 1.6, 1), subdivisions=1))
    # Door with pediment and steps.
    body.append(box((0.18, 0.3, 0.03), (0, 0.1 + 0.15, d / 2)))
    body += [box((0.03, 0.32, 0.05), (s * 0.11, 0.1 + 0.16, d / 2)) for s in (-1, 1)]
    body.append(hull(np.array([[s * 0.16, 0.42, d / 2 + e] for s in (-1, 1) for e in (0, 0.05)]
                              + [[0, 0.5, d / 2 + e] for e in (0, 0.05)])))
    body += [box((0.3, 0.035, 0.05 + 0.05 * i), (0, 0.1 - 0.035 * (i + 0.5), d / 2 + 0.025 * (i + 1)))
             for i in range(2)]
    # Cornice: stepped mouldings with dentils.
    body.append(box((w + 0.06, 0.03, d + 0.06), (0, h - 0.015, 0)))
    body.append(box((w + 0.12, 0.03, d + 0.12), (0, h + 0.04, 0)))
    for i in range(16):
        x = -w / 2 + w * (i + 0.5) / 16
        body.append(box((0.025, 0.03, 0.03), (x, h + 0.012, d / 2 + 0.04)))
    for i in range(10):
        z = -d / 2 + d * (i + 0.5) / 10
        body += [box((0.03, 0.03, 0.025), (s * (w / 2 + 0.04), h + 0.012, z)) for s in (-1, 1)]
    # Mansard roof with dormers and two chimneys.
    y0 = h + 0.055
    roof.append(hull(np.array([[sx * w / 2, y0, sz * d / 2] for sx in (-1, 1) for sz in (-1, 1)]
                              + [[sx * (w / 2 - 0.08), y0 + 0.22, sz * (d / 2 - 0.08)] for sx in (-1, 1) for sz in (-1, 1)])))
    for b in range(bays):
        x = -w / 2 + w * (b + 0.5) / bays
        roof.append(box((0.14, 0.16, 0.1), (x, y0 + 0.1, d / 2 - 0.05)))
        roof.append(hull(np.array([[x + s * 0.1, y0 + 0.18, d / 2 - 0.1 + e] for s in (-1, 1) for e in (0, 0.14)]
                                  + [[x, y0 + 0.26, d / 2 - 0.1 + e] for e in (0, 0.14)])))
        roof += _window(x, y0 + 0.1, d / 2 + 0.0, 0.08, 0.1, "z", t=0.015, mullions=(1, 2), sill=False)
    for s in (-1, 1):
        roof.append(box((0.1, 0.22, 0.16), (s * (w / 2 - 0.12), y0 + 0.3, 0)))
        roof += [rod((s * (w / 2 - 0.12), y0 + 0.4, zz), (s * (w / 2 - 0.12), y0 + 0.46, zz), 0.02) for zz in (-0.04, 0.04)]
    return {"body": body, "roof": roof}


def temple(cols_x: int = 6, cols_z: int = 4, seed: int = 5) -> dict:
    """Classical temple: stepped stylobate, fluted columns with capitals and bases, a cella wall, entablature
    with triglyphs, and a tiled hip roof."""
    body, roof = [], []
    sp = 0.24
    W, D = sp * (cols_x - 1), sp * (cols_z - 1)
    for i in range(3):
        e = 0.12 - 0.04 * i
        body.append(box((W + 0.3 + 2 * e, 0.05, D + 0.3 + 2 * e), (0, 0.025 + 0.05 * i, 0)))
    y0, ch = 0.15, 0.62
    body.append(box((W - 0.2, ch, D - 0.2), (0, y0 + ch / 2, 0)))  # cella
    body.append(box((0.18, 0.36, 0.03), (0, y0 + 0.18, D / 2 - 0.1)))  # door
    pos = [(-W / 2 + sp * i, s * D / 2) for i in range(cols_x) for s in (-1, 1)]
    pos += [(s * W / 2, -D / 2 + sp * j) for j in range(1, cols_z - 1) for s in (-1, 1)]
    for x, z in pos:
        body.append(_square_lathe([(0.05, y0), (0.05, y0 + 0.03)], (x, 0, z)))
        body.append(lathe([(0.045, y0 + 0.02), (0.04, y0 + 0.04), (0.036, y0 + ch - 0.05), (0.045, y0 + ch - 0.03),
                           (0.045, y0 + ch - 0.02)], (x, 0, z), sections=16))
        body += ring_of(8, 0.036, lambda fx, fz, a, x=x, z=z: rod((x + fx, y0 + 0.05, z + fz),
                                                                    (x + fx, y0 + ch - 0.07, z + fz), 0.008, 6))
        body.append(box((0.11, 0.025, 0.11), (x, y0 + ch - 0.0125, z)))  # abacus
    # Entablature: architrave, frieze with triglyphs, cornice.
    ye = y0 + ch
    roof.append(box((W + 0.12, 0.05, D + 0.12), (0, ye + 0.025, 0)))
    roof.append(box((W + 0.1, 0.05, D + 0.1), (0, ye + 0.075, 0)))
    for i in range(cols_x * 2 - 1):
        x = -W / 2 + sp / 2 * i
        roof += [box((0.04, 0.045, 0.02), (x, ye + 0.075, s * (D / 2 + 0.055))) for s in (-1, 1)]
    roof.append(box((W + 0.18, 0.03, D + 0.18), (0, ye + 0.115, 0)))
    # Hip roof with tile ridges (rows of round tiles down each slope).
    yr = ye + 0.13
    hw, hd, rise = W / 2 + 0.1, D / 2 + 0.1, 0.25
    roof.append(hull(np.array([[sx * hw, yr, sz * hd] for sx in (-1, 1) for sz in (-1, 1)]
                              + [[sx * (hw - hd), yr + rise, 0] for sx in (-1, 1)])))
    n = 14
    for i in range(n):
        x = -hw + 2 * hw * (i + 0.5) / n
        for s in (-1, 1):
            x_top = float(np.clip(x, -(hw - hd), hw - hd))
            roof.append(rod((x, yr + 0.01, s * hd), (x_top, yr + rise + 0.005, s * 0.0 + s * 0.01), 0.013, 6))
    for j in range(6):
        z = -hd + 2 * hd * (j + 0.5) / 6
        for s in (-1, 1):
            roof.append(rod((s * hw, yr + 0.01, z), (s * (hw - hd + abs(z)), yr + rise * (1 - abs(z) / hd), z), 0.013, 6))
    for sx in (-1, 1):
        for sz in (-1, 1):
            roof.append(rod((sx * hw, yr, sz * hd), (sx * (hw - hd), yr + rise, 0), 0.02, 8))
    roof.append(rod((-(hw - hd), yr + rise, 0), (hw - hd, yr + rise, 0), 0.025, 8))
    # Acroteria.
    roof += [sphere((sx * (hw - hd), yr + rise + 0.04, 0), 0.04) for sx in (-1, 1)]
    return {"body": body, "roof": roof}


def barn(width: float = 1.2, depth: float = 0.8, wall_h: float = 0.5, seed: int = 6) -> dict:
    """Barn: board-and-batten walls (vertical battens), X-braced double doors, a hayloft door and a gambrel roof
    with a ridge cupola."""
    body, roof = [], []
    w, d, h = width, depth, wall_h
    body.append(box((w, h, d), (0, h / 2, 0)))
    for i in range(30):
        x = -w / 2 + w * (i + 0.5) / 30
        body += [box((0.016, h, 0.02), (x, h / 2, s * (d / 2 + 0.007))) for s in (-1, 1)]
    for i in range(20):
        z = -d / 2 + d * (i + 0.5) / 20
        body += [box((0.02, h, 0.016), (s * (w / 2 + 0.007), h / 2, z)) for s in (-1, 1)]
    # Double doors with X bracing and frame.
    dz = d / 2 + 0.025
    for s in (-1, 1):
        cx = s * 0.11
        body.append(box((0.2, 0.38, 0.02), (cx, 0.19, dz)))
        body += [box((0.2, 0.025, 0.03), (cx, y, dz + 0.01)) for y in (0.02, 0.19, 0.36)]
        body += [box((0.025, 0.38, 0.03), (cx + e * 0.09, 0.19, dz + 0.01)) for e in (-1, 1)]
        body.append(bar((cx - 0.085, 0.03, dz + 0.02), (cx + 0.085, 0.35, dz + 0.02), 0.025, 0.02))
        body.append(bar((cx + 0.085, 0.03, dz + 0.02), (cx - 0.085, 0.35, dz + 0.02), 0.025, 0.02))
    for s in (-1, 1):
        for zc in (-0.2, 0.2):
            body += _window(s * (w / 2 + 0.02), h * 0.55, zc, 0.14, 0.14, "x", t=0.02, mullions=(2, 2))
    body += [box((w + 0.04, 0.03, d + 0.04), (0, y, 0)) for y in (0.015, h - 0.015)]
    # Porch roof on posts over the doors.
    body += [rod((s * 0.3, 0, d / 2 + 0.22), (s * 0.3, h * 0.9, d / 2 + 0.22), 0.014, 8) for s in (-1, 1)]
    body += [bar((s * 0.3, h * 0.7, d / 2 + 0.22), (s * 0.3, h * 0.88, d / 2 + 0.02), 0.02, 0.02) for s in (-1, 1)]
    roof.append(hull(np.array([[s * 0.36, h * 0.92 + e, d / 2 + z] for s in (-1, 1) for e in (0, 0.02)
                               for z in (0.0, 0.27)]) + np.array([0, 0, 0])))
    # Gambrel roof: a lower steep and an upper shallow slope.
    over = 0.05
    hd = d / 2 + over
    prof = [(-hd, h - 0.02), (-hd * 0.62, h + 0.3), (0, h + 0.45), (hd * 0.62, h + 0.3), (hd, h - 0.02)]
    pts = [[sx * (w / 2 + over), y, z] for sx in (-1, 1) for z, y in prof]
    roof.append(hull(np.array(pts)))
    # Gable wall (body part) under the roof, with the hayloft door and a round vent.
    gable = [[sx * (w / 2 - 0.02), y - 0.03, z * 0.9] for sx in (-1, 1) for z, y in prof]
    body.append(hull(np.array(gable)))
    body.append(box((0.16, 0.18, 0.03), (0, h + 0.15, d / 2 + 0.01)))
    body += [box((0.2, 0.025, 0.04), (0, h + 0.15 + e * 0.09, d / 2 + 0.015)) for e in (-1, 1)]
    body.append(bar((-0.07, h + 0.07, d / 2 + 0.03), (0.07, h + 0.23, d / 2 + 0.03), 0.02, 0.02))
    # Standing-seam ribs on the roof: rods following the gambrel profile.
    for i in range(22):
        x = -w / 2 - over + (w + 2 * over) * (i + 0.5) / 22
        for (z0, y0), (z1, y1) in zip(prof[:-1], prof[1:]):
            roof.append(rod((x, y0 + 0.016, z0), (x, y1 + 0.016, z1), 0.013, 6))
    # Cupola on the ridge.
    roof.append(box((0.16, 0.14, 0.16), (0, h + 0.5, 0)))
    for s in (-1, 1):
        roof += [box((0.015, 0.1, 0.01), (x, h + 0.5, s * 0.085)) for x in (-0.04, 0, 0.04)]
    roof.append(_square_lathe([(0.12, 0), (0.0, 0.12)], (0, h + 0.57, 0)))
    roof.append(rod((0, h + 0.65, 0), (0, h + 0.8, 0), 0.01))
    roof.append(bar((-0.06, h + 0.76, 0), (0.06, h + 0.76, 0), 0.012, 0.012))
    return {"body": body, "roof": roof}


# --------------------------------------------------------------------------- plants


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
                leaf.append(_leaf(p, dirn, size, size * 0.28, 0.008))
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
        leaf.append(_leaf(p - out / np.linalg.norm(out) * 0.02, out, 0.1, 0.06, 0.01, curl=0.15))
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
        d, s, n = _frame(np.asarray(p1) - np.asarray(p0))
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
    leaf += ring_of(8, 0.03, lambda x, z, a: _leaf(top + [0, r * 0.9, 0], [x, 0.5 * 0.03, z], 0.07, 0.035, 0.008))
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
                leaf.append(_leaf(q + v / np.linalg.norm(v) * 0.07 * rng.uniform(0.3, 1), v + [0, 0.6, 0], 0.07,
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
            dd, s, n = _frame(d)
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
            leaf.append(_leaf(p, [math.cos(b), 0.5, math.sin(b)], 0.12, 0.045, 0.008, curl=0.2))
        d = top - mid
        d /= np.linalg.norm(d)
        _, s, n = _frame(d)
        for i in range(12):
            ang = 2 * math.pi * i / 12
            pd = s * math.cos(ang) + n * math.sin(ang) + d * 0.15
            leaf.append(_leaf(top, pd, 0.085, 0.032, 0.01))
            leaf.append(_leaf(top - d * 0.01, pd * 0.8 + d * 0.5, 0.06, 0.025, 0.01))
        leaf.append(sphere(top + d * 0.01, 0.03, (1, 0.7, 1)))
    # Basal clump of long strap leaves arching out of the pot.
    for i in range(14):
        a = 2 * math.pi * i / 14 + rng.uniform(-0.2, 0.2)
        p0 = np.array([0.06 * math.cos(a), 0.28, 0.06 * math.sin(a)])
        p1 = p0 + np.array([0.12 * math.cos(a), 0.2, 0.12 * math.sin(a)])
        leaf.append(_leaf(p0, p1 - p0, 0.24, 0.05, 0.01, curl=0.15))
        leaf.append(_leaf(p1, [math.cos(a), -0.2, math.sin(a)], 0.14, 0.045, 0.01, curl=0.15))
    return {"pot": pot, "leaf": leaf}


# --------------------------------------------------------------------------- cakes


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
        top.append(_leaf((x + 0.03, 0.57, z + 0.02), [1, 0.3, 0.2], 0.05, 0.025, 0.006))
    for m in bottom + top:
        m.apply_translation([0, 0.32, 0])
    bottom += _stand(r + 0.12, 0.32)
    return {"bottom": bottom, "top": top}


# --------------------------------------------------------------------------- crystals


def _crystal(base, direction, length: float, radius: float, rng, sides: int = 6, point: float = 1.6,
             double: bool = False):
    """Faceted crystal: a jittered ``sides``-gon prism with a pointed termination (both ends if ``double``)."""
    d, s, n = _frame(direction)
    b = np.asarray(base, float)
    pts = []
    phase = rng.uniform(0, 2 * math.pi)
    for k in range(sides):
        a = phase + 2 * math.pi * k / sides
        rr = radius * rng.uniform(0.8, 1.1)
        off = (s * math.cos(a) + n * math.sin(a)) * rr
        pts += [b + off * (1.0 if not double else 0.8) - d * (radius * point if double else 0),
                b + off + d * length * rng.uniform(0.97, 1.0)]
    pts.append(b + d * (length + radius * point) + s * rng.uniform(-0.2, 0.2) * radius)
    if double:
        pts.append(b - d * radius * point * 2)
    return hull(np.array(pts))


def _rock_base(radius: float, height: float, rocks: int, rng, flat: float = 0.5) -> list:
    """Rough base: many jittered convex rocks piled into a low dome."""
    out = [sphere((0, height * 0.3, 0), radius * 0.8, (1, height / radius * 0.8, 1), subdivisions=2)]
    for _ in range(rocks):
        a = rng.uniform(0, 2 * math.pi)
        rr = radius * math.sqrt(rng.uniform(0, 1))
        y = height * (1 - (rr / radius) ** 2) * flat + rng.uniform(0, height * 0.2)
        size = rng.uniform(0.06, 0.14) * radius
        c = np.array([rr * math.cos(a), y, rr * math.sin(a)])
        pts = c + rng.normal(size=(10, 3)) * size * np.array([1, 0.7, 1])
        out.append(hull(pts))
    return out


def crystal_cluster(count: int = 24, seed: int = 31) -> dict:
    """Quartz cluster: long hexagonal points of several sizes fanning out from the centre of a rocky base."""
    rng = np.random.default_rng(seed)
    bottom = _rock_base(0.55, 0.22, 90, rng)
    top = []
    for i in range(count):
        a = rng.uniform(0, 2 * math.pi)
        tilt = rng.uniform(0.05, 0.75) if i else 0.0
        d = np.array([math.sin(tilt) * math.cos(a), math.cos(tilt), math.sin(tilt) * math.sin(a)])
        size = rng.uniform(0.5, 1.0) * (1.3 if i == 0 else 1.0)
        base = np.array([rng.uniform(-0.2, 0.2), 0.1, rng.uniform(-0.2, 0.2)])
        top.append(_crystal(base, d, 0.55 * size, 0.07 * size, rng))
    return {"bottom": bottom, "top": top}


def druse(count: int = 150, seed: int = 32) -> dict:
    """Druse: a broad dome of rock carpeted with many small stubby crystals pointing outwards from its surface."""
    rng = np.random.default_rng(seed)
    bottom = _rock_base(0.6, 0.35, 60, rng, flat=0.9)
    top = []
    for _ in range(count):
        v = rng.normal(size=3)
        v[1] = abs(v[1]) + 0.6
        v /= np.linalg.norm(v)
        p = np.array([v[0] * 0.55, 0.05 + v[1] * 0.33, v[2] * 0.55])
        d = v + rng.normal(size=3) * 0.25
        size = rng.uniform(0.5, 1.0)
        top.append(_crystal(p, d, 0.12 * size, 0.03 * size, rng, point=1.3))
    return {"bottom": bottom, "top": top}


def quartz_point(seed: int = 33) -> dict:
    """A single big double-ringed quartz point with striations, surrounded by small satellite points,
    on a flat rough slab."""
    rng = np.random.default_rng(seed)
    bottom = _rock_base(0.5, 0.15, 70, rng, flat=0.4)
    top = [_crystal((0, 0.05, 0), (0.08, 1, 0.03), 0.75, 0.16, rng, point=1.5)]
    # Growth striations: thin horizontal bars round the big prism.
    for k in range(10):
        y = 0.12 + 0.065 * k
        top += ring_of(6, 0.155, lambda x, z, a, y=y: box((0.14, 0.012, 0.02), (x + y * 0.08, y, z + y * 0.03),
                                                          -a + 90))
    for i in range(12):
        a = 2 * math.pi * i / 12 + rng.uniform(-0.2, 0.2)
        tilt = rng.uniform(0.4, 1.0)
        d = np.array([math.sin(tilt) * math.cos(a), math.cos(tilt), math.sin(tilt) * math.sin(a)])
        p = np.array([0.22 * math.cos(a), 0.08, 0.22 * math.sin(a)])
        top.append(_crystal(p, d, rng.uniform(0.12, 0.3), rng.uniform(0.03, 0.05), rng))
    return {"bottom": bottom, "top": top}


def pyrite(count: int = 22, seed: int = 34) -> dict:
    """Pyrite / fluorite: interpenetrating cubes (some stepped, with smaller cubes growing on their faces) and a
    few double-terminated prisms on a rocky base."""
    rng = np.random.default_rng(seed)
    bottom = _rock_base(0.55, 0.2, 80, rng)
    top = []
    import trimesh

    for i in range(count):
        size = rng.uniform(0.08, 0.22)
        c = np.array([rng.uniform(-0.35, 0.35), 0.18 + rng.uniform(0, 0.15), rng.uniform(-0.35, 0.35)])
        cube = trimesh.creation.box(extents=[size] * 3)
        cube.apply_transform(trimesh.transformations.random_rotation_matrix(rng.uniform(size=3)))
        cube.apply_translation(c)
        top.append(cube)
        # Stepped growth: a smaller cube set onto one face.
        if i % 2 == 0:
            small = trimesh.creation.box(extents=[size * 0.5] * 3)
            small.apply_transform(trimesh.transformations.random_rotation_matrix(rng.uniform(size=3)))
            small.apply_translation(c + rng.normal(size=3) * size * 0.4 + [0, size * 0.4, 0])
            top.append(small)
    for _ in range(5):
        d = rng.normal(size=3) * 0.6 + [0, 1, 0]
        p = np.array([rng.uniform(-0.3, 0.3), 0.25, rng.uniform(-0.3, 0.3)])
        top.append(_crystal(p, d, 0.25, 0.04, rng, sides=4, point=2.0, double=True))
    return {"bottom": bottom, "top": top}


# --------------------------------------------------------------------------- catalogue

THINGS_CATALOGUE: dict[str, tuple[str, Callable, dict]] = {
    "cottage": ("building", cottage, {}),
    "pagoda": ("building", pagoda, {}),
    "tower": ("building", tower, {}),
    "townhouse": ("building", townhouse, {}),
    "temple": ("building", temple, {}),
    "barn": ("building", barn, {}),
    "fern": ("plant", fern, {}),
    "bush": ("plant", bush, {}),
    "cactus": ("plant", cactus, {}),
    "bonsai": ("plant", tree, {}),
    "succulent": ("plant", succulent, {}),
    "flowers": ("plant", flowers, {}),
    "birthday_cake": ("cake", birthday_cake, {}),
    "wedding_cake": ("cake", wedding_cake, {}),
    "shortcake": ("cake", shortcake, {}),
    "bundt_cake": ("cake", bundt_cake, {}),
    "crystal_cluster": ("crystal", crystal_cluster, {}),
    "druse": ("crystal", druse, {}),
    "quartz_point": ("crystal", quartz_point, {}),
    "pyrite": ("crystal", pyrite, {}),
}

"""Procedural buildings for the ``things`` style set: parts ``body`` (walls, windows, doors, columns)
and ``roof`` (roofs, tiles, eaves, chimneys). Metres, +Y up, front +Z; each about 1–2 m on its longest side.
"""

from __future__ import annotations

import math

import numpy as np

from stylesets.catalogues.prims import bar, box, hull, lathe, oriented_box, ring_of, rod, sphere, square_lathe, torus


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
                out.append(oriented_box(c0 + np.array([x, 0, 0]) + normal * (t * 0.3) * (k % 2 == 0),
                                 u, [1, 0, 0], step * 1.15, tw * 0.92, t))
    return out


def _gable_roof(w: float, d: float, y0: float, rise: float, over: float, t: float) -> list:
    """Solid gable roof (ridge along x) with overhang ``over``; a triangular gable infill under it."""
    hw, hd = w / 2 + over, d / 2 + over
    slab = hull(np.array([[sx * hw, y0 - t, sz * hd] for sx in (-1, 1) for sz in (-1, 1)]
                         + [[sx * hw, y0 + rise, 0] for sx in (-1, 1)]
                         + [[sx * hw, y0 + rise + t, 0] for sx in (-1, 1)]))
    return [slab, bar((-hw - 0.01, y0 + rise + t, 0), (hw + 0.01, y0 + rise + t, 0), t * 2.5, t * 2.5)]


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
    body.append(square_lathe([(base * 0.62, 0), (base * 0.62, 0.05), (base * 0.57, 0.05), (base * 0.57, 0.1)]))
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
        roof.append(square_lathe(prof, (0, y, 0)))
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
                body.append(oriented_box((cx + side[0] * 0.035 * sgn + d[0] * 0.01, h * yf,
                                   cz + side[2] * 0.035 * sgn + d[2] * 0.01), [0, 1, 0], side, 0.18, 0.025, 0.04))
            body.append(oriented_box((cx + d[0] * 0.01, h * yf + 0.1, cz + d[2] * 0.01), [0, 1, 0], side, 0.03, 0.1, 0.05))
    # Buttresses: thin radial fins stepping in towards the top.
    for i in range(8):
        a = math.radians(22.5 + 45 * i)
        c, s_ = math.cos(a), math.sin(a)
        body.append(hull(np.array([[rr * c + e * -s_ * 0.02, y, rr * s_ + e * c * 0.02] for e in (-1, 1)
                                   for rr, y in ((r * 0.9, 0), (r * 1.35, 0), (r * 1.05, h * 0.4), (r * 0.9, h * 0.45))])))
    # Door.
    body.append(oriented_box((0, 0.16, r * 1.1), [0, 1, 0], [1, 0, 0], 0.3, 0.2, 0.04))
    body += [oriented_box((s * 0.11, 0.17, r * 1.1), [0, 1, 0], [1, 0, 0], 0.34, 0.03, 0.07) for s in (-1, 1)]
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
        body.append(square_lathe([(0.05, y0), (0.05, y0 + 0.03)], (x, 0, z)))
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
    roof.append(square_lathe([(0.12, 0), (0.0, 0.12)], (0, h + 0.57, 0)))
    roof.append(rod((0, h + 0.65, 0), (0, h + 0.8, 0), 0.01))
    roof.append(bar((-0.06, h + 0.76, 0), (0.06, h + 0.76, 0), 0.012, 0.012))
    return {"body": body, "roof": roof}

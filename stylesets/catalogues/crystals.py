"""Procedural crystals for the ``things`` style set: parts ``bottom`` (rocky base) and ``top``
(crystals). Metres, +Y up, front +Z; each about 1–2 m on its longest side.
"""

from __future__ import annotations

import math

import numpy as np

from stylesets.catalogues.prims import box, hull, oriented_frame, ring_of, sphere


def _crystal(base, direction, length: float, radius: float, rng, sides: int = 6, point: float = 1.6,
             double: bool = False):
    """Faceted crystal: a jittered ``sides``-gon prism with a pointed termination (both ends if ``double``)."""
    d, s, n = oriented_frame(direction)
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

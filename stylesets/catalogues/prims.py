"""Small closed-mesh primitives for procedural style exemplars (metres, +Y up).

Role: the building blocks every procedural exemplar is assembled from: boxes,
rods between two points, lathe (turned) solids, convex hulls, rings of copies.
Each helper returns one closed, outward-facing ``trimesh.Trimesh``; an
exemplar part is simply a list of them (overlaps are fine: the voxelizer fills
every closed component on its own and unions them).

Plain trimesh primitives are used instead of build123d: the exemplars need
hundreds of small pieces (slats, tiles, beads, leaves) and no booleans, and
tessellating that many B-rep solids would cost minutes per set.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Iterable, Sequence

import numpy as np

if TYPE_CHECKING:
    import trimesh

#: Segments around round things: enough to look round at 256³.
ROUND = 24


def _outward(mesh: "trimesh.Trimesh") -> "trimesh.Trimesh":
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def box(size: Sequence[float], center: Sequence[float], rot_y_deg: float = 0.0) -> "trimesh.Trimesh":
    """Axis-aligned box of ``size`` (3,) metres centred at ``center``, optionally turned about +Y."""
    import trimesh

    mesh = trimesh.creation.box(extents=np.asarray(size, float))
    if rot_y_deg:
        mesh.apply_transform(trimesh.transformations.rotation_matrix(math.radians(rot_y_deg), [0, 1, 0]))
    mesh.apply_translation(np.asarray(center, float))
    return mesh


def rod(p0: Sequence[float], p1: Sequence[float], radius: float, sections: int = 12) -> "trimesh.Trimesh":
    """Round bar of ``radius`` from point ``p0`` to ``p1``."""
    import trimesh

    return _outward(trimesh.creation.cylinder(radius=radius, segment=np.array([p0, p1], float), sections=sections))


def bar(p0: Sequence[float], p1: Sequence[float], width: float, depth: float | None = None) -> "trimesh.Trimesh":
    """Square-section bar from ``p0`` to ``p1`` (a 4-sided prism, ``width`` × ``depth``)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    d = axis / length
    # A side vector perpendicular to the bar, as horizontal as possible.
    ref = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(d, ref)
    u /= np.linalg.norm(u)
    v = np.cross(d, u)
    half_w, half_d = width / 2, (depth if depth is not None else width) / 2
    corners = [s * half_w * u + t * half_d * v for s, t in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    points = np.array([p0 + c for c in corners] + [p1 + c for c in corners])
    return hull(points)


def hull(points: np.ndarray) -> "trimesh.Trimesh":
    """Convex hull of (N, 3) points: crystals, rocks, prisms, wedges."""
    import trimesh

    return _outward(trimesh.convex.convex_hull(np.asarray(points, float)))


def lathe(profile: Sequence[Sequence[float]], base: Sequence[float] = (0, 0, 0),
          sections: int = ROUND) -> "trimesh.Trimesh":
    """Turned solid about the vertical axis through ``base``.

    ``profile`` is a list of (radius, height) points in metres from bottom to
    top; it is closed onto the axis at both ends so the solid is watertight.
    """
    import trimesh

    pts = [(float(r), float(h)) for r, h in profile]
    if pts[0][0] > 0:
        pts.insert(0, (0.0, pts[0][1]))
    if pts[-1][0] > 0:
        pts.append((0.0, pts[-1][1]))
    mesh = trimesh.creation.revolve(np.array(pts), sections=sections)
    # revolve turns about +Z; -90° about X takes +Z onto +Y.
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))
    mesh.apply_translation(np.asarray(base, float))
    return _outward(mesh)


def sphere(center: Sequence[float], radius: float, scale: Sequence[float] = (1, 1, 1),
           subdivisions: int = 2) -> "trimesh.Trimesh":
    """(Ellipsoidal) ball: ``radius`` × ``scale`` per axis."""
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    mesh.apply_scale(1.0)
    mesh.vertices = mesh.vertices * np.asarray(scale, float) + np.asarray(center, float)
    return _outward(mesh)


def torus(center: Sequence[float], major: float, minor: float, sections: int = ROUND) -> "trimesh.Trimesh":
    """Horizontal ring (doughnut) of radius ``major`` and tube radius ``minor``."""
    import trimesh

    mesh = trimesh.creation.torus(major_radius=major, minor_radius=minor, major_sections=sections,
                                  minor_sections=10)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))
    mesh.apply_translation(np.asarray(center, float))
    return _outward(mesh)


def prism(polygon_xz: Sequence[Sequence[float]], y0: float, y1: float) -> "trimesh.Trimesh":
    """Vertical extrusion of a simple (possibly concave) polygon given in the XZ plane, from y0 to y1."""
    import trimesh
    from shapely.geometry import Polygon

    poly = Polygon([(float(x), float(-z)) for x, z in polygon_xz]).buffer(0)
    mesh = trimesh.creation.extrude_polygon(poly, height=y1 - y0)
    # extrude_polygon builds along +Z from the XY plane; -90° about X maps (x, y, z) → (x, z, -y).
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))
    mesh.apply_translation([0, y0, 0])
    return _outward(mesh)


def plate(polygon: Sequence[Sequence[float]], plane: str, offset: float, thickness: float) -> "trimesh.Trimesh":
    """Flat plate: a 2-D polygon in the ``plane`` ("xy" or "zy": first coordinate, then height),
    extruded by ``thickness`` across it, centred at ``offset`` along the third axis."""
    pts = np.asarray(polygon, float)
    half = thickness / 2
    if plane == "xy":
        front = np.c_[pts[:, 0], pts[:, 1], np.full(len(pts), offset + half)]
        back = np.c_[pts[:, 0], pts[:, 1], np.full(len(pts), offset - half)]
    else:
        front = np.c_[np.full(len(pts), offset + half), pts[:, 1], pts[:, 0]]
        back = np.c_[np.full(len(pts), offset - half), pts[:, 1], pts[:, 0]]
    return hull(np.vstack([front, back]))


def ring_of(count: int, radius: float, make, start_deg: float = 0.0) -> list:
    """``make(x, z, angle_deg)`` called at ``count`` points evenly spaced on a horizontal circle."""
    out = []
    for i in range(count):
        a = start_deg + 360.0 * i / count
        x, z = radius * math.cos(math.radians(a)), radius * math.sin(math.radians(a))
        out.append(make(x, z, a))
    return out


def flatten(items: Iterable) -> list:
    """Nested lists of meshes → one flat list."""
    out: list = []
    for item in items:
        if isinstance(item, (list, tuple)):
            out.extend(flatten(item))
        else:
            out.append(item)
    return out


def merge(meshes: Iterable["trimesh.Trimesh"]) -> "trimesh.Trimesh":
    """Concatenate closed meshes into one mesh (components stay separate)."""
    import trimesh

    meshes = flatten(meshes)
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    vertices = np.concatenate([np.asarray(m.vertices, float) for m in meshes])
    faces = np.concatenate([np.asarray(m.faces, np.int64) + o for m, o in zip(meshes, offsets)])
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)


# --------------------------------------------------------------------------- oriented pieces


def oriented_frame(direction) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal (d, side, normal) frame with d along ``direction``."""
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    ref = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    s = np.cross(d, ref)
    s /= np.linalg.norm(s)
    n = np.cross(s, d)
    return d, s, n


def oriented_box(center, u, v, su: float, sv: float, sn: float):
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


def lens_leaf(base, direction, length: float, width: float, thick: float, curl: float = 0.0):
    """Lens-shaped leaf (convex hull) from ``base`` along ``direction``; ``curl`` lifts its edges (cupped)."""
    d, s, n = oriented_frame(direction)
    b = np.asarray(base, float)
    pts = []
    for i in range(9):
        t = i / 8
        w = width / 2 * math.sin(math.pi * t) ** 0.8
        for side in (-1, 1):
            p = b + d * length * t + s * side * w + n * curl * w
            pts += [p + n * thick / 2, p - n * thick / 2]
    return hull(np.array(pts))


def square_lathe(profile, base=(0, 0, 0)):
    """Square-plan turned solid: ``profile`` radii are half-widths of the square (flared roofs, plinths)."""
    import trimesh

    m = lathe([(r * math.sqrt(2), h) for r, h in profile], base=(0, 0, 0), sections=4)
    m.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 4, [0, 1, 0]))
    m.apply_translation(np.asarray(base, float))
    return m

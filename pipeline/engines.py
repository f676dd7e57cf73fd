"""Engine export profiles: LOD chains, collision meshes, node names and axes per game engine.

What each profile writes (``<name>`` is the asset name):

| profile | GLB nodes | separate GLB files | OBJ/STL/PLY frame |
|---|---|---|---|
| generic | ``<name>`` | ``<name>_LOD<n>.glb`` (n ≥ 1), ``<name>_collision.glb`` | glTF: +Y up, metres |
| unity   | ``<name>_LOD0`` … ``<name>_LOD<n>``, ``<name>_collider`` | — | glTF: +Y up, metres |
| unreal  | ``<name>_LOD0`` … ``<name>_LOD<n>``, ``UCX_<name>_00`` … (convex pieces) | — | Z up, centimetres |
| godot   | ``<name>``, ``<name>-colonly`` | ``<name>_LOD<n>.glb`` | glTF: +Y up, metres |

GLB files always follow glTF (+Y up, metres, front +Z); every importer converts
from there, so only the other formats take Unreal's Z-up centimetres
(``(x, y, z) → 100·(x, −z, y)``: +Y up becomes +Z up, the front +Z becomes −Y).
Unity and Unreal pick LOD levels up from the ``_LOD<n>`` suffix; Godot builds
its own LODs on import and would show extra LOD nodes, so its LODs (like the
generic profile's) go to separate files. Unreal takes ``UCX_`` nodes as convex
collision; Godot turns a ``-colonly`` node into a static collision shape.

LODs are decimations of LOD0 (the asset's mesh after ``max_triangles``), given
as ratios of its triangle count (``[1.0, 0.5, 0.25]``) or as triangle counts
(``[20000, 5000, 1000]``); the first entry is LOD0 itself. Collision is the
convex hull of LOD0 (``hull``) or boxes merged from the coarse grid's occupied
cells (``boxes``; each box is a convex piece).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core.errors import MeshingError
from core.grid import LabeledGrid
from core.recipe import CollisionKind, EngineProfile
from pipeline.simplify import decimate_kept

if TYPE_CHECKING:
    import trimesh


#: Most boxes a ``boxes`` collision may have (engines slow down with many convex pieces).
MAX_COLLISION_BOXES = 64

#: Unreal's frame for non-glTF formats: Z up, centimetres, right-handed rotation of +Y up onto +Z.
UNREAL_FROM_GLTF = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]) * 100.0


@dataclass(frozen=True)
class Layout:
    """Which meshes go into which file under which node name."""

    main_nodes: list[tuple[str, "trimesh.Trimesh"]]
    extra_files: list[tuple[str, list[tuple[str, "trimesh.Trimesh"]]]]  # (file stem, nodes)


def lod_targets(lods: list[float] | list[int], lod0_triangles: int) -> list[int]:
    """Triangle counts of LOD1..n from the recipe's ``lods`` (ratios or counts; entry 0 is LOD0)."""
    targets = []
    for value in lods[1:]:
        count = int(round(value * lod0_triangles)) if isinstance(value, float) else int(value)
        targets.append(max(4, min(count, lod0_triangles)))
    return targets


def make_lods(lod0: "trimesh.Trimesh", lods: list | None) -> list["trimesh.Trimesh"]:
    """LOD1..n as decimations of ``lod0`` (metres), coloured like it (a LOD keeps a subset of LOD0's
    vertices and their colours). Empty without ``lods``."""
    import trimesh

    if not lods or len(lods) < 2:
        return []
    colours = np.asarray(lod0.visual.vertex_colors) if getattr(lod0.visual, "kind", None) == "vertex" else None
    out = []
    for target in lod_targets(lods, len(lod0.faces)):
        if target >= len(lod0.faces):
            mesh = lod0.copy()
        else:
            kept, faces = decimate_kept(np.asarray(lod0.vertices), np.asarray(lod0.faces), target)
            mesh = trimesh.Trimesh(np.asarray(lod0.vertices)[kept], faces,
                                   vertex_colors=colours[kept] if colours is not None else None,
                                   process=False, validate=False)
        out.append(mesh)
    return out


def _merge_boxes(occupied: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Greedy cover of occupied cells by disjoint boxes: list of (lo, hi) cell index corners, hi exclusive."""
    free = occupied.copy()
    boxes = []
    for start in zip(*np.nonzero(free)):
        if not free[start]:
            continue
        lo = np.array(start)
        hi = lo + 1
        for axis in range(3):  # grow along x, then y, then z while the whole face is free
            while hi[axis] < free.shape[axis]:
                face = [slice(lo[a], hi[a]) for a in range(3)]
                face[axis] = slice(hi[axis], hi[axis] + 1)
                if not free[tuple(face)].all():
                    break
                hi[axis] += 1
        free[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = False
        boxes.append((lo, hi))
    return boxes


def make_collision(kind: CollisionKind, lod0: "trimesh.Trimesh", grid: "LabeledGrid") -> list["trimesh.Trimesh"]:
    """Collision pieces in metres (same frame as ``lod0``), without colours."""
    import trimesh

    if kind == CollisionKind.NONE:
        return []
    if kind == CollisionKind.HULL:
        hull = lod0.convex_hull
        return [trimesh.Trimesh(hull.vertices, hull.faces, process=True)]
    boxes = _merge_boxes(grid.occupancy)
    if len(boxes) > MAX_COLLISION_BOXES:
        raise MeshingError(f"collision 'boxes' needs {len(boxes)} boxes, more than {MAX_COLLISION_BOXES}",
                           field="export.collision", hint="use collision: hull")
    origin, voxel = np.asarray(grid.origin_m), grid.voxel_size_m
    pieces = []
    for lo, hi in boxes:
        lo_m, hi_m = origin + lo * voxel, origin + hi * voxel
        box = trimesh.creation.box(extents=hi_m - lo_m)
        box.apply_translation((lo_m + hi_m) / 2)
        pieces.append(box)
    return pieces


def layout(profile: EngineProfile, name: str, lod0, lods: list, collision: list) -> Layout:
    """Node names and files for one asset under an engine profile (see the module table)."""
    if profile in (EngineProfile.UNITY, EngineProfile.UNREAL):
        nodes = [(f"{name}_LOD{n}", mesh) for n, mesh in enumerate([lod0, *lods])] if lods else [(name, lod0)]
        if profile == EngineProfile.UNITY:
            nodes += [(f"{name}_collider" + (f"_{i:02d}" if len(collision) > 1 else ""), c)
                      for i, c in enumerate(collision)]
        else:
            nodes += [(f"UCX_{name}_{i:02d}", c) for i, c in enumerate(collision)]
        return Layout(nodes, [])
    extra = [(f"{name}_LOD{n}", [(f"{name}_LOD{n}", mesh)]) for n, mesh in enumerate(lods, start=1)]
    if profile == EngineProfile.GODOT:
        nodes = [(name, lod0)] + [(f"{name}-colonly" + (f"{i:02d}" if len(collision) > 1 else ""), c)
                                  for i, c in enumerate(collision)]
        return Layout(nodes, extra)
    if collision:
        extra.append((f"{name}_collision", [(f"{name}_collision_{i:02d}", c) for i, c in enumerate(collision)]))
    return Layout([(name, lod0)], extra)


def other_format_transform(profile: EngineProfile) -> np.ndarray | None:
    """(3, 3) linear map applied to OBJ/STL/PLY vertices for this profile, or None (glTF frame)."""
    return UNREAL_FROM_GLTF if profile == EngineProfile.UNREAL else None

"""Input frames → the canonical frame (+Y up, front +Z, metres), shared by all sources.

Every source states which axis of its input points up (``UpAxis``); this module
gives the one proper rotation (det +1, never a mirror) that takes it onto +Y.

The mappings, written as where an input point ``(x, y, z)`` lands:

====  ===================  =====================================================
up    (x, y, z) →          why
====  ===================  =====================================================
y     (x, y, z)            already canonical
z     (x, z, -y)           CAD convention: Z up, the front view looks from -Y,
                           so the front faces -Y; -Y → +Z (front), +Z → +Y (up).
                           (The same rotation Blender/glTF exporters use.)
-z    (x, -z, y)           -90° about X: -Z → +Y, +Y → +Z
-y    (x, -y, -z)          180° about X
x     (-y, x, z)           +90° about Z: +X → +Y
-x    (y, -x, z)           -90° about Z: -X → +Y
====  ===================  =====================================================
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from core.errors import SourceError
from core.recipe import UpAxis

if TYPE_CHECKING:  # trimesh is imported lazily
    import trimesh

# Rows are the output axes expressed in input coordinates: canonical = R @ input.
_ROTATIONS: dict[str, tuple[tuple[int, int, int], ...]] = {
    "y": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "z": ((1, 0, 0), (0, 0, 1), (0, -1, 0)),
    "-z": ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
    "-y": ((1, 0, 0), (0, -1, 0), (0, 0, -1)),
    "x": ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
    "-x": ((0, 1, 0), (-1, 0, 0), (0, 0, 1)),
}


def up_axis_rotation(up: UpAxis | str) -> np.ndarray:
    """(3, 3) float64 rotation (det +1) mapping the input's up axis onto +Y.

    Apply as ``canonical = R @ p`` for a column vector, or ``points @ R.T`` for
    (N, 3) rows. See the module docstring for each axis.
    """
    key = up.value if isinstance(up, UpAxis) else UpAxis(up).value
    return np.array(_ROTATIONS[key], dtype=np.float64)


def transform_points(points: np.ndarray, up: UpAxis | str, scale: float) -> np.ndarray:
    """(N, 3) input points → (N, 3) canonical points: scaled by ``scale`` first, then rotated."""
    pts = np.asarray(points, dtype=np.float64)
    return (pts * float(scale)) @ up_axis_rotation(up).T


def transform_mesh(mesh: "trimesh.Trimesh", up: UpAxis | str, scale: float) -> "trimesh.Trimesh":
    """A new mesh in the canonical frame: vertices scaled by ``scale`` (e.g. units → metres), then rotated.

    The input mesh is not modified. Faces keep their winding (the rotation is
    proper and ``scale`` must be positive), so outward normals stay outward.
    """
    if not scale > 0:
        raise ValueError(f"scale must be positive, got {scale}")
    out = mesh.copy()
    out.apply_transform(_homogeneous(up_axis_rotation(up) * float(scale)))
    return out


_DEGENERATE_HINT = "check the source's units and scale, and its coordinates in a mesh viewer"

#: Smallest and largest extent (longest side, metres) a part may have in the canonical frame; outside
#: this range the part is degenerate (it collapses to a point, or float32 outputs lose it).
EXTENT_RANGE_M: tuple[float, float] = (1e-6, 1e6)


def check_part_geometry(mesh: "trimesh.Trimesh", name: str, field: str) -> None:
    """Refuse a part that is degenerate after its transforms (units, scale, up axis).

    Degenerate: a coordinate that is not finite, a longest side outside ``EXTENT_RANGE_M``
    (metres), or every face collapsed (no triangle with an area above 1e-12 of the
    longest side squared). Raises ``SourceError`` at ``field`` naming the part.
    """
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    extent = check_extent(vertices, 1.0, name, field)
    with np.errstate(all="ignore"):
        corners = vertices[np.asarray(mesh.faces, dtype=np.int64)]
        areas = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    if not np.any(areas > 2e-12 * extent * extent):
        raise SourceError(f"every face of part '{name}' has collapsed (zero area) once scaled to metres",
                          field=field, hint=_DEGENERATE_HINT)


def check_extent(vertices: np.ndarray, scale: float, name: str, field: str) -> float:
    """The longest side (metres) of (N, 3) ``vertices`` × ``scale``; SourceError when not finite or out of range.

    Cheap enough to run on a file's raw coordinates before any cleaning (which itself
    misbehaves on coordinates like 1e30).
    """
    with np.errstate(all="ignore"):
        points = np.asarray(vertices, dtype=np.float64) * float(scale)
        if points.size == 0 or not np.all(np.isfinite(points)):
            raise SourceError(f"part '{name}' has coordinates that are not finite once scaled to metres",
                              field=field, hint=_DEGENERATE_HINT)
        extent = float((points.max(axis=0) - points.min(axis=0)).max())
    low, high = EXTENT_RANGE_M
    if not low <= extent <= high:
        what = "too small: it collapses to a point" if extent < low else "too large"
        raise SourceError(f"part '{name}' is {extent:.3g} m across once scaled to metres, {what} "
                          f"(parts must be {low:g} m to {high:g} m across)", field=field, hint=_DEGENERATE_HINT)
    return extent


#: Alias under the name used in the architecture notes.
to_canonical = transform_mesh


def _homogeneous(linear: np.ndarray) -> np.ndarray:
    """(3, 3) linear map → (4, 4) homogeneous matrix."""
    m = np.eye(4)
    m[:3, :3] = linear
    return m

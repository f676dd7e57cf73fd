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


#: Alias under the name used in the architecture notes.
to_canonical = transform_mesh


def _homogeneous(linear: np.ndarray) -> np.ndarray:
    """(3, 3) linear map → (4, 4) homogeneous matrix."""
    m = np.eye(4)
    m[:3, :3] = linear
    return m

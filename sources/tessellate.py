"""Tessellation shared by the CAD sources: build123d shapes → repaired part meshes in metres, +Y up.

Each shape is tessellated (chord tolerance ``spec.tolerance`` in source units,
default ``DEFAULT_RELATIVE_TOLERANCE`` of the part's bounding-box diagonal;
angular tolerance ``ANGULAR_TOLERANCE_RAD``), repaired with trimesh's
``validate=True`` (OCCT leaves degenerate triangles at sphere poles and cone
apexes), scaled to metres and rotated from ``spec.up_axis`` onto +Y by
``sources/frames.py``. Used by ``sources/cad.py`` (primitives) and
``sources/cad_script.py`` (users' scripts, whose cadquery meshes arrive as
vertices and faces).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from core.errors import SourceError
from core.recipe import CadSource
from sources.frames import check_part_geometry, transform_mesh

if TYPE_CHECKING:
    import trimesh

#: Default chord tolerance, as a fraction of a part's bounding-box diagonal.
DEFAULT_RELATIVE_TOLERANCE: float = 1e-3

#: Angular tolerance of the tessellation, radians (≈ 11.5°: about 32 segments per full circle at most coarse,
#: enough for a coarse voxel grid; finer settings multiply triangle counts for no visible gain).
ANGULAR_TOLERANCE_RAD: float = 0.2


def shapes_to_parts(
    named_shapes: Sequence[tuple[str, Any, str]], spec: CadSource
) -> tuple[dict[str, "trimesh.Trimesh"], list[str]]:
    """Tessellate ``(name, build123d shape, field)`` triples into canonical part meshes.

    Returns:
        (parts, warnings): name → mesh in metres, +Y up, in the given order; and
        warnings for parts that stay open after repair.
    """
    parts: dict[str, "trimesh.Trimesh"] = {}
    for name, shape, field in named_shapes:
        vertices, faces = tessellate(shape, spec.tolerance, field, name)
        parts[name] = vertices_to_part(vertices, faces, spec, name, field)
    warnings = [w for name, mesh in parts.items() for w in mesh_warnings(name, mesh)]
    return parts, warnings


def tessellate(shape: Any, tolerance: float | None, field: str, name: str) -> tuple[np.ndarray, np.ndarray]:
    """A build123d shape → ((V, 3) float64 vertices in source units, (F, 3) int64 faces).

    ``tolerance`` is the chord tolerance in source units; ``None`` means
    ``DEFAULT_RELATIVE_TOLERANCE`` × the shape's bounding-box diagonal.
    ``field`` and ``name`` locate errors.
    """
    if not shape.solids():
        raise SourceError(
            f"part '{name}' has no solid (it is a {type(shape).__name__} without volume)",
            field=field,
            hint="return or build closed solids; faces, wires and sketches cannot be voxelized",
        )
    if tolerance is None:
        tolerance = default_tolerance(float(shape.bounding_box().diagonal))
    try:
        verts, tris = shape.tessellate(float(tolerance), ANGULAR_TOLERANCE_RAD)
    except Exception as exc:  # OCCT meshing failures
        raise SourceError(f"tessellating part '{name}' failed: {type(exc).__name__}: {exc}", field=field,
                          hint="try a different 'tolerance'") from None
    vertices = np.array([(v.X, v.Y, v.Z) for v in verts], dtype=np.float64).reshape(-1, 3)
    faces = np.array(tris, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0:
        raise SourceError(f"tessellating part '{name}' produced no triangles", field=field,
                          hint="the part may be too small for the tolerance; set a smaller 'tolerance'")
    return vertices, faces


def vertices_to_part(
    vertices: np.ndarray, faces: np.ndarray, spec: CadSource, name: str, field: str
) -> "trimesh.Trimesh":
    """(V, 3) vertices / (F, 3) faces in source units → a repaired mesh in metres, +Y up."""
    import trimesh

    # validate=True merges duplicate vertices and drops the degenerate pole/apex
    # triangles OCCT emits, which is what makes spheres and cones watertight.
    mesh = trimesh.Trimesh(vertices, faces, validate=True)
    if len(mesh.faces) == 0:
        raise SourceError(f"part '{name}' has no triangles left after repair", field=field,
                          hint="the part may be degenerate (flat or tiny)")
    part = transform_mesh(mesh, spec.up_axis, spec.units.metres)
    check_part_geometry(part, name, field)
    return part


def mesh_warnings(name: str, mesh: "trimesh.Trimesh") -> list[str]:
    """Manifest notes about one part mesh (e.g. it stayed open after repair)."""
    if mesh.is_watertight:
        return []
    return [f"part '{name}' is not watertight after tessellation; voxelizing it may leave holes"]


def default_tolerance(extent_diagonal: float) -> float:
    """The default chord tolerance for a part whose bounding-box diagonal is given (source units)."""
    return max(extent_diagonal * DEFAULT_RELATIVE_TOLERANCE, 1e-9)

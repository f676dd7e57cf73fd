"""The ``cad`` source: primitives and booleans (build123d) → named part meshes, metres, +Y up.

Each top-level node of ``CadSource.parts`` becomes one part, named ``node.name``,
in recipe order. When ``spec.script`` is set the work is handed to
``sources/cad_script.py`` (a user's build123d or cadquery script).

Where each primitive sits before placement (all sizes in ``spec.units``, CAD
frame: Z up, front facing -Y):

- ``box(size)``: centred at the origin.
- ``sphere(radius)``: centred at the origin.
- ``torus(major_radius, minor_radius)``: centred at the origin, ring in the XY
  plane (axis along +Z).
- ``cylinder(radius, height)``: axis along +Z, bottom face on z = 0, centred on
  the Z axis (spans z ∈ [0, height]).
- ``cone(radius_bottom, radius_top, height)``: like the cylinder; the bottom
  radius is at z = 0, the top radius at z = height. Either radius may be 0.
- ``extrude(profile, height)``: the closed XY polygon (in its own coordinates,
  any winding) swept from z = 0 to z = height.

Placement of any node: rotate about X, then Y, then Z (fixed world axes,
degrees), then translate by ``at``. A boolean node (union / difference = first
minus the rest / intersection) combines its children, each placed by its own
``at``/``rotate_deg``, and then applies its own placement to the result.

After building, each part is tessellated (chord tolerance ``spec.tolerance`` in
source units, default 0.1 % of the part's bounding-box diagonal; angular
tolerance ``ANGULAR_TOLERANCE_RAD``), repaired with trimesh's ``validate=True``
(OCCT leaves degenerate triangles at sphere poles and cone apexes), scaled to
metres and rotated from ``spec.up_axis`` onto +Y by ``sources.frames``.
For the default Z-up input a point ``(x, y, z)`` lands at ``(x, z, -y)``: CAD's
up (+Z) becomes +Y and CAD's front (-Y) becomes the canonical front (+Z).

build123d and trimesh are imported inside functions: importing build123d
costs 4–9 s and is only paid when a CAD asset is built.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from core.errors import SourceError
from core.recipe import (
    BooleanShape,
    BoxShape,
    CadSource,
    ConeShape,
    CylinderShape,
    ExtrudeShape,
    SphereShape,
    TorusShape,
)
from sources.base import PartMeshes
from sources.frames import transform_mesh

if TYPE_CHECKING:
    import trimesh

#: Default chord tolerance, as a fraction of a part's bounding-box diagonal.
DEFAULT_RELATIVE_TOLERANCE: float = 1e-3

#: Angular tolerance of the tessellation, radians (≈ 11.5°: about 32 segments per full circle at most coarse,
#: enough for a coarse voxel grid; finer settings multiply triangle counts for no visible gain).
ANGULAR_TOLERANCE_RAD: float = 0.2


def load(spec: CadSource, base_dir: Path) -> PartMeshes:
    """Build the parts of a ``cad`` source.

    Args:
        spec: the validated source spec (``parts`` or ``script``).
        base_dir: the recipe's folder; ``spec.script`` resolves against it.

    Returns:
        PartMeshes with one mesh per top-level node (or per script part), in
        metres, +Y up; ``input_files`` is empty for primitives, ``[script]`` for scripts.

    Raises:
        SourceError: an empty boolean result, a bad extrude profile, a failing
            CAD kernel operation, or any script problem (see ``cad_script``).
    """
    if spec.script is not None:
        from sources import cad_script  # only scripts need it

        return cad_script.load(spec, base_dir)

    assert spec.parts is not None  # guaranteed by CadSource's validator
    named_shapes = []
    for index, node in enumerate(spec.parts):
        field = f"parts[{index}]"
        named_shapes.append((node.name, build_node(node, field), field))
    parts, warnings = shapes_to_parts(named_shapes, spec)
    return PartMeshes(parts=parts, warnings=warnings, input_files=[])


# --------------------------------------------------------------------------- building


def build_node(node: Any, field: str) -> Any:
    """One shape node (primitive or boolean, recursively) → a placed build123d shape in source units.

    ``field`` is the node's path inside the source spec (e.g. ``parts[0].children[1]``),
    used in error messages.
    """
    try:
        shape = _build_unplaced(node, field)
    except SourceError:
        raise
    except Exception as exc:  # OCCT / build123d failures surface as assorted exception types
        raise SourceError(
            f"the CAD kernel could not build this '{node.shape}': {type(exc).__name__}: {exc}",
            field=field,
            hint="check the sizes and positions of this shape and its children",
        ) from None
    return _place(shape, node.rotate_deg, node.at)


def _build_unplaced(node: Any, field: str) -> Any:
    import build123d as bd

    on_floor = (bd.Align.CENTER, bd.Align.CENTER, bd.Align.MIN)
    if isinstance(node, BoxShape):
        return bd.Box(*node.size)
    if isinstance(node, SphereShape):
        return bd.Sphere(node.radius)
    if isinstance(node, TorusShape):
        return bd.Torus(node.major_radius, node.minor_radius)
    if isinstance(node, CylinderShape):
        return bd.Cylinder(node.radius, node.height, align=on_floor)
    if isinstance(node, ConeShape):
        return bd.Cone(node.radius_bottom, node.radius_top, node.height, align=on_floor)
    if isinstance(node, ExtrudeShape):
        points = _check_profile(node.profile, f"{field}.profile")
        face = bd.Polygon(*points, align=None)
        # An explicit direction: a clockwise profile's face normal points -Z, and
        # extruding along the normal would then go below z = 0.
        return bd.extrude(face, node.height, dir=(0, 0, 1))
    if isinstance(node, BooleanShape):
        return _boolean(node, field)
    raise SourceError(f"unknown shape {getattr(node, 'shape', node)!r}", field=field)  # pragma: no cover


def _boolean(node: BooleanShape, field: str) -> Any:
    children = [build_node(child, f"{field}.children[{i}]") for i, child in enumerate(node.children)]
    result = children[0]
    for other in children[1:]:
        if node.shape == "union":
            result = result + other
        elif node.shape == "difference":
            result = result - other
        else:
            result = result & other
    if not result.solids():
        what = {
            "intersection": "the children do not overlap",
            "difference": "the subtracted shapes remove everything",
            "union": "the children have no volume",
        }[node.shape]
        raise SourceError(
            f"'{node.shape}' gives an empty shape: {what}",
            field=field,
            hint="move or resize the children so the result keeps some volume",
        )
    return result


def _place(shape: Any, rotate_deg: Sequence[float], at: Sequence[float]) -> Any:
    """Rotate about the world X, then Y, then Z axes (degrees), then translate by ``at``."""
    import build123d as bd

    for axis, angle in zip((bd.Axis.X, bd.Axis.Y, bd.Axis.Z), rotate_deg):
        if angle:
            shape = shape.rotate(axis, float(angle))  # returns a rotated copy
    if any(at):
        shape = shape.moved(bd.Location(tuple(float(c) for c in at)))
    return shape


def _check_profile(profile: Sequence[Sequence[float]], field: str) -> list[tuple[float, float]]:
    """The profile as a list of points without a repeated closing point; refuses non-simple polygons."""
    from shapely.geometry import Polygon
    from shapely.validation import explain_validity

    points = [(float(x), float(y)) for x, y in profile]
    if len(points) > 3 and points[0] == points[-1]:
        points = points[:-1]  # the polygon closes itself; a repeated first point is a zero-length edge
    polygon = Polygon(points)
    if not polygon.is_valid or polygon.area <= 0:
        reason = explain_validity(polygon) if not polygon.is_valid else "it has zero area"
        raise SourceError(
            f"the profile is not a simple polygon ({reason})",
            field=field,
            hint="list the corners in order around the outline, without crossing edges",
        )
    return points


# --------------------------------------------------------------------------- meshing


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
    return transform_mesh(mesh, spec.up_axis, spec.units.metres)


def mesh_warnings(name: str, mesh: "trimesh.Trimesh") -> list[str]:
    """Manifest notes about one part mesh (e.g. it stayed open after repair)."""
    if mesh.is_watertight:
        return []
    return [f"part '{name}' is not watertight after tessellation; voxelizing it may leave holes"]


def default_tolerance(extent_diagonal: float) -> float:
    """The default chord tolerance for a part whose bounding-box diagonal is given (source units)."""
    return max(extent_diagonal * DEFAULT_RELATIVE_TOLERANCE, 1e-9)

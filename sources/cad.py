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

After building, each part is tessellated, repaired, scaled to metres and rotated
onto +Y by ``sources/tessellate.py``.
For the default Z-up input a point ``(x, y, z)`` lands at ``(x, z, -y)``: CAD's
up (+Z) becomes +Y and CAD's front (-Y) becomes the canonical front (+Z).

build123d and trimesh are imported inside functions: importing build123d
costs 4–9 s and is only paid when a CAD asset is built.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

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
from sources import cad_script
from sources.base import PartMeshes
from sources.tessellate import shapes_to_parts


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
        return cad_script.load(spec, base_dir)

    assert spec.parts is not None  # guaranteed by CadSource's validator
    named_shapes = []
    for index, node in enumerate(spec.parts):
        field = f"parts[{index}]"
        named_shapes.append((node.name, build_node(node, field), field))
    parts, warnings = shapes_to_parts(named_shapes, spec)
    return PartMeshes(parts=parts, warnings=warnings, input_files=[])


def preflight(spec: CadSource, base_dir: Path) -> None:
    """Checks that need no CAD kernel: a script exists, is a readable ``.py`` within its size limit. Never runs it."""
    if spec.script is not None:
        cad_script.resolve_script(spec, base_dir)


# --------------------------------------------------------------------------- building


def build_node(node: Any, field: str) -> Any:
    """One shape node (primitive or boolean tree) → a placed build123d shape in source units.

    ``field`` is the node's path inside the source spec (e.g. ``parts[0].children[1]``),
    used in error messages. The tree is walked with an explicit stack (children
    before their boolean), never by recursion, so depth costs no Python stack.
    """
    built: dict[str, Any] = {}  # field path → placed shape, until its parent takes it
    stack: list[tuple[Any, str, bool]] = [(node, field, False)]
    while stack:
        current, where, children_ready = stack.pop()
        if isinstance(current, BooleanShape) and not children_ready:
            stack.append((current, where, True))
            stack.extend((child, f"{where}.children[{i}]", False)
                         for i, child in reversed(list(enumerate(current.children))))
            continue
        children = ([built.pop(f"{where}.children[{i}]") for i in range(len(current.children))]
                    if isinstance(current, BooleanShape) else [])
        built[where] = _build_one(current, where, children)
    return built[field]


def _build_one(node: Any, field: str, children: list[Any]) -> Any:
    """One node from its already built children; CAD kernel failures become SourceError at ``field``."""
    try:
        shape = _boolean(node, children, field) if isinstance(node, BooleanShape) else _primitive(node, field)
    except SourceError:
        raise
    except Exception as exc:  # OCCT / build123d failures surface as assorted exception types
        raise SourceError(
            f"the CAD kernel could not build this '{node.shape}': {type(exc).__name__}: {exc}",
            field=field,
            hint="check the sizes and positions of this shape and its children",
        ) from None
    return _place(shape, node.rotate_deg, node.at)


def _primitive(node: Any, field: str) -> Any:
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
    raise SourceError(f"unknown shape {getattr(node, 'shape', node)!r}", field=field)  # pragma: no cover


def _boolean(node: BooleanShape, children: list[Any], field: str) -> Any:
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

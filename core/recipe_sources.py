"""Recipe schema, sources: the limits every number obeys, the strict base model, and the source kinds.

The per-asset settings, the asset and the recipe are ``core/recipe.py`` (which
re-exports these names, so ``from core.recipe import CadSource`` keeps working).
Ranges: lengths in a source's units ``SIZE_RANGE``, coordinates within
±``MAX_COORDINATE``, angles within ±``MAX_ANGLE_DEG``, lengths in metres
``METRES_RANGE``, seeds ``[0, MAX_SEED]``; a CAD tree nests at most
``MAX_CAD_DEPTH`` levels and holds ``MAX_CAD_NODES`` shapes.
"""

from __future__ import annotations

from collections import Counter
from enum import Enum
from typing import Annotated, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

#: Smallest and largest size in a source's own units (CAD dimensions, tolerances, mesh scale factors).
SIZE_RANGE: tuple[float, float] = (1e-6, 1e6)
#: Largest absolute coordinate (CAD placements, extrude profiles), in the source's units.
MAX_COORDINATE: float = 1e6
#: Largest absolute rotation angle, degrees.
MAX_ANGLE_DEG: float = 3600.0
#: Smallest and largest length in metres (text size and depth, voxel sizes).
METRES_RANGE: tuple[float, float] = (1e-4, 1e3)
#: Largest seed (seeds are 32-bit).
MAX_SEED: int = 2**32 - 1
#: Deepest nesting of CAD booleans (a top-level part is level 1) and most shapes in one CAD source.
MAX_CAD_DEPTH: int = 32
MAX_CAD_NODES: int = 1_000

Size = Annotated[float, Field(ge=SIZE_RANGE[0], le=SIZE_RANGE[1])]
SizeOrZero = Annotated[float, Field(ge=0, le=SIZE_RANGE[1])]
Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
Angle = Annotated[float, Field(ge=-MAX_ANGLE_DEG, le=MAX_ANGLE_DEG)]
Metres = Annotated[float, Field(ge=METRES_RANGE[0], le=METRES_RANGE[1])]
VoxelMetres = Annotated[float, Field(ge=1e-6, le=METRES_RANGE[1])]
Vec3 = tuple[Coordinate, Coordinate, Coordinate]
AngleVec3 = tuple[Angle, Angle, Angle]
SizeVec3 = tuple[Size, Size, Size]
Vec2 = tuple[Coordinate, Coordinate]
#: Longest path a recipe may give for a file.
MAX_PATH_CHARS = 4096
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$"
#: Value of a region's part/style meaning "keep what the source says".
FROM_SOURCE = "@source"
LABEL_PATTERN = r"^(@source|[A-Za-z0-9][A-Za-z0-9_.\-]*)$"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, use_enum_values=False, allow_inf_nan=False)


# --------------------------------------------------------------------------- enums


class UpAxis(str, Enum):
    """Which axis of the *input* points up; it is rotated onto +Y."""

    X = "x"
    Y = "y"
    Z = "z"
    NEG_X = "-x"
    NEG_Y = "-y"
    NEG_Z = "-z"


class LengthUnit(str, Enum):
    """Unit of the numbers in a source; converted to metres."""

    M = "m"
    CM = "cm"
    MM = "mm"
    INCH = "in"

    @property
    def metres(self) -> float:
        return {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}[self.value]


class TextAlign(str, Enum):
    LEFT = "left"
    CENTER = "center"
    RIGHT = "right"


class PartsFrom(str, Enum):
    """Where a mesh file's parts come from."""

    NODES = "nodes"  # scene nodes / OBJ objects and groups
    WHOLE = "whole"  # the whole file is one part


# --------------------------------------------------------------------------- sources


class TextSource(_Strict):
    """Extruded 3D text; one part per glyph named ``glyph_<index>_<char>``."""

    kind: Literal["text"]
    text: str = Field(max_length=2000, description="The string; '\\n' starts a new line.")
    font: Optional[str] = Field(None, max_length=MAX_PATH_CHARS,
                                description="TTF/OTF path, relative to the recipe; default: bundled DejaVu Sans Bold.")
    size_m: Metres = Field(0.2, description="Font size (em height) in metres.")
    depth_m: Optional[Metres] = Field(None, description="Extrusion depth in metres; default 0.3 × size_m.")
    letter_spacing: float = Field(0.08, ge=-0.5, le=2.0, description="Extra space between glyphs, in em.")
    line_spacing: float = Field(1.2, gt=0, le=5.0, description="Baseline-to-baseline distance, in em.")
    align: TextAlign = TextAlign.CENTER
    bevel_m: float = Field(0.0, ge=0, le=METRES_RANGE[1], description="Chamfer on the front edges, metres; 0 = none.")

    @field_validator("text")
    @classmethod
    def _not_blank(cls, v: str) -> str:
        if not v.strip():
            raise ValueError("text is empty; give at least one visible character")
        return v


class _Placed(_Strict):
    name: Optional[str] = Field(None, pattern=NAME_PATTERN, description="Part name (required on top-level parts).")
    at: Vec3 = Field((0.0, 0.0, 0.0), description="Translation, in the source's units.")
    rotate_deg: AngleVec3 = Field((0.0, 0.0, 0.0), description="Rotation about the fixed X, then Y, then Z axes, in degrees; applied before 'at'.")


class BoxShape(_Placed):
    """A box of ``size`` (x, y, z), centred at the origin before placement."""

    shape: Literal["box"]
    size: SizeVec3


class CylinderShape(_Placed):
    """A cylinder along +Z standing on z = 0 (spans z ∈ [0, height]), centred on the Z axis."""

    shape: Literal["cylinder"]
    radius: Size
    height: Size


class SphereShape(_Placed):
    """A sphere centred at the origin before placement."""

    shape: Literal["sphere"]
    radius: Size


class ConeShape(_Placed):
    """A cone / frustum along +Z: ``radius_bottom`` at z = 0, ``radius_top`` at z = height."""

    shape: Literal["cone"]
    radius_bottom: SizeOrZero
    radius_top: SizeOrZero = 0.0
    height: Size

    @model_validator(mode="after")
    def _one_radius(self) -> "ConeShape":
        if self.radius_bottom == 0 and self.radius_top == 0:
            raise ValueError("a cone needs radius_bottom > 0 or radius_top > 0")
        return self


class TorusShape(_Placed):
    """A torus centred at the origin, its ring in the XY plane (axis +Z)."""

    shape: Literal["torus"]
    major_radius: Size
    minor_radius: Size

    @model_validator(mode="after")
    def _radii(self) -> "TorusShape":
        if self.minor_radius >= self.major_radius:
            raise ValueError("minor_radius must be smaller than major_radius")
        return self


class ExtrudeShape(_Placed):
    """A closed 2-D polygon in the XY plane (any winding), extruded from z = 0 to z = height (+Z, the CAD up axis by default)."""

    shape: Literal["extrude"]
    profile: list[Vec2] = Field(min_length=3, max_length=10_000)
    height: Size


class BooleanShape(_Placed):
    """union / difference (first child minus the rest) / intersection of children."""

    shape: Literal["union", "difference", "intersection"]
    children: list["ShapeNode"] = Field(min_length=1, max_length=MAX_CAD_NODES)

    @model_validator(mode="after")
    def _arity(self) -> "BooleanShape":
        if self.shape != "union" and len(self.children) < 2:
            raise ValueError(f"'{self.shape}' needs at least two children")
        return self


ShapeNode = Annotated[
    Union[BoxShape, CylinderShape, SphereShape, ConeShape, TorusShape, ExtrudeShape, BooleanShape],
    Field(discriminator="shape"),
]
BooleanShape.model_rebuild()


class CadSource(_Strict):
    """CAD primitives and booleans (build123d), or a user's build123d script.

    Give either ``parts`` (each top-level node is a named part) or ``script``: a
    Python file run only because the recipe names it; its function
    ``script_function`` returns a shape or a dict of part name → shape.
    """

    kind: Literal["cad"]
    units: LengthUnit = LengthUnit.M
    up_axis: UpAxis = Field(UpAxis.Z, description="CAD convention is Z up; it is rotated onto +Y.")
    parts: Optional[list[ShapeNode]] = Field(None, max_length=MAX_CAD_NODES)
    script: Optional[str] = Field(None, max_length=MAX_PATH_CHARS)
    script_function: str = Field("build", pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")
    script_engine: Literal["build123d", "cadquery"] = Field(
        "build123d", description="Library the script uses; cadquery scripts run in the optional cadquery runtime.")
    tolerance: Optional[Size] = Field(
        None, description="Tessellation chord tolerance in the source's units; default 0.1 % of the size.")
    script_timeout_s: float = Field(
        300.0, ge=1, le=86_400, description="Wall-clock limit of one script run (start, imports, the script, "
        "tessellation), seconds; past it the script is stopped and the asset fails.")
    script_memory_mb: int = Field(
        4096, ge=64, le=1_048_576, description="Memory a script may take beyond the CAD engine's own, MiB "
        "(an address-space limit of the process it runs in); a script that needs more fails its asset.")

    @model_validator(mode="after")
    def _parts_or_script(self) -> "CadSource":
        if (self.parts is None) == (self.script is None):
            raise ValueError("give exactly one of 'parts' (primitives) or 'script' (a .py file)")
        if self.parts is not None:
            if not self.parts:
                raise ValueError("'parts' is empty; add at least one shape")
            names = [p.name for p in self.parts]
            if any(n is None for n in names):
                raise ValueError("every top-level part needs a 'name'")
            dup = {n for n, c in Counter(names).items() if c > 1}
            if dup:
                raise ValueError(f"duplicate part names: {sorted(dup)}")
            _check_cad_tree(self.parts)
        return self


def _check_cad_tree(parts: list) -> None:
    """Refuse CAD trees deeper than ``MAX_CAD_DEPTH`` or with more than ``MAX_CAD_NODES`` shapes (iterative walk)."""
    stack = [(node, 1, f"parts[{i}]") for i, node in enumerate(parts)]
    count = 0
    while stack:
        node, depth, where = stack.pop()
        count += 1
        if depth > MAX_CAD_DEPTH:
            raise ValueError(f"the CAD tree is nested more than {MAX_CAD_DEPTH} levels deep (at {where}); "
                             "flatten it: a union takes any number of children")
        if count > MAX_CAD_NODES:
            raise ValueError(f"the CAD tree holds more than {MAX_CAD_NODES} shapes; "
                             "use a script (source.script) for larger models")
        for i, child in enumerate(getattr(node, "children", ())):
            stack.append((child, depth + 1, f"{where}.children[{i}]"))


class MeshSource(_Strict):
    """An imported mesh file (OBJ, STL, PLY, OFF, GLB/GLTF)."""

    kind: Literal["mesh"]
    path: str = Field(max_length=MAX_PATH_CHARS)
    up_axis: UpAxis = UpAxis.Y
    units: LengthUnit = LengthUnit.M
    scale: Size = Field(1.0, description="Factor applied to the file's numbers (after 'units').")
    parts_from: PartsFrom = PartsFrom.NODES


class VoxelsSource(_Strict):
    """A grid from another generator: .npy (occupancy) or .npz (occupancy, optional part/style)."""

    kind: Literal["voxels"]
    path: str = Field(max_length=MAX_PATH_CHARS)
    up_axis: UpAxis = UpAxis.Y
    voxel_size_m: VoxelMetres = Field(0.05, description="Edge of one input voxel in metres.")


#: ``VoxSource.model`` value that merges every visible model instance as the scene places it.
ALL_MODELS = "@all"
#: Palette indices of a .vox file (0 is "empty", never a voxel).
PaletteIndex = Annotated[int, Field(ge=1, le=255)]


class VoxSource(_Strict):
    """A MagicaVoxel / Goxel ``.vox`` file; palette indices (1..255) become parts and optionally styles.

    ``parts`` maps a part name to the palette indices painted with it (default:
    one part per index used, named ``palette_<index>``); ``styles`` likewise
    names a style per index (then every mapped index needs one; regions keep
    them with ``style: '@source'``). ``ignore`` drops indices (guides, scaffolding).
    A file with several models needs ``model``: an instance's index or name, or
    ``'@all'`` to merge them as the scene places them (see sources/vox.py).
    """

    kind: Literal["vox"]
    path: str = Field(max_length=MAX_PATH_CHARS)
    parts: Optional[dict[Annotated[str, Field(pattern=NAME_PATTERN)], list[PaletteIndex]]] = None
    styles: Optional[dict[Annotated[str, Field(pattern=NAME_PATTERN)], list[PaletteIndex]]] = None
    ignore: list[PaletteIndex] = Field([], description="Palette indices whose voxels are dropped.")
    model: Optional[Union[Annotated[int, Field(ge=0)], str]] = Field(
        None, description="Which model instance of a multi-model file: index, name, or '@all' (merged as placed).")
    up_axis: UpAxis = Field(UpAxis.Z, description="MagicaVoxel is Z up (front -Y); it is rotated onto +Y.")
    voxel_size_m: VoxelMetres = Field(0.05, description="Edge of one input voxel in metres.")

    @model_validator(mode="after")
    def _one_label_per_index(self) -> "VoxSource":
        ignored = set(self.ignore)
        for what, mapping in (("part", self.parts), ("style", self.styles)):
            owner: dict[int, str] = {}
            for name, indices in (mapping or {}).items():
                for index in indices:
                    if index in ignored:
                        raise ValueError(f"palette index {index} is both ignored and mapped to {what} '{name}'")
                    if index in owner and owner[index] != name:
                        raise ValueError(f"palette index {index} is mapped to two {what}s, "
                                         f"'{owner[index]}' and '{name}'")
                    owner[index] = name
        if self.styles is not None:
            if self.parts is None:
                raise ValueError("'styles' needs 'parts' too (every palette index with a style needs a part)")
            parted = {i for indices in self.parts.values() for i in indices}
            styled = {i for indices in self.styles.values() for i in indices}
            for index in sorted(parted ^ styled):
                where = "a part but no style" if index in parted else "a style but no part"
                raise ValueError(f"palette index {index} has {where} (with 'styles', every part index needs one)")
        return self


SourceSpec = Annotated[Union[TextSource, CadSource, MeshSource, VoxelsSource, VoxSource], Field(discriminator="kind")]

#: Fields of each source kind that name input files (resolved against the recipe's folder).
SOURCE_FILE_FIELDS: dict[str, tuple[str, ...]] = {
    "text": ("font",),
    "cad": ("script",),
    "mesh": ("path",),
    "voxels": ("path",),
    "vox": ("path",),
}

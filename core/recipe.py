"""Recipe schema (version 1): typed, strict, validated; every user-facing setting lives here.

A recipe is YAML::

    version: 1
    defaults: {grid: {...}, detailize: {...}, export: {...}}   # optional
    assets:
      - name: hello
        source: {kind: text, text: HELLO}
        regions:
          - {parts: ["glyph_*"], part: body, style: brick}
          - {band: top, part: roof, style: tiles}

Validation is strict (JSON mode): unknown keys are errors, strings are never
coerced to numbers, lists are accepted where tuples are meant, NaN and
infinities are refused, and every number has a documented range (shown as
``minimum``/``maximum`` in ``decollage schema``): lengths in a source's units
``SIZE_RANGE``, coordinates within ±``MAX_COORDINATE``, angles within
±``MAX_ANGLE_DEG``, lengths in metres ``METRES_RANGE``, seeds ``[0, MAX_SEED]``.
A CAD tree may nest ``MAX_CAD_DEPTH`` levels and hold ``MAX_CAD_NODES`` shapes. Reading a recipe
file (YAML, defaults, variants, errors naming the file and the field path) is
``core/recipe_loader.py``.
"""

from __future__ import annotations

from collections import Counter
from enum import Enum
from typing import Annotated, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, field_validator, model_validator

from core.detailizer import DEFAULT_DETAILIZER

SCHEMA_VERSION = 1

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


class FitMode(str, Enum):
    """How a source is scaled into the coarse grid.

    longest: the longest side spans ``resolution`` voxels (the classic 16³ cube).
    height: the Y extent spans ``resolution`` voxels; X and Z grow as needed
        (default for text: each glyph gets about ``resolution`` voxels of height).
    voxel_size: use ``voxel_size_m`` as given; the grid is as large as the shape.
    """

    LONGEST = "longest"
    HEIGHT = "height"
    VOXEL_SIZE = "voxel_size"


class PartsFrom(str, Enum):
    """Where a mesh file's parts come from."""

    NODES = "nodes"  # scene nodes / OBJ objects and groups
    WHOLE = "whole"  # the whole file is one part


class ExportFormat(str, Enum):
    GLB = "glb"
    OBJ = "obj"
    STL = "stl"
    PLY = "ply"


class EngineProfile(str, Enum):
    """Node naming, LOD/collision layout and axes for a game engine (pipeline/engines.py)."""

    GENERIC = "generic"
    UNITY = "unity"
    UNREAL = "unreal"
    GODOT = "godot"


class CollisionKind(str, Enum):
    NONE = "none"
    HULL = "hull"  # convex hull of LOD0
    BOXES = "boxes"  # boxes merged from the coarse grid's occupied cells


class Device(str, Enum):
    """Where a learned detailizer runs: the GPU when there is one (auto), or always the CPU / a CUDA GPU."""

    AUTO = "auto"
    CPU = "cpu"
    CUDA = "cuda"


class AssetUse(str, Enum):
    """What an asset is for in a game; sets its default triangle budget (pipeline/mesh.py's ``triangle_budget``).

    hero: close-ups, the player's focus; prop: ordinary objects (the default); background: distant scenery.
    """

    HERO = "hero"
    PROP = "prop"
    BACKGROUND = "background"


class GlbCompression(str, Enum):
    """How GLB files store their geometry.

    none: plain float32 attributes (every glTF reader loads them);
    meshopt: quantized attributes (KHR_mesh_quantization) compressed with EXT_meshopt_compression
    (pipeline/glb_meshopt.py), about a fifth of the size; readers need meshopt's decoder.
    """

    NONE = "none"
    MESHOPT = "meshopt"


class VoxExport(str, Enum):
    """Which grid of an asset ``export.vox`` writes as a MagicaVoxel file (pipeline/vox_export.py)."""

    COARSE = "coarse"  # the labelled coarse grid: one palette index per (part, style), recorded in the manifest
    FINE = "fine"  # the detailed grid, downsampled to at most 256 per axis, one palette index per style


class Pivot(str, Enum):
    """Where the exported mesh's origin sits."""

    BOTTOM_CENTER = "bottom_center"  # centre of the footprint, at the lowest point (game-engine friendly)
    CENTER = "center"  # centre of the bounding box
    SOURCE = "source"  # keep the source's own coordinates


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


# --------------------------------------------------------------------------- per-asset settings


class GridSettings(_Strict):
    """How the source becomes the coarse labeled grid."""

    resolution: int = Field(16, ge=4, le=64, description="Voxels across the fitted extent.")
    fit: Optional[FitMode] = Field(None, description="Default: 'height' for text, 'longest' otherwise.")
    voxel_size_m: Optional[VoxelMetres] = Field(None, description="Only with fit: voxel_size.")
    max_cells: int = Field(
        1024, ge=4, le=1024,
        description="Largest allowed coarse grid side. Grids longer than 64 cells along x (long text) are "
                    "detailized and meshed block by block, so their memory does not grow with their length; "
                    "the per-asset memory estimate (core/budget.py) guards the other sides.")
    min_coverage: float = Field(0.5, gt=0, le=1, description="Fraction of a cell a shape must fill to occupy it.")
    keep_thin: bool = Field(False, description="Keep parts thinner than a voxel (at least one voxel each).")

    @model_validator(mode="after")
    def _voxel_size(self) -> "GridSettings":
        if (self.fit == FitMode.VOXEL_SIZE) != (self.voxel_size_m is not None):
            raise ValueError("'voxel_size_m' goes together with fit: voxel_size (and only with it)")
        return self


class Band(_Strict):
    """A slab of the asset's bounding box, as fractions of its extent along ``axis``."""

    axis: Literal["x", "y", "z"] = "y"
    from_: float = Field(0.0, ge=0, le=1, alias="from")
    to: float = Field(1.0, ge=0, le=1)

    @model_validator(mode="after")
    def _order(self) -> "Band":
        if self.from_ >= self.to:
            raise ValueError("band 'from' must be smaller than 'to'")
        return self


BAND_SHORTCUTS = {"top": Band(**{"from": 0.5, "to": 1.0}), "bottom": Band(**{"from": 0.0, "to": 0.5})}


#: Largest index a ``cells`` entry may hold: the coarse grid is at most ``max_cells`` (≤ 1024) cells a side.
MAX_CELL_INDEX = 1023
CellIndex = Annotated[int, Field(ge=0, le=MAX_CELL_INDEX)]


class RegionRule(_Strict):
    """Give matching voxels a part label and a style. Later rules override earlier ones.

    A voxel matches when its source part matches one of ``parts`` (shell-style
    globs over source part names), if ``band`` is given it lies in the band, and
    if ``cells`` is given it is one of those coarse cells.
    """

    parts: list[str] = Field(["*"], min_length=1)
    band: Optional[Union[Literal["top", "bottom"], Band]] = None
    cells: Optional[list[tuple[CellIndex, CellIndex, CellIndex]]] = Field(
        None, min_length=1, max_length=1 << 18,
        description="Coarse grid cells [x, y, z] (0-based indices of the asset's labeled grid, +Y up) the rule "
                    "is limited to; 'decollage paint' writes them for voxels painted with its brush.")
    part: str = Field(pattern=LABEL_PATTERN, description="Semantic part label, e.g. body, roof; "
                      "'@source' keeps the source's own part name.")
    style: str = Field(pattern=LABEL_PATTERN, description="Style name (an exemplar of the detailizer); "
                       "'@source' keeps the style a voxels input carries.")

    def band_range(self) -> Band | None:
        if isinstance(self.band, str):
            return BAND_SHORTCUTS[self.band]
        return self.band


class DetailizeSettings(_Strict):
    detailizer: str = Field(DEFAULT_DETAILIZER, description="'decollage' (the learned model; the shipped weights "
                            "unless 'checkpoint' names others), 'quilt' (non-learned: copies the style exemplars' "
                            "detail) or 'upsample' (the non-learned baseline).")
    checkpoint: Optional[str] = Field(None, max_length=MAX_PATH_CHARS,
                                      description="Checkpoint file for a learned detailizer; for 'quilt' the "
                                      "style set it copies from (a set name or .npz file; default: things).")
    seed: int = Field(0, ge=0, le=MAX_SEED)
    device: Device = Device.AUTO


class ExportSettings(_Strict):
    formats: list[ExportFormat] = Field([ExportFormat.GLB], min_length=1)
    preview: bool = True
    preview_size_px: int = Field(512, ge=64, le=4096)
    taubin_iterations: int = Field(8, ge=0, le=200, description="Taubin smoothing passes (irons out the "
                                   "stair steps of a near-binary fine grid); 0 = off.")
    taubin_max_shift_voxels: Optional[float] = Field(
        0.5, gt=0, le=16, description="While smoothing, no vertex moves farther than this many fine voxels from "
                                       "where marching cubes put it (irons out terraces, keeps larger detail); "
                                       "null = unbounded.")
    max_triangles: Optional[Union[int, Literal["auto"]]] = Field(
        "auto", description="Decimate above this many triangles; 'auto' = a budget from the asset's coarse surface "
                            "and its 'use' (pipeline/mesh.py's triangle_budget); null = never.")
    use: AssetUse = Field(AssetUse.PROP, description="hero, prop or background: sets the 'auto' triangle budget.")
    pivot: Pivot = Pivot.BOTTOM_CENTER
    vertex_colors: bool = True
    compression: GlbCompression = Field(GlbCompression.NONE, description="GLB geometry: 'none' (plain, every "
                                        "reader) or 'meshopt' (quantized + EXT_meshopt_compression, ~5× smaller; "
                                        "readers need meshopt's decoder, as three.js, Unity glTFast, Godot 4 have).")
    glb_material: bool = Field(False, description="Give GLBs a white matte material, for viewers whose default "
                               "glTF material (fully metallic) shows vertex colours too dark.")
    profile: EngineProfile = Field(EngineProfile.GENERIC, description="Engine conventions for names, LODs, "
                                   "collision and axes: generic, unity, unreal, godot.")
    lods: Optional[Union[list[Annotated[int, Field(ge=4, le=100_000_000)]],
                         list[Annotated[float, Field(gt=0, le=1)]]]] = Field(
        None, max_length=16, description="LOD chain: ratios of LOD0's triangles ([1.0, 0.5, 0.25]) or triangle counts "
                          "([20000, 5000, 1000]); the first entry is LOD0.")
    collision: CollisionKind = CollisionKind.NONE
    vox: list[VoxExport] = Field([], description="Also write <name>.coarse.vox and/or <name>.fine.vox "
                                 "(MagicaVoxel) to touch the asset up in a voxel editor.")

    @field_validator("max_triangles")
    @classmethod
    def _triangle_count(cls, v: int | str | None) -> int | str | None:
        if isinstance(v, int) and not 4 <= v <= 100_000_000:
            raise ValueError("Input should be greater than or equal to 4 and at most 100000000 (or 'auto', or null)")
        return v

    @field_validator("lods")
    @classmethod
    def _lod_chain(cls, v: list | None) -> list | None:
        if v is None:
            return v
        if not v:
            raise ValueError("lods is empty; give e.g. [1.0, 0.5, 0.25] or leave it out")
        if any(b >= a for a, b in zip(v, v[1:])):
            raise ValueError("lods must decrease from LOD0 to the last level")
        if isinstance(v[0], float):
            if v[0] != 1.0 or v[-1] <= 0:
                raise ValueError("lod ratios start at 1.0 (LOD0) and stay above 0")
        elif v[-1] < 4:
            raise ValueError("a LOD needs at least 4 triangles")
        return v

    @field_validator("formats", "vox")
    @classmethod
    def _unique(cls, v: list) -> list:
        if len(set(v)) != len(v):
            raise ValueError("an entry is listed twice")
        return v


VariantValue = Union[str, int, float, bool]


class Asset(_Strict):
    name: str = Field(pattern=NAME_PATTERN, max_length=100)
    variants: Optional[dict[str, list[VariantValue]]] = Field(
        None, description="A matrix of values (key → list); the asset expands to one asset per combination, "
                          "with ${key} replaced everywhere (see core/variants.py).")
    name_template: Optional[str] = Field(None, description="Names of the expanded assets, e.g. "
                                         "'{asset}_{style}_{seed}'; default: {asset}_ and every key in order.")
    variant: Optional[dict[str, VariantValue]] = Field(
        None, description="Set by the expansion: the values this asset was made with.")
    source: SourceSpec
    grid: GridSettings = GridSettings()
    regions: list[RegionRule] = Field(min_length=1)
    detailize: DetailizeSettings = DetailizeSettings()
    export: ExportSettings = ExportSettings()

    @property
    def fit(self) -> FitMode:
        """The grid fit with the per-kind default applied."""
        if self.grid.fit is not None:
            return self.grid.fit
        return FitMode.HEIGHT if self.source.kind == "text" else FitMode.LONGEST


class Defaults(_Strict):
    grid: GridSettings = GridSettings()
    detailize: DetailizeSettings = DetailizeSettings()
    export: ExportSettings = ExportSettings()


class Recipe(_Strict):
    #: Per (expanded) asset: (index of the asset in the recipe file, variant name or None).
    _origin: list[tuple[int, Optional[str]]] = PrivateAttr(default_factory=list)

    version: Literal[1] = Field(description="Schema version; this tool reads version 1.")
    defaults: Defaults = Defaults()
    assets: list[Asset] = Field(min_length=1)

    @field_validator("assets")
    @classmethod
    def _unique_names(cls, assets: list[Asset]) -> list[Asset]:
        dup = sorted(n for n, c in Counter(a.name for a in assets).items() if c > 1)
        if dup:
            raise ValueError(f"asset names must be unique; repeated: {dup}")
        return assets


# --------------------------------------------------------------------------- loading

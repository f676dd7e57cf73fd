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

from pydantic import Field, PrivateAttr, field_validator, model_validator

from core.detailizer import DEFAULT_DETAILIZER, STYLE_SET_DETAILIZERS
from core.recipe_sources import (  # noqa: F401  (re-exported: the schema's names live in core.recipe)
    ALL_MODELS,
    FROM_SOURCE,
    LABEL_PATTERN,
    MAX_ANGLE_DEG,
    MAX_CAD_DEPTH,
    MAX_CAD_NODES,
    MAX_COORDINATE,
    MAX_PATH_CHARS,
    MAX_SEED,
    METRES_RANGE,
    NAME_PATTERN,
    SIZE_RANGE,
    SOURCE_FILE_FIELDS,
    Angle,
    AngleVec3,
    BooleanShape,
    BoxShape,
    CadSource,
    ConeShape,
    Coordinate,
    CylinderShape,
    ExtrudeShape,
    LengthUnit,
    MeshSource,
    Metres,
    PaletteIndex,
    PartsFrom,
    ShapeNode,
    Size,
    SizeOrZero,
    SizeVec3,
    SourceSpec,
    SphereShape,
    TextAlign,
    TextSource,
    TorusShape,
    UpAxis,
    Vec2,
    Vec3,
    VoxelMetres,
    VoxelsSource,
    VoxSource,
    _Strict,
)

SCHEMA_VERSION = 1



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


class MeshResolution(str, Enum):
    """At which resolution the fine field is meshed (pipeline/mesh.py's ``mesh_sample_step``).

    full: marching cubes on every fine voxel; half: on the field box-averaged 2×2×2 (a quarter of the
    triangles to smooth and decimate; a feature one fine voxel thin becomes paper-thin or goes, and an
    asset that would vanish is meshed at full resolution); auto (the default):
    half where the triangle budget keeps at most 1 in ``HALF_RES_FACE_RATIO`` of the full-resolution
    surface's triangles (long words, small budgets: there decimation removes that detail anyway), else full.
    """

    AUTO = "auto"
    FULL = "full"
    HALF = "half"


class VoxExport(str, Enum):
    """Which grid of an asset ``export.vox`` writes as a MagicaVoxel file (pipeline/vox_export.py)."""

    COARSE = "coarse"  # the labelled coarse grid: one palette index per (part, style), recorded in the manifest
    FINE = "fine"  # the detailed grid, downsampled to at most 256 per axis, one palette index per style


class Pivot(str, Enum):
    """Where the exported mesh's origin sits."""

    BOTTOM_CENTER = "bottom_center"  # centre of the footprint, at the lowest point (game-engine friendly)
    CENTER = "center"  # centre of the bounding box
    SOURCE = "source"  # keep the source's own coordinates


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
    detailizer: str = Field(DEFAULT_DETAILIZER, description="'quilt' (the default; non-learned: copies and joins "
                            "the style exemplars' real detail), 'decollage' (the learned model; the shipped weights "
                            "unless 'checkpoint' names others) or 'upsample' (the non-learned baseline).")
    checkpoint: Optional[str] = Field(None, max_length=MAX_PATH_CHARS, description="Checkpoint file for "
                                      "'decollage' (default: the shipped weights).")
    style_set: Optional[str] = Field(None, max_length=MAX_PATH_CHARS, description="The style set 'quilt' copies "
                                     "from: built-in (things, furniture...), imported, or a .npz file (default: things).")
    seed: int = Field(0, ge=0, le=MAX_SEED)
    device: Device = Device.AUTO

    @model_validator(mode="after")
    def _data_file_fits_the_detailizer(self) -> "DetailizeSettings":
        wrong = "checkpoint" if self.detailizer in STYLE_SET_DETAILIZERS else "style_set"
        if getattr(self, wrong) is not None:
            raise ValueError(f"'{self.detailizer}' takes no {wrong} (remove '{wrong}'): 'quilt' copies from a "
                             "'style_set', the learned model loads a 'checkpoint'")
        return self

    def data_file(self, detailizer: str) -> tuple[str, Optional[str]]:
        """(field, recipe value) of the file ``detailizer`` loads: its ``style_set`` or ``checkpoint``; the value
        is None when ``detailizer`` is not the recipe's own (a command line's ``--detailizer``)."""
        field = "style_set" if detailizer in STYLE_SET_DETAILIZERS else "checkpoint"
        return field, getattr(self, field) if detailizer == self.detailizer else None


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
    mesh_resolution: MeshResolution = Field(MeshResolution.AUTO, description="Mesh the fine field at 'full' "
                                            "resolution or box-averaged to 'half' (4× fewer triangles before "
                                            "decimation); 'auto' = half when the triangle budget is far below the "
                                            "full surface's count.")
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

"""What every source produces, and the small protocol a source implements.

A source turns its typed spec (from ``core/recipe.py``) into named parts in
the canonical frame: +Y up, front +Z, metres. It never voxelizes (except the
``voxels`` source, whose input already *is* voxels) and never sees tensors.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, Union

import numpy as np

if TYPE_CHECKING:  # trimesh is imported lazily by the sources that need it
    import trimesh


@dataclass
class PartMeshes:
    """Named triangle meshes, one per source part, in metres, +Y up.

    Attributes:
        parts: part name → ``trimesh.Trimesh`` (vertices in metres). Insertion
            order is the part order; names are unique.
        warnings: human-readable notes for the manifest (e.g. "mesh is not watertight").
        input_files: every file the source read, the recipe-named one first: recorded by the
            readers that opened them (a glTF's buffers and images, an OBJ's material library,
            a script's local modules and data files, a font), including files a reader looked
            for and did not find. The one list a build's cache key and manifest read
            (``pipeline/cache.py``): an edit to any of them makes the asset stale.
        fit_height_m: the height that ``fit: height`` maps onto ``grid.resolution``
            voxels, when it is not simply the bounding box's Y extent (text: the
            font's cap height, so every line's capitals get the same voxels whatever
            accents, descenders or line count the string has). None = Y extent.
    """

    parts: dict[str, "trimesh.Trimesh"]
    warnings: list[str] = field(default_factory=list)
    input_files: list[Path] = field(default_factory=list)
    fit_height_m: float | None = None

    def bounds_m(self) -> np.ndarray:
        """(2, 3) min/max over all parts, metres."""
        boxes = np.array([m.bounds for m in self.parts.values()])
        return np.stack([boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)])


@dataclass
class PartVoxels:
    """A ready-made voxel grid with a source part per voxel (the ``voxels`` source).

    Attributes:
        part: (X, Y, Z) int16, index into ``part_names``; -1 where empty. +Y up.
        part_names: source part names.
        style: optional (X, Y, Z) int16 index into ``style_names`` (-1 empty), when the
            input file carries styles.
        style_names: names behind ``style``.
        voxel_size_m: edge of one voxel in metres.
    """

    part: np.ndarray
    part_names: tuple[str, ...]
    voxel_size_m: float
    style: np.ndarray | None = None
    style_names: tuple[str, ...] = ()
    warnings: list[str] = field(default_factory=list)
    input_files: list[Path] = field(default_factory=list)  # as PartMeshes.input_files: the voxel file


SourceResult = Union[PartMeshes, PartVoxels]


class Source(Protocol):
    """One module per source kind exposes ``load(spec, base_dir) -> SourceResult``.

    ``spec`` is the kind's pydantic model from ``core/recipe.py``; ``base_dir``
    is the recipe file's folder, against which relative paths resolve. Errors
    are raised as ``SourceError`` with ``field`` set relative to the source
    (e.g. ``"font"``); the caller prefixes the asset path.
    """

    def __call__(self, spec, base_dir: Path) -> SourceResult: ...

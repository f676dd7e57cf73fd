"""The painter's view of one asset: its coarse grid before and after the region rules, and the page's edits.

Role: load one recipe asset up to its labeled grid, the same stages as
``pipeline/build.py`` (source → ``geometry/voxelize.py`` → ``pipeline/regions.py``),
and translate between that grid and the JSON the page works on.

Voxels travel as flat lists in the order of ``np.argwhere(occupied)`` (x, then
y, then z; C order): ``cells`` is ``[x0, y0, z0, x1, y1, z1, ...]`` (grid
indices, +Y up), and every per-voxel list (``part``, ``style``,
``source_part``) has one entry per occupied voxel, an index into its name list.
The page sends its edits back as a *target*: the part label and style it wants
on every occupied voxel (``Target``); ``studio/paint_rules.py`` turns a target
into region rules.

A script source runs only when the recipe names it and the painter was started
with ``--allow-scripts`` (``allow_scripts``); otherwise loading such an asset
raises StudioError without running anything.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass

import numpy as np

from core.errors import DecollageError, StudioError
from core.grid import EMPTY, LabeledGrid
from core.recipe import NAME_PATTERN, SOURCE_FILE_FIELDS, Asset, RegionRule
from core.recipe_loader import LoadedRecipe
from geometry.voxelize import PartGrid, voxelize
from pipeline.palette import palette_rgba
from pipeline.regions import apply_regions
from sources import load_source

_NAME = re.compile(NAME_PATTERN)


@dataclass(frozen=True, eq=False)
class AssetGrid:
    """One asset of the recipe, loaded up to its labeled grid.

    Attributes:
        index: the asset's index among the recipe's expanded assets.
        field: where it is in the recipe file (``assets[2]``).
        asset: the validated asset (defaults applied, variants expanded).
        source_grid: source-part labels per coarse voxel (before the rules).
        labeled: the grid after the asset's region rules (what the detailizer gets).
        cells: (N, 3) int64 grid indices of the occupied voxels, C order.
        warnings: the source's, the voxelizer's and the rules' notes.
    """

    index: int
    field: str
    asset: Asset
    source_grid: PartGrid
    labeled: LabeledGrid
    cells: np.ndarray
    warnings: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class Target:
    """The part label and style the page wants on each occupied voxel.

    Attributes:
        part_names / style_names: the names the indices point at.
        part / style: (N,) int64 indices, one per occupied voxel (``AssetGrid.cells`` order).
    """

    part_names: tuple[str, ...]
    style_names: tuple[str, ...]
    part: np.ndarray
    style: np.ndarray

    def names(self) -> tuple[np.ndarray, np.ndarray]:
        """(N,) str arrays: the wanted part label and style of each occupied voxel."""
        return np.asarray(self.part_names, dtype=str)[self.part], np.asarray(self.style_names, dtype=str)[self.style]


def script_of(asset: Asset) -> str | None:
    """The script file an asset's source runs, or None (only ``cad`` sources with ``script`` run code)."""
    return getattr(asset.source, "script", None) if asset.source.kind == "cad" else None


def source_key(loaded: LoadedRecipe, asset: Asset) -> str:
    """What an asset's source-part grid depends on: its source and grid settings, and its input files' stamps."""
    stamps = []
    for name in SOURCE_FILE_FIELDS[asset.source.kind]:
        value = getattr(asset.source, name)
        if value is not None:
            path = loaded.resolve(value)
            stat = path.stat() if path.exists() else None
            stamps.append([str(path), stat and stat.st_mtime_ns, stat and stat.st_size])
    return json.dumps([str(loaded.base_dir), asset.source.model_dump(mode="json"), asset.grid.model_dump(mode="json"),
                       asset.fit.value, stamps])


def load_asset_grid(loaded: LoadedRecipe, index: int, allow_scripts: bool,
                    source_grids: dict[str, tuple[PartGrid, tuple[str, ...]]] | None = None) -> AssetGrid:
    """Source, voxelize and apply the rules of expanded asset ``index``; errors name the recipe field.

    ``source_grids`` (``source_key`` → source-part grid and its warnings) skips the
    source and the voxelizer when nothing they read changed; it is filled here.
    """
    asset = loaded.recipe.assets[index]
    field, _ = loaded.where(index)
    script = script_of(asset)
    if script is not None and not allow_scripts:
        raise StudioError(f"this asset runs the script {script!r}; the painter did not run it",
                          file=loaded.path, field=f"{field}.source.script",
                          hint="start the painter with --allow-scripts to run scripts the recipe names")
    key = source_key(loaded, asset)
    try:
        if source_grids is not None and key in source_grids:
            part_grid, source_warnings = source_grids[key]
        else:
            source = load_source(asset.source, loaded.base_dir)
            part_grid = voxelize(source, asset.grid, asset.fit)
            source_warnings = (*source.warnings, *part_grid.warnings)
            if source_grids is not None:
                source_grids[key] = (part_grid, source_warnings)
        labeled, rule_warnings = apply_regions(part_grid, asset.regions, field=f"{field}.regions")
    except DecollageError as exc:
        raise exc.located(file=loaded.path, field=field) from None
    cells = np.argwhere(part_grid.part != EMPTY)
    return AssetGrid(index, field, asset, part_grid, labeled, cells, (*source_warnings, *rule_warnings))


def relabel(grid: AssetGrid, rules: list[RegionRule]) -> LabeledGrid:
    """The asset's labeled grid under other region rules (same source grid)."""
    labeled, _ = apply_regions(grid.source_grid, rules, field=f"{grid.field}.regions")
    return labeled


def grid_json(grid: AssetGrid) -> dict:
    """What the page needs to draw and edit the coarse grid (see the module docstring for the layout)."""
    at = tuple(grid.cells.T)
    labeled, source = grid.labeled, grid.source_grid
    return {
        "name": grid.asset.name,
        "field": grid.field,
        "variant": grid.asset.variant,
        "shape": list(labeled.shape),
        "voxel_size_m": labeled.voxel_size_m,
        "origin_m": list(labeled.origin_m),
        "cells": grid.cells.ravel().tolist(),
        "source_part_names": list(source.part_names),
        "source_part": source.part[at].tolist(),
        "part_names": list(labeled.part_names),
        "part": labeled.part[at].tolist(),
        "style_names": list(labeled.style_names),
        "style": labeled.style[at].tolist(),
        "palette": palette(labeled.style_names),
        "rules": [r.model_dump(mode="json", by_alias=True, exclude_none=True) for r in grid.asset.regions],
        "detailize": grid.asset.detailize.model_dump(mode="json"),
        "warnings": list(grid.warnings),
    }


def palette(style_names) -> dict[str, list[int]]:
    """Style name → [r, g, b] (0-255): the colours the GLB's vertex colours use (``pipeline/palette.py``)."""
    rows = palette_rgba(tuple(style_names))
    return {name: [int(v) for v in rows[i][:3]] for i, name in enumerate(style_names)}


def parse_target(data: object, grid: AssetGrid) -> Target:
    """Check and convert the page's ``{part_names, style_names, part, style}``; raises StudioError."""
    if not isinstance(data, dict):
        raise StudioError("target: expected an object with part_names, style_names, part and style")
    count = len(grid.cells)
    parsed = {}
    for key in ("part_names", "style_names"):
        names = data.get(key)
        if not isinstance(names, list) or not names or len(names) > 4096:
            raise StudioError(f"target.{key}: expected a non-empty list of names")
        for name in names:
            if not isinstance(name, str) or not _NAME.match(name) or len(name) > 100:
                raise StudioError(f"target.{key}: {name!r} is not a valid name",
                                  hint="letters, digits, '_', '.', '-'; starting with a letter or digit")
        if len(set(names)) != len(names):
            raise StudioError(f"target.{key}: names are repeated")
        parsed[key] = tuple(names)
    for key, names_key in (("part", "part_names"), ("style", "style_names")):
        values = data.get(key)
        if not isinstance(values, list) or len(values) != count:
            raise StudioError(f"target.{key}: expected {count} indices, one per occupied voxel")
        try:
            arr = np.asarray(values, dtype=np.int64)
        except (TypeError, ValueError):
            raise StudioError(f"target.{key}: expected whole numbers") from None
        if arr.ndim != 1 or (count and (arr.min() < 0 or arr.max() >= len(parsed[names_key]))):
            raise StudioError(f"target.{key}: an index is outside its name list")
        parsed[key] = arr
    return Target(parsed["part_names"], parsed["style_names"], parsed["part"], parsed["style"])

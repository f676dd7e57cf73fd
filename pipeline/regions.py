"""Region rules: give every occupied voxel of a source-part grid a part label and a style.

Rules apply in recipe order; a later matching rule overrides an earlier one, so
a catch-all ``parts: ["*"]`` rule usually comes first and specific ones follow.
A voxel matches a rule when its source part name matches one of the rule's
shell-style globs, if the rule has a band, its centre lies in the band
(fractions of the occupied bounding box along the band's axis; ``to = 1`` is
inclusive), and if the rule lists cells, it is one of them ([x, y, z] indices
of the coarse grid). ``@source`` keeps the source's own part name or style.
"""

from __future__ import annotations

import fnmatch
from collections.abc import Sequence

import numpy as np

from core.errors import RecipeError
from core.grid import EMPTY, LabeledGrid
from core.recipe import FROM_SOURCE, RegionRule
from geometry.voxelize import PartGrid

_AXES = {"x": 0, "y": 1, "z": 2}


def _band_mask(occupied: np.ndarray, axis: str, lo_frac: float, hi_frac: float) -> np.ndarray:
    """(X, Y, Z) bool: cells whose centre lies in [lo, hi) of the occupied extent along ``axis``."""
    ax = _AXES[axis]
    other = tuple(i for i in range(3) if i != ax)
    filled = np.flatnonzero(occupied.any(axis=other))
    lo, hi = filled[0], filled[-1] + 1
    t = (np.arange(occupied.shape[ax]) + 0.5 - lo) / (hi - lo)
    inside = (t >= lo_frac) & ((t < hi_frac) | (hi_frac >= 1.0))
    shape = [1, 1, 1]
    shape[ax] = -1
    return np.broadcast_to(inside.reshape(shape), occupied.shape)


def _cells_mask(shape: tuple[int, int, int], cells: Sequence[tuple[int, int, int]], field: str) -> np.ndarray:
    """(X, Y, Z) bool: True at the listed [x, y, z] cells. Raises RecipeError for a cell outside the grid."""
    idx = np.asarray(cells, dtype=np.int64).reshape(-1, 3)
    outside = np.flatnonzero((idx >= np.asarray(shape)).any(axis=1))
    if outside.size:
        first = int(outside[0])
        raise RecipeError(
            f"cell {idx[first].tolist()} is outside the {'×'.join(map(str, shape))} coarse grid",
            field=f"{field}[{first}]",
            hint="the source or grid settings changed since the cells were painted; paint them again",
        )
    mask = np.zeros(shape, dtype=bool)
    mask[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    return mask


def _intern(names: list[str], name: str) -> int:
    if name not in names:
        names.append(name)
    return names.index(name)


def apply_regions(
    grid: PartGrid, rules: Sequence[RegionRule], *, field: str = "regions"
) -> tuple[LabeledGrid, list[str]]:
    """Map source parts to (part label, style) per voxel.

    Args:
        grid: source-part grid from the voxelizer.
        rules: the asset's region rules.
        field: field path of the rules in the recipe, for messages.

    Returns:
        The LabeledGrid (part/style names in order of first use) and warnings.

    Raises:
        RecipeError: an occupied voxel is matched by no rule, or ``@source`` asks
            for a style the source does not carry.
    """
    occupied = grid.part != EMPTY
    part_idx = np.full(grid.part.shape, EMPTY, dtype=np.int16)
    style_idx = np.full(grid.part.shape, EMPTY, dtype=np.int16)
    part_names: list[str] = []
    style_names: list[str] = []
    warnings: list[str] = []

    for r, rule in enumerate(rules):
        matched_parts = [
            i for i, name in enumerate(grid.part_names) if any(fnmatch.fnmatchcase(name, g) for g in rule.parts)
        ]
        if not matched_parts:
            warnings.append(
                f"{field}[{r}].parts {rule.parts} match no source part (source parts: {list(grid.part_names)})"
            )
            continue
        mask = np.isin(grid.part, matched_parts)
        band = rule.band_range()
        if band is not None:
            mask &= _band_mask(occupied, band.axis, band.from_, band.to)
        if rule.cells is not None:
            mask &= _cells_mask(grid.part.shape, rule.cells, f"{field}[{r}].cells")
        if not mask.any():
            warnings.append(f"{field}[{r}] matches no voxel")
            continue

        if rule.part == FROM_SOURCE:
            lut = np.array([_intern(part_names, n) for n in grid.part_names], dtype=np.int16)
            part_idx[mask] = lut[grid.part[mask]]
        else:
            part_idx[mask] = _intern(part_names, rule.part)

        if rule.style == FROM_SOURCE:
            if grid.style is None:
                raise RecipeError(
                    "style '@source' but this source carries no styles",
                    field=f"{field}[{r}].style",
                    hint="name a style, or give the .npz a 'style' array",
                )
            src = grid.style[mask]
            if np.any(src == EMPTY):
                raise RecipeError(
                    "style '@source' but some matched voxels have no style in the input",
                    field=f"{field}[{r}].style",
                    hint="give every occupied voxel a style in the .npz, or name a style",
                )
            lut = np.array([_intern(style_names, n) for n in grid.style_names], dtype=np.int16)
            style_idx[mask] = lut[src]
        else:
            style_idx[mask] = _intern(style_names, rule.style)

    uncovered = occupied & (part_idx == EMPTY)
    if uncovered.any():
        missing = sorted({grid.part_names[i] for i in np.unique(grid.part[uncovered])})
        raise RecipeError(
            f"{int(uncovered.sum())} voxels of source parts {missing} are matched by no region rule",
            field=field,
            hint="add a first rule with parts: ['*'] as a catch-all",
        )
    labeled = LabeledGrid(
        occupancy=occupied,
        part=part_idx,
        style=style_idx,
        part_names=tuple(part_names),
        style_names=tuple(style_names),
        voxel_size_m=grid.voxel_size_m,
        origin_m=grid.origin_m,
    )
    return labeled, warnings

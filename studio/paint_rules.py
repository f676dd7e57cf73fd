"""Paint → region rules: the fewest edits to an asset's rules that give every voxel the painted part and style.

Role: the painter's compiler (pure: numpy arrays in, rule edits out). Given an
asset's source-part grid, its region rules and the page's target (the part
label and style wanted on each occupied voxel, ``studio/paint_grid.py``), it
returns ``RuleEdits``:

1. a rule whose voxels (those where it is the last matching rule) all want the
   same new part and style is changed in place (``regions[2].style: pagoda →
   temple``), so the recipe reads as the user thinks of it;
2. the voxels still wrong are grouped by the part and style they want; a group
   that covers whole source parts becomes ``{parts: [roof], part, style}``, the
   rest ``{parts: ["*"], cells: [[x, y, z], ...], part, style}`` (coarse grid
   indices, as ``pipeline/regions.py`` reads them);
3. the result is checked by applying the edited rules (``pipeline/regions.py``):
   they must give exactly the target, else StudioError.

The appended rules only touch voxels that want their part and style, so their
order does not matter; they go after the existing rules (later rules win).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from core.errors import RecipeError, StudioError
from core.grid import EMPTY
from core.recipe import FROM_SOURCE, RegionRule
from geometry.voxelize import PartGrid
from pipeline.regions import apply_regions

_GLOB_CHARS = re.compile(r"[*?\[\]]")


@dataclass(frozen=True)
class RuleEdits:
    """Changes to one asset's ``regions`` list.

    Attributes:
        changed: rule index → the keys to set on that rule (``{"style": "temple"}``).
        appended: new rules as plain dicts, in recipe key order (parts, cells, part, style).
    """

    changed: dict[int, dict[str, str]] = field(default_factory=dict)
    appended: list[dict] = field(default_factory=list)

    @property
    def empty(self) -> bool:
        return not self.changed and not self.appended

    def apply(self, rules: list[RegionRule]) -> list[RegionRule]:
        """The rules with these edits made."""
        out = [r.model_copy(update=self.changed[i]) if i in self.changed else r for i, r in enumerate(rules)]
        return out + [RegionRule.model_validate(d) for d in self.appended]

    def describe(self, rules: list[RegionRule], field_prefix: str = "regions") -> list[str]:
        """One line per edit, e.g. ``regions[2].style: pagoda → temple`` or ``+ regions[3]: 4 cells → top/druse``."""
        lines = []
        for i, keys in sorted(self.changed.items()):
            for key, value in keys.items():
                lines.append(f"{field_prefix}[{i}].{key}: {getattr(rules[i], key)} → {value}")
        for j, rule in enumerate(self.appended, start=len(rules)):
            what = f"{len(rule['cells'])} cells" if "cells" in rule else "parts " + ", ".join(rule["parts"])
            lines.append(f"+ {field_prefix}[{j}]: {what} → part {rule['part']}, style {rule['style']}")
        return lines


def labels_of(grid: PartGrid, rules: list[RegionRule]) -> tuple[np.ndarray, np.ndarray]:
    """(N,) str arrays: the part label and style the rules give each occupied voxel (C order)."""
    labeled, _ = apply_regions(grid, rules)
    occupied = grid.part != EMPTY
    parts = np.asarray(labeled.part_names, dtype=str)[labeled.part[occupied]]
    styles = np.asarray(labeled.style_names, dtype=str)[labeled.style[occupied]]
    return parts, styles


def owners(grid: PartGrid, rules: list[RegionRule]) -> np.ndarray:
    """(N,) int: index of the last rule matching each occupied voxel (the one that decides its labels)."""
    marked = [r.model_copy(update={"style": f"r{i}", "part": "p"}) for i, r in enumerate(rules)]
    labeled, _ = apply_regions(grid, marked)
    names = np.asarray([int(n[1:]) for n in labeled.style_names], dtype=np.int64)
    return names[labeled.style[grid.part != EMPTY]]


def compile_edits(grid: PartGrid, rules: list[RegionRule], want_part: np.ndarray, want_style: np.ndarray) -> RuleEdits:
    """The edits to ``rules`` after which every occupied voxel has ``want_part`` / ``want_style``.

    Args:
        grid: the asset's source-part grid.
        rules: its current region rules (they must cover every occupied voxel).
        want_part / want_style: (N,) str, one per occupied voxel in C order.

    Raises:
        StudioError: no edit reproduces the target (a bug) or a name is not a valid label.
    """
    have_part, have_style = labels_of(grid, rules)
    if np.array_equal(have_part, want_part) and np.array_equal(have_style, want_style):
        return RuleEdits()
    changed = _in_place(grid, rules, want_part, want_style)
    edits = RuleEdits(changed, [])
    have_part, have_style = labels_of(grid, edits.apply(rules))
    edits = RuleEdits(changed, _appended(grid, have_part, have_style, want_part, want_style))
    if _reproduces(grid, edits.apply(rules), want_part, want_style):
        return edits
    # Never expected; the plainest form (cells only, no rule changed) is the fallback.
    have_part, have_style = labels_of(grid, rules)
    fallback = RuleEdits({}, _appended(grid, have_part, have_style, want_part, want_style, whole_parts=False))
    if _reproduces(grid, fallback.apply(rules), want_part, want_style):
        return fallback
    raise StudioError("the painted labels cannot be written as region rules (please report it)")


def _in_place(grid: PartGrid, rules: list[RegionRule], want_part: np.ndarray, want_style: np.ndarray) -> dict:
    owner = owners(grid, rules)
    changed: dict[int, dict[str, str]] = {}
    for i, rule in enumerate(rules):
        mine = owner == i
        if not mine.any():
            continue
        parts, styles = np.unique(want_part[mine]), np.unique(want_style[mine])
        if len(parts) != 1 or len(styles) != 1:
            continue
        keys = {}
        for key, value in (("part", str(parts[0])), ("style", str(styles[0]))):
            current = getattr(rule, key)
            if value != current:
                if current == FROM_SOURCE:
                    keys = {}
                    break
                keys[key] = value
        if keys:
            changed[i] = keys
    return changed


def _appended(grid: PartGrid, have_part, have_style, want_part, want_style, whole_parts: bool = True) -> list[dict]:
    occupied = grid.part != EMPTY
    cells = np.argwhere(occupied)
    source = grid.part[occupied]
    wrong = (have_part != want_part) | (have_style != want_style)
    appended = []
    for part, style in sorted({(str(p), str(s)) for p, s in zip(want_part[wrong], want_style[wrong])}):
        wants = (want_part == part) & (want_style == style)
        group = wrong & wants
        whole = []
        if whole_parts:
            for k in np.unique(source[group]):
                name = grid.part_names[k]
                if wants[source == k].all() and not _GLOB_CHARS.search(name):
                    whole.append(int(k))
        if whole:
            appended.append({"parts": [grid.part_names[k] for k in sorted(whole)], "part": part, "style": style})
            group &= ~np.isin(source, whole)
        if group.any():
            appended.append({"parts": ["*"], "cells": cells[group].tolist(), "part": part, "style": style})
    for rule in appended:
        try:
            RegionRule.model_validate(rule)
        except ValueError as exc:
            raise StudioError(f"cannot write the rule {rule['part']}/{rule['style']}: {exc}") from None
    return appended


def _reproduces(grid: PartGrid, rules: list[RegionRule], want_part: np.ndarray, want_style: np.ndarray) -> bool:
    try:
        parts, styles = labels_of(grid, rules)
    except RecipeError:
        return False
    return bool(np.array_equal(parts, want_part) and np.array_equal(styles, want_style))

"""The ``vox`` source: a MagicaVoxel / Goxel ``.vox`` file → ``PartVoxels``, +Y up.

A voxel artist paints parts with palette colours; the recipe says which
palette indices (1..255, as the editor's palette shows them) make which part,
and optionally which style::

    source:
      kind: vox
      path: house.vox
      parts: {body: [1, 2], roof: [3]}      # default: one part per index, named palette_<index>
      styles: {cottage: [1, 3], tower: [2]} # optional; then regions keep them with style: '@source'
      ignore: [255]                         # optional: indices whose voxels are dropped

Every occupied voxel's index must be mapped (or ignored): an unmapped one is
an error naming the palette index, its colour and how many voxels use it. A
mapped index no voxel uses is a warning.

Models (``spec.model``): a file may hold several models placed by transform
nodes (MagicaVoxel's outliner). With one model instance it is read as is
(its rotation, if any, applied). With several, the file is refused, listing
them, unless ``model`` picks one by index (scene order, 0-based) or name, or
is ``'@all'``: every visible instance merged where the scene places it
(``sources/vox_file.py``: translation and rotation composed from the root;
later instances win where they overlap). A file without a scene graph (old
version 150 with several models) cannot be merged: the models have no
placement. To make one asset per model, use a variant matrix over ``model``.

The file's frame is MagicaVoxel's (x right, y back, z up, front -Y), turned
into the canonical frame by ``up_axis`` (default ``z``) exactly like the
``voxels`` source does. Errors are ``SourceError`` with the field they concern
(``path``, ``model``, ``parts``, ``styles``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from core.errors import SourceError
from core.files import InputKind, input_file, read_input_bytes
from core.grid import EMPTY
from core.recipe import ALL_MODELS, VoxSource
from sources.base import PartVoxels
from sources.vox_file import MAX_PLACED_VOXELS, VoxScene, dense, place, read_vox
from sources.voxels import rotate_grid


def preflight(spec: VoxSource, base_dir: Path) -> None:
    """Checks before building: a regular ``.vox`` file within the vox size limit (nothing parsed)."""
    _resolve(spec.path, base_dir)


def _resolve(relative: str, base_dir: Path) -> Path:
    path = input_file(relative, base_dir, field="path", noun="file", hint="name a .vox file", kind=InputKind.VOX)
    if path.suffix.lower() != ".vox":
        raise SourceError(f"unsupported format {path.suffix or '(no extension)'!r} for a vox source", field="path",
                          hint="name a MagicaVoxel .vox file (or use kind: voxels for .npy/.npz)")
    return path


def load(spec: VoxSource, base_dir: Path) -> PartVoxels:
    """Read ``spec.path`` (relative to ``base_dir``) into a ``PartVoxels`` in the canonical frame."""
    path = _resolve(spec.path, base_dir)
    scene = read_vox(read_input_bytes(path, InputKind.VOX, field="path"))
    grid, warnings = select_model(scene, spec.model)
    part, part_names, style, style_names, more = map_palette(grid, scene.palette, spec)
    return PartVoxels(
        part=rotate_grid(part, spec.up_axis),
        part_names=part_names,
        voxel_size_m=float(spec.voxel_size_m),
        style=None if style is None else rotate_grid(style, spec.up_axis),
        style_names=style_names,
        warnings=[f"{path.name}: {w}" for w in (*scene.notes, *warnings, *more)],
        input_files=[path],
    )


# --------------------------------------------------------------------------- models


def describe_models(scene: VoxScene) -> str:
    """One line listing the instances: ``0: 'house' 16×16×20, 1: 'tree' 5×5×9 (hidden)``."""
    items = []
    for i, inst in enumerate(scene.instances[:12]):
        size = "×".join(map(str, scene.models[inst.model].size))
        items.append(f"{i}: {inst.name!r} {size}" if inst.name else f"{i}: {size}")
        if inst.hidden:
            items[-1] += " (hidden)"
    more = len(scene.instances) - len(items)
    return ", ".join(items) + (f", and {more} more" if more > 0 else "")


def select_model(scene: VoxScene, choice: int | str | None) -> tuple[np.ndarray, list[str]]:
    """(X, Y, Z) uint8 palette indices (0 empty) of the chosen instance(s), in the file's frame; and warnings."""
    instances = scene.instances
    listing = f"the file's models: {describe_models(scene)}"
    if choice is None:
        if len(instances) != 1:
            raise SourceError(f"the file has {len(instances)} models and the recipe does not say which to read "
                              f"({listing})", field="model",
                              hint="set model: <index or name> for one, model: '@all' to merge them as placed, "
                                   "or a variant matrix over model for one asset each")
        chosen = [instances[0]]
    elif choice == ALL_MODELS:
        if not scene.placed and len(scene.models) > 1:
            raise SourceError(f"the file has {len(scene.models)} models but no scene graph placing them, so they "
                              "cannot be merged", field="model", hint="pick one with model: <index>")
        chosen = [inst for inst in instances if not inst.hidden] or list(instances)
    elif isinstance(choice, int):
        if choice >= len(instances):
            raise SourceError(f"model {choice} does not exist ({listing})", field="model",
                              hint=f"indices go from 0 to {len(instances) - 1}")
        chosen = [instances[choice]]
    else:
        chosen = [inst for inst in instances if inst.name == choice]
        if len(chosen) != 1:
            problem = "no model is named" if not chosen else f"{len(chosen)} models are named"
            raise SourceError(f"{problem} {choice!r} ({listing})", field="model",
                              hint="use a unique name, or the model's index")
    total = sum(len(scene.models[inst.model].voxels) for inst in chosen)
    if total > MAX_PLACED_VOXELS:
        raise SourceError(f"the chosen models hold {total} voxels, more than {MAX_PLACED_VOXELS} can be read",
                          field="model", hint="pick fewer models with model: <index or name>")
    rows = [place(scene.models[inst.model], inst) for inst in chosen]
    rows = [r for r in rows if len(r)]
    if not rows:
        raise SourceError("the chosen model has no voxel", field="model", hint=listing)
    grid, _origin = dense(np.concatenate(rows))
    warnings = []
    if choice == ALL_MODELS and len(chosen) < len(instances):
        warnings.append(f"{len(instances) - len(chosen)} hidden model(s) left out of the merge")
    return grid, warnings


# --------------------------------------------------------------------------- palette → parts and styles


def _colour(palette: np.ndarray | None, index: int) -> str:
    return "" if palette is None else "#" + "".join(f"{int(c):02x}" for c in palette[index][:3]) + ", "


def _lookup(mapping: dict[str, list[int]], used: np.ndarray, counts: np.ndarray, palette, what: str,
            ignored: set[int]) -> tuple[np.ndarray, tuple[str, ...], list[str]]:
    """(256,) int16 table palette index → label index (EMPTY if unmapped), the label names, warnings."""
    names = tuple(mapping)
    table = np.full(256, EMPTY, dtype=np.int16)
    for label, indices in enumerate(mapping.values()):
        table[indices] = label
    for index, count in zip(used, counts):
        if table[index] == EMPTY and int(index) not in ignored:
            mapped = sorted(int(i) for i in np.flatnonzero(table != EMPTY))
            raise SourceError(
                f"palette index {int(index)} ({_colour(palette, int(index))}{int(count)} voxels) is mapped to no "
                f"{what} (mapped: {', '.join(map(str, mapped)) or 'none'})", field=f"{what}s",
                hint=f"add {int(index)} to a {what}'s list in '{what}s', or to 'ignore'")
    present = set(int(i) for i in used)
    warnings = [f"palette index {i} ({what} '{names[table[i]]}') is used by no voxel"
                for i in np.flatnonzero(table != EMPTY) if int(i) not in present]
    return table, names, warnings


def map_palette(grid: np.ndarray, palette: np.ndarray | None, spec: VoxSource):
    """Palette indices (X, Y, Z) uint8 → (part int16, part names, style int16 | None, style names, warnings)."""
    ignored = set(spec.ignore)
    used, counts = np.unique(grid[grid > 0], return_counts=True)
    if not [i for i in used if int(i) not in ignored]:
        raise SourceError("no voxel is left: every palette index used is ignored" if used.size else
                          "the model has no voxel", field="ignore" if used.size else "path")
    parts = spec.parts
    if parts is None:
        parts = {f"palette_{int(i)}": [int(i)] for i in used if int(i) not in ignored}
    part_table, part_names, warnings = _lookup(parts, used, counts, palette, "part", ignored)
    part = part_table[grid]  # index 0 (empty) maps to EMPTY: table[0] is never set
    style, style_names = None, ()
    if spec.styles is not None:
        style_table, style_names, more = _lookup(spec.styles, used, counts, palette, "style", ignored)
        style = style_table[grid]
        warnings += more
    return part, part_names, style, style_names, warnings

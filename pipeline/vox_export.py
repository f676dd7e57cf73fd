"""``.vox`` export: an asset's coarse grid and its detailed grid as MagicaVoxel files, to touch up in an editor.

``export.vox: [coarse, fine]`` writes ``<name>.coarse.vox`` and ``<name>.fine.vox``
beside the GLB (written with the asset's other files, all or nothing).

- **coarse**: the labelled ``LabeledGrid`` exactly. One palette index per
  (part, style) pair the grid uses, coloured by the style (``pipeline/palette.py``),
  darker for later parts. The manifest records the mapping as a ready ``vox``
  source (``parts``/``styles`` → palette indices), so the file comes back as the
  same grid: ``source: {kind: vox, path: <name>.coarse.vox, parts: ..., styles: ...}``
  with ``regions: [{part: '@source', style: '@source'}]``. A side longer than the
  format's 256 is written as several models tiled side by side in the scene
  (read them back with ``model: '@all'``).
- **fine**: the detailizer's grid binarised at ``ISO_LEVEL``, downsampled by the
  smallest integer factor that brings every side to ≤ 256 (a block is filled when
  at least half its fine voxels are), one palette index per style (the style at
  each block's first voxel: styles are constant over a coarse cell). Built block by
  block (``FineVox``), so long assets detailized in blocks get one too.

Files are in MagicaVoxel's frame: the canonical grid (+Y up, front +Z) turned
back by the inverse of the ``vox`` source's ``up_axis: z`` rotation.
"""

from __future__ import annotations

import numpy as np

from core.errors import ExportError
from core.grid import ISO_LEVEL, FineGrid, LabeledGrid
from core.recipe import UpAxis, VoxExport
from pipeline.palette import palette_rgba
from sources.frames import up_axis_rotation
from sources.vox_file import MAX_SIDE, write_vox

#: The frame the files are written in (MagicaVoxel: Z up, front -Y).
FILE_UP = UpAxis.Z


def to_file_frame(grid: np.ndarray, up: UpAxis = FILE_UP) -> np.ndarray:
    """Canonical (X, Y, Z) grid → the file's frame: the inverse of ``sources.voxels.rotate_grid(·, up)``."""
    rotation = up_axis_rotation(up)
    source_axis = [int(np.argmax(np.abs(row))) for row in rotation]
    flips = tuple(a for a in range(3) if rotation[a, source_axis[a]] < 0)
    out = np.flip(grid, axis=flips) if flips else grid
    return np.ascontiguousarray(np.transpose(out, np.argsort(source_axis)))


def _tiles(grid: np.ndarray) -> tuple[list[np.ndarray], list[tuple[int, int, int]]]:
    """Split a grid into ≤ 256-sided blocks and their min corners (one block when it fits)."""
    blocks, corners = [], []
    steps = [range(0, n, MAX_SIDE) for n in grid.shape]
    for x in steps[0]:
        for y in steps[1]:
            for z in steps[2]:
                blocks.append(grid[x:x + MAX_SIDE, y:y + MAX_SIDE, z:z + MAX_SIDE])
                corners.append((x, y, z))
    return blocks, corners


def coarse_vox(grid: LabeledGrid) -> tuple[bytes, dict]:
    """(file bytes, manifest record) of a labelled coarse grid; see the module docstring."""
    occ = grid.occupancy
    pairs = np.unique(np.stack([grid.part[occ], grid.style[occ]], axis=1), axis=0) if occ.any() else np.zeros((0, 2))
    if len(pairs) > 255:
        raise ExportError(f"the coarse grid uses {len(pairs)} (part, style) pairs; a .vox palette holds 255",
                          hint="leave 'coarse' out of export.vox for this asset")
    index = np.zeros((len(grid.part_names) + 1, len(grid.style_names) + 1), dtype=np.uint8)
    styles_rgba = palette_rgba(grid.style_names)
    palette = np.zeros((256, 4), dtype=np.uint8)
    parts: dict[str, list[int]] = {}
    styles: dict[str, list[int]] = {}
    for i, (p, s) in enumerate(pairs.tolist(), start=1):
        index[p, s] = i
        shade = 1.0 - 0.18 * (p % 4)
        palette[i] = (*(styles_rgba[s, :3] * shade).astype(np.uint8), 255)
        parts.setdefault(grid.part_names[p], []).append(i)
        styles.setdefault(grid.style_names[s], []).append(i)
    labels = np.where(occ, index[grid.part.clip(0), grid.style.clip(0)], 0).astype(np.uint8)
    blocks, corners = _tiles(to_file_frame(labels))
    data = write_vox(blocks, palette, positions=corners)
    record = {"models": len(blocks), "shape": list(to_file_frame(labels).shape), "up_axis": FILE_UP.value,
              "source": {"kind": "vox", "parts": parts, "styles": styles,
                         **({"model": "@all"} if len(blocks) > 1 else {})}}
    return data, record


class FineVox:
    """The fine ``.vox`` of a detailed grid, built block by block along x (``add``), so that an asset
    detailized in blocks (``pipeline/chunks.py``: its whole fine grid never exists) gets one too.

    The grid is downsampled by ``factor``, the smallest integer that brings every side to ≤ 256: a cell is
    filled when at least half of its factor³ fine voxels are solid (beyond the grid counts as empty), and
    takes the style of its first fine voxel. Holds the downsampled grid only (≤ 256³ counts).
    """

    def __init__(self, fine_shape: tuple[int, int, int], style_names: tuple[str, ...]) -> None:
        if len(style_names) > 255:
            raise ExportError(f"the asset has {len(style_names)} styles; a .vox palette holds 255",
                              field="export.vox", hint="use vox: [coarse], or fewer styles")
        self.factor = max(1, -(-max(fine_shape) // MAX_SIDE))
        self.fine_shape = tuple(int(n) for n in fine_shape)
        self.style_names = tuple(style_names)
        shape = tuple(-(-n // self.factor) for n in self.fine_shape)
        self.counts = np.zeros(shape, dtype=np.int32)
        self.style = np.zeros(shape, dtype=np.int16)

    def add(self, x0: int, occupancy: np.ndarray, style: np.ndarray) -> None:
        """Fine columns ``x0 …`` of the grid: (W, Y, Z) float32 occupancy and int16 style (any order of blocks,
        each column once)."""
        f = self.factor
        solid = occupancy >= ISO_LEVEL
        lead = x0 % f  # the block's first column sits this far into its downsampled cell
        cells = -(-(lead + solid.shape[0]) // f)
        y, z = self.counts.shape[1], self.counts.shape[2]
        padded = np.zeros((cells * f, y * f, z * f), dtype=bool)
        padded[lead:lead + solid.shape[0], :solid.shape[1], :solid.shape[2]] = solid
        first = x0 // f
        self.counts[first:first + cells] += padded.reshape(cells, f, y, f, z, f).sum(axis=(1, 3, 5),
                                                                                         dtype=np.int32)
        own = -(-x0 // f)  # the first downsampled cell whose first column is in this block
        sampled = style[own * f - x0::f, ::f, ::f]
        self.style[own:own + len(sampled)] = sampled

    def encode(self) -> tuple[bytes, dict]:
        """(file bytes, manifest record) once every column was added."""
        filled = 2 * self.counts >= self.factor ** 3
        palette = np.zeros((256, 4), dtype=np.uint8)
        n = len(self.style_names)
        palette[1:n + 1] = palette_rgba(self.style_names)[:n]
        labels = np.where(filled, np.clip(self.style, 0, max(n - 1, 0)) + 1, 0).astype(np.uint8)
        labels = to_file_frame(labels)
        data = write_vox([labels], palette)
        record = {"downsample": self.factor, "shape": list(labels.shape), "up_axis": FILE_UP.value,
                  "palette": {str(i + 1): name for i, name in enumerate(self.style_names)}}
        return data, record


def fine_vox(fine: FineGrid) -> tuple[bytes, dict]:
    """(file bytes, manifest record) of a whole detailed grid (``FineVox`` with one block)."""
    writer = FineVox(fine.shape, fine.style_names)
    writer.add(0, fine.occupancy, fine.style)
    return writer.encode()


def vox_files(kinds, grid: LabeledGrid, fine: FineVox | None, stem: str) -> tuple[list[tuple], dict]:
    """The export jobs ``(kind, file name, () → bytes)`` and the manifest's ``vox`` record for ``export.vox``.

    The bytes are made here (the records need them); the jobs hand them over. ``fine`` holds the detailed
    grid's blocks (``FineVox``; needed when ``kinds`` has ``fine``).
    """
    jobs, record = [], {}
    for kind in (VoxExport(k) for k in kinds):
        if kind == VoxExport.FINE and fine is None:
            raise ValueError("a fine .vox needs the FineVox the blocks were added to")
        data, info = coarse_vox(grid) if kind == VoxExport.COARSE else fine.encode()
        jobs.append((f"vox_{kind.value}", f"{stem}.{kind.value}.vox", lambda data=data: data))
        record[kind.value] = info
    return jobs, record

"""``quilt``: the example-based, non-learned detailizer (pipeline ``Detailizer`` protocol).

Turns a coarse ``LabeledGrid`` (X, Y, Z) into a ``FineGrid`` (16X, 16Y, 16Z)
by copying the real fine blocks of the style exemplars assigned to each
region, chosen coherently so that neighbouring cells mostly continue each
other in the exemplar. No training: any style set works, built-in or
imported, as soon as it is built.

Pipeline per grid:

1. map the grid's style names to the set's exemplars and its part names to
   the set's vocabulary (``model.quilt.sets``);
2. the library of the exemplars used (``model.quilt.library``: stats cached
   on disk per set digest, tables per exemplar kept in memory);
3. the coherent source field (``model.quilt.field``);
4. the blended, confined fine field (``model.quilt.assemble``);
5. structure repair: every occupied cell keeps material and no fragment floats
   (``model.quilt.repair``).

Styles in the output are the input's style indices, nearest-upsampled to every
fine voxel (empty ones take the nearest occupied cell's style). ``extras``
records the seed, the set, the continuation fraction and the repairs.
Deterministic for a given (grid, set, seed), whatever the number of threads.

Cost (``benchmarks/bench_quilt.py speed``/``long``, 2 shared cores at load ~11): a 16³ → 256³
detailization 0.5–0.7 s CPU (2.0–2.4 s wall under that load; upsample 0.15 s CPU, the shipped
model 1.1–1.6 s CPU); the library of a 20-exemplar set 7.8 s CPU once (stats then read from the
disk cache in 0.16 s); peak RSS 0.57 GB; a 367×21×6 word in 40 s and 1.5 GB (upsample 1.2 GB).
"""

from __future__ import annotations

from collections import OrderedDict
from pathlib import Path

import numpy as np
from scipy import ndimage

from core.grid import UPSAMPLE_FACTOR, FineGrid, LabeledGrid
from model.quilt import assemble as asm
from model.quilt import field, repair, search
from model.quilt import library as libm
from model.quilt.sets import accepted_parts, check_set, map_parts, map_styles, resolve_style_set
from stylesets.format import StyleSet

#: Padded fine exemplars kept in memory (≈ 18 MB each at 256³).
FINE_CACHE = 8


class QuiltDetailizer:
    """Example-based detailizer over a style set (see module docstring).

    Args:
        checkpoint: the style set: a built-in name, an imported set's name or a ``.npz`` file
            (None: ``sets.DEFAULT_SET``); a recipe names it with ``detailize.style_set``. Named ``checkpoint`` because the pipeline passes a
            detailizer's data file under that name.
        device: ignored (CPU only); accepted for the pipeline's factory signature.
        style_set: an already loaded set (tests, benchmarks); overrides ``checkpoint``.
    Raises:
        DetailizeError: unknown or unreadable set, a set without exemplars.
    """

    name = "quilt"
    learned = False

    def __init__(self, checkpoint: str | Path | None = None, device: str = "auto",
                 style_set: StyleSet | None = None) -> None:
        del device
        self.style_set = style_set if style_set is not None else resolve_style_set(checkpoint)
        check_set(self.style_set)
        self.style_names: tuple[str, ...] | None = tuple(ex.name for ex in self.style_set.exemplars)
        self.part_names: tuple[str, ...] | None = accepted_parts(self.style_set)
        self._stats: list[libm.ExemplarStats] | None = None
        self._tables: dict[int, libm.ExemplarTable] = {}
        self._fine: OrderedDict[int, np.ndarray] = OrderedDict()

    # ------------------------------------------------------------------ protocol

    @property
    def input_files(self) -> tuple[Path, ...]:
        """The style set file it copies from (a build records it in each asset's input closure)."""
        return (Path(self.style_set.path).resolve(),) if self.style_set.path else ()

    def describe(self) -> dict:
        s = self.style_set
        return {
            "name": self.name, "learned": False, "method": "example-based block quilting (non-learned)",
            "style_set": s.name, "style_set_path": str(s.path) if s.path else None,
            "style_set_hash": s.inputs_hash, "code_version": libm.CODE_VERSION,
            "factor": UPSAMPLE_FACTOR, "halo": asm.HALO, "sigma": asm.SIGMA, "iterations": search.ITERATIONS,
            "style_names": list(self.style_names or ()),
        }

    def detailize(self, grid: LabeledGrid, seed: int = 0) -> FineGrid:
        """LabeledGrid (X, Y, Z) → FineGrid (16X, 16Y, 16Z), occupancy float32 in [0, 1].

        Raises:
            DetailizeError: a style or part name the set does not have.
        """
        f = UPSAMPLE_FACTOR
        occ = grid.occupancy
        extras: dict = {"seed": int(seed), "style_set": self.style_set.name}
        if not occ.any():
            fine = np.zeros(tuple(n * f for n in grid.shape), dtype=np.float32)
        else:
            fine, info = self._run(grid, int(seed))
            extras.update(info)
        return FineGrid(occupancy=fine, style=_fine_styles(grid, f), style_names=grid.style_names,
                        voxel_size_m=grid.voxel_size_m / f, origin_m=grid.origin_m, detailizer=self.name,
                        extras=extras)

    def prepare(self, grid: LabeledGrid) -> None:
        """Load the tables and smoothed exemplars of the styles ``grid`` uses (the ``prepare`` part of the
        protocol: a block process forked afterwards inherits them; ≈ 0.3 s per 256³ exemplar on first use).

        Raises:
            DetailizeError: a style or part name the set does not have (as ``detailize`` would).
        """
        if not grid.occupancy.any():
            return
        used = self._set_indices(grid)[2]
        self._load_tables(used)
        self.fine_sources(tuple(used[-FINE_CACHE:]))

    # ------------------------------------------------------------------ steps

    def _set_indices(self, grid: LabeledGrid) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """The set's indices for a non-empty grid: part index → vocabulary part, (X, Y, Z) exemplar per cell
        (−1 empty), and the exemplars used, ascending.

        Raises:
            DetailizeError: a style or part name the set does not have.
        """
        occ = grid.occupancy
        style_ex = map_styles(grid.style_names, np.unique(grid.style[occ]), self.style_set)
        part_voc = map_parts(grid.part_names, np.unique(grid.part[occ]), self.style_set)
        ex_grid = np.where(occ, style_ex[np.clip(grid.style, 0, None)], -1)
        return part_voc, ex_grid, [int(e) for e in np.unique(ex_grid[occ])]

    def source_field(self, grid: LabeledGrid, seed: int = 0):
        """(content, library, search result) of a non-empty grid: the search without the assembly."""
        occ = grid.occupancy
        part_voc, ex_grid, used = self._set_indices(grid)
        lib = self.library(used)
        table_of = np.full(len(self.style_set.exemplars), -1, dtype=np.int64)
        table_of[used] = np.arange(len(used))
        table_grid = np.where(occ, table_of[np.clip(ex_grid, 0, None)], -1)
        part_grid = np.where(occ, part_voc[np.clip(grid.part, 0, None)], -1)
        content = search.make_content(occ, table_grid, part_grid)
        return content, lib, field.search(content, lib, seed)

    def library(self, exemplars: list[int]) -> libm.Library:
        """The search library over the given exemplars (set indices), from cached stats and tables."""
        self._load_tables(exemplars)
        return libm.combine([self._tables[e] for e in exemplars], exemplars)

    def _load_tables(self, exemplars: list[int]) -> None:
        """The stats of the set (disk cache) and the tables of ``exemplars`` (set indices), kept in memory."""
        if self._stats is None:
            self._stats = libm.load_stats(self.style_set)
        for e in exemplars:
            if e not in self._tables:
                self._tables[e] = libm.build_table(self._stats[e])

    def fine_sources(self, exemplars: tuple[int, ...]) -> list[np.ndarray]:
        """Smoothed, padded fine occupancy of each exemplar (kept for the last ``FINE_CACHE`` used)."""
        out = []
        for e in exemplars:
            if e in self._fine:
                self._fine.move_to_end(e)
            else:
                ex = self.style_set.exemplars[e]
                self._fine[e] = asm.smooth_source(ex.labels, ex.offset, self.style_set.resolution)
                while len(self._fine) > FINE_CACHE:
                    self._fine.popitem(last=False)
            out.append(self._fine[e])
        return out

    def _run(self, grid: LabeledGrid, seed: int) -> tuple[np.ndarray, dict]:
        content, lib, result = self.source_field(grid, seed)
        fine = asm.assemble(content, lib, self.fine_sources(lib.exemplars), result.field)
        fixes = repair.repair(fine, content.occ)
        info = {"continuation": round(result.continuation, 4), "energy": round(result.energies[-1], 1),
                **fixes}
        return fine, info


def _fine_styles(grid: LabeledGrid, f: int) -> np.ndarray:
    """(fX, fY, fZ) int16: every fine voxel takes its coarse cell's style, empty cells the nearest occupied one's."""
    if grid.occupancy.any():
        _, (ix, iy, iz) = ndimage.distance_transform_edt(~grid.occupancy, return_indices=True)
        coarse = grid.style[ix, iy, iz].astype(np.int16)
    else:
        coarse = np.zeros(grid.shape, dtype=np.int16)
    x, y, z = coarse.shape
    view = np.broadcast_to(coarse[:, None, :, None, :, None], (x, f, y, f, z, f))
    return view.reshape(x * f, y * f, z * f)

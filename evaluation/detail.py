"""LP-detail, style specificity and the paper's LP figures, from one streamed patch search.

Why (``reference/detail-metrics.md``): at ×16 a 12³ patch is smaller than one
coarse cell, so most surface patches of blurred blocks are flat faces or
straight rounded edges — *extrusions* — that every exemplar also has, and the
paper's LP-IOU rewards them. Definitions here, per output:

* ``N_PATCHES`` seeded surface patches (``evaluation/patches.py``);
* a patch is an **extrusion** when it is constant along at least one axis
  (every slice along that axis equal); flat faces, straight edges and empty
  or full patches are;
* each patch belongs to the region of the coarse cell holding its centre
  voxel (empty cells take the nearest occupied cell's style): its *assigned
  exemplar* is that region's style;
* **LP-detail** = fraction of the sampled patches that are not extrusions and
  match (IOU > 0.95) some patch of their assigned exemplar; *LP-detail (all)*
  the same against every exemplar; *LP-detail (other)* against the exemplars
  of the other categories than the assigned one's;
* **style specificity** = LP-detail − LP-detail (other): positive when the
  detail is the assigned style's, not texture any category has;
* the paper's **LP-IOU** (every patch, every exemplar) and **LP-F**
  (surface F-score, bounded search: a lower bound, see
  ``evaluation/detail_index.py``) come from the same search, for comparison only.

Cost: patches of every output are gathered first (``PatchRecords.add``, 1000
packed rows an output), then the exemplars are visited one at a time
(``match_all``: build its table, search every output's patches that still
need it, drop the table), so memory holds one exemplar's table, and work is
bounded per patch and exemplar.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from evaluation.detail_index import (
    PatchBank,
    Queries,
    SearchStats,
    exemplar_patches,
    f_matches,
    iou_matches,
    make_queries,
    packed_patch_words,
)
from evaluation.patch_index import _PACKED
from evaluation.patches import N_PATCHES, PATCH_SIZE, as_bool_tensor, sample_surface_patches

#: Centre voxel of a patch relative to its candidate position (the patch is [p − 5, p + 7)).
_CENTRE_OFFSET = 1


def is_extrusion(occ_bits: np.ndarray) -> np.ndarray:
    """(m,) bool: packed (m, 216) patches that are constant along at least one axis.

    A patch P (12, 12, 12) is constant along axis a when every slice along a
    equals the first one; empty and full patches are too.
    """
    p = np.unpackbits(occ_bits, axis=1).reshape(-1, PATCH_SIZE, PATCH_SIZE, PATCH_SIZE).astype(bool)
    out = np.zeros(len(p), dtype=bool)
    for axis in (1, 2, 3):
        first = np.take(p, [0], axis=axis)
        out |= (p == first).all(axis=(1, 2, 3))
    return out


def region_exemplars(grid, style_index: dict[str, int]) -> np.ndarray:
    """(X, Y, Z) int16: the exemplar index of every coarse cell's style (empty cells: the nearest occupied one's).

    Args:
        grid: the output's coarse ``LabeledGrid``.
        style_index: style name → exemplar index in the bank.
    """
    from scipy.ndimage import distance_transform_edt

    lut = np.array([style_index[n] for n in grid.style_names], dtype=np.int16)
    occ = np.asarray(grid.occupancy, dtype=bool)
    styles = np.where(occ, grid.style, 0).astype(np.int64)
    if not occ.all():
        idx = distance_transform_edt(~occ, return_distances=False, return_indices=True)
        styles = styles[tuple(idx)]
    return lut[styles]


def patch_owners(positions: np.ndarray, regions: np.ndarray, factor: int) -> np.ndarray:
    """(m,) int16 assigned exemplar of each patch: the region of the coarse cell of its centre voxel."""
    centre = np.asarray(positions, dtype=np.int64) + _CENTRE_OFFSET
    cells = np.minimum(centre // factor, np.asarray(regions.shape) - 1)
    return regions[cells[:, 0], cells[:, 1], cells[:, 2]].astype(np.int16)


@dataclass
class PatchRecords:
    """Sampled patches of many outputs, concatenated, with what the search has found so far.

    Per patch (row): the output it belongs to, its assigned exemplar, whether it
    is an extrusion; after ``match_all``: own (matches its assigned exemplar),
    other (an exemplar of another category), any (some exemplar), f (LP-F).
    """

    ids: list[str] = field(default_factory=list)
    _parts: list[tuple] = field(default_factory=list)
    queries: Queries | None = None
    output: np.ndarray | None = None
    owner: np.ndarray | None = None
    extrusion: np.ndarray | None = None
    own: np.ndarray | None = None
    other: np.ndarray | None = None
    any: np.ndarray | None = None
    f: np.ndarray | None = None
    stats: SearchStats = field(default_factory=SearchStats)

    def add(self, output_id: str, shape, owners: Callable[[np.ndarray], np.ndarray] | np.ndarray | int,
            seed: int, n: int = N_PATCHES) -> int:
        """Sample ``n`` surface patches of ``shape`` (seeded), pack them and keep them for the search.

        Args:
            output_id: the output's id (a key of ``scores``).
            shape: (X, Y, Z) bool output at the exemplars' resolution.
            owners: the assigned exemplar of every patch: a callable positions → (m,)
                indices, an array, or one index for all.
            seed: sampling seed (the output's protocol index).
        Returns:
            The number of patches sampled (0 for a shape without surface patches).
        """
        occ = as_bool_tensor(shape, "output").cpu()
        pos = sample_surface_patches(occ, n=n, seed=seed)
        own = (owners(pos) if callable(owners) else np.broadcast_to(np.asarray(owners, np.int16), (len(pos),)))
        if len(pos):
            q = make_queries(packed_patch_words(occ), pos)
            self._parts.append((len(self.ids), q, np.asarray(own, np.int16), is_extrusion(q.occ_bits)))
        self.ids.append(output_id)
        return len(pos)

    def _finish(self) -> None:
        parts = self._parts
        cat = (lambda name: np.concatenate([getattr(p[1], name) for p in parts]) if parts else None)
        if parts:
            self.queries = Queries(*(cat(k) for k in ("occ_bits", "occ_count", "occ_desc", "sd_bits", "surf_count",
                                                       "sd_desc")))
        else:
            empty = np.zeros((0, _PACKED), np.uint8)
            self.queries = Queries(empty, np.zeros(0, np.int64), np.zeros((0, 8), np.uint8),
                                   np.zeros((0, 2 * _PACKED), np.uint8), np.zeros(0, np.int64), np.zeros((0, 8), np.uint8))
        self.output = np.concatenate([np.full(len(p[1]), p[0], np.int32) for p in parts]) if parts \
            else np.zeros(0, np.int32)
        self.owner = np.concatenate([p[2] for p in parts]) if parts else np.zeros(0, np.int16)
        self.extrusion = np.concatenate([p[3] for p in parts]) if parts else np.zeros(0, bool)
        m = len(self.queries)
        self.own, self.other, self.any, self.f = (np.zeros(m, bool) for _ in range(4))
        self._parts = []

    def match(self, table, e: int, categories: Sequence[str]) -> None:
        """Search the patches that still need exemplar ``e`` (table ``table``) and record the hits."""
        cats = np.asarray(categories)
        other_cat = cats[self.owner] != categories[e]
        mine = self.owner == e
        need = ~self.any | (mine & ~self.own) | (other_cat & ~self.extrusion & ~self.other)
        hit = iou_matches(self.queries, table, np.nonzero(need)[0], self.stats)
        self.any |= hit
        self.own |= hit & mine
        self.other |= hit & other_cat
        self.f |= f_matches(self.queries, table, np.nonzero(~self.f)[0])

    def scores(self) -> dict[str, dict]:
        """Output id → figures (fractions of its sampled patches; None without patches):
        lp_detail, lp_detail_all, lp_detail_other, specificity, lp_iou, lp_f, own_lp_iou
        (every patch against its assigned exemplar), extrusions, patches."""
        out = {}
        detail = ~self.extrusion
        for k, oid in enumerate(self.ids):
            sel = self.output == k
            n = int(sel.sum())
            if n == 0:
                out[oid] = {"patches": 0, **dict.fromkeys(("lp_detail", "lp_detail_all", "lp_detail_other",
                                                           "specificity", "lp_iou", "lp_f", "own_lp_iou",
                                                           "extrusions"))}
                continue
            mean = (lambda v: float(v[sel].mean()))
            d_own, d_other = mean(detail & self.own), mean(detail & self.other)
            out[oid] = {"patches": n, "lp_detail": d_own, "lp_detail_all": mean(detail & self.any),
                        "lp_detail_other": d_other, "specificity": d_own - d_other, "lp_iou": mean(self.any),
                        "lp_f": mean(self.f), "own_lp_iou": mean(self.own), "extrusions": mean(self.extrusion)}
        return out


def match_all(records: Sequence[PatchRecords], shapes: Callable[[int], np.ndarray], names: Sequence[str],
              categories: Sequence[str], progress: Callable[[str], None] | None = None,
              bank: PatchBank | None = None) -> dict:
    """Search every record's patches against every exemplar, one exemplar table at a time.

    Args:
        records: PatchRecords filled with ``add``.
        shapes: e → (X, Y, Z) bool occupancy of exemplar e (called once per exemplar).
        names, categories: of the exemplars, in bank order (the records' owner indices).
        bank: prebuilt tables (tests); None = build each from ``shapes`` and drop it after use.
    Returns:
        {"tables_s", "search_s", "table_mb_max"}: seconds building tables, seconds searching,
        the largest table in MB.
    """
    for r in records:
        r._finish()
    t_tables = t_search = 0.0
    biggest = 0
    for e, (name, category) in enumerate(zip(names, categories)):
        t0 = time.perf_counter()
        table = bank.tables[e] if bank is not None else exemplar_patches(shapes(e), name, category)
        t1 = time.perf_counter()
        for r in records:
            r.match(table, e, categories)
        t2 = time.perf_counter()
        t_tables += t1 - t0
        t_search += t2 - t1
        biggest = max(biggest, table.nbytes)
        if progress:
            progress(f"  exemplar {e + 1}/{len(names)} {name}: {len(table.occ_count)} + {len(table.surf_count)} "
                     f"patches, {table.nbytes / 1e6:.0f} MB ({t1 - t0:.1f} s table, {t2 - t1:.1f} s search)")
        del table
    return {"tables_s": round(t_tables, 2), "search_s": round(t_search, 2), "table_mb_max": round(biggest / 1e6, 1)}

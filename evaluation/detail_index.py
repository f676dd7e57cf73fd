"""Per-exemplar patch tables and a bounded patch search (the LP-detail and paper-LP matching).

One ``ExemplarPatches`` per style exemplar holds that exemplar's distinct
12³ surface patches (``evaluation/patches.py`` definitions), packed (216 bytes
a patch), with small descriptors in kd-trees:

* occupancy: IOU > 0.95 ⟺ Hamming h < (|A|+|B|)/39 ⟹ h < |A|/19, and the L1
  distance between 6³-octant counts (8 numbers) is at most h, so every match
  lies in the L1 ball of radius |A|/19 around the query's octant vector;
* surface / dilated surface (LP-F): the surface's 8 octant counts.

The search is **bounded**: an exact duplicate is found by a 64-bit row hash;
otherwise a query is checked exactly (packed popcounts) against at most
``K_IOU`` nearest rows inside its ball (IOU), or the ``K_F`` nearest rows (F).
Work is therefore at most queries × exemplars × K rows, whatever the
contents — a query that matches nothing costs the same as one that matches
late, not a scan of the dictionary. (The F candidates are ``K_F`` near surface
descriptors within L1 distance ``F_RADIUS`` · |S_q|, from an approximate kd-tree search.) The IOU search is exact unless the ball
holds more than ``K_IOU`` rows and none of the nearest ``K_IOU`` matches; such
(query, exemplar) pairs are counted as *capped* and reported. The F search is
a lower bound of the exhaustive one (``evaluation/patch_index.py``: exact, no
bound on its cost) and is labelled so wherever it is shown.

Memory: per distinct patch 216 bytes packed + 8·8 bytes of octants (+ the
kd-tree's copy and index) for occupancy, 432 + 16·8 (+ tree) for the surface
pair; tables are built one exemplar at a time (the chunked extraction bounds
the transient memory). ``PatchBank.nbytes`` reports the total.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from evaluation.patch_index import (
    _PACKED,
    _crop_around,
    _hash_index,
    _lookup,
    _octants_from_cells,
    _unique_packed,
    _z_words,
    extract_packed,
    packed_cell_counts,
)
from evaluation.patches import _T_DEN, _T_NUM, as_bool_tensor, surface_and_dilation, surface_candidates

#: Rows checked per (query, exemplar) beyond an exact duplicate: first the nearest ``K_FIRST``,
#: then up to ``K_IOU`` inside the IOU ball; ``K_F`` nearest for the F-score.
K_FIRST: int = 8
K_IOU: int = 256
K_F: int = 32
#: L1 radius of the F candidates, as a fraction of the query's surface voxels (a heuristic: see f_matches).
F_RADIUS: float = 1.0
#: Approximation of the F candidates' kd-tree search (scipy's ``eps``: each returned k-th neighbour is
#: within (1 + eps) of the true k-th distance); 7× faster than exact neighbours on detailed outputs.
F_EPS: float = 1.0
#: Candidate pairs verified at a time (memory ≈ 216 bytes each).
_PAIR_CHUNK = 1 << 16


@dataclass(frozen=True, eq=False)
class ExemplarPatches:
    """The distinct surface patches of one exemplar, ready for bounded matching.

    Attributes:
        name, category: the exemplar's.
        occ_bits: (N1, 216) uint8 packed occupancy patches (distinct).
        occ_count: (N1,) int64 occupied voxels of each.
        occ_tree: scipy cKDTree over their (N1, 8) octant counts.
        occ_hash: sorted 64-bit hashes + row order (exact-duplicate lookups).
        sd_bits: (N2, 432) uint8 packed surface then dilated surface (distinct pairs).
        surf_count: (N2,) int64 surface voxels of each.
        sd_tree: cKDTree over (N2, 8) octant counts of the surface.
        sd_hash: as occ_hash, for sd_bits.
    """

    name: str
    category: str
    occ_bits: np.ndarray
    occ_count: np.ndarray
    occ_tree: object
    occ_hash: tuple[np.ndarray, np.ndarray]
    sd_bits: np.ndarray
    surf_count: np.ndarray
    sd_tree: object
    sd_hash: tuple[np.ndarray, np.ndarray]

    @property
    def nbytes(self) -> int:
        """Bytes held by the tables and trees (a tree: a copy of its points plus an index)."""
        arrays = (self.occ_bits, self.occ_count, self.sd_bits, self.surf_count, *self.occ_hash, *self.sd_hash)
        trees = sum(t.n * (t.m * 8 + 8) for t in (self.occ_tree, self.sd_tree))
        return int(sum(a.nbytes for a in arrays) + trees)


def _cells(bits: np.ndarray, chunk: int = 32768) -> np.ndarray:
    parts = [packed_cell_counts(bits[s : s + chunk]) for s in range(0, len(bits), chunk)]
    return np.concatenate(parts) if parts else np.zeros((0, 216), dtype=np.int8)


def occupancy_descriptor(bits: np.ndarray) -> np.ndarray:
    """(m, 8) float64 octant counts of packed occupancy rows."""
    return _octants_from_cells(_cells(bits))


def surface_descriptor(sd_bits: np.ndarray) -> np.ndarray:
    """(m, 8) float64 octant counts of the surface (first half) of packed (m, 432) surface pairs."""
    return _octants_from_cells(_cells(np.ascontiguousarray(sd_bits[:, :_PACKED])))


def packed_patch_words(shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The z-words (``patch_index._z_words``) of a shape's occupancy, surface and dilated surface.

    Args:
        shape: (X, Y, Z) bool (numpy or torch; floats binarised at ISO_LEVEL).
    Returns:
        Three (X, Y, Z − 11) uint16 arrays for ``extract_packed``.
    """
    occ = as_bool_tensor(shape, "shape")
    surf, dil = surface_and_dilation(occ)
    return tuple(_z_words(v.cpu().numpy()) for v in (occ, surf, dil))  # type: ignore[return-value]


def exemplar_patches(shape, name: str, category: str, chunk: int = 32768) -> ExemplarPatches:
    """Build the table of one exemplar's distinct surface patches.

    Args:
        shape: (X, Y, Z) bool exemplar occupancy at the output resolution.
        chunk: candidate positions extracted at a time (transient memory ≈ chunk · 650 bytes).
    """
    from scipy.spatial import cKDTree

    occ = _crop_around(as_bool_tensor(shape, f"exemplar {name}").cpu())
    pos = surface_candidates(occ)
    words = packed_patch_words(occ)
    occ_rows, sd_rows = [], []
    for s in range(0, len(pos), chunk):
        p = pos[s : s + chunk]
        bits = [extract_packed(w, p) for w in words]
        occ_rows.append(_unique_packed([bits[0]], _PACKED))
        sd_rows.append(_unique_packed([np.concatenate(bits[1:], axis=1)], 2 * _PACKED))
    del words
    occ_bits = _unique_packed(occ_rows, _PACKED)
    sd_bits = _unique_packed(sd_rows, 2 * _PACKED)
    return ExemplarPatches(
        name=name, category=category,
        occ_bits=occ_bits, occ_count=np.bitwise_count(occ_bits).sum(axis=1, dtype=np.int64),
        occ_tree=cKDTree(occupancy_descriptor(occ_bits)), occ_hash=_hash_index(occ_bits),
        sd_bits=sd_bits, surf_count=np.bitwise_count(sd_bits[:, :_PACKED]).sum(axis=1, dtype=np.int64),
        sd_tree=cKDTree(surface_descriptor(sd_bits)), sd_hash=_hash_index(sd_bits))


@dataclass(frozen=True, eq=False)
class PatchBank:
    """The patch tables of every exemplar of a style set, in the set's order."""

    tables: tuple[ExemplarPatches, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.tables)

    @property
    def categories(self) -> tuple[str, ...]:
        return tuple(t.category for t in self.tables)

    @property
    def nbytes(self) -> int:
        return sum(t.nbytes for t in self.tables)

    def index(self, name: str) -> int:
        return self.names.index(name)


def patch_bank(shapes: Sequence, names: Sequence[str], categories: Sequence[str]) -> PatchBank:
    """A PatchBank from (X, Y, Z) bool exemplar shapes (one table each, built one at a time)."""
    return PatchBank(tuple(exemplar_patches(s, n, c) for s, n, c in zip(shapes, names, categories)))


# --------------------------------------------------------------------------- queries


@dataclass(frozen=True, eq=False)
class Queries:
    """Packed query patches and their descriptors.

    Attributes:
        occ_bits: (m, 216) uint8; occ_count: (m,) int64; occ_desc: (m, 8) uint8 octant counts.
        sd_bits: (m, 432) uint8; surf_count: (m,) int64; sd_desc: (m, 8) uint8 surface octant counts.
    """

    occ_bits: np.ndarray
    occ_count: np.ndarray
    occ_desc: np.ndarray
    sd_bits: np.ndarray
    surf_count: np.ndarray
    sd_desc: np.ndarray

    def __len__(self) -> int:
        return len(self.occ_bits)


def make_queries(words: tuple[np.ndarray, np.ndarray, np.ndarray], positions: np.ndarray) -> Queries:
    """Queries at candidate ``positions`` (m, 3) of a shape given by its ``packed_patch_words``."""
    occ, surf, dil = (extract_packed(w, positions) for w in words)
    sd = np.concatenate([surf, dil], axis=1)
    # octant counts are at most 6³ = 216: kept as uint8, widened when a tree is queried
    return Queries(occ, np.bitwise_count(occ).sum(axis=1, dtype=np.int64), occupancy_descriptor(occ).astype(np.uint8),
                   sd, np.bitwise_count(surf).sum(axis=1, dtype=np.int64), surface_descriptor(sd).astype(np.uint8))


@dataclass
class SearchStats:
    """How bounded the searches were: (query, exemplar) pairs searched, and those capped undecided."""

    pairs: int = 0
    capped: int = 0

    def to_json(self) -> dict:
        return {"pairs": self.pairs, "capped": self.capped}


def _iou_pass(q: Queries, t: ExemplarPatches, qi: np.ndarray, ri: np.ndarray) -> np.ndarray:
    """(P,) bool: exact IOU > 19/20 of paired rows (packed popcounts, in chunks)."""
    out = np.zeros(len(qi), dtype=bool)
    for s in range(0, len(qi), _PAIR_CHUNK):
        a, b = qi[s : s + _PAIR_CHUNK], ri[s : s + _PAIR_CHUNK]
        inter = np.bitwise_count(q.occ_bits[a] & t.occ_bits[b]).sum(axis=1, dtype=np.int64)
        union = q.occ_count[a] + t.occ_count[b] - inter
        out[s : s + _PAIR_CHUNK] = _T_DEN * inter > _T_NUM * union
    return out


def _knn_pass(q: Queries, t: ExemplarPatches, todo: np.ndarray, k: int, radius: np.ndarray,
              found: np.ndarray) -> np.ndarray:
    """Check the k nearest rows inside each query's ball; set ``found``; return (len(todo),) 'ball full'."""
    n = len(t.occ_count)
    k = min(k, n)
    dist, nn = t.occ_tree.query(q.occ_desc[todo].astype(np.float64), k=k, p=1, distance_upper_bound=float(radius[todo].max()))
    dist, nn = dist.reshape(len(todo), k), nn.reshape(len(todo), k)
    ok = (nn < n) & (dist <= radius[todo][:, None])
    qi = np.broadcast_to(todo[:, None], ok.shape)[ok]
    hit = _iou_pass(q, t, qi, nn[ok])
    found[np.unique(qi[hit])] = True
    return ok.all(axis=1) & (k < n)


def iou_matches(q: Queries, t: ExemplarPatches, which: np.ndarray | None = None,
                stats: SearchStats | None = None) -> np.ndarray:
    """(m,) bool: queries (those in ``which``, default all) with a patch of ``t`` at IOU > 0.95.

    Bounded: an exact duplicate, then the ``K_FIRST`` nearest rows (octant L1)
    inside the ball of radius |A|/19, then up to ``K_IOU`` nearest inside it.
    A query whose ball holds more than ``K_IOU`` rows and matched none is
    counted in ``stats.capped`` (reported as "not decided").
    """
    m = len(q)
    found = np.zeros(m, dtype=bool)
    todo = np.arange(m) if which is None else np.asarray(which, dtype=np.int64)
    if len(todo) == 0 or len(t.occ_count) == 0:
        return found
    if stats is not None:
        stats.pairs += len(todo)
    found[todo] = _lookup(t.occ_hash, t.occ_bits, q.occ_bits[todo])
    radius = q.occ_count / _T_NUM
    todo = todo[~found[todo]]
    if len(todo):
        # a query whose ball holds fewer than K_FIRST rows has had every candidate checked
        full = _knn_pass(q, t, todo, K_FIRST, radius, found)
        todo = todo[full & ~found[todo]]
    if len(todo):
        full = _knn_pass(q, t, todo, K_IOU, radius, found)
        if stats is not None:
            stats.capped += int((full & ~found[todo]).sum())
    return found


def _f_pass(q: Queries, t: ExemplarPatches, qi: np.ndarray, ri: np.ndarray) -> np.ndarray:
    """(P,) bool: exact surface F-score > 19/20 of paired rows (1-voxel tolerance)."""
    out = np.zeros(len(qi), dtype=bool)
    for s in range(0, len(qi), _PAIR_CHUNK):
        a, b = qi[s : s + _PAIR_CHUNK], ri[s : s + _PAIR_CHUNK]
        qs, qd = q.sd_bits[a, :_PACKED], q.sd_bits[a, _PACKED:]
        ts, td = t.sd_bits[b, :_PACKED], t.sd_bits[b, _PACKED:]
        x = np.bitwise_count(qs & td).sum(axis=1, dtype=np.int64)  # |S_q ∧ Dil_s|
        y = np.bitwise_count(qd & ts).sum(axis=1, dtype=np.int64)  # |Dil_q ∧ S_s|
        so, ss = q.surf_count[a], t.surf_count[b]
        # F = 2xy / (x·|S_s| + y·|S_q|) > 19/20; x = 0 or y = 0 is F = 0 (or NaN): not similar
        out[s : s + _PAIR_CHUNK] = (40 * x * y - _T_NUM * (x * ss + y * so) > 0) & (so > 0) & (ss > 0)
    return out


def f_matches(q: Queries, t: ExemplarPatches, which: np.ndarray | None = None) -> np.ndarray:
    """(m,) bool: queries with a patch of ``t`` at surface F-score > 0.95 among an exact duplicate and
    ``K_F`` near rows by surface descriptor within L1 ``F_RADIUS``·|S_q| (approximate neighbours,
    ``F_EPS``): a lower bound of the exhaustive search — the candidates are limited, each is checked
    exactly."""
    m = len(q)
    found = np.zeros(m, dtype=bool)
    todo = np.arange(m) if which is None else np.asarray(which, dtype=np.int64)
    todo = todo[q.surf_count[todo] > 0]
    n = len(t.surf_count)
    if len(todo) == 0 or n == 0:
        return found
    found[todo] = _lookup(t.sd_hash, t.sd_bits, q.sd_bits[todo])
    todo = todo[~found[todo]]
    radius = F_RADIUS * q.surf_count
    for k in (K_FIRST, K_F):  # the nearest few first; more only where the radius holds more
        if len(todo) == 0:
            break
        k = min(k, n)
        dist, nn = t.sd_tree.query(q.sd_desc[todo].astype(np.float64), k=k, p=1, eps=F_EPS,
                                   distance_upper_bound=float(radius[todo].max()))
        dist, nn = dist.reshape(len(todo), k), nn.reshape(len(todo), k)
        ok = (nn < n) & (dist <= radius[todo][:, None])
        qi = np.broadcast_to(todo[:, None], ok.shape)[ok]
        found[np.unique(qi[_f_pass(q, t, qi, nn[ok])])] = True
        todo = todo[ok.all(axis=1) & (k < n) & ~found[todo]]
    return found


def any_match(q: Queries, bank: PatchBank, exemplars: Sequence[int], which: np.ndarray, kind: str = "iou",
              stats: SearchStats | None = None) -> np.ndarray:
    """(m,) bool: queries in ``which`` matching a patch of any of ``exemplars`` (a query leaves at its first)."""
    found = np.zeros(len(q), dtype=bool)
    todo = np.asarray(which, dtype=np.int64)
    for e in exemplars:
        if len(todo) == 0:
            break
        t = bank.tables[e]
        hit = iou_matches(q, t, todo, stats) if kind == "iou" else f_matches(q, t, todo)
        found |= hit
        todo = todo[~found[todo]]
    return found

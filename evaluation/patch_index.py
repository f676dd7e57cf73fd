"""The style patch dictionary and its exact, pruned similarity search (LP-IOU and LP-F matching).

Instead of a Python loop per patch, every search is exact but pruned by bounds
that provably cannot change a decision (only "similar or not" is needed, so a
query also stops at its first match):

* exact duplicates are found by a 64-bit row hash (verified byte-exactly):
  IOU = F = 1;
* LP-IOU: IOU > 0.95 ⟺ Hamming distance h < (|A|+|B|)/39, hence h < |A|/19;
  the L1 distance between 6³-octant counts is a lower bound of h, so a
  kd-tree (scipy cKDTree, L1 ball) returns every possible match, which is then
  verified with packed-bit popcounts (216 bytes a patch);
* LP-F: F > 0.95 needs recall > 19/21, and recall ≤ |Dil_q| / |S_s| bounds
  |S_s|; 2³-cell bounds |A ∧ B| ≤ Σ_cells count_A · [B present] give upper
  bounds of precision and recall through int8 matrix products
  (``torch._int_mm``, exact int32; exact float32 fallback) 8× smaller than
  the exact ones; only pairs whose bound passes are checked exactly; the
  dictionary is visited outward from the queries' own surface count and each
  query's best-bounded rows are checked first.

Thresholds are compared in integers (0.95 = 19/20), so there is no float
rounding at the boundary.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from evaluation.patches import (
    PATCH_BEFORE,
    PATCH_SIZE,
    PATCH_VOXELS,
    _T_DEN,
    _T_NUM,
    as_bool_tensor,
    surface_and_dilation,
    surface_candidates,
)

if TYPE_CHECKING:  # pragma: no cover
    import torch

#: LP-F search: query rows per block and dictionary rows per chunk (the bound
#: matrices are _QUERY_BLOCK × _DICT_CHUNK int32, 32 MiB).
_QUERY_BLOCK = 256
_DICT_CHUNK = 32768


# --------------------------------------------------------------------------- style dictionary

_PACKED = PATCH_VOXELS // 8  # 216 bytes per packed patch
_CELLS = (PATCH_SIZE // 2) ** 3  # 216 cells of 2³ voxels per patch


def cell_signatures(rows: "torch.Tensor") -> tuple["torch.Tensor", "torch.Tensor"]:
    """Per-2³-cell counts and presence of (m, 1728) 0/1 int8 patch rows.

    Returns:
        (counts, presence): (m, 216) int8 each; counts in 0..8, presence 0/1.
        They give cheap exact upper bounds on intersections:
        |A ∧ B| <= counts(A) · presence(B).
    """
    import torch

    cells = rows.reshape(-1, 6, 2, 6, 2, 6, 2).sum(dim=(2, 4, 6), dtype=torch.int16)
    cells = cells.reshape(-1, _CELLS)
    return cells.to(torch.int8), (cells > 0).to(torch.int8)


def _octants(rows: "torch.Tensor") -> np.ndarray:
    """(m, 8) float64 numpy: ones per 6³ octant of (m, 1728) 0/1 rows.

    L1 distance between octant vectors is a lower bound of the Hamming distance.
    """
    import torch

    return rows.reshape(-1, 2, 6, 2, 6, 2, 6).sum(dim=(2, 4, 6), dtype=torch.int32).reshape(-1, 8) \
        .cpu().numpy().astype(np.float64)


@dataclass(frozen=True, eq=False)
class StyleDictionary:
    """All distinct surface patches of a set of style shapes, ready for matching.

    Two tables: distinct occupancy patches (for LP-IOU) and distinct
    (surface, dilated surface) pairs (for LP-F), each sorted by its count.
    Duplicates are removed across all shapes (a superset of "per shape"
    deduplication; the max over patches, hence every metric, is unchanged).
    Patches are stored packed (216 bytes each, numpy, CPU); the 2³-cell
    signatures used for pruning are dense int8 tensors (216 bytes each) on
    the dictionary's device. Memory ≈ 648 B per occupancy row + 864 B per
    surface row.

    Attributes:
        occ_bits: (N1, 216) uint8 packed occupancy, ascending occ_count.
        occ_count: (N1,) int64 occupied voxels.
        occ_oct: (N1, 8) float64 occupied voxels per 6³ octant.
        occ_tree: scipy cKDTree over occ_oct (L1 ball queries).
        sd_bits: (N2, 432) uint8 packed surface then dilated surface, ascending
            surf_count (``surf_bits`` / ``dil_bits`` are views of its halves).
        surf_count, dil_count: (N2,) int64.
        surf_cells: (N2, 216) int8 cell counts of the surface.
        dil_pres: (N2, 216) int8 cell presence of the dilated surface.
        occ_hash, sd_hash: sorted 64-bit row hashes (+ row order) for exact-duplicate lookups.
    """

    occ_bits: np.ndarray
    occ_count: np.ndarray
    occ_oct: np.ndarray
    occ_tree: object
    sd_bits: np.ndarray
    surf_count: np.ndarray
    dil_count: np.ndarray
    surf_cells: "torch.Tensor"
    dil_pres: "torch.Tensor"
    occ_hash: tuple[np.ndarray, np.ndarray]
    sd_hash: tuple[np.ndarray, np.ndarray]

    @property
    def device(self):
        return self.surf_cells.device

    @property
    def nbytes(self) -> int:
        """Memory held by the dictionary's arrays and tensors, in bytes."""
        total = 0
        for v in self.__dict__.values():
            for x in (v if isinstance(v, tuple) else (v,)):
                if isinstance(x, np.ndarray):
                    total += x.nbytes
                elif hasattr(x, "element_size"):
                    total += x.numel() * x.element_size()
                else:  # the kd-tree keeps a copy of its points plus an index
                    total += x.n * (x.m * 8 + 8)
        return total

    @property
    def surf_bits(self) -> np.ndarray:
        return self.sd_bits[:, :_PACKED]

    @property
    def dil_bits(self) -> np.ndarray:
        return self.sd_bits[:, _PACKED:]

    def to(self, device) -> "StyleDictionary":
        """The same dictionary with its tensors on ``device`` (packed bits stay on the CPU)."""
        import torch

        moved = {k: (v.to(device) if isinstance(v, torch.Tensor) else v) for k, v in self.__dict__.items()}
        return StyleDictionary(**moved)


def _unique_packed(rows: list[np.ndarray], width: int) -> np.ndarray:
    """Distinct rows of concatenated packed-bit arrays, in order of first occurrence (exact).

    Rows are grouped by a 64-bit hash; a group whose rows are not all
    byte-identical to its first (a hash collision) is deduplicated exactly.
    """
    if not rows:
        return np.zeros((0, width), dtype=np.uint8)
    packed = np.ascontiguousarray(np.concatenate(rows))
    if len(packed) == 0:
        return packed.reshape(0, width)
    h = _row_hash(packed)
    order = np.argsort(h, kind="stable")
    hs = h[order]
    first = np.ones(len(h), dtype=bool)
    first[1:] = hs[1:] != hs[:-1]
    group = np.maximum.accumulate(np.where(first, np.arange(len(h)), 0))  # sorted position of the group's head
    dup = np.nonzero(~first)[0]
    differs = np.zeros(len(dup), dtype=bool)
    for s in range(0, len(dup), 65536):
        d = dup[s : s + 65536]
        differs[s : s + 65536] = (packed[order[d]] != packed[order[group[d]]]).any(axis=1)
    if not differs.any():
        return packed[np.sort(order[first])]
    collided = np.isin(group, group[dup[differs]])
    rows_c = order[collided]
    keys = packed[rows_c].view(np.dtype((np.void, packed.shape[1])))[:, 0]
    _, first_c = np.unique(keys, return_index=True)
    keep = np.concatenate([order[first & ~collided], rows_c[first_c]])
    return packed[np.sort(keep)]


_HASH_MULT = np.random.default_rng(20240527).integers(1, 2**63, size=64, dtype=np.uint64) | np.uint64(1)


def _row_hash(packed: np.ndarray) -> np.ndarray:
    """(N,) uint64 hash of packed rows (width a multiple of 8 bytes); equal rows, equal hash."""
    words = np.ascontiguousarray(packed).view(np.uint64)
    with np.errstate(over="ignore"):
        h = (words * _HASH_MULT[: words.shape[1]]).sum(axis=1, dtype=np.uint64)
        return h ^ (h >> np.uint64(29))


def _hash_index(packed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    h = _row_hash(packed)
    order = np.argsort(h, kind="stable")
    return h[order], order


def _lookup(index: tuple[np.ndarray, np.ndarray], table: np.ndarray, query: np.ndarray) -> np.ndarray:
    """(m,) bool: whether each packed query row occurs verbatim in ``table``."""
    keys, order = index
    out = np.zeros(len(query), dtype=bool)
    if len(keys) == 0 or len(query) == 0:
        return out
    h = _row_hash(query)
    lo = np.searchsorted(keys, h, side="left")
    hi = np.searchsorted(keys, h, side="right")
    for q in np.nonzero(hi > lo)[0]:  # hash hits only; collisions are verified byte-exactly
        out[q] = bool((table[order[lo[q] : hi[q]]] == query[q]).all(axis=1).any())
    return out


def _unpack(bits: np.ndarray, device) -> "torch.Tensor":
    """(N, 216) packed rows → (N, 1728) int8 0/1 tensor on ``device``."""
    import torch

    return torch.from_numpy(np.unpackbits(bits, axis=1).view(np.int8)).to(device)


def _pack(rows) -> np.ndarray:
    """(N, 1728) 0/1 rows (numpy or torch) → (N, 216) uint8 packed bits."""
    arr = rows.cpu().numpy() if hasattr(rows, "cpu") else np.asarray(rows)
    return np.packbits(arr.reshape(len(arr), PATCH_VOXELS).astype(bool), axis=1)


# Packed patch extraction for the dictionary: 12-bit words along z, 144 words a patch.


def _z_words(vol: np.ndarray) -> np.ndarray:
    """(X, Y, Z−11) uint16: bit 11−c of word [x, y, k] is vol[x, y, k + c] (c < 12, first voxel highest)."""
    v = vol.astype(np.uint16)
    n = vol.shape[2] - (PATCH_SIZE - 1)
    w = np.zeros(vol.shape[:2] + (n,), dtype=np.uint16)
    for c in range(PATCH_SIZE):
        w |= v[:, :, c : c + n] << np.uint16(PATCH_SIZE - 1 - c)
    return w


def _words_to_bytes(words: np.ndarray) -> np.ndarray:
    """(m, 144) uint16 12-bit words → (m, 216) uint8, the same bit stream (= np.packbits of the row)."""
    w = words.reshape(len(words), -1, 2)
    w0, w1 = w[..., 0], w[..., 1]
    out = np.empty((len(words), w.shape[1], 3), dtype=np.uint8)
    out[..., 0] = w0 >> 4
    out[..., 1] = ((w0 & 0xF) << 4) | (w1 >> 8)
    out[..., 2] = w1 & 0xFF
    return out.reshape(len(words), _PACKED)


def _bytes_to_words(bits: np.ndarray) -> np.ndarray:
    """Inverse of ``_words_to_bytes``."""
    b = bits.reshape(len(bits), -1, 3).astype(np.uint16)
    out = np.empty((len(bits), b.shape[1], 2), dtype=np.uint16)
    out[..., 0] = (b[..., 0] << 4) | (b[..., 1] >> 4)
    out[..., 1] = ((b[..., 1] & 0xF) << 8) | b[..., 2]
    return out.reshape(len(bits), PATCH_SIZE * PATCH_SIZE)


def extract_packed(words: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Packed 12³ patches from a volume's ``_z_words``: (m, 216) uint8, equal to
    ``_pack(extract_patches(volume, positions))`` at 1/12 of the gathers."""
    X, Y, n = words.shape
    corners = np.asarray(positions, dtype=np.int64).reshape(-1, 3) - PATCH_BEFORE
    r = np.arange(PATCH_SIZE, dtype=np.int64)
    offsets = (r[:, None] * (Y * n) + r[None, :] * n).reshape(-1)  # (144,) over (a, b)
    start = corners[:, 0] * (Y * n) + corners[:, 1] * n + corners[:, 2]
    return _words_to_bytes(words.reshape(-1)[start[:, None] + offsets[None, :]])


#: bits (2j, 2j+1) of a 12-bit word (first voxel highest) → the 6 pair counts of the word.
_PAIR_LUT = ((np.arange(4096)[:, None] >> (10 - 2 * np.arange(6))[None, :]) & 3)
_PAIR_LUT = ((_PAIR_LUT & 1) + (_PAIR_LUT >> 1)).astype(np.uint8)


def packed_cell_counts(bits: np.ndarray) -> np.ndarray:
    """(m, 216) int8 2³-cell counts of packed rows (same values and order as ``cell_signatures``)."""
    pairs = _PAIR_LUT[_bytes_to_words(bits)]  # (m, 144, 6): per (a, b), counts of c-pairs
    p = pairs.reshape(len(bits), 6, 2, 6, 2, 6)
    cells = p[:, :, 0, :, 0] + p[:, :, 0, :, 1] + p[:, :, 1, :, 0] + p[:, :, 1, :, 1]  # uint8, <= 8
    return cells.reshape(len(bits), _CELLS).view(np.int8)


def _octants_from_cells(counts: np.ndarray) -> np.ndarray:
    """(m, 8) float64 ones per 6³ octant from (m, 216) cell counts (same as ``_octants`` of the rows)."""
    return counts.reshape(-1, 2, 3, 2, 3, 2, 3).sum(axis=(2, 4, 6), dtype=np.int64).reshape(-1, 8).astype(np.float64)


def _dictionary_from_packed(occ_rows: list[np.ndarray], sd_rows: list[np.ndarray], device,
                            chunk: int = 16384) -> StyleDictionary:
    import torch

    occ = _unique_packed(occ_rows, _PACKED)
    sd = _unique_packed(sd_rows, 2 * _PACKED)
    occ_count = np.bitwise_count(occ).sum(axis=1, dtype=np.int64)
    o = np.argsort(occ_count, kind="stable")
    occ, occ_count = np.ascontiguousarray(occ[o]), occ_count[o]
    surf_count = np.bitwise_count(sd[:, :_PACKED]).sum(axis=1, dtype=np.int64)
    o = np.argsort(surf_count, kind="stable")
    sd, surf_count = np.ascontiguousarray(sd[o]), surf_count[o]
    surf, dil = np.ascontiguousarray(sd[:, :_PACKED]), np.ascontiguousarray(sd[:, _PACKED:])
    dil_count = np.bitwise_count(dil).sum(axis=1, dtype=np.int64)

    def counts(bits: np.ndarray) -> np.ndarray:
        parts = [packed_cell_counts(bits[s : s + chunk]) for s in range(0, len(bits), chunk)]
        return np.concatenate(parts) if parts else np.zeros((0, _CELLS), dtype=np.int8)

    from scipy.spatial import cKDTree

    occ_oct = _octants_from_cells(counts(occ))
    surf_cells = torch.from_numpy(counts(surf)).to(device)
    dil_pres = torch.from_numpy((counts(dil) > 0).astype(np.int8)).to(device)
    return StyleDictionary(
        occ_bits=occ, occ_count=occ_count, occ_oct=occ_oct, occ_tree=cKDTree(occ_oct),
        sd_bits=sd, surf_count=surf_count, dil_count=dil_count,
        surf_cells=surf_cells, dil_pres=dil_pres,
        occ_hash=_hash_index(occ), sd_hash=_hash_index(sd),
    )


def dictionary_from_patches(occ, surf, dil, device="cpu") -> StyleDictionary:
    """A StyleDictionary from explicit patches (deduplicated and sorted here).

    Args:
        occ, surf, dil: (N, 1728) or (N, 12, 12, 12) 0/1 arrays or tensors: the
            occupancy, surface and dilated-surface patches (row n of each
            belongs to the same patch).
    """
    sd = np.concatenate([_pack(surf), _pack(dil)], axis=1)
    return _dictionary_from_packed([_pack(occ)], [sd], device)


def _crop_around(occ: "torch.Tensor", margin: int = PATCH_SIZE) -> "torch.Tensor":
    """The occupied box plus ``margin`` voxels a side, clipped to the grid (a view).

    With a margin of at least 8 the crop has the same surface, candidates and
    patches as the whole grid: candidate cells touch the box, a patch reaches 5
    before and 7 after, and where the crop meets the grid border it is the border.
    """
    nz = occ.nonzero()
    if len(nz) == 0:
        return occ
    lo = (nz.min(dim=0).values - margin).clamp(min=0).tolist()
    hi = [min(int(v) + margin + 1, n) for v, n in zip(nz.max(dim=0).values.tolist(), occ.shape)]
    return occ[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]


def style_patch_dictionary(style_shapes: Sequence, chunk: int = 16384) -> StyleDictionary:
    """Build the deduplicated dictionary of all surface patches of the style shapes.

    Args:
        style_shapes: (X, Y, Z) bool grids (any sizes), at output resolution.
        chunk: patches extracted at a time (memory ~ chunk·(288 + 216)·3 bytes).
    Returns:
        StyleDictionary on the device of the first shape (CPU for numpy input).
    """
    import torch

    occ_rows: list[np.ndarray] = []
    sd_rows: list[np.ndarray] = []
    device = torch.device("cpu")
    for n, shape in enumerate(style_shapes):
        occ = as_bool_tensor(shape, f"style_shapes[{n}]")
        if n == 0:
            device = occ.device
        occ = _crop_around(occ)
        surf, dil = surface_and_dilation(occ)
        pos = surface_candidates(occ)
        if len(pos) == 0:
            continue
        words = [_z_words(v.cpu().numpy()) for v in (occ, surf, dil)]
        for s in range(0, len(pos), chunk):
            p = pos[s : s + chunk]
            bits = [extract_packed(w, p) for w in words]
            # dedupe each chunk early to bound memory; the final pass dedupes across all
            occ_rows.append(_unique_packed([bits[0]], _PACKED))
            sd_rows.append(_unique_packed([np.concatenate(bits[1:], axis=1)], 2 * _PACKED))
    return _dictionary_from_packed(occ_rows, sd_rows, device)


# --------------------------------------------------------------------------- matching


_INT_MM_OK: dict[str, bool] = {}


def _intersections(a: "torch.Tensor", b: "torch.Tensor") -> "torch.Tensor":
    """(m, n) int32 dot products of int8 matrices a (m, K) and b (n, K) with small entries.

    Used for counts of common 1s (K = 1728) and for cell-count bounds (K = 216);
    all sums stay below 2¹⁵, so both the int8 GEMM and the float32 fallback are exact.
    """
    import torch

    key = a.device.type
    if _INT_MM_OK.get(key, True):
        try:
            m, n = a.shape[0], b.shape[0]
            # CUDA's int8 GEMM wants m > 16 and n a multiple of 8: pad, then crop.
            pa = torch.nn.functional.pad(a, (0, 0, 0, max(0, 17 - m)))
            pb = torch.nn.functional.pad(b, (0, 0, 0, (-n) % 8))
            out = torch._int_mm(pa, pb.t())[:m, :n]
            _INT_MM_OK[key] = True
            return out
        except (RuntimeError, AttributeError, NotImplementedError):
            _INT_MM_OK[key] = False
    return torch.round(a.float() @ b.float().t()).to(torch.int32)


def _query_blocks(counts: np.ndarray) -> list[np.ndarray]:
    """Query indices sorted by count, cut into blocks of _QUERY_BLOCK (narrow count windows)."""
    order = np.argsort(counts, kind="stable")
    return [order[s : s + _QUERY_BLOCK] for s in range(0, len(order), _QUERY_BLOCK)]


def _chunks_outward(lo: int, hi: int, centre: int, size: int) -> list[tuple[int, int]]:
    """Cut [lo, hi) into chunks of ``size``, ordered outward from ``centre``.

    Dictionary rows are sorted by count, so rows near the queries' own count
    come first: that is where matches usually are, and found queries leave early.
    """
    centre = min(max(centre, lo), hi)
    right = [(a, min(a + size, hi)) for a in range(centre, hi, size)]
    left = [(max(a - size, lo), a) for a in range(centre, lo, -size)]
    out = []
    for k in range(max(len(right), len(left))):
        out += right[k : k + 1] + left[k : k + 1]
    return out


#: Best-bound candidates per query checked exactly before the full check of a chunk.
_TOP_K = 4


def _any_match(found: np.ndarray, key_count: np.ndarray, window, bound, exact, exact_pairs) -> None:
    """Shared search loop: set ``found[q]`` when some dictionary row has exact slack > 0.

    window(block) -> (lo, hi, centre): dictionary rows that can match any query
        of the block, and where to start;
    bound(active, s, e) -> (len(active), e-s) int32 upper bound of the slack
        (slack > 0 ⟺ similar), computed from 2³-cell signatures;
    exact(active, rows) -> (len(active), len(rows)) int32 exact slack;
    exact_pairs(queries, rows) -> (P,) int32 exact slack of paired rows.
    Per chunk, each query's few best-bounded rows are checked first (most
    similar queries end there); then every row whose bound passes for a
    remaining query is checked exactly. A query leaves at its first match.
    """
    import torch

    for block in _query_blocks(key_count):
        active = block[~found[block]]
        if len(active) == 0:
            continue
        lo, hi, centre = window(block)
        for s, e in _chunks_outward(lo, hi, centre, _DICT_CHUNK):
            if len(active) == 0:
                break
            ub = bound(active, s, e)
            cand = ub > 0
            any_cand = cand.any(dim=1)
            if not bool(any_cand.any()):
                continue
            # 1) the few best-bounded rows of each query
            k = min(_TOP_K, e - s)
            top_val, top_col = torch.topk(ub, k, dim=1)
            q_rows = torch.arange(len(active), device=ub.device)[:, None].expand(-1, k)
            ok = top_val > 0
            qi, cols = q_rows[ok].cpu().numpy(), top_col[ok].cpu().numpy()
            hit_pair = (exact_pairs(active[qi], s + cols) > 0)
            hit = np.zeros(len(active), dtype=bool)
            hit[qi[hit_pair.cpu().numpy()]] = True
            # 2) everything else the bound lets through, for queries still unmatched
            rest = ~hit & any_cand.cpu().numpy()
            if rest.any():
                sub = cand[torch.from_numpy(rest).to(cand.device)]
                cols_t = torch.nonzero(sub.any(dim=0)).reshape(-1)
                full = (exact(active[rest], s + cols_t.cpu().numpy()) > 0) & sub[:, cols_t]
                hit[np.nonzero(rest)[0][full.any(dim=1).cpu().numpy()]] = True
            found[active[hit]] = True
            active = active[~hit]


def _tensor(a: np.ndarray, device) -> "torch.Tensor":
    import torch

    return torch.from_numpy(np.ascontiguousarray(a)).to(device)


#: Nearest octant neighbours checked before the full ball of candidates.
_KNN = 8
#: Candidate pairs verified at a time (memory ~ 216 bytes each).
_PAIR_CHUNK = 1 << 18
#: Queries whose full candidate balls are gathered at a time.
_BALL_BLOCK = 64


def _iou_pairs_pass(q_bits, a_count, dictionary, qi: np.ndarray, ri: np.ndarray) -> np.ndarray:
    """Exact IOU > 19/20 for paired rows (packed popcount)."""
    inter = np.bitwise_count(q_bits[qi] & dictionary.occ_bits[ri]).sum(axis=1, dtype=np.int64)
    union = a_count[qi] + dictionary.occ_count[ri] - inter
    return _T_DEN * inter > _T_NUM * union


def _mark_pairs(found, q_bits, a_count, dictionary, qi: np.ndarray, ri: np.ndarray) -> None:
    for s in range(0, len(qi), _PAIR_CHUNK):
        q, r = qi[s : s + _PAIR_CHUNK], ri[s : s + _PAIR_CHUNK]
        found[np.unique(q[_iou_pairs_pass(q_bits, a_count, dictionary, q, r)])] = True


def iou_similar(queries: "torch.Tensor", dictionary: StyleDictionary) -> np.ndarray:
    """Whether each query patch has a dictionary patch with IOU > 0.95 (exact).

    IOU > 19/20 ⟺ Hamming h < (a+b)/39, and with b < 20a/19 this gives
    h < a/19; the L1 distance of 6³-octant counts is <= h, so every match lies
    in the L1 ball of radius a/19 around the query's octant vector. A kd-tree
    returns that ball (first its 8 nearest points, then the whole ball for
    queries still unmatched) and candidates are verified exactly with packed
    popcounts. Runs on the CPU.

    Args:
        queries: (m, 1728) int8 0/1 occupancy patches.
        dictionary: the style dictionary.
    Returns:
        (m,) bool.
    """
    m = int(queries.shape[0])
    n_dict = len(dictionary.occ_count)
    if m == 0 or n_dict == 0:
        return np.zeros(m, dtype=bool)
    q_bits = _pack(queries)
    found = _lookup(dictionary.occ_hash, dictionary.occ_bits, q_bits)  # IOU 1
    a_count = np.bitwise_count(q_bits).sum(axis=1, dtype=np.int64)
    q_oct = _octants(queries)
    radius = a_count / _T_NUM  # float; the ball is closed, a superset of the strict bound
    tree = dictionary.occ_tree
    todo = np.nonzero(~found)[0]
    if len(todo):
        k = min(_KNN, n_dict)
        dist, nn = tree.query(q_oct[todo], k=k, p=1, distance_upper_bound=float(radius[todo].max()), workers=-1)
        dist, nn = dist.reshape(len(todo), k), nn.reshape(len(todo), k)
        ok = (nn < n_dict) & (dist <= radius[todo][:, None])
        _mark_pairs(found, q_bits, a_count, dictionary,
                    np.broadcast_to(todo[:, None], ok.shape)[ok], nn[ok])
    todo = np.nonzero(~found)[0]
    for s in range(0, len(todo), _BALL_BLOCK):  # blocks bound the size of the candidate lists
        part = todo[s : s + _BALL_BLOCK]
        balls = tree.query_ball_point(q_oct[part], r=radius[part], p=1, workers=-1, return_sorted=False)
        lengths = np.array([len(b) for b in balls], dtype=np.int64)
        if lengths.sum():
            ri = np.concatenate([np.asarray(b, dtype=np.int64) for b in balls])
            _mark_pairs(found, q_bits, a_count, dictionary, np.repeat(part, lengths), ri)
    return found


def f_similar(q_surf: "torch.Tensor", q_dil: "torch.Tensor", dictionary: StyleDictionary) -> np.ndarray:
    """Whether each query has a dictionary patch with surface F-score > 0.95 (exact).

    precision = |S_q ∧ Dil_s| / |S_q|, recall = |Dil_q ∧ S_s| / |S_s|,
    F = 2PR/(P+R); NaN (an empty surface) counts as not similar.

    Args:
        q_surf, q_dil: (m, 1728) int8 surface and dilated-surface query patches.
    Returns:
        (m,) bool.
    """
    import torch

    m = int(q_surf.shape[0])
    ss_count = dictionary.surf_count
    if m == 0 or len(ss_count) == 0:
        return np.zeros(m, dtype=bool)
    device = q_surf.device
    so_count = q_surf.sum(dim=1, dtype=torch.int64).cpu().numpy()
    do_count = q_dil.sum(dim=1, dtype=torch.int64).cpu().numpy()
    # |S_q| = 0 makes precision NaN: never similar, kept out of the search
    skip = so_count == 0
    # an identical (surface, dilation) pair has F = 1
    found = _lookup(dictionary.sd_hash, dictionary.sd_bits,
                    np.concatenate([_pack(q_surf), _pack(q_dil)], axis=1)) | skip
    ss_dev = _tensor(ss_count, device).to(torch.int32)
    so_dev = _tensor(so_count, device).to(torch.int32)
    qs_cells, _ = cell_signatures(q_surf)
    _, qd_pres = cell_signatures(q_dil)

    def window(block):
        # F > 19/20 needs recall > 19/21, and recall <= |Dil_q| / |S_s|; |S_s| = 0 is NaN
        lo = np.searchsorted(ss_count, 1, side="left")
        hi = np.searchsorted(ss_count, -(-21 * int(do_count[block].max()) // 19), side="right")
        return int(lo), int(hi), int(np.searchsorted(ss_count, int(np.median(so_count[block]))))

    def slack(x, y, so, ss):
        # F = 2xy / (x·|S_s| + y·|S_q|) > 19/20 ⟺ slack > 0; grows with x and y;
        # x = 0 or y = 0 gives slack <= 0 (F = 0 or NaN)
        return 40 * x * y - _T_NUM * (x * ss + y * so)

    def bound(active, s, e):
        idx = _tensor(active, device)
        x = _intersections(qs_cells[idx], dictionary.dil_pres[s:e])
        y = _intersections(qd_pres[idx], dictionary.surf_cells[s:e])
        return slack(x, y, so_dev[idx][:, None], ss_dev[s:e][None, :])

    def exact(active, rows):
        idx = _tensor(active, device)
        x = _intersections(q_surf[idx], _unpack(dictionary.dil_bits[rows], device))
        y = _intersections(q_dil[idx], _unpack(dictionary.surf_bits[rows], device))
        return slack(x, y, so_dev[idx][:, None], ss_dev[_tensor(rows, device)][None, :])

    def exact_pairs(q, rows):
        qi, ri = _tensor(q, device), _tensor(rows, device)
        x = (q_surf[qi] * _unpack(dictionary.dil_bits[rows], device)).sum(dim=1, dtype=torch.int32)
        y = (q_dil[qi] * _unpack(dictionary.surf_bits[rows], device)).sum(dim=1, dtype=torch.int32)
        return slack(x, y, so_dev[qi], ss_dev[ri])

    _any_match(found, do_count, window, bound, exact, exact_pairs)
    return found & ~skip

"""Voxelizer: a source's parts → a coarse grid of source-part labels (``PartGrid``).

Role: sizes the grid from the recipe's ``grid`` settings, fills every part mesh
into solid occupancy, and labels each occupied voxel with the source part that
fills most of it. A ``voxels`` source (already a grid) is passed through or
resampled. Region rules (part/style names) are applied later, not here.

Grid sizing (``FitMode``): ``longest``: voxel = longest bounding-box side /
resolution; ``height``: voxel = Y extent / resolution; ``voxel_size``: as
given. Each axis gets ``ceil(extent / voxel)`` voxels (at least 1) and the shape
is centred in the grid; no empty margin is added.

Solid fill (numpy ray parity, no trimesh ``voxelized().fill()``/``contains()``,
which fatten shapes and fail on open meshes): triangles are expressed in sample
units with sample centres on integers; rays run along one grid axis through
every column of sample centres (shifted by ~1e-7 so they do not hit edges or
vertices), each crossing toggles the first sample beyond it, and a cumulative
sum's parity marks the inside. Crossings are counted by sorting them (at 256³
~25× faster than ``np.bincount``, whose grid-sized int64 result dominates).
Edge hits that survive the shift follow a half-open (top-left) rule so that a
ray through a shared edge counts once.

Connected components, because parity cancels where two closed bodies overlap:
each part mesh is split into edge-connected components and every watertight
component is filled on its own, in its own bounding box (one ray axis is exact
for a closed surface). Components are combined with a signed count, like a
winding number at component granularity: an outward-facing component adds 1,
an inward-facing one (negative signed volume: a cavity, e.g. the inverted inner
sphere of a hollow shell) subtracts 1 where it lies inside the other
components, and a voxel sample is solid where the count is positive. So
overlapping bodies stay solid, cavities stay empty and a body inside a cavity
stays solid. If the watertight components' total volume is negative (a file
whose normals all point inwards) every sign is flipped first; an inward-facing
component that lies in nothing is treated as a solid. All non-watertight
components of a part are filled together with a ray along each of the three
axes and a majority vote, which tolerates holes (a ray that leaves through a
hole is outvoted by the two others); such parts get a warning.

Labels by volume: for coarse grids (every side ≤ 64) each voxel is sampled at
4×4×4 sub-voxel centres (``supersample`` 4); a part's coverage of a voxel is the
fraction of those samples inside it. A voxel is occupied when the union of all
parts covers at least ``grid.min_coverage`` of it, and it is labelled with the
part that covers most of it (ties: the earlier part). Larger grids (exemplars
at 256³) sample voxel centres only (``supersample`` 1, coverage 0 or 1).

keep_thin: with ``grid.keep_thin`` every part additionally occupies its
strongest voxels: those where its own coverage is > 0 and ≥ min(min_coverage,
0.5 × its largest coverage of any voxel). Such voxels still take the label of
the part that covers them most. A part that misses every sample stays empty.

Voxels sources: the input grid is cropped to its occupied box. It passes
through unchanged when the fitted extent already spans ``resolution`` voxels
(or ``voxel_size`` asks for the input's own voxel size); otherwise it is
resampled by any (non-integer) factor: the coverage of an output voxel is the
overlap-weighted fraction of occupied input voxels, and its label (and style)
is the overlap-weighted most frequent one among them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core.errors import VoxelizeError
from core.grid import EMPTY
from core.recipe import FitMode, GridSettings
from sources.base import PartMeshes, PartVoxels, SourceResult

if TYPE_CHECKING:  # imported lazily
    import trimesh

#: Sub-voxel samples per axis for grids whose sides are all ≤ ``COARSE_MAX_SIDE``.
COARSE_SUPERSAMPLE: int = 4
COARSE_MAX_SIDE: int = 64

# Every ray is moved off the integer lattice by this much (sample units), so that
# rays through mesh vertices and edges that lie exactly on the lattice (common:
# CAD shapes sit on round numbers) do not count a crossing twice or not at all.
_RAY_SHIFT = (1.23e-7, 0.71e-7)
# Largest number of (triangle, ray) candidate pairs evaluated at once (memory bound).
_CHUNK_PAIRS = 1 << 20
# Float tolerance when comparing coverage fractions (k/64) with thresholds.
_COVERAGE_EPS = 1e-6

_NOTHING_HINT = "increase grid.resolution, or set grid.keep_thin: true, or check the source's size"


@dataclass(frozen=True, eq=False)
class PartGrid:
    """Source-part labels on the coarse grid (before region rules give parts and styles).

    Attributes:
        part: (X, Y, Z) int16 index into ``part_names``; -1 (``EMPTY``) where empty.
            Axes x, y, z; +Y up.
        part_names: the source's part names, all of them (some may occupy no voxel).
        voxel_size_m: edge of one voxel, metres.
        origin_m: world position of the min corner of voxel (0, 0, 0), metres.
        style: (X, Y, Z) int16 style index passed through from a voxels source
            (-1 empty), or None.
        style_names: names behind ``style``.
        warnings: the voxelizer's own notes (the source's warnings are not repeated).
    """

    part: np.ndarray
    part_names: tuple[str, ...]
    voxel_size_m: float
    origin_m: tuple[float, float, float]
    style: np.ndarray | None = None
    style_names: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.part.ndim != 3 or self.part.dtype != np.int16:
            raise ValueError(f"part must be a 3-D int16 array, got {self.part.dtype} {self.part.shape}")
        if self.style is not None and self.style.shape != self.part.shape:
            raise ValueError("style and part shapes differ")

    @property
    def occupancy(self) -> np.ndarray:
        """(X, Y, Z) bool: occupied voxels."""
        return self.part != EMPTY

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(self.part.shape)  # type: ignore[return-value]


# --------------------------------------------------------------------------- public API


def voxelize(source: SourceResult, settings: GridSettings, fit: FitMode, *,
             supersample: int | None = None) -> PartGrid:
    """Turn a source's parts into a ``PartGrid`` sized by ``settings`` and ``fit``.

    ``supersample`` overrides the automatic choice (4 when every grid side is
    ≤ 64, else 1) for mesh sources. Raises ``VoxelizeError`` when the grid
    would be too large or nothing is occupied.
    """
    if isinstance(source, PartVoxels):
        return _voxelize_voxels(source, settings, fit)
    if isinstance(source, PartMeshes):
        return _voxelize_meshes(source, settings, fit, supersample)
    raise TypeError(f"cannot voxelize a {type(source).__name__}")


def mesh_grid_shape(source: PartMeshes, settings: GridSettings, fit: FitMode) -> tuple[tuple[int, int, int], int]:
    """The coarse grid (X, Y, Z) that ``voxelize`` will give a mesh source, and its supersampling, without voxelizing.

    For a pre-flight memory estimate; raises ``VoxelizeError`` as ``voxelize`` would (no
    parts, coordinates not finite, zero extent, more than ``grid.max_cells``).
    """
    if not source.parts:
        raise VoxelizeError("the source has no parts", field="grid", hint="check the source")
    lo, hi = source.bounds_m()
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise VoxelizeError("the source's coordinates are not finite", field="grid", hint="check the source")
    dims = _grid_dims((hi - lo) / _fit_voxel_size(hi - lo, settings, fit, source.fit_height_m), settings, fit)
    return dims, COARSE_SUPERSAMPLE if max(dims) <= COARSE_MAX_SIDE else 1


def solid_occupancy(mesh: "trimesh.Trimesh", shape: tuple[int, int, int], origin_m, voxel_size_m: float,
                    supersample: int = 1) -> np.ndarray:
    """(X, Y, Z) float32 coverage in [0, 1]: fraction of each voxel's samples inside ``mesh``.

    ``shape`` is the grid in voxels, ``origin_m`` the min corner of voxel (0, 0, 0)
    and ``voxel_size_m`` its edge, metres. Each voxel is sampled at
    ``supersample``³ sub-voxel centres (1: the voxel centre only).
    """
    coverage, _ = _mesh_coverage(mesh, tuple(int(n) for n in shape), np.asarray(origin_m, float),
                                 float(voxel_size_m), int(supersample))
    return coverage


# --------------------------------------------------------------------------- grid sizing


def _fit_voxel_size(extent_m: np.ndarray, settings: GridSettings, fit: FitMode,
                    fit_height_m: float | None = None) -> float:
    """Edge of one voxel in metres for a shape of ``extent_m`` (3,) metres.

    ``fit_height_m`` replaces the Y extent for ``fit: height`` when the source
    names a reference height (text: the cap height).
    """
    if fit == FitMode.VOXEL_SIZE:
        if settings.voxel_size_m is None:
            raise VoxelizeError("fit: voxel_size needs grid.voxel_size_m", field="grid",
                                hint="set grid.voxel_size_m or use fit: longest")
        return float(settings.voxel_size_m)
    if fit == FitMode.HEIGHT:
        fitted, what = float(fit_height_m or extent_m[1]), "height (Y extent)"
    else:
        fitted, what = float(extent_m.max()), "size"
    voxel = fitted / settings.resolution
    if not (math.isfinite(voxel) and voxel > 0):
        raise VoxelizeError(f"the source has zero {what}, so it cannot be fitted to the grid", field="grid",
                            hint="use fit: longest for flat shapes, or check the source's size")
    return voxel


def _grid_dims(extent: np.ndarray, settings: GridSettings, fit: FitMode) -> tuple[int, int, int]:
    """Grid sides for a shape of ``extent`` (3,) voxels; refuses grids over ``max_cells``."""
    dims = tuple(max(1, math.ceil(float(e) - 1e-9)) for e in extent)
    if max(dims) > settings.max_cells:
        hint = "lower grid.resolution, use fit: longest, or raise grid.max_cells"
        if fit == FitMode.HEIGHT:
            hint = "lower grid.resolution or raise grid.max_cells (long text: split it over lines with '\\n')"
        elif fit == FitMode.VOXEL_SIZE:
            hint += ", or raise grid.voxel_size_m"
        raise VoxelizeError(
            f"the grid would be {dims[0]}×{dims[1]}×{dims[2]} voxels, more than grid.max_cells = "
            f"{settings.max_cells} along an axis", field="grid", hint=hint)
    return dims  # type: ignore[return-value]


# --------------------------------------------------------------------------- meshes


def _voxelize_meshes(source: PartMeshes, settings: GridSettings, fit: FitMode,
                     supersample: int | None) -> PartGrid:
    if not source.parts:
        raise VoxelizeError("the source has no parts", field="grid", hint="check the source")
    lo, hi = source.bounds_m()
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise VoxelizeError("the source's coordinates are not finite", field="grid", hint="check the source")
    voxel = _fit_voxel_size(hi - lo, settings, fit, source.fit_height_m)
    dims = _grid_dims((hi - lo) / voxel, settings, fit)
    origin = (lo + hi) / 2 - np.asarray(dims) * voxel / 2
    if supersample is None:
        supersample = COARSE_SUPERSAMPLE if max(dims) <= COARSE_MAX_SIDE else 1

    names = tuple(source.parts)
    vote = _LabelVote(dims, settings.min_coverage, settings.keep_thin)
    union = np.zeros(tuple(n * supersample for n in dims), dtype=bool)
    warnings: list[str] = []
    for index, (name, mesh) in enumerate(source.parts.items()):
        samples, watertight = _mesh_samples(mesh, dims, origin, voxel, supersample)
        if not watertight:
            warnings.append(f"part '{name}' is not watertight; filled by 3-axis ray-parity vote "
                            "(gaps narrower than a voxel are bridged)")
        union |= samples
        vote.add(index, _block_mean(samples, supersample))
    part = vote.finish(_block_mean(union, supersample))
    if not (part != EMPTY).any():
        raise VoxelizeError("the source voxelizes to nothing at this resolution", field="grid", hint=_NOTHING_HINT)
    for index, name in enumerate(names):
        if not (part == index).any():
            warnings.append(f"part '{name}' occupies no voxel at this resolution (it is thinner or smaller "
                            "than a voxel, or covered by other parts)")
    return PartGrid(part=part, part_names=names, voxel_size_m=voxel,
                    origin_m=tuple(float(v) for v in origin), warnings=tuple(warnings))


def _mesh_coverage(mesh, dims, origin, voxel, supersample) -> tuple[np.ndarray, bool]:
    samples, watertight = _mesh_samples(mesh, dims, origin, voxel, supersample)
    return _block_mean(samples, supersample), watertight


def _mesh_samples(mesh, dims, origin, voxel, supersample) -> tuple[np.ndarray, bool]:
    """(X·s, Y·s, Z·s) bool samples inside ``mesh``, and whether every component is watertight."""
    shape = tuple(int(n) * supersample for n in dims)
    faces = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    vertices = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
    if len(faces) == 0:
        return np.zeros(shape, dtype=bool), True
    # Sample units: sample (i, j, k) is centred at integer (i, j, k).
    tri = (vertices[faces] - np.asarray(origin, float)) * (supersample / voxel) - 0.5
    comp, comp_closed, comp_oriented = _components(vertices, faces)
    n_comp = len(comp_closed)
    order = np.argsort(comp, kind="stable")
    bounds = np.searchsorted(comp[order], np.arange(n_comp + 1))
    members = [order[bounds[c]:bounds[c + 1]] for c in range(n_comp)]

    count = np.zeros(shape, dtype=np.int16)
    closed = [c for c in range(n_comp) if comp_closed[c]]
    volumes = {c: _signed_volume(tri[members[c]]) for c in closed}
    # Only consistently oriented components have a meaningful volume sign.
    flip = -1.0 if sum(volumes[c] for c in closed if comp_oriented[c]) < 0 else 1.0
    # Solids first, so that each inward-facing component can ask whether it lies inside them.
    solids = [c for c in closed if not comp_oriented[c] or flip * volumes[c] >= 0]
    cavities = sorted(set(closed) - set(solids))
    for c in solids:
        _fill_into(count, tri[members[c]], vote=False, sign=1)
    for c in cavities:
        _fill_into(count, tri[members[c]], vote=False, sign=0)
    open_faces = [members[c] for c in range(n_comp) if not comp_closed[c]]
    if open_faces:
        _fill_into(count, tri[np.concatenate(open_faces)], vote=True, sign=1)
    return count > 0, not open_faces


def _fill_into(count: np.ndarray, tri: np.ndarray, *, vote: bool, sign: int) -> None:
    """Add the solid filled by triangles ``tri`` (F, 3, 3) to the signed ``count`` grid, in place.

    ``sign`` 1 adds; ``sign`` 0 means "a cavity": subtract where the filled
    samples mostly lie inside what is already counted, else add.
    """
    shape = np.asarray(count.shape)
    corners = tri.reshape(-1, 3)
    start = np.maximum(np.ceil(corners.min(axis=0)).astype(np.int64), 0)
    stop = np.minimum(np.floor(corners.max(axis=0)).astype(np.int64) + 1, shape)
    if np.any(stop <= start):
        return  # thinner than the sample spacing: no sample centre inside
    local_shape = tuple(int(n) for n in stop - start)
    local = tri - start.astype(np.float64)
    if vote:
        votes = sum(_parity_fill(local, local_shape, axis).view(np.uint8) for axis in range(3))
        solid = votes >= 2
    else:
        # Rays along the longest side: fewest columns, so fewest (triangle, ray) pairs;
        # ties go to z, whose result needs no transpose.
        solid = _parity_fill(local, local_shape, 2 - int(np.argmax(local_shape[::-1])))
    window = count[tuple(slice(a, b) for a, b in zip(start, stop))]
    if sign == 0:
        inside = np.count_nonzero((window > 0) & solid)
        sign = -1 if 2 * inside >= np.count_nonzero(solid) else 1
    # Whole-window add/subtract of the bool mask: much faster than boolean indexing.
    if sign > 0:
        window += solid
    else:
        window -= solid


def _signed_volume(tri: np.ndarray) -> float:
    """Signed volume enclosed by triangles (F, 3, 3); positive when the normals face outwards."""
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


def _components(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edge-connected components of a triangle mesh.

    Returns (F,) component id per face (numbered in order of first face), (C,)
    whether each component is closed (every edge used by exactly two faces) and
    (C,) whether it is consistently oriented (the two uses of each edge run in
    opposite directions). When the mesh is not closed as indexed, vertices are
    merged by exact position first, so unmerged meshes (e.g. raw STL) still connect.
    """
    edges = _edge_table(faces)
    if np.any(edges[2] != 2):
        _, vid = np.unique(vertices, axis=0, return_inverse=True)
        edges = _edge_table(vid.reshape(-1)[faces])
    edge_id, dir_flag, edge_uses = edges
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n_faces, n_edges = len(faces), len(edge_uses)
    face_of = np.repeat(np.arange(n_faces), 3)
    # Bipartite graph faces ↔ edges: faces sharing an edge end up in one component.
    graph = coo_matrix((np.ones(len(face_of), dtype=np.int8), (face_of, n_faces + edge_id)),
                       shape=(n_faces + n_edges, n_faces + n_edges))
    _, labels = connected_components(graph, directed=False)
    # Renumber components by first face so that ids are deterministic and dense.
    _, first, comp = np.unique(labels[:n_faces], return_index=True, return_inverse=True)
    comp = np.argsort(np.argsort(first))[comp]
    n_comp = len(first)
    forward = np.bincount(edge_id, weights=dir_flag, minlength=n_edges)
    bad_edge = np.bincount(comp[face_of], weights=edge_uses[edge_id] != 2, minlength=n_comp)
    bad_dir = np.bincount(comp[face_of], weights=forward[edge_id] != 1, minlength=n_comp)
    return comp, bad_edge == 0, bad_dir == 0


def _edge_table(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(3F,) undirected edge id per face edge, (3F,) 1.0 where it runs low→high index, (E,) uses per edge."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    _, edge_id, uses = np.unique(lo * (int(faces.max()) + 1) + hi, return_inverse=True, return_counts=True)
    return edge_id, (directed[:, 0] < directed[:, 1]).astype(np.float64), uses


def _parity_fill(tri: np.ndarray, shape: tuple[int, int, int], axis: int) -> np.ndarray:
    """(X, Y, Z) bool: samples inside the closed surface ``tri`` by ray parity along ``axis``.

    ``tri``: (F, 3, 3) float64 in sample units, sample (i, j, k) centred at (i, j, k).
    """
    perm = [a for a in range(3) if a != axis] + [axis]
    nu, nv, nw = (shape[a] for a in perm)
    t = tri[:, :, perm]
    # Moving the triangles by -shift is moving every ray by +shift.
    u = t[:, :, 0] - _RAY_SHIFT[0]
    v = t[:, :, 1] - _RAY_SHIFT[1]
    w = t[:, :, 2]
    area = (u[:, 1] - u[:, 0]) * (v[:, 2] - v[:, 0]) - (u[:, 2] - u[:, 0]) * (v[:, 1] - v[:, 0])
    i0 = np.maximum(np.ceil(u.min(axis=1)), 0).astype(np.int64)
    i1 = np.minimum(np.floor(u.max(axis=1)), nu - 1).astype(np.int64)
    j0 = np.maximum(np.ceil(v.min(axis=1)), 0).astype(np.int64)
    j1 = np.minimum(np.floor(v.max(axis=1)), nv - 1).astype(np.int64)
    cols_u = np.maximum(i1 - i0 + 1, 0)
    cols_v = np.maximum(j1 - j0 + 1, 0)
    pairs = cols_u * cols_v
    # Faces parallel to the ray (zero projected area) never cross it.
    live = np.flatnonzero((pairs > 0) & (area != 0))
    if len(live) == 0:
        return np.zeros(shape, dtype=bool)

    # Edge k runs from vertex k to vertex k+1; E_k(p) = a_k·p_u + b_k·p_v + c_k,
    # multiplied by the orientation sign so that inside means E_k > 0 for all k.
    sgn = np.sign(area[live])[:, None]
    uu, vv, ww = u[live], v[live], w[live]
    du = np.roll(uu, -1, axis=1) - uu
    dv = np.roll(vv, -1, axis=1) - vv
    ea, eb, ec = -dv * sgn, du * sgn, (dv * uu - du * vv) * sgn
    # Half-open rule for points exactly on an edge: keep the edge if its oriented
    # direction is "positive" (dv > 0, or dv == 0 and du > 0). Of two triangles
    # sharing an edge, exactly one gets it.
    odu, odv = du * sgn, dv * sgn
    edge_owned = (odv > 0) | ((odv == 0) & (odu > 0))

    hits: list[np.ndarray] = []
    counts = pairs[live]
    ends = np.cumsum(counts)
    begin = 0
    while begin < len(live):
        base = ends[begin - 1] if begin else 0
        end = max(int(np.searchsorted(ends, base + _CHUNK_PAIRS, side="right")), begin + 1)
        sel = np.arange(begin, end)
        n = counts[sel]
        tid = np.repeat(sel, n)
        offset = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
        cv = cols_v[live][tid]
        i = i0[live][tid] + offset // cv
        j = j0[live][tid] + offset % cv
        e = ea[tid] * i[:, None] + eb[tid] * j[:, None] + ec[tid]
        inside = np.all((e > 0) | ((e == 0) & edge_owned[tid]), axis=1)
        e, tid, i, j = e[inside], tid[inside], i[inside], j[inside]
        # Barycentric weight of the vertex opposite edge k is E_k / ΣE.
        depth = (e[:, 0] * ww[tid, 2] + e[:, 1] * ww[tid, 0] + e[:, 2] * ww[tid, 1]) / e.sum(axis=1)
        # A crossing at depth z toggles the first sample beyond it (half-open: z == k toggles k+1).
        k = np.maximum(np.floor(depth).astype(np.int64) + 1, 0)
        keep = k < nw
        hits.append(((i[keep] * nv + j[keep]) * nw + k[keep]))
        begin = end

    # Only the parity of each sample's crossing count matters. Counting the few
    # hits by sorting is ~25x faster at 256³ than np.bincount, whose grid-sized
    # int64 result costs more than all the ray work.
    where, uses = np.unique(np.concatenate(hits), return_counts=True)
    toggles = np.zeros(nu * nv * nw, dtype=np.uint8)
    toggles[where[(uses & 1) == 1]] = 1
    # uint8 wrap-around keeps parity (256 is even).
    parity = np.cumsum(toggles.reshape(nu, nv, nw), axis=2, dtype=np.uint8) & 1
    return parity.view(bool).transpose(np.argsort(perm))


def _block_mean(samples: np.ndarray, s: int) -> np.ndarray:
    """(X·s, Y·s, Z·s) bool → (X, Y, Z) float32 fraction of True per s³ block."""
    if s == 1:
        return samples.astype(np.float32)
    x, y, z = (n // s for n in samples.shape)
    counts = samples.reshape(x, s, y, s, z, s).sum(axis=(1, 3, 5), dtype=np.int32)
    return (counts / float(s ** 3)).astype(np.float32)


# --------------------------------------------------------------------------- labels


class _LabelVote:
    """Running per-voxel argmax over part coverages, plus the keep_thin candidates."""

    def __init__(self, dims, min_coverage: float, keep_thin: bool) -> None:
        self.min_coverage = min_coverage
        self.best = np.zeros(dims, dtype=np.float32)
        self.label = np.full(dims, EMPTY, dtype=np.int16)
        self.keep_thin = keep_thin
        # keep_thin: each part's cells at or above its own threshold, collected as parts arrive.
        self.thin = np.zeros(dims, dtype=bool)

    def add(self, index: int, coverage: np.ndarray) -> None:
        """Offer part ``index``'s (X, Y, Z) coverage; strictly larger wins, so ties keep the earlier part."""
        better = coverage > self.best
        # copyto with where= is several times faster than boolean indexing on big grids.
        np.copyto(self.best, coverage, where=better)
        np.copyto(self.label, np.int16(index), where=better)
        if self.keep_thin:
            top = float(coverage.max())
            if top > 0:
                self.thin |= coverage >= min(self.min_coverage, 0.5 * top) - _COVERAGE_EPS

    def finish(self, union: np.ndarray) -> np.ndarray:
        """(X, Y, Z) int16 labels: occupied where ``union`` ≥ ``min_coverage`` (or kept thin)."""
        occupied = (union >= self.min_coverage - _COVERAGE_EPS) | self.thin
        return np.where(occupied, self.label, np.int16(EMPTY)).astype(np.int16)


# --------------------------------------------------------------------------- voxels sources


def _voxelize_voxels(source: PartVoxels, settings: GridSettings, fit: FitMode) -> PartGrid:
    occupied = source.part != EMPTY
    if not occupied.any():
        raise VoxelizeError("the source voxelizes to nothing at this resolution", field="grid", hint=_NOTHING_HINT)
    nz = [np.flatnonzero(occupied.any(axis=tuple(b for b in range(3) if b != a))) for a in range(3)]
    start = np.array([idx[0] for idx in nz])
    crop = tuple(slice(idx[0], idx[-1] + 1) for idx in nz)
    part = source.part[crop]
    style = source.style[crop] if source.style is not None else None
    n_in = np.asarray(part.shape, dtype=np.float64)
    src_voxel = float(source.voxel_size_m)

    voxel = _fit_voxel_size(n_in * src_voxel, settings, fit)
    factor = voxel / src_voxel  # output voxel edge in input voxels
    if abs(factor - 1.0) < 1e-9:
        _grid_dims(n_in, settings, fit)
        return PartGrid(part=part.astype(np.int16), part_names=tuple(source.part_names), voxel_size_m=src_voxel,
                        origin_m=tuple(float(v) for v in start * src_voxel),
                        style=None if style is None else style.astype(np.int16),
                        style_names=tuple(source.style_names))

    dims = _grid_dims(n_in / factor, settings, fit)
    # Output grid centred on the cropped input, in input-voxel units from the crop's corner.
    out_start = n_in / 2 - np.asarray(dims) * factor / 2
    weights = [_overlap_matrix(dims[a], int(n_in[a]), out_start[a], factor) for a in range(3)]
    cell = factor ** 3

    def coverage_of(mask: np.ndarray) -> np.ndarray:
        return (_separable(mask.astype(np.float32), weights) / cell).astype(np.float32)

    vote = _LabelVote(dims, settings.min_coverage, settings.keep_thin)
    for index in range(len(source.part_names)):
        mask = part == index
        if mask.any():
            vote.add(index, coverage_of(mask))
    labels = vote.finish(coverage_of(part != EMPTY))
    if not (labels != EMPTY).any():
        raise VoxelizeError("the source voxelizes to nothing at this resolution", field="grid", hint=_NOTHING_HINT)
    out_style = None
    if style is not None:
        style_vote = _LabelVote(dims, settings.min_coverage, keep_thin=False)
        for index in range(len(source.style_names)):
            mask = style == index
            if mask.any():
                style_vote.add(index, coverage_of(mask))
        out_style = np.where(labels != EMPTY, style_vote.label, np.int16(EMPTY)).astype(np.int16)
    origin = (start + out_start) * src_voxel
    return PartGrid(part=labels, part_names=tuple(source.part_names), voxel_size_m=voxel,
                    origin_m=tuple(float(v) for v in origin), style=out_style,
                    style_names=tuple(source.style_names))


def _overlap_matrix(n_out: int, n_in: int, start: float, step: float) -> np.ndarray:
    """(n_out, n_in) float32: length of output cell [start + d·step, +step) ∩ input cell [c, c+1)."""
    lo = start + np.arange(n_out)[:, None] * step
    c = np.arange(n_in)[None, :]
    return np.clip(np.minimum(lo + step, c + 1) - np.maximum(lo, c), 0, None).astype(np.float32)


def _separable(volume: np.ndarray, weights: list[np.ndarray]) -> np.ndarray:
    """Apply one (n_out, n_in) matrix per axis to an (X, Y, Z) volume → (X', Y', Z')."""
    out = volume
    for w in weights:
        # Contracting axis 0 appends the new axis last, so after three steps the order is x, y, z again.
        out = np.tensordot(out, w, axes=([0], [1]))
    return out

"""Decimation: a closed triangle mesh down to a triangle budget, kept closed (and 2-manifold where it can be).

Quadric decimation by meshoptimizer's simplifier (``decimate_kept``), then two repairs of what strong
decimation occasionally leaves: back-to-back triangles on the same three vertices (``drop_coincident_faces``)
and two sheets brought together along an edge or at a vertex (``split_pinches``; the edges a split cannot
part are collapsed, ``close_pinches``). Works in any length unit (the simplifier's
error is relative to the mesh's extent); ``pipeline/mesh.py`` calls it in fine-voxel units, the LOD chain
(``pipeline/engines.py``) in metres.
"""

from __future__ import annotations

import numpy as np

from core.errors import MeshingError

#: Largest error meshoptimizer's simplifier may make, relative to the mesh's extent: high enough that the
#: triangle count, not the error, decides where it stops (as with a ``max_triangles`` budget).
DECIMATE_MAX_ERROR = 1.0


def decimate(verts: np.ndarray, faces: np.ndarray, target: int,
             lock_border: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Quadric decimation (meshoptimizer) to at most ``target`` faces (voxel units in, voxel units out).

    See ``decimate_kept``; returns the kept (V', 3) vertices and the (F', 3) faces into them.
    """
    kept, out_f = decimate_kept(verts, faces, target, lock_border)
    return np.asarray(verts, dtype=np.float64)[kept], out_f


def decimate_kept(verts: np.ndarray, faces: np.ndarray, target: int,
                  lock_border: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Quadric decimation to at most ``target`` faces: (V',) indices of the input vertices kept (in input
    order, then the copies ``close_pinches`` made) and (F', 3) int64 faces into them (so vertex attributes
    follow by indexing).

    The simplifier keeps the mesh's topology; ``lock_border`` keeps every vertex on an open
    boundary where it is (a block's side that another block continues).

    Raises:
        MeshingError: the simplifier failed, could not reach ``target``, or left nothing.
    """
    import meshoptimizer

    indices = np.ascontiguousarray(faces, dtype=np.uint32).reshape(-1)
    out = np.empty_like(indices)
    options = meshoptimizer.SIMPLIFY_LOCK_BORDER if lock_border else 0
    try:
        count = meshoptimizer.simplify(out, indices, np.ascontiguousarray(verts, dtype=np.float32),
                                       target_index_count=3 * target, target_error=DECIMATE_MAX_ERROR,
                                       options=options)
    except (ValueError, RuntimeError) as exc:
        raise MeshingError(f"decimation failed: {exc}", field="export.max_triangles",
                           hint="set export.max_triangles: null to skip it") from None
    out_f = drop_coincident_faces(out[:count].reshape(-1, 3).astype(np.int64))
    if len(out_f) > target:
        raise MeshingError(
            f"could not decimate below {len(out_f)} triangles (max_triangles is {target})",
            field="export.max_triangles", hint="raise export.max_triangles or set it to null",
        )
    if len(out_f) == 0:
        raise MeshingError(f"decimation to {target} triangles left nothing", field="export.max_triangles",
                           hint="raise export.max_triangles")
    kept, inverse = np.unique(out_f, return_inverse=True)
    source, faces_out = close_pinches(inverse.reshape(-1, 3).astype(np.int64),
                                      np.asarray(verts, dtype=np.float64)[kept])
    return kept[source], faces_out


def edge_groups(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Half-edges grouped by undirected edge: (order (3F,) half-edges sorted by edge, group starts, counts).
    Half-edge c runs from corner c (``faces.reshape(-1)[c]``) to the next corner of its face."""
    start = faces.reshape(-1)
    corner = np.arange(len(start))
    end = start[3 * (corner // 3) + (corner + 1) % 3]
    key = np.minimum(start, end) * np.int64(n_vertices) + np.maximum(start, end)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    starts = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
    return order, starts, np.diff(np.r_[starts, len(key)])


def split_pinches(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Give each sheet of a pinch its own vertices, so that fewer edges are used by more than two faces.

    Decimation sometimes brings two parts of a closed surface together along an edge (the edge then
    belongs to four faces) or at a vertex: the mesh stays closed but is no longer a 2-manifold, and readers
    that check (trimesh's ``is_watertight``, engines' collision cookers) refuse it. A vertex's faces are
    grouped into fans, two faces being in one fan when they share an edge through the vertex that only they
    use; the first fan keeps the vertex, each further fan gets a copy at the same position. Where the sheets
    cross along the edge (one sheet's fans at its two ends hold different faces), splitting would open holes:
    such an edge's faces stay joined. Geometry is unchanged, and no edge ends up in fewer than two faces.

    Args:
        faces: (F, 3) int64 vertex indices.
        n_vertices: how many vertices the faces index.
    Returns:
        (V',) int64 the original vertex of each output vertex (the first ``n_vertices`` are the identity,
        copies come after them) and (F, 3) the faces into the output vertices.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    unchanged = np.arange(n_vertices), faces
    if len(faces) == 0:
        return unchanged
    order, starts, counts = edge_groups(faces, n_vertices)
    if (counts == 2).all():
        return unchanged  # every edge in two faces: nothing pinched along an edge
    start = faces.reshape(-1)
    corner = np.arange(len(start))
    nxt = 3 * (corner // 3) + (corner + 1) % 3
    # an edge used by exactly two faces joins, for each of its two vertices, the corners holding it in them
    # (half-edge c runs from corner c to corner nxt[c])
    e1, e2 = order[starts[counts == 2]], order[starts[counts == 2] + 1]
    flipped = start[e1] == start[e2]  # the two faces wind the edge the same way (not outward-consistent)
    rows = [e1, nxt[e1]]
    cols = [np.where(flipped, e2, nxt[e2]), np.where(flipped, nxt[e2], e2)]
    group_of = np.empty(len(start), dtype=np.int64)  # half-edge → its edge's group
    group_of[order] = np.repeat(np.arange(len(starts)), counts)
    for _ in range(8):
        graph = coo_matrix((np.ones(sum(len(r) for r in rows), dtype=np.int8),
                            (np.concatenate(rows), np.concatenate(cols))), shape=(len(start), len(start)))
        _, fan = connected_components(graph, directed=False)
        # per vertex, its fans in order of their first corner: the first keeps the vertex, the others are copies
        fan_first = np.full(fan.max() + 1, len(start), dtype=np.int64)
        np.minimum.at(fan_first, fan, corner)
        fan_vertex = start[fan_first]
        by_vertex = np.lexsort((fan_first, fan_vertex))
        keeps = np.r_[True, fan_vertex[by_vertex][1:] != fan_vertex[by_vertex][:-1]]
        new_id = np.empty(len(fan_first), dtype=np.int64)
        new_id[by_vertex[keeps]] = fan_vertex[by_vertex[keeps]]
        extra = by_vertex[~keeps]
        new_id[extra] = n_vertices + np.arange(len(extra))
        out_faces = new_id[fan].reshape(-1, 3)
        out_order, out_starts, out_counts = edge_groups(out_faces, n_vertices + len(extra))
        lone = out_order[out_starts[out_counts == 1]]  # half-edges whose edge the split left open
        lone = lone[counts[group_of[lone]] > 1]  # (an edge in one face from the start is an open border)
        if len(lone) == 0:
            return np.concatenate([np.arange(n_vertices), fan_vertex[extra]]), out_faces
        # those edges' faces were tangled: join all of them at both ends and split again
        tangled = np.isin(group_of, np.unique(group_of[lone]))
        h = np.flatnonzero(tangled)
        h = h[np.argsort(group_of[h], kind="stable")]
        first_of = np.r_[True, group_of[h][1:] != group_of[h][:-1]]
        lead = h[first_of][np.cumsum(first_of) - 1]  # the group's first half-edge, for every member
        same = start[h] == start[lead]
        rows += [h, nxt[h]]
        cols += [np.where(same, lead, nxt[lead]), np.where(same, nxt[lead], lead)]
    return unchanged


#: Most rounds of ``close_pinches`` (a round changes edges that share no vertex; two close the showcase's).
CLOSE_ROUNDS = 8


def close_pinches(faces: np.ndarray, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``split_pinches``, then collapse or flip the edges it could not part, until every edge is in two faces.

    An edge still used by four faces after the split has, at each of its two ends, all four faces in one
    fan: the sheets meet there in a way no copy of vertices separates. Such an edge is collapsed onto the
    end whose move turns none of the faces around the other end over (the edge's own faces become
    degenerate and go); when both would fold a face, two of its faces (one winding it each way) get their
    shared edge flipped instead (``_flip_one_pair``: no vertex moves). Up to ``CLOSE_ROUNDS`` rounds, each
    over edges with no vertex near another's change (no second split: each costs a pass over the mesh, and a
    vertex a collapse pinched leaves every edge in two faces, so the mesh stays watertight). A vertex on
    an open boundary (a block's side, welded to the next block's later) never moves, and an edge in an odd
    number of faces (next to a hole) is left. The collapsed edges are 1–5 fine voxels long on the showcase.
    Vertices stay input vertices.

    Args:
        faces: (F, 3) int64 indices into ``vertices``; vertices: (V, 3) float positions.
    Returns:
        (V',) int64 the input vertex of each output vertex (copies at the same position included; vertices
        no face uses any more are dropped) and (F', 3) faces into the output vertices.
    """
    source, faces = split_pinches(faces, len(vertices))
    for _ in range(CLOSE_ROUNDS):
        order, starts, counts = edge_groups(faces, len(source))
        stuck = np.flatnonzero((counts > 2) & (counts % 2 == 0))  # an odd count borders a hole: left
        if len(stuck) == 0:
            break
        remap = np.arange(len(source))
        corners = faces.reshape(-1)
        # vertices on an open boundary (a block's side that the next block continues) never move
        border = order[starts[counts == 1]]
        pinned = set(corners[border].tolist()) | set(corners[3 * (border // 3) + (border + 1) % 3].tolist())
        busy: set[int] = set()  # vertices next to a change of this round: their edges wait for the next
        for g in stuck:
            h = order[starts[g]]
            a, b = int(corners[h]), int(corners[3 * (h // 3) + (h + 1) % 3])
            if a in busy or b in busy:
                continue
            for keep, gone in ((min(a, b), max(a, b)), (max(a, b), min(a, b))):
                if gone not in pinned and not _folds(faces, vertices[source], gone, keep):
                    remap[gone] = keep
                    busy.update(faces[(faces == gone).any(axis=1)].reshape(-1).tolist())
                    break
            else:  # both collapses fold a face: flip the edge between two of its faces instead
                flipped = _flip_one_pair(faces, vertices[source], order[starts[g]:starts[g] + counts[g]])
                busy.update(flipped + [a, b] if flipped else [])
        if not busy:
            break
        faces = drop_coincident_faces(remap[faces])
    used, faces = np.unique(faces, return_inverse=True)
    return source[used], faces.reshape(-1, 3)


def _flip_one_pair(faces: np.ndarray, positions: np.ndarray, half_edges: np.ndarray) -> list[int]:
    """Flip the shared edge of one pair of the faces around an edge (one winding it each way), in place.

    Faces (a, b, c) and (b, a, d) become (c, a, d) and (d, b, c): the edge (a, b) keeps the other faces,
    every other edge its count, and no vertex moves. The pair taken is the first (in order) whose new edge
    (c, d) is not already an edge and whose flip turns neither face over. Returns [c, d] (the flipped pair's
    other corners), or [] when no pair could be flipped.
    """
    face = half_edges // 3
    a = faces.reshape(-1)[half_edges]
    forward, backward = face[a == a[0]], face[a != a[0]]
    for f in forward:
        for g in backward:
            i = int(np.flatnonzero(faces[f] == a[0])[0])
            va, vb, c = faces[f, i], faces[f, (i + 1) % 3], faces[f, (i + 2) % 3]
            d = int(np.setdiff1d(faces[g], (va, vb))[0])
            if c == d or ((faces == c).any(axis=1) & (faces == d).any(axis=1)).any():
                continue
            new = np.array([(c, va, d), (d, vb, c)])
            if (np.einsum("ij,ij->i", _normals(positions[new]), _normals(positions[faces[[f, g]]])) <= 0).any():
                continue
            faces[f], faces[g] = new
            return [int(c), d]
    return []


def _folds(faces: np.ndarray, positions: np.ndarray, gone: int, keep: int) -> bool:
    """Whether moving vertex ``gone`` onto ``keep`` turns one of ``gone``'s other faces over (or flat)."""
    around = faces[(faces == gone).any(axis=1) & ~(faces == keep).any(axis=1)]
    if len(around) == 0:
        return False
    before = positions[around]
    after = np.where((around == gone)[:, :, None], positions[keep], before)
    return bool((np.einsum("ij,ij->i", _normals(before), _normals(after)) <= 0).any())


def _normals(corners: np.ndarray) -> np.ndarray:
    """(n, 3) unnormalised normals of triangles given by their (n, 3, 3) corner positions (right hand)."""
    return np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])


def drop_coincident_faces(faces: np.ndarray) -> np.ndarray:
    """(F', 3) faces without degenerate faces, and with each set of faces on the same three vertices resolved.

    Strong decimation occasionally folds a thin spot into two back-to-back triangles on the same three
    vertices (a zero-volume fin); their edges are then used four times and the mesh is no longer watertight:
    such pairs cancel (both go). It also leaves, rarely, a triangle twice with the same winding, where the
    surface needs one of them: removing both would open a hole (3 open edges each, seen on the batch's
    mushrooms and signs). So per set of faces on the same vertices, the windings are summed (+1 for one
    orientation, −1 for the other): a sum of 0 drops them all, any other keeps one face, wound as the sum.
    """
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    if len(faces) == 0:
        return faces
    key = np.sort(faces, axis=1)
    if int(key[:, 2].max()) < (1 << 21):
        # One int64 per triangle: a 1-D unique is several times faster than axis=0.
        key = (key[:, 0] << 42) | (key[:, 1] << 21) | key[:, 2]
        _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    else:
        _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    if (counts == 1).all():
        return faces
    # winding: +1 when (a, b, c) is a rotation of its sorted order, −1 otherwise
    low = np.argmin(faces, axis=1)
    after_low = faces[np.arange(len(faces)), (low + 1) % 3]
    winding = np.where(after_low < faces[np.arange(len(faces)), (low + 2) % 3], 1, -1)
    net = np.zeros(len(counts), dtype=np.int64)
    np.add.at(net, inverse, winding)
    keep = counts[inverse] == 1
    # of a set that does not cancel, the first face wound as the sum stays
    shared = np.flatnonzero((counts[inverse] > 1) & (net[inverse] != 0) & (winding == np.sign(net[inverse])))
    keep[shared[np.unique(inverse[shared], return_index=True)[1]]] = True
    return faces[keep]



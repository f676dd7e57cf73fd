"""Expansion moves: grow whole regions that copy one exemplar offset, by minimum cuts (graphcut textures).

Role: the search's coarse-to-region step. A *label* is (exemplar table,
symmetry, offset t): cell q with that label copies the entry at transformed
source cell q + t. Two 6-neighbours continue each other exactly when they
have the same label, so the energy of ``model.quilt.search`` is a labelling
problem with a Potts-like seam term, and single-cell updates (ICM,
PatchMatch) stall at 40–50 % continuation: one cell cannot agree with two
neighbours that disagree.

An α-expansion (Boykov, Veksler & Zabih 2001; Kwatra et al. 2003 for
textures) lets every cell where α is valid (an entry exists at q + t and the
cell's style is α's exemplar) switch to α at once; the best such switch is a
minimum s–t cut (``scipy.sparse.csgraph.maximum_flow``) over those cells.
Costs are integers; a pair term that would make the cut non-submodular is
clipped at 0 (with ``SEAM_BREAK`` ≥ ``SEAM_WEIGHT`` the seam cost satisfies
the triangle inequality and nothing is clipped); when a term was clipped, the
move is kept only if the exact energy of the switched cells and their pairs
does not rise. Costs of the current field are kept up to date
(``FieldCosts``) rather than recomputed, and cells that cannot gain from α
whatever their neighbours do are left out of the graph (exact pruning).

Proposals: the labels of each cell's few nearest entries and of the current
field, by how many cells vote for them (most first, ties by label value),
over ``ROUNDS`` rounds. Deterministic.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, maximum_flow

from model.quilt import search
from model.quilt.library import Library
from model.quilt.search import UNIT, Content, seam, total_energy, unary

#: Nearest entries per cell that vote for proposal labels.
VOTERS = 4
#: Proposals per round: a base number plus one per this many cells.
PROPOSALS_BASE = 48
PROPOSALS_PER_CELLS = 6
#: Expansion rounds over the proposals.
ROUNDS = 1
_T_BITS = 12  # offsets are stored + 2048 in 12 bits per axis


def label_keys(content: Content, lib: Library, cells: np.ndarray, entries: np.ndarray) -> np.ndarray:
    """int64 label keys (table, symmetry, offset) of ``entries`` used at content ``cells`` (−1 entries → −1)."""
    t = lib.pos[np.maximum(entries, 0)].astype(np.int64) - content.cells[cells] + (1 << (_T_BITS - 1))
    key = (lib.style[np.maximum(entries, 0)].astype(np.int64) * 8 + lib.sym[np.maximum(entries, 0)]) << (3 * _T_BITS)
    key |= (t[:, 0] << (2 * _T_BITS)) | (t[:, 1] << _T_BITS) | t[:, 2]
    return np.where(entries >= 0, key, -1)


def label_entries(content: Content, lib: Library, key: int) -> np.ndarray:
    """(N,) the entry label ``key`` gives every content cell, −1 where it has none or the style differs.

    Only cells q with q + t inside the exemplar's coarse grid can have one: they are read from the
    content's id grid over that box, so a proposal costs O(exemplar cells), not O(content cells).
    """
    mask = (1 << _T_BITS) - 1
    t = np.array([(key >> (2 * _T_BITS)) & mask, (key >> _T_BITS) & mask, key & mask]) - (1 << (_T_BITS - 1))
    ts = key >> (3 * _T_BITS)
    table, sym = ts // 8, ts % 8
    out = np.full(len(content), -1, dtype=np.int64)
    n = lib.index_maps[table].shape[1]
    lo = np.maximum(-t, 0)
    hi = np.minimum(n - t, content.shape)
    if (hi <= lo).any():
        return out
    ids = content.ids[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    idx = ids[ids >= 0]
    idx = idx[content.table[idx] == table]
    if len(idx):
        p = content.cells[idx] + t
        out[idx] = lib.index_maps[table][sym, p[:, 0], p[:, 1], p[:, 2]]
    return out


class FieldCosts:
    """The current field with its unary cost per cell and its seam cost per (cell, face), kept up to date.

    Expansions read the current costs from here instead of recomputing them; ``switch`` updates
    the switched cells and the pairs they belong to (V is symmetric: V(x@q, y@q+d) = V(y@r, x@r−d)).
    """

    def __init__(self, content: Content, lib: Library, field: np.ndarray) -> None:
        self.content, self.lib, self.field = content, lib, field
        n = len(content)
        self.u = unary(content, lib, np.arange(n), field[:, None])[:, 0]
        self.v = np.zeros((n, 6), dtype=np.int64)
        qi, di = np.nonzero(content.nb >= 0)
        self.v[qi, di] = seam(lib, field[qi], field[content.nb[qi, di]], di)

    def switch(self, cells: np.ndarray, entries: np.ndarray, u_new: np.ndarray) -> None:
        self.field[cells] = entries
        self.u[cells] = u_new
        nb = self.content.nb[cells]
        qi, di = np.nonzero(nb >= 0)
        q, r = cells[qi], nb[qi, di]
        v = seam(self.lib, self.field[q], self.field[r], di)
        self.v[q, di] = v
        self.v[r, di ^ 1] = v

    def local_sum(self, cells: np.ndarray, changed: np.ndarray) -> int:
        """Σ U over ``cells`` plus Σ V over the pairs with an end among them (each pair once)."""
        nb = self.content.nb[cells]
        qi, di = np.nonzero(nb >= 0)
        once = ~changed[nb[qi, di]] | (di % 2 == 1)
        return int(self.u[cells].sum()) + int(self.v[cells[qi[once]], di[once]].sum())


def _sum_by(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """(n,) int64 sums of integer ``values`` per ``index`` (exact: np.add.at, no float weights)."""
    out = np.zeros(n, dtype=np.int64)
    np.add.at(out, index, values)
    return out


def expand(costs: FieldCosts, alpha: np.ndarray) -> int:
    """One α-expansion in place (``alpha``: the entry α gives each cell, −1 none); returns cells switched."""
    move = best_switch(costs, alpha)
    return 0 if move is None else apply_switch(costs, alpha, *move)


def best_switch(costs: FieldCosts, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool] | None:
    """The optimal α-switch of the current field, not applied: (cells that take α, their unary cost
    under α, whether a pair term was clipped), or None when no cell switches.

    Binary choice per node (cells where α is valid and new): x = 0 keeps the entry, x = 1 takes α.
    A pair term with E(0,0)=A, E(0,1)=B, E(1,0)=C, E(1,1)=0 (α continues α) is
    A + (C−A)·x_q − C·x_r + (B+C−A)·(1−x_q)·x_r: linear parts go to the terminal edges, the
    last one is an edge q → r. Pairs with a fixed cell are unary terms of the node. The cut's
    source side is the set reachable from s in the residual graph (the smallest minimum cut), which
    does not depend on the flow found: so a graph of disjoint parts gives each part its own cut.
    """
    content, lib, field = costs.content, costs.lib, costs.field
    idx = np.flatnonzero((alpha >= 0) & (alpha != field))
    if len(idx) == 0:
        return None
    u1 = unary(content, lib, idx, alpha[idx][:, None])[:, 0]
    # The most switching q can save is, per neighbour, its current seam cost, or the largest seam cost
    # when the neighbour may switch too (then q's old entry would meet α). A cell whose unary rise
    # under α is at least that keeps its entry in an optimal cut: leave it out of the graph.
    r_all = content.nb[idx]
    may = (r_all >= 0) & (alpha[np.maximum(r_all, 0)] >= 0) & (alpha[np.maximum(r_all, 0)] != field[np.maximum(r_all, 0)])
    v_max = int(np.ceil((search.SEAM_BREAK + search.SEAM_WEIGHT) * UNIT)) + 1  # the largest V can be
    saving = np.where(may, v_max, costs.v[idx]).sum(axis=1)
    hopeful = u1 - costs.u[idx] < saving
    idx, u1 = idx[hopeful], u1[hopeful]
    n = len(idx)
    if n == 0:
        return None
    nid = np.full(len(content), -1, dtype=np.int64)
    nid[idx] = np.arange(n)
    nb = content.nb[idx]
    qi, di = np.nonzero(nb >= 0)
    rr = nb[qi, di]
    c_ = seam(lib, alpha[idx[qi]], field[rr], di)  # q takes α, r keeps its entry
    a_ = costs.v[idx[qi], di]  # both keep
    delta = u1 - costs.u[idx] + _sum_by(qi, c_ - a_, n)  # (C − A) for every pair of a node
    both = (nid[rr] >= 0) & (di % 2 == 1)  # node–node pairs once, q below r
    if both.any():
        b_q, b_r, b_d = idx[qi[both]], rr[both], di[both]
        b_ = seam(lib, field[b_q], alpha[b_r], b_d)
        delta -= _sum_by(nid[b_r], c_[both], n)
        edge = b_ + c_[both] - a_[both]
        clipped = bool((edge < 0).any())
    else:
        edge, clipped = np.zeros(0, dtype=np.int64), False
    # node–node pairs seen from the upper cell (d even) were counted above as if r were fixed: undo
    upper = (nid[rr] >= 0) & (di % 2 == 0)
    delta -= _sum_by(qi[upper], c_[upper] - a_[upper], n)
    if not (delta < 0).any():
        return None  # no node gains on its own terms: nothing reaches the sink, the cut keeps everything
    s, t = n, n + 1
    src, snk = np.flatnonzero(delta > 0), np.flatnonzero(delta < 0)
    u = np.concatenate([np.full(len(src), s), snk, qi[both]])
    v = np.concatenate([src, np.full(len(snk), t), nid[rr[both]]])
    cap = np.concatenate([delta[src], -delta[snk], np.maximum(edge, 0)])
    keep = cap > 0
    cap = np.minimum(cap[keep], np.iinfo(np.int32).max // 8).astype(np.int32)
    graph = coo_matrix((cap, (u[keep], v[keep])), shape=(n + 2, n + 2)).tocsr()
    flow = maximum_flow(graph, s, t, method="dinic").flow
    residual = (graph - flow).tocsr()
    residual.data = (residual.data > 0).astype(np.int8)
    residual.eliminate_zeros()
    reach = breadth_first_order(residual, s, directed=True, return_predecessors=False)
    sink_side = np.ones(n + 2, dtype=bool)
    sink_side[reach] = False
    chosen = np.flatnonzero(sink_side[:n])
    if len(chosen) == 0:
        return None
    return idx[chosen], u1[chosen], clipped


def apply_switch(costs: FieldCosts, alpha: np.ndarray, switch: np.ndarray, u_new: np.ndarray,
                 clipped: bool) -> int:
    """Switch cells ``switch`` to α (``best_switch``'s move) in place; returns how many switched. A move
    cut on a clipped energy is kept only if the true energy of the cells and their pairs did not rise."""
    if not clipped:
        costs.switch(switch, alpha[switch], u_new)
        return len(switch)
    changed = np.zeros(len(costs.content), dtype=bool)
    changed[switch] = True
    before, old, old_u = costs.local_sum(switch, changed), costs.field[switch].copy(), costs.u[switch].copy()
    costs.switch(switch, alpha[switch], u_new)
    if costs.local_sum(switch, changed) > before:
        costs.switch(switch, old, old_u)
        return 0
    return len(switch)


def proposals(content: Content, lib: Library, field: np.ndarray, knn: np.ndarray) -> list[int]:
    """Label keys to try, most voted first (votes: each cell's ``VOTERS`` nearest entries and its current one)."""
    cells = np.arange(len(content))
    keys = [label_keys(content, lib, cells, field)]
    for j in range(min(VOTERS, knn.shape[1])):
        keys.append(label_keys(content, lib, cells, knn[:, j]))
    keys = np.concatenate(keys)
    keys = keys[keys >= 0]
    uniq, counts = np.unique(keys, return_counts=True)
    order = np.lexsort((uniq, -counts))
    m = PROPOSALS_BASE + len(content) // PROPOSALS_PER_CELLS
    return [int(k) for k in uniq[order[:m]] if counts[np.searchsorted(uniq, k)] > 1]


def commuting_levels(content: Content, supports: list[np.ndarray]) -> list[list[int]]:
    """The proposals (by their ``supports``: cells where each gives an entry) in levels of moves that commute.

    An expansion reads and writes the field and its costs only on its support and the support's
    6-neighbours (its *reach*). Two proposals whose reaches are disjoint give the same result in
    either order, and their graphs share no node or edge. Proposal j goes one level above the highest
    earlier proposal whose reach meets its own, so running the levels in order, each level's
    proposals together, is exactly running them one by one in list order. Returns the levels, each
    a list of proposal indices in list order.
    """
    level_at = np.full(len(content), -1, dtype=np.int64)  # highest level whose reach holds the cell
    levels: list[list[int]] = []
    for i, cells in enumerate(supports):
        nb = content.nb[cells]
        reach = np.concatenate([cells, nb[nb >= 0]])
        level = int(level_at[reach].max()) + 1 if len(reach) else 0
        level_at[reach] = level
        if level == len(levels):
            levels.append([])
        levels[level].append(i)
    return levels


def expansion_moves(content: Content, lib: Library, field: np.ndarray, knn: np.ndarray,
                    rounds: int = ROUNDS) -> list[float]:
    """Run expansion rounds in place; returns the total energy after each round.

    Each round tries the proposals in order; proposals that commute (``commuting_levels``) are cut
    as one graph of disjoint parts — the same result as one by one, in fewer, larger cuts (a cut's
    fixed cost, ~0.4 ms in scipy, dominates graphs of ~130 nodes). When a part's pair term had to be
    clipped, the level's proposals are run one by one instead (each keeps or drops its own move).
    """
    history = []
    costs = FieldCosts(content, lib, field)
    for _ in range(rounds):
        switched = 0
        supports, values = [], []  # per proposal: the cells it gives an entry, and those entries
        for key in proposals(content, lib, field, knn):
            entries = label_entries(content, lib, key)
            supports.append(np.flatnonzero(entries >= 0))
            values.append(entries[supports[-1]])

        def alpha_of(level: list[int]) -> np.ndarray:
            alpha = np.full(len(content), -1, dtype=np.int64)
            for i in level:
                alpha[supports[i]] = values[i]
            return alpha
        for level in commuting_levels(content, supports):
            alpha = alpha_of(level)
            move = best_switch(costs, alpha)
            if move is None:
                continue
            if move[2] and len(level) > 1:
                switched += sum(expand(costs, alpha_of([i])) for i in level)
            else:
                switched += apply_switch(costs, alpha, *move)
        history.append(total_energy(content, lib, field))
        if switched == 0:
            break
    return history

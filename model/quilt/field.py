"""The coherent search: optimise which exemplar cell each surface cell of the content copies.

Minimises the energy E of ``model/quilt/search.py`` over the source field.
Optimisation (deterministic for a given content, library and seed):

1. candidates: each cell's ``K_NEAREST`` entries by U (``nearest_entries``: one
   exact matrix product per style, part and distinct neighbourhood, ties in a
   seeded order); start from the best;
2. graph-cut expansion moves (``model.quilt.graphcut``): whole regions switch
   to one exemplar offset at once; this is what makes neighbours continue
   each other (single-cell updates stall at 40–50 % continuation);
3. ``ITERATIONS`` PatchMatch-style sweeps over the two colours of a 3-D
   checkerboard (6-neighbours always have the other colour, so each update
   lowers E exactly): proposals are the current entry, the continuations of
   the 6 neighbours (propagation), ``RANDOM_KNN`` random picks among the K
   nearest and ``RANDOM_LOCAL`` random jumps around the current source cell
   (random search).
"""

from __future__ import annotations

import numpy as np

from model.quilt.graphcut import expansion_moves
from model.quilt.library import Library
from model.quilt.search import (
    EXPANSIONS,
    ITERATIONS,
    RANDOM_KNN,
    RANDOM_LOCAL,
    Content,
    SearchResult,
    continuation,
    local_energy,
    nearest_entries,
    total_energy,
)


def search(content: Content, lib: Library, seed: int, iterations: int = ITERATIONS) -> SearchResult:
    """The optimised source field of ``content`` (see the module docstring and ``model/quilt/search.py``)."""
    rng = np.random.default_rng([int(seed), 0x51_17])
    knn = nearest_entries(content, lib, rng)
    field = knn[:, 0].copy()
    energies = [total_energy(content, lib, field)]
    if EXPANSIONS:
        energies += expansion_moves(content, lib, field, knn)
    colour = content.cells.sum(axis=1) % 2
    for it in range(iterations):
        radius = max(1, 4 >> it)
        for c in (it % 2, 1 - it % 2):
            q = np.flatnonzero(colour == c)
            if len(q) == 0:
                continue
            props = [field[q][:, None]]
            for d in range(6):  # continuation of the neighbour across face d (it sits at q + dir(d))
                r = content.nb[q, d]
                prop = np.where(r >= 0, lib.shift[field[np.maximum(r, 0)], d ^ 1], -1)
                props.append(prop[:, None])
            props.append(knn[q[:, None], rng.integers(0, knn.shape[1], size=(len(q), RANDOM_KNN))])
            cur = field[q]
            for _ in range(RANDOM_LOCAL):
                jump = rng.integers(-radius, radius + 1, size=(len(q), 3))
                props.append(lib.lookup(lib.style[cur], lib.sym[cur], lib.pos[cur].astype(np.int64) + jump)[:, None])
            cand = np.concatenate(props, axis=1)
            energy = local_energy(content, lib, field, q, cand)
            field[q] = cand[np.arange(len(q)), energy.argmin(axis=1)]
        energies.append(total_energy(content, lib, field))
    return SearchResult(field=field, energies=energies, continuation=continuation(content, lib, field))

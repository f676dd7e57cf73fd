"""Procedural buildings, plants, cakes and crystals for the ``things`` style set.

Role: ``THINGS_CATALOGUE`` maps exemplar name → (category, function, kwargs);
``stylesets/registry.py`` turns it into ``ExemplarSpec`` s. Each
function returns {part name: list of closed meshes}, with the category's own
part names (vocabulary ``THINGS``):

* building → ``body`` (walls, windows, doors, columns), ``roof`` (roofs, tiles, eaves, chimneys)
* plant    → ``pot`` (pot, soil), ``leaf`` (stems, branches, leaves, flowers)
* cake     → ``bottom`` (lowest tier), ``top`` (upper tiers and decorations)
* crystal  → ``bottom`` (rocky base), ``top`` (crystals)

Exemplars within a category differ in their *detail* (tiles vs flared eaves vs
crenellations; fronds vs round leaves vs ribs and spines; beads vs drips vs
fruit; long prisms vs druse vs cubes), not only in proportions.

Units: metres, +Y up, front +Z. Every shape is about 1–2 m on its longest side
(aspect ≤ ~2.5:1), so one voxel at 256³ is ~4–8 mm and the thinnest pieces are
made ≥ ~2.5 voxels. Randomness uses ``np.random.default_rng(seed)``: builds are
deterministic.
"""

from __future__ import annotations

from typing import Callable

from stylesets.catalogues.buildings import barn, cottage, pagoda, temple, tower, townhouse
from stylesets.catalogues.cakes import birthday_cake, bundt_cake, shortcake, wedding_cake
from stylesets.catalogues.crystals import crystal_cluster, druse, pyrite, quartz_point
from stylesets.catalogues.plants import bush, cactus, fern, flowers, succulent, tree

THINGS_CATALOGUE: dict[str, tuple[str, Callable, dict]] = {
    "cottage": ("building", cottage, {}),
    "pagoda": ("building", pagoda, {}),
    "tower": ("building", tower, {}),
    "townhouse": ("building", townhouse, {}),
    "temple": ("building", temple, {}),
    "barn": ("building", barn, {}),
    "fern": ("plant", fern, {}),
    "bush": ("plant", bush, {}),
    "cactus": ("plant", cactus, {}),
    "bonsai": ("plant", tree, {}),
    "succulent": ("plant", succulent, {}),
    "flowers": ("plant", flowers, {}),
    "birthday_cake": ("cake", birthday_cake, {}),
    "wedding_cake": ("cake", wedding_cake, {}),
    "shortcake": ("cake", shortcake, {}),
    "bundt_cake": ("cake", bundt_cake, {}),
    "crystal_cluster": ("crystal", crystal_cluster, {}),
    "druse": ("crystal", druse, {}),
    "quartz_point": ("crystal", quartz_point, {}),
    "pyrite": ("crystal", pyrite, {}),
}

"""``quilt``: an example-based, non-learned detailizer that copies the style exemplars' real fine blocks.

Modules (one role each): ``sets`` (which style set, name mapping, errors),
``library`` (exemplar cells in 8 symmetries, cached stats), ``search`` (the
energy of a source field), ``graphcut`` (expansion moves), ``field`` (the
coherent PatchMatch-style optimisation of the source field), ``assemble`` (blocks with halos, feathered
joins, confinement), ``repair`` (no floating fragments, material in every
cell) and ``detailizer`` (the pipeline ``Detailizer``).
"""

from model.quilt.detailizer import QuiltDetailizer

__all__ = ["QuiltDetailizer"]

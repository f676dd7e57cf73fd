"""Sources: one module per recipe source kind, each exposing ``load(spec, base_dir) -> SourceResult``.

The modules are light to import: the heavy libraries they use (build123d,
trimesh, fontTools) are imported inside the functions that need them, so only
the kinds a recipe uses pay for them.
"""

from __future__ import annotations

from pathlib import Path

from sources import cad, mesh, text, vox, voxels
from sources.base import PartMeshes, PartVoxels, Source, SourceResult

#: source kind (the recipe's ``source.kind``) → its ``load``.
REGISTRY: dict[str, Source] = {
    "text": text.load,
    "cad": cad.load,
    "mesh": mesh.load,
    "voxels": voxels.load,
    "vox": vox.load,
}


def load_source(spec, base_dir: Path) -> SourceResult:
    """Run the source registered for ``spec.kind`` (a recipe source spec, ``core/recipe.py``)."""
    return REGISTRY[spec.kind](spec, base_dir)


__all__ = ["REGISTRY", "load_source", "PartMeshes", "PartVoxels", "SourceResult"]

"""Sources: one module per kind, each with ``load(spec, base_dir) -> SourceResult``.

Modules are imported only when a recipe uses their kind (build123d alone costs
seconds to import).
"""

from __future__ import annotations

import importlib
from pathlib import Path

from sources.base import PartMeshes, PartVoxels, SourceResult

#: source kind (the recipe's ``source.kind``) → module implementing ``load``.
REGISTRY: dict[str, str] = {
    "text": "sources.text",
    "cad": "sources.cad",
    "mesh": "sources.mesh",
    "voxels": "sources.voxels",
}


def load_source(spec, base_dir: Path) -> SourceResult:
    """Run the source module registered for ``spec.kind``."""
    module = importlib.import_module(REGISTRY[spec.kind])
    return module.load(spec, base_dir)


__all__ = ["REGISTRY", "load_source", "PartMeshes", "PartVoxels", "SourceResult"]

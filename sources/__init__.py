"""Sources: one module per recipe source kind, each exposing ``load(spec, base_dir) -> SourceResult``
and ``preflight(spec, base_dir) -> None`` (the checks ``validate`` and the build's pre-flight run:
files exist, are regular files within their size limits and in a readable format, a font covers
its text; cheap, and never runs a script).

The modules are light to import: the heavy libraries they use (build123d,
trimesh, fontTools) are imported inside the functions that need them, so only
the kinds a recipe uses pay for them.
"""

from __future__ import annotations

from collections.abc import Callable
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


#: source kind → its ``preflight``.
PREFLIGHT: dict[str, Callable[..., None]] = {
    "text": text.preflight,
    "cad": cad.preflight,
    "mesh": mesh.preflight,
    "voxels": voxels.preflight,
    "vox": vox.preflight,
}


def preflight_source(spec, base_dir: Path) -> None:
    """Check ``spec``'s inputs without building (raises ``SourceError`` with ``field`` relative to the source)."""
    PREFLIGHT[spec.kind](spec, base_dir)


def load_source(spec, base_dir: Path) -> SourceResult:
    """Run the source registered for ``spec.kind`` (a recipe source spec, ``core/recipe.py``)."""
    return REGISTRY[spec.kind](spec, base_dir)


__all__ = ["REGISTRY", "PREFLIGHT", "load_source", "preflight_source", "PartMeshes", "PartVoxels", "SourceResult"]

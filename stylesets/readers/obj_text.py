"""A small OBJ text reader for the real-mesh exemplar sets (``monastery``, ``sweethome``).

Role: positions, triangles (polygons fan-split; 1-based or negative indices),
and per triangle the group (``g``/``o``) and material (``usemtl``) it came
after. The label maps of those sets are written against these group and
material names, which trimesh's loaders merge or rename, hence a reader of
our own. Texture coordinates, normals and everything else are ignored.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from stylesets.format import ExemplarError


@dataclass(frozen=True, eq=False)
class GroupedObj:
    """Triangles of an OBJ with their group and material.

    Attributes:
        vertices: (V, 3) float64 positions in the file's units.
        faces: (F, 3) int64 vertex indices.
        group: (F,) int64 index into ``groups`` (0 = ``""``, faces before any ``g``/``o``).
        groups: group names in order of first appearance.
        material: (F,) int64 index into ``materials`` (-1 = before any ``usemtl``).
        materials: material names in order of first appearance.
    """

    vertices: np.ndarray
    faces: np.ndarray
    group: np.ndarray
    groups: tuple[str, ...]
    material: np.ndarray
    materials: tuple[str, ...]

    def material_names(self, faces: np.ndarray) -> list[str]:
        """Material name of each of ``faces`` (indices into ``self.faces``; ``""`` = none)."""
        return ["" if m < 0 else self.materials[m] for m in self.material[faces]]


def parse_obj(lines: Iterable[str], where: str, hint: str, file: str | None = None) -> GroupedObj:
    """Read OBJ ``lines`` (a file handle or ``text.splitlines()``).

    Raises:
        ExemplarError: a line that is not valid OBJ, no faces, or faces that refer to missing
            vertices; the message names ``where`` (and ``file``), ``hint`` says how to fix it.
    """
    vertices: list[list[str]] = []
    faces: list[tuple[int, int, int]] = []
    face_group: list[int] = []
    face_material: list[int] = []
    groups: dict[str, int] = {"": 0}
    materials: dict[str, int] = {}
    group, material, number = 0, -1, 0
    try:
        for number, line in enumerate(lines, 1):
            head = line[:2]
            if head == "v ":
                vertices.append(line.split()[1:4])
            elif head == "f ":
                ids = [int(t.split("/")[0]) for t in line.split()[1:]]
                ids = [i - 1 if i > 0 else len(vertices) + i for i in ids]  # 1-based or negative
                n = max(0, len(ids) - 2)
                faces.extend((ids[0], ids[k], ids[k + 1]) for k in range(1, len(ids) - 1))
                face_group.extend([group] * n)
                face_material.extend([material] * n)
            elif head in ("g ", "o "):
                group = groups.setdefault(line[2:].strip(), len(groups))
            elif line.startswith("usemtl"):
                material = materials.setdefault(line[6:].strip(), len(materials))
        v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    except (ValueError, IndexError):
        raise ExemplarError(f"cannot read {where}: line {number} is not valid OBJ", file=file, hint=hint) from None
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0 or f.min() < 0 or f.max() >= len(v) or not np.all(np.isfinite(v)):
        raise ExemplarError(f"cannot read {where}: no faces, or faces that refer to missing vertices",
                            file=file, hint=hint)
    return GroupedObj(v, f, np.asarray(face_group, np.int64), tuple(groups),
                      np.asarray(face_material, np.int64), tuple(materials))

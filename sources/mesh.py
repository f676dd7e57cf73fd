"""The ``mesh`` source: a mesh file (OBJ, STL, PLY, OFF, GLB, GLTF) → named part meshes, metres, +Y up.

Parts (``parts_from``):

- ``nodes``: every mesh instance of the file is a part. For GLB/GLTF that is
  each scene-graph node with geometry, its world transform baked in, named
  after the node; for OBJ each ``o`` object / ``g`` group (or, in a file with
  neither, each material). A file holding a single mesh instance (always the
  case for STL, PLY and OFF; also a GLB with one node) gives one part named
  after the file stem.
- ``whole``: everything merged into one part named after the file stem.

Names are sanitised to ``[A-Za-z0-9][A-Za-z0-9_.-]*`` (other characters become
``_``) and made unique with ``_2``, ``_3``... suffixes. Parts are ordered by
their name in the file (scene-graph order is an implementation detail of the
loader, so sorting keeps the order deterministic).

Each part is rebuilt from positions and faces only (colours, UVs and normals
are dropped, so vertices split for texturing merge again), duplicate vertices
are merged and degenerate faces dropped, then it is scaled to metres
(``units`` × ``scale``) and rotated from ``up_axis`` onto +Y by
``sources.frames``. A part that is not watertight is kept, with a warning; the
voxelizer fills it by a 3-axis vote.

The file must be a regular file within the mesh size limit
(``core/files.py``, ``InputKind.MESH``), checked before it is read. A part
that is degenerate once scaled (not finite, under 1 µm or over 1,000 km
across, every face collapsed: ``sources.frames.check_part_geometry``) is an
error. Every failure is a ``SourceError`` with ``field="path"``; no exception
from trimesh escapes.

Companion files (a glTF's external buffers and images, an OBJ's ``mtllib``
and the textures it names) are read through a resolver that records each file
it opens, and each file it looked for and did not find (a file created there
later would change the result): they follow the mesh in ``input_files``, so a
build's cache sees an edit to any of them (``pipeline/cache.py``). Each is
held to the mesh file's own limits before it is read (a regular file within
``InputKind.MESH``'s size limit), so a buffer the file names cannot make the
build read without bound.
"""

from __future__ import annotations

import json
import os
import re
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from core.errors import SourceError
from core.files import InputKind, check_input_file, input_file
from core.recipe import MeshSource, PartsFrom, UpAxis
from sources.base import PartMeshes
from sources.frames import check_extent, check_part_geometry, transform_mesh

if TYPE_CHECKING:
    import trimesh

#: File extensions this source reads (lower case, without the dot).
SUPPORTED_FORMATS: tuple[str, ...] = ("obj", "stl", "ply", "off", "glb", "gltf")

_NAME_BAD_CHARS = re.compile(r"[^A-Za-z0-9_.\-]")
_OBJ_SPLIT_DIRECTIVE = re.compile(rb"^[ \t]*[og][ \t]", re.MULTILINE)


def load(spec: MeshSource, base_dir: Path) -> PartMeshes:
    """Read ``spec.path`` (relative to ``base_dir``) into named parts in the canonical frame."""
    path = resolve_path(spec.path, base_dir)
    ext = path.suffix.lower().lstrip(".")
    companions: list[Path] = []
    raw = _read_instances(path, ext, read=companions)
    if not raw:
        raise SourceError("mesh has no faces", field="path",
                          hint="the file holds only points or lines; export the surface as triangles")
    if spec.parts_from == PartsFrom.WHOLE or len(raw) == 1:
        raw = [(path.stem, _concatenate([mesh for _, mesh in raw]))]

    scale = spec.units.metres * spec.scale
    parts: dict[str, "trimesh.Trimesh"] = {}
    warnings: list[str] = []
    for original, mesh in sorted(raw, key=lambda item: item[0]):
        name = unique_name(sanitize_name(original), parts)
        if len(mesh.vertices) and np.all(np.isfinite(mesh.vertices)):  # NaN is _clean's to report
            check_extent(mesh.vertices, scale, name, "path")  # before cleaning, which breaks on huge numbers
        cleaned = _clean(mesh, name)
        parts[name] = transform_mesh(cleaned, spec.up_axis, scale)
        check_part_geometry(parts[name], name, "path")
        if not cleaned.is_watertight:
            warnings.append(f"part '{name}' is not watertight (it has open or non-manifold edges)")
    if not parts:
        raise SourceError("mesh has no faces", field="path",
                          hint="every face is degenerate; check the file in a mesh viewer")
    return PartMeshes(parts=parts, warnings=warnings, input_files=[path, *companions])


def read_named_parts(path: Path, up_axis: UpAxis | str = UpAxis.Y) -> list[tuple[str, "trimesh.Trimesh"]]:
    """Every mesh instance of ``path`` as (sanitised node/group name, cleaned mesh, +Y up), sorted by name.

    Unlike ``load``, a file with a single instance keeps that instance's own
    name (a one-node GLB's node, an OBJ's only group); only a file with no
    names at all (STL, PLY, OFF, an OBJ without ``o``/``g``) gives its file
    stem. Names are not made unique: equal names are returned as separate
    entries. Units are left as they are. Raises ``SourceError`` like ``load``.
    """
    path = check_input_file(Path(path), InputKind.MESH, field="path")
    ext = path.suffix.lower().lstrip(".")
    # An OBJ with a single ``o``/``g`` keeps that name (trimesh would return a bare, unnamed mesh).
    named_obj = ext == "obj" and _obj_options(path).get("split_groups", False)
    raw = _read_instances(path, ext, force="scene" if named_obj else None)
    if not raw:
        raise SourceError("mesh has no faces", field="path",
                          hint="the file holds only points or lines; export the surface as triangles")
    out = []
    for original, mesh in sorted(raw, key=lambda item: item[0]):
        name = sanitize_name(original)
        out.append((name, transform_mesh(_clean(mesh, name), up_axis, 1.0)))
    return out


def preflight(spec: MeshSource, base_dir: Path) -> None:
    """Checks before building: the file exists, is a regular file within the mesh size limit, in a known format."""
    resolve_path(spec.path, base_dir)


def resolve_path(relative: str, base_dir: Path) -> Path:
    """The file's absolute path; refuses missing files, folders, devices, oversized files and unknown extensions."""
    path = input_file(relative, base_dir, field="path", noun="file", hint="name a mesh file", kind=InputKind.MESH)
    ext = path.suffix.lower().lstrip(".")
    if ext not in SUPPORTED_FORMATS:
        raise SourceError(f"unsupported mesh format {path.suffix or '(no extension)'!r}", field="path",
                          hint="supported: " + ", ".join("." + f for f in SUPPORTED_FORMATS))
    return path


def sanitize_name(name: str) -> str:
    """A part name matching ``^[A-Za-z0-9][A-Za-z0-9_.-]*$`` ("part" when nothing usable is left)."""
    cleaned = _NAME_BAD_CHARS.sub("_", str(name).strip())
    cleaned = cleaned.lstrip("_.-")
    return cleaned or "part"


def unique_name(name: str, taken) -> str:
    """``name``, or ``name_2``, ``name_3``... whichever is first not in ``taken``."""
    if name not in taken:
        return name
    n = 2
    while f"{name}_{n}" in taken:
        n += 1
    return f"{name}_{n}"


# --------------------------------------------------------------------------- reading


def _read_instances(path: Path, ext: str, force: str | None = None,
                    read: list[Path] | None = None) -> list[tuple[str, "trimesh.Trimesh"]]:
    """(name, mesh with world transform applied) for every triangle mesh instance in the file.

    ``force="scene"`` keeps the node name of a file holding a single named mesh
    (e.g. an OBJ with one ``g`` group) instead of naming it after the file stem.
    ``read`` gets every companion file the loader opened or looked for (``_recording_resolver``).
    """
    import trimesh

    try:
        size = path.stat().st_size
    except OSError as exc:
        raise SourceError(f"cannot read mesh: {exc.strerror}", field="path") from None
    if size == 0:
        raise SourceError("cannot read mesh: the file is empty", field="path", hint="re-export the mesh")
    kwargs: dict = {}
    if ext == "obj":
        kwargs = _obj_options(path)
    elif ext == "gltf":
        _check_gltf_json(path)
    try:
        # process=False: _clean does the cleaning, and reports NaN vertices instead of dropping them.
        resolver = _recording_resolver()(str(path), [] if read is None else read)
        loaded = trimesh.load(str(path), file_type=ext, force=force, process=False, resolver=resolver, **kwargs)
        instances = _instances(loaded, path.stem)
    except SourceError:
        raise
    except Exception as exc:  # noqa: BLE001 - any loader failure is a bad file, never a traceback
        raise SourceError(f"cannot read mesh: {_short_reason(exc)}", field="path",
                          hint=f"check that the file is a valid .{ext} file, e.g. in a mesh viewer") from None
    if not instances and _has_no_geometry(loaded):
        raise SourceError(f"cannot read mesh: no geometry found (is this really a .{ext} file?)", field="path",
                          hint="re-export the mesh")
    return instances


@cache
def _recording_resolver() -> type:
    """trimesh's file resolver, recording what it reads (a class made once trimesh is imported)."""
    from trimesh.resolvers import FilePathResolver

    class RecordingResolver(FilePathResolver):
        """``FilePathResolver`` that appends each file it opens (or looked for in vain) to ``read``."""

        def __init__(self, source: str, read: list[Path]) -> None:
            super().__init__(source)
            self.read = read

        def get(self, name: str) -> bytes:
            # The candidates and their order are FilePathResolver.get's (trimesh 5.2).
            for candidate in (name.strip(), name.strip().lstrip("/"), os.path.split(name)[-1]):
                try:
                    path = self.absolute(candidate)
                except ValueError:
                    continue
                if path.is_file():
                    self.read.append(path)
                    check_input_file(path, InputKind.MESH, field="path")  # the mesh's own limits
                    return path.read_bytes()
            missing = self.absolute(name)  # raises when the name leaves the mesh's folder, as trimesh does
            self.read.append(missing)
            raise FileNotFoundError(name)

        def namespaced(self, namespace: str) -> "RecordingResolver":
            return RecordingResolver(os.path.join(self.parent, namespace, "_"), self.read)

    return RecordingResolver


def _obj_options(path: Path) -> dict:
    """OBJ loader options: one mesh per object/group, or per material when the file has neither."""
    try:
        has_split = _OBJ_SPLIT_DIRECTIVE.search(path.read_bytes()) is not None
    except OSError as exc:
        raise SourceError(f"cannot read mesh: {exc.strerror}", field="path") from None
    if has_split:
        return {"split_objects": True, "split_groups": True, "group_material": False}
    return {"group_material": True}


def _check_gltf_json(path: Path) -> None:
    # trimesh reports a non-JSON .gltf as a missing resource; say what is really wrong.
    try:
        json.loads(path.read_bytes())
    except (ValueError, UnicodeDecodeError):
        raise SourceError("cannot read mesh: not a glTF JSON file", field="path",
                          hint="a .gltf file is JSON text; for a binary file use the .glb extension") from None


def _instances(loaded, stem: str) -> list[tuple[str, "trimesh.Trimesh"]]:
    import trimesh

    if isinstance(loaded, trimesh.Trimesh):
        return [(stem, loaded)] if len(loaded.faces) else []
    if not isinstance(loaded, trimesh.Scene):
        return []  # point cloud, path...: no faces
    out = []
    for node in loaded.graph.nodes_geometry:
        transform, geom_name = loaded.graph[node]
        geometry = loaded.geometry.get(geom_name)
        if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
            continue
        mesh = trimesh.Trimesh(vertices=np.asarray(geometry.vertices, dtype=np.float64),
                               faces=np.asarray(geometry.faces), process=False)
        mesh.apply_transform(np.asarray(transform, dtype=np.float64))
        out.append((str(node), mesh))
    return out


def _has_no_geometry(loaded) -> bool:
    import trimesh

    if isinstance(loaded, trimesh.Scene):
        return len(loaded.geometry) == 0
    return len(getattr(loaded, "vertices", ())) == 0


def _short_reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    text = text[:160]
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


# --------------------------------------------------------------------------- cleaning


def _concatenate(meshes: list["trimesh.Trimesh"]) -> "trimesh.Trimesh":
    import trimesh

    if len(meshes) == 1:
        return meshes[0]
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    vertices = np.concatenate([np.asarray(m.vertices, dtype=np.float64) for m in meshes])
    faces = np.concatenate([np.asarray(m.faces) + o for m, o in zip(meshes, offsets)])
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)


def _clean(mesh: "trimesh.Trimesh", name: str) -> "trimesh.Trimesh":
    """Positions and faces only, finite, duplicate vertices merged, degenerate faces dropped."""
    import trimesh

    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise SourceError(f"part '{name}': a face refers to a vertex that does not exist", field="path",
                          hint="the file is corrupt; re-export the mesh")
    if not np.all(np.isfinite(vertices[faces])):
        raise SourceError(f"part '{name}' has vertices that are NaN or infinite", field="path",
                          hint="the file is corrupt; re-export the mesh")
    try:
        # validate=True merges vertices and drops degenerate/duplicate faces.
        cleaned = trimesh.Trimesh(vertices=vertices, faces=faces, process=True, validate=True)
    except Exception as exc:  # noqa: BLE001 - trimesh internals on odd data
        raise SourceError(f"cannot read mesh: part '{name}': {_short_reason(exc)}", field="path") from None
    if len(cleaned.faces) == 0:
        raise SourceError(f"mesh has no faces: every face of part '{name}' is degenerate", field="path",
                          hint="check the file in a mesh viewer")
    return cleaned

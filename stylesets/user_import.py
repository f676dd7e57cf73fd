"""Users' own style exemplars: a folder of meshes → ``ExemplarSpec`` list (``decollage styles import``).

Role: finds the exemplars in a folder, reads their part meshes (through
``sources.mesh``), maps part names onto a vocabulary and checks everything
before anything is voxelized; ``import_folder`` then builds the set with
``stylesets.format.build_set``, so user sets share the cache and the file
format of the built-in ones.

Folder layout (entries are sorted by name; dotfiles are ignored):

- ``<name>.glb|.gltf|.obj|.ply|.stl|.off``: one exemplar named ``<name>``; its
  parts are the file's scene nodes (GLB/GLTF) or ``o``/``g`` groups (OBJ), each
  named after its part. Several nodes may name the same part.
- ``<name>/``: one exemplar named ``<name>``, one mesh file per part named by
  its part (``<name>/roof.obj``, ``<name>/body.stl``); everything in a part
  file belongs to that part.

Part names: a node, group or file name is looked up in the vocabulary as it
is (category aliases accepted, e.g. ``roof`` = ``top`` of a building), then
with trailing numeric suffixes stripped (``leg.001``, ``leg_2``, ``leg-3``,
``leg2`` → ``leg``), then case-insensitively. Unknown names are an error
listing the accepted ones.

Category: ``category`` when given, else the alias category whose own names the
exemplar uses (``body``/``roof`` → ``building``), else ``"user"``.

Meshes may be in any unit (exemplars are normalised to the grid); ``up`` says
which of their axes points up (glTF and most OBJ: ``y``; CAD/STL often ``z``).
Every problem is an ``ExemplarError`` naming the file, the exemplar and the fix.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

from core.errors import DecollageError, SourceError
from core.files import InputKind, code_digest, read_input_bytes
from sources.mesh import read_named_parts, sanitize_name
from stylesets.format import RESOLUTION, BuildResult, ExemplarError, ExemplarSpec, Vocabulary, build_set, set_path
from stylesets.registry import BUILTIN_SETS

if TYPE_CHECKING:
    import trimesh

#: Mesh file extensions that are exemplars (or parts), lower case, no dot (those of ``sources.mesh``).
MESH_EXTENSIONS: tuple[str, ...] = ("glb", "gltf", "obj", "ply", "stl", "off")
#: Companion files skipped without a warning (glTF buffers, OBJ materials, textures, notes).
_COMPANIONS = {"bin", "mtl", "png", "jpg", "jpeg", "webp", "ktx2", "tga", "bmp", "txt", "md", "yaml", "yml", "json"}
_COMPANION_NAMES = {"license", "licence", "notice", "readme", "copying", "authors"}
_NUMERIC_SUFFIX = re.compile(r"[._-]?\d+$")
_SET_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
DEFAULT_LICENCE = "user-supplied"
DEFAULT_CATEGORY = "user"
_LAYOUT_HINT = ("put one mesh file per exemplar (parts = scene nodes / OBJ groups named after parts) "
                "or one subfolder per exemplar with one mesh file per part, e.g. house/roof.obj")


@dataclass(frozen=True)
class FolderEntry:
    """One exemplar found in the folder: ``path`` is its mesh file or its part folder."""

    name: str
    path: Path
    part_files: tuple[Path, ...]  # the files read (the mesh file itself, or the folder's part files)

    @property
    def is_folder(self) -> bool:
        return self.path.is_dir()


# --------------------------------------------------------------------------- names


def check_set_name(name: str) -> str:
    """A user set name: a plain file name that is not a built-in set's."""

    if not _SET_NAME.match(name or ""):
        raise ExemplarError(f"bad set name {name!r}", field="name",
                            hint="use letters, digits, '_', '.' and '-', starting with a letter or digit")
    if name in BUILTIN_SETS:
        raise ExemplarError(f"'{name}' is the name of a built-in set", field="name",
                            hint="choose another name, e.g. 'my_" + name + "'")
    return name


def part_for(name: str, vocabulary: Vocabulary, category: str | None = None) -> str | None:
    """The vocabulary part (its base name) that node/group/file name ``name`` stands for, or None.

    Tried in order: the name, the name without trailing numeric suffixes
    (``leg.001`` → ``leg``), then both lower-cased; category aliases count.
    """
    candidates = [name]
    stem = name
    while _NUMERIC_SUFFIX.search(stem) and _NUMERIC_SUFFIX.sub("", stem):
        stem = _NUMERIC_SUFFIX.sub("", stem)
        candidates.append(stem)
    for candidate in candidates + [c.lower() for c in candidates]:
        try:
            return vocabulary.parts[vocabulary.index(candidate, category)]
        except KeyError:
            continue
    return None


def accepted_names(vocabulary: Vocabulary, category: str | None) -> list[str]:
    """Part names accepted for an exemplar of ``category`` (all aliases when it has none of its own)."""
    if category in vocabulary.aliases:
        return sorted(set(vocabulary.parts) | set(vocabulary.aliases[category]))
    return vocabulary.accepted()


def infer_category(names: Sequence[str], vocabulary: Vocabulary) -> str:
    """The alias category whose own part names ``names`` use (if exactly one fits), else ``"user"``."""
    fits = []
    for category, aliases in sorted(vocabulary.aliases.items()):
        own = Vocabulary("own", tuple(a for a in aliases if a not in vocabulary.parts))
        if own.parts and any(part_for(n, own) for n in names) \
                and all(part_for(n, vocabulary, category) for n in names):
            fits.append(category)
    return fits[0] if len(fits) == 1 else DEFAULT_CATEGORY


# --------------------------------------------------------------------------- finding exemplars


def _is_mesh(path: Path) -> bool:
    return path.is_file() and path.suffix.lower().lstrip(".") in MESH_EXTENSIONS


def _is_companion(path: Path) -> bool:
    return (path.suffix.lower().lstrip(".") in _COMPANIONS
            or path.stem.lower() in _COMPANION_NAMES or path.name.lower() in _COMPANION_NAMES)


def find_exemplars(folder: Path) -> tuple[list[FolderEntry], list[str]]:
    """The exemplars in ``folder`` (sorted by name) and warnings about skipped files."""

    folder = Path(folder)
    if not folder.exists():
        raise ExemplarError(f"folder not found: {folder}", file=folder, hint=_LAYOUT_HINT)
    if not folder.is_dir():
        raise ExemplarError(f"not a folder: {folder}", file=folder,
                            hint="give the folder that holds the exemplar meshes")
    entries: list[FolderEntry] = []
    warnings: list[str] = []
    by_name: dict[str, Path] = {}
    for path in sorted(folder.iterdir()):
        if path.name.startswith("."):
            continue
        if path.is_dir():
            part_files = tuple(p for p in sorted(path.iterdir()) if not p.name.startswith(".") and _is_mesh(p))
            for other in sorted(path.iterdir()):
                if not other.name.startswith(".") and other not in part_files and not _is_companion(other):
                    warnings.append(f"skipped {other} (not a {'/'.join(MESH_EXTENSIONS)} part file)")
            if not part_files:
                raise ExemplarError("exemplar folder has no part files", file=path, field=path.name,
                                    hint="put one mesh file per part in it, named by its part (e.g. roof.obj); "
                                         "supported: " + ", ".join("." + e for e in MESH_EXTENSIONS))
        elif _is_mesh(path):
            part_files = (path,)
        else:
            if not _is_companion(path):
                warnings.append(f"skipped {path} (not a {'/'.join(MESH_EXTENSIONS)} mesh file)")
            continue
        name = sanitize_name(path.stem if path.is_file() else path.name)
        if name in by_name:
            raise ExemplarError(f"duplicate exemplar name '{name}': {by_name[name].name} and {path.name}",
                                file=path, field=name, hint="rename one of them; exemplar names must be unique")
        by_name[name] = path
        entries.append(FolderEntry(name, path, part_files))
    if not entries:
        raise ExemplarError("no exemplars found in the folder", file=folder, hint=_LAYOUT_HINT)
    return entries, warnings


# --------------------------------------------------------------------------- reading parts


def _read(file: Path, up: str, exemplar: str) -> list[tuple[str, "trimesh.Trimesh"]]:

    try:
        return read_named_parts(file, up)
    except SourceError as exc:
        raise ExemplarError(exc.message, file=file, field=exemplar, hint=exc.hint) from None


def raw_parts(entry: FolderEntry, up: str = "y") -> list[tuple[str, "trimesh.Trimesh", Path]]:
    """(name in the file(s), mesh, file) for every mesh of the exemplar, before vocabulary mapping."""
    out = []
    if entry.is_folder:
        for file in entry.part_files:
            for _, mesh in _read(file, up, entry.name):
                out.append((file.stem, mesh, file))
    else:
        for name, mesh in _read(entry.path, up, entry.name):
            out.append((name, mesh, entry.path))
    return out


def map_parts(entry: FolderEntry, raw: Sequence[tuple[str, "trimesh.Trimesh", Path]], vocabulary: Vocabulary,
              category: str | None) -> dict[str, list["trimesh.Trimesh"]]:
    """Raw named meshes → {vocabulary part: meshes}; ExemplarError listing every unknown name."""
    parts: dict[str, list] = {}
    unknown: list[str] = []
    for name, mesh, _ in raw:
        part = part_for(name, vocabulary, category)
        if part is None:
            if name not in unknown:
                unknown.append(name)
            continue
        parts.setdefault(part, []).append(mesh)
    if unknown:
        listed = ", ".join(f"'{n}'" for n in unknown[:8])
        if len(unknown) > 8:
            listed += f" and {len(unknown) - 8} more"
        if entry.is_folder:
            what, fix = "part file", "name each part file after a part"
        elif len(raw) == 1 and raw[0][0] == entry.name:
            what, fix = ("the file has no named nodes or groups, so its one part is named after the file",
                         "name its scene nodes / OBJ groups after parts, or make a folder with one file per part")
        else:
            what, fix = "scene node / OBJ group", "name each scene node / OBJ group after a part"
        raise ExemplarError(
            f"unknown part name{'s' if len(unknown) > 1 else ''} {listed} ({what})", file=entry.path,
            field=entry.name,
            hint=f"{fix} of vocabulary '{vocabulary.name}': " + ", ".join(accepted_names(vocabulary, category))
                 + "; a numeric suffix like '.001' or '_2' is ignored")
    return parts


def exemplar_parts(entry: FolderEntry, vocabulary: Vocabulary, category: str, up: str = "y") -> dict[str, list]:
    """``ExemplarSpec.make`` of a user exemplar: read its files, map its parts (module level: picklable)."""
    return map_parts(entry, raw_parts(entry, up), vocabulary, category)


# --------------------------------------------------------------------------- specs and import


def _gltf_buffers(file: Path) -> list[Path]:
    """External buffer files a .gltf reads (their bytes change the geometry)."""
    if file.suffix.lower() != ".gltf":
        return []
    try:
        data = json.loads(read_input_bytes(file, InputKind.MESH))  # within the mesh size limit
    except (DecollageError, OSError, ValueError, UnicodeDecodeError):
        return []
    out = []
    for buffer in data.get("buffers", []) if isinstance(data, dict) else []:
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if isinstance(uri, str) and not uri.startswith("data:") and (file.parent / uri).is_file():
            out.append(file.parent / uri)
    return out


def folder_specs(folder: Path, vocabulary: Vocabulary, *, category: str | None = None,
                 licence: str = DEFAULT_LICENCE, up: str = "y") -> tuple[list[ExemplarSpec], list[str]]:
    """Every exemplar of ``folder`` as an ``ExemplarSpec`` (source "user"), checked; plus warnings.

    Reads every mesh once, so unreadable files and unknown part names are
    reported before anything is voxelized; the specs read them again when made.
    """
    folder = Path(folder)
    entries, warnings = find_exemplars(folder)
    code = code_digest("stylesets/user_import.py", "sources/mesh.py", "sources/frames.py")
    specs = []
    for entry in entries:
        raw = raw_parts(entry, up)
        cat = category or infer_category([name for name, _, _ in raw], vocabulary)
        map_parts(entry, raw, vocabulary, cat)
        files = [*entry.part_files, *(b for f in entry.part_files for b in _gltf_buffers(f))]
        key = json.dumps({"layout": "folder" if entry.is_folder else "file",
                          "files": [f.relative_to(folder).as_posix() for f in files],
                          "up": up, "code": code}, sort_keys=True)
        specs.append(ExemplarSpec(name=entry.name, category=cat,
                                  make=partial(exemplar_parts, entry, vocabulary, cat, up),
                                  key=key, source="user", licence=licence, attribution="",
                                  input_files=tuple(files)))
    return specs, warnings


def import_folder(folder: Path, name: str, vocabulary: Vocabulary, *, out: Path | None = None,
                  resolution: int = RESOLUTION, category: str | None = None, licence: str = DEFAULT_LICENCE,
                  up: str = "y", force: bool = False, workers: int = 1,
                  progress: Callable[[str], None] | None = None) -> tuple[BuildResult, list[str]]:
    """Import ``folder`` as set ``name`` into ``out`` (default ``style_dir()``); cached like any set.

    Returns the build result and the warnings (skipped files). Nothing is
    written unless every exemplar voxelizes.
    """
    check_set_name(name)
    folder = Path(folder)
    specs, warnings = folder_specs(folder, vocabulary, category=category, licence=licence, up=up)
    # An exemplar's location: its mesh file, or its part folder.
    where = {s.name: s.input_files[0] if s.input_files[0].parent == folder else s.input_files[0].parent
             for s in specs}
    try:
        result = build_set(name, vocabulary, specs, set_path(name, out), resolution=resolution, force=force,
                           workers=workers, progress=progress)
    except DecollageError as exc:
        if exc.file is None and exc.field in where:
            exc.located(file=where[exc.field])
        raise
    return result, warnings

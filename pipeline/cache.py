"""Incremental builds: a content-hash key per asset, the input closure it read, and a record of what was built.

An asset is up to date when three things still hold:

1. its **key** (``asset_key``) is unchanged: a sha256 over the resolved recipe
   entry (after defaults and variants), the bytes of the files the recipe
   names, the checkpoint's bytes, the detailizer chosen, and the versions of
   this project and of the libraries that shape the geometry;
2. its **input closure** is unchanged: every file the asset's build actually
   read (recorded by the readers that opened them, ``sources/base.py``'s
   ``input_files`` and a detailizer's ``input_files``: a glTF's buffers and
   images, an OBJ's material library, a script's local modules and data files,
   a font, a voxel file, a checkpoint) still has the sha256 recorded when it was
   read, and a file that a reader looked for and did not find is still absent;
3. its **outputs** are in place: every file its entry lists exists with the
   recorded size and sha256.

Together (1) and (2) make the closure part of the key: only files that are
known before anything is read can be hashed up front; the rest are known once
the readers ran, so they are recorded with the asset and compared on the next
plan. After an asset's files are in place, a record
``<out>/.decollage/<asset>.json`` (key + manifest entry, whose ``inputs.files``
is the closure) is written atomically; a build killed at any point therefore
rebuilds exactly the assets without a valid record.

Paths in the closure are written portably (``portable_path``): relative to
the recipe's folder, ``<decollage>/...`` for files shipped with this
project (the bundled font, the shipped weights), or ``<styles>/...`` for
built style sets in the per-user cache, so that manifests hold no
machine-specific paths.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable
from importlib import metadata
from pathlib import Path

from core import __version__
from core.files import sha256_file, write_bytes_atomic
from pipeline.report import AssetStatus
from stylesets.format import style_dir

RECORD_DIR = ".decollage"
#: 2: entries carry the asset's provenance (exemplars, licences) and GLBs carry it in asset.extras.
#: 3: the entry's ``inputs.files`` is the asset's input closure (a list), checked on every plan.
RECORD_FORMAT = 3

#: Distributions whose versions change the bytes of the outputs.
KEY_LIBRARIES = ("numpy", "scipy", "scikit-image", "trimesh", "fast-simplification", "meshoptimizer", "fonttools", "manifold3d",
                 "shapely", "mapbox-earcut", "build123d", "torch", "Pillow")

#: Prefix of closure paths inside this project's own folder (the folder holding ``core/``).
PROJECT_PREFIX = "<decollage>/"
#: Prefix of closure paths inside the built style sets' folder (``stylesets/format.py``'s ``style_dir``:
#: a per-user cache, e.g. the quilt detailizer's default set ``<styles>/things.npz``).
STYLES_PREFIX = "<styles>/"
_PROJECT_ROOT = Path(__file__).resolve().parents[1]


def library_versions() -> dict[str, str]:
    versions = {}
    for name in KEY_LIBRARIES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "absent"
    return versions


_VERSIONS: dict[str, str] | None = None


def asset_key(entry: dict, input_hashes: dict[str, str], checkpoint_sha256: str | None, detailizer: str) -> str:
    """sha256 (hex) over everything known about an asset before anything is read."""
    global _VERSIONS
    if _VERSIONS is None:
        _VERSIONS = library_versions()
    payload = {
        "record_format": RECORD_FORMAT,
        "decollage": __version__,
        "libraries": _VERSIONS,
        "entry": entry,
        "inputs": dict(sorted(input_hashes.items())),
        "checkpoint": checkpoint_sha256,
        "detailizer": detailizer,
    }
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()


# --------------------------------------------------------------------------- the input closure


def file_digest(path: Path) -> str | None:
    """sha256 (hex) of a file's bytes; None when there is no such file (a reader looked for it in vain)."""
    try:
        return sha256_file(path)
    except (FileNotFoundError, NotADirectoryError, IsADirectoryError):
        return None


class Digests:
    """``file_digest`` memoised for one plan: a batch whose assets share a font or a checkpoint hashes it once."""

    def __init__(self) -> None:
        self._known: dict[Path, str | None] = {}

    def __call__(self, path: Path) -> str | None:
        if path not in self._known:
            self._known[path] = file_digest(path)
        return self._known[path]


def portable_path(path: Path, base_dir: Path) -> str:
    """How a closure file is written in a manifest: relative to the recipe folder ``base_dir`` when inside it,
    ``<decollage>/...`` inside this project, ``<styles>/...`` inside the built style sets' folder, else
    relative to ``base_dir`` (``..`` allowed) or absolute."""
    path, base = Path(os.path.abspath(path)), Path(os.path.abspath(base_dir))
    if path.is_relative_to(base):
        return path.relative_to(base).as_posix()
    if path.is_relative_to(_PROJECT_ROOT):
        return PROJECT_PREFIX + path.relative_to(_PROJECT_ROOT).as_posix()
    styles = Path(os.path.abspath(style_dir()))
    if path.is_relative_to(styles):
        return STYLES_PREFIX + path.relative_to(styles).as_posix()
    try:
        return Path(os.path.relpath(path, base)).as_posix()
    except ValueError:  # another drive (Windows)
        return str(path)


def resolve_portable(text: str, base_dir: Path) -> Path:
    """The file a ``portable_path`` string names (inverse of ``portable_path``)."""
    if text.startswith(PROJECT_PREFIX):
        return _PROJECT_ROOT / text[len(PROJECT_PREFIX):]
    if text.startswith(STYLES_PREFIX):
        return style_dir() / text[len(STYLES_PREFIX):]
    return Path(base_dir) / text  # an absolute text stays absolute


def closure_records(files: Iterable[tuple[Path, str]], base_dir: Path) -> list[dict]:
    """The manifest's ``inputs.files``: one ``{"path", "sha256", "read_by"}`` per file read, first read first.

    ``files`` are (path, reader) pairs; ``reader`` is ``"source"`` or ``"detailizer"``. A file
    listed twice is kept once; ``sha256`` is None for a file a reader looked for and did not find.
    """
    seen: set[str] = set()
    out = []
    for path, reader in files:
        text = portable_path(path, base_dir)
        if text not in seen:
            seen.add(text)
            out.append({"path": text, "sha256": file_digest(path), "read_by": reader})
    return out


def closure_paths(records: list, base_dir: Path) -> list[Path]:
    """The files a manifest entry's ``inputs.files`` names (for ``--watch``); nothing for a malformed closure."""
    if not isinstance(records, list):
        return []
    return [resolve_portable(r["path"], base_dir) for r in records
            if isinstance(r, dict) and isinstance(r.get("path"), str)]


def changed_input(records: list, base_dir: Path, digests: Digests) -> str | None:
    """The first closure file whose bytes (or presence) differ from its record, as written there; None if none.

    A malformed closure (not a list of records) counts as changed ("?").
    """
    if not isinstance(records, list):
        return "?"
    for record in records:
        if not isinstance(record, dict) or not isinstance(record.get("path"), str):
            return "?"
        if digests(resolve_portable(record["path"], base_dir)) != record.get("sha256"):
            return record["path"]
    return None


# --------------------------------------------------------------------------- records


def record_path(out_dir: Path, name: str) -> Path:
    return out_dir / RECORD_DIR / f"{name}.json"


def write_record(out_dir: Path, name: str, key: str, entry: dict) -> None:
    """Record that ``name`` was built with ``key`` (after its outputs are in place)."""

    (out_dir / RECORD_DIR).mkdir(exist_ok=True)
    # Key order is kept: a cached entry must serialise exactly like a fresh one.
    data = json.dumps({"format": RECORD_FORMAT, "key": key, "entry": entry}, indent=1)
    write_bytes_atomic(record_path(out_dir, name), data.encode())


def check_record(out_dir: Path, name: str, key: str, base_dir: Path,
                 digests: Digests | None = None) -> tuple[dict | None, str]:
    """(the recorded manifest entry, "") when ``name`` is up to date for ``key``, else (None, why it is stale).

    ``base_dir`` is the recipe's folder, against which closure paths resolve.
    """
    digests = digests or Digests()
    path = record_path(out_dir, name)
    try:
        record = json.loads(path.read_text())
    except FileNotFoundError:
        return None, "not built yet"
    except (OSError, ValueError):
        return None, "unreadable record"
    if not isinstance(record, dict) or record.get("format") != RECORD_FORMAT:
        return None, "record from another decollage version"
    if record.get("key") != key:
        return None, "recipe entry, named input, checkpoint or library versions changed"
    entry = record.get("entry") or {}
    outputs = entry.get("outputs") or {}
    if entry.get("status") != AssetStatus.BUILT or not outputs:
        return None, "not built yet"
    changed = changed_input((entry.get("inputs") or {}).get("files"), base_dir, digests)
    if changed is not None:
        return None, f"input changed: {changed}"
    for out in outputs.values():
        file = out_dir / out["path"]
        if not file.is_file() or file.stat().st_size != out["bytes"] or sha256_file(file) != out["sha256"]:
            return None, f"output missing or modified: {out['path']}"
    return entry, ""


def remove_stale_temporaries(out_dir: Path) -> int:
    """Delete temporaries left by a killed build (``.<name>.<pid>.<n>.tmp``); returns how many."""
    removed = 0
    for folder in (out_dir, out_dir / RECORD_DIR):
        if folder.is_dir():
            for temp in folder.glob(".*.tmp"):
                temp.unlink(missing_ok=True)
                removed += 1
    return removed


def remove_unfinished_outputs(out_dir: Path, unfinished: Iterable[str], keep: set[str], since_ns: int) -> list[str]:
    """Delete files an interrupted build wrote for assets it did not finish; returns their names.

    A file goes when it was written since ``since_ns`` (the build's start, on the folder's clock),
    its name starts with an unfinished asset's name (``<asset>.glb``, ``<asset>_LOD1.glb``...) and
    no finished asset lists it (``keep``). Earlier files are never touched.
    """
    prefixes = tuple(unfinished)
    removed = []
    if not prefixes or not out_dir.is_dir():
        return removed
    for file in sorted(out_dir.iterdir()):
        name = file.name
        if name in keep or name.startswith(".") or not name.startswith(prefixes) or not file.is_file():
            continue
        if file.stat().st_mtime_ns >= since_ns:
            file.unlink(missing_ok=True)
            removed.append(name)
    return removed

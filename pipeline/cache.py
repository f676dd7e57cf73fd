"""Incremental builds: a content-hash key per asset and a record of what was built with it.

The key of an asset covers everything its outputs depend on: the resolved
recipe entry (after defaults and variants), the bytes of its input files, the
checkpoint's bytes, the detailizer chosen, and the versions of this project
and of the libraries that shape the geometry. After an asset's files are in
place, a record ``<out>/.decollage/<asset>.json`` (key + its manifest entry) is
written atomically. An asset is up to date when its record has the same key and
every output it lists exists with the recorded sha256; a build killed at any
point therefore rebuilds exactly the assets without a valid record.
"""

from __future__ import annotations

import hashlib
import json
from importlib import metadata
from pathlib import Path

from core import __version__
from core.files import sha256_file, write_bytes_atomic
from pipeline.report import AssetStatus

RECORD_DIR = ".decollage"
#: 2: entries carry the asset's provenance (exemplars, licences) and GLBs carry it in asset.extras.
RECORD_FORMAT = 2

#: Distributions whose versions change the bytes of the outputs.
KEY_LIBRARIES = ("numpy", "scipy", "scikit-image", "trimesh", "fast-simplification", "fonttools", "manifold3d",
                 "shapely", "mapbox-earcut", "build123d", "torch", "Pillow")


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
    """sha256 (hex) over everything an asset's outputs depend on."""
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


def record_path(out_dir: Path, name: str) -> Path:
    return out_dir / RECORD_DIR / f"{name}.json"


def write_record(out_dir: Path, name: str, key: str, entry: dict) -> None:
    """Record that ``name`` was built with ``key`` (after its outputs are in place)."""

    (out_dir / RECORD_DIR).mkdir(exist_ok=True)
    # Key order is kept: a cached entry must serialise exactly like a fresh one.
    data = json.dumps({"format": RECORD_FORMAT, "key": key, "entry": entry}, indent=1)
    write_bytes_atomic(record_path(out_dir, name), data.encode())


def valid_record(out_dir: Path, name: str, key: str) -> dict | None:
    """The recorded manifest entry when ``name`` is up to date for ``key``, else None."""
    path = record_path(out_dir, name)
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("format") != RECORD_FORMAT or record.get("key") != key:
        return None
    entry = record.get("entry") or {}
    outputs = entry.get("outputs") or {}
    if entry.get("status") != AssetStatus.BUILT or not outputs:
        return None
    for out in outputs.values():
        file = out_dir / out["path"]
        if not file.is_file() or file.stat().st_size != out["bytes"] or sha256_file(file) != out["sha256"]:
            return None
    return entry


def remove_stale_temporaries(out_dir: Path) -> int:
    """Delete temporaries left by a killed build (``.<name>.<pid>.<n>.tmp``); returns how many."""
    removed = 0
    for folder in (out_dir, out_dir / RECORD_DIR):
        if folder.is_dir():
            for temp in folder.glob(".*.tmp"):
                temp.unlink(missing_ok=True)
                removed += 1
    return removed

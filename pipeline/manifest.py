"""``manifest.json``: one file per build describing inputs, outputs, geometry and timings.

Format version 2. Paths of outputs are relative to the manifest's folder.
Axes and units are stated explicitly so that a consumer never has to guess.
Each asset's ``inputs`` holds ``entry_sha256`` (its resolved recipe entry) and
``files``, its input closure: one ``{"path", "sha256", "read_by"}`` per file
its source or detailizer read (``read_by``: ``source`` or ``detailizer``), the
path relative to the recipe's folder or ``<decollage>/...`` for files shipped
with this project, ``sha256`` null for a file a reader looked for and did not
find (``pipeline/cache.py``). Version 1 keyed ``files`` by recipe field and
listed only the files the recipe names.
No path in a manifest depends on where the checkout, the output folder or the user's cache lies: the
recipe is named relative to the output folder (or ``<decollage>/...``), a detailizer's checkpoint or
style set file like the input closure's paths (``<decollage>/...``, ``<styles>/...``, or relative to
the recipe's folder), with its sha256 in ``inputs.files``. An asset detailized block by block
(``pipeline/chunks.py``) says into how many blocks (``chunks``).
Timings are the only non-deterministic values; they live under ``timings_s``,
and an asset taken from the cache keeps the entry (timings included) recorded
when it was built, so rebuilding unchanged inputs rewrites an identical file.
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path

from core import __version__
from core.files import sha256_file, write_bytes_atomic
from core.grid import ISO_LEVEL
from pipeline.cache import portable_path
from pipeline.report import AssetStatus

MANIFEST_NAME = "manifest.json"
#: Rewritten after every build (also one that changed nothing): the signal a gallery polls to refresh.
#: At the top level: ``.decollage/`` holds one record per asset, and an asset may be named "build".
BUILD_SIGNAL = Path("build.json")
MANIFEST_FORMAT = 2

AXES = {"up": "+Y", "front": "+Z", "right": "+X", "units": "m", "convention": "glTF 2.0"}


def manifest_dict(loaded, reports, out_dir: Path) -> dict:
    """The manifest of a build into ``out_dir``: ``reports`` in recipe order (cached ones carry their recorded entry).

    The recipe's path is relative to ``out_dir`` when the recipe lies inside it, ``<decollage>/...``
    inside this project, else relative to ``out_dir`` (``pipeline/cache.py``'s ``portable_path``).
    """

    return {
        "format": MANIFEST_FORMAT,
        "tool": {"name": "decollage", "version": __version__, "python": platform.python_version()},
        # where the recipe lies, written so that it does not depend on where the checkout or the cwd is
        "recipe": {"path": portable_path(loaded.path, out_dir), "sha256": sha256_file(loaded.path)},
        "axes": AXES,
        "iso_level": ISO_LEVEL,
        "summary": {
            "assets": len(reports),
            "built": sum(r.status == AssetStatus.BUILT for r in reports),
            "failed": sum(r.status == AssetStatus.FAILED for r in reports),
        },
        "assets": [r.entry() for r in reports],
    }


def write_manifest(out_dir: Path, loaded, reports) -> Path:
    """Write ``out_dir/manifest.json`` atomically; returns its path."""

    path = out_dir / MANIFEST_NAME
    text = json.dumps(manifest_dict(loaded, reports, out_dir), indent=2, sort_keys=False) + "\n"
    write_bytes_atomic(path, text.encode("utf-8"))
    return path


def write_build_signal(out_dir: Path, reports) -> Path:
    """Write ``out_dir/build.json`` after a build: ``{"counter", "finished_unix", "rebuilt", "failed"}``.

    ``counter`` goes up by one per build into ``out_dir`` (``decollage build``, and each rebuild of
    ``--watch``); ``rebuilt`` names the assets built this time (not taken from the cache). A viewer
    polls the file (or its mtime) and reloads the assets named. ``manifest.json`` itself is not the
    signal: an unchanged rebuild rewrites it byte-identical.
    """
    path = out_dir / BUILD_SIGNAL
    try:
        counter = int(json.loads(path.read_text()).get("counter", 0))
    except (OSError, ValueError, AttributeError):
        counter = 0
    data = {"counter": counter + 1, "finished_unix": round(time.time(), 3),
            "rebuilt": [r.name for r in reports if not r.cached and r.status == AssetStatus.BUILT],
            "failed": [r.name for r in reports if r.status == AssetStatus.FAILED]}
    write_bytes_atomic(path, (json.dumps(data) + "\n").encode("utf-8"))
    return path

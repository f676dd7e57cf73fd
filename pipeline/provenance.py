"""Every asset's provenance (manifest entry and GLB ``asset.extras``) and the build folder's ``NOTICE.txt``.

An asset's ``provenance`` record (plain JSON, the same in ``manifest.json`` and
in the GLB's ``asset.extras.provenance``)::

    {"detailizer": "decollage",
     "checkpoint": {"file": "things.pt", "sha256": "..."} | null,      # null: no weights (upsample)
     "style_set": {"name": "things", "digest": "..."} | null,          # the set's inputs_hash
     "exemplars": [{"name", "style_set", "licence", "attribution", "source", "requires"}, ...] | null,
     "requires_attribution": ["ella_chair", ...]}                      # names of the exemplars that need it

``exemplars`` is what the detailizer reported (``core/provenance.py``); null
means it reported nothing, which the NOTICE says. ``write_notice`` writes
``<out>/NOTICE.txt`` from the built assets' records: exactly the exemplars they
used, grouped by what their licence asks (attribution, a licence to check,
nothing), each with the assets that use it.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from core.files import sha256_file, write_bytes_atomic

from core.provenance import EXEMPLARS, STYLE_SET, STYLE_SET_DIGEST, ExemplarCredit, LicenceNeed
from pipeline.report import AssetStatus

NOTICE_NAME = "NOTICE.txt"


@lru_cache(maxsize=16)
def _digest(path: str, size: int, mtime_ns: int) -> str:
    del size, mtime_ns  # part of the cache key: a replaced file is hashed again
    return sha256_file(Path(path))


def file_digest(path: str | Path) -> str:
    """sha256 of a file, hashed once per process while its size and mtime stay the same."""
    stat = Path(path).stat()
    return _digest(str(path), stat.st_size, stat.st_mtime_ns)


def asset_provenance(detailizer_name: str, checkpoint: str | None, extras: dict) -> dict:
    """The provenance record of one asset (see the module docstring).

    Args:
        detailizer_name: the registry name the asset was detailized with.
        checkpoint: the weights (or data) file the detailizer loaded, or None.
        extras: the detailized grid's ``FineGrid.extras`` (merged over blocks, ``pipeline/chunks.py``),
            which carry the exemplars.
    """
    ckpt = None
    if checkpoint and Path(checkpoint).is_file():
        ckpt = {"file": Path(checkpoint).name, "sha256": file_digest(checkpoint)}
    credits = None
    if EXEMPLARS in extras:
        credits = [ExemplarCredit.from_json(c).to_json() for c in extras[EXEMPLARS]]
    style_set = None
    if extras.get(STYLE_SET):
        style_set = {"name": str(extras[STYLE_SET]), "digest": extras.get(STYLE_SET_DIGEST)}
    return {
        "detailizer": detailizer_name,
        "checkpoint": ckpt,
        "style_set": style_set,
        "exemplars": credits,
        "requires_attribution": [c["name"] for c in credits or [] if c["requires"] == LicenceNeed.ATTRIBUTION],
    }


def glb_extras(provenance: dict) -> dict:
    """The GLB's ``asset.extras``: the provenance record under ``provenance``."""
    return {"provenance": provenance}


# --------------------------------------------------------------------------- NOTICE


_SECTIONS = (
    (LicenceNeed.ATTRIBUTION, "Attribution required",
     "Their licences (Creative Commons Attribution) ask that you credit them wherever the assets go:"),
    (LicenceNeed.UNCLEAR, "Licence to check before shipping",
     "No licence is stated for these, or it is one this tool does not know; check it before you ship:"),
    (LicenceNeed.NONE, "No attribution required",
     "Public domain (CC0) or this project's own procedural designs; listed for completeness:"),
)


def notice_text(entries: list[dict]) -> str:
    """NOTICE.txt for the manifest entries of a build (only built assets count)."""
    used: dict[tuple[str, str], tuple[ExemplarCredit, list[str]]] = {}
    unknown: list[str] = []
    for entry in entries:
        if entry.get("status") != AssetStatus.BUILT:
            continue
        credits = (entry.get("provenance") or {}).get("exemplars")
        if credits is None:
            unknown.append(entry["name"])
            continue
        for raw in credits:
            credit = ExemplarCredit.from_json(raw)
            used.setdefault((credit.style_set, credit.name), (credit, []))[1].append(entry["name"])
    lines = ["Third-party material in the assets of this build", "=" * 48, "",
             "Written by decollage with manifest.json: the style exemplars whose geometry the",
             "built assets carry, and what their licences ask of whoever ships the assets.", ""]
    if not used:
        lines += ["No built asset carries the geometry of a style exemplar.", ""]
    for need, title, intro in _SECTIONS:
        group = sorted((v for v in used.values() if v[0].need == need), key=lambda v: (v[0].style_set, v[0].name))
        if not group:
            continue
        lines += [title, "-" * len(title), intro, ""]
        for credit, assets in group:
            lines.append(f"  {credit.name} (style set '{credit.style_set}'), licence: {credit.licence}")
            if credit.attribution:
                lines.append(f"      {credit.attribution}")
            if credit.source:
                lines.append(f"      source: {credit.source}")
            lines.append(f"      used by: {', '.join(sorted(set(assets)))}")
        lines.append("")
    if unknown:
        lines += ["Not known", "---------", "These assets' detailizer does not report which exemplars it used:",
                  "  " + ", ".join(sorted(unknown)), ""]
    return "\n".join(lines)


def write_notice(out_dir: Path, entries: list[dict]) -> Path:
    """Write ``out_dir/NOTICE.txt`` atomically; returns its path."""
    path = Path(out_dir) / NOTICE_NAME
    write_bytes_atomic(path, notice_text(entries).encode("utf-8"))
    return path

"""The fixed evaluation protocol: which coarse contents, in which styles, every run evaluates.

A protocol is two files side by side in ``evaluation/protocols/``:

* ``<name>.json`` — format, version, the style set it was made for, the part
  vocabulary, the style names, one record per content (id, kind, how it was
  made, coarse shape) and the exact list of outputs: content × style
  assignment (part → style name), in evaluation order;
* from version 2, ``split``: the contents of ``dev`` and of ``test`` (half of
  every kind each, ``make_split``). Choices of checkpoints, recipes and
  thresholds are made on dev; acceptance figures are reported on test. The
  shipped ``things_v2.json`` is ``things_v1.json`` (same contents file, same
  outputs) with that split (``with_split``); v1 files stay readable, without a split;
* ``<name>.npz`` — the coarse contents as int8 label grids (−1 empty, else the
  index of the part in the vocabulary), one array per content id; its sha256 is
  in the JSON, so a stale pair is refused.

Evaluating needs neither build123d nor the fonts: the contents are stored. They
are made by ``make_protocol`` (``benchmarks/make_protocol.py``) from

* the recipe ``<name>_contents.yaml`` (text with the bundled font, CAD
  compositions, the imported cottage mesh and the mushroom voxels), voxelized
  by the pipeline itself to a grid whose longest side is 14 cells;
* augmentations of the style exemplars (``model.data``: anisotropic scale,
  rotation, combination of two exemplars of different categories) drawn with
  ``HELD_OUT_SEED``, a seed no training run uses (training draws from
  ``model.data.rng_for(seed, step, stream)``), at the 256³ scale, max-pooled ×16;

every content cropped to its occupied box plus one empty cell a side (so the
fine output is at most 256³). Style assignments per content: ``N_SINGLE``
single-style ones (every part the same exemplar; over all contents every
exemplar appears equally often) then ``N_MIXED`` mixed ones (bottom and top from
two different exemplars, drawn with the protocol seed). Regenerate with
``python benchmarks/make_protocol.py`` (deterministic: same set names, same bytes).
"""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

from core.errors import DecollageError

if TYPE_CHECKING:  # pragma: no cover
    from core.grid import LabeledGrid

FORMAT = "decollage-eval-protocol"
#: Version 2 adds the fixed dev/test split of the contents; version 1 files (no split) stay readable.
FORMAT_VERSION = 2
READABLE_VERSIONS = (1, 2)
PROTOCOL_DIR = Path(__file__).resolve().parent / "protocols"
DEFAULT_PROTOCOL = PROTOCOL_DIR / "things_v2.json"
#: The two halves of a v2 protocol: choices (checkpoints, recipes, thresholds) on dev, figures on test.
SPLITS = ("dev", "test")
#: Salt of the split's content order (see ``make_split``).
SPLIT_SALT = "decollage-eval-split-v2"
#: Seed of the exemplar augmentations and of the mixed style draws (never a training seed).
HELD_OUT_SEED = 9_900_001
N_SINGLE, N_MIXED = 8, 8
#: Longest side of a content, coarse cells (plus one empty cell a side: at most 16).
CONTENT_CELLS = 14
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


class ProtocolError(DecollageError):
    """An evaluation protocol is missing, damaged, or does not fit the detailizer or style set."""


@dataclass(frozen=True)
class OutputSpec:
    """One evaluated output: a content in a style assignment.

    Attributes:
        id: ``<content>/<nn>``.
        index: position in the protocol (seeds the output's patch sample and views).
        content: content id.
        styles: part name → style name, for every part of the vocabulary.
        mixed: whether the parts have different styles.
    """

    id: str
    index: int
    content: str
    styles: dict[str, str]
    mixed: bool


@dataclass(frozen=True, eq=False)
class Protocol:
    """A loaded protocol (see the module docstring)."""

    name: str
    path: Path
    style_set: str
    parts: tuple[str, ...]
    styles: tuple[str, ...]
    contents: dict[str, np.ndarray]
    content_info: dict[str, dict]
    outputs: tuple[OutputSpec, ...]
    meta: dict
    split: dict[str, tuple[str, ...]] | None = None

    def outputs_of(self, split: str | None) -> tuple[OutputSpec, ...]:
        """The outputs of the contents of ``split`` ("dev" or "test"), or all of them for None.

        Raises:
            ProtocolError: a split asked of a protocol without one (version 1), or an unknown split name.
        """
        if split is None:
            return self.outputs
        if split not in SPLITS:
            raise ProtocolError(f"unknown split {split!r}", field="--split", hint="dev or test")
        if self.split is None:
            raise ProtocolError("this protocol has no dev/test split (a version 1 file)", file=self.path,
                                field="split", hint=f"use {DEFAULT_PROTOCOL.name}, or evaluate every output")
        keep = set(self.split[split])
        return tuple(o for o in self.outputs if o.content in keep)

    def split_of(self, content: str) -> str | None:
        """"dev" or "test" for a content of a split protocol, None otherwise."""
        if self.split is None:
            return None
        return next((name for name in SPLITS if content in self.split[name]), None)

    def grid(self, output: OutputSpec, voxel_size_m: float = 0.1) -> "LabeledGrid":
        """The coarse LabeledGrid of an output: the content's parts, each in its assigned style."""
        from core.grid import EMPTY, LabeledGrid

        labels = self.contents[output.content]
        occ = labels >= 0
        names = tuple(dict.fromkeys(output.styles[p] for p in self.parts))  # distinct, in part order
        lut = np.array([names.index(output.styles[p]) for p in self.parts], dtype=np.int16)
        part = np.where(occ, labels, EMPTY).astype(np.int16)
        style = np.where(occ, lut[np.clip(labels, 0, None)], EMPTY).astype(np.int16)
        return LabeledGrid(occupancy=occ, part=part, style=style, part_names=self.parts, style_names=names,
                           voxel_size_m=voxel_size_m)


# --------------------------------------------------------------------------- reading


def _bad(path: Path, why: str, hint: str = "regenerate it with 'python benchmarks/make_protocol.py'") -> ProtocolError:
    return ProtocolError(f"not a usable evaluation protocol: {why}", file=path, hint=hint)


def load_protocol(path: str | Path = DEFAULT_PROTOCOL) -> Protocol:
    """Read and check a protocol (its JSON and the contents file beside it).

    Raises:
        ProtocolError: missing or unreadable files, wrong format/version, a
            contents file that does not match the JSON's hash, an output naming
            a content, part or style the protocol does not define.
    """
    path = Path(path)
    if not path.is_file():
        raise ProtocolError("protocol file not found", file=path,
                            hint=f"the shipped one is {DEFAULT_PROTOCOL.relative_to(PROTOCOL_DIR.parents[1])}")
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _bad(path, f"cannot read it as JSON ({type(exc).__name__})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise _bad(path, "it is not a decollage evaluation protocol", hint="give a protocol .json file")
    if meta.get("version") not in READABLE_VERSIONS:
        raise _bad(path, f"format version {meta.get('version')} is not one of the supported "
                         f"{', '.join(map(str, READABLE_VERSIONS))}")
    try:
        parts = tuple(str(p) for p in meta["parts"])
        styles = tuple(str(s) for s in meta["styles"])
        contents_path = path.parent / str(meta["contents_file"])
        records = {str(c["id"]): c for c in meta["contents"]}
        outputs_raw = list(meta["outputs"])
    except (KeyError, TypeError) as exc:
        raise _bad(path, f"missing field {exc}") from None
    if not contents_path.is_file():
        raise _bad(path, f"its contents file {contents_path.name} is missing")
    data = contents_path.read_bytes()
    if hashlib.sha256(data).hexdigest() != meta.get("contents_sha256"):
        raise _bad(path, f"{contents_path.name} does not match the hash recorded in the protocol")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            contents = {cid: np.asarray(npz[cid]) for cid in records}
    except (KeyError, ValueError, zipfile.BadZipFile, OSError) as exc:
        raise _bad(path, f"{contents_path.name} lacks a content or is damaged ({exc})") from None
    for cid, lab in contents.items():
        if lab.ndim != 3 or lab.dtype != np.int8 or lab.min() < -1 or lab.max() >= len(parts) or lab.max() < 0:
            raise _bad(path, f"content {cid!r} is not a 3-D int8 label grid with parts in [0, {len(parts)})")
    outputs = []
    for i, o in enumerate(outputs_raw):
        where = f"outputs[{i}]"
        try:
            oid, content, assign = str(o["id"]), str(o["content"]), {str(k): str(v) for k, v in o["styles"].items()}
        except (KeyError, TypeError, AttributeError):
            raise _bad(path, f"{where} needs id, content and styles") from None
        if content not in contents:
            raise ProtocolError(f"{where} names the unknown content {content!r}", file=path, field=where)
        if set(assign) != set(parts):
            raise ProtocolError(f"{where} assigns styles to {sorted(assign)}, not to the parts {list(parts)}",
                                file=path, field=where)
        unknown = sorted(set(assign.values()) - set(styles))
        if unknown:
            raise ProtocolError(f"{where} names styles the protocol does not list: {', '.join(unknown)}",
                                file=path, field=where, hint="styles: " + ", ".join(styles))
        outputs.append(OutputSpec(oid, i, content, assign, len(set(assign.values())) > 1))
    if len({o.id for o in outputs}) != len(outputs):
        raise _bad(path, "output ids repeat")
    split = _read_split(path, meta, set(records)) if meta["version"] >= 2 else None
    return Protocol(name=str(meta.get("name", path.stem)), path=path, style_set=str(meta.get("style_set", "")),
                    parts=parts, styles=styles, contents=contents, content_info=records, outputs=tuple(outputs),
                    meta=meta, split=split)


def _read_split(path: Path, meta: dict, content_ids: set[str]) -> dict[str, tuple[str, ...]]:
    """The v2 ``split`` field: every content in exactly one of dev and test."""
    raw = meta.get("split")
    if not isinstance(raw, dict) or set(raw) != set(SPLITS):
        raise ProtocolError("a version 2 protocol needs a split with 'dev' and 'test' content lists",
                            file=path, field="split")
    split = {k: tuple(str(c) for c in raw[k]) for k in SPLITS}
    both = set(split["dev"]) & set(split["test"])
    listed = set(split["dev"]) | set(split["test"])
    if both or listed != content_ids or any(len(set(v)) != len(v) for v in split.values()):
        raise ProtocolError("the split must put every content in exactly one of dev and test"
                            + (f" (in both: {', '.join(sorted(both))})" if both else "")
                            + (f" (unknown or missing: {', '.join(sorted(listed ^ content_ids))})"
                               if listed != content_ids else ""), file=path, field="split")
    return split


def make_split(contents: list[tuple[str, str]], salt: str = SPLIT_SALT) -> dict[str, list[str]]:
    """A dev/test split of (content id, kind) pairs, stratified by kind, fixed by the ids alone.

    Within each kind the contents are ordered by sha256(salt, id) and alternate
    test, dev, test, ... (an odd count gives test the extra one). The order does
    not depend on the order of ``contents`` or on other kinds, so the split is
    reproducible from the ids; the protocol file stores it, so it never moves.
    """
    split: dict[str, list[str]] = {"dev": [], "test": []}
    kinds = dict.fromkeys(kind for _, kind in contents)
    for kind in kinds:
        ids = sorted((cid for cid, k in contents if k == kind),
                     key=lambda cid: hashlib.sha256(f"{salt}/{cid}".encode()).hexdigest())
        for i, cid in enumerate(ids):
            split["test" if i % 2 == 0 else "dev"].append(cid)
    return split


def with_split(v1_path: str | Path, name: str, folder: Path = PROTOCOL_DIR) -> Path:
    """Write ``<folder>/<name>.json``: the protocol at ``v1_path`` (same contents file, outputs, seeds)
    as a version 2 file with the dev/test split of ``make_split``. Returns the new path."""
    from core.files import write_bytes_atomic

    old = load_protocol(v1_path)
    meta = dict(old.meta)
    meta.update(version=FORMAT_VERSION, name=name,
                split=make_split([(cid, str(info.get("kind", "?"))) for cid, info in old.content_info.items()]))
    if Path(folder).resolve() != old.path.parent.resolve():
        raise ProtocolError("the v2 file must sit beside its contents file", field="folder")
    order = [k for k in meta if k not in ("contents", "outputs")] + ["contents", "outputs"]
    json_path = Path(folder) / f"{name}.json"
    write_bytes_atomic(json_path, _format_json({k: meta[k] for k in order}).encode())
    return json_path


def check_detailizer(protocol: Protocol, detailizer) -> None:
    """ProtocolError unless the detailizer knows every style and part the protocol uses."""
    used = sorted({s for o in protocol.outputs for s in o.styles.values()})
    known = getattr(detailizer, "style_names", None)
    if known is not None:
        unknown = [s for s in used if s not in known]
        if unknown:
            raise ProtocolError(
                f"the protocol names {len(unknown)} style(s) the '{detailizer.name}' detailizer does not know: "
                f"{', '.join(unknown[:8])}{' …' if len(unknown) > 8 else ''}", file=protocol.path, field="styles",
                hint=f"it knows: {', '.join(known)}; use a protocol made for its style set "
                     "or regenerate it with 'python benchmarks/make_protocol.py'")
    parts = getattr(detailizer, "part_names", None)
    if parts is not None:
        missing = [p for p in protocol.parts if p not in parts]
        if missing:
            raise ProtocolError(f"the '{detailizer.name}' detailizer has no part(s) {', '.join(missing)}",
                                file=protocol.path, field="parts", hint=f"its parts: {', '.join(parts)}")


# --------------------------------------------------------------------------- making


def style_assignments(styles: list[str], n_contents: int, parts: tuple[str, ...], seed: int = HELD_OUT_SEED,
                      n_single: int = N_SINGLE, n_mixed: int = N_MIXED) -> list[list[dict[str, str]]]:
    """Per content, ``n_single`` single-style then ``n_mixed`` mixed assignments (part → style).

    Single styles rotate through the list (content c gets styles c·n_single … mod
    n), so every style is used equally often when n divides n_contents·n_single;
    mixed ones give every part a style, not all the same, drawn without repeats.
    """
    n = len(styles)
    if n < 2 or len(parts) < 2:
        raise ValueError("mixed assignments need at least two styles and two parts")
    out = []
    for c in range(n_contents):
        rows = [{p: styles[(c * n_single + k) % n] for p in parts} for k in range(n_single)]
        rng = np.random.default_rng([seed, c])
        seen: set[tuple[str, ...]] = set()
        while len(rows) < n_single + n_mixed:
            pick = tuple(styles[int(i)] for i in rng.integers(0, n, size=len(parts)))
            if len(set(pick)) > 1 and pick not in seen:
                seen.add(pick)
                rows.append(dict(zip(parts, pick)))
        out.append(rows)
    return out


def crop_with_margin(labels: np.ndarray, margin: int = 1) -> np.ndarray:
    """Labels (−1 empty) cropped to the occupied box plus ``margin`` empty cells a side, int8."""
    idx = np.argwhere(labels >= 0)
    lo, hi = idx.min(axis=0), idx.max(axis=0) + 1
    box = labels[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    return np.pad(box, margin, constant_values=-1).astype(np.int8)


def recipe_contents(recipe_path: Path, parts: tuple[str, ...],
                    progress: Callable[[str], None] | None = None) -> list[tuple[str, str, dict, np.ndarray]]:
    """(id, kind, description, coarse labels) of every asset of a contents recipe, voxelized by the pipeline."""
    from core.recipe_loader import load_recipe
    from pipeline.regions import apply_regions
    from geometry.voxelize import voxelize
    from sources import load_source

    loaded = load_recipe(recipe_path)
    out = []
    for i, asset in enumerate(loaded.recipe.assets):
        source = load_source(asset.source, loaded.base_dir)
        grid, _ = apply_regions(voxelize(source, asset.grid, asset.fit), asset.regions, field=f"assets[{i}].regions")
        lut = np.array([parts.index(p) for p in grid.part_names], dtype=np.int16)
        labels = np.where(grid.occupancy, lut[np.clip(grid.part, 0, None)], -1)
        desc = {"recipe": recipe_path.name, "asset": asset.name,
                "source": json.loads(asset.source.model_dump_json(exclude_defaults=True))}
        out.append((asset.name, asset.source.kind, desc, crop_with_margin(labels)))
        if progress:
            progress(asset.name)
    return out


#: Exemplar augmentations: (id, category of the first exemplar, category of a second one or None).
AUGMENTED = (
    ("aug_building", "building", None),
    ("aug_plant", "plant", None),
    ("aug_cake", "cake", None),
    ("aug_crystal", "crystal", None),
    ("aug_building_plant", "building", "plant"),
    ("aug_cake_crystal", "cake", "crystal"),
    ("aug_crystal_building", "crystal", "building"),
    ("aug_plant_cake", "plant", "cake"),
)


def augmented_contents(style_set, seed: int = HELD_OUT_SEED) -> list[tuple[str, str, dict, np.ndarray]]:
    """Augmented exemplars (one or two combined), drawn with ``seed``, as coarse labels (×16 max-pool)."""
    from model.data import AugmentConfig, augment_exemplar, combine, exemplars_from_set, fit_max_side, \
        place_in_crop
    from model.masks import coarse_part_labels

    exemplars = exemplars_from_set(style_set)
    aug = AugmentConfig(resolution=style_set.resolution)
    f = style_set.resolution // 16
    out = []
    for k, (cid, first, second) in enumerate(AUGMENTED):
        rng = np.random.default_rng([seed, 1000 + k])
        pool = [e for e in exemplars if e.category == first]
        if not pool:
            raise ProtocolError(f"the style set has no '{first}' exemplar for content {cid}", field="set")
        a = pool[int(rng.integers(len(pool)))]
        shape = augment_exemplar(a, rng, aug)
        used = [a.name]
        if second is not None:
            pool2 = [e for e in exemplars if e.category == second]
            if not pool2:
                raise ProtocolError(f"the style set has no '{second}' exemplar for content {cid}", field="set")
            b = pool2[int(rng.integers(len(pool2)))]
            shape = combine(shape, augment_exemplar(b, rng, aug), rng, aug)
            used.append(b.name)
        shape = fit_max_side(shape, CONTENT_CELLS * f - f)  # leaves room for the sub-cell offset
        fine = place_in_crop(shape, rng, f, margin=1)
        coarse_occ = (fine >= 0).reshape(fine.shape[0] // f, f, fine.shape[1] // f, f, fine.shape[2] // f, f) \
            .any(axis=(1, 3, 5))
        labels = np.where(coarse_occ, coarse_part_labels(fine, f, len(a.part_names)), -1)
        desc = {"exemplars": used, "seed": [seed, 1000 + k], "augment": "model.data augment_exemplar"
                + (" + combine" if second else "")}
        out.append((cid, "augmented_exemplar", desc, crop_with_margin(labels)))
    return out


def _format_json(meta: dict) -> str:
    """Indented JSON with one line per list item of ``contents``/``outputs`` (diff-friendly)."""
    lines = ["{"]
    keys = list(meta)
    for i, key in enumerate(keys):
        end = "," if i < len(keys) - 1 else ""
        value = meta[key]
        if isinstance(value, list) and value and isinstance(value[0], dict):
            items = [" " + json.dumps(v, ensure_ascii=False) for v in value]
            lines.append(f" {json.dumps(key)}: [\n " + ",\n ".join(items) + f"\n ]{end}")
        else:
            lines.append(f" {json.dumps(key)}: {json.dumps(value, ensure_ascii=False)}{end}")
    return "\n".join(lines) + "\n}\n"


def _npy_bytes(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=False)
    return buf.getvalue()


def encode_contents(contents: list[tuple[str, np.ndarray]]) -> bytes:
    """A deterministic zip (fixed timestamps) of ``<id>.npy`` arrays, readable by ``np.load``."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for cid, arr in contents:
            info = zipfile.ZipInfo(f"{cid}.npy", date_time=_ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, _npy_bytes(np.ascontiguousarray(arr)))
    return buf.getvalue()


def make_protocol(name: str = "things_v1", set_name: str = "things", folder: Path = PROTOCOL_DIR,
                  progress: Callable[[str], None] | None = None) -> Path:
    """Make ``<folder>/<name>.json`` and ``.npz`` from the style set and ``<name>_contents.yaml``.

    Needs the CAD and text sources (build123d, fonts) and builds the style set
    if it is not cached. Returns the JSON path.
    """
    from stylesets.registry import resolve_style_set

    style_set = resolve_style_set(set_name)
    made = recipe_contents(folder / f"{name}_contents.yaml", tuple(style_set.vocabulary.parts), progress) \
        + augmented_contents(style_set)
    return write_protocol(name, folder, set_name, style_set, made)


def write_protocol(name: str, folder: Path, set_name: str, style_set, made: list[tuple[str, str, dict, np.ndarray]],
                   n_single: int = N_SINGLE, n_mixed: int = N_MIXED, seed: int = HELD_OUT_SEED) -> Path:
    """Write a protocol from its contents (id, kind, description, coarse labels) and a style set.

    ``set_name`` is what the protocol records to find the set again: a built-in
    set name, or a ``.npz`` set file (relative to the protocol's folder).
    """
    from core.files import write_bytes_atomic

    parts = tuple(style_set.vocabulary.parts)
    styles = [e.name for e in style_set.exemplars]
    for cid, _, _, lab in made:
        missing = [p for i, p in enumerate(parts) if not (lab == i).any()]
        if missing:
            raise ProtocolError(f"content {cid} has no {', '.join(missing)} part", field=cid,
                                hint="every content needs every part, or mixed styles mean nothing")
        if max(lab.shape) > CONTENT_CELLS + 2:
            raise ProtocolError(f"content {cid} is {lab.shape} cells, more than {CONTENT_CELLS + 2}", field=cid)
    assignments = style_assignments(styles, len(made), parts, seed, n_single, n_mixed)
    data = encode_contents([(cid, lab) for cid, _, _, lab in made])
    outputs = []
    for (cid, _, _, _), rows in zip(made, assignments):
        outputs += [{"id": f"{cid}/{k:02d}", "content": cid, "styles": row} for k, row in enumerate(rows)]
    split = make_split([(cid, kind) for cid, kind, _, _ in made])
    meta = {
        "format": FORMAT, "version": FORMAT_VERSION, "name": name, "style_set": set_name,
        "style_set_digest": set_digest(style_set), "parts": list(parts), "styles": styles,
        "seed": seed, "n_single": n_single, "n_mixed": n_mixed,
        "contents_file": f"{name}.npz", "contents_sha256": hashlib.sha256(data).hexdigest(),
        "made_by": "python benchmarks/make_protocol.py", "split": split,
        "contents": [{"id": cid, "kind": kind, "shape": list(lab.shape), "occupied": int((lab >= 0).sum()),
                      **desc} for cid, kind, desc, lab in made],
        "outputs": outputs,
    }
    write_bytes_atomic(Path(folder) / f"{name}.npz", data)
    json_path = Path(folder) / f"{name}.json"
    write_bytes_atomic(json_path, _format_json(meta).encode())
    return json_path


def set_digest(style_set) -> str:
    """sha256 of a style set's exemplars (names, categories, offsets, label arrays): its geometry.

    Unlike the set's ``inputs_hash`` it does not change when only code changes.
    """
    h = hashlib.sha256()
    for ex in style_set.exemplars:
        h.update(json.dumps([ex.name, ex.category, list(ex.offset), list(ex.labels.shape)]).encode())
        h.update(np.ascontiguousarray(ex.labels).tobytes())
    return h.hexdigest()


def resolve_protocol_set(protocol: Protocol):
    """The protocol's style set: a built-in name (built and cached if needed) or a .npz next to the protocol."""
    from stylesets.registry import resolve_style_set

    name = protocol.style_set or "things"
    if name.endswith(".npz") and not Path(name).is_absolute():
        name = str(protocol.path.parent / name)
    return resolve_style_set(name)

"""Style exemplar sets: part-labelled 256³ solid voxel grids, one versioned compressed file per set.

Role: voxelizes exemplar specs (procedural, real meshes, or a user's folder)
into labelled grids, writes them as one ``.npz`` per set, loads them back and
refuses foreign, old or damaged files. The detailizer's training data.

Normalisation: each exemplar's bounding box is scaled so that its longest side
spans ``fit_voxels(resolution)`` = 15/16 of the grid (240 of 256 voxels) and
centred in the ``resolution``³ cube. (DECOR-GAN scales the *diagonal* to the
cube, which spends a third of the resolution on nothing; training crops to the
bounding box and rescales by U(0.7, 2.0) anyway, so the scale is free and the
finest grid keeps the most detail.)

Labels (like DECOLLAGE's ``segmentation_voxel.hdf5``): uint8, 0 = empty,
``i + 1`` = part ``vocabulary.parts[i]``. Both sets share one small vocabulary:
furniture ``back, seat, leg, armrest, stretcher`` (tables: tabletop = seat,
legs/aprons/pedestals = leg, stretchers/shelves = stretcher; P = 5); things
``bottom, top`` (P = 2) where each category names them its own way: building
body/roof, plant pot/leaf, cake and crystal bottom/top, as the paper does.

File format (``FORMAT``, version ``FORMAT_VERSION``): a zip (``np.load``
readable) with ``meta.npy`` (uint8 bytes of a UTF-8 JSON blob: format, version,
set name, vocabulary, resolution, inputs hash, per exemplar its name,
category, parts, source, licence, attribution, voxel counts, crop offset and
shape, detail ratio) and ``labels_<i>.npy`` (the exemplar's labels cropped to
its occupied box: (X, Y, Z) uint8, placed at ``offset`` in the full grid). Zip
entries carry a fixed timestamp, so the same inputs give the same bytes.

Cache: ``inputs_hash`` = sha256 of the format version, resolution, the code
that makes exemplars (this module, the voxelizer, ``sources/exemplars/*.py``)
and every spec (name, category, source, licence, design key, input-file
hashes). ``build_set`` does nothing when the file on disk carries the same hash.
Files live in ``style_dir()``: ``$DECOLLAGE_STYLES_DIR``, else
``$XDG_CACHE_HOME/decollage/styles`` (``~/.cache/decollage/styles``); they are
derived from third-party meshes and cheap to rebuild, so they are not committed.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import sys
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from core.errors import DecollageError, VoxelizeError
from core.files import (
    InputKind,
    check_input_file,
    code_digest,
    ensure_writable_dir,
    input_limit_bytes,
    sha256_file,
    write_bytes_atomic,
)
from core.recipe import FitMode, GridSettings
from geometry.voxelize import voxelize
from sources.base import PartMeshes
from stylesets.catalogues.prims import merge

if TYPE_CHECKING:
    import trimesh

FORMAT = "decollage-style-set"
FORMAT_VERSION = 1
#: Exemplar grid side (the paper's 256³).
RESOLUTION = 256
#: Coarse grid side of the detail check (the detailizer's 16³ input).
COARSE_SIDE = 16
#: An exemplar passes the detail check when its fine surface ratio is ≥ this × its coarse one.
DETAIL_RATIO_MIN = 1.3
#: Below this fraction of interior voxels an exemplar is a hollow shell (a failed fill), refused.
MIN_INTERIOR_FRACTION = 0.03
#: The hollow-shell check only applies from this grid side up: on coarser grids thin parts
#: (slats, spindles) are one or two voxels thick and have no interior even when filled.
HOLLOW_CHECK_MIN_RESOLUTION = 128
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


class ExemplarError(DecollageError):
    """A style exemplar or style set could not be built, imported or loaded."""


# --------------------------------------------------------------------------- vocabularies


@dataclass(frozen=True)
class Vocabulary:
    """The part names of a set; label ``i + 1`` is ``parts[i]``.

    ``aliases``: category → its own names for the same parts, in the same order
    (e.g. building → ("body", "roof") for ("bottom", "top")).
    """

    name: str
    parts: tuple[str, ...]
    aliases: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def index(self, part: str, category: str | None = None) -> int:
        """Label index (0-based) of ``part``, accepting any category's alias; KeyError if unknown."""
        if part in self.parts:
            return self.parts.index(part)
        names = [self.aliases[category]] if category in self.aliases else list(self.aliases.values())
        for alias in names:
            if part in alias:
                return alias.index(part)
        raise KeyError(part)

    def alias_map(self) -> dict[str, str]:
        """Every unambiguous alias that is not itself a part name → its part (e.g. roof → top)."""
        seen: dict[str, set[str]] = {}
        for names in self.aliases.values():
            for alias, part in zip(names, self.parts):
                if alias != part and alias not in self.parts:
                    seen.setdefault(alias, set()).add(part)
        return {a: next(iter(p)) for a, p in sorted(seen.items()) if len(p) == 1}

    def accepted(self) -> list[str]:
        """Every accepted part name, sorted."""
        return sorted(set(self.parts).union(*[set(a) for a in self.aliases.values()]))

    def to_json(self) -> dict:
        return {"name": self.name, "parts": list(self.parts),
                "aliases": {k: list(v) for k, v in sorted(self.aliases.items())}}

    @classmethod
    def from_json(cls, data: dict) -> "Vocabulary":
        return cls(str(data["name"]), tuple(data["parts"]),
                   {k: tuple(v) for k, v in data.get("aliases", {}).items()})


FURNITURE = Vocabulary("furniture", ("back", "seat", "leg", "armrest", "stretcher"),
                       {"table": ("back", "tabletop", "leg", "armrest", "stretcher")})
THINGS = Vocabulary("things", ("bottom", "top"),
                    {"building": ("body", "roof"), "plant": ("pot", "leaf"),
                     "cake": ("bottom", "top"), "crystal": ("bottom", "top")})
VOCABULARIES: dict[str, Vocabulary] = {v.name: v for v in (FURNITURE, THINGS)}


def vocabulary_from_arg(text: str) -> Vocabulary:
    """``furniture`` / ``things`` / a comma-separated part list (``a,b,c``) → a Vocabulary."""
    if text in VOCABULARIES:
        return VOCABULARIES[text]
    parts = tuple(p.strip() for p in text.split(",") if p.strip())
    if len(parts) < 1 or len(set(parts)) != len(parts) or len(parts) > 254:
        raise ExemplarError(f"bad vocabulary {text!r}", field="vocab",
                            hint="use 'furniture', 'things' or distinct part names like 'body,roof'")
    return Vocabulary("custom", parts)


# --------------------------------------------------------------------------- specs and results


@dataclass(frozen=True)
class ExemplarSpec:
    """How to make one exemplar.

    Attributes:
        name, category: e.g. "chair_windsor", "chair".
        make: () → {part name: mesh or list of closed meshes}, metres, +Y up;
            part names from the set's vocabulary (or the category's aliases).
        key: a stable text describing the design (hashed for the cache).
        source: "procedural", "sweethome3d-furniture", "user"...
        licence, attribution: what the NOTICE needs.
        input_files: files the meshes are read from (hashed for the cache).
    """

    name: str
    category: str
    make: Callable[[], dict]
    key: str
    source: str = "procedural"
    licence: str = "project licence (procedural)"
    attribution: str = ""
    input_files: tuple[Path, ...] = ()


@dataclass(frozen=True, eq=False)
class Exemplar:
    """One voxelized exemplar.

    ``labels``: (X, Y, Z) uint8 labels cropped to the occupied box (0 empty,
    i + 1 = vocabulary part i), placed at ``offset`` (3,) in the full grid.
    ``meta``: the JSON record (name, category, parts, source, licence, counts, detail...).
    """

    labels: np.ndarray
    offset: tuple[int, int, int]
    meta: dict

    @property
    def name(self) -> str:
        return self.meta["name"]

    @property
    def category(self) -> str:
        return self.meta["category"]

    def full(self, resolution: int) -> np.ndarray:
        """(R, R, R) uint8 labels in the full exemplar grid."""
        out = np.zeros((resolution,) * 3, dtype=np.uint8)
        sl = tuple(slice(o, o + n) for o, n in zip(self.offset, self.labels.shape))
        out[sl] = self.labels
        return out


@dataclass(frozen=True, eq=False)
class StyleSet:
    """A loaded style set: its vocabulary, resolution and exemplars (in build order)."""

    name: str
    vocabulary: Vocabulary
    resolution: int
    inputs_hash: str
    exemplars: tuple[Exemplar, ...]
    path: Path | None = None

    def get(self, name: str) -> Exemplar:
        for ex in self.exemplars:
            if ex.name == name:
                return ex
        raise ExemplarError(f"set '{self.name}' has no exemplar '{name}'", field="name",
                            hint="exemplars: " + ", ".join(e.name for e in self.exemplars))


@dataclass(frozen=True)
class BuildResult:
    path: Path
    built: bool  # False: the file on disk was already up to date
    seconds: float
    style_set: StyleSet


# --------------------------------------------------------------------------- voxelizing


def fit_voxels(resolution: int) -> int:
    """Voxels across an exemplar's longest side (15/16 of the grid)."""
    return max(1, (resolution * 15) // 16)


def voxelize_parts(parts: dict[str, "trimesh.Trimesh"], part_labels: Sequence[int], resolution: int,
                   name: str = "") -> tuple[np.ndarray, list[str]]:
    """Named part meshes → (R, R, R) uint8 labels (0 empty, ``part_labels[i]`` for part i) + warnings.

    Solid fill and labels by the project voxelizer at voxel centres; the
    shape's longest side spans ``fit_voxels(resolution)`` voxels, centred.
    """

    settings = GridSettings.model_construct(resolution=fit_voxels(resolution), fit=FitMode.LONGEST,
                                            voxel_size_m=None, max_cells=resolution, min_coverage=0.5,
                                            keep_thin=False)
    try:
        grid = voxelize(PartMeshes(parts=dict(parts)), settings, FitMode.LONGEST, supersample=1)
    except VoxelizeError as exc:
        raise ExemplarError(f"exemplar '{name}': {exc.message}", field=name or None,
                            hint="check that the meshes have faces and a non-zero size") from None
    lut = np.zeros(len(part_labels) + 1, dtype=np.uint8)  # index -1 (empty) → 0 via the last slot
    lut[:len(part_labels)] = np.asarray(part_labels, dtype=np.uint8)
    small = lut[grid.part.astype(np.int64)]
    out = np.zeros((resolution,) * 3, dtype=np.uint8)
    start = [(resolution - n) // 2 for n in small.shape]
    out[tuple(slice(s, s + n) for s, n in zip(start, small.shape))] = small
    return out, list(grid.warnings)


def surface_mask(occ: np.ndarray) -> np.ndarray:
    """(X, Y, Z) bool: occupied voxels with at least one empty 6-neighbour (outside the grid is empty)."""
    padded = np.pad(occ, 1)
    interior = occ.copy()
    for axis in range(3):
        for step in (-1, 1):
            interior &= np.roll(padded, step, axis=axis)[1:-1, 1:-1, 1:-1]
    return occ & ~interior


def detail_figures(occ: np.ndarray, coarse_side: int = COARSE_SIDE) -> dict:
    """The detail sanity check on an (R, R, R) bool grid (R divisible by ``coarse_side``).

    ``fine`` = surface / occupied voxels at R³; ``coarse`` = the same for the
    ``coarse_side``³ max-pool upsampled back to R³; ``ratio`` = fine / coarse;
    ``interior`` = fraction of occupied voxels that are not surface.
    """
    r = occ.shape[0]
    f = r // coarse_side
    n_occ = int(occ.sum())
    n_surf = int(surface_mask(occ).sum())
    pooled = occ.reshape(coarse_side, f, coarse_side, f, coarse_side, f).any(axis=(1, 3, 5))
    # The upsampled block grid's surface counts per block face: count it at coarse
    # resolution (a block on the coarse surface contributes its f×f faces' voxels).
    up = pooled.repeat(f, 0).repeat(f, 1).repeat(f, 2)
    c_occ = int(up.sum())
    c_surf = int(surface_mask(up).sum())
    fine = n_surf / n_occ if n_occ else 0.0
    coarse = c_surf / c_occ if c_occ else 0.0
    return {"fine": round(fine, 4), "coarse": round(coarse, 4),
            "ratio": round(fine / coarse, 3) if coarse else 0.0,
            "interior": round(1 - fine, 4)}


def make_exemplar(spec: ExemplarSpec, vocabulary: Vocabulary, resolution: int = RESOLUTION) -> Exemplar:
    """Build one exemplar from its spec: make the meshes, check parts, voxelize, measure, crop."""

    try:
        raw = spec.make()
    except DecollageError as exc:
        raise exc.located(field=spec.name)
    parts: dict = {}
    labels: list[int] = []
    for part, meshes in raw.items():
        try:
            index = vocabulary.index(part, spec.category)
        except KeyError:
            raise ExemplarError(f"exemplar '{spec.name}': unknown part name '{part}'", field=spec.name,
                                hint="parts of vocabulary '" + vocabulary.name + "': "
                                     + ", ".join(vocabulary.accepted())) from None
        mesh = merge(meshes if isinstance(meshes, (list, tuple)) else [meshes])
        if len(mesh.faces) == 0:
            continue
        parts[f"{part}"] = mesh
        labels.append(index + 1)
    if not parts:
        raise ExemplarError(f"exemplar '{spec.name}' has no parts", field=spec.name,
                            hint="give it at least one part mesh with faces")
    full, warnings = voxelize_parts(parts, labels, resolution, spec.name)
    occ = full > 0
    if not occ.any():
        raise ExemplarError(f"exemplar '{spec.name}' voxelizes to nothing", field=spec.name,
                            hint="its meshes have no volume (flat or open surfaces only?)")
    figures = detail_figures(occ) if resolution % COARSE_SIDE == 0 else {}
    if figures and resolution >= HOLLOW_CHECK_MIN_RESOLUTION and figures["interior"] < MIN_INTERIOR_FRACTION:
        raise ExemplarError(f"exemplar '{spec.name}' voxelizes to a hollow shell "
                            f"({figures['interior']:.1%} interior voxels)", field=spec.name,
                            hint="its mesh is too open to fill; close the holes or use another model")
    nz = [np.flatnonzero(occ.any(axis=tuple(b for b in range(3) if b != a))) for a in range(3)]
    offset = tuple(int(i[0]) for i in nz)
    crop = full[tuple(slice(i[0], i[-1] + 1) for i in nz)].copy()
    counts = np.bincount(crop.reshape(-1), minlength=len(vocabulary.parts) + 1)
    aliases = vocabulary.aliases.get(spec.category, vocabulary.parts)
    meta = {
        "name": spec.name, "category": spec.category, "source": spec.source, "licence": spec.licence,
        "attribution": spec.attribution,
        "parts": [vocabulary.parts[i] for i in range(len(vocabulary.parts)) if counts[i + 1] > 0],
        "part_aliases": {vocabulary.parts[i]: aliases[i] for i in range(len(vocabulary.parts))
                         if counts[i + 1] > 0 and aliases[i] != vocabulary.parts[i]},
        "voxels": int(occ.sum()),
        "part_voxels": {vocabulary.parts[i]: int(counts[i + 1]) for i in range(len(vocabulary.parts))},
        "offset": list(offset), "shape": list(crop.shape),
        "detail": figures, "warnings": warnings,
    }
    return Exemplar(labels=crop, offset=offset, meta=meta)


# --------------------------------------------------------------------------- hashing and files


def code_hash(specs: Sequence[ExemplarSpec] = ()) -> str:
    """sha256 of the code that makes the exemplars of ``specs``.

    This module, the voxelizer and the primitives, plus the module of every spec's
    ``make`` function (e.g. ``stylesets/catalogues/things.py``): editing one set's
    designs, or adding a set, leaves the other sets' caches valid.
    """
    root = Path(__file__).resolve().parent.parent
    modules = {"stylesets/format.py", "geometry/voxelize.py", "stylesets/catalogues/prims.py"}
    for spec in specs:
        func = getattr(spec.make, "func", spec.make)  # functools.partial → the function
        path = Path(getattr(sys.modules.get(getattr(func, "__module__", "")), "__file__", "") or "").resolve()
        if path.is_file() and root in path.parents:
            modules.add(path.relative_to(root).as_posix())
    return code_digest(*sorted(modules))


def inputs_hash(set_name: str, vocabulary: Vocabulary, specs: Sequence[ExemplarSpec], resolution: int) -> str:
    """The cache key of a set (see module docstring)."""
    record = {
        "format": FORMAT, "version": FORMAT_VERSION, "set": set_name, "resolution": resolution,
        "vocabulary": vocabulary.to_json(), "code": code_hash(specs),
        "specs": [{"name": s.name, "category": s.category, "source": s.source, "licence": s.licence,
                   "attribution": s.attribution, "key": s.key,
                   "files": [sha256_file(Path(p)) for p in s.input_files]} for s in specs],
    }
    return hashlib.sha256(json.dumps(record, sort_keys=True).encode()).hexdigest()


def style_dir() -> Path:
    """Folder of built style sets (see module docstring)."""
    if os.environ.get("DECOLLAGE_STYLES_DIR"):
        return Path(os.environ["DECOLLAGE_STYLES_DIR"]).expanduser()
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache).expanduser() / "decollage" / "styles"


def set_path(name: str, folder: Path | None = None) -> Path:
    return Path(folder or style_dir()) / f"{name}.npz"


def _npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, np.ascontiguousarray(array), allow_pickle=False)
    return buffer.getvalue()


def encode_set(name: str, vocabulary: Vocabulary, resolution: int, digest: str,
               exemplars: Sequence[Exemplar]) -> bytes:
    """The set file's bytes (deterministic: fixed zip timestamps, fixed entry order)."""
    meta = {"format": FORMAT, "version": FORMAT_VERSION, "set": name, "resolution": resolution,
            "vocabulary": vocabulary.to_json(), "inputs_hash": digest,
            "exemplars": [ex.meta for ex in exemplars]}
    entries = [("meta.npy", np.frombuffer(json.dumps(meta, sort_keys=True).encode(), dtype=np.uint8))]
    entries += [(f"labels_{i}.npy", ex.labels) for i, ex in enumerate(exemplars)]
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for entry, array in entries:
            info = zipfile.ZipInfo(entry, date_time=_ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, _npy_bytes(array), compresslevel=6)
    return buffer.getvalue()


def _refuse(path: Path, why: str) -> ExemplarError:
    return ExemplarError(f"not a usable style set: {why}", file=path,
                         hint="rebuild it with 'decollage styles build' (or re-import it)")


def read_meta(path: Path) -> dict:
    """Only the JSON header of a set file (fast; validates format and version)."""
    return _open(Path(path), with_labels=False)[0]


def load_set(path: Path) -> StyleSet:
    """Load a set file; refuses missing, foreign, old, truncated or inconsistent files (ExemplarError)."""
    path = Path(path)
    meta, arrays = _open(path, with_labels=True)
    vocab = Vocabulary.from_json(meta["vocabulary"])
    exemplars = []
    for i, record in enumerate(meta["exemplars"]):
        labels = arrays[i]
        if labels.dtype != np.uint8 or list(labels.shape) != record["shape"]:
            raise _refuse(path, f"exemplar {i} has a {labels.dtype} {labels.shape} array, expected {record['shape']}")
        if labels.size and int(labels.max()) > len(vocab.parts):
            raise _refuse(path, f"exemplar {i} has labels beyond its {len(vocab.parts)} parts")
        exemplars.append(Exemplar(labels=labels, offset=tuple(record["offset"]), meta=record))
    return StyleSet(name=meta["set"], vocabulary=vocab, resolution=int(meta["resolution"]),
                    inputs_hash=meta["inputs_hash"], exemplars=tuple(exemplars), path=path)


def _check_unpacked(path: Path) -> None:
    """Refuse a set whose arrays would unpack to more than the style-set size limit (a zip bomb)."""
    limit = input_limit_bytes(InputKind.STYLE_SET)
    try:
        with zipfile.ZipFile(path) as archive:
            unpacked = sum(info.file_size for info in archive.infolist())
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        raise _refuse(path, f"the file is truncated or corrupt ({type(exc).__name__})") from None
    if unpacked > limit:
        raise _refuse(path, f"it unpacks to {unpacked / (1 << 20):,.0f} MB, more than the {limit / (1 << 20):.4g} MB "
                            f"limit for style sets (raise it with {InputKind.STYLE_SET.env_var}=<MB>)")


def _open(path: Path, with_labels: bool) -> tuple[dict, list[np.ndarray]]:
    if not path.exists():
        raise ExemplarError(f"style set file not found: {path}", file=path,
                            hint="build it with 'decollage styles build <set>'")
    check_input_file(path, InputKind.STYLE_SET, error=ExemplarError, file=path)  # no device, within its limit
    _check_unpacked(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            if "meta" not in data.files:
                raise _refuse(path, "it has no metadata (not a decollage style set)")
            meta = json.loads(bytes(data["meta"]).decode())
            if not isinstance(meta, dict) or meta.get("format") != FORMAT:
                raise _refuse(path, "it is not a decollage style set")
            if meta.get("version") != FORMAT_VERSION:
                raise _refuse(path, f"format version {meta.get('version')} is not the supported {FORMAT_VERSION}")
            arrays = []
            if with_labels:
                for i in range(len(meta["exemplars"])):
                    if f"labels_{i}" not in data.files:
                        raise _refuse(path, f"exemplar {i}'s labels are missing")
                    arrays.append(data[f"labels_{i}"])
            return meta, arrays
    except ExemplarError:
        raise
    except (zipfile.BadZipFile, EOFError, ValueError, KeyError, OSError, UnicodeDecodeError, TypeError) as exc:
        raise _refuse(path, f"the file is truncated or corrupt ({type(exc).__name__})") from None


# --------------------------------------------------------------------------- building


def build_set(name: str, vocabulary: Vocabulary, specs: Sequence[ExemplarSpec], path: Path | None = None, *,
              resolution: int = RESOLUTION, force: bool = False, workers: int = 1,
              progress: Callable[[str], None] | None = None) -> BuildResult:
    """Build set ``name`` into ``path`` (default ``set_path(name)``); a no-op when already up to date.

    ``workers`` > 1 voxelizes exemplars in that many processes (the result is
    identical: exemplars are independent and kept in spec order).
    """

    started = time.perf_counter()
    path = Path(path) if path is not None else set_path(name)
    if not specs:
        raise ExemplarError(f"set '{name}' has no exemplars", field=name, hint="give it at least one exemplar")
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise ExemplarError(f"set '{name}' has duplicate exemplar names: {', '.join(dup)}", field=name,
                            hint="exemplar names must be unique")
    digest = inputs_hash(name, vocabulary, specs, resolution)
    if not force and path.is_file():
        try:
            if read_meta(path).get("inputs_hash") == digest:
                return BuildResult(path, False, time.perf_counter() - started, load_set(path))
        except ExemplarError:
            pass  # damaged or old: rebuild
    exemplars = _make_all(specs, vocabulary, resolution, workers, progress)
    ensure_writable_dir(path.parent)
    write_bytes_atomic(path, encode_set(name, vocabulary, resolution, digest, exemplars))
    return BuildResult(path, True, time.perf_counter() - started, load_set(path))


def _make_all(specs, vocabulary, resolution, workers, progress) -> list[Exemplar]:
    if workers <= 1 or len(specs) == 1:
        out = []
        for spec in specs:
            out.append(make_exemplar(spec, vocabulary, resolution))
            if progress:
                progress(spec.name)
        return out
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(make_exemplar, spec, vocabulary, resolution) for spec in specs]
        out = []
        for spec, future in zip(specs, futures):
            out.append(future.result())
            if progress:
                progress(spec.name)
        return out

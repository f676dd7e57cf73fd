"""The one flow that builds an asset: source → voxelize → regions → detailize → mesh → export.

``check_recipe`` does every check that needs no heavy work (input files exist,
are regular files within their size limits and of a readable format, fonts
cover the text, the detailizer, checkpoint, style and part names are known)
so that a bad recipe fails before anything is written; it never runs a
script. ``build_asset`` builds one asset; a failing asset is reported and
leaves no partial file. While it builds, its memory is estimated as soon as
its grid size is known (``core/budget.py``) and library warnings are caught
into its manifest warnings (``core/capture.py``). Its manifest entry records
the asset's input closure: every file its source and its detailizer read,
with their sha256 (``pipeline/cache.py``). Its kernels run with ``ASSET_THREADS``
threads (``pipeline/executors.py``) so the bytes do not depend on where it
runs. Planning, executors, records and the manifest of a whole recipe are in
``pipeline/batch.py``.
"""

from __future__ import annotations

import hashlib
import time
import traceback
from contextlib import contextmanager
from pathlib import Path

from core.budget import check_asset_memory, memory_budget_bytes
from core.capture import captured_warnings
from core.detailizer import effective_checkpoint, get_detailizer, kernel_threads
from core.errors import DecollageError, RecipeError, UsageError
from core.files import InputKind, check_input_file, sha256_file
from core.grid import UPSAMPLE_FACTOR
from core.processes import blas_threads
from core.recipe import FROM_SOURCE, SOURCE_FILE_FIELDS, Asset, VoxExport
from core.recipe_loader import LoadedRecipe
from geometry.voxelize import mesh_grid_shape, voxelize
from pipeline.cache import closure_records, portable_path
from pipeline.engines import make_collision, make_lods
from pipeline.executors import ASSET_THREADS
from pipeline.export import apply_pivot, export_asset
from pipeline.chunks import detail_shape, detailize_and_mesh
from pipeline.mesh import MeshSettings, mesh_stats
from pipeline.provenance import asset_provenance, glb_extras
from pipeline.regions import apply_regions
from pipeline.report import AssetReport, AssetStatus
from pipeline.vox_export import FineVox, vox_files
from sources import PartMeshes, load_source, preflight_source


class Progress:
    """Callbacks the CLI implements to show progress; the default does nothing."""

    def asset_started(self, index: int, total: int, name: str) -> None: ...

    def stage(self, name: str) -> None: ...

    def asset_finished(self, report: AssetReport) -> None: ...

    def waiting_for_lock(self, holder) -> None:
        """Another build holds the output folder (``pipeline/lock.py``'s ``Holder``, or None); this one waits."""

    def took_over_lock(self, holder) -> None:
        """The output folder's lock was left by a build that was killed (its ``Holder``); this one took it."""


def named_input_files(asset: Asset, loaded: LoadedRecipe) -> dict[str, Path]:
    """Recipe field name → resolved path, for the source's file fields that are set."""
    files = {}
    for name in SOURCE_FILE_FIELDS[asset.source.kind]:
        value = getattr(asset.source, name)
        if value is not None:
            files[name] = loaded.resolve(value)
    return files


def detailizer_of(asset: Asset, loaded: LoadedRecipe, override: str | None) -> tuple[str, str | None]:
    """(detailizer name, resolved path of the file it loads: its checkpoint or style set, or None = its default)."""
    name = override or asset.detailize.detailizer
    _, value = asset.detailize.data_file(name)
    return name, value and str(loaded.resolve(value))


def input_paths(loaded: LoadedRecipe, detailizer_override: str | None = None) -> set[Path]:
    """Every file the assets' keys hash before building: the files the recipe names, the weights."""
    paths = set()
    for asset in loaded.recipe.assets:
        paths.update(named_input_files(asset, loaded).values())
        weights = effective_checkpoint(*detailizer_of(asset, loaded, detailizer_override))
        if weights:
            paths.add(Path(weights))
    return paths


def check_recipe(loaded: LoadedRecipe, detailizer_override: str | None = None) -> None:
    """Static checks before building (no script runs). Raises RecipeError naming file and field."""

    checked: dict[tuple, DecollageError | None] = {}  # a batch repeats the same files and texts
    for i, asset in enumerate(loaded.recipe.assets):
        where, variant = loaded.where(i)
        suffix = f" (in variant {variant})" if variant else ""
        try:
            key = ("source", asset.source.model_dump_json())
            if key not in checked:
                checked[key] = None
                try:
                    preflight_source(asset.source, loaded.base_dir)
                except UsageError:
                    raise  # e.g. an unusable DECOLLAGE_MAX_*_MB: not the recipe's fault
                except DecollageError as exc:
                    checked[key] = exc
            if checked[key] is not None:
                raise checked[key]
        except UsageError:
            raise
        except DecollageError as exc:
            message = exc.message if exc.message.endswith(suffix) else exc.message + suffix
            raise RecipeError(message, file=loaded.path, field=f"{where}.source.{exc.field or ''}".rstrip("."),
                              hint=exc.hint) from None
        name, checkpoint = detailizer_of(asset, loaded, detailizer_override)
        field, value = asset.detailize.data_file(name)
        _check_data_file(value, loaded, f"{where}.detailize.{field}")
        try:
            det = get_detailizer(name, checkpoint, asset.detailize.device)
        except DecollageError as exc:
            message = f"{exc.file}: {exc.message}" if exc.file else exc.message
            about = field if (checkpoint and exc.file == checkpoint) or exc.field == field else "detailizer"
            raise RecipeError(message, file=loaded.path, field=f"{where}.detailize.{about}",
                              hint=exc.hint) from None
        for r, rule in enumerate(asset.regions):
            for attr, vocab in (("style", det.style_names), ("part", det.part_names)):
                value = getattr(rule, attr)
                if vocab is not None and value != FROM_SOURCE and value not in vocab:
                    raise RecipeError(
                        f"unknown {attr} {value!r}{suffix} (known: {', '.join(vocab)})",
                        file=loaded.path, field=f"{where}.regions[{r}].{attr}",
                        hint=(f"use one of the {attr}s the '{det.name}' detailizer was trained on" if det.learned
                              else f"use one of the {attr}s of the style set the '{det.name}' detailizer copies from"),
                    )


def _check_data_file(value: str | None, loaded: LoadedRecipe, field: str) -> None:
    """A ``checkpoint`` or ``style_set`` that names a file (it exists, or looks like a path) is checked for kind
    and size before any detailizer reads it: a ``.npz`` as a style set, anything else as a checkpoint. A bare
    name (``quilt``'s built-in set ``things``) is left to the detailizer to resolve."""
    if value is None:
        return
    path = loaded.resolve(value)
    looks_like_a_path = "/" in value or "\\" in value or Path(value).suffix != ""
    if path.exists() or path.is_symlink() or looks_like_a_path:
        kind = InputKind.STYLE_SET if path.suffix.lower() == ".npz" else InputKind.CHECKPOINT
        check_input_file(path, kind, error=RecipeError, file=loaded.path, field=field)


def _locate(exc: DecollageError, loaded: LoadedRecipe, index: int, sub: str = "") -> DecollageError:
    """Put an error raised deep inside a stage at its place in the recipe file."""
    where, variant = loaded.where(index)
    if exc.file and Path(exc.file) != loaded.path:
        exc.message = f"{exc.file}: {exc.message}"
    if variant and "(in variant" not in exc.message:
        exc.message += f" (in variant {variant})"
    exc.file = str(loaded.path)
    prefix = where + (f".{sub}" if sub else "")
    if exc.field and exc.field.startswith("assets["):
        exc.field = where + exc.field[exc.field.index("]") + 1:]
    else:
        exc.field = f"{prefix}.{exc.field}" if exc.field else prefix
    return exc


@contextmanager
def _timed(report: AssetReport, stage: str, progress: Progress):
    progress.stage(stage)
    start = time.perf_counter()
    try:
        yield
    finally:
        report.timings_s[stage] = round(time.perf_counter() - start, 3)


def build_asset(loaded: LoadedRecipe, index: int, out_dir: Path, progress: Progress,
                detailizer_override: str | None = None, block_processes: int = 1) -> AssetReport:
    """Build one asset; never raises for asset-level problems (they go into the report).

    ``block_processes`` 2 lets an asset of several blocks use a second process for half of them
    (``pipeline/chunks.py``) when twice its memory estimate fits the budget; outputs are the same.
    """
    asset = loaded.recipe.assets[index]
    report = AssetReport(name=asset.name, index=index)
    where, _ = loaded.where(index)
    try:
        with captured_warnings(report.warnings):
            _build(asset, loaded, index, out_dir, progress, report, detailizer_override, block_processes)
        report.status = AssetStatus.BUILT
    except DecollageError as exc:
        report.status = AssetStatus.FAILED
        report.error = _locate(exc, loaded, index).one_line()
    except MemoryError:
        report.status = AssetStatus.FAILED
        report.error = f"{loaded.path}: {where}: ran out of memory (lower grid.resolution or max_cells)"
    except Exception as exc:  # an internal bug must not take the other assets down
        report.status = AssetStatus.FAILED
        report.error = (f"{loaded.path}: {where}: internal error {type(exc).__name__}: {exc} "
                        "(please report it; run with --debug for the traceback)")
        report.traceback = traceback.format_exc()
    return report


def _build(asset: Asset, loaded: LoadedRecipe, index: int, out_dir: Path, progress: Progress,
           report: AssetReport, detailizer_override: str | None, block_processes: int = 1) -> None:

    report.inputs = {
        "entry_sha256": hashlib.sha256(asset.model_dump_json(by_alias=True).encode()).hexdigest(),
        "files": [],  # the input closure, once the readers have run
    }
    where, _ = loaded.where(index)

    with _timed(report, "source", progress):
        try:
            source = load_source(asset.source, loaded.base_dir)
        except DecollageError as exc:
            raise _locate(exc, loaded, index, "source")
    report.warnings += source.warnings

    grid_args = {"resolution": asset.grid.resolution, "fit": asset.fit.value}
    with _timed(report, "voxelize", progress):
        if isinstance(source, PartMeshes):  # refuse a grid too large to voxelize before voxelizing it
            shape, supersample = mesh_grid_shape(source, asset.grid, asset.fit)
            check_asset_memory(shape, supersample=supersample, **grid_args)
        part_grid = voxelize(source, asset.grid, asset.fit)
        # the fine grid's cost, before detailizing: of the largest block a long grid is cut into (pipeline/chunks.py)
        needed = check_asset_memory(detail_shape(part_grid.shape), **grid_args)
    if 2 * needed > memory_budget_bytes():
        block_processes = 1  # a second process holds blocks of its own
    report.warnings += list(part_grid.warnings)

    with _timed(report, "regions", progress):
        grid, warnings = apply_regions(part_grid, asset.regions, field=f"{where}.regions")
    report.warnings += warnings

    name, checkpoint = detailizer_of(asset, loaded, detailizer_override)
    detailizer = get_detailizer(name, checkpoint, asset.detailize.device)
    report.inputs["files"] = closure_records(
        [*((p, "source") for p in source.input_files),
         *((p, "detailizer") for p in getattr(detailizer, "input_files", ()))], loaded.base_dir)
    export = asset.export
    progress.stage("detailize")
    fine_vox = (FineVox(tuple(n * UPSAMPLE_FACTOR for n in grid.shape), grid.style_names)
                if VoxExport.FINE in export.vox else None)  # filled block by block, as the blocks are detailized
    with kernel_threads(ASSET_THREADS), blas_threads(ASSET_THREADS):  # block by block (pipeline/chunks.py)
        seed = asset.detailize.seed
        by_columns = getattr(detailizer, "column_detailizer", None)  # optional (core/detailizer.py)
        prepare = getattr(detailizer, "prepare", None)  # optional: loads before the block process forks
        if prepare is not None:
            started = time.perf_counter()
            prepare(grid)
            report.timings_s["detailize"] = report.timings_s.get("detailize", 0.0) + time.perf_counter() - started
        detailed = detailize_and_mesh(grid, lambda g: detailizer.detailize(g, seed=seed),
                                      MeshSettings.from_export(export, grid.occupancy), report.timings_s,
                                      on_block=fine_vox.add if fine_vox is not None else None,
                                      processes=block_processes,
                                      columns=(lambda g: by_columns(g, seed=seed)) if by_columns else None)
    for stage in ("detailize", "mesh"):
        report.timings_s[stage] = round(report.timings_s.get(stage, 0.0), 3)
    mesh = detailed.mesh
    provenance = asset_provenance(name, effective_checkpoint(name, checkpoint), detailed.extras)
    with _timed(report, "engine", progress):
        lods = make_lods(mesh, export.lods)
        collision = make_collision(export.collision, mesh, grid)

    with _timed(report, "export", progress):
        vox_jobs, vox_record = vox_files(export.vox, grid, fine_vox, asset.name)
        written, pivot_offset = export_asset(mesh, out_dir, asset.name, export.formats, export.pivot,
                                             preview_size_px=export.preview_size_px if export.preview else None,
                                             glb_material=export.glb_material, profile=export.profile,
                                             lods=lods, collision=collision, asset_extras=glb_extras(provenance),
                                             extra_files=vox_jobs, compression=export.compression)

    report.outputs = {
        kind: {"path": path.name, "sha256": sha256_file(path), "bytes": path.stat().st_size}
        for kind, path in written.items()
    }
    report.info = {
        "source_kind": asset.source.kind,
        **({"variant": asset.variant} if asset.variant else {}),
        "detailizer": portable_description(detailizer.describe(), loaded.base_dir),
        "provenance": provenance,
        **({"vox": vox_record} if vox_record else {}),
        "coarse_grid": {
            "shape": list(grid.shape),
            "voxel_size_m": grid.voxel_size_m,
            "occupied": grid.count,
            "parts": list(grid.part_names),
            "styles": list(grid.style_names),
        },
        "fine_grid_shape": list(detailed.fine_shape),
        **({"chunks": detailed.chunks} if detailed.chunks > 1 else {}),
        "structure": detailed.structure,
        "pivot_offset_m": [round(float(v), 9) for v in pivot_offset],
        "mesh": mesh_stats(apply_pivot(mesh, export.pivot)[0]),  # stats of the geometry as exported
        "engine": {"profile": export.profile.value, "lod_triangles": [len(m.faces) for m in (mesh, *lods)],
                   "collision": export.collision.value, "collision_pieces": len(collision)},
    }


#: Keys of a detailizer's ``describe()`` that hold a file path (the manifest writes them portably).
DESCRIBED_PATH_KEYS = ("checkpoint", "style_set_path")


def portable_description(description: dict, base_dir: Path) -> dict:
    """A detailizer's ``describe()`` with its file paths written like the input closure's (``portable_path``).

    A checkpoint or style set inside the recipe's folder becomes relative to it, one shipped with this
    project ``<decollage>/...``: two checkouts of the same commit write the same manifest. The file's
    bytes are identified by its sha256 in ``inputs.files``.
    """
    out = dict(description)
    for key in DESCRIBED_PATH_KEYS:
        if isinstance(out.get(key), str):
            out[key] = portable_path(Path(out[key]), base_dir)
    return out

"""Run the one flow for every asset of a recipe: source → voxelize → regions → detailize → mesh → export.

``check_recipe`` does every check that needs no heavy work (input files exist,
are regular files within their size limits and of a readable format, fonts
cover the text, the detailizer, checkpoint, style and part names are known)
so that a bad recipe fails before anything is written; it never runs a
script. ``build_recipe`` first checks the output folder (``check_output``:
the folder, its ``.decollage`` records folder, ``manifest.json``, ``NOTICE.txt``
and ``build.json`` are of the right kind and writable) and writes nothing when they are not. While an
asset builds, its memory is estimated as soon as its grid size is known
(``core/budget.py``) and library warnings are caught into its manifest
warnings (``core/capture.py``). ``plan_build`` computes each asset's content key and finds
the assets whose recorded outputs are still valid (``pipeline/cache.py``).
``build_recipe`` builds the rest through an executor (in process, worker
processes, or a cluster: ``pipeline/executors.py``); a failing asset is
reported and leaves no partial file, the others are still built, and
``manifest.json`` describes the whole build.
"""

from __future__ import annotations

import hashlib
import time
import traceback
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from core.budget import check_asset_memory, memory_budget_bytes
from core.capture import captured_warnings
from core.detailizer import effective_checkpoint, get_detailizer
from core.errors import DecollageError, RecipeError, UsageError
from core.files import InputKind, check_input_file, check_output_folder, ensure_writable_dir, sha256_file
from core.recipe import FROM_SOURCE, SOURCE_FILE_FIELDS, Asset
from core.recipe_loader import LoadedRecipe, parse_recipe
from core.structure import strict_loose_iou
from geometry.voxelize import mesh_grid_shape, voxelize
from pipeline.cache import RECORD_DIR, asset_key, remove_stale_temporaries, valid_record, write_record
from pipeline.engines import make_collision, make_lods
from pipeline.executors import LocalExecutor
from pipeline.export import apply_pivot, export_asset
from pipeline.manifest import BUILD_SIGNAL, MANIFEST_NAME, write_build_signal, write_manifest
from pipeline.mesh import MeshSettings, mesh_fine_grid, mesh_stats
from pipeline.provenance import NOTICE_NAME, asset_provenance, glb_extras, write_notice
from pipeline.regions import apply_regions
from pipeline.report import AssetReport, AssetStatus
from pipeline.vox_export import vox_files
from sources import PartMeshes, load_source, preflight_source


class Progress:
    """Callbacks the CLI implements to show progress; the default does nothing."""

    def asset_started(self, index: int, total: int, name: str) -> None: ...

    def stage(self, name: str) -> None: ...

    def asset_finished(self, report: AssetReport) -> None: ...


@dataclass(frozen=True)
class PlannedAsset:
    """One asset of a build: its content key, and its recorded entry when that is still valid."""

    index: int
    name: str
    key: str
    cached_entry: dict | None


def _input_files(asset: Asset, loaded: LoadedRecipe) -> dict[str, Path]:
    """Recipe field name → resolved path, for the source's file fields that are set."""
    files = {}
    for name in SOURCE_FILE_FIELDS[asset.source.kind]:
        value = getattr(asset.source, name)
        if value is not None:
            files[name] = loaded.resolve(value)
    return files


def _detailizer_of(asset: Asset, loaded: LoadedRecipe, override: str | None) -> tuple[str, str | None]:
    settings = asset.detailize
    return override or settings.detailizer, settings.checkpoint and str(loaded.resolve(settings.checkpoint))


def input_paths(loaded: LoadedRecipe, detailizer_override: str | None = None) -> set[Path]:
    """Every file the assets' keys hash before building: the files the recipe names, the weights."""
    paths = set()
    for asset in loaded.recipe.assets:
        paths.update(_input_files(asset, loaded).values())
        weights = effective_checkpoint(*_detailizer_of(asset, loaded, detailizer_override))
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
        _check_checkpoint_file(asset.detailize.checkpoint, loaded, f"{where}.detailize.checkpoint")
        name, checkpoint = _detailizer_of(asset, loaded, detailizer_override)
        try:
            det = get_detailizer(name, checkpoint, asset.detailize.device)
        except DecollageError as exc:
            message = f"{exc.file}: {exc.message}" if exc.file else exc.message
            about = "checkpoint" if checkpoint and exc.file == checkpoint else "detailizer"
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


def _check_checkpoint_file(value: str | None, loaded: LoadedRecipe, field: str) -> None:
    """A ``checkpoint`` that names a file (it exists, or looks like a path) is checked for kind and size before
    any detailizer reads it: a ``.npz`` (a style set for ``quilt``) as a style set, anything else as a
    checkpoint. A bare name (``quilt``'s built-in set ``things``) is left to the detailizer to resolve."""
    if value is None:
        return
    path = loaded.resolve(value)
    looks_like_a_path = "/" in value or "\\" in value or Path(value).suffix != ""
    if path.exists() or path.is_symlink() or looks_like_a_path:
        kind = InputKind.STYLE_SET if path.suffix.lower() == ".npz" else InputKind.CHECKPOINT
        check_input_file(path, kind, error=RecipeError, file=loaded.path, field=field)


def check_output(out_dir: Path) -> None:
    """Before any work: ``out_dir``, its records folder and the build-level files (``manifest.json``,
    ``NOTICE.txt``, ``build.json``) can be written (ExportError if not).

    Writes nothing (``core.files.check_output_folder``).
    """
    check_output_folder(out_dir, folders=(RECORD_DIR,), files=(MANIFEST_NAME, NOTICE_NAME, str(BUILD_SIGNAL)))
    memory_budget_bytes()  # an unusable DECOLLAGE_MEMORY_BUDGET_GB is a usage error now, not an asset error later


def plan_build(loaded: LoadedRecipe, out_dir: Path, detailizer_override: str | None = None,
               only: Callable[[Asset], bool] | None = None, force: bool = False) -> list[PlannedAsset]:
    """Content keys of the selected assets, and which of them are up to date in ``out_dir``."""

    planned, weight_hashes = [], {}
    for i, asset in enumerate(loaded.recipe.assets):
        if only is not None and not only(asset):
            continue
        inputs = {n: sha256_file(p) for n, p in _input_files(asset, loaded).items()}
        name, checkpoint = _detailizer_of(asset, loaded, detailizer_override)
        weights = effective_checkpoint(name, checkpoint)
        if weights not in weight_hashes:  # hashed once a build, not once an asset (a batch shares one model)
            weight_hashes[weights] = sha256_file(Path(weights)) if weights and Path(weights).is_file() else None
        key = asset_key(asset.model_dump(mode="json", by_alias=True), inputs, weight_hashes[weights], name)
        cached = None if force else valid_record(out_dir, asset.name, key)
        planned.append(PlannedAsset(i, asset.name, key, cached))
    return planned


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
                detailizer_override: str | None = None) -> AssetReport:
    """Build one asset; never raises for asset-level problems (they go into the report)."""
    asset = loaded.recipe.assets[index]
    report = AssetReport(name=asset.name, index=index)
    where, _ = loaded.where(index)
    try:
        with captured_warnings(report.warnings):
            _build(asset, loaded, index, out_dir, progress, report, detailizer_override)
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
           report: AssetReport, detailizer_override: str | None) -> None:

    report.inputs = {
        "entry_sha256": hashlib.sha256(asset.model_dump_json(by_alias=True).encode()).hexdigest(),
        "files": {name: {"path": str(path), "sha256": sha256_file(path)}
                  for name, path in _input_files(asset, loaded).items()},
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
        check_asset_memory(part_grid.shape, **grid_args)  # the fine grid's cost, before detailizing
    report.warnings += list(part_grid.warnings)

    with _timed(report, "regions", progress):
        grid, warnings = apply_regions(part_grid, asset.regions, field=f"{where}.regions")
    report.warnings += warnings

    name, checkpoint = _detailizer_of(asset, loaded, detailizer_override)
    detailizer = get_detailizer(name, checkpoint, asset.detailize.device)
    with _timed(report, "detailize", progress):
        fine = detailizer.detailize(grid, seed=asset.detailize.seed)

    export = asset.export
    provenance = asset_provenance(name, effective_checkpoint(name, checkpoint), fine)
    with _timed(report, "mesh", progress):
        mesh = mesh_fine_grid(fine, MeshSettings.from_export(export))
        lods = make_lods(mesh, fine, export.lods)
        collision = make_collision(export.collision, mesh, grid)

    with _timed(report, "export", progress):
        vox_jobs, vox_record = vox_files(export.vox, grid, fine, asset.name)
        written, pivot_offset = export_asset(mesh, out_dir, asset.name, export.formats, export.pivot,
                                             preview_size_px=export.preview_size_px if export.preview else None,
                                             glb_material=export.glb_material, profile=export.profile,
                                             lods=lods, collision=collision, asset_extras=glb_extras(provenance),
                                             extra_files=vox_jobs)

    report.outputs = {
        kind: {"path": path.name, "sha256": sha256_file(path), "bytes": path.stat().st_size}
        for kind, path in written.items()
    }
    report.info = {
        "source_kind": asset.source.kind,
        **({"variant": asset.variant} if asset.variant else {}),
        "detailizer": detailizer.describe(),
        "provenance": provenance,
        **({"vox": vox_record} if vox_record else {}),
        "coarse_grid": {
            "shape": list(grid.shape),
            "voxel_size_m": grid.voxel_size_m,
            "occupied": grid.count,
            "parts": list(grid.part_names),
            "styles": list(grid.style_names),
        },
        "fine_grid_shape": list(fine.shape),
        "structure": _structure(fine, grid),
        "pivot_offset_m": [round(float(v), 9) for v in pivot_offset],
        "mesh": mesh_stats(apply_pivot(mesh, export.pivot)[0]),  # stats of the geometry as exported
        "engine": {"profile": export.profile.value, "lod_triangles": [len(m.faces) for m in (mesh, *lods)],
                   "collision": export.collision.value, "collision_pieces": len(collision)},
    }


def _structure(fine, grid) -> dict:
    """How well the detailed shape keeps the coarse one: the paper's Strict- and Loose-IOU.

    The fine occupancy binarised at 0.4 and max-pooled ×16 against the coarse
    occupancy (``core/structure.py``): strict = |D∧C|/|D∨C|,
    loose = |D∧C|/|C|; 1 is perfect.
    """
    factor = fine.shape[0] // grid.shape[0]
    strict, loose = strict_loose_iou(fine.occupancy, grid.occupancy, factor)
    return {"strict_iou": round(strict, 4), "loose_iou": round(loose, 4)}


# --------------------------------------------------------------------------- tasks run by executors

_LOADED: dict[tuple[str, str], LoadedRecipe] = {}


def build_task(recipe_text: str, recipe_path: str, index: int, key: str, out_dir: str,
               detailizer_override: str | None = None, progress: Progress | None = None) -> AssetReport:
    """Build one planned asset and record it; a function of plain data, so any executor can run it.

    The parsed recipe is kept per process, so a worker parses each recipe once.
    """
    cache_key = (recipe_path, hashlib.sha256(recipe_text.encode()).hexdigest())
    if cache_key not in _LOADED:
        path = Path(recipe_path)
        # The main process checked the expansion against its cap (--max-assets) already.
        _LOADED[cache_key] = LoadedRecipe(parse_recipe(recipe_text, path, max_assets=None), path, recipe_text)
    out = Path(out_dir)
    report = build_asset(_LOADED[cache_key], index, out, progress or Progress(), detailizer_override)
    if report.status == AssetStatus.BUILT:
        write_record(out, report.name, key, report.entry())
    return report


def build_recipe(loaded: LoadedRecipe, out_dir: Path, progress: Progress | None = None,
                 detailizer_override: str | None = None,
                 only: Callable[[Asset], bool] | None = None, force: bool = False,
                 executor=None) -> list[AssetReport]:
    """Check, plan, build what is not up to date, and write ``out_dir/manifest.json`` atomically.

    Returns one report per selected asset in recipe order (``cached`` marks those
    taken from a valid record). ``executor`` defaults to building in this process.
    On KeyboardInterrupt the manifest of what finished is written before re-raising.
    """

    progress = progress or Progress()
    executor = executor or LocalExecutor(progress)
    check_output(out_dir)
    check_recipe(loaded, detailizer_override)
    plan = plan_build(loaded, out_dir, detailizer_override, only, force)
    if any(p.cached_entry is None for p in plan):
        executor.start()  # e.g. connect to a cluster: failing here must leave out_dir untouched
    ensure_writable_dir(out_dir)
    remove_stale_temporaries(out_dir)
    reports: dict[int, AssetReport] = {}
    for p in plan:
        if p.cached_entry is not None:
            reports[p.index] = AssetReport.from_entry(p.index, p.cached_entry)
            progress.asset_finished(reports[p.index])
    todo = [p for p in plan if p.cached_entry is None]
    tasks = [(loaded.text, str(loaded.path), p.index, p.key, str(out_dir), detailizer_override) for p in todo]

    def done(report: AssetReport) -> None:
        reports[report.index] = report
        progress.asset_finished(report)

    try:
        executor.run(build_task, tasks, done, names=[p.name for p in todo])
    finally:
        ordered = [reports[p.index] for p in plan if p.index in reports]
        write_manifest(out_dir, loaded, ordered)
        write_notice(out_dir, [r.entry() for r in ordered])
        write_build_signal(out_dir, ordered)
    return ordered

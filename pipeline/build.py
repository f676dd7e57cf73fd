"""Run the one flow for every asset of a recipe: source → voxelize → regions → detailize → mesh → export.

``check_recipe`` does every check that needs no heavy work (input files exist,
detailizer and style names are known) so that a bad recipe fails before
anything is written. ``build_recipe`` then builds asset by asset; a failing
asset is reported and leaves no partial file, the others are still built, and
``manifest.json`` describes the whole build.
"""

from __future__ import annotations

import hashlib
import time
import traceback
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from pipeline.errors import DecollageError, RecipeError
from pipeline.recipe import FROM_SOURCE, SOURCE_FILE_FIELDS, Asset, LoadedRecipe


@dataclass
class AssetReport:
    """What happened to one asset; becomes its manifest entry."""

    name: str
    index: int
    status: str = "pending"  # built | failed
    error: str | None = None
    warnings: list[str] = field(default_factory=list)
    timings_s: dict[str, float] = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    outputs: dict[str, dict] = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    traceback: str | None = None


class Progress:
    """Callbacks the CLI implements to show progress; the default does nothing."""

    def asset_started(self, index: int, total: int, name: str) -> None: ...

    def stage(self, name: str) -> None: ...

    def asset_finished(self, report: AssetReport) -> None: ...


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _asset_field(index: int) -> str:
    return f"assets[{index}]"


def _input_files(asset: Asset, loaded: LoadedRecipe) -> dict[str, Path]:
    """Recipe field name → resolved path, for the source's file fields that are set."""
    files = {}
    for name in SOURCE_FILE_FIELDS[asset.source.kind]:
        value = getattr(asset.source, name)
        if value is not None:
            files[name] = loaded.resolve(value)
    return files


def check_recipe(loaded: LoadedRecipe, detailizer_override: str | None = None) -> None:
    """Static checks before building. Raises RecipeError naming file and field."""
    from pipeline.detailize import get_detailizer

    for i, asset in enumerate(loaded.recipe.assets):
        where = _asset_field(i)
        for name, path in _input_files(asset, loaded).items():
            if not path.exists():
                raise RecipeError(f"file not found: {path}", file=loaded.path, field=f"{where}.source.{name}",
                                  hint="relative paths are resolved against the recipe's folder")
            if not path.is_file():
                raise RecipeError(f"not a file: {path}", file=loaded.path, field=f"{where}.source.{name}")
        settings = asset.detailize
        name = detailizer_override or settings.detailizer
        try:
            det = get_detailizer(name, settings.checkpoint and str(loaded.resolve(settings.checkpoint)),
                                 settings.device)
        except DecollageError as exc:
            raise RecipeError(exc.message, file=loaded.path, field=f"{where}.detailize.detailizer",
                              hint=exc.hint) from None
        for r, rule in enumerate(asset.regions):
            for attr, vocab in (("style", det.style_names), ("part", det.part_names)):
                value = getattr(rule, attr)
                if vocab is not None and value != FROM_SOURCE and value not in vocab:
                    raise RecipeError(
                        f"unknown {attr} {value!r} (known: {', '.join(vocab)})",
                        file=loaded.path, field=f"{where}.regions[{r}].{attr}",
                        hint=f"use one of the {attr}s the '{det.name}' detailizer was trained on",
                    )


def _locate(exc: DecollageError, loaded: LoadedRecipe, where: str) -> DecollageError:
    """Put an error raised deep inside a stage at its place in the recipe."""
    if exc.file and Path(exc.file) != loaded.path:
        exc.message = f"{exc.file}: {exc.message}"
    exc.file = str(loaded.path)
    exc.field = f"{where}.{exc.field}" if exc.field and not exc.field.startswith("assets[") else (exc.field or where)
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
    where = _asset_field(index)
    try:
        _build(asset, loaded, out_dir, progress, report, where, detailizer_override)
        report.status = "built"
    except DecollageError as exc:
        report.status = "failed"
        report.error = _locate(exc, loaded, where).one_line()
    except MemoryError:
        report.status = "failed"
        report.error = f"{loaded.path}: {where}: ran out of memory (lower grid.resolution or max_cells)"
    except Exception as exc:  # an internal bug must not take the other assets down
        report.status = "failed"
        report.error = (f"{loaded.path}: {where}: internal error {type(exc).__name__}: {exc} "
                        "(please report it; run with --debug for the traceback)")
        report.traceback = traceback.format_exc()
    return report


def _build(asset: Asset, loaded: LoadedRecipe, out_dir: Path, progress: Progress, report: AssetReport,
           where: str, detailizer_override: str | None) -> None:
    from pipeline.detailize import get_detailizer
    from pipeline.export import apply_pivot, export_asset
    from pipeline.mesh import MeshSettings, mesh_fine_grid, mesh_stats
    from pipeline.regions import apply_regions
    from pipeline.voxelize import voxelize
    from sources import load_source

    report.inputs = {
        "entry_sha256": hashlib.sha256(asset.model_dump_json(by_alias=True).encode()).hexdigest(),
        "files": {},
    }
    for name, path in _input_files(asset, loaded).items():
        report.inputs["files"][name] = {"path": str(path), "sha256": sha256_file(path)}

    with _timed(report, "source", progress):
        try:
            source = load_source(asset.source, loaded.base_dir)
        except DecollageError as exc:
            raise _locate(exc, loaded, f"{where}.source")
    report.warnings += source.warnings

    with _timed(report, "voxelize", progress):
        try:
            part_grid = voxelize(source, asset.grid, asset.fit)
        except DecollageError as exc:
            raise _locate(exc, loaded, where)
    report.warnings += list(part_grid.warnings)

    with _timed(report, "regions", progress):
        try:
            grid, warnings = apply_regions(part_grid, asset.regions, field=f"{where}.regions")
        except DecollageError as exc:
            raise _locate(exc, loaded, where)
    report.warnings += warnings

    settings = asset.detailize
    checkpoint = settings.checkpoint and str(loaded.resolve(settings.checkpoint))
    detailizer = get_detailizer(detailizer_override or settings.detailizer, checkpoint, settings.device)
    with _timed(report, "detailize", progress):
        fine = detailizer.detailize(grid, seed=settings.seed)

    export = asset.export
    with _timed(report, "mesh", progress):
        mesh = mesh_fine_grid(fine, MeshSettings(taubin_iterations=export.taubin_iterations,
                                                 max_triangles=export.max_triangles,
                                                 vertex_colors=export.vertex_colors))

    with _timed(report, "export", progress):
        written, pivot_offset = export_asset(mesh, out_dir, asset.name, export.formats, export.pivot,
                                             preview_size_px=export.preview_size_px if export.preview else None,
                                             glb_material=export.glb_material)

    report.outputs = {
        kind: {"path": path.name, "sha256": sha256_file(path), "bytes": path.stat().st_size}
        for kind, path in written.items()
    }
    report.info = {
        "source_kind": asset.source.kind,
        "detailizer": detailizer.describe(),
        "coarse_grid": {
            "shape": list(grid.shape),
            "voxel_size_m": grid.voxel_size_m,
            "occupied": grid.count,
            "parts": list(grid.part_names),
            "styles": list(grid.style_names),
        },
        "fine_grid_shape": list(fine.shape),
        "pivot_offset_m": [round(float(v), 9) for v in pivot_offset],
        "mesh": mesh_stats(apply_pivot(mesh, export.pivot)[0]),  # stats of the geometry as exported
    }


def build_recipe(loaded: LoadedRecipe, out_dir: Path, progress: Progress | None = None,
                 detailizer_override: str | None = None,
                 only: Callable[[Asset], bool] | None = None) -> list[AssetReport]:
    """Check, then build every selected asset; writes ``out_dir/manifest.json`` atomically."""
    from pipeline.export import ensure_writable_dir
    from pipeline.manifest import write_manifest

    progress = progress or Progress()
    check_recipe(loaded, detailizer_override)
    ensure_writable_dir(out_dir)
    selected = [i for i, a in enumerate(loaded.recipe.assets) if only is None or only(a)]
    reports = []
    for n, i in enumerate(selected):
        progress.asset_started(n, len(selected), loaded.recipe.assets[i].name)
        report = build_asset(loaded, i, out_dir, progress, detailizer_override)
        progress.asset_finished(report)
        reports.append(report)
    write_manifest(out_dir, loaded, reports)
    return reports

"""A recipe's assets as one build: plan what is stale, run the rest on an executor, record them, write the manifest.

``plan_build`` computes each asset's content key and finds the assets whose
record is still valid: same key, same bytes in every file of the input closure
they read, outputs in place (``pipeline/cache.py``); each stale asset says why.
``build_recipe`` first checks the output folder (``check_output``: the folder,
its ``.decollage`` records folder, ``manifest.json``, ``NOTICE.txt`` and
``build.json`` are of the right kind and writable) and the recipe
(``pipeline/build.py``'s ``check_recipe``: every source's pre-flight, no script
runs), and writes nothing when they are wrong. It then takes the output
folder's lock (``pipeline/lock.py``: a second build waits or stops; a lock
left by a killed build is taken over), builds the stale assets through an executor (in process, worker processes or a
cluster: ``pipeline/executors.py``) as ``build_task`` calls, and writes
``manifest.json``, whose entries are the built assets' records and the cached
ones' recorded entries.

Interruption (Ctrl-C, SIGTERM, ``--fail-fast``): the executor stops all its
work first (workers are killed, nothing is queued); then an asset whose
record was written is listed even when its report never arrived, files that
unfinished assets had already moved into place are removed, and only then is
the manifest written, so it lists exactly the assets whose files are in the
folder. A KeyboardInterrupt comes out as ``BuildInterrupted``, which says what
was built, what was stopped in progress and what never started.
"""

from __future__ import annotations

import hashlib
import signal
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from core.budget import memory_budget_bytes
from core.detailizer import effective_checkpoint
from core.errors import AbandonedError
from core.files import check_output_folder, ensure_writable_dir
from core.recipe import Asset
from core.recipe_loader import LoadedRecipe, parse_recipe
from pipeline.build import Progress, build_asset, check_recipe, detailizer_of, named_input_files
from pipeline.cache import (RECORD_DIR, Digests, asset_key, check_record, remove_stale_temporaries,
                            remove_unfinished_outputs, write_record)
from pipeline.executors import LocalExecutor
from pipeline.lock import BuildLock, lease_holds
from pipeline.manifest import BUILD_SIGNAL, MANIFEST_NAME, write_build_signal, write_manifest
from pipeline.provenance import NOTICE_NAME, write_notice
from pipeline.report import AssetReport, AssetStatus


@dataclass(frozen=True)
class PlannedAsset:
    """One asset of a build: its content key, its recorded entry when still valid, else why it is stale."""

    index: int
    name: str
    key: str
    cached_entry: dict | None
    reason: str = ""


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

    planned, digests = [], Digests()  # a file shared by many assets (a font, the weights) is hashed once
    for i, asset in enumerate(loaded.recipe.assets):
        if only is not None and not only(asset):
            continue
        inputs = {n: digests(p) for n, p in named_input_files(asset, loaded).items()}
        name, checkpoint = detailizer_of(asset, loaded, detailizer_override)
        weights = effective_checkpoint(name, checkpoint)
        key = asset_key(asset.model_dump(mode="json", by_alias=True), inputs,
                        digests(Path(weights)) if weights else None, name)
        cached, reason = (None, "--force") if force else check_record(out_dir, asset.name, key, loaded.base_dir,
                                                                      digests)
        planned.append(PlannedAsset(i, asset.name, key, cached, reason))
    return planned


# --------------------------------------------------------------------------- the task executors run

_LOADED: dict[tuple[str, str], LoadedRecipe] = {}


class _Leased(Progress):
    """Passes progress on, and stops the asset at its next stage once its build no longer holds the folder."""

    def __init__(self, inner: Progress, out_dir: Path, lease: str) -> None:
        self.inner, self.out_dir, self.lease = inner, out_dir, lease

    def check(self) -> None:
        if not lease_holds(self.out_dir, self.lease):
            raise AbandonedError("the build that asked for this asset stopped (killed or interrupted); "
                                 "its files are not written", hint="build again")

    def asset_started(self, index: int, total: int, name: str) -> None:
        self.inner.asset_started(index, total, name)

    def stage(self, name: str) -> None:
        self.check()
        self.inner.stage(name)


def build_task(recipe_text: str, recipe_path: str, index: int, key: str, out_dir: str,
               detailizer_override: str | None = None, lease: str = "", block_processes: int = 1,
               progress: Progress | None = None) -> AssetReport:
    """Build one planned asset and record it; a function of plain data, so any executor can run it.

    ``lease`` is the build id of the build that holds ``out_dir`` (``pipeline/lock.py``): the task
    checks it before every stage and before its record, and writes nothing once it is gone.
    The parsed recipe is kept per process, so a worker parses each recipe once.
    """
    cache_key = (recipe_path, hashlib.sha256(recipe_text.encode()).hexdigest())
    if cache_key not in _LOADED:
        path = Path(recipe_path)
        # The main process checked the expansion against its cap (--max-assets) already.
        _LOADED[cache_key] = LoadedRecipe(parse_recipe(recipe_text, path, max_assets=None), path, recipe_text)
    out = Path(out_dir)
    leased = _Leased(progress or Progress(), out, lease)
    report = build_asset(_LOADED[cache_key], index, out, leased, detailizer_override, block_processes)
    if report.status == AssetStatus.BUILT:
        try:
            leased.check()
        except AbandonedError as exc:
            report.status, report.error = AssetStatus.FAILED, exc.one_line()
            return report
        write_record(out, report.name, key, report.entry())
    return report


# --------------------------------------------------------------------------- a whole build


@dataclass
class Stopped:
    """What an interrupted build left: the reports of the assets in the manifest, and the others by name."""

    reports: list[AssetReport]
    in_progress: list[str] = field(default_factory=list)
    not_started: list[str] = field(default_factory=list)
    removed_files: list[str] = field(default_factory=list)


class BuildInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM) stopped a build; ``stopped`` says what the manifest lists and what was left."""

    def __init__(self, stopped: Stopped) -> None:
        super().__init__("build interrupted")
        self.stopped = stopped


def build_recipe(loaded: LoadedRecipe, out_dir: Path, progress: Progress | None = None,
                 detailizer_override: str | None = None,
                 only: Callable[[Asset], bool] | None = None, force: bool = False,
                 executor=None, wait: bool = True) -> list[AssetReport]:
    """Check, lock, plan, build what is not up to date, and write ``out_dir/manifest.json`` atomically.

    Returns one report per selected asset in recipe order (``cached`` marks those
    taken from a valid record). ``executor`` defaults to building in this process.
    ``wait``: wait for another build that holds ``out_dir`` (else ``LockedError``).

    Raises:
        BuildInterrupted: on KeyboardInterrupt, after the manifest of what is on disk was written.
        LockedError: ``out_dir`` is in use and ``wait`` is False.
    """

    progress = progress or Progress()
    executor = executor or LocalExecutor(progress)
    check_output(out_dir)
    check_recipe(loaded, detailizer_override)
    plan = plan_build(loaded, out_dir, detailizer_override, only, force)
    if any(p.cached_entry is None for p in plan):
        executor.start()  # e.g. connect to a cluster: failing here must leave out_dir untouched
    ensure_writable_dir(out_dir)
    lock = BuildLock(out_dir)
    if lock.acquire(wait, progress.waiting_for_lock):
        plan = plan_build(loaded, out_dir, detailizer_override, only, force)  # the other build changed the folder
    try:
        if lock.previous is not None:
            progress.took_over_lock(lock.previous)
        return _run(loaded, out_dir, plan, progress, detailizer_override, executor, lock)
    finally:
        lock.release()


def _run(loaded: LoadedRecipe, out_dir: Path, plan: list[PlannedAsset], progress: Progress,
         detailizer_override: str | None, executor, lock: BuildLock) -> list[AssetReport]:
    remove_stale_temporaries(out_dir)
    reports: dict[int, AssetReport] = {}
    for p in plan:
        if p.cached_entry is not None:
            reports[p.index] = AssetReport.from_entry(p.index, p.cached_entry)
            progress.asset_finished(reports[p.index])
    todo = [p for p in plan if p.cached_entry is None]
    processes = getattr(executor, "block_processes", 1)
    tasks = [(loaded.text, str(loaded.path), p.index, p.key, str(out_dir), detailizer_override, lock.build_id,
              processes) for p in todo]

    def done(report: AssetReport) -> None:
        reports[report.index] = report
        progress.asset_finished(report)

    def lost(position: int, why: str) -> None:
        p = todo[position]
        where, _ = loaded.where(p.index)
        done(AssetReport(name=p.name, index=p.index, status=AssetStatus.FAILED,
                         error=f"{loaded.path}: {where}: the process building it died ({why})"))

    try:
        executor.run(build_task, tasks, done, names=[p.name for p in todo], lost=lost)
    except BaseException as exc:
        with _signals_held():  # a second Ctrl-C must not cut the clean-up short
            stopped = _after_stop(loaded, out_dir, plan, todo, reports, set(getattr(executor, "started", ())), lock)
            write_manifest(out_dir, loaded, stopped.reports)
        if isinstance(exc, KeyboardInterrupt) and not isinstance(exc, BuildInterrupted):
            raise BuildInterrupted(stopped) from None
        raise
    ordered = [reports[p.index] for p in plan if p.index in reports]
    _write_build_files(out_dir, loaded, ordered)
    return ordered


def _write_build_files(out_dir: Path, loaded: LoadedRecipe, reports: list[AssetReport]) -> None:
    """The build-level files: ``manifest.json``, ``NOTICE.txt`` (pipeline/provenance.py), ``build.json``."""
    write_manifest(out_dir, loaded, reports)
    write_notice(out_dir, [r.entry() for r in reports])
    write_build_signal(out_dir, reports)


@contextmanager
def _signals_held():
    """Absorb SIGINT and SIGTERM until the block ends (main thread only): the stop is already under way."""
    try:
        previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:  # not the main thread: signals are not ours to handle
        yield
        return
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _after_stop(loaded: LoadedRecipe, out_dir: Path, plan: list[PlannedAsset], todo: list[PlannedAsset],
                reports: dict[int, AssetReport], started: set[int], lock: BuildLock) -> Stopped:
    """Make the folder and the reports agree once the executor has stopped all its work."""
    for p in todo:
        if p.index not in reports:  # recorded just before the stop, its report never arrived
            entry, _ = check_record(out_dir, p.name, p.key, loaded.base_dir)
            if entry is not None:
                reports[p.index] = AssetReport.from_entry(p.index, entry)
                reports[p.index].cached = False
    unfinished = [(n, p) for n, p in enumerate(todo) if p.index not in reports]
    ordered = [reports[p.index] for p in plan if p.index in reports]
    keep = {out["path"] for r in ordered for out in r.outputs.values()} | {MANIFEST_NAME, NOTICE_NAME,
                                                                         str(BUILD_SIGNAL)}
    remove_stale_temporaries(out_dir)
    removed = remove_unfinished_outputs(out_dir, [p.name for _, p in unfinished], keep, lock.started_ns)
    return Stopped(reports=ordered, in_progress=[p.name for n, p in unfinished if n in started],
                   not_started=[p.name for n, p in unfinished if n not in started], removed_files=removed)

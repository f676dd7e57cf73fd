"""``decollage build --watch``: rebuild what changed whenever an input of the build is saved.

What is watched: the recipe file, every file its assets name (source files,
fonts, scripts), every file a built asset recorded as an input in its manifest
entry (``inputs.files``), the detailizers' weights (the checkpoint, or a data
file such as a style set passed as ``checkpoint``) and a style set file a
detailizer reports in its description (``style_set_path``).

How: the folders holding those files are watched (not recursively) through
``watchfiles`` (Rust ``notify``: inotify on Linux), so an editor's
save-by-rename is seen too; events on other files are dropped. Events are
debounced: a rebuild starts once no watched file changed for ``quiet_ms``
(a burst of saves is one rebuild; a burst never delays it past ``max_ms``).

What is rebuilt is left to the build's cache (``pipeline/cache.py``): every
rebuild re-reads the recipe and re-plans, and an asset is rebuilt exactly when
its key changed (its resolved recipe entry, the bytes of its input files, the
weights, the detailizer, the library versions). Saving a file without changing
its bytes therefore rebuilds nothing. A recipe that no longer parses is
reported and the previous watch goes on until it is fixed.

The gallery signal: every build rewrites ``<out>/build.json``
(``pipeline/manifest.py``), whose ``counter`` goes up and whose ``rebuilt``
names the assets to reload.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from core.errors import DecollageError
from core.recipe_loader import LoadedRecipe, load_recipe
from pipeline.build import input_paths
from pipeline.cache import closure_paths
from pipeline.report import AssetReport

#: A rebuild starts after this long without a change to a watched file (milliseconds).
QUIET_MS = 100
#: ... and at the latest this long after the first change of a burst.
MAX_MS = 1000


@dataclass
class Rebuild:
    """One round of watch mode, for the caller to show.

    ``changed``: the watched files whose events triggered it (empty for the first build);
    ``reports``: the build's reports (None when the recipe failed to load or check: then ``error``);
    ``since_save_s``: seconds from the newest change's file mtime to the end of the build (manifest written);
    ``detected_s``: from that mtime to the start of the round (event delivery and debounce);
    ``cpu_s``: CPU seconds this process spent in the round (all threads): on cores shared with other
    work, the wall time grows but this does not.
    """

    changed: list[Path]
    reports: list[AssetReport] | None = None
    error: DecollageError | None = None
    build_s: float = 0.0
    since_save_s: float | None = None
    detected_s: float | None = None
    cpu_s: float = 0.0
    rebuilt: list[str] = field(default_factory=list)


def watched_files(loaded: LoadedRecipe, reports: list[AssetReport] | None,
                  detailizer_override: str | None = None) -> set[Path]:
    """The files whose change may change an output (see the module docstring), resolved."""
    paths = {loaded.path, *input_paths(loaded, detailizer_override)}
    for report in reports or ():
        paths.update(closure_paths(report.inputs.get("files"), loaded.base_dir))  # every file its build read
        style_set = (report.info.get("detailizer") or {}).get("style_set_path")
        if style_set:
            paths.add(Path(style_set))
    return {p.resolve() for p in paths}


def _newest_mtime(paths: list[Path]) -> float | None:
    times = []
    for p in paths:
        try:
            times.append(p.stat().st_mtime)
        except OSError:
            pass  # deleted: no save time
    return max(times) if times else None


def watch_build(recipe: Path, build: Callable[[LoadedRecipe], list[AssetReport]],
                on_round: Callable[[Rebuild], None], *, detailizer_override: str | None = None,
                stop: threading.Event | None = None, quiet_ms: int = QUIET_MS, max_ms: int = MAX_MS) -> None:
    """Build once, then rebuild after every change of a watched file until ``stop`` is set (or Ctrl-C).

    Args:
        recipe: the recipe file.
        build: builds a loaded recipe into the output folder and returns its reports
            (the CLI's ``build_recipe`` call, with its executor and progress).
        on_round: called after the first build and after every rebuild.
        stop: ends the watch (tests); Ctrl-C ends it too.
    """
    import watchfiles

    stop = stop or threading.Event()
    loaded: LoadedRecipe | None = None
    reports: list[AssetReport] | None = None
    watched = {Path(recipe).resolve()}

    def run(changed: list[Path]) -> None:
        nonlocal loaded, reports, watched
        started, cpu = time.time(), time.process_time()
        result = Rebuild(changed)
        try:
            fresh = load_recipe(recipe)
            result.reports = build(fresh)
            loaded, reports = fresh, result.reports
            result.rebuilt = [r.name for r in reports if not r.cached]
        except DecollageError as exc:
            result.error = exc
        finished = time.time()
        result.build_s = finished - started
        result.cpu_s = time.process_time() - cpu
        saved = _newest_mtime(changed)
        result.since_save_s = None if saved is None else finished - saved
        result.detected_s = None if saved is None else started - saved
        if loaded is not None:
            watched = watched_files(loaded, reports, detailizer_override) | {Path(recipe).resolve()}
        on_round(result)

    run([])
    while not stop.is_set():
        targets = set(watched)
        folders = sorted({p.parent for p in targets if p.parent.is_dir()})
        for changes in watchfiles.watch(*folders, watch_filter=lambda _change, path: Path(path) in targets,
                                        debounce=max_ms, step=quiet_ms, stop_event=stop, rust_timeout=500,
                                        recursive=False, raise_interrupt=False):
            run(sorted({Path(path) for _change, path in changes}))
            if watched != targets:
                break  # the set of inputs changed: watch the new folders
        else:
            return  # stopped

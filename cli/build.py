"""``decollage build``: build every asset of a recipe into meshes, previews and a manifest (only what changed)."""

from __future__ import annotations

import json
import signal
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from cli.console import ExitCode, fail, literal, stderr
from core.errors import DecollageError, UsageError
from core.recipe_loader import load_recipe
from core.variants import DEFAULT_MAX_ASSETS
from pipeline.batch import BuildInterrupted, build_recipe, plan_build
from pipeline.build import check_recipe
from pipeline.executors import ExecutorKind, LocalExecutor, make_executor
from pipeline.report import AssetStatus
from pipeline.watch import QUIET_MS, Rebuild, watch_build


def build_command(
    recipe: Path = typer.Argument(..., help="Recipe YAML file."),
    out: Path = typer.Option(Path("out"), "--out", "-o", help="Output folder (created if missing)."),
    only: Optional[list[str]] = typer.Option(None, "--only", help="Build only assets with these names."),
    detailizer: Optional[str] = typer.Option(None, "--detailizer", help="Override every asset's detailizer."),
    jobs: int = typer.Option(1, "--jobs", "-j", min=1, help="Worker processes on this machine."),
    executor: ExecutorKind = typer.Option(ExecutorKind.LOCAL, "--executor",
                                          help="local, or dask (a cluster; needs --address)."),
    address: Optional[str] = typer.Option(None, "--address", help="Cluster scheduler, e.g. tcp://host:8786."),
    gpus_per_task: float = typer.Option(0.0, "--gpus-per-task", min=0.0,
                                        help="GPUs a cluster task asks for (Dask resource 'GPU')."),
    force: bool = typer.Option(False, "--force", help="Rebuild even assets whose outputs are up to date."),
    wait: bool = typer.Option(True, "--wait/--no-wait",
                              help="When another build is writing into the output folder: wait for it (default), "
                                   "or stop at once (exit 2)."),
    list_only: bool = typer.Option(False, "--list", help="Show the assets (variants expanded) and stop."),
    max_assets: int = typer.Option(DEFAULT_MAX_ASSETS, "--max-assets", min=1,
                                   help="Refuse a recipe whose variants expand to more assets than this."),
    check: bool = typer.Option(False, "--check", help="Exit 1 if any output is stale; build nothing."),
    json_out: bool = typer.Option(False, "--json", help="Machine-readable summary on stdout; logs on stderr."),
    keep_going: bool = typer.Option(True, "--keep-going/--fail-fast",
                                    help="Build the other assets after a failure (default), or stop at the first."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Only errors and the summary."),
    debug: bool = typer.Option(False, "--debug", help="Show tracebacks of internal errors."),
    watch: bool = typer.Option(False, "--watch", help="Build, then rebuild the assets whose inputs change "
                               "(recipe entries, input files, weights) whenever a watched file is saved; Ctrl-C stops."),
    quiet_ms: int = typer.Option(QUIET_MS, "--debounce-ms", min=10, max=5000,
                                 help="--watch: rebuild once no watched file changed for this long."),
) -> None:
    """Build every asset of a recipe into meshes, previews and a manifest (only what changed)."""

    started = time.perf_counter()
    term = _Signal()
    try:
        loaded = load_recipe(recipe, max_assets)
        assets = loaded.recipe.assets
        names = [a.name for a in assets]
        unknown = sorted(set(only or ()) - set(names))
        if unknown:
            raise UsageError(f"--only names unknown assets {unknown} (assets: {names[:20]})")
        selected = set(only) if only else None
        pick = (lambda a: a.name in selected) if selected else None
        if watch and (list_only or check or json_out):
            raise UsageError("--watch builds and keeps watching; it does not go with --list, --check or --json")
        if list_only:
            _print_list(loaded, pick, json_out)
            return
        if watch:
            _watch(recipe, out, pick, detailizer, make_executor(executor, jobs, address, gpus_per_task), force,
                   quiet, keep_going, quiet_ms)
            return
        if check:
            check_recipe(loaded, detailizer)
            plan = plan_build(loaded, out, detailizer, pick)
            _print_check(plan, json_out)
            raise typer.Exit(ExitCode.ASSETS_FAILED if any(p.cached_entry is None for p in plan) else ExitCode.OK)
        total = len(selected) if selected else len(names)
        with _ConsoleProgress(total, quiet or json_out, keep_going, out) as progress, _sigterm_interrupts(term):
            runner = make_executor(executor, jobs, address, gpus_per_task, progress)
            reports = build_recipe(loaded, out, progress, detailizer, only=pick, force=force, executor=runner,
                                   wait=wait)
    except DecollageError as exc:
        fail(exc)
    except _Stopped as stop:
        reports = stop.reports
    except BuildInterrupted as interrupted:
        _STOPPED.received = True
        _report_interruption(interrupted.stopped, out, recipe, time.perf_counter() - started, json_out,
                             "SIGTERM" if term.received else "Ctrl-C")
        raise typer.Exit(ExitCode.TERMINATED if term.received else ExitCode.INTERRUPTED) from None
    if debug:
        for r in reports:
            if r.traceback:
                stderr().print(r.traceback, markup=False)
    wall = time.perf_counter() - started
    if json_out:
        sys.stdout.write(json.dumps(_json_summary(reports, recipe, out, wall), indent=2) + "\n")
    else:

        Console(highlight=False).print(_summary_table(reports, out))
        cached = sum(r.cached for r in reports)
        built = sum(r.status == AssetStatus.BUILT and not r.cached for r in reports)
        stderr().print(f"{built} built, {cached} up to date (cached), "
                        f"{sum(r.status == 'failed' for r in reports)} failed in {wall:.1f} s")
    failed = [r for r in reports if r.status != AssetStatus.BUILT]
    if failed:
        stderr().print(f"[red]{len(failed)} of {len(reports)} assets failed[/]; "
                        f"the others are in {literal(out)} (see manifest.json)")
        raise typer.Exit(ExitCode.ASSETS_FAILED)


def _watch(recipe: Path, out: Path, pick, detailizer, runner, force: bool, quiet: bool, keep_going: bool,
           quiet_ms: int) -> None:
    """``--watch``: the first build, then one rebuild per burst of saves (pipeline/watch.py)."""
    console = stderr()
    first = [force]

    def build(loaded):
        with _ConsoleProgress(len(loaded.recipe.assets), True, True, out) as progress:
            if isinstance(runner, LocalExecutor):
                runner.progress = progress
            reports = build_recipe(loaded, out, progress, detailizer, only=pick, force=first[0], executor=runner)
        first[0] = False
        return reports

    def show(round_: Rebuild) -> None:
        changed = ", ".join(p.name for p in round_.changed) or "first build"
        if round_.error is not None:
            console.print(f"[red]{changed}: not built[/]: {round_.error.one_line()}", markup=True)
            return
        failed = [r for r in round_.reports if r.status == AssetStatus.FAILED]
        built = [n for n in round_.rebuilt if n not in {r.name for r in failed}]
        timing = f"{round_.build_s:.2f} s" + (f", {round_.since_save_s:.2f} s after the save"
                                              if round_.since_save_s is not None else "")
        console.print(f"{changed}: rebuilt {', '.join(built) or 'nothing'} ({timing}); "
                      f"{len(round_.reports) - len(round_.rebuilt)} up to date")
        if not quiet:
            for r in round_.reports:
                if not r.cached:
                    for w in r.warnings:
                        console.print(f"  [yellow]warning:[/] {r.name}: {w}")
        if round_.changed == []:
            console.print(f"watching for changes (saves settle for {quiet_ms} ms); Ctrl-C stops")

    del keep_going  # every round builds every stale asset; a failure is shown and watching goes on
    try:
        watch_build(recipe, build, show, detailizer_override=detailizer, quiet_ms=quiet_ms)
    except KeyboardInterrupt:
        pass
    console.print("stopped watching")


def _print_list(loaded, pick, json_out: bool) -> None:
    rows = []
    for i, a in enumerate(loaded.recipe.assets):
        if pick is None or pick(a):
            where, _ = loaded.where(i)
            rows.append({"name": a.name, "recipe_field": where, "source": a.source.kind, "variant": a.variant})
    if json_out:
        sys.stdout.write(json.dumps(rows, indent=2) + "\n")
        return
    for row in rows:
        variant = " ".join(f"{k}={v}" for k, v in (row["variant"] or {}).items())
        typer.echo(f"{row['name']}\t{row['source']}\t{row['recipe_field']}\t{variant}".rstrip())
    typer.echo(f"{len(rows)} assets", err=True)


def _print_check(plan, json_out: bool) -> None:
    stale = [p for p in plan if p.cached_entry is None]
    fresh = [p.name for p in plan if p.cached_entry is not None]
    if json_out:
        sys.stdout.write(json.dumps({"stale": [p.name for p in stale], "up_to_date": fresh,
                                     "reasons": {p.name: p.reason for p in stale}}, indent=2) + "\n")
    else:
        for p in stale:
            typer.echo(f"stale\t{p.name}\t{p.reason}")
        typer.echo(f"{len(stale)} stale, {len(fresh)} up to date", err=True)


class _Signal:
    received = False


_STOPPED = _Signal()  # set once a build here was stopped by a signal


def build_was_stopped() -> bool:
    """Whether a build in this process was stopped by Ctrl-C or SIGTERM (its files are all written and closed)."""
    return _STOPPED.received


@contextmanager
def _sigterm_interrupts(state: _Signal):
    """While building, SIGTERM (a CI timeout, ``kill``) stops the build as Ctrl-C does: workers first, then
    the manifest of what is on disk; ``state.received`` says whether SIGTERM came."""

    def handler(signum, frame):
        state.received = True
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave SIGTERM alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _report_interruption(stopped, out: Path, recipe: Path, wall_s: float, json_out: bool, cause: str) -> None:
    """What an interrupted build left: printed on stderr (and as the --json summary on stdout)."""
    reports = stopped.reports
    if json_out:
        summary = _json_summary(reports, recipe, out, wall_s)
        summary["interrupted"] = {"by": cause, "in_progress": stopped.in_progress, "not_started": stopped.not_started,
                                  "removed_files": stopped.removed_files}
        sys.stdout.write(json.dumps(summary, indent=2) + "\n")
    console = stderr()
    built = sum(r.status == AssetStatus.BUILT and not r.cached for r in reports)
    cached = sum(r.cached for r in reports)

    def listing(names):
        return f" ({literal(', '.join(names[:8]))}{', ...' if len(names) > 8 else ''})" if names else ""

    console.print(f"[yellow]interrupted[/] by {cause} after {wall_s:.1f} s: stopped "
                  f"{len(stopped.in_progress)} assets in progress{listing(stopped.in_progress)}, "
                  f"{len(stopped.not_started)} not started{listing(stopped.not_started)}")
    console.print(f"{literal(out / 'manifest.json')} lists the {len(reports)} assets in the folder ({built} built, "
                  f"{cached} up to date, {len(reports) - built - cached} failed); the same command builds the rest")


def _json_summary(reports, recipe: Path, out: Path, wall_s: float) -> dict:
    return {
        "recipe": str(recipe),
        "out": str(out),
        "manifest": str(out / "manifest.json"),
        "wall_time_s": round(wall_s, 3),
        "summary": {
            "assets": len(reports),
            "built": sum(r.status == AssetStatus.BUILT and not r.cached for r in reports),
            "cached": sum(r.cached for r in reports),
            "failed": sum(r.status == AssetStatus.FAILED for r in reports),
        },
        "assets": [{"name": r.name, "status": "cached" if r.cached else r.status,
                    "outputs": {k: str(out / v["path"]) for k, v in r.outputs.items()},
                    **({"error": r.error} if r.error else {})} for r in reports],
    }


class _Stopped(Exception):
    """--fail-fast: an asset failed; carries the reports so far."""

    def __init__(self, reports) -> None:
        super().__init__("stopped after a failure")
        self.reports = reports


class _ConsoleProgress:
    """Asset-level progress on stderr: a live bar on a terminal, one line per asset otherwise."""

    def __init__(self, total: int, quiet: bool, keep_going: bool = True, out: Path | None = None) -> None:

        self.out = out
        self.console = stderr()
        self.quiet = quiet
        self.keep_going = keep_going
        self.live = self.console.is_terminal and not quiet
        self.name = ""
        self.reports: list = []
        self.bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                            TimeElapsedColumn(), console=self.console, transient=True)
        self.task = self.bar.add_task("building", total=total)

    def __enter__(self):
        if self.live:
            self.bar.start()
        return self

    def __exit__(self, *exc):
        if self.live:
            self.bar.stop()

    def waiting_for_lock(self, holder) -> None:
        who = holder.describe() if holder else "another build"
        self.console.print(f"waiting: {literal(self.out)} is being written by another build ({literal(who)}); "
                           "Ctrl-C to stop waiting, --no-wait to stop instead of waiting")

    def took_over_lock(self, holder) -> None:
        if not self.quiet:
            self.console.print(f"[dim]note: the build that last wrote {literal(self.out)} did not finish "
                               f"({literal(holder.describe())}); its lock was taken over[/]")

    def asset_started(self, index: int, total: int, name: str) -> None:
        self.name = name
        self.bar.update(self.task, description=f"{name}: starting")

    def stage(self, stage: str) -> None:
        self.bar.update(self.task, description=f"{self.name}: {stage}")

    def asset_finished(self, report) -> None:
        self.reports.append(report)
        self.bar.advance(self.task)
        self.bar.update(self.task, description=f"{report.name}: {'cached' if report.cached else report.status}")
        if not self.quiet:
            if report.cached:
                self.console.print(f"[dim]cached[/] {report.name}")
            elif report.status == AssetStatus.BUILT:
                self.console.print(f"[green]built[/]  {report.name} ({sum(report.timings_s.values()):.1f} s)")
            else:
                self.console.print(f"[red]failed[/] {report.name}: {literal(report.error)}")
            if not report.cached:
                for w in report.warnings:
                    self.console.print(f"  [yellow]warning:[/] {literal(w)}")
        elif report.status == AssetStatus.FAILED:
            self.console.print(f"[red]failed[/] {report.name}: {literal(report.error)}")
        if report.status == AssetStatus.FAILED and not self.keep_going:
            raise _Stopped(list(self.reports))


def _summary_table(reports, out_dir: Path):

    table = Table(title=f"decollage build → {out_dir}", title_justify="left")
    for col in ("asset", "status", "triangles", "size (m)", "files", "time (s)"):
        table.add_column(col, justify="right" if col in ("triangles", "time (s)") else "left")
    for r in reports:
        mesh = r.info.get("mesh", {})
        if mesh:
            lo, hi = mesh["bbox_min_m"], mesh["bbox_max_m"]
            size = "×".join(f"{b - a:.2f}" for a, b in zip(lo, hi))
        else:
            size = ""
        table.add_row(r.name, "built" if r.status == AssetStatus.BUILT else "[red]failed[/]",
                      str(mesh.get("triangles", "")), size, ", ".join(sorted(r.outputs)),
                      f"{sum(r.timings_s.values()):.1f}")
    return table




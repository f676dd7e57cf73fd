"""``decollage``: the command line. The only place that prints for people and maps errors to exit codes.

Exit codes:
    0  everything asked for was done (all assets built / recipe valid)
    1  some assets failed; the others were still built and are in the manifest
    2  invalid recipe or usage (nothing was built or written)
    3  internal error (a bug; run with --debug for the traceback)
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Optional

import typer

from pipeline.errors import DecollageError

EXIT_OK, EXIT_ASSETS_FAILED, EXIT_INVALID, EXIT_INTERNAL = 0, 1, 2, 3

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Turn coarse 3D shapes into detailed, game-ready meshes.",
)


def _stderr():
    from rich.console import Console

    return Console(stderr=True, highlight=False, soft_wrap=True)


def _fail(exc: DecollageError, code: int = EXIT_INVALID) -> None:
    _stderr().print(f"[bold red]error:[/] {exc.one_line()}", markup=True)
    raise typer.Exit(code)


class _ConsoleProgress:
    """Asset-level progress on stderr: a live bar on a terminal, one line per asset otherwise."""

    def __init__(self, total: int, quiet: bool) -> None:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        self.console = _stderr()
        self.quiet = quiet
        self.live = self.console.is_terminal and not quiet
        self.started = 0.0
        self.name = ""
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

    def asset_started(self, index: int, total: int, name: str) -> None:
        self.name, self.started = name, time.perf_counter()
        self.bar.update(self.task, description=f"{name}: starting")

    def stage(self, stage: str) -> None:
        self.bar.update(self.task, description=f"{self.name}: {stage}")

    def asset_finished(self, report) -> None:
        self.bar.advance(self.task)
        if self.quiet:
            return
        took = time.perf_counter() - self.started
        if report.status == "built":
            self.console.print(f"[green]built[/]  {report.name} ({took:.1f} s)")
        else:
            self.console.print(f"[red]failed[/] {report.name}: {report.error}")
        for w in report.warnings:
            self.console.print(f"  [yellow]warning:[/] {w}")


def _summary_table(reports, out_dir: Path):
    from rich.table import Table

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
        table.add_row(r.name, "built" if r.status == "built" else "[red]failed[/]",
                      str(mesh.get("triangles", "")), size, ", ".join(sorted(r.outputs)),
                      f"{sum(r.timings_s.values()):.1f}")
    return table


@app.command()
def build(
    recipe: Path = typer.Argument(..., help="Recipe YAML file."),
    out: Path = typer.Option(Path("out"), "--out", "-o", help="Output folder (created if missing)."),
    only: Optional[list[str]] = typer.Option(None, "--only", help="Build only assets with these names."),
    detailizer: Optional[str] = typer.Option(None, "--detailizer", help="Override every asset's detailizer."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Only errors and the summary."),
    debug: bool = typer.Option(False, "--debug", help="Show tracebacks of internal errors."),
) -> None:
    """Build every asset of a recipe into meshes, previews and a manifest."""
    from pipeline.build import build_recipe
    from pipeline.recipe import load_recipe

    try:
        loaded = load_recipe(recipe)
        names = {a.name for a in loaded.recipe.assets}
        unknown = sorted(set(only or ()) - names)
        if unknown:
            from pipeline.errors import UsageError

            raise UsageError(f"--only names unknown assets {unknown} (assets: {sorted(names)})")
        selected = set(only) if only else None
        total = len(selected) if selected else len(names)
        with _ConsoleProgress(total, quiet) as progress:
            reports = build_recipe(loaded, out, progress, detailizer,
                                   only=(lambda a: a.name in selected) if selected else None)
    except DecollageError as exc:
        _fail(exc)
    if debug:
        for r in reports:
            if r.traceback:
                _stderr().print(r.traceback, markup=False)
    from rich.console import Console

    Console(highlight=False).print(_summary_table(reports, out))
    failed = [r for r in reports if r.status != "built"]
    if failed:
        _stderr().print(f"[red]{len(failed)} of {len(reports)} assets failed[/]; "
                        f"the others are in {out} (see manifest.json)")
        raise typer.Exit(EXIT_ASSETS_FAILED)


@app.command()
def validate(recipes: list[Path] = typer.Argument(..., help="Recipe files to check.")) -> None:
    """Check recipes (schema, input files, detailizer and style names) without building."""
    from pipeline.build import check_recipe
    from pipeline.recipe import load_recipe

    for path in recipes:
        try:
            loaded = load_recipe(path)
            check_recipe(loaded)
        except DecollageError as exc:
            _fail(exc)
        typer.echo(f"{path}: ok ({len(loaded.recipe.assets)} assets)")


@app.command()
def schema(out: Optional[Path] = typer.Option(None, "--out", "-o", help="Write to a file instead of stdout.")) -> None:
    """Print the JSON Schema of recipes (for editor autocomplete)."""
    from pipeline.recipe import json_schema

    text = json.dumps(json_schema(), indent=2) + "\n"
    if out is None:
        sys.stdout.write(text)
    else:
        from pipeline.export import write_bytes_atomic

        try:
            write_bytes_atomic(out, text.encode())
        except DecollageError as exc:
            _fail(exc)


@app.command()
def version() -> None:
    """Print the version."""
    from pipeline import __version__

    typer.echo(f"decollage {__version__}")


def main() -> None:
    """Console-script entry point; turns unexpected exceptions into exit code 3."""
    try:
        app()
    except SystemExit:
        raise
    except KeyboardInterrupt:
        _stderr().print("interrupted")
        sys.exit(130)
    except Exception as exc:  # a bug: say so briefly, no traceback unless asked
        if "--debug" in sys.argv:
            raise
        _stderr().print(f"internal error: {type(exc).__name__}: {exc} (run with --debug for the traceback)",
                        markup=False)
        sys.exit(EXIT_INTERNAL)


if __name__ == "__main__":
    main()

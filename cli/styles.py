"""``decollage styles``: build, import, list and show style exemplar sets.

Role: the ``styles`` sub-app of ``cli.app`` (registered there with
``app.add_typer``). Tables go to stdout (rich), progress lines to stderr;
errors are ``DecollageError``s mapped to exit code 2 by ``cli.console.fail``
(one line, no traceback, nothing half-written: set files and sheets are
written atomically, and only after every exemplar voxelized).

- ``styles build <set>``: a built-in set → ``<out>/<set>.npz`` (cached: a
  second build with the same inputs does nothing) and its contact sheet
  ``<out>/<set>.png``.
- ``styles import <folder> --name N --vocab V``: a folder of the user's meshes
  → ``<out>/<N>.npz`` in the same format (see ``stylesets.user_import``).
- ``styles list``: the built-in sets and every set file in the styles folder.
- ``styles show <set-or-file>``: the exemplars' table and the contact sheet.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.table import Table

from cli.console import fail, literal, stderr
from core.errors import DecollageError, UsageError
from core.recipe import UpAxis
from stylesets.contact_sheet import write_contact_sheet
from stylesets.format import (
    DETAIL_RATIO_MIN,
    RESOLUTION,
    ExemplarError,
    build_set,
    inputs_hash,
    load_set,
    read_meta,
    set_path,
    style_dir,
    vocabulary_from_arg,
)
from stylesets.registry import BUILTIN_SETS, builtin_set
from stylesets.user_import import check_set_name, find_exemplars, import_folder

styles_app = typer.Typer(
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Style exemplar sets: build the built-in ones, import your own, list and show them.",
)

_OUT_HELP = "Folder of set files (default: $DECOLLAGE_STYLES_DIR, else ~/.cache/decollage/styles)."


def _console():
    """stdout; piped output (logs, CI) gets wide rows instead of rich's default 80 columns."""

    console = Console(highlight=False, soft_wrap=True)
    if not console.is_terminal:
        console.width = 160
    return console


def _progress(total: int, quiet: bool):
    """A ``build_set`` progress callback printing one line per voxelized exemplar to stderr."""

    console, done, started = stderr(), [0], time.perf_counter()

    def report(name: str) -> None:
        done[0] += 1
        if not quiet:
            console.print(f"voxelized {name} ({done[0]}/{total}, {time.perf_counter() - started:.1f} s)",
                          markup=False)

    return report


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def _exemplar_table(style_set):


    where = f" → {style_set.path}" if style_set.path else ""
    table = Table(title=f"style set '{style_set.name}': {_plural(len(style_set.exemplars), 'exemplar')} at "
                        f"{style_set.resolution}³, vocabulary '{style_set.vocabulary.name}'{where}",
                  title_justify="left")
    for col in ("exemplar", "category", "parts (voxels)", "voxels", "detail", "source", "licence"):
        table.add_column(col, justify="right" if col in ("voxels", "detail") else "left", overflow="fold")
    for ex in style_set.exemplars:
        meta = ex.meta
        aliases = meta.get("part_aliases", {})
        parts = ", ".join(f"{aliases.get(p, p)} {meta['part_voxels'].get(p, 0)}" for p in meta["parts"])
        ratio = (meta.get("detail") or {}).get("ratio")
        if ratio is None:
            detail = "-"
        elif ratio >= DETAIL_RATIO_MIN:
            detail = f"x{ratio:.2f}"
        else:
            detail = f"[yellow]x{ratio:.2f} low[/]"
        table.add_row(ex.name, ex.category, parts, str(meta["voxels"]), detail, meta.get("source", ""),
                      meta.get("licence", ""))
    return table


def _report(result, warnings, sheet: bool, quiet: bool) -> None:
    """Print the set's table, write its sheet, print the paths."""

    console = _console()
    if not quiet:
        console.print(_exemplar_table(result.style_set))
    for warning in warnings:
        stderr().print(f"[yellow]warning:[/] {literal(warning)}")
    state = "built" if result.built else "up to date (cached)"
    stderr().print(f"{state} in {result.seconds:.1f} s")
    typer.echo(f"set: {result.path}")
    if sheet:
        path, written = write_contact_sheet(result.style_set, force=result.built)
        typer.echo(f"sheet: {path}" + ("" if written else " (up to date)"))


@styles_app.command("build")
def build_command(
    set_name: str = typer.Argument(..., metavar="SET", help="A built-in set: furniture, things or monastery."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help=_OUT_HELP),
    force: bool = typer.Option(False, "--force", help="Rebuild even when the set file is up to date."),
    jobs: int = typer.Option(2, "--jobs", "-j", min=1, help="Worker processes voxelizing exemplars."),
    sheet: bool = typer.Option(True, "--sheet/--no-sheet", help="Also write the contact sheet <set>.png."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress lines and no table."),
) -> None:
    """Voxelize every exemplar of a built-in set at 256³ into one versioned set file (cached)."""

    try:
        if set_name not in BUILTIN_SETS:
            raise UsageError(f"unknown built-in style set '{set_name}'", field="SET",
                             hint="built-in sets: " + ", ".join(BUILTIN_SETS)
                                  + "; your own meshes go in with 'decollage styles import'")
        vocab, specs = builtin_set(set_name)
        path = set_path(set_name, out)
        if not quiet:
            stderr().print(f"set '{set_name}': {_plural(len(specs), 'exemplar')} at {RESOLUTION}³, "
                            f"{jobs} workers → {path}",
                            markup=False)
        result = build_set(set_name, vocab, specs, path, force=force, workers=jobs,
                           progress=_progress(len(specs), quiet))
        _report(result, [], sheet, quiet)
    except DecollageError as exc:
        fail(exc)


@styles_app.command("import")
def import_command(
    folder: Path = typer.Argument(..., help="Folder of exemplar meshes (one file, or one subfolder, each)."),
    name: str = typer.Option(..., "--name", "-n", help="Name of the new set (its file is <out>/<name>.npz)."),
    vocab: str = typer.Option(..., "--vocab", help="Part vocabulary: furniture, things, or names like 'a,b,c'."),
    category: Optional[str] = typer.Option(None, "--category",
                                           help="Category of every exemplar (default: from its part names)."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help=_OUT_HELP),
    resolution: int = typer.Option(256, "--resolution", min=16, max=512,
                                   help="Exemplar grid side (a multiple of 16)."),
    licence: str = typer.Option("user-supplied", "--licence", help="Licence recorded for every exemplar."),
    up: UpAxis = typer.Option(UpAxis.Y, "--up", help="Which axis of the meshes points up."),
    force: bool = typer.Option(False, "--force", help="Rebuild even when the set file is up to date."),
    jobs: int = typer.Option(2, "--jobs", "-j", min=1, help="Worker processes voxelizing exemplars."),
    sheet: bool = typer.Option(True, "--sheet/--no-sheet", help="Also write the contact sheet <name>.png."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress lines and no table."),
) -> None:
    """Turn a folder of your own meshes into a style set (same format and cache as the built-in sets)."""

    try:
        if resolution % 16:
            raise UsageError(f"--resolution {resolution} is not a multiple of 16", field="--resolution",
                             hint="e.g. 64, 128 or 256 (the detail check pools to 16³)")
        vocabulary = vocabulary_from_arg(vocab)
        check_set_name(name)
        if not quiet:
            stderr().print(f"importing {folder} as set '{name}' ({vocabulary.name} vocabulary, {resolution}³) "
                            f"→ {set_path(name, out)}", markup=False)
        progress = _progress(_count_exemplars(folder), quiet)
        result, warnings = import_folder(folder, name, vocabulary, out=out, resolution=resolution,
                                         category=category, licence=licence, up=up.value, force=force,
                                         workers=jobs, progress=progress)
        _report(result, warnings, sheet, quiet)
    except DecollageError as exc:
        fail(exc)


def _count_exemplars(folder: Path) -> int:

    return len(find_exemplars(folder)[0])


@styles_app.command("list")
def list_command(
    out: Optional[Path] = typer.Option(None, "--dir", "-d", help=_OUT_HELP),
) -> None:
    """List the built-in sets and every set file in the styles folder: exemplars, built or not, path."""


    folder = Path(out) if out is not None else style_dir()
    table = Table(title=f"style sets in {folder}", title_justify="left")
    for col in ("set", "kind", "exemplars", "grid", "status"):
        table.add_column(col, justify="right" if col in ("exemplars", "grid") else "left")
    table.add_column("path", overflow="fold")
    try:
        seen = set()
        for name in BUILTIN_SETS:
            path = set_path(name, folder)
            seen.add(path.name)
            try:
                vocab, specs = builtin_set(name)
            except ExemplarError as exc:
                table.add_row(name, "built-in", "-", "-", f"unavailable: {exc.message}", "")
                continue
            status, grid = "not built", "256"
            if path.is_file():
                try:
                    meta = read_meta(path)
                    grid = str(meta["resolution"])
                    fresh = meta.get("inputs_hash") == inputs_hash(name, vocab, specs, int(meta["resolution"]))
                    status = "[green]built[/]" if fresh else "[yellow]stale[/] (rebuild: styles build)"
                except ExemplarError as exc:
                    status = f"[red]unreadable[/] ({literal(exc.message)})"
            table.add_row(name, "built-in", str(len(specs)), grid, status, str(path))
        files = sorted(folder.glob("*.npz")) if folder.is_dir() else []
        for path in files:
            if path.name in seen:
                continue
            try:
                meta = read_meta(path)
                table.add_row(str(meta["set"]), "user" if _all_user(meta) else "file", str(len(meta["exemplars"])),
                              str(meta["resolution"]), "[green]built[/]", str(path))
            except ExemplarError as exc:
                table.add_row(path.stem, "file", "-", "-", f"[red]unreadable[/] ({literal(exc.message)})", str(path))
    except DecollageError as exc:
        fail(exc)
    _console().print(table)


def _all_user(meta: dict) -> bool:
    return bool(meta["exemplars"]) and all(e.get("source") == "user" for e in meta["exemplars"])


@styles_app.command("show")
def show_command(
    set_or_path: str = typer.Argument(..., metavar="SET", help="A set name (in the styles folder) or a .npz file."),
    sheet: Optional[Path] = typer.Option(None, "--sheet", help="Contact sheet PNG (default: <set>.png beside it)."),
    no_sheet: bool = typer.Option(False, "--no-sheet", help="Only print the table."),
    out: Optional[Path] = typer.Option(None, "--dir", "-d", help=_OUT_HELP),
) -> None:
    """Print a set's exemplars (categories, parts, voxels, detail ratio, source, licence) and draw its sheet."""

    try:
        if no_sheet and sheet is not None:
            raise UsageError("--sheet and --no-sheet contradict each other", field="--sheet")
        path = Path(set_or_path)
        if not path.is_file() and path.suffix != ".npz":
            path = set_path(set_or_path, out)
            if not path.is_file():
                folder = Path(out) if out is not None else style_dir()
                how = (f"build it with 'decollage styles build {set_or_path}'" if set_or_path in BUILTIN_SETS
                       else "'decollage styles list' shows the sets; import one with 'decollage styles import'")
                raise ExemplarError(f"no style set '{set_or_path}' in {folder}", field="SET", hint=how)
        style_set = load_set(path)
        _console().print(_exemplar_table(style_set))
        if not no_sheet:
            written_to, _ = write_contact_sheet(style_set, sheet)
            typer.echo(f"sheet: {written_to}")
    except DecollageError as exc:
        fail(exc)

"""``decollage``: the command line, one module per sub-command. The only place that prints for people.

Exit codes (``cli/console.py``, ``ExitCode``):
    0  everything asked for was done (all assets built / recipe valid)
    1  some assets failed; the others were still built and are in the manifest
    2  invalid recipe or usage (nothing was built or written)
    3  internal error (a bug; run with --debug for the traceback)
"""

from __future__ import annotations

import os
import sys

import typer
from typer.exceptions import TyperException

from cli.bench import bench_command
from cli.build import build_command, build_was_stopped
from cli.console import ExitCode, literal, stderr
from cli.eval import eval_command
from cli.paint import paint_command
from cli.schema import schema_command, version_command
from cli.styles import styles_app
from cli.train import train_command
from cli.validate import validate_command
from cli.view import view_command
from pipeline.executors import abandoned_work

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Turn coarse 3D shapes into detailed, game-ready meshes.",
)
app.command("build")(build_command)
app.command("validate")(validate_command)
app.command("schema")(schema_command)
app.command("version")(version_command)
app.command("train")(train_command)
app.command("eval")(eval_command)
app.command("bench")(bench_command)
app.command("view")(view_command)
app.command("paint")(paint_command)
app.add_typer(styles_app, name="styles")


_COMMAND = None


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point: usage errors as one line (exit 2), unexpected exceptions as exit code 3.

    ``argv`` defaults to ``sys.argv[1:]``. Always ends with ``SystemExit`` carrying the exit code.
    """
    global _COMMAND
    if _COMMAND is None:  # typer builds the click command once per process (tests call main many times)
        _COMMAND = typer.main.get_command(app)
    debug = "--debug" in (sys.argv[1:] if argv is None else argv)
    try:
        code = _COMMAND.main(args=argv, standalone_mode=False, prog_name="decollage")
        sys.exit(code if isinstance(code, int) else 0)
    except SystemExit as exc:
        if build_was_stopped() or abandoned_work():
            # A stopped build has written and closed everything (manifest, records, lock): end at once.
            # The interpreter's clean-up takes seconds with torch loaded, and must not wait for a kernel
            # that an abandoned in-process task still runs.
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(exc.code if isinstance(exc.code, int) else ExitCode.INTERRUPTED)
        raise
    except TyperException as exc:  # the command line itself is wrong (click's usage errors, vendored by typer)
        sys.exit(_usage_error(exc))
    except (KeyboardInterrupt, typer.Abort):  # click turns Ctrl-C into Abort outside standalone mode
        stderr().print("interrupted")
        sys.exit(ExitCode.INTERRUPTED)
    except Exception as exc:  # a bug: say so briefly, no traceback unless asked
        if debug:
            raise
        stderr().print(f"internal error: {type(exc).__name__}: {exc} (run with --debug for the traceback)",
                        markup=False)
        sys.exit(ExitCode.INTERNAL)


def _usage_error(exc: TyperException) -> int:
    """Print a usage error as ``error: <command>: <option>: <message> (see <command> --help)``; its exit code."""
    ctx = getattr(exc, "ctx", None)
    if type(exc).__name__ == "NoArgsIsHelpError" and ctx is not None:
        typer.echo(ctx.get_help())
        return ExitCode.INVALID
    command = ctx.command_path if ctx is not None else "decollage"
    param = getattr(exc, "param", None)
    option = "/".join(param.opts) if param is not None and getattr(param, "opts", None) else ""
    message = " ".join(str(exc.format_message() if hasattr(exc, "format_message") else exc).split())
    where = ": ".join(p for p in (command, option) if p)
    stderr().print(f"[bold red]error:[/] {literal(where)}: {literal(message)} (see {literal(command)} --help)")
    code = getattr(exc, "exit_code", ExitCode.INVALID)
    return code if isinstance(code, int) and code else ExitCode.INVALID


if __name__ == "__main__":
    main()

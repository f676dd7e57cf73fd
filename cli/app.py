"""``decollage``: the command line, one module per sub-command. The only place that prints for people.

Exit codes (``cli/console.py``, ``ExitCode``):
    0  everything asked for was done (all assets built / recipe valid)
    1  some assets failed; the others were still built and are in the manifest
    2  invalid recipe or usage (nothing was built or written)
    3  internal error (a bug; run with --debug for the traceback)
"""

from __future__ import annotations

import sys

import typer

from cli.bench import bench_command
from cli.build import build_command
from cli.console import ExitCode, stderr
from cli.eval import eval_command
from cli.paint import paint_command
from cli.schema import schema_command, version_command
from cli.styles import styles_app
from cli.train import train_command
from cli.validate import validate_command
from cli.view import view_command

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


def main() -> None:
    """Console-script entry point; turns unexpected exceptions into exit code 3."""
    try:
        app()
    except SystemExit:
        raise
    except KeyboardInterrupt:
        stderr().print("interrupted")
        sys.exit(ExitCode.INTERRUPTED)
    except Exception as exc:  # a bug: say so briefly, no traceback unless asked
        if "--debug" in sys.argv:
            raise
        stderr().print(f"internal error: {type(exc).__name__}: {exc} (run with --debug for the traceback)",
                        markup=False)
        sys.exit(ExitCode.INTERNAL)


if __name__ == "__main__":
    main()

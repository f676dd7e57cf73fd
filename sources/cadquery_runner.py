"""Run one cadquery script inside the optional cadquery runtime and write its parts as STL files.

This file runs under a *different* interpreter (the ``.venv-cadquery`` venv,
see ``sources/cad_script.py``), so it imports nothing from decollage and only
the standard library plus cadquery.

Usage::

    python cadquery_runner.py SCRIPT FUNCTION OUTDIR [--tolerance T|auto]
                               [--relative-tolerance R] [--angular-tolerance A]

It runs SCRIPT in a fresh namespace (``__name__ == "decollage_script"``), calls
FUNCTION(), and accepts a ``cq.Workplane`` (its ``.vals()`` shapes, combined
into one compound), a ``cq.Shape``, a ``cq.Assembly``, a dict of name → those,
or a list of (name, those) pairs. Each part is tessellated (chord tolerance T
in the script's units, or R × the part's bounding-box diagonal when T is
``auto``; angular tolerance A radians) and written to OUTDIR as a binary STL
``part_<i>.stl`` (little-endian float32, unmerged triangles), plus
``index.json``: ``{"parts": [{"name": ..., "file": ...}, ...]}`` in part order.

On failure it exits with status 1 and prints one line of JSON on stderr:
``{"field": "script" | "script_function" | "script_engine", "message": ..., "hint": ...}``.
"""

from __future__ import annotations

import argparse
import json
import runpy
import struct
import sys
import traceback
from pathlib import Path

SCRIPT_MODULE_NAME = "decollage_script"
ACCEPTED = "a cadquery Workplane/Shape/Assembly, a dict of part name → those, or a list of (name, shape) pairs"
MAX_MESSAGE_CHARS = 400


class RunnerError(Exception):
    """A problem to report to the main process as one JSON line."""

    def __init__(self, message: str, field: str = "script", hint: str | None = None) -> None:
        super().__init__(message)
        self.message, self.field, self.hint = message, field, hint


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("script", type=Path)
    parser.add_argument("function")
    parser.add_argument("outdir", type=Path)
    parser.add_argument("--tolerance", default="auto")
    parser.add_argument("--relative-tolerance", type=float, default=1e-3)
    parser.add_argument("--angular-tolerance", type=float, default=0.2)
    args = parser.parse_args(argv)
    try:
        run(args)
    except RunnerError as err:
        print(json.dumps({"field": err.field, "message": err.message, "hint": err.hint}), file=sys.stderr)
        return 1
    return 0


def run(args: argparse.Namespace) -> None:
    try:
        import cadquery as cq
    except Exception as exc:  # a broken runtime (e.g. mixed OCP wheels) fails here
        raise RunnerError(f"the cadquery runtime {sys.executable} cannot import cadquery: "
                          f"{type(exc).__name__}: {exc}", field="script_engine",
                          hint="reinstall it with `bash scripts/install.sh cadquery`") from None
    script = args.script.resolve()
    result = call_script(script, args.function)
    parts = named_shapes(cq, result, script, args.function)
    args.outdir.mkdir(parents=True, exist_ok=True)
    index = []
    for i, (name, shape) in enumerate(parts):
        if not shape.Solids():
            raise RunnerError(f"part {name!r} has no solid (it is a {type(shape).__name__} without volume)",
                              hint="return closed solids; faces, wires and sketches cannot be voxelized")
        if args.tolerance == "auto":
            tolerance = max(shape.BoundingBox().DiagonalLength * args.relative_tolerance, 1e-9)
        else:
            tolerance = float(args.tolerance)
        try:
            vertices, triangles = shape.tessellate(tolerance, args.angular_tolerance)
        except Exception as exc:
            raise RunnerError(f"tessellating part {name!r} failed: {type(exc).__name__}: {exc}",
                              hint="try a different 'tolerance'") from None
        filename = f"part_{i:03d}.stl"
        write_binary_stl(args.outdir / filename, [v.toTuple() for v in vertices], triangles)
        index.append({"name": name, "file": filename})
    (args.outdir / "index.json").write_text(json.dumps({"parts": index}), encoding="utf-8")


def call_script(script: Path, function: str):
    if not script.is_file():
        raise RunnerError(f"script not found: {script}", hint="the path is relative to the recipe's folder")
    sys.path.insert(0, str(script.parent))  # helper modules beside the script
    try:
        namespace = runpy.run_path(str(script), run_name=SCRIPT_MODULE_NAME)
    except (Exception, SystemExit) as exc:
        raise RunnerError(describe_exception(exc, script),
                          hint="fix the script; run it with python to see the full traceback") from None
    target = namespace.get(function)
    if not callable(target):
        found = sorted(name for name, obj in namespace.items()
                       if callable(obj) and getattr(getattr(obj, "__code__", None), "co_filename", None) == str(script))
        raise RunnerError(f"script has no function {function!r} (functions defined in {script.name}: "
                          f"{', '.join(found) if found else 'none'})", field="script_function",
                          hint=f"define `def {function}():` returning {ACCEPTED}, or set script_function")
    try:
        return target()
    except (Exception, SystemExit) as exc:
        raise RunnerError(describe_exception(exc, script),
                          hint="fix the script; run it with python to see the full traceback") from None


def describe_exception(exc: BaseException, script: Path) -> str:
    """``script raised <Type>: <message> (line N of <file>)``, the same wording as the main process."""
    line = None
    if isinstance(exc, SyntaxError) and exc.filename and Path(exc.filename).resolve() == script:
        line, text = exc.lineno, exc.msg
    else:
        text = str(exc)
        for frame in traceback.extract_tb(exc.__traceback__):
            if frame.filename and Path(frame.filename).resolve() == script:
                line = frame.lineno
    text = " ".join(text.split())
    if len(text) > MAX_MESSAGE_CHARS:
        text = text[: MAX_MESSAGE_CHARS - 1] + "…"
    message = f"script raised {type(exc).__name__}" + (f": {text}" if text else "")
    if line is not None:
        message += f" (line {line} of {script.name})"
    return message


def named_shapes(cq, result, script: Path, function: str) -> list:
    """The function's return value → ``[(name, cq.Shape), ...]`` (names checked by the main process)."""

    def as_shape(obj, what: str):
        if isinstance(obj, cq.Workplane):
            shapes = [v for v in obj.vals() if isinstance(v, cq.Shape)]
            if not shapes:
                raise RunnerError(f"{function}() returned {what}: a Workplane that holds no shapes",
                                  hint="end the Workplane chain on a solid")
            return shapes[0] if len(shapes) == 1 else cq.Compound.makeCompound(shapes)
        if isinstance(obj, cq.Assembly):
            return obj.toCompound()
        if isinstance(obj, cq.Shape):
            return obj
        raise RunnerError(f"{function}() returned {what} that is a {type(obj).__name__}, not a cadquery shape",
                          hint=f"return {ACCEPTED}")

    if isinstance(result, (cq.Workplane, cq.Shape, cq.Assembly)):
        return [(stem_part_name(script), as_shape(result, "a value"))]
    if isinstance(result, dict):
        pairs = list(result.items())
    elif isinstance(result, (list, tuple)) and result and all(
            isinstance(item, (list, tuple)) and len(item) == 2 for item in result):
        pairs = [tuple(item) for item in result]
    else:
        raise RunnerError(f"{function}() returned a {type(result).__name__}; expected {ACCEPTED}",
                          hint=f"return {ACCEPTED}")
    if not pairs:
        raise RunnerError(f"{function}() returned no parts", hint="return at least one shape")
    for name, _ in pairs:
        if not isinstance(name, str):
            raise RunnerError(f"{function}() returned an invalid part name {name!r}",
                              hint="part names are strings of letters, digits, '_', '.', '-'")
    return [(name, as_shape(obj, f"part {name!r}")) for name, obj in pairs]


def stem_part_name(script: Path) -> str:
    """A valid part name from the file stem; same rule as ``cad_script.stem_part_name``."""
    import re

    name = re.sub(r"[^A-Za-z0-9_.\-]", "_", script.stem)
    name = re.sub(r"^[^A-Za-z0-9]+", "", name)
    return name or "part"


def write_binary_stl(path: Path, vertices: list, triangles: list) -> None:
    """Binary STL (80-byte header, uint32 count, 50 bytes per triangle); normals left zero (readers recompute)."""
    record = struct.Struct("<12fH")
    out = bytearray(b"decollage cadquery runner".ljust(80, b"\0"))
    out += struct.pack("<I", len(triangles))
    for a, b, c in triangles:
        out += record.pack(0.0, 0.0, 0.0, *vertices[a], *vertices[b], *vertices[c], 0)
    path.write_bytes(bytes(out))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

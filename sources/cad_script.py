"""The ``cad`` source's script mode: a user's build123d or cadquery script → named part meshes.

Security model: a script is ordinary Python with the user's full rights. It
runs **only because the recipe names it** (``source.script``), exactly like
running ``python script.py`` by hand; decollage never runs a script that a
recipe does not name, never fetches scripts, and does not sandbox them. Treat
recipes from others like any code from others.

The script (a ``.py`` file, relative to the recipe's folder) defines a function
``spec.script_function`` (default ``build``) that takes no arguments and returns:

- one shape → one part, named after the script's file stem (``tower.py`` → ``tower``);
- a ``dict`` of part name → shape → one part per entry, in the dict's order;
- a ``list`` of ``(name, shape)`` pairs → one part per pair, in list order.

Part names must match ``recipe.NAME_PATTERN`` and be unique. A "shape" is any
build123d ``Shape`` (``Part``, ``Solid``, ``Compound``...) or a ``BuildPart``
builder (its ``.part`` is used). Numbers in the script are in ``spec.units``;
the script's up axis is ``spec.up_axis`` (CAD's Z by default).

Engines:

- ``build123d`` (default): the file runs in this process with ``runpy.run_path``
  in a fresh namespace whose ``__name__`` is ``"decollage_script"`` (so an
  ``if __name__ == "__main__":`` block does not run). The script's folder is on
  ``sys.path`` while it runs, so it can import helper modules next to it.
  The working directory is not changed: open data files via ``__file__``.
- ``cadquery``: cadquery 2.8 and build123d 0.13 need different OCP versions and
  cannot share a venv, so cadquery scripts run in a **separate, optional
  runtime**: another Python interpreter that has cadquery installed. It is
  found, in order, at ``$DECOLLAGE_CADQUERY_PYTHON``; ``<repo>/.venv-cadquery/bin/python``
  (``<repo>`` = the folder holding ``sources/``); ``<parent of sys.prefix>/.venv-cadquery/bin/python``
  (a cadquery venv beside the main venv). ``bash scripts/install.sh cadquery``
  creates it. That interpreter runs ``sources/cadquery_runner.py`` (which
  imports nothing from decollage) in a subprocess; the runner tessellates each
  part to a binary STL plus ``index.json`` in a temporary folder, and this
  module loads them. Shapes accepted there: ``cq.Workplane`` (its ``.vals()``
  combined), ``cq.Shape``, ``cq.Assembly``, and dicts / lists of those.

Errors inside the script become ``SourceError(field="script")`` with a message
like ``script raised ValueError: bad size (line 12 of tower.py)``; no traceback
is shown.
"""

from __future__ import annotations

import json
import os
import re
import runpy
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from core.errors import SourceError
from core.files import InputKind, input_file
from core.recipe import NAME_PATTERN, CadSource
from sources.base import PartMeshes
from sources.cadquery_runner import MAX_MESSAGE_CHARS, describe_exception
from sources.tessellate import (
    ANGULAR_TOLERANCE_RAD,
    DEFAULT_RELATIVE_TOLERANCE,
    mesh_warnings,
    shapes_to_parts,
    vertices_to_part,
)

#: Wall-clock limit for one cadquery script run (subprocess start + import + script + tessellation), seconds.
CADQUERY_TIMEOUT_S: float = 300.0

#: Environment variable naming the cadquery runtime's Python interpreter.
CADQUERY_PYTHON_ENV: str = "DECOLLAGE_CADQUERY_PYTHON"

#: Folder name of the optional cadquery venv.
CADQUERY_VENV_NAME: str = ".venv-cadquery"

#: What to tell a user whose machine lacks the cadquery runtime.
CADQUERY_INSTALL_HINT: str = (
    "install the optional cadquery runtime with `bash scripts/install.sh cadquery` "
    f"(a separate venv, {CADQUERY_VENV_NAME}/ in the repository), or set {CADQUERY_PYTHON_ENV} "
    "to a Python interpreter that has cadquery 2.8 installed"
)

#: Module name scripts run under (anything but "__main__", so `if __name__ == "__main__":` blocks stay quiet).
SCRIPT_MODULE_NAME: str = "decollage_script"

_RUNNER = Path(__file__).resolve().with_name("cadquery_runner.py")
_ACCEPTED = "a shape, a dict of part name → shape, or a list of (name, shape) pairs"


def load(spec: CadSource, base_dir: Path) -> PartMeshes:
    """Run ``spec.script`` and turn what its function returns into canonical part meshes.

    Returns:
        PartMeshes (metres, +Y up) with ``input_files=[script path]``.

    Raises:
        SourceError: missing / unreadable script (field ``script``), missing function
            (``script_function``), script exceptions or bad return values (``script``),
            missing cadquery runtime (``script_engine``).
    """
    path = resolve_script(spec, base_dir)
    if spec.script_engine == "cadquery":
        parts, warnings = _load_cadquery(spec, path)
    else:
        parts, warnings = _load_build123d(spec, path)
    return PartMeshes(parts=parts, warnings=warnings, input_files=[path])


def resolve_script(spec: CadSource, base_dir: Path) -> Path:
    """The script's absolute path; refuses missing files, folders and non-``.py`` files."""
    assert spec.script is not None
    path = input_file(spec.script, base_dir, field="script", noun="script", hint="name a .py file", kind=InputKind.SCRIPT)
    if path.suffix != ".py":
        raise SourceError(f"script must be a .py file, got {path.name!r}", field="script",
                          hint="name a Python file that defines the build function")
    return path


# --------------------------------------------------------------------------- build123d, in-process


def _load_build123d(spec: CadSource, path: Path) -> tuple[dict, list[str]]:
    result = _call_script(path, spec.script_function)
    named = named_shapes(result, path, spec.script_function)
    return shapes_to_parts([(name, shape, "script") for name, shape in named], spec)


def _call_script(path: Path, function: str) -> Any:
    """Run the file in a fresh namespace and call its function; script errors → SourceError."""
    folder = str(path.parent)
    added = folder not in sys.path
    if added:
        sys.path.insert(0, folder)  # lets the script import helper modules beside it
    try:
        try:
            namespace = runpy.run_path(str(path), run_name=SCRIPT_MODULE_NAME)
        except (Exception, SystemExit) as exc:  # anything the script raises while loading
            raise script_error(exc, path) from None
        target = namespace.get(function)
        if not callable(target):
            found = sorted(
                name for name, obj in namespace.items()
                if callable(obj) and getattr(getattr(obj, "__code__", None), "co_filename", None) == str(path)
            )
            listing = ", ".join(found) if found else "none"
            raise SourceError(
                f"script has no function {function!r} (functions defined in {path.name}: {listing})",
                field="script_function",
                hint=f"define `def {function}():` returning {_ACCEPTED}, or set script_function",
            )
        try:
            return target()
        except (Exception, SystemExit) as exc:
            raise script_error(exc, path) from None
    finally:
        if added and folder in sys.path:
            sys.path.remove(folder)


def script_error(exc: BaseException, path: Path) -> SourceError:
    """``script raised <Type>: <message> (line N of <file>)`` for an exception from a user's script."""
    return SourceError(describe_exception(exc, path), field="script",
                       hint="fix the script; run it with python to see the full traceback")


def named_shapes(result: Any, path: Path, function: str) -> list[tuple[str, Any]]:
    """The script function's return value → ``[(part name, build123d Shape), ...]`` in order."""
    import build123d as bd

    def as_shape(obj: Any, what: str) -> Any:
        if isinstance(obj, bd.BuildPart):
            obj = obj.part
        if isinstance(obj, bd.Shape):
            return obj
        raise SourceError(
            f"{function}() returned {what} that is a {type(obj).__name__}, not a build123d shape",
            field="script", hint=f"return {_ACCEPTED}")

    if isinstance(result, (bd.Shape, bd.BuildPart)):
        return [(stem_part_name(path), as_shape(result, "a value"))]
    if isinstance(result, dict):
        pairs = list(result.items())
    elif isinstance(result, (list, tuple)) and result and all(
        isinstance(item, (list, tuple)) and len(item) == 2 for item in result
    ):
        pairs = [tuple(item) for item in result]
    else:
        raise SourceError(f"{function}() returned a {type(result).__name__}; expected {_ACCEPTED}",
                          field="script", hint=f"return {_ACCEPTED}")
    names = check_part_names([name for name, _ in pairs], function)
    return [(name, as_shape(obj, f"part {name!r}")) for name, (_, obj) in zip(names, pairs)]


def check_part_names(names: list[Any], function: str) -> list[str]:
    """Validate part names from a script: non-empty list, strings matching NAME_PATTERN, unique."""
    if not names:
        raise SourceError(f"{function}() returned no parts", field="script",
                          hint="return at least one shape")
    for name in names:
        if not isinstance(name, str) or not re.match(NAME_PATTERN, name):
            raise SourceError(
                f"{function}() returned an invalid part name {name!r}", field="script",
                hint="part names start with a letter or digit and use only letters, digits, '_', '.', '-'")
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise SourceError(f"{function}() returned duplicate part names: {duplicates}", field="script",
                          hint="give every part its own name")
    return names


def stem_part_name(path: Path) -> str:
    """A valid part name from the script's file stem (``my tower.py`` → ``my_tower``)."""
    name = re.sub(r"[^A-Za-z0-9_.\-]", "_", path.stem)
    name = re.sub(r"^[^A-Za-z0-9]+", "", name)
    return name or "part"


# --------------------------------------------------------------------------- cadquery, in its own runtime


def find_cadquery_python() -> Path:
    """The cadquery runtime's interpreter (lookup order in the module docstring).

    Raises:
        SourceError(field="script_engine"): none found, or the env var names a missing file.
    """
    configured = os.environ.get(CADQUERY_PYTHON_ENV)
    if configured:
        path = Path(configured).expanduser()
        if not (path.is_file() and os.access(path, os.X_OK)):
            raise SourceError(f"{CADQUERY_PYTHON_ENV} names {path}, which is not an executable file",
                              field="script_engine", hint=CADQUERY_INSTALL_HINT)
        return path
    repo_root = Path(__file__).resolve().parents[1]
    for folder in (repo_root, Path(sys.prefix).resolve().parent):
        for relative in ("bin/python", "Scripts/python.exe"):
            candidate = folder / CADQUERY_VENV_NAME / relative
            if candidate.is_file():
                return candidate
    raise SourceError("this script uses cadquery, but the cadquery runtime is not installed",
                      field="script_engine", hint=CADQUERY_INSTALL_HINT)


def _load_cadquery(spec: CadSource, path: Path) -> tuple[dict, list[str]]:
    python = find_cadquery_python()
    with tempfile.TemporaryDirectory(prefix="decollage-cq-") as tmp:
        outdir = Path(tmp)
        command = [
            str(python), str(_RUNNER), str(path), spec.script_function, str(outdir),
            "--tolerance", repr(spec.tolerance) if spec.tolerance is not None else "auto",
            "--relative-tolerance", repr(DEFAULT_RELATIVE_TOLERANCE),
            "--angular-tolerance", repr(ANGULAR_TOLERANCE_RAD),
        ]
        # The runtime is another venv: our PYTHONPATH/PYTHONHOME would leak this venv's OCP into it.
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        try:
            proc = subprocess.run(command, capture_output=True, text=True, timeout=CADQUERY_TIMEOUT_S,
                                  env=env, check=False)
        except subprocess.TimeoutExpired:
            raise SourceError(f"the cadquery script did not finish within {CADQUERY_TIMEOUT_S:.0f} s",
                              field="script", hint="make the script faster, or check it for endless loops") from None
        except OSError as exc:
            raise SourceError(f"cannot start the cadquery runtime {python}: {exc.strerror}",
                              field="script_engine", hint=CADQUERY_INSTALL_HINT) from None
        if proc.returncode != 0:
            raise _runner_error(proc.returncode, proc.stderr, python)
        entries = _read_index(outdir / "index.json", python)
        names = check_part_names([e.get("name") for e in entries], spec.script_function)
        parts = {}
        for name, entry in zip(names, entries):
            vertices, faces = _read_stl(outdir / str(entry.get("file", "")), name, python)
            parts[name] = vertices_to_part(vertices, faces, spec, name, "script")
    warnings = [w for name, mesh in parts.items() for w in mesh_warnings(name, mesh)]
    return parts, warnings


def _runner_error(returncode: int, stderr: str, python: Path) -> SourceError:
    """The runner's one-line JSON error (last such line on stderr) → SourceError."""
    for line in reversed(stderr.strip().splitlines()):
        try:
            report = json.loads(line)
        except ValueError:
            continue  # OCP prints a harmless fontconfig warning on stderr, among other noise
        if isinstance(report, dict) and "message" in report:
            field = report.get("field") if report.get("field") in ("script", "script_function", "script_engine") \
                else "script"
            return SourceError(str(report["message"]), field=field, hint=report.get("hint") or None)
    last = stderr.strip().splitlines()[-1] if stderr.strip() else "no error output"
    return SourceError(f"the cadquery runtime {python} failed (exit code {returncode}): {last[:MAX_MESSAGE_CHARS]}",
                       field="script_engine", hint=CADQUERY_INSTALL_HINT)


def _read_index(index_path: Path, python: Path) -> list[dict]:
    try:
        index = json.loads(index_path.read_text(encoding="utf-8"))
        entries = index["parts"]
        if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
            raise ValueError("'parts' is not a list of objects")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SourceError(f"the cadquery runtime {python} wrote no usable index.json ({exc})",
                          field="script_engine", hint=CADQUERY_INSTALL_HINT) from None
    return entries


def _read_stl(stl_path: Path, name: str, python: Path):
    """A binary STL from the runner → ((V, 3) float64 vertices, (F, 3) int64 faces), unmerged."""
    import numpy as np

    try:
        data = stl_path.read_bytes()
        count = int(np.frombuffer(data, dtype="<u4", count=1, offset=80)[0])
        record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")])
        tris = np.frombuffer(data, dtype=record, count=count, offset=84)
    except (OSError, ValueError, IndexError) as exc:
        raise SourceError(f"the cadquery runtime {python} wrote an unreadable mesh for part '{name}' ({exc})",
                          field="script_engine", hint=CADQUERY_INSTALL_HINT) from None
    vertices = tris["corners"].reshape(-1, 3).astype(np.float64)
    faces = np.arange(len(vertices), dtype=np.int64).reshape(-1, 3)
    return vertices, faces

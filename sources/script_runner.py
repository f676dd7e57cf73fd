"""Run users' CAD scripts (build123d or cadquery) isolated from the build: one process per script run.

This file runs under the interpreter of the script's engine: the project's own
venv for build123d, the optional ``.venv-cadquery`` for cadquery (see
``sources/cad_script.py``). It imports nothing from decollage: the standard
library, and the engine inside the functions that need it.

Protocol (one for both engines; ``sources/cad_script.py`` is the client)::

    python script_runner.py serve ENGINE      # ENGINE: build123d | cadquery

The server imports the engine once, prints ``{"ready": true}`` (or
``{"ready": false, "error": {...}}``) on stdout, then reads one JSON request
per line on stdin::

    {"script": ..., "function": ..., "outdir": ..., "tolerance": T | "auto",
     "relative_tolerance": R, "angular_tolerance": A, "timeout_s": S, "memory_mb": M}

For each it forks a child in a process group of its own, which runs the request
(``run_request``) under resource limits (address space: its size at the start
plus M MiB; no core file; files it writes at most ``MAX_FILE_BYTES``) with stdin
closed and stdout/stderr going to ``OUTDIR/output.txt``, and answers one line::

    {"exit": code or null, "signal": number or null, "timed_out": bool, "peak_rss_kb": n}

after the child ended, or after S seconds (then the child's whole process group
is killed). Whatever the child left running is killed too. The server ends when
stdin closes, or, while a script runs, when the process that started it is
gone (the script's group is killed first). ``python script_runner.py run ENGINE REQUEST_JSON`` runs one
request in the current process instead (no fork; for platforms without it and
for debugging).

What a run leaves in OUTDIR: ``result.json``, written last and atomically, is
either ``{"error": {"field": "script" | "script_function" | "script_engine",
"message": ..., "hint": ...}}`` or ``{"complete": true, "parts": [{"name": ...,
"file": ..., "vertices": V, "faces": F}, ...], "read_files": [paths]}``.
Each part file holds V×3 float64 vertices then F×3 int64 vertex indices,
little-endian, in the script's units, unmerged as the engine tessellated them.
``read_files`` lists what the script read while it ran, recorded in the child
by ``sources/script_reads.py`` (loaded from its file beside this one, since
this runner imports nothing of decollage by name): the local modules it
imported, then the data files it opened (and those it looked for in vain),
absolute and first read first, so that they can join the asset's inputs. No
``result.json`` means the script ended the process itself (``os._exit``, a
crash, a kill): the client reports that from the exit status.

The script runs in a fresh namespace (``__name__ == "decollage_script"``, so an
``if __name__ == "__main__":`` block does not run) with its folder first on
``sys.path``. Its function returns a shape, a dict of part name → shape, or a
list of (name, shape) pairs. build123d shapes: any ``Shape`` or a ``BuildPart``
(its ``.part``); cadquery: a ``Workplane`` (its shapes combined), a ``Shape``
or an ``Assembly``. Each part is tessellated with chord tolerance T (script
units) or R × its bounding-box diagonal when T is ``auto``, and angular
tolerance A radians.
"""

from __future__ import annotations

import importlib.util
import json
import os
import runpy
import sys
import time
import traceback
from array import array
from pathlib import Path

SCRIPT_MODULE_NAME = "decollage_script"
MAX_MESSAGE_CHARS = 400
#: Largest file a script run may write (its parts and its printed output), bytes.
MAX_FILE_BYTES = 2 << 30
ENGINES = ("build123d", "cadquery")
_ACCEPTED = {
    "build123d": "a shape, a dict of part name → shape, or a list of (name, shape) pairs",
    "cadquery": "a cadquery Workplane/Shape/Assembly, a dict of part name → those, or a list of (name, shape) pairs",
}
_FIX = "fix the script; run it with python to see the full traceback"


class RunnerError(Exception):
    """A problem to report to the client in ``result.json``."""

    def __init__(self, message: str, field: str = "script", hint: str | None = None) -> None:
        super().__init__(message)
        self.message, self.field, self.hint = message, field, hint


# --------------------------------------------------------------------------- the server


_PARENT = os.getppid()


def serve(engine: str) -> int:
    """Import the engine, then fork one child per request line on stdin (see the module docstring).

    The server ends when stdin closes, or while a script runs as soon as the process that started it is gone
    (then the script's process group is killed first).
    """
    try:
        _import_engine(engine)
        _script_reads()
    except RunnerError as err:
        _reply({"ready": False, "error": {"field": err.field, "message": err.message, "hint": err.hint}})
        return 1
    _reply({"ready": True})
    for line in sys.stdin:
        if not line.strip():
            continue
        try:
            request = json.loads(line)
        except ValueError:
            _reply({"exit": None, "signal": None, "timed_out": False, "peak_rss_kb": 0, "bad_request": True})
            continue
        _reply(_fork_and_wait(engine, request))
    return 0


def _reply(message: dict) -> None:
    sys.stdout.write(json.dumps(message) + "\n")
    sys.stdout.flush()


def _fork_and_wait(engine: str, request: dict) -> dict:
    timeout = float(request.get("timeout_s", 300.0))
    pid = os.fork()
    if pid == 0:  # the child: never returns
        code = 1
        try:
            os.setsid()
            _limit_resources(int(request.get("memory_mb", 4096)))
            _redirect_output(Path(request["outdir"]) / "output.txt")
            run_request(engine, request)
            code = 0
        except BaseException:  # noqa: BLE001 - nothing may escape a forked child
            code = 1
        finally:
            os._exit(code)
    deadline = time.monotonic() + timeout
    timed_out = False
    while True:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            break
        if os.getppid() != _PARENT:  # the build that started this runner is gone: stop its script, and leave
            _kill_group(pid)
            os._exit(1)
        if time.monotonic() > deadline:
            timed_out = True
            _kill_group(pid)
            _, status, usage = os.wait4(pid, 0)
            break
        time.sleep(0.01)
    _kill_group(pid)  # anything the script started and left behind
    return {"exit": os.WEXITSTATUS(status) if os.WIFEXITED(status) else None,
            "signal": os.WTERMSIG(status) if os.WIFSIGNALED(status) else None,
            "timed_out": timed_out, "peak_rss_kb": int(usage.ru_maxrss)}


def _kill_group(pgid: int) -> None:
    import signal

    try:
        os.killpg(pgid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _limit_resources(memory_mb: int) -> None:
    import resource

    with open("/proc/self/statm") as handle:  # first field: the address space's size in pages
        current = int(handle.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    for kind, wanted in ((resource.RLIMIT_AS, current + memory_mb * (1 << 20)), (resource.RLIMIT_CORE, 0),
                         (resource.RLIMIT_FSIZE, MAX_FILE_BYTES)):
        _, hard = resource.getrlimit(kind)
        if hard != resource.RLIM_INFINITY:  # never above a limit set by whoever started the build
            wanted = min(wanted, hard)
        resource.setrlimit(kind, (wanted, wanted))


def _redirect_output(path: Path) -> None:
    null = os.open(os.devnull, os.O_RDONLY)
    out = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    os.dup2(null, 0)
    os.dup2(out, 1)
    os.dup2(out, 2)
    os.close(null)
    os.close(out)


# --------------------------------------------------------------------------- one run


def run_request(engine: str, request: dict) -> None:
    """Run one script and write ``result.json`` (parts or an error) into the request's outdir."""
    outdir = Path(request["outdir"])
    outdir.mkdir(parents=True, exist_ok=True)
    try:
        result = _run(engine, request, outdir)
    except RunnerError as err:
        result = {"error": {"field": err.field, "message": err.message, "hint": err.hint}}
    except MemoryError:
        limit = request.get("memory_mb", "?")
        result = {"error": {"field": "script", "message": f"the script ran out of memory (script_memory_mb = {limit} "
                            "MiB beyond the CAD engine's own)", "hint": "make the script lighter, or raise "
                            "script_memory_mb"}}
    temp = outdir / "result.json.tmp"
    temp.write_text(json.dumps(result), encoding="utf-8")
    os.replace(temp, outdir / "result.json")


def _run(engine: str, request: dict, outdir: Path) -> dict:
    module = _import_engine(engine)
    script = Path(request["script"]).resolve()
    with _script_reads().ScriptReads() as reads:
        result = call_script(script, request["function"])
    parts = named_shapes(engine, module, result, script, request["function"])
    index = []
    for i, (name, shape) in enumerate(parts):
        vertices, triangles = _tessellate(engine, shape, name, request)
        filename = f"part_{i:03d}.bin"
        write_part(outdir / filename, vertices, triangles)
        index.append({"name": name, "file": filename, "vertices": len(vertices), "faces": len(triangles)})
    return {"complete": True, "parts": index, "read_files": [str(p) for p in reads.files() if p != script]}


_READS_MODULE = None


def _script_reads():
    """``sources/script_reads.py``, loaded from its file (the server loads it once, before forking)."""
    global _READS_MODULE
    if _READS_MODULE is None:
        spec = importlib.util.spec_from_file_location("decollage_script_reads",
                                                      Path(__file__).resolve().with_name("script_reads.py"))
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _READS_MODULE = module
    return _READS_MODULE


def _import_engine(engine: str):
    if engine not in ENGINES:
        raise RunnerError(f"unknown script engine {engine!r}", field="script_engine")
    try:
        if engine == "cadquery":
            import cadquery as module
        else:
            import build123d as module
    except Exception as exc:  # a broken runtime (e.g. mixed OCP wheels) fails here
        hint = ("reinstall it with `bash scripts/install.sh cadquery`" if engine == "cadquery"
                else "reinstall decollage with `bash scripts/install.sh`")
        raise RunnerError(f"the {engine} runtime {sys.executable} cannot import {engine}: "
                          f"{type(exc).__name__}: {exc}", field="script_engine", hint=hint) from None
    return module


def call_script(script: Path, function: str):
    """Run the file in a fresh namespace and call its function; script errors → RunnerError."""
    if not script.is_file():
        raise RunnerError(f"script not found: {script}", hint="the path is relative to the recipe's folder")
    sys.path.insert(0, str(script.parent))  # helper modules beside the script
    try:
        namespace = runpy.run_path(str(script), run_name=SCRIPT_MODULE_NAME)
    except MemoryError:
        raise
    except (Exception, SystemExit) as exc:
        raise RunnerError(describe_exception(exc, script), hint=_FIX) from None
    target = namespace.get(function)
    if not callable(target):
        found = sorted(name for name, obj in namespace.items()
                       if callable(obj) and getattr(getattr(obj, "__code__", None), "co_filename", None) == str(script))
        raise RunnerError(f"script has no function {function!r} (functions defined in {script.name}: "
                          f"{', '.join(found) if found else 'none'})", field="script_function",
                          hint=f"define `def {function}():` returning a shape, or set script_function")
    try:
        return target()
    except MemoryError:
        raise
    except (Exception, SystemExit) as exc:
        raise RunnerError(describe_exception(exc, script), hint=_FIX) from None


def describe_exception(exc: BaseException, script: Path) -> str:
    """``script raised <Type>: <message> (line N of <file>)``, for an exception from a user's script."""
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


def named_shapes(engine: str, module, result, script: Path, function: str) -> list:
    """The function's return value → ``[(name, shape), ...]`` (names are checked again by the client)."""
    accepted = _ACCEPTED[engine]
    single = _single_types(engine, module)
    if isinstance(result, single):
        return [(stem_part_name(script), _as_shape(engine, module, result, "a value", function))]
    if isinstance(result, dict):
        pairs = list(result.items())
    elif isinstance(result, (list, tuple)) and result and all(
            isinstance(item, (list, tuple)) and len(item) == 2 for item in result):
        pairs = [tuple(item) for item in result]
    else:
        raise RunnerError(f"{function}() returned a {type(result).__name__}; expected {accepted}",
                          hint=f"return {accepted}")
    if not pairs:
        raise RunnerError(f"{function}() returned no parts", hint="return at least one shape")
    for name, _ in pairs:
        if not isinstance(name, str):
            raise RunnerError(f"{function}() returned an invalid part name {name!r}",
                              hint="part names are strings of letters, digits, '_', '.', '-'")
    return [(name, _as_shape(engine, module, obj, f"part {name!r}", function)) for name, obj in pairs]


def _single_types(engine: str, module) -> tuple:
    if engine == "cadquery":
        return (module.Workplane, module.Shape, module.Assembly)
    return (module.Shape, module.BuildPart)


def _as_shape(engine: str, module, obj, what: str, function: str):
    if engine == "cadquery":
        cq = module
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
    else:
        if isinstance(obj, module.BuildPart):
            obj = obj.part
        if isinstance(obj, module.Shape):
            return obj
    raise RunnerError(f"{function}() returned {what} that is a {type(obj).__name__}, not a {engine} shape",
                      hint=f"return {_ACCEPTED[engine]}")


def _tessellate(engine: str, shape, name: str, request: dict) -> tuple[list, list]:
    """A shape → (vertices as (x, y, z) tuples, triangles as index triples), script units."""
    solids = shape.Solids() if engine == "cadquery" else shape.solids()
    if not solids:
        raise RunnerError(f"part '{name}' has no solid (it is a {type(shape).__name__} without volume)",
                          hint="return closed solids; faces, wires and sketches cannot be voxelized")
    if request.get("tolerance", "auto") == "auto":
        diagonal = shape.BoundingBox().DiagonalLength if engine == "cadquery" else shape.bounding_box().diagonal
        tolerance = max(float(diagonal) * float(request["relative_tolerance"]), 1e-9)
    else:
        tolerance = float(request["tolerance"])
    try:
        vertices, triangles = shape.tessellate(tolerance, float(request["angular_tolerance"]))
    except Exception as exc:
        raise RunnerError(f"tessellating part '{name}' failed: {type(exc).__name__}: {exc}",
                          hint="try a different 'tolerance'") from None
    if engine == "cadquery":
        points = [v.toTuple() for v in vertices]
    else:
        points = [(v.X, v.Y, v.Z) for v in vertices]
    if not triangles:
        raise RunnerError(f"tessellating part '{name}' produced no triangles",
                          hint="the part may be too small for the tolerance; set a smaller 'tolerance'")
    return points, [tuple(t) for t in triangles]


def write_part(path: Path, vertices: list, triangles: list) -> None:
    """V×3 float64 then F×3 int64, little-endian (the module docstring's part file)."""
    coords = array("d", (float(c) for v in vertices for c in v))
    indices = array("q", (int(i) for t in triangles for i in t))
    if sys.byteorder != "little":
        coords.byteswap()
        indices.byteswap()
    with open(path, "wb") as handle:
        coords.tofile(handle)
        indices.tofile(handle)


def stem_part_name(script: Path) -> str:
    """A valid part name from the file stem (``my tower.py`` → ``my_tower``)."""
    import re

    name = re.sub(r"[^A-Za-z0-9_.\-]", "_", script.stem)
    name = re.sub(r"^[^A-Za-z0-9]+", "", name)
    return name or "part"


def main(argv: list[str]) -> int:
    here = str(Path(__file__).resolve().parent)
    sys.path[:] = [p for p in sys.path if p and str(Path(p).resolve()) != here]  # scripts must not import sources/
    if len(argv) == 2 and argv[0] == "serve" and argv[1] in ENGINES:
        return serve(argv[1])
    if len(argv) == 3 and argv[0] == "run" and argv[1] in ENGINES:
        run_request(argv[1], json.loads(argv[2]))
        return 0
    sys.stderr.write("usage: script_runner.py serve ENGINE | run ENGINE REQUEST_JSON\n")
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

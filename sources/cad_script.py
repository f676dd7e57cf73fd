"""The ``cad`` source's script mode: a user's build123d or cadquery script → named part meshes.

Security model: a script is ordinary Python with the user's full rights. It
runs **only because the recipe names it** (``source.script``), exactly like
running ``python script.py`` by hand; decollage never runs a script that a
recipe does not name, never fetches scripts, and does not sandbox them against
reading or writing the user's files. Treat recipes from others like any code
from others. ``validate``, ``build --list`` and ``build --check`` never run a
script (``sources.cad.preflight`` only checks the file).

Isolation: a script never runs in the build's own process. Both engines run it
the same way, through ``sources/script_runner.py`` (its docstring has the
protocol): a warm runner process per engine imports the engine once, and
forks one child per script run, in a process group of its own, limited to
``spec.script_timeout_s`` seconds and ``spec.script_memory_mb`` MiB of address
space beyond the engine's own. So a script that calls ``os._exit``, crashes
the CAD kernel, loops forever or eats memory fails its asset with a message
saying which, and the build goes on (exit code 1). ``sys.exit`` inside the
script is an exception like any other. Whatever the script leaves running is
killed when it returns.

The script (a ``.py`` file, relative to the recipe's folder) defines a function
``spec.script_function`` (default ``build``) that takes no arguments and returns:

- one shape → one part, named after the script's file stem (``tower.py`` → ``tower``);
- a ``dict`` of part name → shape → one part per entry, in the dict's order;
- a ``list`` of ``(name, shape)`` pairs → one part per pair, in list order.

Part names must match ``recipe.NAME_PATTERN`` and be unique. Numbers in the
script are in ``spec.units``; the script's up axis is ``spec.up_axis`` (CAD's
Z by default). The script runs with ``__name__ == "decollage_script"`` (so an
``if __name__ == "__main__":`` block does not run) and its folder first on
``sys.path`` (helper modules beside it can be imported). The working
directory is not changed: open data files via ``__file__``. Its printed output
is discarded.

What the script read is recorded where it runs, in the runner's forked child
(``sources/script_reads.py``): the local modules it imported (its helpers and
their own local imports, wherever they lie outside the Python installation)
and the data files it opened for reading (or tried to, and found missing).
The runner reports them with the parts, and they join
``PartMeshes.input_files`` after the script, for both engines, so an edit to
a helper or a data file, or a missing file that appears, makes the asset
stale (``pipeline/cache.py``).

Engines:

- ``build123d`` (default): the runner runs under this interpreter
  (``sys.executable``). Shapes: any build123d ``Shape`` or a ``BuildPart``.
- ``cadquery``: cadquery 2.8 and build123d 0.13 need different OCP versions and
  cannot share a venv, so cadquery scripts run in a **separate, optional
  runtime**: another Python interpreter that has cadquery installed. It is
  found, in order, at ``$DECOLLAGE_CADQUERY_PYTHON``; ``<repo>/.venv-cadquery/bin/python``
  (``<repo>`` = the folder holding ``sources/``); ``<parent of sys.prefix>/.venv-cadquery/bin/python``
  (a cadquery venv beside the main venv). ``bash scripts/install.sh cadquery``
  creates it. Shapes: ``cq.Workplane`` (its ``.vals()`` combined),
  ``cq.Shape``, ``cq.Assembly``, and dicts / lists of those.

Errors inside the script become ``SourceError(field="script")`` with a message
like ``script raised ValueError: bad size (line 12 of tower.py)``; no traceback
is shown.
"""

from __future__ import annotations

import atexit
import json
import os
import re
import select
import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any

import numpy as np

from core.errors import SourceError
from core.files import InputKind, input_file
from core.recipe import NAME_PATTERN, CadSource
from sources.base import PartMeshes
from sources.tessellate import ANGULAR_TOLERANCE_RAD, DEFAULT_RELATIVE_TOLERANCE, mesh_warnings, vertices_to_part

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

#: Seconds a runner may take to start (import its engine) before it is given up.
RUNNER_START_TIMEOUT_S: float = 180.0

_RUNNER = Path(__file__).resolve().with_name("script_runner.py")
_SIGNALS = {signal.SIGSEGV: "a segmentation fault", signal.SIGABRT: "an abort", signal.SIGBUS: "a bus error",
            signal.SIGFPE: "a floating-point exception", signal.SIGILL: "an illegal instruction",
            signal.SIGKILL: "a kill (out of memory?)"}
_FIX = "fix the script; run it with python to see the full traceback"


def load(spec: CadSource, base_dir: Path) -> PartMeshes:
    """Run ``spec.script`` in an isolated process and turn what its function returns into canonical part meshes.

    Returns:
        PartMeshes (metres, +Y up) with ``input_files=[script path, local modules and data files it read...]``.

    Raises:
        SourceError: missing / unreadable script (field ``script``), missing function
            (``script_function``), script exceptions, bad return values, a script that ended
            its process, crashed, ran past ``script_timeout_s`` or ``script_memory_mb``
            (``script``), missing or broken runtime (``script_engine``).
    """
    path = resolve_script(spec, base_dir)
    python = find_cadquery_python() if spec.script_engine == "cadquery" else Path(sys.executable)
    with tempfile.TemporaryDirectory(prefix="decollage-script-") as tmp:
        outdir = Path(tmp)
        status = _runner(python, spec.script_engine).run({
            "script": str(path), "function": spec.script_function, "outdir": str(outdir),
            "tolerance": spec.tolerance if spec.tolerance is not None else "auto",
            "relative_tolerance": DEFAULT_RELATIVE_TOLERANCE, "angular_tolerance": ANGULAR_TOLERANCE_RAD,
            "timeout_s": spec.script_timeout_s, "memory_mb": spec.script_memory_mb,
        }, spec.script_timeout_s)
        result = _read_result(outdir, status, spec, python)
        names = check_part_names([e.get("name") for e in result["parts"]], spec.script_function)
        parts = {}
        for name, entry in zip(names, result["parts"]):
            vertices, faces = _read_part(outdir, entry, name, python)
            parts[name] = vertices_to_part(vertices, faces, spec, name, "script")
    warnings = [w for name, mesh in parts.items() for w in mesh_warnings(name, mesh)]
    return PartMeshes(parts=parts, warnings=warnings, input_files=[path, *_read_files(result, path)])


def resolve_script(spec: CadSource, base_dir: Path) -> Path:
    """The script's absolute path; refuses missing files, folders, devices, oversized and non-``.py`` files."""
    assert spec.script is not None
    path = input_file(spec.script, base_dir, field="script", noun="script", hint="name a .py file",
                      kind=InputKind.SCRIPT)
    if path.suffix != ".py":
        raise SourceError(f"script must be a .py file, got {path.name!r}", field="script",
                          hint="name a Python file that defines the build function")
    return path


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
    seen: set[str] = set()
    duplicates = sorted({n for n in names if n in seen or seen.add(n)})
    if duplicates:
        raise SourceError(f"{function}() returned duplicate part names: {duplicates}", field="script",
                          hint="give every part its own name")
    return names


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


# --------------------------------------------------------------------------- the runner process


class _Runner:
    """One warm ``script_runner.py serve ENGINE`` process; ``run`` sends a request and waits for its answer.

    One request at a time: the protocol is one answer line per request line, so threads that share a
    runner (a threaded cluster worker, an in-process task still running after its build stopped) take turns.
    """

    def __init__(self, python: Path, engine: str) -> None:
        self.python, self.engine, self.owner = python, engine, os.getpid()
        self.turn = threading.Lock()
        self.hint = CADQUERY_INSTALL_HINT if engine == "cadquery" else "reinstall with `bash scripts/install.sh`"
        env = dict(os.environ)
        if engine == "cadquery":  # another venv: our PYTHONPATH/PYTHONHOME would leak this venv's OCP into it
            env = {k: v for k, v in env.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        # One thread in the runner, so that forking it is safe (no thread pool holds a lock at fork time).
        env.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1", PYTHONUNBUFFERED="1")
        self._stderr = tempfile.TemporaryFile()
        try:
            self.proc = subprocess.Popen([str(python), str(_RUNNER), "serve", engine], stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE, stderr=self._stderr, env=env,
                                         start_new_session=True, close_fds=True, bufsize=0)
        except OSError as exc:
            raise SourceError(f"cannot start the {engine} runtime {python}: {exc.strerror or exc}",
                              field="script_engine", hint=self.hint) from None
        ready = self._answer(RUNNER_START_TIMEOUT_S)
        if not ready.get("ready"):
            error = ready.get("error") or {}
            self.close()
            raise SourceError(str(error.get("message") or f"the {engine} runtime {python} did not start"),
                              field="script_engine", hint=error.get("hint") or self.hint)

    def alive(self) -> bool:
        """Running, and started by this process (a forked process must not share another's runner)."""
        return self.owner == os.getpid() and self.proc.poll() is None

    def run(self, request: dict, timeout_s: float) -> dict:
        with self.turn:
            try:
                self.proc.stdin.write((json.dumps(request) + "\n").encode())
                self.proc.stdin.flush()
            except (OSError, ValueError):  # ValueError: closed by a request that found the runner dead
                self.close()
                raise SourceError(f"the {self.engine} script runner stopped unexpectedly", field="script_engine",
                                  hint=self.hint) from None
            return self._answer(timeout_s + 30.0)

    def _answer(self, timeout_s: float) -> dict:
        """The runner's next JSON line; a dead or silent runner is closed and reported."""
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout_s)
        line = self.proc.stdout.readline() if ready else b""
        try:
            answer = json.loads(line)
            if isinstance(answer, dict):
                return answer
        except ValueError:
            pass
        self._stderr.seek(0, os.SEEK_END)
        self._stderr.seek(max(0, self._stderr.tell() - 2000))
        last = (self._stderr.read().decode("utf-8", "replace").strip().splitlines() or ["no output"])[-1]
        self.close()
        raise SourceError(f"the {self.engine} runtime {self.python} failed: {last[:400]}", field="script_engine",
                          hint=self.hint)

    def close(self) -> None:
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
            self.proc.wait()
        self._stderr.close()


_RUNNERS: dict[tuple[str, str], _Runner] = {}
_RUNNERS_LOCK = threading.Lock()


def _runner(python: Path, engine: str) -> _Runner:
    """The warm runner for (interpreter, engine), started on first use and again if it died."""
    key = (str(python), engine)
    with _RUNNERS_LOCK:
        runner = _RUNNERS.get(key)
        if runner is None or not runner.alive():
            if runner is not None and runner.owner == os.getpid():
                runner.close()
            runner = _RUNNERS[key] = _Runner(python, engine)
        return runner


@atexit.register
def close_runners() -> None:
    """End every warm runner (at exit; tests may call it)."""
    with _RUNNERS_LOCK:
        for runner in _RUNNERS.values():
            if runner.owner == os.getpid():
                runner.close()
        _RUNNERS.clear()


# --------------------------------------------------------------------------- results


def _read_result(outdir: Path, status: dict, spec: CadSource, python: Path) -> dict:
    """``result.json`` of a run → its parts, or the SourceError that explains why there are none."""
    function = spec.script_function
    if status.get("timed_out"):
        raise SourceError(f"the script did not finish within {spec.script_timeout_s:g} s (script_timeout_s); "
                          "it was stopped", field="script",
                          hint="make it faster, check it for endless loops, or raise script_timeout_s")
    try:
        result = json.loads((outdir / "result.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        result = None
    if isinstance(result, dict) and isinstance(result.get("error"), dict):
        error = result["error"]
        field = error.get("field") if error.get("field") in ("script", "script_function", "script_engine") \
            else "script"
        return _raise(str(error.get("message")), field, error.get("hint") or None)
    if isinstance(result, dict) and result.get("complete") is True and isinstance(result.get("parts"), list) \
            and all(isinstance(e, dict) for e in result["parts"]):
        return result
    code, sig = status.get("exit"), status.get("signal")
    if sig:
        name = signal.Signals(sig).name if sig in signal.Signals._value2member_map_ else f"signal {sig}"
        why = _SIGNALS.get(sig, "a signal")
        hint = (f"the limit is script_memory_mb = {spec.script_memory_mb} MiB; make the script lighter or raise it"
                if sig in (signal.SIGKILL, signal.SIGABRT) else _FIX)
        return _raise(f"the script's process crashed before {function}() returned ({name}: {why})", "script", hint)
    if code == 0:
        return _raise(f"the script ended its own process (os._exit(0) or similar) before {function}() returned "
                      "its parts, so nothing was built", "script",
                      f"return the parts from {function}(); do not end the process")
    return _raise(f"the script's process exited with status {code} before {function}() returned "
                  "(os._exit, or a library that ended the process)", "script", _FIX)


def _read_files(result: dict, script: Path) -> list[Path]:
    """The files the runner's child recorded as read (``read_files``: absolute paths), the script itself left out."""
    read = result.get("read_files")
    if not isinstance(read, list):
        return []
    files = [Path(p) for p in read if isinstance(p, str) and os.path.isabs(p)]
    return [p for p in dict.fromkeys(files) if p != script]


def _raise(message: str, field: str, hint: str | None):
    raise SourceError(message, field=field, hint=hint)


def _read_part(outdir: Path, entry: dict, name: str, python: Path) -> tuple[np.ndarray, np.ndarray]:
    """A part file from the runner → ((V, 3) float64 vertices, (F, 3) int64 faces), script units."""
    try:
        count_v, count_f = int(entry["vertices"]), int(entry["faces"])
        path = outdir / Path(str(entry["file"])).name
        if path.stat().st_size != (count_v + count_f) * 24:
            raise ValueError(f"{path.name} has {path.stat().st_size} bytes, not {(count_v + count_f) * 24}")
        data = path.read_bytes()
        vertices = np.frombuffer(data, dtype="<f8", count=count_v * 3).reshape(-1, 3).astype(np.float64)
        faces = np.frombuffer(data, dtype="<i8", count=count_f * 3, offset=count_v * 24).reshape(-1, 3)
        if faces.size and (faces.min() < 0 or faces.max() >= count_v):
            raise ValueError("a face refers to a vertex that does not exist")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SourceError(f"the script runner {python} wrote an unreadable mesh for part '{name}' ({exc})",
                          field="script_engine", hint="reinstall decollage") from None
    return vertices, faces.astype(np.int64)

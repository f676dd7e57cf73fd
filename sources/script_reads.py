"""What a user's script read while it ran: the local modules it imported and the data files it opened.

Role: a script source (``sources/cad_script.py``) runs arbitrary Python, so
only watching the run tells which files its result depends on. Scripts run in
a forked child of a warm runner (``sources/script_runner.py``), so that is
where the watching happens: ``ScriptReads`` is a context manager around the
script's run in that child, and the runner sends ``files()`` back to the build
with the parts. Afterwards ``files()`` lists, first read first:

- **modules**: every module imported during the run whose file lies outside
  the Python installation and outside this project's own packages: the
  script's helpers (``helper.py`` beside it) and their local imports, however
  deep. Local modules that an earlier run imported are dropped from
  ``sys.modules`` before each run, so a helper shared by several scripts is
  read (and recorded) by each of them, and an edited helper is never served
  from an earlier import in a long-lived process (the runner's children are
  fresh forks, so there it never happens);
- **data files**: every regular file opened for reading from Python in the
  recording thread during the run (the ``open`` audit event, PEP 578), from
  the script or a library it calls (``numpy.load``...);
- **absent files**: a path the run tried to open for reading that did not
  exist (``try: open("extra.csv")``), as ``mesh.py``'s resolver records a
  missing companion: creating the file later would change the result, so the
  cache records it as absent (``pipeline/cache.py``, sha256 None).

Not recorded, as tool state rather than inputs: files of the Python
installation, of this project's packages, under ``/dev``, ``/proc`` or
``/sys``, on a hidden path (``~/.cache/...``), compiled caches, files the run
opened for writing (temporaries it made and read back), and paths that are
neither a regular file nor absent (folders, devices).

Standard library only, and no import of decollage: the runner loads this file
by its path, under this project's interpreter (build123d) or the cadquery
runtime's (``sources/script_runner.py``).
"""

from __future__ import annotations

import os
import sys
import sysconfig
import threading
from pathlib import Path

_PROJECT = Path(__file__).resolve().parents[1]
_active: list["ScriptReads"] = []
_hook_installed = False
_local_modules: set[str] = set()  # names of local modules imported by earlier runs, in this process


def _excluded_roots() -> tuple[str, ...]:
    roots = {sys.prefix, sys.base_prefix, sys.exec_prefix, sys.base_exec_prefix, "/dev", "/proc", "/sys"}
    roots.update(p for p in (sysconfig.get_paths().get(k) for k in ("stdlib", "platstdlib", "purelib", "platlib"))
                 if p)
    roots.update(str(p) for p in _PROJECT.iterdir() if (p / "__init__.py").is_file())  # this project's packages
    return tuple(sorted({os.path.realpath(r) + os.sep for r in roots}))


def _is_input(path: str, roots: tuple[str, ...], absent_too: bool = False) -> bool:
    """Whether ``path`` (absolute, real) can be a user's input rather than tool state: a regular file,
    or with ``absent_too`` nothing at all (a file the run looked for in vain)."""
    if (path + os.sep).startswith(roots) or path.endswith((".pyc", ".pyo")):
        return False
    if any(part.startswith(".") for part in Path(path).parts[1:]):
        return False
    return os.path.isfile(path) or (absent_too and not os.path.lexists(path))


def _audit(event: str, args: tuple) -> None:
    if event != "open" or not _active:
        return
    reads = _active[-1]
    if threading.get_ident() != reads.thread:
        return
    path, mode, flags = args
    if not isinstance(path, (str, bytes, os.PathLike)):
        return  # a file descriptor
    path = os.path.abspath(os.fsdecode(path))
    writes = (any(c in mode for c in "wax+") if isinstance(mode, str)
              else bool(flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT)))
    (reads.written if writes else reads.opened).append(path)


class ScriptReads:
    """Record what the code run inside ``with ScriptReads():`` read; see the module docstring."""

    def __init__(self) -> None:
        self.thread = threading.get_ident()
        self.opened: list[str] = []
        self.written: list[str] = []
        self._modules_before: set[str] = set()
        self._files: list[Path] = []

    def __enter__(self) -> "ScriptReads":
        global _hook_installed
        if not _hook_installed:  # an audit hook cannot be removed: one for the process, idle outside runs
            sys.addaudithook(_audit)
            _hook_installed = True
        for name in _local_modules:
            sys.modules.pop(name, None)
        self._modules_before = set(sys.modules)
        _active.append(self)
        return self

    def __exit__(self, *exc) -> None:
        _active.remove(self)
        roots = _excluded_roots()
        modules = []
        for name, module in list(sys.modules.items()):
            file = getattr(module, "__file__", None)
            if name not in self._modules_before and isinstance(file, str):
                real = os.path.realpath(file)
                if _is_input(real, roots):
                    _local_modules.add(name)
                    modules.append(real)
        written = {os.path.realpath(p) for p in self.written}
        data = [real for real in map(os.path.realpath, self.opened)
                if real not in written and _is_input(real, roots, absent_too=True)]
        seen: set[str] = set()
        self._files = [Path(p) for p in [*modules, *data] if not (p in seen or seen.add(p))]

    def files(self) -> list[Path]:
        """The files read, absolute: local modules first (in import order), then data files (in open order,
        absent ones among them)."""
        return list(self._files)

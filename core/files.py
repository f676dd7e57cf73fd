"""Files: atomic writes, writable-folder checks, content digests, and bounded reads of the files users name.

Role: the ground floor's file I/O, used by every room that writes something a
user keeps (assets, manifests, style sets, evaluation reports) and by every
cache key. Writes are all-or-nothing: files are written under hidden temporary
names in the target folder (same filesystem) and moved onto their final names
with ``os.replace`` only once all of them were written; a failure removes the
temporaries and raises ``ExportError``. ``check_output_folder`` checks an output
folder, its sub-folders and files before a build does any work, writing nothing.

Files a user names (recipe, font, mesh, voxel grid, checkpoint, style set,
script) go through ``check_input_file`` / ``read_input_bytes`` (or
``input_file`` for paths inside a recipe): the path must be an existing,
readable regular file (not a folder, device, pipe or socket) no larger than
its kind's limit (``INPUT_LIMITS_MB``, raised per kind with an environment
variable such as ``DECOLLAGE_MAX_MESH_MB``), checked before a byte is read.
"""

from __future__ import annotations

import hashlib
import itertools
import os
import stat
import threading
from enum import Enum
from pathlib import Path
from types import TracebackType

from core.errors import DecollageError, ExportError, SourceError, UsageError

_WRITABLE_HINT = "choose another output folder (--out) or fix its permissions"

# Unique temporary names within this process; pid separates processes.
_temp_counter = itertools.count()
_temp_lock = threading.Lock()
# Threads whose commits are refused (``forbid_commits``); commits and changes to the set are serialised.
_commit_lock = threading.Lock()
_forbidden: set[int] = set()


# --------------------------------------------------------------------------- atomic writing


class AtomicWriter:
    """Write several files so that either all of them appear, or none.

    Usage::

        with AtomicWriter(out_dir) as writer:
            writer.add(out_dir / "a.glb", glb_bytes)   # written to a temp file now
            writer.add(out_dir / "a.stl", stl_bytes)
        # leaving the block without an exception moves all of them into place;
        # an exception removes the temporaries and propagates
        # (an OSError is turned into ExportError).

    Files must live in ``out_dir`` so that ``os.replace`` is an atomic rename.
    """

    def __init__(self, out_dir: Path) -> None:
        self.out_dir = Path(out_dir)
        self._pending: list[tuple[Path, Path]] = []  # (temporary, final)

    def add(self, path: Path, data: bytes) -> None:
        """Write ``data`` to a temporary file that ``commit`` will move onto ``path``."""
        path = Path(path)
        if path.parent.resolve() != self.out_dir.resolve():
            raise ValueError(f"{path} is not directly inside {self.out_dir}")
        if any(final == path for _, final in self._pending):
            raise ValueError(f"{path} was added twice")
        with _temp_lock:
            serial = next(_temp_counter)
        temp = path.with_name(f".{path.name}.{os.getpid()}.{serial}.tmp")
        try:
            # O_EXCL: never write through someone else's file; 0o666 lets the
            # umask decide the final permissions, as for any normal file.
            fd = os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except OSError as exc:
            raise _os_error(exc, path) from None
        self._pending.append((temp, path))
        try:
            with os.fdopen(fd, "wb") as handle:
                handle.write(data)
                handle.flush()
                # Make the content durable before the rename can be.
                os.fsync(handle.fileno())
        except OSError as exc:
            raise _os_error(exc, path) from None

    def commit(self) -> list[Path]:
        """Move every temporary onto its final name; returns the final paths.

        Should a rename fail half-way (it practically cannot within one
        folder), the files already moved are removed too, so the asset is left
        with none of its new files rather than a mixture (an older file they
        had replaced is gone as well: a clean absence, never a mixed set).
        """
        placed: list[Path] = []
        with _commit_lock:  # ``forbid_commits`` waits for a commit in progress, never splits it
            if threading.get_ident() in _forbidden:
                self.discard()
                raise ExportError("not written: the build was interrupted", file=self.out_dir,
                                  hint="build again to finish it")
            for temp, final in self._pending:
                try:
                    os.replace(temp, final)
                except OSError as exc:
                    for done in placed:
                        _remove_quietly(done)
                    self.discard()
                    raise _os_error(exc, final) from None
                placed.append(final)
        done = [final for _, final in self._pending]
        self._pending = []
        return done

    def discard(self) -> None:
        """Remove all temporaries that were not moved into place."""
        for temp, _ in self._pending:
            _remove_quietly(temp)
        self._pending = []

    def __enter__(self) -> "AtomicWriter":
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()


def forbid_commits(thread_id: int) -> None:
    """Refuse every later ``commit`` from thread ``thread_id``; waits for a commit in progress to end.

    An interrupted build calls this for work it abandons in another thread (a kernel cannot be
    stopped mid-call) before it writes its manifest, so that work can never land a file
    afterwards: its next ``commit`` discards its temporaries and raises ``ExportError``.
    """
    with _commit_lock:
        _forbidden.add(thread_id)


def allow_commits(thread_id: int) -> None:
    """Undo ``forbid_commits`` (the abandoned thread calls it as it ends)."""
    with _commit_lock:
        _forbidden.discard(thread_id)


def write_bytes_atomic(path: Path, data: bytes) -> None:
    """Write one file atomically (temporary file + rename). Raises ExportError."""
    path = Path(path)
    with AtomicWriter(path.parent) as writer:
        writer.add(path, data)


def ensure_writable_dir(path: Path) -> None:
    """Create ``path`` (and parents) if missing and check that files can be written in it.

    The check writes and deletes a real probe file, which also catches
    read-only mounts and ACLs that permission bits do not show.

    Raises:
        ExportError: the folder cannot be created or written.
    """
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise ExportError("output directory is not writable: a file with this name exists",
                          file=path, hint=_WRITABLE_HINT) from None
    except OSError as exc:
        raise ExportError(f"output directory is not writable: {exc.strerror or exc}",
                          file=path, hint=_WRITABLE_HINT) from None
    probe = path / f".decollage-probe.{os.getpid()}.{threading.get_ident()}"
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        try:
            os.write(fd, b"probe")
        finally:
            os.close(fd)
    except OSError as exc:
        raise ExportError(f"output directory is not writable: {exc.strerror or exc}",
                          file=path, hint=_WRITABLE_HINT) from None
    finally:
        _remove_quietly(probe)


def check_output_folder(out_dir: Path, *, folders: tuple[str, ...] = (), files: tuple[str, ...] = ()) -> None:
    """Check, writing nothing, that a build can write ``out_dir``, its sub-folders ``folders`` and files ``files``.

    ``out_dir`` must be a folder or not exist yet (then its nearest existing parent must be a
    writable folder); each of ``folders`` a writable folder or missing; each of ``files`` a
    regular file or missing. Writability is tested with a probe file created and removed at once
    (it sees read-only mounts that permission bits do not show), so "writing nothing" means no
    file is left behind.

    Raises:
        ExportError: naming the first path that is of the wrong kind or not writable.
    """
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ExportError("the output folder is a file", file=out_dir, hint=_WRITABLE_HINT)
    if not out_dir.exists():
        parent = out_dir.parent
        while not parent.exists() and parent != parent.parent:
            parent = parent.parent
        if not parent.is_dir():
            raise ExportError(f"the output folder cannot be created: {parent} is a file", file=out_dir,
                              hint=_WRITABLE_HINT)
        _probe(parent, out_dir)
        return
    _probe(out_dir, out_dir)
    for name in folders:
        folder = out_dir / name
        if folder.exists() or folder.is_symlink():
            if not folder.is_dir():
                raise ExportError("this must be a folder (the build keeps its records there), but it is a file",
                                  file=folder, hint="remove or rename the file, or choose another --out")
            _probe(folder, folder)
    for name in files:
        path = out_dir / name
        if (path.exists() or path.is_symlink()) and not path.is_file():
            raise ExportError("this must be a file (the build writes it), but it is a folder or something else",
                              file=path, hint="remove or rename it, or choose another --out")


def _probe(folder: Path, named: Path) -> None:
    """Create and remove a probe file in ``folder``; ExportError naming ``named`` when that fails."""
    probe = folder / f".decollage-probe.{os.getpid()}.{threading.get_ident()}"
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        os.close(fd)
    except OSError as exc:
        raise ExportError(f"not writable: {exc.strerror or exc}", file=named, hint=_WRITABLE_HINT) from None
    finally:
        _remove_quietly(probe)


def _os_error(exc: OSError, path: Path) -> ExportError:
    return ExportError(f"could not write: {exc.strerror or exc}", file=path,
                       hint="check free disk space and the folder's permissions")


def _remove_quietly(path: Path) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass
    except OSError:
        pass  # best effort: the caller is already reporting the real failure


# --------------------------------------------------------------------------- digests


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def code_digest(*modules: str) -> str:
    """sha256 of project source files given relative to the repository root (``"geometry/voxelize.py"``).

    Part of cache keys whose results depend on that code: an edit to any of them
    changes the key; other files do not matter.
    """
    root = Path(__file__).resolve().parent.parent
    digest = hashlib.sha256()
    for rel in modules:
        digest.update(rel.encode() + b"\0" + (root / rel).read_bytes() + b"\0")
    return digest.hexdigest()


# --------------------------------------------------------------------------- input files

#: The hint of every "not found" error for a path a recipe names.
RELATIVE_HINT = "the path is relative to the recipe's folder"


class InputKind(Enum):
    """The kinds of file a user names, each with its own size limit (``INPUT_LIMITS_MB``)."""

    RECIPE = "recipe"
    FONT = "font"
    MESH = "mesh"
    VOXELS = "voxels"
    VOX = "vox"
    CHECKPOINT = "checkpoint"
    STYLE_SET = "style set"
    SCRIPT = "script"

    @property
    def env_var(self) -> str:
        """The environment variable that raises this kind's limit, in MiB (``DECOLLAGE_MAX_MESH_MB``)."""
        return f"DECOLLAGE_MAX_{self.name}_MB"


#: Largest file of each kind that is read, in MiB (2**20 bytes); ``InputKind.env_var`` raises a limit.
#: Chosen so that reading and parsing the largest allowed file stays within a few GB of memory:
#: a recipe is text (a real one is a few KB; the YAML reader parses ~1 MB/s); a 128 MB font fits the
#: largest CJK collections; a 256 MB mesh is ~5 M binary-STL triangles; a voxel file holds at most
#: 512 MB of array data once decompressed, a .vox file 512 MB (a full 256³ model is 64 MB); the shipped checkpoint is 4.2 MB; a 256³ style set of 32
#: exemplars is ~40 MB compressed; a script is Python source.
INPUT_LIMITS_MB: dict[InputKind, int] = {
    InputKind.RECIPE: 1,
    InputKind.FONT: 128,
    InputKind.MESH: 256,
    InputKind.VOXELS: 512,
    InputKind.VOX: 512,
    InputKind.CHECKPOINT: 512,
    InputKind.STYLE_SET: 1024,
    InputKind.SCRIPT: 16,
}

_FILE_TYPES = ((stat.S_ISDIR, "a folder"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
               (stat.S_ISFIFO, "a named pipe"), (stat.S_ISSOCK, "a socket"))


def input_limit_bytes(kind: InputKind) -> int:
    """The size limit of ``kind`` in bytes: ``INPUT_LIMITS_MB``, or the MiB in ``kind.env_var`` when set.

    An unusable value in the variable (not a positive number) is a ``UsageError``.
    """
    raw = os.environ.get(kind.env_var)
    if raw is None or not raw.strip():
        return INPUT_LIMITS_MB[kind] << 20
    try:
        mb = float(raw)
    except ValueError:
        mb = float("nan")
    if not (mb > 0 and mb < 1 << 40):
        raise UsageError(f"{kind.env_var}={raw!r} is not a size in MB", field=kind.env_var,
                         hint="give a positive number of MiB, e.g. 512")
    return int(mb * (1 << 20))


def _describe_size(size: int) -> str:
    return f"{size / (1 << 20):,.1f} MB" if size >= 1 << 20 else f"{size:,} bytes"


def check_input_file(path: str | Path, kind: InputKind, *, error: type[DecollageError] = SourceError,
                     field: str | None = None, file: str | Path | None = None) -> Path:
    """Check, without reading it, that ``path`` is a readable regular file within ``kind``'s size limit.

    Symbolic links are followed (a link to ``/dev/zero`` is a device). Returns ``path`` as given.

    Raises:
        ``error`` (a ``DecollageError`` class) with ``field``/``file``: missing, not a regular file
        (folder, device, pipe, socket), larger than the limit (naming it and ``kind.env_var``),
        or unreadable.
    """
    path = Path(path)
    noun = kind.value
    try:
        info = os.stat(path)
    except FileNotFoundError:
        hint = "check the path" if kind is InputKind.RECIPE else RELATIVE_HINT
        raise error(f"{noun} file not found: {path}", file=file, field=field, hint=hint) from None
    except OSError as exc:
        raise error(f"cannot read the {noun} file {path}: {exc.strerror or exc}", file=file, field=field) from None
    if not stat.S_ISREG(info.st_mode):
        what = next((name for test, name in _FILE_TYPES if test(info.st_mode)), "not a regular file")
        raise error(f"{path} is {what}, not a {noun} file", file=file, field=field,
                    hint=f"name a regular {noun} file")
    limit = input_limit_bytes(kind)
    if info.st_size > limit:
        raise error(f"the {noun} file {path} is {_describe_size(info.st_size)}, more than the "
                    f"{limit / (1 << 20):.4g} MB limit for {noun} files", file=file, field=field,
                    hint=f"use a smaller file, or raise the limit with {kind.env_var}=<MB>")
    if not os.access(path, os.R_OK):
        raise error(f"cannot read the {noun} file {path}: permission denied", file=file, field=field,
                    hint="fix the file's permissions")
    return path


def read_input_bytes(path: str | Path, kind: InputKind, *, error: type[DecollageError] = SourceError,
                     field: str | None = None, file: str | Path | None = None) -> bytes:
    """The bytes of a user's file after ``check_input_file``; never reads more than the limit.

    A file that grows past the limit while it is read (or a special file that reports a size of 0)
    is refused like an oversized one.
    """
    path = check_input_file(path, kind, error=error, field=field, file=file)
    limit = input_limit_bytes(kind)
    try:
        with open(path, "rb") as handle:
            data = handle.read(limit + 1)
    except OSError as exc:
        raise error(f"cannot read the {kind.value} file {path}: {exc.strerror or exc}", file=file,
                    field=field) from None
    if len(data) > limit:
        raise error(f"the {kind.value} file {path} is larger than the {limit / (1 << 20):.4g} MB limit for "
                    f"{kind.value} files", file=file, field=field,
                    hint=f"use a smaller file, or raise the limit with {kind.env_var}=<MB>")
    return data


def resolve_relative(relative: str | Path, base_dir: Path) -> Path:
    """A path a recipe names (``~`` expanded), joined to the recipe's folder unless absolute; not checked."""
    path = Path(relative).expanduser()
    return path if path.is_absolute() else Path(base_dir) / path


def input_file(relative: str | Path, base_dir: Path, *, field: str, noun: str, hint: str,
               kind: InputKind) -> Path:
    """The absolute path of an input file a recipe names: an existing, readable regular file within ``kind``'s limit.

    Args:
        relative: the recipe's value (relative to ``base_dir`` unless absolute).
        base_dir: the recipe's folder.
        field: the recipe field, for the error (e.g. ``"path"``).
        noun: what the file is, for the messages (``"file"``, ``"script"``, ``"font file"``).
        hint: how to fix a path that names something other than a file.
        kind: the kind of file, whose size limit applies (``INPUT_LIMITS_MB``).
    Raises:
        SourceError: missing, not a regular file (folder, device, pipe), too large, or unreadable.
    """
    path = resolve_relative(relative, base_dir).resolve()
    if not path.exists():
        raise SourceError(f"{noun} not found: {path}", field=field, hint=RELATIVE_HINT)
    if path.is_dir():
        raise SourceError(f"not a {noun}: {path}", field=field, hint=hint)
    return check_input_file(path, kind, field=field)

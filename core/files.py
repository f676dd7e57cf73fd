"""Files: atomic writes, writable-folder checks and content digests.

Role: the ground floor's file I/O, used by every room that writes something a
user keeps (assets, manifests, style sets, evaluation reports) and by every
cache key. Writes are all-or-nothing: files are written under hidden temporary
names in the target folder (same filesystem) and moved onto their final names
with ``os.replace`` only once all of them were written; a failure removes the
temporaries and raises ``ExportError``.
"""

from __future__ import annotations

import hashlib
import itertools
import os
import threading
from pathlib import Path
from types import TracebackType

from core.errors import ExportError, SourceError

_WRITABLE_HINT = "choose another output folder (--out) or fix its permissions"

# Unique temporary names within this process; pid separates processes.
_temp_counter = itertools.count()
_temp_lock = threading.Lock()


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


# --------------------------------------------------------------------------- input paths

#: The hint of every "not found" error for a path a recipe names.
RELATIVE_HINT = "the path is relative to the recipe's folder"


def resolve_relative(relative: str | Path, base_dir: Path) -> Path:
    """A path a recipe names (``~`` expanded), joined to the recipe's folder unless absolute; not checked."""
    path = Path(relative).expanduser()
    return path if path.is_absolute() else Path(base_dir) / path


def input_file(relative: str | Path, base_dir: Path, *, field: str, noun: str, hint: str) -> Path:
    """The absolute path of an input file a recipe names, which must exist and be a file.

    Args:
        relative: the recipe's value (relative to ``base_dir`` unless absolute).
        base_dir: the recipe's folder.
        field: the recipe field, for the error (e.g. ``"path"``).
        noun: what the file is, for the messages (``"file"``, ``"script"``, ``"font file"``).
        hint: how to fix a path that names something other than a file.
    Raises:
        SourceError: missing, or not a regular file.
    """
    path = resolve_relative(relative, base_dir).resolve()
    if not path.exists():
        raise SourceError(f"{noun} not found: {path}", field=field, hint=RELATIVE_HINT)
    if not path.is_file():
        raise SourceError(f"not a {noun}: {path}", field=field, hint=hint)
    return path

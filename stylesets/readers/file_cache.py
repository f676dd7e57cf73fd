"""Per-process caching of what is read from a file, keyed by the file's identity (path, size, mtime).

Exemplar sets read the same large file (a catalogue zip, an OBJ) once per
exemplar; ``cached_per_file`` reads it once per process and again only when the
file changes on disk.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Callable, TypeVar

T = TypeVar("T")


def cached_per_file(maxsize: int) -> Callable[[Callable[..., T]], Callable[..., T]]:
    """Decorator for ``fn(path: Path, *args)``: results cached per (resolved path, size, mtime_ns, *args).

    ``path.stat()`` errors (OSError) propagate to the caller; ``args`` must be hashable.
    """
    def wrap(fn: Callable[..., T]) -> Callable[..., T]:
        @functools.lru_cache(maxsize=maxsize)
        def keyed(path: str, size: int, mtime_ns: int, *args) -> T:
            return fn(Path(path), *args)

        @functools.wraps(fn)
        def cached(path, *args) -> T:
            path = Path(path).resolve()
            stat = path.stat()
            return keyed(str(path), stat.st_size, stat.st_mtime_ns, *args)

        cached.cache_clear = keyed.cache_clear  # type: ignore[attr-defined]
        return cached
    return wrap

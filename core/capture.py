"""Warnings from libraries, caught while an asset builds and reported once, counted, in the project's words.

Role: ``captured_warnings(notes)`` is a context manager around one asset's
build. Inside it every ``warnings.warn`` (any category, any module, each
occurrence: the filter is "always") and every log record of level WARNING or
above that reaches the root logger (trimesh, PIL, ...) is caught instead of
being printed; on leaving, one line per distinct warning is appended to ``notes``
(the asset's manifest warnings), e.g.::

    numpy warned 3 times: overflow encountered in multiply (RuntimeWarning)
    trimesh warned: face normals didn't match (log)

The library is named by the top-level package of the file or logger that
warned (a warning numpy raises on behalf of its caller names the caller).
Lines are in first-seen order, messages are cut to one line of at most
``MAX_NOTE_CHARS`` characters, and at most ``MAX_NOTES`` distinct warnings are
listed (then one line says how many more kinds there were).
Warnings raised by the project's own packages are reported the same way.
Nothing is printed. Not thread-safe (``warnings.catch_warnings`` is not):
builds run one asset at a time per process.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

#: Longest message kept per warning, characters.
MAX_NOTE_CHARS: int = 200
#: Most distinct warnings listed per asset.
MAX_NOTES: int = 20


_PROJECT_ROOT = Path(__file__).resolve().parents[1]


def _library_of_file(filename: str) -> str:
    """``.../site-packages/numpy/core/x.py`` → ``numpy``; this project's ``pipeline/mesh.py`` → ``decollage
    (pipeline/mesh.py)``; anything else → the file's name."""
    path = Path(filename)
    parts = path.parts
    for marker in ("site-packages", "dist-packages"):
        if marker in parts:
            index = parts.index(marker)
            if index + 1 < len(parts):
                return parts[index + 1].removesuffix(".py").split("-")[0]
    try:
        return f"decollage ({path.resolve().relative_to(_PROJECT_ROOT).as_posix()})"
    except (ValueError, OSError):
        return path.name or "python"


def _one_line(text: str) -> str:
    line = " ".join(str(text).split())
    return line if len(line) <= MAX_NOTE_CHARS else line[: MAX_NOTE_CHARS - 1] + "…"


class _Collector(logging.Handler):
    def __init__(self) -> None:
        super().__init__(level=logging.WARNING)
        self.counts: dict[tuple[str, str, str], int] = {}

    def add(self, library: str, message: str, kind: str) -> None:
        key = (library, _one_line(message), kind)
        self.counts[key] = self.counts.get(key, 0) + 1

    def emit(self, record: logging.LogRecord) -> None:
        try:
            message = record.getMessage()
        except Exception:  # noqa: BLE001 - a library's bad format string must not break the build
            message = str(record.msg)
        self.add(record.name.split(".")[0] or "python", message, "log")

    def notes(self) -> list[str]:
        out = []
        for (library, message, kind), count in self.counts.items():
            times = f" {count} times" if count > 1 else ""
            out.append(f"{library} warned{times}: {message} ({kind})")
        if len(out) > MAX_NOTES:
            out = out[:MAX_NOTES] + [f"… and {len(out) - MAX_NOTES} more kinds of library warnings"]
        return out


@contextmanager
def captured_warnings(notes: list[str]) -> Iterator[None]:
    """Catch library warnings and log records inside the block; append their counted summary to ``notes``."""
    collector = _Collector()
    root = logging.getLogger()
    root.addHandler(collector)  # records that reach the root no longer fall through to logging's stderr printer
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                yield
            finally:
                for item in caught:
                    collector.add(_library_of_file(item.filename), str(item.message), item.category.__name__)
    finally:
        root.removeHandler(collector)
        notes.extend(collector.notes())

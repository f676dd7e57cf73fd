"""The one error hierarchy of decollage.

Library code raises these; only ``cli/app.py`` prints them and maps them
to exit codes. Every error carries enough context for a one-line message of
the form ``<file>: <field path>: <what is wrong> (<how to fix it>)``.
"""

from __future__ import annotations

from pathlib import Path


class DecollageError(Exception):
    """Base class of every error this project raises on purpose.

    Attributes:
        message: what is wrong, in one sentence, without location.
        file: the file the problem was found in (recipe, mesh, font...), if any.
        field: dotted/indexed path inside that file, e.g. ``assets[2].source.font``.
        hint: how to fix it, if we know.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | Path | None = None,
        field: str | None = None,
        hint: str | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.file = str(file) if file is not None else None
        self.field = field
        self.hint = hint

    def located(self, *, file: str | Path | None = None, field: str | None = None) -> "DecollageError":
        """Fill in location details that the raiser could not know; returns self."""
        if self.file is None and file is not None:
            self.file = str(file)
        if self.field is None and field is not None:
            self.field = field
        return self

    def one_line(self) -> str:
        """The user-facing message: ``file: field: message (hint)``."""
        parts = [p for p in (self.file, self.field) if p]
        text = ": ".join([*parts, self.message])
        if self.hint:
            text += f" ({self.hint})"
        return " ".join(text.split("\n"))

    def __str__(self) -> str:  # pragma: no cover - exercised through one_line
        return self.one_line()


class RecipeError(DecollageError):
    """The recipe file is unreadable, not YAML, or fails the schema."""


class SourceError(DecollageError):
    """A source could not produce parts: missing/corrupt font or mesh, bad script, empty text."""


class VoxelizeError(DecollageError):
    """Parts could not be turned into a labeled grid (e.g. nothing occupied)."""


class DetailizeError(DecollageError):
    """The detailizer could not be loaded or refused its input."""


class MeshingError(DecollageError):
    """Marching cubes, smoothing or decimation failed (e.g. empty field)."""


class ExportError(DecollageError):
    """Outputs could not be written (unwritable directory, disk full...)."""


class UsageError(DecollageError):
    """The command line itself is wrong (bad option combination, missing file)."""


class StudioError(DecollageError):
    """The studio (``decollage view`` / ``paint``) refuses a request or cannot do it (bad path, save refused)."""


class LockedError(DecollageError):
    """Another build holds the output folder's lock (``pipeline/lock.py``)."""


class AbandonedError(DecollageError):
    """The build that asked for an asset no longer holds the output folder (it was killed or
    interrupted), so the asset's files are not written."""

"""Strict reading and writing of plain JSON objects (the model config's checkpoint form).

``to_plain`` turns frozen dataclasses, enums and tuples into dicts, strings and lists;
``Reader`` reads one JSON object back key by key without coercing types, and ``done``
refuses keys nobody read. Every failure is a ``DetailizeError`` whose ``field`` is the
dotted path inside the object (e.g. ``config.levels[3].width``).
"""

from __future__ import annotations

import dataclasses
from enum import Enum
from typing import Any

from core.errors import DetailizeError


def bad(message: str, field_: str, hint: str) -> DetailizeError:
    """A ``DetailizeError`` for a bad value at dotted path ``field_``."""
    return DetailizeError(message, field=field_, hint=hint)


def to_plain(obj: Any) -> Any:
    """``obj`` as plain JSON types: dataclasses → dicts, enums → their values, tuples → lists."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, Enum):
        return obj.value
    if isinstance(obj, (tuple, list)):
        return [to_plain(x) for x in obj]
    return obj


_MISSING = object()


class Reader:
    """Strict reader of one JSON object: every key must be read exactly once, types are not coerced."""

    def __init__(self, data: Any, path: str) -> None:
        if not isinstance(data, dict):
            raise bad(f"expected an object, got {type(data).__name__}", path, "re-save the checkpoint")
        self.data, self.path, self.seen = data, path, set()

    def get(self, key: str, default: Any = _MISSING) -> Any:
        """The value of ``key``; a missing key is an error unless a ``default`` is given (keys added later)."""
        if key not in self.data:
            if default is not _MISSING:
                return default
            raise bad(f"missing key {key!r}", f"{self.path}.{key}", "the checkpoint is from another version")
        self.seen.add(key)
        return self.data[key]

    def int(self, key: str, default: Any = _MISSING) -> int:
        v = self.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int):
            raise bad(f"expected an integer, got {v!r}", f"{self.path}.{key}", "use an integer")
        return v

    def float(self, key: str, default: Any = _MISSING) -> float:
        v = self.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise bad(f"expected a number, got {v!r}", f"{self.path}.{key}", "use a number")
        return float(v)

    def bool(self, key: str, default: Any = _MISSING) -> bool:
        v = self.get(key, default)
        if not isinstance(v, bool):
            raise bad(f"expected true/false, got {v!r}", f"{self.path}.{key}", "use a boolean")
        return v

    def list(self, key: str) -> list:
        v = self.get(key)
        if not isinstance(v, list):
            raise bad(f"expected a list, got {v!r}", f"{self.path}.{key}", "use a list")
        return v

    def float_list(self, key: str, default: Any = _MISSING) -> list[float]:
        v = self.get(key, default)
        if not isinstance(v, list):
            raise bad(f"expected a list, got {v!r}", f"{self.path}.{key}", "use a list")
        for i, x in enumerate(v):
            if isinstance(x, bool) or not isinstance(x, (int, float)):
                raise bad(f"expected a number, got {x!r}", f"{self.path}.{key}[{i}]", "use numbers")
        return [float(x) for x in v]

    def int_list(self, key: str) -> list[int]:
        v = self.list(key)
        for i, x in enumerate(v):
            if isinstance(x, bool) or not isinstance(x, int):
                raise bad(f"expected an integer, got {x!r}", f"{self.path}.{key}[{i}]", "use integers")
        return v

    def enum(self, key: str, kind: type[Enum], default: Any = _MISSING) -> Any:
        v = self.get(key, default)
        try:
            return kind(v)
        except ValueError:
            allowed = ", ".join(m.value for m in kind)  # type: ignore[attr-defined]
            raise bad(f"unknown value {v!r}", f"{self.path}.{key}", f"use one of: {allowed}") from None

    def done(self) -> None:
        extra = sorted(set(self.data) - self.seen)
        if extra:
            raise bad(f"unknown key {extra[0]!r}", f"{self.path}.{extra[0]}", "remove it or update decollage")

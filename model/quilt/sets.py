"""Which style set quilt copies from, and how a grid's style and part names map onto it.

Role: resolve the set a recipe names (``detailize: {detailizer: quilt,
style_set: <set>}``; none = ``DEFAULT_SET``) into a loaded ``StyleSet``, and
map a ``LabeledGrid``'s style names (exemplar names) and part names (the set's
vocabulary or a category's aliases, e.g. ``roof`` = ``top``) onto it. Every
failure is a one-line ``DetailizeError`` that says what to do.

A set is named by

* a built-in set name (``things``, ``furniture``...): built into the styles
  folder the first time (``decollage styles build``; about 40 s for
  ``things``), then read from there;
* the name of a set made by ``decollage styles import`` (``<styles dir>/<name>.npz``);
* a ``.npz`` set file. (The build resolves a recipe's ``style_set`` against
  the recipe's folder, so a bare name arrives as ``<recipe dir>/<name>``: when
  no such file exists its last component is taken as the set name.)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from core.errors import DecollageError, DetailizeError
from stylesets.format import StyleSet, build_set, load_set, set_path
from stylesets.registry import BUILTIN_SETS, builtin_set

#: The set quilt copies from when a recipe names none (the one the shipped model was trained on).
DEFAULT_SET = "things"

_SET_HINT = ("name a built-in set (" + ", ".join(BUILTIN_SETS) + "), a set made with "
             "'decollage styles import FOLDER --name NAME', or a .npz set file")


def __getattr__(name: str):
    """``DEFAULT_SET_FILE``: where the default set's file is (read when the pipeline keys a build's cache)."""
    if name == "DEFAULT_SET_FILE":
        return set_path(DEFAULT_SET)
    raise AttributeError(name)


def _as_detailize_error(exc: DecollageError) -> DetailizeError:
    message = f"{exc.file}: {exc.message}" if exc.file else exc.message
    return DetailizeError(f"style set for 'quilt': {message}", field="style_set", hint=exc.hint or _SET_HINT)


def resolve_style_set(spec: str | Path | None) -> StyleSet:
    """The ``StyleSet`` named by ``spec`` (see module docstring); DetailizeError if there is none."""
    name = DEFAULT_SET if spec is None else str(spec)
    try:
        if name in BUILTIN_SETS:
            vocab, specs = builtin_set(name)
            return build_set(name, vocab, specs, workers=2).style_set
        path = Path(name)
        if path.is_file():
            return load_set(path)
        if path.suffix != ".npz":
            if path.name in BUILTIN_SETS:
                return resolve_style_set(path.name)
            if set_path(path.name).is_file():
                return load_set(set_path(path.name))
    except DecollageError as exc:
        raise _as_detailize_error(exc) from None
    shown = name if Path(name).suffix == ".npz" else Path(name).name  # a bare name arrives as <recipe dir>/<name>
    raise DetailizeError(f"unknown style set {shown!r} for 'quilt'", field="style_set", hint=_SET_HINT)


def check_set(style_set: StyleSet) -> None:
    """DetailizeError unless the set has exemplars on a grid quilt can cut into 16³ cells."""
    if not style_set.exemplars:
        raise DetailizeError(f"style set '{style_set.name}' has no exemplars", field="style_set",
                             hint="import at least one mesh with 'decollage styles import', or use a built-in set")
    if style_set.resolution % 16 or style_set.resolution < 16:
        raise DetailizeError(f"style set '{style_set.name}' has resolution {style_set.resolution}, "
                             "not a multiple of 16", field="style_set", hint="rebuild it at 256")


def accepted_parts(style_set: StyleSet) -> tuple[str, ...]:
    """Every part name the set accepts: its vocabulary, then the categories' aliases."""
    vocab = style_set.vocabulary
    return tuple(dict.fromkeys([*vocab.parts, *vocab.accepted()]))


def map_styles(names: tuple[str, ...], used: np.ndarray, style_set: StyleSet) -> np.ndarray:
    """Grid style indices → exemplar indices of the set (−1 for unused names); unknown used names raise."""
    index = {ex.name: i for i, ex in enumerate(style_set.exemplars)}
    unknown = [names[i] for i in used if names[i] not in index]
    if unknown:
        known = ", ".join(index)
        raise DetailizeError(f"unknown style {unknown[0]!r} for set '{style_set.name}' (known: {known})",
                             field="style", hint="use one of the set's exemplar names, or another style set")
    return np.array([index.get(n, -1) for n in names] or [-1], dtype=np.int64)


def map_parts(names: tuple[str, ...], used: np.ndarray, style_set: StyleSet) -> np.ndarray:
    """Grid part indices → vocabulary part indices (aliases accepted); unknown used names raise."""
    vocab = style_set.vocabulary
    out = np.full(max(1, len(names)), -1, dtype=np.int64)
    for i, name in enumerate(names):
        try:
            out[i] = vocab.index(name)
        except KeyError:
            if i in used:
                raise DetailizeError(f"unknown part {name!r} for set '{style_set.name}' "
                                     f"(known: {', '.join(vocab.accepted())})", field="part",
                                     hint="use one of the set's part names or their aliases") from None
    return out

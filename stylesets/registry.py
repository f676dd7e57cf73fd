"""Built-in style exemplar sets: ``furniture`` (chairs, tables), ``things`` (buildings, plants, cakes,
crystals), ``monastery`` (real temple buildings read from the installed PyPI package ``pybullet``) and
``sweethome`` (real chairs and tables read from the installed Debian package ``sweethome3d-furniture``).

Role: the registry ``BUILTIN_SETS``: set name → (vocabulary, function giving
the ``ExemplarSpec`` list). Specs are cheap to list; meshes are only made when
``stylesets.format.make_exemplar`` calls ``spec.make()``.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Callable

from stylesets.catalogues.furniture import CHAIRS, TABLES, chair_parts, table_parts
from stylesets.catalogues.things import THINGS_CATALOGUE
from stylesets.format import (
    FURNITURE,
    THINGS,
    ExemplarError,
    ExemplarSpec,
    StyleSet,
    Vocabulary,
    build_set,
    load_set,
    set_path,
)
from stylesets.readers.monastery import monastery_specs
from stylesets.readers.sweethome import sweethome_specs


def furniture_specs() -> list[ExemplarSpec]:
    """16 chairs + 16 tables, procedural."""
    specs = [ExemplarSpec(name, "chair", partial(chair_parts, d), repr(d)) for name, d in CHAIRS.items()]
    specs += [ExemplarSpec(name, "table", partial(table_parts, d), repr(d)) for name, d in TABLES.items()]
    return specs


def things_specs() -> list[ExemplarSpec]:
    """Buildings, plants, cakes and crystals, procedural."""
    return [ExemplarSpec(name, category, partial(fn, **kw), f"{fn.__name__}{sorted(kw.items())}")
            for name, (category, fn, kw) in THINGS_CATALOGUE.items()]


BUILTIN_SETS: dict[str, tuple[Vocabulary, Callable[[], list[ExemplarSpec]]]] = {
    "furniture": (FURNITURE, furniture_specs),
    "things": (THINGS, things_specs),
    "monastery": (THINGS, monastery_specs),  # ExemplarError when pybullet is not installed
    "sweethome": (FURNITURE, sweethome_specs),  # ExemplarError when sweethome3d-furniture is not installed
}


def builtin_set(name: str) -> tuple[Vocabulary, list[ExemplarSpec]]:
    """(vocabulary, specs) of a built-in set; ExemplarError for an unknown name."""
    if name not in BUILTIN_SETS:
        raise ExemplarError(f"unknown style set '{name}'", field="set",
                            hint="built-in sets: " + ", ".join(BUILTIN_SETS))
    vocab, specs = BUILTIN_SETS[name]
    return vocab, specs()


def resolve_style_set(name_or_path: str, progress=None) -> StyleSet:
    """A style set by name or file → ``StyleSet``.

    A built-in name is built into ``style_dir()`` if needed (cached); another name is
    a set imported there before (``decollage styles import``); else a ``.npz`` path.
    """
    if name_or_path in BUILTIN_SETS:
        vocab, specs = builtin_set(name_or_path)
        return build_set(name_or_path, vocab, specs, workers=2, progress=progress).style_set
    path = Path(name_or_path)
    if path.suffix != ".npz" and not path.exists():
        if set_path(name_or_path).is_file():
            return load_set(set_path(name_or_path))
        raise ExemplarError(f"unknown style set '{name_or_path}'", field="set",
                            hint="built-in sets: " + ", ".join(BUILTIN_SETS)
                                 + "; a set imported with 'decollage styles import'; or a .npz set file")
    return load_set(path)

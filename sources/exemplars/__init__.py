"""Built-in style exemplar sets: ``furniture`` (chairs, tables), ``things`` (buildings, plants, cakes,
crystals), ``monastery`` (real temple buildings read from the installed PyPI package ``pybullet``) and
``sweethome`` (real chairs and tables read from the installed Debian package ``sweethome3d-furniture``).

Role: the registry ``BUILTIN_SETS``: set name → (vocabulary, function giving
the ``ExemplarSpec`` list). Specs are cheap to list; meshes are only made when
``pipeline.exemplars.make_exemplar`` calls ``spec.make()``.
"""

from __future__ import annotations

from functools import partial
from typing import Callable

from pipeline.exemplars import FURNITURE, THINGS, ExemplarError, ExemplarSpec, Vocabulary


def furniture_specs() -> list[ExemplarSpec]:
    """16 chairs + 16 tables, procedural."""
    from sources.exemplars.furniture import CHAIRS, TABLES, chair_parts, table_parts

    specs = [ExemplarSpec(name, "chair", partial(chair_parts, d), repr(d)) for name, d in CHAIRS.items()]
    specs += [ExemplarSpec(name, "table", partial(table_parts, d), repr(d)) for name, d in TABLES.items()]
    return specs


def things_specs() -> list[ExemplarSpec]:
    """Buildings, plants, cakes and crystals, procedural."""
    try:
        from sources.exemplars.things import THINGS_CATALOGUE
    except ImportError:  # not written yet (issue 3, in progress)
        raise ExemplarError("the 'things' set has no exemplars yet", field="set",
                            hint="only 'furniture' can be built so far") from None

    return [ExemplarSpec(name, category, partial(fn, **kw), f"{fn.__name__}{sorted(kw.items())}")
            for name, (category, fn, kw) in THINGS_CATALOGUE.items()]


def monastery_specs() -> list[ExemplarSpec]:
    """Temple buildings of pybullet_data's samurai_monastry.obj; ExemplarError when pybullet is not installed."""
    from sources.exemplars.monastery import monastery_specs as specs

    return specs()


def sweethome_specs() -> list[ExemplarSpec]:
    """Chairs and tables of sweethome3d-furniture; ExemplarError when the package is not installed."""
    from sources.exemplars.sweethome import sweethome_specs as specs

    return specs()


BUILTIN_SETS: dict[str, tuple[Vocabulary, Callable[[], list[ExemplarSpec]]]] = {
    "furniture": (FURNITURE, furniture_specs),
    "things": (THINGS, things_specs),
    "monastery": (THINGS, monastery_specs),
    "sweethome": (FURNITURE, sweethome_specs),
}


def builtin_set(name: str) -> tuple[Vocabulary, list[ExemplarSpec]]:
    """(vocabulary, specs) of a built-in set; ExemplarError for an unknown name."""
    if name not in BUILTIN_SETS:
        raise ExemplarError(f"unknown style set '{name}'", field="set",
                            hint="built-in sets: " + ", ".join(BUILTIN_SETS))
    vocab, specs = BUILTIN_SETS[name]
    return vocab, specs()

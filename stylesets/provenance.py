"""What a style set says about its exemplars' origins: name, digest, and each exemplar's licence.

Role: one small, JSON-able record (``StyleSetRecord``) made from a loaded set
(``record_of_set``: what training stores in a checkpoint) or, without building
anything, from a built-in set's specs (``builtin_record``: for checkpoints
written before they stored one). The digest is the set's ``inputs_hash``
(``stylesets/format.py``): the same hash that names a built set file.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from core.errors import DecollageError
from core.provenance import ExemplarCredit
from stylesets.format import RESOLUTION, StyleSet, inputs_hash
from stylesets.registry import BUILTIN_SETS, builtin_set


@dataclass(frozen=True)
class StyleSetRecord:
    """A set's provenance. ``credits``: exemplar name → its credit."""

    name: str
    digest: str | None
    credits: dict[str, ExemplarCredit] = field(default_factory=dict)

    def credit(self, exemplar: str) -> ExemplarCredit:
        """The exemplar's credit; one with an unclear licence when the set does not list it."""
        return self.credits.get(exemplar) or ExemplarCredit(exemplar, self.name, "unclear: not in the set's record")

    def to_json(self) -> dict:
        return {"name": self.name, "digest": self.digest,
                "exemplars": {n: {"licence": c.licence, "attribution": c.attribution, "source": c.source}
                              for n, c in self.credits.items()}}

    @classmethod
    def from_json(cls, data: dict) -> "StyleSetRecord":
        name = str(data.get("name", ""))
        credits = {n: ExemplarCredit(n, name, str(c.get("licence", "")), str(c.get("attribution", "")),
                                     str(c.get("source", "")))
                   for n, c in (data.get("exemplars") or {}).items()}
        return cls(name, data.get("digest"), credits)


def record_of_set(style_set: StyleSet) -> StyleSetRecord:
    """The record of a loaded set, from its exemplars' metadata."""
    credits = {ex.name: ExemplarCredit(ex.name, style_set.name, str(ex.meta.get("licence", "")),
                                       str(ex.meta.get("attribution", "")), str(ex.meta.get("source", "")))
               for ex in style_set.exemplars}
    return StyleSetRecord(style_set.name, style_set.inputs_hash, credits)


def builtin_record(name: str) -> StyleSetRecord | None:
    """The record of built-in set ``name`` from its specs (no voxelizing); None if unknown or unavailable.

    The digest is the set's ``inputs_hash`` as the code and the inputs are now,
    which is the trained-on set's only if neither changed since training.
    """
    if name not in BUILTIN_SETS:
        return None
    try:
        vocabulary, specs = builtin_set(name)
        digest = inputs_hash(name, vocabulary, specs, RESOLUTION)
    except (DecollageError, OSError):  # a set reading an absent package (monastery, sweethome)
        return None
    return StyleSetRecord(name, digest, {s.name: ExemplarCredit(s.name, name, s.licence, s.attribution, s.source)
                                         for s in specs})

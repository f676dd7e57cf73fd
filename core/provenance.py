"""Provenance: which style exemplars' geometry an asset carries, under which licence.

The contract between detailizers and the pipeline. A detailizer reports, in
``FineGrid.extras`` (``core/grid.py``):

- ``extras["exemplars"]``: a list of ``ExemplarCredit.to_json()`` records, the
  exemplars whose geometry the output carries. A learned detailizer reports the
  exemplars of the styles assigned to the grid (their style codes shaped it);
  a copying detailizer reports the exemplars it copied blocks from; a baseline
  that adds no exemplar geometry (``upsample``) reports an empty list. A
  detailizer that does not set the key is reported as "unknown".
- ``extras["style_set"]`` (name) and ``extras["style_set_digest"]`` (the set's
  ``inputs_hash``, ``stylesets/format.py``; None when unknown).

The pipeline puts them into every asset's manifest entry and GLB
(``pipeline/provenance.py``) and lists what the assets require in the build
folder's NOTICE.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from enum import StrEnum

#: ``FineGrid.extras`` keys of the contract above.
EXEMPLARS = "exemplars"
STYLE_SET = "style_set"
STYLE_SET_DIGEST = "style_set_digest"


class LicenceNeed(StrEnum):
    """What using an exemplar's geometry asks of whoever ships the asset."""

    ATTRIBUTION = "attribution"  # CC-BY and friends: credit the author (the NOTICE lists it)
    NONE = "none"  # CC0, public domain, or the project's own procedural designs
    UNCLEAR = "unclear"  # no licence stated, a user's own files, or an unknown text: check before shipping


def licence_need(licence: str) -> LicenceNeed:
    """Classify a licence text as recorded in a style set (e.g. ``CC-BY-3.0``, ``CC0-1.0``, ``unclear: ...``)."""
    text = " ".join(licence.lower().replace("_", "-").split())
    if not text or text.startswith("unclear") or text.startswith("user"):
        return LicenceNeed.UNCLEAR
    if text.startswith(("cc-by", "cc by", "creative commons attribution")):
        return LicenceNeed.ATTRIBUTION
    if text.startswith(("cc0", "public domain", "project licence", "project license")):
        return LicenceNeed.NONE
    return LicenceNeed.UNCLEAR


@dataclass(frozen=True)
class ExemplarCredit:
    """One exemplar an asset's geometry came from.

    Attributes:
        name: the exemplar (= style) name.
        style_set: the set it belongs to.
        licence: as the set records it (e.g. ``CC-BY-3.0``).
        attribution: the credit line the licence asks for ("" when none is recorded).
        source: where its mesh came from (``procedural``, ``sweethome3d-furniture``, ``user``...).
    """

    name: str
    style_set: str
    licence: str
    attribution: str = ""
    source: str = ""

    @property
    def need(self) -> LicenceNeed:
        return licence_need(self.licence)

    def to_json(self) -> dict:
        return {**asdict(self), "requires": self.need.value}

    @classmethod
    def from_json(cls, data: dict) -> "ExemplarCredit":
        return cls(str(data["name"]), str(data.get("style_set", "")), str(data.get("licence", "")),
                   str(data.get("attribution", "")), str(data.get("source", "")))

"""Write the painter's edits into the recipe file, keeping the user's comments, order and layout.

Role: the YAML round trip. The recipe is read with ruamel.yaml's round-trip
loader (comments, key order, flow/block style and quotes kept), the asset's
``regions`` and ``detailize`` entries are changed in place, and the document is
written back. The indentation is taken from the file itself: the first of a few
common layouts that writes the unchanged file back byte for byte.

``render`` returns the new text; ``check_saved`` proves, before anything is
written, that the new text is a valid recipe (``core/recipe_loader.py``) whose
asset is exactly the one the page built (so ``decollage build`` reproduces the
page's GLB).
"""

from __future__ import annotations

import hashlib
import io
import re
from pathlib import Path

from core.errors import DecollageError, StudioError
from core.recipe import Asset
from core.recipe_loader import parse_recipe
from studio.paint_rules import RuleEdits

#: (mapping indent, sequence indent, sequence dash offset) tried in order; the project's recipes use the first.
_LAYOUTS = ((2, 4, 2), (2, 2, 0), (4, 4, 2), (4, 6, 4), (2, 4, 0), (4, 4, 0))
_ASSET_FIELD = re.compile(r"^assets\[(\d+)\]$")
#: Asset fields the painter may change; any other difference between the saved and the built asset is a bug.
EDITABLE = ("regions", "detailize")


def _yaml(layout: tuple[int, int, int]):
    from ruamel.yaml import YAML

    yaml = YAML(typ="rt")
    yaml.preserve_quotes = True
    yaml.width = 4096  # never re-wrap the user's lines
    mapping, sequence, offset = layout
    yaml.indent(mapping=mapping, sequence=sequence, offset=offset)
    return yaml


def _dump(yaml, data) -> str:
    buf = io.StringIO()
    yaml.dump(data, buf)
    return buf.getvalue()


def digest(text: str) -> str:
    """sha256 hex of recipe text (how the painter notices a file changed on disk)."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


class RecipeDocument:
    """A recipe file held as a round-trip YAML document.

    Attributes:
        text: the file's text when it was read.
        lossless: True when the unchanged document writes back byte for byte
            (else the file's layout is normalised where it is written).
    """

    def __init__(self, text: str, path: Path) -> None:
        from ruamel.yaml.error import YAMLError

        self.path = path
        self.text = text
        self.lossless = False
        first = None
        for layout in _LAYOUTS:
            yaml = _yaml(layout)
            try:
                data = yaml.load(text)
            except YAMLError as exc:
                raise StudioError(f"cannot read the recipe for editing: {exc}", file=path) from None
            if first is None:
                first = (yaml, data)
            if _dump(yaml, data) == text:
                self.yaml, self.data, self.lossless = yaml, data, True
                break
        else:
            self.yaml, self.data = first

    def asset_node(self, field: str):
        """The mapping of ``assets[i]`` in the file."""
        match = _ASSET_FIELD.match(field)
        assets = self.data.get("assets") if hasattr(self.data, "get") else None
        if not match or not isinstance(assets, list) or int(match.group(1)) >= len(assets):
            raise StudioError(f"{field} is not in the file any more", file=self.path, hint="reload the page")
        node = assets[int(match.group(1))]
        if not hasattr(node, "get"):
            raise StudioError(f"{field} is not a mapping", file=self.path)
        return node

    def apply(self, field: str, edits: RuleEdits, detailize: dict) -> None:
        """Make ``edits`` on the asset's ``regions`` and set ``detailize`` keys (value None = the key's null)."""
        from ruamel.yaml.comments import CommentedMap, CommentedSeq

        node = self.asset_node(field)
        regions = node.get("regions")
        if not isinstance(regions, list):
            raise StudioError(f"{field}.regions is not a list", file=self.path)
        for i, keys in edits.changed.items():
            for key, value in keys.items():
                regions[i][key] = value
        flow = bool(regions) and hasattr(regions[-1], "fa") and regions[-1].fa.flow_style()
        for rule in edits.appended:
            item = CommentedMap()
            for key, value in rule.items():
                if key == "cells":
                    seq = CommentedSeq()
                    for cell in value:
                        triple = CommentedSeq(cell)
                        triple.fa.set_flow_style()
                        seq.append(triple)
                    item[key] = seq
                else:
                    item[key] = _flow_list(value) if isinstance(value, list) else value
            if flow and "cells" not in rule:
                item.fa.set_flow_style()
            regions.append(item)
        if detailize:
            current = node.get("detailize")
            if current is None:
                current = CommentedMap()
                current.fa.set_flow_style()
                node["detailize"] = current
            elif not hasattr(current, "get"):
                raise StudioError(f"{field}.detailize is not a mapping", file=self.path)
            for key, value in detailize.items():
                current[key] = value

    def render(self) -> str:
        """The document as text."""
        return _dump(self.yaml, self.data)


def _flow_list(values: list):
    from ruamel.yaml.comments import CommentedSeq

    seq = CommentedSeq(values)
    seq.fa.set_flow_style()
    return seq


def detailize_changes(current: Asset, wanted: dict) -> dict:
    """The ``detailize`` keys to write so that the asset's settings become ``wanted`` (a full dump).

    A key whose value already comes out right (from the asset or the recipe's
    defaults) is left alone.
    """
    have = current.detailize.model_dump(mode="json")
    return {k: v for k, v in wanted.items() if have.get(k) != v}


def comparable(asset: Asset) -> dict:
    """An asset as plain JSON without what variant expansion adds (the fields a build depends on)."""
    return asset.model_dump(mode="json", by_alias=True, exclude={"variant", "variants", "name_template"})


def check_saved(text: str, path: Path, expected: Asset) -> None:
    """Raise StudioError unless ``text`` is a valid recipe whose asset ``expected.name`` equals ``expected``."""
    try:
        recipe = parse_recipe(text, path)
    except DecollageError as exc:
        raise StudioError(f"the edited recipe would not validate: {exc.one_line()}", file=path,
                          hint="nothing was written") from None
    saved = next((a for a in recipe.assets if a.name == expected.name), None)
    if saved is None or comparable(saved) != comparable(expected):
        raise StudioError(f"the edited recipe would not give the asset {expected.name!r} the page built",
                          file=path, hint="nothing was written; please report it")

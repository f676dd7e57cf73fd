"""Provenance: licences classified, exemplars in the manifest and GLB asset.extras, NOTICE lists exactly what is used."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest

from core import detailizer as registry
from core.grid import FineGrid, LabeledGrid
from core.provenance import ExemplarCredit, LicenceNeed, licence_need
from core.recipe_loader import load_recipe
from model.provenance import exemplar_extras
from model.upsample import UpsampleDetailizer
from pipeline.batch import build_recipe
from pipeline.provenance import NOTICE_NAME, notice_text
from sources.vox_file import write_vox
from stylesets.provenance import StyleSetRecord
from tests.gltf_validator import validate_glbs

#: A style set made in code: two CC-BY chairs (one never used below), a CC0 chair, a user's own file.
CHAIRS = StyleSetRecord("chairs", "c0ffee", {c.name: c for c in (
    ExemplarCredit("ella_chair", "chairs", "CC-BY-3.0", '"Chair" by Sizzler, BlendSwap-CC-BY', "sweethome3d-furniture"),
    ExemplarCredit("kitchen_chair", "chairs", "CC-BY-3.0", '"Chair" by Cisco336, BlendSwap-CC-BY', "sweethome3d-furniture"),
    ExemplarCredit("oak_chair", "chairs", "CC0-1.0", '"Oak chair" by Doug C', "sweethome3d-furniture"),
    ExemplarCredit("my_chair", "chairs", "user-supplied", "", "user"),
)})


class CopyingDetailizer:
    """A stand-in for an example-based detailizer: upsample's geometry, reporting the exemplars assigned."""

    name = "copying"
    learned = False
    style_names = tuple(CHAIRS.credits)
    part_names = None

    def __init__(self, checkpoint=None, device="auto") -> None:
        self.base = UpsampleDetailizer()

    def describe(self) -> dict:
        return {"name": self.name, "learned": False}

    def detailize(self, grid: LabeledGrid, seed: int = 0) -> FineGrid:
        fine = self.base.detailize(grid, seed)
        used = [grid.style_names[i] for i in np.unique(grid.style[grid.occupancy])]
        return FineGrid(fine.occupancy, fine.style, fine.style_names, fine.voxel_size_m, fine.origin_m,
                        self.name, exemplar_extras(CHAIRS, used))


@pytest.mark.parametrize("licence, need", [
    ("CC-BY-3.0", LicenceNeed.ATTRIBUTION), ("CC-BY-3.0-US", LicenceNeed.ATTRIBUTION),
    ("Creative Commons Attribution 4.0", LicenceNeed.ATTRIBUTION), ("CC0-1.0", LicenceNeed.NONE),
    ("project licence (procedural)", LicenceNeed.NONE), ("unclear: no licence recorded", LicenceNeed.UNCLEAR),
    ("user-supplied", LicenceNeed.UNCLEAR), ("", LicenceNeed.UNCLEAR), ("GPL-3.0", LicenceNeed.UNCLEAR),
])
def test_licences_are_classified(licence, need):
    assert licence_need(licence) == need


RECIPE = """
version: 1
defaults:
  grid: {resolution: 6}
  export: {preview: false, max_triangles: 2000}
assets:
  - name: lounge
    source: {kind: vox, path: chair.vox}
    detailize: {detailizer: copying}
    regions: [{part: body, style: ella_chair}]
  - name: kitchen
    source: {kind: vox, path: chair.vox}
    detailize: {detailizer: copying}
    regions: [{part: body, style: oak_chair}, {band: top, part: body, style: my_chair}]
  - name: plain
    source: {kind: vox, path: chair.vox}
    detailize: {detailizer: upsample}
    regions: [{part: body, style: ella_chair}]
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    folder = tmp_path_factory.mktemp("prov")
    chair = np.zeros((4, 4, 6), dtype=np.uint8)
    chair[:, :, :2] = 1
    chair[:, 0, 2:] = 1
    (folder / "chair.vox").write_bytes(write_vox([chair]))
    (folder / "r.yaml").write_text(RECIPE)
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(registry.REGISTRY, "copying", f"{__name__}:CopyingDetailizer")
        reports = build_recipe(load_recipe(folder / "r.yaml"), folder / "out")
    assert [r.status for r in reports] == ["built"] * 3, [r.error for r in reports]
    return folder / "out", {r.name: r for r in reports}


def _glb_json(path: Path) -> dict:
    data = path.read_bytes()
    length = struct.unpack_from("<I", data, 12)[0]
    return json.loads(data[20:20 + length])


def test_manifest_entries_carry_provenance(built):
    out, reports = built
    entries = {e["name"]: e for e in json.loads((out / "manifest.json").read_text())["assets"]}
    lounge = entries["lounge"]["provenance"]
    assert lounge["detailizer"] == "copying" and lounge["style_set"] == {"name": "chairs", "digest": "c0ffee"}
    assert [(c["name"], c["licence"], c["requires"]) for c in lounge["exemplars"]] == [
        ("ella_chair", "CC-BY-3.0", "attribution")]
    assert lounge["exemplars"][0]["attribution"] == '"Chair" by Sizzler, BlendSwap-CC-BY'
    assert lounge["requires_attribution"] == ["ella_chair"]
    assert {c["name"] for c in entries["kitchen"]["provenance"]["exemplars"]} == {"oak_chair", "my_chair"}
    plain = entries["plain"]["provenance"]
    assert plain["exemplars"] == [] and plain["checkpoint"] is None  # upsample copies no exemplar geometry


def test_glb_asset_extras_carry_the_exemplars_and_licences(built):
    out, _ = built
    gltf = _glb_json(out / "lounge.glb")
    provenance = gltf["asset"]["extras"]["provenance"]
    assert provenance == json.loads((out / "manifest.json").read_text())["assets"][0]["provenance"]
    assert provenance["exemplars"][0]["licence"] == "CC-BY-3.0"


@pytest.mark.e2e
def test_glbs_with_provenance_pass_the_gltf_validator(built):
    out, _ = built
    reports = validate_glbs(sorted(out.glob("*.glb")))
    assert all(r["errors"] == 0 for r in reports), reports


def test_notice_lists_exactly_the_exemplars_used(built):
    out, _ = built
    text = (out / NOTICE_NAME).read_text()
    attribution = text.split("Attribution required")[1].split("Licence to check")[0]
    assert "ella_chair (style set 'chairs'), licence: CC-BY-3.0" in attribution
    assert '"Chair" by Sizzler, BlendSwap-CC-BY' in attribution
    assert "used by: lounge\n" in attribution  # not 'plain': upsample used no geometry of it
    assert "kitchen_chair" not in text  # in the set, used by no asset
    check = text.split("Licence to check before shipping")[1].split("No attribution required")[0]
    assert "my_chair" in check and "used by: kitchen" in check
    assert "oak_chair" in text.split("No attribution required")[1]


def test_notice_counts_only_built_assets_and_names_unknown_ones():
    credit = ExemplarCredit("ella_chair", "chairs", "CC-BY-3.0", "by Sizzler").to_json()
    entries = [{"name": "a", "status": "failed", "provenance": {"exemplars": [credit]}},
               {"name": "b", "status": "built", "provenance": {"exemplars": None}},
               {"name": "c", "status": "built", "provenance": {"exemplars": []}}]
    text = notice_text(entries)
    assert "ella_chair" not in text and "No built asset carries" in text
    assert "Not known" in text and "  b\n" in text

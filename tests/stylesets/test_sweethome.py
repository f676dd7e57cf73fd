"""The ``sweethome`` set (chairs and tables of sweethome3d-furniture): catalogue, label maps, voxels, errors.

The 120 MB Debian package is not needed: a tiny ``.sh3f`` made in code (a zip
with a properties file and two OBJs of boxes with groups) has the real
catalogues' structure. Only the last test reads the installed package, when there is one.
"""

from __future__ import annotations

import zipfile
from functools import partial
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from stylesets.format import FURNITURE, ExemplarError, ExemplarSpec, inputs_hash, make_exemplar
from stylesets.registry import BUILTIN_SETS
from stylesets.readers import sweethome as sh
from stylesets.readers.sweethome import Model, Rule

R = 64
CATALOGUE = "Fixture-CC-BY"

PROPERTIES = """# PluginFurnitureCatalog.properties (made in code)
id=Fixture
name=Fixture catalog
id#1=Fixture#stool
name#1=Stool \\u00e0 dossier
category#1=Living room
creator#1=Test Author
model#1=/fixture/stool/stool.obj
width#1=40
depth#1=40
height#1=80
id#2=Fixture#table
name#2=Small table
category#2=Kitchen
creator#2=Other Author
model#2=/fixture/table/table.obj
width#2=100
depth#2=60
height#2=75
"""


class _Obj:
    """Writes OBJ text: axis-aligned boxes as quads (fan-split by the reader), each under a group."""

    def __init__(self):
        self.lines = ["# made in code", "mtllib fixture.mtl"]
        self.n = 0

    def box(self, group: str, lo, hi, material: str = "wood"):
        self.lines += [f"g {group}", f"usemtl {material}"]
        for x in (lo[0], hi[0]):
            for y in (lo[1], hi[1]):
                for z in (lo[2], hi[2]):
                    self.lines.append(f"v {x:.6f} {y:.6f} {z:.6f}")
        for quad in ((1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)):
            self.lines.append("f " + " ".join(f"{self.n + i}/{i}" for i in quad))
        self.n += 8
        return self

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


def _stool() -> str:
    o = _Obj()
    for x in (0.0, 3.6):  # four legs in one group, the back posts go up to the top
        for z in (0.0, 3.6):
            o.box("frame", (x, 0, z), (x + 0.4, 8.0 if z == 0.0 else 4.0, z + 0.4))
    o.box("board", (0, 4.0, 0), (4, 4.5, 4))
    o.box("rail", (0.4, 6.5, 0.0), (3.6, 7.5, 0.4))  # back rail between the back posts
    o.lines += ["g glides", "usemtl plastic", "v 0 0 0", "v 0.1 0 0", "v 0 0 0.1", "f -3 -2 -1"]  # a flat scrap
    return o.text()


def _table() -> str:
    o = _Obj()
    o.box("top", (0, 7.0, 0), (10, 7.5, 6))  # one group for the top and the legs, like many real models
    for x in (0.5, 9.0):
        for z in (0.5, 5.0):
            o.box("top", (x, 0, z), (x + 0.5, 7.0, z + 0.5))
    return o.text()


def _write(folder: Path, properties: str = PROPERTIES, stool: str | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{CATALOGUE}.sh3f"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr(sh.PROPERTIES, properties.encode("iso-8859-1"))
        z.writestr("fixture/stool/stool.obj", stool or _stool())
        z.writestr("fixture/table/table.obj", _table())
        z.writestr("fixture/stool/LICENSE.txt", "CC-BY 3.0")
    return path


MODELS = {
    "stool": Model(CATALOGUE, "fixture/stool/stool.obj", "chair", (
        Rule("glides", ""), Rule("board", "seat"), Rule("rail", "back"),
        Rule("frame", "back", "h>0.6"), Rule("frame", "leg"))),
    "table": Model(CATALOGUE, "fixture/table/table.obj", "table", sh.TABLE),
}


@pytest.fixture
def folder(tmp_path) -> Path:
    _write(tmp_path / "furniture")
    return tmp_path / "furniture"


# --------------------------------------------------------------------------- reading


def test_catalogue_entries_and_sizes(folder):
    path = sh.catalogue_path(CATALOGUE, folder)
    entries = sh.read_catalogue(path)
    assert sorted(entries) == ["fixture/stool/stool.obj", "fixture/table/table.obj"]
    stool = entries["fixture/stool/stool.obj"]
    assert stool.name == "Stool à dossier" and stool.creator == "Test Author" and stool.category == "Living room"
    assert (stool.width, stool.depth, stool.height) == (40.0, 40.0, 80.0) and not stool.rotated
    # the model is scaled per axis to its catalogue size (cm → m), min corner at the origin
    obj = sh.read_model(path, "fixture/table/table.obj")
    used = obj.vertices[np.unique(obj.faces)]
    assert np.allclose(used.min(axis=0), 0) and np.allclose(used.max(axis=0), [1.0, 0.75, 0.6])
    assert obj.groups == ("", "top") and len(obj.faces) == 5 * 12


def test_obj_groups_and_materials(folder):
    obj = sh.read_model(sh.catalogue_path(CATALOGUE, folder), "fixture/stool/stool.obj")
    assert obj.groups == ("", "frame", "board", "rail", "glides")
    assert np.bincount(obj.group).tolist() == [0, 48, 12, 12, 1]
    assert obj.materials == ("wood", "plastic") and obj.material[-1] == 1


# --------------------------------------------------------------------------- labels


def test_label_map_by_group_and_component_box(folder):
    obj = sh.read_model(sh.catalogue_path(CATALOGUE, folder), "fixture/stool/stool.obj")
    parts = sh.face_parts(obj, MODELS["stool"].rules, "stool")
    frame = parts[obj.group == 1].reshape(4, 12)[:, 0].tolist()
    assert frame == ["back", "leg", "back", "leg"]  # the two tall rear posts (over 60 % of the height) are back
    assert set(parts[obj.group == 2]) == {"seat"} and set(parts[obj.group == 3]) == {"back"}
    assert parts[-1] == ""  # left out
    # the table heuristic: the wide slab at the top is the tabletop, the rest legs
    table = sh.read_model(sh.catalogue_path(CATALOGUE, folder), "fixture/table/table.obj")
    labels = sh.face_parts(table, sh.TABLE, "table")
    assert labels[:12].tolist() == ["seat"] * 12 and set(labels[12:]) == {"leg"}


def test_stale_label_maps_are_errors(folder):
    obj = sh.read_model(sh.catalogue_path(CATALOGUE, folder), "fixture/stool/stool.obj")
    with pytest.raises(ExemplarError, match="names group 'cushion', which the model does not have") as info:
        sh.face_parts(obj, (Rule("cushion", "seat"), Rule("*", "leg")), "stool")
    assert "'frame'" in info.value.message and "sweethome3d-furniture" in info.value.hint
    with pytest.raises(ExemplarError, match="no label-map rule matches a component of group 'board'"):
        sh.face_parts(obj, (Rule("frame", "leg"), Rule("rail", "back"), Rule("glides", "")), "stool")
    with pytest.raises(ExemplarError, match="unknown part 'roof'"):
        sh.face_parts(obj, (Rule("*", "roof"),), "stool")
    with pytest.raises(ExemplarError, match="names material 'steel'"):
        sh.face_parts(obj, (Rule("mtl:steel", "leg"), Rule("*", "seat")), "stool")
    with pytest.raises(ValueError, match="bad label-map condition"):
        sh.face_parts(obj, (Rule("*", "leg", "height>2"),), "stool")
    # a model the catalogue does not list
    with pytest.raises(ExemplarError, match="has no model fixture/sofa/sofa.obj"):
        sh.model_record(Model(CATALOGUE, "fixture/sofa/sofa.obj", "chair", ()), folder)


# --------------------------------------------------------------------------- package missing


def test_missing_package_is_an_error_with_the_install_hint(tmp_path, monkeypatch):
    monkeypatch.setattr(sh, "FURNITURE_DIR", tmp_path / "nothing")
    with pytest.raises(ExemplarError) as info:
        BUILTIN_SETS["sweethome"][1]()
    assert "sweethome3d-furniture" in info.value.message and "not installed" in info.value.message
    assert "bash scripts/install.sh exemplars" in info.value.hint
    # the package's folder without the catalogue: reinstall
    (tmp_path / "empty").mkdir()
    with pytest.raises(ExemplarError, match="no catalogue BlendSwap-CC-0.sh3f"):
        sh.catalogue_path("BlendSwap-CC-0", tmp_path / "empty")


def test_cli_build_without_the_package_exits_2(tmp_path, monkeypatch):
    from cli.app import app

    monkeypatch.setattr(sh, "FURNITURE_DIR", tmp_path / "nothing")
    out = tmp_path / "styles"
    out.mkdir()
    result = CliRunner().invoke(app, ["styles", "build", "sweethome", "--jobs", "1"],
                                env={"DECOLLAGE_STYLES_DIR": str(out)})
    assert result.exit_code == 2
    assert "bash scripts/install.sh exemplars" in result.stderr and "Traceback" not in result.stderr
    assert not list(out.iterdir())


def test_corrupt_catalogue_is_a_clear_error(tmp_path):
    bad = tmp_path / f"{CATALOGUE}.sh3f"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ExemplarError, match="cannot read the catalogue"):
        sh.read_catalogue(bad)


# --------------------------------------------------------------------------- voxels and specs


def test_voxelized_exemplars_keep_their_parts(folder):
    ex = make_exemplar(ExemplarSpec("stool", "chair", partial(sh.model_parts, "stool", folder, R, MODELS), "k"),
                       FURNITURE, R)
    counts = ex.meta["part_voxels"]
    assert counts["seat"] > 0 and counts["leg"] > 0 and counts["back"] > 0
    full = ex.full(R)
    ys = {p: np.nonzero(full == FURNITURE.parts.index(p) + 1)[1] for p in ("seat", "leg", "back")}
    assert ys["leg"].min() < ys["seat"].min() < ys["back"].mean()
    table = make_exemplar(ExemplarSpec("table", "table", partial(sh.model_parts, "table", folder, R, MODELS),
                                       "k"), FURNITURE, R)
    assert table.meta["part_aliases"]["seat"] == "tabletop"
    seat, leg = table.meta["part_voxels"]["seat"], table.meta["part_voxels"]["leg"]
    voxel = 1.0 / (R * 15 // 16)  # the 1 m long side spans 60 voxels
    assert seat == pytest.approx(1.0 * 0.05 * 0.6 / voxel ** 3, rel=0.25)  # a solid slab, not a shell
    assert leg > 0


def test_specs_record_source_licence_and_the_catalogue(folder, monkeypatch):
    monkeypatch.setitem(sh.LICENCES, CATALOGUE, "CC-BY-3.0")
    specs = sh.sweethome_specs(folder, MODELS)
    assert [(s.name, s.category) for s in specs] == [("stool", "chair"), ("table", "table")]
    stool = specs[0]
    assert stool.source == "sweethome3d-furniture: Fixture-CC-BY/Stool à dossier by Test Author"
    assert stool.input_files == (folder / f"{CATALOGUE}.sh3f",)
    assert "Test Author" in stool.attribution and "Stool à dossier" in stool.attribution
    assert stool.licence == "CC-BY-3.0, by Test Author"
    # the cache key follows the catalogue's bytes
    before = inputs_hash("sweethome", FURNITURE, specs, R)
    _write(folder, stool=_stool() + "# edited\n")
    assert inputs_hash("sweethome", FURNITURE, sh.sweethome_specs(folder, MODELS), R) != before
    assert BUILTIN_SETS["sweethome"][0] is FURNITURE


def test_licences_of_the_catalogues():
    assert sh.LICENCES["BlendSwap-CC-0"] == "CC0-1.0"
    for name, model in sh.MODELS.items():
        assert model.catalogue in sh.LICENCES, name
        assert model.category in ("chair", "table"), name


# --------------------------------------------------------------------------- the real package (when installed)


@pytest.mark.skipif(not sh.FURNITURE_DIR.is_dir(), reason="sweethome3d-furniture is not installed")
def test_label_maps_match_the_installed_package():
    for name, model in sh.MODELS.items():
        path = sh.catalogue_path(model.catalogue)
        obj = sh.read_model(path, model.model)
        parts = sh.face_parts(obj, model.rules, name)
        kept = {p for p in parts if p}
        assert "seat" in kept and "leg" in kept, name
        assert model.category == "table" or "back" in kept or "stool" in name, name
        source, licence, _ = sh.model_record(model)
        assert licence.startswith("CC0-1.0" if model.catalogue == "BlendSwap-CC-0" else "CC-BY-3.0"), name

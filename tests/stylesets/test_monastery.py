"""The ``monastery`` set (buildings of pybullet's samurai_monastry.obj): splitting, labels, voxels, errors.

pybullet is not needed: a small OBJ made in code has the real file's
structure (one ``o`` object, ``Prefix:Reference:material`` names, several
copies of a building under one prefix, a single-material pagoda-like tower,
open roof shells). Only the last test reads the real file, when it is installed.
"""

from __future__ import annotations

import importlib.util
from functools import partial
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from stylesets.format import THINGS, ExemplarError, ExemplarSpec, make_exemplar
from stylesets.registry import BUILTIN_SETS
from stylesets.readers import monastery as mon
from stylesets.readers.monastery import Building

R = 64

#: The fixture's buildings: a hall with an open pyramid roof, one of two shrine copies, a tiered tower.
BUILDINGS = {
    "hall": Building(("Hall",), (2.0, 1.5)),
    "shrine": Building(("Shrine",), (21.0, 1.0)),
    "tower": Building(("Tower",), (30.3, 0.3), roof="tiers"),
}
ROOF = frozenset({"Hall:Hall:tiles", "Shrine:Shrine:roof"})


class _Obj:
    """Writes OBJ text: boxes as quads (fan-split by the reader), open pyramids as triangles."""

    def __init__(self):
        self.lines = ["# made in code", "mtllib fixture.mtl", "o fixture_triangles"]
        self.n = 0

    def _face(self, *ids):
        self.lines.append("f " + " ".join(f"{self.n + i}/{i}" for i in ids))  # v/vt like the real file

    def box(self, material: str, lo, hi):
        self.lines.append(f"usemtl {material}")
        for x in (lo[0], hi[0]):
            for y in (lo[1], hi[1]):
                for z in (lo[2], hi[2]):
                    self.lines.append(f"v {x:.6f} {y:.6f} {z:.6f}")
        # corners: index 1 + 4·x + 2·y + z; outward quads
        for quad in ((1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)):
            self._face(*quad)
        self.n += 8

    def pyramid(self, material: str, lo, hi, y0: float, apex: float):
        """Four sloped triangles over the rectangle lo..hi (x, z) at height y0, no base: an open shell."""
        self.lines.append(f"usemtl {material}")
        for x, z in ((lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])):
            self.lines.append(f"v {x:.6f} {y0:.6f} {z:.6f}")
        self.lines.append(f"v {(lo[0] + hi[0]) / 2:.6f} {apex:.6f} {(lo[1] + hi[1]) / 2:.6f}")
        for a, b in ((1, 2), (2, 3), (3, 4), (4, 1)):
            self._face(b, a, 5)
        self.n += 5

    def write(self, path: Path) -> Path:
        path.write_text("\n".join(self.lines) + "\n")
        return path


@pytest.fixture(scope="module")
def obj_path(tmp_path_factory) -> Path:
    o = _Obj()
    # hall: a body box, a trim band drawn with another body material, an open pyramid roof
    o.box("Hall:Hall:wall", (0, 0, 0), (4, 2, 3))
    o.box("Hall:Hall:trim", (-0.2, 1.8, -0.2), (4.2, 2.0, 3.2))
    o.pyramid("Hall:Hall:tiles", (-0.5, -0.5), (4.5, 3.5), 2.0, 4.0)
    # two copies of one shrine under one prefix, 10 units apart
    for x in (10.0, 20.0):
        o.box("Shrine:Shrine:wall", (x, 0, 0), (x + 2, 1.5, 2))
        o.box("Shrine:Shrine:roof", (x - 0.3, 1.5, -0.3), (x + 2.3, 2.0, 2.3))
    # a tower with one material: a core through two wide flat tiers, a spire on top
    tower = "Tower:tower:blinn1SG"
    o.box(tower, (30, 0, 0), (30.6, 5, 0.6))
    o.box(tower, (29.3, 2.0, -0.7), (31.3, 2.2, 1.3))
    o.box(tower, (29.3, 4.0, -0.7), (31.3, 4.2, 1.3))
    o.box(tower, (30.2, 5.0, 0.2), (30.4, 6.0, 0.4))
    # an unprefixed lantern far away, in no building
    o.box("blinn9SG", (40, 0, 0), (40.5, 1, 0.5))
    return o.write(tmp_path_factory.mktemp("monastery") / "fixture.obj")


@pytest.fixture(scope="module")
def obj(obj_path):
    return mon.read_obj(obj_path)


def _names(obj, faces):
    return obj.material_names(faces)


# --------------------------------------------------------------------------- reading and splitting


def test_read_obj_fan_splits_quads_and_keeps_materials(obj):
    # 11 boxes × 6 quads × 2 triangles + 1 pyramid × 4 triangles
    assert len(obj.faces) == 11 * 12 + 4
    assert obj.materials == ("Hall:Hall:wall", "Hall:Hall:trim", "Hall:Hall:tiles", "Shrine:Shrine:wall",
                             "Shrine:Shrine:roof", "Tower:tower:blinn1SG", "blinn9SG")
    assert np.bincount(obj.material).tolist() == [12, 12, 4, 24, 24, 48, 12]
    assert mon.family_of("Out_Temple1:Out_Temple:lambert2SG") == "Out_Temple1" and mon.family_of("blinn6SG") == ""


def test_split_takes_the_family_and_the_anchored_copy(obj):
    parts = mon.split_buildings(obj, BUILDINGS)
    assert list(parts) == ["hall", "shrine", "tower"]
    assert sorted(set(_names(obj, parts["hall"]))) == ["Hall:Hall:tiles", "Hall:Hall:trim", "Hall:Hall:wall"]
    assert len(parts["hall"]) == 28
    # only the copy at x = 20 (the anchor's), not the one at x = 10
    shrine_x = obj.vertices[obj.faces[parts["shrine"]]][..., 0]
    assert len(parts["shrine"]) == 24 and shrine_x.min() == pytest.approx(19.7) and shrine_x.max() == pytest.approx(22.3)
    assert len(parts["tower"]) == 48 and set(_names(obj, parts["tower"])) == {"Tower:tower:blinn1SG"}
    assert not any(n == "blinn9SG" for faces in parts.values() for n in _names(obj, faces))
    # the other copy is reachable by its own anchor
    other = mon.split_buildings(obj, {"left": Building(("Shrine",), (11.0, 1.0))})["left"]
    assert obj.vertices[obj.faces[other]][..., 0].max() == pytest.approx(12.3)
    assert not set(other.tolist()) & set(parts["shrine"].tolist())


def test_split_refuses_a_stale_label_map(obj):
    with pytest.raises(ExemplarError, match="no copy stands at x=15.0"):
        mon.split_buildings(obj, {"gap": Building(("Shrine",), (15.0, 1.0))})
    with pytest.raises(ExemplarError, match="no faces with materials 'Pagoda:\\*'"):
        mon.split_buildings(obj, {"gone": Building(("Pagoda",), (0.0, 0.0))})


def test_roof_by_label_map_and_by_tiers(obj):
    parts = mon.split_buildings(obj, BUILDINGS)
    hall = parts["hall"]
    roof = mon.roof_mask(obj, hall, "materials", ROOF)
    names = np.array(_names(obj, hall))
    assert (roof == (names == "Hall:Hall:tiles")).all() and roof.sum() == 4  # the trim stays body
    tower = parts["tower"]
    tiers = mon.roof_mask(obj, tower, "tiers")
    # faces in file order: the core (body), then the two flat tiers and the spire, which stands
    # wholly above the top tier's underside (roof)
    assert tiers.tolist() == [False] * 12 + [True] * 36
    # a steeper threshold leaves the tiers as body (and with them the spire)
    assert not mon.roof_mask(obj, tower, "tiers", min_up=0.9).any()
    with pytest.raises(ValueError):
        mon.roof_mask(obj, tower, "guess")


# --------------------------------------------------------------------------- voxels


def _spec(name, path):
    return ExemplarSpec(name, "building", partial(mon.building_parts, name, path, R, BUILDINGS, ROOF), name,
                        source=mon.SOURCE, licence=mon.LICENCE, input_files=(path,))


def test_open_roof_shell_is_filled_solid_and_labels_survive_the_voxelizer(obj, obj_path):
    ex = make_exemplar(_spec("hall", obj_path), THINGS, R)
    assert ex.meta["parts"] == ["bottom", "top"] and ex.meta["part_aliases"] == {"bottom": "body", "top": "roof"}
    body, roof = ex.meta["part_voxels"]["bottom"], ex.meta["part_voxels"]["top"]
    voxel = 5.0 / (R * 15 // 16)  # the longest side (the roof's 5 units) spans 60 voxels
    pyramid = 5.0 * 4.0 * 2.0 / 3.0 / voxel ** 3
    assert roof > 0.8 * pyramid  # a filled pyramid, not its open shell (~20 % of it)
    assert body > 0.8 * 4 * 2 * 3 / voxel ** 3
    full = ex.full(R)
    ys = [np.nonzero(full == label)[1] for label in (1, 2)]
    assert ys[1].mean() > ys[0].max() - 3  # roof on top
    # make_exemplar got back exactly the occupancy labelled_fill computed on its grid
    faces = mon.split_buildings(obj, {"hall": BUILDINGS["hall"]})["hall"]
    corners = obj.vertices[obj.faces[faces]].reshape(-1, 3)
    origin, vox, dims = mon.lattice(corners.min(axis=0), corners.max(axis=0), R)
    assert vox == pytest.approx(voxel)
    b, r = mon.labelled_fill(obj, faces, mon.roof_mask(obj, faces, "materials", ROOF), origin, vox, dims)
    mine = np.zeros(dims, dtype=np.uint8)
    mine[b], mine[r] = 1, 2
    nz = [np.flatnonzero(mine.any(axis=tuple(k for k in range(3) if k != a))) for a in range(3)]
    assert np.array_equal(mine[tuple(slice(i[0], i[-1] + 1) for i in nz)], ex.labels)


def test_thin_panels_are_kept(tmp_path):
    # A single-sided square panel (no volume, no voxel centre inside) and a body box.
    o = _Obj()
    o.box("Gate:Gate:wall", (0, 0, 0), (2, 2, 0.5))
    o.lines += ["usemtl Gate:Gate:tiles", "v 0 2.5 0", "v 2 2.5 0", "v 2 2.5 0.5", "v 0 2.5 0.5", "f 9 10 11 12"]
    path = o.write(tmp_path / "panel.obj")
    parts = mon.building_parts("gate", path, 32, {"gate": Building(("Gate",), (1.0, 0.25))},
                               frozenset({"Gate:Gate:tiles"}))
    assert set(parts) == {"body", "roof"}
    ex = make_exemplar(ExemplarSpec("gate", "building", partial(lambda p: p, parts), "k"), THINGS, 32)
    assert ex.meta["part_voxels"]["top"] > 0


def test_building_spec_records_source_licence_and_input_file(monkeypatch, obj_path):
    monkeypatch.setattr(mon, "find_obj", lambda: obj_path)
    monkeypatch.setattr(mon, "BUILDINGS", BUILDINGS)
    specs = mon.monastery_specs()
    assert [s.name for s in specs] == ["hall", "shrine", "tower"]
    for spec in specs:
        assert spec.category == "building" and spec.input_files == (obj_path,)
        assert spec.source == "pybullet_data samurai_monastry.obj"
        assert spec.licence.startswith("unclear") and "zlib" in spec.licence and "pybullet" in spec.attribution
    assert BUILTIN_SETS["monastery"][0] is THINGS


# --------------------------------------------------------------------------- pybullet missing


@pytest.fixture
def no_pybullet(monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *args: None if name == "pybullet_data" else real(name, *args))


def test_missing_package_is_a_clear_error(no_pybullet):
    with pytest.raises(ExemplarError) as info:
        BUILTIN_SETS["monastery"][1]()
    assert "pybullet_data" in info.value.message and "not installed" in info.value.message
    assert "pip install pybullet==3.2.7" in info.value.hint


def test_cli_build_without_pybullet_exits_2(no_pybullet, tmp_path):
    from cli.app import app

    result = CliRunner().invoke(app, ["styles", "build", "monastery", "--jobs", "1"],
                                env={"DECOLLAGE_STYLES_DIR": str(tmp_path)})
    assert result.exit_code == 2
    assert "pip install pybullet==3.2.7" in result.stderr and "Traceback" not in result.stderr
    assert not list(tmp_path.iterdir())
    listed = CliRunner().invoke(app, ["styles", "list"], env={"DECOLLAGE_STYLES_DIR": str(tmp_path)})
    assert listed.exit_code == 0 and "unavailable" in listed.stdout


def test_corrupt_obj_is_a_clear_error(tmp_path):
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    with pytest.raises(ExemplarError, match="missing vertices"):
        mon.read_obj(bad)
    bad.write_text("v 0 0 x\nf 1 1 1\n")
    with pytest.raises(ExemplarError, match="cannot read"):
        mon.read_obj(bad)


# --------------------------------------------------------------------------- the real file (when installed)


@pytest.mark.skipif(importlib.util.find_spec("pybullet_data") is None, reason="pybullet is not installed")
def test_label_map_matches_the_installed_model():
    obj = mon.read_obj(mon.find_obj())
    families = {mon.family_of(m) for m in obj.materials}
    assert all(set(b.families) <= families for b in mon.BUILDINGS.values())
    assert mon.ROOF_MATERIALS <= set(obj.materials)
    parts = mon.split_buildings(obj)
    assert list(parts) == list(mon.BUILDINGS)
    for name, faces in parts.items():
        roof = mon.roof_mask(obj, faces, mon.BUILDINGS[name].roof)
        assert 0.02 < roof.mean() < 0.6, name

"""Style exemplar sets: file round trip and cache, label mapping, a procedural chair, users' own
exemplars (GLB nodes, OBJ groups, one file per part) with their errors, and ``decollage styles``.

Everything is made in code and voxelized at 32³ or 64³ (the real sets use 256³).
"""

from __future__ import annotations

import io
import json
import zipfile
from functools import partial
from pathlib import Path

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

import stylesets.format as exemplars
from stylesets.format import (
    FURNITURE,
    THINGS,
    ExemplarError,
    ExemplarSpec,
    build_set,
    encode_set,
    fit_voxels,
    load_set,
    make_exemplar,
    read_meta,
    vocabulary_from_arg,
)
from stylesets.user_import import folder_specs, import_folder, part_for
from stylesets.catalogues.prims import box, rod

R = 32
T = trimesh.transformations.translation_matrix


# --------------------------------------------------------------------------- fixtures made in code


def _stool(height: float, legs: int = 4) -> dict:
    """A tiny procedural stool: a seat board on ``legs`` round legs (module level: picklable)."""
    seat = box((0.5, 0.06, 0.5), (0, height, 0))
    corners = [(0.2, 0.2), (-0.2, 0.2), (0.2, -0.2), (-0.2, -0.2)][:legs]
    return {"seat": seat, "leg": [rod((x, 0, z), (x, height, z), 0.03) for x, z in corners]}


def _house() -> dict:
    """A building in its own part names: body + roof (= bottom + top of the things vocabulary)."""
    roof = trimesh.creation.cone(0.6, 0.4)
    roof.apply_translation((0, 0.5, 0))
    return {"body": box((0.8, 0.5, 0.8), (0, 0.25, 0)), "roof": roof}


def _stool_specs() -> list[ExemplarSpec]:
    return [ExemplarSpec("stool_low", "chair", partial(_stool, 0.4), "stool 0.4"),
            ExemplarSpec("stool_tall", "chair", partial(_stool, 0.8, 3), "stool 0.8 3")]


def _chair_scene(leg_names=("leg.001", "leg.002", "leg.003", "leg.004"), extra: dict | None = None):
    """A chair as a trimesh.Scene: one node per part, named like a DCC tool names them."""
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box((1, 0.1, 1)), node_name="seat", geom_name="seat_g",
                       transform=T([0, 0.5, 0]))
    for name, (x, z) in zip(leg_names, [(0.4, 0.4), (-0.4, 0.4), (0.4, -0.4), (-0.4, -0.4)]):
        scene.add_geometry(trimesh.creation.box((0.1, 0.5, 0.1)), node_name=name, geom_name=name + "_g",
                           transform=T([x, 0.2, z]))
    scene.add_geometry(trimesh.creation.box((1, 0.8, 0.1)), node_name="back", geom_name="back_g",
                       transform=T([0, 0.9, -0.45]))
    for name, mesh in (extra or {}).items():
        scene.add_geometry(mesh, node_name=name, geom_name=name + "_g")
    return scene


def _write_obj(path: Path, groups: dict[str, trimesh.Trimesh]) -> Path:
    """An OBJ file with one ``g`` group per entry."""
    lines, offset = [], 0
    for name, mesh in groups.items():
        lines.append(f"g {name}")
        lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in mesh.vertices]
        lines += [f"f {a + 1 + offset} {b + 1 + offset} {c + 1 + offset}" for a, b, c in mesh.faces]
        offset += len(mesh.vertices)
    path.write_text("\n".join(lines) + "\n")
    return path


def _z_up(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The same mesh in Z-up coordinates: (x, y, z) +Y up → (x, -z, y)."""
    mesh = mesh.copy()
    mesh.vertices = np.c_[mesh.vertices[:, 0], -mesh.vertices[:, 2], mesh.vertices[:, 1]]
    return mesh


def _moved(mesh: trimesh.Trimesh, offset) -> trimesh.Trimesh:
    mesh = mesh.copy()
    mesh.apply_translation(offset)
    return mesh


@pytest.fixture
def user_folder(tmp_path) -> Path:
    """A user's folder: a GLB chair (scene nodes) and an OBJ stool (groups)."""
    folder = tmp_path / "mine"
    folder.mkdir()
    _chair_scene().export(folder / "chair.glb")
    _write_obj(folder / "stool.obj", {"seat": box((0.5, 0.06, 0.5), (0, 0.4, 0)),
                                      "leg_1": box((0.05, 0.4, 0.05), (0.2, 0.2, 0.2)),
                                      "leg_2": box((0.05, 0.4, 0.05), (-0.2, 0.2, -0.2))})
    (folder / "LICENSE").write_text("CC0\n")  # companion files are skipped quietly
    return folder


# --------------------------------------------------------------------------- set files and the cache


def test_set_round_trips_byte_identically_and_rebuild_is_cached(tmp_path):
    path = tmp_path / "stools.npz"
    first = build_set("stools", FURNITURE, _stool_specs(), path, resolution=R)
    assert first.built and first.path == path
    data = path.read_bytes()
    loaded = load_set(path)
    assert [e.name for e in loaded.exemplars] == ["stool_low", "stool_tall"]
    assert loaded.vocabulary == FURNITURE and loaded.resolution == R
    for made, back in zip(first.style_set.exemplars, loaded.exemplars):
        assert back.labels.dtype == np.uint8 and np.array_equal(made.labels, back.labels)
        assert back.meta == made.meta and back.offset == made.offset
        assert back.full(R).shape == (R,) * 3 and int((back.full(R) > 0).sum()) == back.meta["voxels"]
    stool = loaded.get("stool_low")
    assert stool.meta["parts"] == ["seat", "leg"]
    leg, seat = FURNITURE.parts.index("leg") + 1, FURNITURE.parts.index("seat") + 1
    assert set(np.unique(stool.labels)) == {0, seat, leg}
    assert stool.meta["part_voxels"]["leg"] == int((stool.labels == leg).sum()) > 0
    # Encoding what was loaded gives the file's bytes; a forced rebuild too (fixed zip timestamps).
    assert encode_set("stools", FURNITURE, R, loaded.inputs_hash, loaded.exemplars) == data
    assert build_set("stools", FURNITURE, _stool_specs(), path, resolution=R, force=True).built
    assert path.read_bytes() == data
    # Same inputs: nothing is voxelized or written.
    mtime = path.stat().st_mtime_ns
    again = build_set("stools", FURNITURE, _stool_specs(), path, resolution=R)
    assert not again.built and path.stat().st_mtime_ns == mtime
    # A changed design is a new inputs hash: rebuilt.
    changed = [_stool_specs()[0], ExemplarSpec("stool_tall", "chair", partial(_stool, 0.9, 3), "stool 0.9 3")]
    assert build_set("stools", FURNITURE, changed, path, resolution=R).built
    assert read_meta(path)["inputs_hash"] != loaded.inputs_hash


def test_truncated_foreign_and_old_files_are_refused(tmp_path):
    good = build_set("stools", FURNITURE, _stool_specs()[:1], tmp_path / "stools.npz", resolution=R).path
    data = good.read_bytes()
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(data[: len(data) // 2])
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, occupancy=np.ones((4, 4, 4), bool))
    old = tmp_path / "old.npz"
    meta = read_meta(good)
    meta["version"] = exemplars.FORMAT_VERSION + 1
    with zipfile.ZipFile(good) as src, zipfile.ZipFile(old, "w") as dst:
        for item in src.infolist():
            body = src.read(item)
            if item.filename == "meta.npy":
                buffer = io.BytesIO()
                np.save(buffer, np.frombuffer(json.dumps(meta).encode(), np.uint8))
                body = buffer.getvalue()
            dst.writestr(item, body)
    for path, why in ((truncated, "truncated or corrupt"), (foreign, "no metadata"), (old, "format version"),
                      (tmp_path / "missing.npz", "not found")):
        with pytest.raises(ExemplarError) as info:
            load_set(path)
        assert why in info.value.message and info.value.file == str(path)
        assert "decollage styles" in info.value.one_line()
    # A damaged set file is rebuilt, not trusted.
    good.write_bytes(data[:100])
    assert build_set("stools", FURNITURE, _stool_specs()[:1], good, resolution=R).built
    assert good.read_bytes() == data


def test_duplicate_exemplar_names_and_empty_sets_are_refused(tmp_path):
    twice = [_stool_specs()[0], _stool_specs()[0]]
    with pytest.raises(ExemplarError, match="duplicate exemplar names: stool_low"):
        build_set("dup", FURNITURE, twice, tmp_path / "dup.npz", resolution=R)
    with pytest.raises(ExemplarError, match="no exemplars"):
        build_set("none", FURNITURE, [], tmp_path / "none.npz", resolution=R)
    assert not any(tmp_path.iterdir())


# --------------------------------------------------------------------------- labels and vocabularies


def test_category_aliases_map_onto_vocabulary_labels():
    assert THINGS.index("roof", "building") == THINGS.index("top") == 1
    assert THINGS.index("pot", "plant") == THINGS.index("bottom") == 0
    assert FURNITURE.index("tabletop", "table") == FURNITURE.index("seat")
    with pytest.raises(KeyError):
        THINGS.index("roof", "plant")  # a plant's parts are pot and leaf
    ex = make_exemplar(ExemplarSpec("house", "building", _house, "house"), THINGS, R)
    assert ex.meta["parts"] == ["bottom", "top"]
    assert ex.meta["part_aliases"] == {"bottom": "body", "top": "roof"}
    # The roof sits on the body: label 2 (top) occupies the upper voxels, label 1 the lower ones.
    ys = {label: np.nonzero(ex.labels == label)[1].mean() for label in (1, 2)}
    assert ys[2] > ys[1]


def test_unknown_part_name_lists_the_accepted_ones():
    spec = ExemplarSpec("lamp", "chair", lambda: {"seat": box((1, 0.1, 1), (0, 0, 0)),
                                                  "lampshade": box((0.1, 0.1, 0.1), (0, 1, 0))}, "lamp")
    with pytest.raises(ExemplarError) as info:
        make_exemplar(spec, FURNITURE, R)
    text = info.value.one_line()
    assert "unknown part name 'lampshade'" in text
    assert all(name in text for name in ("back", "seat", "leg", "armrest", "stretcher", "tabletop"))


def test_part_names_with_numeric_suffixes_and_custom_vocabularies():
    for name in ("leg", "leg.001", "leg_2", "Leg-3", "leg2", "leg.001_2", "LEG"):
        assert part_for(name, FURNITURE) == "leg", name
    assert part_for("roof.002", THINGS, "building") == "top"
    assert part_for("Table_Top", FURNITURE) is None and part_for("legend", FURNITURE) is None
    assert part_for("roof", THINGS, "plant") is None
    custom = vocabulary_from_arg("hull, mast,sail")
    assert custom.parts == ("hull", "mast", "sail") and part_for("mast.001", custom) == "mast"
    assert vocabulary_from_arg("things") is THINGS
    for bad in ("a,a", " , "):
        with pytest.raises(ExemplarError, match="bad vocabulary"):
            vocabulary_from_arg(bad)


# --------------------------------------------------------------------------- a procedural exemplar


def test_procedural_chairs_at_64():
    from stylesets.registry import builtin_set

    vocab, specs = builtin_set("furniture")
    by_name = {s.name: s for s in specs}
    windsor = make_exemplar(by_name["chair_windsor"], vocab, 64)
    assert windsor.category == "chair" and windsor.meta["source"] == "procedural"
    assert {"back", "seat", "leg"} <= set(windsor.meta["parts"])
    assert all(windsor.meta["part_voxels"][p] > 0 for p in windsor.meta["parts"])
    assert max(windsor.labels.shape) == fit_voxels(64)  # the longest side spans 15/16 of the grid
    assert int(windsor.labels.max()) <= len(vocab.parts)
    detail = windsor.meta["detail"]
    # A chair's fine surface is a larger share of its voxels than its 16³ blocks' surface.
    assert detail["coarse"] < detail["fine"] <= 1 and detail["ratio"] == pytest.approx(
        detail["fine"] / detail["coarse"], abs=2e-3) and detail["ratio"] > 1.1
    # Thin slats have no interior at 64³; the hollow-shell check only applies from 128³.
    ladder = make_exemplar(by_name["chair_ladderback"], vocab, 64)
    assert ladder.meta["detail"]["interior"] < exemplars.MIN_INTERIOR_FRACTION
    assert "stretcher" in ladder.meta["parts"]


# --------------------------------------------------------------------------- users' own exemplars


def test_import_glb_nodes_and_obj_groups(user_folder, tmp_path):
    out = tmp_path / "styles"
    result, warnings = import_folder(user_folder, "mine", FURNITURE, out=out, resolution=R, licence="CC0")
    assert result.built and result.path == out / "mine.npz" and warnings == []
    chair, stool = load_set(result.path).exemplars
    assert (chair.name, stool.name) == ("chair", "stool")
    assert chair.meta["parts"] == ["back", "seat", "leg"]  # leg.001..leg.004 → leg
    assert stool.meta["parts"] == ["seat", "leg"]  # leg_1, leg_2 → leg
    for ex in (chair, stool):
        assert ex.meta["source"] == "user" and ex.meta["licence"] == "CC0" and ex.category == "user"
        assert all(ex.meta["part_voxels"][p] > 0 for p in ex.meta["parts"])
    # Four legs of equal size: the leg voxels split into 4 equal columns below the seat.
    leg = chair.labels == FURNITURE.parts.index("leg") + 1
    assert leg.any() and not leg[:, -1, :].any()
    # Cached on the files' bytes: unchanged → no-op; an edited mesh → rebuilt.
    assert not import_folder(user_folder, "mine", FURNITURE, out=out, resolution=R, licence="CC0")[0].built
    _chair_scene(extra={"back.001": trimesh.creation.box((0.1, 0.1, 0.1))}).export(user_folder / "chair.glb")
    assert import_folder(user_folder, "mine", FURNITURE, out=out, resolution=R, licence="CC0")[0].built


def test_import_folder_with_one_file_per_part(tmp_path):
    folder = tmp_path / "town"
    (folder / "house").mkdir(parents=True)
    (folder / "tower").mkdir()
    # Z-up meshes (as CAD tools write them), turned +Y up by up="z".
    parts = {name: _z_up(mesh) for name, mesh in _house().items()}
    parts["body"].export(folder / "house" / "body.stl")
    _write_obj(folder / "house" / "roof.obj", {"roof": parts["roof"]})
    # The tower's parts are named top/bottom directly, with a second top piece carrying a suffix.
    trimesh.creation.box((0.4, 0.4, 1.0)).export(folder / "tower" / "bottom.ply")
    _moved(trimesh.creation.box((0.5, 0.5, 0.2)), (0, 0, 0.6)).export(folder / "tower" / "top.off")
    _moved(trimesh.creation.box((0.2, 0.2, 0.3)), (0, 0, 0.85)).export(folder / "tower" / "top_2.stl")
    (folder / "notes.fbx").write_text("not read")
    specs, warnings = folder_specs(folder, THINGS, up="z")
    assert [(s.name, s.category) for s in specs] == [("house", "building"), ("tower", "user")]
    assert len(warnings) == 1 and "notes.fbx" in warnings[0]
    assert [p.name for p in specs[0].input_files] == ["body.stl", "roof.obj"]
    result, _ = import_folder(folder, "town", THINGS, out=tmp_path / "s", resolution=R, category="building",
                              up="z")
    house, tower = result.style_set.exemplars
    assert house.category == tower.category == "building"
    assert house.meta["part_aliases"] == {"bottom": "body", "top": "roof"}
    # Turned +Y up: the top parts lie above the bottom ones, and the tall tower spans the grid's height.
    for ex in (house, tower):
        assert np.nonzero(ex.labels == 2)[1].mean() > np.nonzero(ex.labels == 1)[1].mean()
    assert tower.labels.shape[1] == fit_voxels(R)


def test_import_gltf_with_external_buffer(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    files = _chair_scene().export(file_type="gltf")  # {"model.gltf": JSON, "gltf_buffer_*.bin": bytes}
    for name, data in files.items():
        (folder / name).write_bytes(data)
    (folder / "model.gltf").rename(folder / "chair.gltf")
    specs, warnings = folder_specs(folder, FURNITURE)
    assert warnings == [] and [s.name for s in specs] == ["chair"]
    # The buffers hold the geometry: they are hashed for the cache along with the JSON.
    buffers = sorted(n for n in files if n.endswith(".bin"))
    assert specs[0].input_files[0].name == "chair.gltf"
    assert buffers and sorted(p.name for p in specs[0].input_files[1:]) == buffers
    assert sorted(specs[0].make()) == ["back", "leg", "seat"] and len(specs[0].make()["leg"]) == 4


def test_import_with_two_workers_gives_the_same_bytes(user_folder, tmp_path):
    one, _ = import_folder(user_folder, "mine", FURNITURE, out=tmp_path / "a", resolution=R, workers=1)
    two, _ = import_folder(user_folder, "mine", FURNITURE, out=tmp_path / "b", resolution=R, workers=2)
    assert one.path.read_bytes() == two.path.read_bytes()


def _bad_unknown_part(folder: Path) -> Path:
    _chair_scene(extra={"cushion": trimesh.creation.box((0.5, 0.1, 0.5))}).export(folder / "chair.glb")
    return folder / "chair.glb"


def _bad_unnamed_stl(folder: Path) -> Path:
    trimesh.creation.box((1, 1, 1)).export(folder / "crate.stl")
    return folder / "crate.stl"


def _bad_no_faces(folder: Path) -> Path:
    (folder / "dots.obj").write_text("g seat\nv 0 0 0\nv 1 0 0\nv 0 1 0\n")
    return folder / "dots.obj"


def _bad_corrupt(folder: Path) -> Path:
    (folder / "chair.glb").write_bytes(b"glTF" + bytes(range(64)))
    return folder / "chair.glb"


def _bad_flat(folder: Path) -> Path:
    quad = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], [[0, 1, 2], [0, 2, 3]])
    _write_obj(folder / "sheet.obj", {"seat": quad})
    return folder / "sheet.obj"


def _bad_duplicate(folder: Path) -> Path:
    _chair_scene().export(folder / "chair.glb")
    (folder / "chair").mkdir()
    trimesh.creation.box((1, 1, 1)).export(folder / "chair" / "seat.stl")
    return folder / "chair.glb"


def _bad_empty_part_folder(folder: Path) -> Path:
    (folder / "chair").mkdir()
    (folder / "chair" / "readme.txt").write_text("parts go here")
    return folder / "chair"


def _bad_empty(folder: Path) -> Path:
    (folder / ".hidden.glb").write_bytes(b"")
    return folder


BAD_INPUTS = {
    "unknown part": (_bad_unknown_part, "unknown part name 'cushion'", "armrest, back, leg, seat, stretcher"),
    "no node names": (_bad_unnamed_stl, "unknown part name 'crate'", "one file per part"),
    "no faces": (_bad_no_faces, "no faces", "triangles"),
    "corrupt mesh": (_bad_corrupt, "cannot read mesh", "valid .glb"),
    "voxelizes to nothing": (_bad_flat, "voxelizes to nothing", "non-zero size"),
    "duplicate names": (_bad_duplicate, "duplicate exemplar name 'chair'", "rename"),
    "empty part folder": (_bad_empty_part_folder, "no part files", "roof.obj"),
    "empty folder": (_bad_empty, "no exemplars found", "one subfolder per exemplar"),
}


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_user_exemplars_give_clear_errors_and_write_nothing(case, tmp_path):
    make, message, hint = BAD_INPUTS[case]
    folder = tmp_path / "in"
    folder.mkdir()
    culprit = make(folder)
    out = tmp_path / "styles"
    with pytest.raises(ExemplarError) as info:
        import_folder(folder, "mine", FURNITURE, out=out, resolution=R)
    err = info.value
    assert message in err.message, err.one_line()
    assert hint in (err.hint or ""), err.one_line()
    assert err.file == str(culprit), err.one_line()
    assert not out.exists()


def test_set_names_are_checked(user_folder, tmp_path):
    for name, why in (("furniture", "built-in"), ("../up", "bad set name"), ("", "bad set name")):
        with pytest.raises(ExemplarError, match=why):
            import_folder(user_folder, name, FURNITURE, out=tmp_path, resolution=R)
    with pytest.raises(ExemplarError, match="folder not found"):
        import_folder(tmp_path / "nowhere", "x", FURNITURE, out=tmp_path, resolution=R)


# --------------------------------------------------------------------------- the CLI


RUNNER = CliRunner()


def _cli(args, styles_dir: Path):
    from cli.app import app

    result = RUNNER.invoke(app, ["styles", *map(str, args)], env={"DECOLLAGE_STYLES_DIR": str(styles_dir)})
    return result.exit_code, result.stdout, result.stderr


def test_cli_import_show_list(user_folder, tmp_path):
    styles = tmp_path / "styles"
    code, out, err = _cli(["import", user_folder, "--name", "mine", "--vocab", "furniture", "--resolution", R,
                           "--jobs", 1, "--licence", "CC-BY-4.0"], styles)
    assert code == 0, err
    assert f"set: {styles / 'mine.npz'}" in out and f"sheet: {styles / 'mine.png'}" in out
    assert "voxelized chair (1/2" in err and "voxelized stool (2/2" in err
    assert "chair" in out and "stool" in out and "CC-BY-4.0" in out
    sheet = styles / "mine.png"
    from PIL import Image

    with Image.open(sheet) as image:
        assert image.width >= 2 * 320 and image.height > 320
    # Second run: nothing rebuilt, the sheet kept.
    mtimes = {p: p.stat().st_mtime_ns for p in styles.iterdir()}
    code, out, err = _cli(["import", user_folder, "--name", "mine", "--vocab", "furniture", "--resolution", R,
                           "--jobs", 1, "--licence", "CC-BY-4.0"], styles)
    assert code == 0 and "up to date" in err and "(up to date)" in out
    assert "voxelized" not in err and {p: p.stat().st_mtime_ns for p in styles.iterdir()} == mtimes

    code, out, err = _cli(["list"], styles)
    assert code == 0, err
    rows = {line.split()[1]: line for line in out.splitlines() if line.startswith("│")}
    assert "mine" in rows and "user" in rows["mine"] and "built" in rows["mine"] and " 2 " in rows["mine"]
    assert "furniture" in rows and "not built" in rows["furniture"] and " 32 " in rows["furniture"]

    custom_sheet = tmp_path / "sheets" / "look.png"
    code, out, err = _cli(["show", styles / "mine.npz", "--sheet", custom_sheet], styles)
    assert code == 0, err
    assert custom_sheet.is_file() and f"sheet: {custom_sheet}" in out
    for text in ("chair", "stool", "back", "seat", "leg", "CC-BY-4.0", "user", "32³"):
        assert text in out, text
    code, out, _ = _cli(["show", "mine", "--no-sheet"], styles)
    assert code == 0 and "sheet:" not in out and "stool" in out


def test_cli_build_a_builtin_set(monkeypatch, tmp_path):
    """``styles build`` on a small stand-in for a built-in set, voxelized at 32³ instead of 256³."""
    from cli import styles as styles_cli
    from stylesets import registry as builtin

    monkeypatch.setitem(builtin.BUILTIN_SETS, "stools", (FURNITURE, _stool_specs))
    monkeypatch.setattr(styles_cli, "build_set", partial(build_set, resolution=R))
    styles = tmp_path / "styles"
    code, out, err = _cli(["build", "stools", "--jobs", 2], styles)
    assert code == 0, err
    assert "voxelized stool_low (1/2" in err and "voxelized stool_tall (2/2" in err
    assert f"set: {styles / 'stools.npz'}" in out and (styles / "stools.png").is_file()
    assert "stool_tall" in out and "procedural" in out, out
    data = (styles / "stools.npz").read_bytes()
    code, out, err = _cli(["build", "stools", "--no-sheet"], styles)
    assert code == 0 and "up to date" in err and "sheet:" not in out
    code, out, err = _cli(["build", "stools", "--force", "--no-sheet", "--jobs", 1, "--out", tmp_path / "other"],
                          styles)
    assert code == 0 and "built in" in err and (tmp_path / "other" / "stools.npz").read_bytes() == data
    code, out, _ = _cli(["list"], styles)
    assert any("stools" in line and "built-in" in line and "built" in line.split("built-in")[1]
               for line in out.splitlines())


@pytest.mark.parametrize("args, message", [
    (["build", "chairs"], "unknown built-in style set 'chairs'"),
    (["show", "nothing"], "no style set 'nothing'"),
    (["show", "furniture"], "styles build furniture"),
    (["import", "{folder}", "--name", "x", "--vocab", "things", "--resolution", 32], "unknown part names"),
    (["import", "{folder}", "--name", "x", "--vocab", "a,a"], "bad vocabulary"),
    (["import", "{folder}", "--name", "x", "--vocab", "furniture", "--resolution", 40], "multiple of 16"),
])
def test_cli_errors_are_one_line_exit_2(args, message, user_folder, tmp_path):
    styles = tmp_path / "styles"
    args = [str(user_folder) if a == "{folder}" else a for a in args]
    code, out, err = _cli(args, styles)
    assert code == 2, (out, err)
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and message in lines[0], err
    assert "Traceback" not in err and not styles.exists()

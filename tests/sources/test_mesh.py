"""Mesh source: round trips through every format, parts, frames, units, and every error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from core.errors import SourceError
from core.recipe import MeshSource
from sources.mesh import load, sanitize_name, unique_name


def _spec(path, **kwargs) -> MeshSource:
    return MeshSource(kind="mesh", path=str(path), **kwargs)


def _box(size=(1.0, 2.0, 3.0), at=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    mesh = trimesh.creation.box(extents=size)
    mesh.apply_translation(at)
    return mesh


def _two_part_scene() -> trimesh.Scene:
    scene = trimesh.Scene()
    scene.add_geometry(_box((1, 1, 1)), node_name="Body", geom_name="cube")
    scene.add_geometry(trimesh.creation.icosphere(2, radius=0.5), node_name="Wheel Left!", geom_name="ball",
                       transform=trimesh.transformations.translation_matrix((3.0, 0.0, 0.0)))
    return scene


def _error(spec: MeshSource, base: Path) -> SourceError:
    with pytest.raises(SourceError) as info:
        load(spec, base)
    assert info.value.field == "path"
    return info.value


# --------------------------------------------------------------------------- formats and parts


@pytest.mark.parametrize("ext", ["stl", "ply", "off", "obj", "glb"])
def test_single_mesh_round_trips_as_one_part_named_after_the_file(tmp_path, ext):
    path = tmp_path / f"crate.{ext}"
    _box(at=(1.0, 0.0, 0.0)).export(path)
    result = load(_spec(path.name), tmp_path)
    assert list(result.parts) == ["crate"]
    mesh = result.parts["crate"]
    assert mesh.is_watertight and len(mesh.faces) == 12
    assert mesh.bounds == pytest.approx(np.array([[0.5, -1.0, -1.5], [1.5, 1.0, 1.5]]))
    assert result.warnings == []
    assert result.input_files == [path]


def test_obj_with_two_objects_gives_two_parts(tmp_path):
    text = "".join(
        f"o {name}\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in _box(at=(dx, 0, 0)).vertices)
        + "".join(f"f {a + 1 + base} {b + 1 + base} {c + 1 + base}\n" for a, b, c in _box().faces)
        for name, dx, base in (("Lid", 0.0, 0), ("Base", 5.0, 8))
    )
    path = tmp_path / "chest.obj"
    path.write_text(text)
    result = load(_spec(path), tmp_path)
    assert list(result.parts) == ["Base", "Lid"]  # ordered by name
    assert result.parts["Lid"].bounds[:, 0] == pytest.approx([-0.5, 0.5])
    assert result.parts["Base"].bounds[:, 0] == pytest.approx([4.5, 5.5])
    assert all(m.is_watertight for m in result.parts.values())


@pytest.mark.parametrize("ext", ["glb", "gltf"])
def test_gltf_scene_nodes_become_named_parts_with_transforms(tmp_path, ext):
    path = tmp_path / f"cart.{ext}"
    _two_part_scene().export(path)
    result = load(_spec(path), tmp_path)
    assert list(result.parts) == ["Body", "Wheel_Left_"]
    assert result.parts["Wheel_Left_"].bounds[:, 0] == pytest.approx([2.5, 3.5], abs=1e-6)
    assert result.parts["Body"].bounds[:, 0] == pytest.approx([-0.5, 0.5])


def test_parts_from_whole_merges_everything(tmp_path):
    path = tmp_path / "cart.glb"
    _two_part_scene().export(path)
    result = load(_spec(path, parts_from="whole"), tmp_path)
    assert list(result.parts) == ["cart"]
    assert len(result.parts["cart"].faces) == 12 + 320
    assert result.parts["cart"].bounds[:, 0] == pytest.approx([-0.5, 3.5], abs=1e-6)


def test_names_are_sanitised_and_made_unique():
    assert sanitize_name("Wheel Left!") == "Wheel_Left_"
    assert sanitize_name("__.hidden") == "hidden"
    assert sanitize_name("???") == "part"
    assert unique_name("a", {"a", "a_2"}) == "a_3"
    assert unique_name("b", {"a"}) == "b"


def test_clashing_node_names_get_suffixes(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(_box(), node_name="door A", geom_name="g1")
    scene.add_geometry(_box(at=(4, 0, 0)), node_name="door?A", geom_name="g2")
    path = tmp_path / "doors.glb"
    scene.export(path)
    result = load(_spec(path), tmp_path)
    assert list(result.parts) == ["door_A", "door_A_2"]
    assert result.parts["door_A"].bounds[0, 0] == pytest.approx(-0.5)  # "door A" sorts before "door?A"


# --------------------------------------------------------------------------- frames, units, cleaning


def test_up_axis_z_rotates_onto_y(tmp_path):
    path = tmp_path / "post.stl"
    _box((1.0, 2.0, 3.0)).export(path)
    mesh = load(_spec(path, up_axis="z"), tmp_path).parts["post"]
    assert mesh.extents == pytest.approx([1.0, 3.0, 2.0])


def test_units_and_scale_convert_to_metres(tmp_path):
    path = tmp_path / "small.stl"
    _box((100.0, 200.0, 300.0), at=(100.0, 0.0, 0.0)).export(path)
    mesh = load(_spec(path, units="cm", scale=2.0), tmp_path).parts["small"]
    assert mesh.extents == pytest.approx([2.0, 4.0, 6.0])
    assert mesh.bounds[0, 0] == pytest.approx(1.0)


def test_degenerate_faces_are_dropped_and_vertices_merged(tmp_path):
    box = _box()
    # Unshared vertices (as in STL) plus one zero-area face.
    vertices = box.vertices[box.faces].reshape(-1, 3)
    faces = np.arange(len(vertices)).reshape(-1, 3)
    lines = [f"v {x} {y} {z}" for x, y, z in vertices] + ["v 0 0 0"]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces] + ["f 1 1 2"]
    path = tmp_path / "soup.obj"
    path.write_text("\n".join(lines) + "\n")
    mesh = load(_spec(path), tmp_path).parts["soup"]
    assert len(mesh.faces) == 12 and len(mesh.vertices) == 8
    assert mesh.is_watertight


def test_open_mesh_is_kept_with_a_warning(tmp_path):
    box = _box()
    path = tmp_path / "tray.stl"
    trimesh.Trimesh(box.vertices, box.faces[2:], process=False).export(path)
    result = load(_spec(path), tmp_path)
    assert len(result.parts["tray"].faces) == 10
    assert len(result.warnings) == 1 and "'tray' is not watertight" in result.warnings[0]


# --------------------------------------------------------------------------- errors


def test_missing_file_names_the_resolved_path(tmp_path):
    err = _error(_spec("nope/missing.obj"), tmp_path)
    assert str((tmp_path / "nope" / "missing.obj").resolve()) in err.message
    assert "relative to the recipe" in err.hint


def test_unsupported_extension_lists_the_supported_ones(tmp_path):
    (tmp_path / "model.fbx").write_bytes(b"x")
    err = _error(_spec("model.fbx"), tmp_path)
    assert "'.fbx'" in err.message
    for ext in (".obj", ".stl", ".ply", ".off", ".glb", ".gltf"):
        assert ext in err.hint


def test_folder_is_refused(tmp_path):
    (tmp_path / "dir.obj").mkdir()
    assert "not a file" in _error(_spec("dir.obj"), tmp_path).message


@pytest.mark.parametrize("ext", ["obj", "glb", "stl", "ply", "off", "gltf"])
def test_corrupt_file_is_a_clean_error(tmp_path, ext):
    path = tmp_path / f"junk.{ext}"
    path.write_bytes(np.random.default_rng(7).bytes(3000))
    err = _error(_spec(path.name), tmp_path)
    assert err.message.startswith("cannot read mesh")
    assert err.one_line().count("\n") == 0


@pytest.mark.parametrize("ext", ["obj", "stl", "glb"])
def test_empty_file(tmp_path, ext):
    (tmp_path / f"empty.{ext}").write_bytes(b"")
    assert _error(_spec(f"empty.{ext}"), tmp_path).message == "cannot read mesh: the file is empty"


def test_vertices_only_obj_has_no_faces(tmp_path):
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    assert _error(_spec("points.obj"), tmp_path).message == "mesh has no faces"


def test_point_cloud_ply_has_no_faces(tmp_path):
    trimesh.PointCloud(np.eye(3)).export(tmp_path / "cloud.ply")
    assert _error(_spec("cloud.ply"), tmp_path).message == "mesh has no faces"


def test_only_degenerate_faces_is_an_error(tmp_path):
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    assert "no faces" in _error(_spec("flat.obj"), tmp_path).message


def test_nan_vertices_are_an_error(tmp_path):
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    assert "NaN or infinite" in _error(_spec("nan.obj"), tmp_path).message


@pytest.mark.parametrize("size, scale, words", [
    (1e30, 1.0, "too large"),
    (1.0, 1e7, "too large"),
    (1e-7, 1.0, "collapses to a point"),
])
def test_parts_degenerate_after_scaling_are_errors(tmp_path, size, scale, words):
    path = tmp_path / "box.stl"
    _box((size, size, size)).export(path)
    from core.recipe import LengthUnit, PartsFrom, UpAxis

    spec = MeshSource.model_construct(kind="mesh", path=str(path), up_axis=UpAxis.Y, units=LengthUnit.M, scale=scale,
                                      parts_from=PartsFrom.NODES)  # past the schema's range, to reach the check
    err = _error(spec, tmp_path)
    assert words in err.message and "'box'" in err.message


def test_devices_pipes_and_oversized_files_are_refused_before_reading(tmp_path, monkeypatch):
    import os

    assert "character device" in _error(_spec("/dev/zero"), tmp_path).message
    os.mkfifo(tmp_path / "pipe.obj")
    assert "named pipe" in _error(_spec("pipe.obj"), tmp_path).message
    _box().export(tmp_path / "box.stl")
    monkeypatch.setenv("DECOLLAGE_MAX_MESH_MB", "0.0001")
    err = _error(_spec("box.stl"), tmp_path)
    assert "limit for mesh files" in err.message and "DECOLLAGE_MAX_MESH_MB" in err.hint


def test_a_gltf_buffer_over_the_mesh_limit_is_refused_before_it_is_read(tmp_path, monkeypatch):
    """Companion files (sources/mesh.py's recording resolver) are held to the mesh file's own size limit."""
    for name, data in _box().export(file_type="gltf").items():
        (tmp_path / ("box.gltf" if name == "model.gltf" else name)).write_bytes(data)
    buffer = next(tmp_path.glob("*.bin"))
    with open(buffer, "r+b") as handle:
        handle.truncate(3 << 20)  # sparse: 3 MB of zeros after the real buffer
    monkeypatch.setenv("DECOLLAGE_MAX_MESH_MB", "1")
    err = _error(_spec("box.gltf"), tmp_path)
    assert buffer.name in err.message and "1 MB limit" in err.message and "DECOLLAGE_MAX_MESH_MB" in err.hint

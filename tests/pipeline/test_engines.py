"""Engine profiles: LOD chains, collision meshes, node names and axes per engine."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

from cli.app import app
from pipeline.engines import _merge_boxes, lod_targets

pytestmark = pytest.mark.e2e  # whole builds per engine profile and the glTF validator

REPO = Path(__file__).resolve().parents[2]

RECIPE = """
version: 1
defaults:
  detailize: {{detailizer: upsample}}
assets:
  - name: shroom
    source: {{kind: voxels, path: {npz}, voxel_size_m: 0.05}}
    grid: {{fit: voxel_size, voxel_size_m: 0.1}}
    regions: [{{part: body, style: moss}}]
    export: {{formats: [glb, obj], profile: {profile}, lods: [1.0, 0.5, 0.25], collision: {collision},
              max_triangles: 4000, preview: false}}
"""


def _glb_nodes(path: Path) -> list[str]:
    data = path.read_bytes()
    length = struct.unpack("<I", data[12:16])[0]
    return [n["name"] for n in json.loads(data[20:20 + length])["nodes"]]


def _build(tmp_path, profile, collision="hull"):
    recipe = tmp_path / "r.yaml"
    recipe.write_text(RECIPE.format(npz=REPO / "recipes" / "inputs" / "mushroom.npz", profile=profile,
                                    collision=collision))
    out = tmp_path / profile
    result = CliRunner().invoke(app, ["build", str(recipe), "-o", str(out), "--json"])
    assert result.exit_code == 0, result.stderr
    return out, json.loads((out / "manifest.json").read_text())["assets"][0]


def test_lod_targets_from_ratios_and_counts():
    assert lod_targets([1.0, 0.5, 0.25], 4000) == [2000, 1000]
    assert lod_targets([3000, 800], 4000) == [800]
    assert lod_targets([1.0, 0.0001], 4000) == [4]


def test_box_merging_covers_exactly_the_occupied_cells():
    occ = np.zeros((5, 4, 3), bool)
    occ[0:3, 0:2, :] = True
    occ[4, 3, 2] = True
    boxes = _merge_boxes(occ)
    cover = np.zeros_like(occ, dtype=int)
    for lo, hi in boxes:
        cover[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] += 1
    assert (cover == occ).all() and len(boxes) == 2


def test_unreal_profile(tmp_path):
    out, entry = _build(tmp_path, "unreal")
    assert _glb_nodes(out / "shroom.glb") == ["shroom_LOD0", "shroom_LOD1", "shroom_LOD2", "UCX_shroom_00"]
    tris = entry["engine"]["lod_triangles"]
    assert tris[0] <= 4000 and tris[1] == pytest.approx(tris[0] / 2, rel=0.05) and tris[2] < tris[1]
    # GLB stays glTF (+Y up, metres); the OBJ takes Unreal's Z-up centimetres
    glb = trimesh.load(out / "shroom.glb").geometry["shroom_LOD0"]
    obj = trimesh.load(out / "shroom.obj")
    np.testing.assert_allclose(obj.extents, glb.extents[[0, 2, 1]] * 100, rtol=1e-5)
    assert obj.bounds[0][2] == pytest.approx(0, abs=1e-3)  # standing on z = 0
    hull = trimesh.load(out / "shroom.glb").geometry["UCX_shroom_00"]
    assert hull.is_convex and hull.volume >= glb.volume * 0.99


def test_unity_profile_and_boxes(tmp_path):
    out, entry = _build(tmp_path, "unity", collision="boxes")
    nodes = _glb_nodes(out / "shroom.glb")
    assert nodes[:3] == ["shroom_LOD0", "shroom_LOD1", "shroom_LOD2"]
    assert all(n.startswith("shroom_collider") for n in nodes[3:]) and entry["engine"]["collision_pieces"] >= 1


def test_godot_and_generic_keep_extra_lods_out_of_the_main_scene(tmp_path):
    out, entry = _build(tmp_path, "godot")
    assert _glb_nodes(out / "shroom.glb") == ["shroom", "shroom-colonly"]
    assert _glb_nodes(out / "shroom_LOD2.glb") == ["shroom_LOD2"]
    out, entry = _build(tmp_path, "generic")
    assert _glb_nodes(out / "shroom.glb") == ["shroom"]
    assert sorted(entry["outputs"]) == ["glb", "glb_LOD1", "glb_LOD2", "glb_collision", "obj"]


def test_unknown_profile_is_a_recipe_error(tmp_path):
    recipe = tmp_path / "r.yaml"
    recipe.write_text(RECIPE.format(npz="x.npz", profile="cryengine", collision="none"))
    result = CliRunner().invoke(app, ["build", str(recipe), "-o", str(tmp_path / "o")])
    assert result.exit_code == 2 and "assets[0].export.profile" in result.stderr
    assert "'generic'" in result.stderr


@pytest.mark.parametrize("profile", ["unreal", "generic", "unity", "godot"])
def test_engine_glbs_pass_the_khronos_validator(tmp_path, profile):
    from tests.gltf_validator import validate_glbs

    out, _ = _build(tmp_path, profile)
    for report in validate_glbs(sorted(out.glob("*.glb"))):
        assert report["errors"] == 0, report

"""Every bundled example recipe builds end to end through the CLI (the acceptance check)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from cli.app import app
from tests.glb_reader import decompress, read_glb

pytestmark = pytest.mark.e2e  # builds the showcase and runs the glTF validator

RECIPES = Path(__file__).resolve().parents[2] / "recipes"


@pytest.fixture(scope="module")
def showcase(tmp_path_factory):
    out = tmp_path_factory.mktemp("showcase")
    result = CliRunner().invoke(app, ["build", str(RECIPES / "showcase.yaml"), "-o", str(out), "--quiet"])
    assert result.exit_code == 0, result.stderr
    return out, json.loads((out / "manifest.json").read_text())


def test_showcase_has_every_source_kind(showcase):
    _, manifest = showcase
    kinds = {a["source_kind"] for a in manifest["assets"]}
    assert kinds == {"text", "cad", "mesh", "voxels"}
    assert manifest["summary"] == {"assets": 4, "built": 4, "failed": 0}
    assert manifest["axes"]["up"] == "+Y" and manifest["axes"]["units"] == "m"


def test_every_asset_writes_a_glb_that_loads_back_with_colours_and_normals(showcase):
    out, manifest = showcase
    for entry in manifest["assets"]:
        data = (out / entry["outputs"]["glb"]["path"]).read_bytes()
        tree, meshes = read_glb(data)  # the showcase writes meshopt-compressed GLBs (export.compression)
        assert tree["extensionsRequired"] == ["EXT_meshopt_compression", "KHR_mesh_quantization"]
        assert entry["outputs"]["glb"]["bytes"] < 2_000_000
        verts, faces, normals, colours = meshes[entry["name"]]
        assert len(faces) > 1000 and len(faces) == entry["mesh"]["triangles"]
        assert colours is not None and len({tuple(c) for c in colours}) == len(entry["coarse_grid"]["styles"])
        assert np.allclose(np.linalg.norm(normals, axis=1), 1, atol=0.02)  # stored in the file
        lo, hi = verts.min(axis=0), verts.max(axis=0)
        step = (hi - lo) / 65535  # the quantization step
        np.testing.assert_allclose(lo, entry["mesh"]["bbox_min_m"], atol=step.max())
        np.testing.assert_allclose(hi, entry["mesh"]["bbox_max_m"], atol=step.max())
        # pivot bottom_center: standing on y = 0, centred on the footprint
        assert abs(lo[1]) <= step[1]
        assert np.allclose((lo[[0, 2]] + hi[[0, 2]]) / 2, 0, atol=step.max())


def test_every_asset_has_a_preview_a_person_can_look_at(showcase):
    out, manifest = showcase
    for entry in manifest["assets"]:
        image = np.asarray(Image.open(out / entry["outputs"]["preview"]["path"]).convert("RGB"))
        assert image.shape == (512, 512, 3)
        background = image[0, 0]
        covered = np.any(np.abs(image.astype(int) - background) > 12, axis=2).mean()
        assert 0.03 < covered < 0.9, entry["name"]


def test_sizes_follow_the_recipes(showcase):
    _, manifest = showcase
    by_name = {a["name"]: a for a in manifest["assets"]}
    size = lambda e: np.subtract(e["mesh"]["bbox_max_m"], e["mesh"]["bbox_min_m"])
    tower = size(by_name["watchtower"])  # 0.5 plinth + 2.2 shaft + 1.0 roof, Z-up CAD → +Y up
    assert tower[1] == pytest.approx(3.7, abs=0.3) and tower[0] == pytest.approx(1.6, abs=0.2)
    word = size(by_name["castle_word"])  # a long word: much wider than tall
    assert word[0] > 4 * word[1]
    # 16 voxels of cap height; round letters (C, S) overshoot it by up to one voxel
    assert by_name["castle_word"]["coarse_grid"]["shape"][1] in (16, 17)


@pytest.mark.parametrize("recipe", ["text_word.yaml", "cad_tower.yaml", "imported_mesh.yaml", "voxel_grid.yaml",
                                    "vox_model.yaml"])
def test_single_example_recipes_validate(recipe):
    result = CliRunner().invoke(app, ["validate", str(RECIPES / recipe)])
    assert result.exit_code == 0, result.stderr


def test_rebuilds_are_byte_identical(showcase, tmp_path):
    out, manifest = showcase
    result = CliRunner().invoke(app, ["build", str(RECIPES / "showcase.yaml"), "-o", str(tmp_path), "--quiet",
                                      "--only", "cottage", "--only", "mushroom"])
    assert result.exit_code == 0, result.stderr
    again = {a["name"]: a for a in json.loads((tmp_path / "manifest.json").read_text())["assets"]}
    for entry in manifest["assets"]:
        if entry["name"] in again:
            assert entry["outputs"] == again[entry["name"]]["outputs"]  # same sha256 for GLB and PNG
    assert set(again) == {"cottage", "mushroom"}


def test_glbs_pass_the_khronos_validator(showcase):
    from tests.gltf_validator import validate_glbs

    out, _ = showcase
    glbs = sorted(out.glob("*.glb"))
    decoded = []  # the validator cannot decode EXT_meshopt_compression: check the decoded data too
    for glb in glbs:
        decoded.append(out.parent / f"{glb.stem}.decoded.glb")
        decoded[-1].write_bytes(decompress(glb.read_bytes()))
    reports = validate_glbs(glbs + decoded)
    assert len(reports) == 8
    for report in reports:
        assert report["errors"] == 0 and report["warnings"] == 0, report

"""Every bundled example recipe builds end to end through the CLI (the acceptance check)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image
from typer.testing import CliRunner

from cli.app import app

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
        glb = out / entry["outputs"]["glb"]["path"]
        mesh = trimesh.load(glb, force="mesh")
        assert len(mesh.faces) > 1000 and len(mesh.faces) == entry["mesh"]["triangles"]
        assert mesh.visual.kind == "vertex"
        assert len({tuple(c) for c in mesh.visual.vertex_colors}) == len(entry["coarse_grid"]["styles"])
        scene = trimesh.load(glb)
        geometry = next(iter(scene.geometry.values()))
        assert "vertex_normals" in geometry._cache.cache  # stored in the file, not recomputed
        np.testing.assert_allclose(mesh.bounds[0], entry["mesh"]["bbox_min_m"], atol=1e-5)
        np.testing.assert_allclose(mesh.bounds[1], entry["mesh"]["bbox_max_m"], atol=1e-5)
        # pivot bottom_center: standing on y = 0, centred on the footprint
        assert abs(mesh.bounds[0][1]) < 1e-6
        assert np.allclose((mesh.bounds[0][[0, 2]] + mesh.bounds[1][[0, 2]]) / 2, 0, atol=1e-6)


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
    reports = validate_glbs(sorted(out.glob("*.glb")))
    assert len(reports) == 4
    for report in reports:
        assert report["errors"] == 0 and report["warnings"] == 0, report

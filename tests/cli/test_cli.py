"""The command line: exit codes, one-line errors naming file and field, no partial outputs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.app import app

RUNNER = CliRunner()

TEXT_ASSET = """
version: 1
defaults:
  detailize: {{detailizer: upsample}}
assets:
  - name: word
    source: {{kind: text, text: {text}, size_m: {size}{extra}}}
    regions: [{{part: body, style: stone}}]
"""


def _text_recipe(text="Hi", size="0.2", extra=""):
    return TEXT_ASSET.format(text=text, size=size, extra=extra)


def _mesh_recipe(path: str) -> str:
    return f"""
version: 1
defaults:
  detailize: {{detailizer: upsample}}
assets:
  - name: thing
    source: {{kind: mesh, path: {path}}}
    regions: [{{part: body, style: stone}}]
"""


def _run(args):
    result = RUNNER.invoke(app, [str(a) for a in args])
    return result.exit_code, result.stdout, result.stderr


def _files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def _assert_one_line_error(stderr: str, recipe: Path, field: str | None):
    lines = [l for l in stderr.splitlines() if l.strip()]
    errors = [l for l in lines if "error" in l or "failed" in l]
    assert errors, stderr
    assert "Traceback" not in stderr
    assert str(recipe) in errors[0] or recipe.name in errors[0], errors[0]
    if field:
        assert field in errors[0], errors[0]


INVALID = {  # exit 2: nothing is built, the output folder is not even created
    "empty file": ("", None),
    "not YAML": ("version: 1\nassets: [\n  {name: x", "line"),
    "list at top level": ("- version: 1\n- assets: []\n", None),
    "unknown key": (_text_recipe(extra=", colour: red"), "assets[0].source.colour"),
    "wrong type": (_text_recipe(size="big"), "assets[0].source.size_m"),
    "unknown source kind": (_text_recipe().replace("kind: text", "kind: hologram"), "assets[0].source"),
    "missing font": (_text_recipe(extra=", font: fonts/nope.ttf"), "assets[0].source.font"),
    "empty text": (_text_recipe(text='"   "'), "assets[0].source.text"),
    "missing mesh file": (_mesh_recipe("meshes/missing.obj"), "assets[0].source.path"),
    "zero size": (_text_recipe(size="0"), "assets[0].source.size_m"),
    "negative size": (_text_recipe(size="-2"), "assets[0].source.size_m"),
    "unknown detailizer": (_text_recipe().replace("regions:", "detailize: {detailizer: magic}\n    regions:"),
                           "assets[0].detailize.detailizer"),
}


@pytest.mark.parametrize("case", sorted(INVALID))
def test_invalid_recipes_exit_2(case, write_recipe, tmp_path):
    text, field = INVALID[case]
    recipe = write_recipe(text)
    out = tmp_path / "out"
    code, _, stderr = _run(["build", recipe, "-o", out])
    assert code == 2, stderr
    _assert_one_line_error(stderr, recipe, field)
    assert not out.exists()
    code, _, stderr = _run(["validate", recipe])
    assert code == 2


def _garbage_font(tmp_path: Path) -> str:
    (tmp_path / "bad.ttf").write_bytes(np.random.default_rng(0).bytes(4000))
    return _text_recipe(extra=", font: bad.ttf")


def _corrupt_mesh(tmp_path: Path) -> str:
    (tmp_path / "broken.obj").write_bytes(b"v 0 0 0\nf 1 2 \x00\xff garbage\n" + np.random.default_rng(1).bytes(500))
    return _mesh_recipe("broken.obj")


def _faceless_mesh(tmp_path: Path) -> str:
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    return _mesh_recipe("points.obj")


def _voxelizes_to_nothing(tmp_path: Path) -> str:
    return _text_recipe(size="0.001").replace(
        "regions:", "grid: {fit: voxel_size, voxel_size_m: 1.0}\n    regions:")


def test_garbage_font_is_refused_before_building(write_recipe, tmp_path):
    """validate and the build's pre-flight read the font (to check that it covers the text): exit 2, nothing written."""
    recipe = write_recipe(_garbage_font(tmp_path))
    out = tmp_path / "out"
    code, _, stderr = _run(["build", recipe, "-o", out])
    assert code == 2, stderr
    _assert_one_line_error(stderr, recipe, "assets[0].source.font")
    assert not out.exists()
    assert _run(["validate", recipe])[0] == 2


ASSET_FAILURES = {  # exit 1: the asset fails, is in the manifest as failed, leaves no file
    "corrupt mesh": (_corrupt_mesh, "assets[0].source.path"),
    "mesh with no faces": (_faceless_mesh, "assets[0].source.path"),
    "voxelizes to nothing": (_voxelizes_to_nothing, "assets[0]"),
}


@pytest.mark.parametrize("case", sorted(ASSET_FAILURES))
def test_failing_assets_exit_1_without_partial_files(case, write_recipe, tmp_path):
    make, field = ASSET_FAILURES[case]
    recipe = write_recipe(make(tmp_path))
    out = tmp_path / "out"
    code, _, stderr = _run(["build", recipe, "-o", out])
    assert code == 1, stderr
    _assert_one_line_error(stderr, recipe, field)
    assert _files(out) == [".decollage", "NOTICE.txt", "build.json", "manifest.json"]  # build-level files only
    assert _files(out / ".decollage") == ["build.lock"]  # the lock; no record
    manifest = json.loads((out / "manifest.json").read_text())
    entry = manifest["assets"][0]
    assert entry["status"] == "failed" and field in entry["error"] and entry["outputs"] == {}


def test_one_bad_asset_does_not_stop_the_others(write_recipe, tmp_path):
    (tmp_path / "points.obj").write_text("v 0 0 0\n")
    recipe = write_recipe(_text_recipe() + """
  - name: thing
    source: {kind: mesh, path: points.obj}
    regions: [{part: body, style: stone}]
""")
    out = tmp_path / "out"
    code, stdout, stderr = _run(["build", recipe, "-o", out])
    assert code == 1
    assert "1 built, 0 up to date (cached), 1 failed" in stderr  # a failed asset is not counted as built
    assert _files(out) == [".decollage", "NOTICE.txt", "build.json", "manifest.json", "word.glb", "word.png"]  # .decollage: records, lock
    summary = json.loads((out / "manifest.json").read_text())["summary"]
    assert summary == {"assets": 2, "built": 1, "failed": 1}


def test_unwritable_output_dir_exit_2(write_recipe, tmp_path):
    recipe = write_recipe(_text_recipe())
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a folder")
    code, _, stderr = _run(["build", recipe, "-o", blocker / "out"])
    assert code == 2
    assert "file.txt" in stderr and "Traceback" not in stderr


def test_usage_errors_exit_2(write_recipe, tmp_path):
    recipe = write_recipe(_text_recipe())
    assert _run(["build"])[0] == 2
    assert _run(["build", recipe, "--frobnicate"])[0] == 2
    code, _, stderr = _run(["build", recipe, "--only", "nope", "-o", tmp_path / "o"])
    assert code == 2 and "nope" in stderr


def test_schema_command_prints_json_schema():
    code, stdout, _ = _run(["schema"])
    assert code == 0
    schema = json.loads(stdout)
    assert "assets" in schema["properties"]


@pytest.mark.e2e  # a subprocess CLI run
def test_console_script_entry_point_reports_errors_without_traceback(write_recipe):
    recipe = write_recipe("- just a list")
    proc = subprocess.run([sys.executable, "-m", "cli.app", "validate", str(recipe)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "recipe.yaml" in proc.stderr

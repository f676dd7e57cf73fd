"""Recipe schema: strict loading, defaults merging, and messages that name file and field."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from core.errors import RecipeError
from core.recipe import ExportFormat, FitMode
from core.recipe_loader import json_schema, load_recipe, parse_recipe

GOOD = """
version: 1
defaults:
  detailize: {detailizer: upsample}
  export: {formats: [glb, obj], max_triangles: 5000}
  grid: {resolution: 12}
assets:
  - name: hello
    source: {kind: text, text: HELLO}
    regions:
      - {part: body, style: brick}
      - {band: top, part: roof, style: tiles}
    export: {max_triangles: 900}
  - name: tower
    source:
      kind: cad
      parts:
        - {name: base, shape: box, size: [1, 1, 0.5]}
        - name: top
          shape: difference
          children:
            - {shape: cylinder, radius: 0.3, height: 1, at: [0, 0, 1]}
            - {shape: sphere, radius: 0.2, at: [0, 0, 1.5]}
    grid: {resolution: 20}
    regions: [{part: body, style: a}]
"""


def _error(text: str) -> RecipeError:
    with pytest.raises(RecipeError) as info:
        parse_recipe(text, Path("r.yaml"))
    return info.value


def test_good_recipe_and_defaults_merge():
    recipe = parse_recipe(GOOD, Path("r.yaml"))
    hello, tower = recipe.assets
    assert hello.fit == FitMode.HEIGHT and tower.fit == FitMode.LONGEST
    # defaults apply field by field, the asset's own value wins
    assert hello.export.formats == [ExportFormat.GLB, ExportFormat.OBJ]
    assert hello.export.max_triangles == 900 and tower.export.max_triangles == 5000
    assert hello.grid.resolution == 12 and tower.grid.resolution == 20
    assert tower.source.parts[1].children[1].radius == 0.2
    assert hello.regions[1].band_range().from_ == 0.5


@pytest.mark.parametrize(
    "text, field, words",
    [
        ("", None, "empty"),
        ("a: [", "line 1", "not valid YAML"),
        ("- 1\n- 2", None, "list"),
        ("version: 1\nversion: 1", "line 2", "duplicate key"),
        (GOOD.replace("text: HELLO", "text: HELLO, colour: red"), "assets[0].source.colour", "unknown key"),
        (GOOD.replace("size: [1, 1, 0.5]", "size: [1, big, 0.5]"), "assets[1].source.parts[0].size[1]", "number"),
        (GOOD.replace("size: [1, 1, 0.5]", "size: [1, 0, 0.5]"), "assets[1].source.parts[0].size[1]", "greater than or equal to 0.000001"),
        (GOOD.replace("kind: text", "kind: txt"), "assets[0].source", "unknown kind 'txt'"),
        (GOOD.replace("shape: sphere", "shape: blob"), "assets[1].source.parts[1].children[1]", "unknown shape"),
        (GOOD.replace("text: HELLO", 'text: "  "'), "assets[0].source.text", "empty"),
        (GOOD.replace("max_triangles: 5000", "max_triangles: 2"), "defaults.export.max_triangles", "greater than or equal to 4"),
        (GOOD.replace("formats: [glb, obj]", "formats: [glb, fbx]"), "defaults.export.formats[1]", "'glb'"),
        (GOOD.replace("version: 1", "version: 2"), "version", "1"),
        (GOOD.replace("- name: tower", "- name: hello"), "assets", "unique"),
        (GOOD.replace("resolution: 20", 'resolution: "20"'), "assets[1].grid.resolution", "integer"),
        ("version: 1\nassets: []", "assets", "at least 1"),
        ("version: 1\nassets:\n  - name: x\n    source: {kind: text, text: A}\n", "assets[0].regions", "Field required"),
    ],
)
def test_bad_recipes_name_the_field(text, field, words):
    err = _error(text)
    line = err.one_line()
    assert line.startswith("r.yaml")
    assert "\n" not in line
    if field:
        exact = not field.startswith("line")  # YAML errors also give the column
        assert (err.field == field) if exact else err.field.startswith(field + ","), line
    assert words.lower() in line.lower(), line


def test_size_must_be_positive():
    err = _error(GOOD.replace("text: HELLO", "text: HELLO, size_m: -1"))
    assert err.field == "assets[0].source.size_m"


def test_load_recipe_file_errors(tmp_path):
    with pytest.raises(RecipeError, match="file not found"):
        load_recipe(tmp_path / "nope.yaml")
    binary = tmp_path / "b.yaml"
    binary.write_bytes(bytes(range(256)))
    with pytest.raises(RecipeError, match="not UTF-8"):
        load_recipe(binary)
    with pytest.raises(RecipeError, match="folder"):
        load_recipe(tmp_path)


def test_json_schema_is_complete():
    schema = json_schema()
    text = json.dumps(schema)
    for key in ("TextSource", "CadSource", "MeshSource", "VoxelsSource", "RegionRule", "letter_spacing"):
        assert key in text
    assert schema["properties"]["version"]


def test_bundled_recipes_validate():
    recipes = sorted((Path(__file__).parents[2] / "recipes").glob("*.yaml"))
    assert len(recipes) >= 5
    for path in recipes:
        assert load_recipe(path).recipe.assets

"""The bounded YAML reader (core/safe_yaml.py) and the input-file checks (core/files.py)."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
import yaml

from core.errors import ExportError, RecipeError, SourceError, UsageError
from core.files import (
    INPUT_LIMITS_MB,
    InputKind,
    check_input_file,
    check_output_folder,
    input_limit_bytes,
    read_input_bytes,
)
from core.recipe_loader import load_recipe, parse_recipe
from core.safe_yaml import MAX_DEPTH, MAX_VALUES, YamlLimitError, load_yaml
from core.variants import count_values, expand_assets


@pytest.mark.parametrize("text, value", [
    ("1e-3", 0.001), ("1E6", 1e6), ("-2.5e+3", -2500.0), ("012", 12), ("0o17", 15), ("0x1F", 31), ("+7", 7),
    ("1.", 1.0), (".5", 0.5), ("true", True), ("False", False), ("TRUE", True), ("null", None), ("~", None),
    ("yes", "yes"), ("NO", "NO"), ("on", "on"), ("1_000", "1_000"), ("1:20", "1:20"), ("2024-01-01", "2024-01-01"),
])
def test_scalars_follow_the_yaml_1_2_core_schema(text, value):
    assert load_yaml(f"v: {text}") == {"v": value}


def test_infinities_and_nan_are_floats_for_the_schema_to_refuse():
    data = load_yaml("a: .inf\nb: -.inf\nc: .nan")
    assert data["a"] == float("inf") and data["b"] == float("-inf") and data["c"] != data["c"]


def test_an_alias_bomb_is_refused_by_counting_without_expanding():
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 10)]
    started = time.perf_counter()
    with pytest.raises(YamlLimitError, match=f"{MAX_VALUES:,} values") as info:
        load_yaml("\n".join(lines))
    assert time.perf_counter() - started < 2 and info.value.line is not None


def test_small_aliases_and_merge_keys_still_work():
    data = load_yaml("base: &b {x: 1, y: 2}\nd: {<<: *b, y: 3}\ne: [*b, *b]")
    assert data["d"] == {"x": 1, "y": 3} and data["e"] == [{"x": 1, "y": 2}] * 2


def test_recursive_aliases_are_refused():
    with pytest.raises(YamlLimitError, match="recursive"):
        load_yaml("a: &x [1, *x]")


@pytest.mark.parametrize("opening, closing", [("[", "]"), ("{a: ", "}")])
def test_nesting_is_bounded_with_the_line_and_column(opening, closing):
    assert load_yaml("v: " + opening * (MAX_DEPTH - 1) + "1" * (opening == "{a: ") + closing * (MAX_DEPTH - 1))
    with pytest.raises(YamlLimitError, match=f"more than {MAX_DEPTH} levels") as info:
        load_yaml("\nv: " + opening * 5000 + "1" * (opening == "{a: ") + closing * 5000)
    assert info.value.line == 2 and info.value.column > MAX_DEPTH


@pytest.mark.parametrize("text, words", [
    ("a: 1\na: 2", "duplicate key 'a'"),
    ("{[1]: 2}", "mapping key"),
    ("a: {<<: {[1]: 2}}", "mapping key"),
    ("!!python/object/apply:os.system ['true']", "could not determine a constructor"),
])
def test_bad_keys_and_tags_are_yaml_errors(text, words):
    with pytest.raises(yaml.YAMLError, match=words.replace("[", r"\[")):
        load_yaml(text)


def test_recipe_errors_carry_line_and_column(tmp_path):
    with pytest.raises(RecipeError) as info:
        parse_recipe("version: 1\nassets: " + "[" * 200 + "]" * 200, Path("r.yaml"))
    assert info.value.field.startswith("line 2, column") and "levels" in info.value.message
    with pytest.raises(RecipeError, match="but found another document"):
        parse_recipe("version: 1\n---\nversion: 1\n", Path("r.yaml"))


def test_variant_caps_are_checked_before_expanding():
    raw = [{"name": f"a{i}", "variants": {"k": list(range(100)), "j": list(range(100))}} for i in range(50)]
    started = time.perf_counter()
    with pytest.raises(RecipeError, match="500,000 assets, more than the cap of 2,000") as info:
        expand_assets(raw)
    assert time.perf_counter() - started < 1 and "--max-assets" in info.value.hint
    big = [{"name": "a", "variants": {"k": list(range(50))}, "p": list(range(100_000)), "t": "${k}"}]
    with pytest.raises(RecipeError, match="values"):
        expand_assets(big)
    assert count_values({"a": [1, [2, 3]], "b": {}}) == 7


def test_deep_variant_data_is_substituted_without_recursion():
    deep: object = "${k}"
    for _ in range(5000):
        deep = [deep]
    (asset,), _ = expand_assets([{"name": "a", "variants": {"k": [7]}, "deep": deep}])
    for _ in range(5000):
        asset["deep"] = asset["deep"][0]
    assert asset["deep"] == 7


# --------------------------------------------------------------------------- input files


def test_input_kinds_are_checked_before_reading(tmp_path):
    with pytest.raises(SourceError, match="character device"):
        check_input_file("/dev/zero", InputKind.MESH, field="path")
    os.mkfifo(tmp_path / "pipe")
    with pytest.raises(SourceError, match="named pipe"):
        read_input_bytes(tmp_path / "pipe", InputKind.FONT)
    with pytest.raises(RecipeError, match="a folder"):
        read_input_bytes(tmp_path, InputKind.RECIPE, error=RecipeError)
    with pytest.raises(RecipeError, match="not found") as info:
        read_input_bytes(tmp_path / "nope.yaml", InputKind.RECIPE, error=RecipeError)
    assert info.value.hint == "check the path"


def test_sizes_are_checked_against_the_kind_limit_and_the_env_override(tmp_path, monkeypatch):
    big = tmp_path / "big.stl"
    with open(big, "wb") as handle:
        handle.truncate((INPUT_LIMITS_MB[InputKind.MESH] << 20) + 1)
    with pytest.raises(SourceError, match="256 MB limit") as info:
        check_input_file(big, InputKind.MESH, field="path")
    assert "DECOLLAGE_MAX_MESH_MB" in info.value.hint and info.value.field == "path"
    monkeypatch.setenv("DECOLLAGE_MAX_MESH_MB", "300")
    assert check_input_file(big, InputKind.MESH) == big
    assert input_limit_bytes(InputKind.MESH) == 300 << 20
    monkeypatch.setenv("DECOLLAGE_MAX_MESH_MB", "-3")
    with pytest.raises(UsageError, match="not a size"):
        input_limit_bytes(InputKind.MESH)


def test_a_recipe_is_read_within_its_limit(tmp_path):
    recipe = tmp_path / "r.yaml"
    recipe.write_text("version: 1\n" + "#" * (1 << 20))
    with pytest.raises(RecipeError, match="more than the 1 MB limit for recipe files"):
        load_recipe(recipe)


def test_output_folder_checks_write_nothing(tmp_path):
    out = tmp_path / "out"
    check_output_folder(out, folders=(".decollage",), files=("manifest.json",))
    assert not out.exists()
    out.mkdir()
    (out / ".decollage").write_text("x")
    with pytest.raises(ExportError, match="must be a folder"):
        check_output_folder(out, folders=(".decollage",))
    (out / ".decollage").unlink()
    (out / "manifest.json").mkdir()
    with pytest.raises(ExportError, match="must be a file"):
        check_output_folder(out, files=("manifest.json",))
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json"]
    (tmp_path / "file").write_text("x")
    with pytest.raises(ExportError, match="is a file"):
        check_output_folder(tmp_path / "file" / "out")

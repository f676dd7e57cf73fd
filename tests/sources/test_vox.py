"""The .vox codec and the vox source: round trip, scene placement, several models, palette mapping, bad files."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from core.errors import RecipeError, SourceError
from core.grid import EMPTY
from core.recipe import VoxSource
from core.recipe_loader import parse_recipe
from sources import load_source
from sources.vox_file import MAX_SIDE, model_grid, pack_rotation, read_vox, write_vox
from sources.voxels import rotate_grid


def _palette() -> np.ndarray:
    pal = np.zeros((256, 4), dtype=np.uint8)
    pal[1:] = np.random.default_rng(1).integers(0, 256, (255, 4))
    return pal


def _house() -> np.ndarray:
    """(6, 4, 7) palette indices, z up: a body of index 1, a roof of index 3, a door of index 7."""
    g = np.zeros((6, 4, 7), dtype=np.uint8)
    g[:, :, :4] = 1
    g[1:5, 1:3, 4:7] = 3
    g[2, 0, 0:2] = 7
    return g


def _spec(path: str = "a.vox", **kw) -> VoxSource:
    return VoxSource(kind="vox", path=path, **kw)


def test_codec_round_trip_is_identical():
    rng = np.random.default_rng(0)
    grid = np.where(rng.random((9, 13, 5)) < 0.3, rng.integers(1, 256, (9, 13, 5)), 0).astype(np.uint8)
    scene = read_vox(write_vox([grid], _palette()))
    assert scene.version == 200 and len(scene.models) == 1 and len(scene.instances) == 1
    assert np.array_equal(model_grid(scene.models[0]), grid)
    assert np.array_equal(scene.palette[1:], _palette()[1:])


def test_codec_round_trip_at_the_format_limit():
    grid = np.zeros((MAX_SIDE, 2, MAX_SIDE), dtype=np.uint8)
    grid[MAX_SIDE - 1, 1, MAX_SIDE - 1] = 255
    grid[0, 0, 0] = 1
    assert np.array_equal(model_grid(read_vox(write_vox([grid])).models[0]), grid)
    with pytest.raises(ValueError):
        write_vox([np.ones((MAX_SIDE + 1, 1, 1), dtype=np.uint8)])


def test_source_reads_parts_and_styles_in_the_canonical_frame(tmp_path):
    (tmp_path / "a.vox").write_bytes(write_vox([_house()], _palette()))
    spec = _spec(parts={"body": [1, 7], "roof": [3]}, styles={"cottage": [1, 3], "tower": [7]})
    got = load_source(spec, tmp_path)
    expected = rotate_grid(_house(), "z")  # MagicaVoxel z up → +Y up, front -Y → +Z
    assert got.part.shape == (6, 7, 4)
    assert got.part_names == ("body", "roof") and got.style_names == ("cottage", "tower")
    assert np.array_equal(got.part == EMPTY, expected == 0)
    assert np.array_equal(got.part[expected == 3], np.ones((expected == 3).sum(), dtype=np.int16))
    assert set(got.style[expected == 7].tolist()) == {1}
    assert got.input_files == [(tmp_path / "a.vox").resolve()]
    assert got.warnings == []


def test_default_parts_are_named_after_palette_indices_and_ignore_drops(tmp_path):
    (tmp_path / "a.vox").write_bytes(write_vox([_house()]))
    got = load_source(_spec(ignore=[7]), tmp_path)
    assert got.part_names == ("palette_1", "palette_3")
    assert (got.part != EMPTY).sum() == (_house() != 0).sum() - 2 and got.style is None


def test_unmapped_palette_index_is_an_error_naming_it(tmp_path):
    (tmp_path / "a.vox").write_bytes(write_vox([_house()], _palette()))
    with pytest.raises(SourceError) as info:
        load_source(_spec(parts={"body": [1], "roof": [3]}), tmp_path)
    assert info.value.field == "parts"
    assert "palette index 7 (#" in info.value.message and "2 voxels" in info.value.message
    assert "7" in info.value.hint


def test_unused_mapped_index_warns(tmp_path):
    (tmp_path / "a.vox").write_bytes(write_vox([_house()]))
    got = load_source(_spec(parts={"body": [1, 7, 9], "roof": [3]}), tmp_path)
    assert any("palette index 9 (part 'body') is used by no voxel" in w for w in got.warnings)


@pytest.mark.parametrize("source, message", [
    ("{kind: vox, path: a.vox, parts: {body: [1, 3], roof: [3]}}", "palette index 3 is mapped to two parts"),
    ("{kind: vox, path: a.vox, parts: {body: [0]}}", "greater than or equal to 1"),
    ("{kind: vox, path: a.vox, parts: {body: [256]}}", "less than or equal to 255"),
    ("{kind: vox, path: a.vox, parts: {body: [1]}, ignore: [1]}", "palette index 1 is both ignored and mapped"),
    ("{kind: vox, path: a.vox, parts: {body: [1, 2]}, styles: {moss: [1]}}",
     "palette index 2 has a part but no style"),
])
def test_recipe_mapping_errors_name_the_palette_index(source, message):
    text = f"version: 1\nassets:\n  - name: a\n    source: {source}\n    regions: [{{part: body, style: moss}}]\n"
    with pytest.raises(RecipeError) as info:
        parse_recipe(text, Path("r.yaml"))
    assert message in info.value.message
    assert info.value.field.startswith("assets[0].source")


def _two_models(tmp_path, **kw) -> Path:
    a = np.ones((2, 2, 3), dtype=np.uint8)
    b = np.full((3, 1, 1), 2, dtype=np.uint8)
    (tmp_path / "two.vox").write_bytes(write_vox([a, b], positions=[(0, 0, 0), (5, 1, 0)],
                                                 names=["tower", "wall"], **kw))
    return tmp_path / "two.vox"


def test_several_models_are_refused_with_their_list(tmp_path):
    _two_models(tmp_path)
    with pytest.raises(SourceError) as info:
        load_source(_spec("two.vox"), tmp_path)
    assert info.value.field == "model"
    assert "2 models" in info.value.message and "0: 'tower' 2×2×3, 1: 'wall' 3×1×1" in info.value.message
    assert "model: '@all'" in info.value.hint


def test_one_model_by_index_or_name_and_all_merged_as_placed(tmp_path):
    _two_models(tmp_path)
    by_name = load_source(_spec("two.vox", model="wall"), tmp_path)
    by_index = load_source(_spec("two.vox", model=1), tmp_path)
    assert by_name.part.shape == by_index.part.shape == rotate_grid(np.ones((3, 1, 1)), "z").shape
    merged = load_source(_spec("two.vox", model="@all", up_axis="y"), tmp_path)  # y: keep the file's axes
    expected = np.zeros((8, 2, 3), dtype=bool)  # tower at x 0..1, y 0..1, z 0..2; wall at x 5..7, y 1, z 0
    expected[0:2, 0:2, 0:3] = True
    expected[5:8, 1, 0] = True
    assert np.array_equal(merged.part != EMPTY, expected)
    with pytest.raises(SourceError, match="model 2 does not exist"):
        load_source(_spec("two.vox", model=2), tmp_path)
    with pytest.raises(SourceError, match="no model is named 'gate'"):
        load_source(_spec("two.vox", model="gate"), tmp_path)


def test_rotation_turns_the_model_about_its_centre(tmp_path):
    model = np.zeros((3, 2, 1), dtype=np.uint8)
    model[0, 0, 0], model[2, 1, 0] = 1, 2
    quarter = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]])  # +90° about z: x → y
    (tmp_path / "r.vox").write_bytes(write_vox([model], rotations=[quarter]))
    got = load_source(_spec("r.vox", up_axis="y"), tmp_path)
    assert np.array_equal(got.part != EMPTY, np.rot90(model != 0, k=1, axes=(0, 1)))
    assert pack_rotation(quarter) == 1 | 0 << 2 | 1 << 4  # row 0 → column 1 negative, row 1 → column 0


def test_merge_without_a_scene_graph_is_refused(tmp_path):
    def chunk(cid, content):
        return struct.pack("<4sii", cid, len(content), 0) + content
    body = b""
    for _ in range(2):
        body += chunk(b"SIZE", struct.pack("<iii", 1, 1, 1)) + chunk(b"XYZI", struct.pack("<i", 1) + bytes([0, 0, 0, 1]))
    data = b"VOX " + struct.pack("<i", 150) + struct.pack("<4sii", b"MAIN", 0, len(body)) + body
    (tmp_path / "old.vox").write_bytes(data)
    with pytest.raises(SourceError, match="no scene graph"):
        load_source(_spec("old.vox", model="@all"), tmp_path)
    assert load_source(_spec("old.vox", model=1), tmp_path).part.shape == (1, 1, 1)


def _valid() -> bytes:
    return write_vox([_house()], _palette())


@pytest.mark.parametrize("mutate, message", [
    (lambda b: b"", "the file is empty"),
    (lambda b: b"PK\x03\x04" + b[4:], "does not start with 'VOX '"),
    (lambda b: b[:4] + struct.pack("<i", 7) + b[8:], "unknown format version 7"),
    (lambda b: b[:60], "claims more bytes than the file has"),
    (lambda b: b.replace(struct.pack("<iii", 6, 4, 7), struct.pack("<iii", 6, 4, 300), 1), "outside 1..256"),
    (lambda b: b.replace(struct.pack("<iii", 6, 4, 7), struct.pack("<iii", 6, 4, 2), 1), "outside its size"),
])
def test_broken_files_are_refused_clearly(tmp_path, mutate, message):
    (tmp_path / "a.vox").write_bytes(mutate(_valid()))
    with pytest.raises(SourceError) as info:
        load_source(_spec(), tmp_path)
    assert info.value.field == "path" and message in info.value.message


def test_scene_graph_cycle_is_refused(tmp_path):
    data = bytearray(write_vox([_house()]))
    # the model's transform (node 2) points at its shape (node 3); point it back at the root instead
    marker = struct.pack("<i", 2) + struct.pack("<i", 0) + struct.pack("<iiii", 3, -1, 0, 1)
    at = bytes(data).index(marker)
    data[at + 8:at + 12] = struct.pack("<i", 0)
    (tmp_path / "a.vox").write_bytes(bytes(data))
    with pytest.raises(SourceError, match="cycle"):
        load_source(_spec(), tmp_path)


def test_wrong_extension_is_refused(tmp_path):
    (tmp_path / "a.npy").write_bytes(_valid())
    with pytest.raises(SourceError, match="unsupported format"):
        load_source(_spec("a.npy"), tmp_path)


def test_a_scene_graph_multiplying_models_is_refused(tmp_path):
    def chunk(cid, content):
        return struct.pack("<4sii", cid, len(content), 0) + content

    def ints(*values):
        return struct.pack(f"<{len(values)}i", *values)

    empty = ints(0)  # an empty DICT
    body = chunk(b"SIZE", ints(1, 1, 1)) + chunk(b"XYZI", ints(1) + bytes([0, 0, 0, 1]))
    body += chunk(b"nTRN", ints(0) + empty + ints(1, -1, -1, 1) + empty)
    # 20 levels of groups, each holding its child twice: 2**20 paths to one shape
    for level in range(20):
        group, transform = 1 + 2 * level, 2 + 2 * level
        body += chunk(b"nGRP", ints(group) + empty + ints(2, transform, transform))
        body += chunk(b"nTRN", ints(transform) + empty + ints(group + 2 if level < 19 else 99, -1, -1, 1) + empty)
    body += chunk(b"nSHP", ints(99) + empty + ints(1, 0) + empty)
    data = b"VOX " + ints(200) + struct.pack("<4sii", b"MAIN", 0, len(body)) + body
    (tmp_path / "bomb.vox").write_bytes(data)
    with pytest.raises(SourceError, match="places more than"):
        load_source(_spec("bomb.vox", model="@all"), tmp_path)

"""Voxels source: .npy / .npz layouts, up-axis rotation (agreeing with sources.frames), every error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from core.errors import SourceError
from core.grid import EMPTY
from core.recipe import UpAxis, VoxelsSource
from sources.frames import transform_points
from sources.voxels import load, rotate_grid


def _spec(path, **kwargs) -> VoxelsSource:
    return VoxelsSource(kind="voxels", path=str(path), **kwargs)


def _error(spec: VoxelsSource, base: Path) -> SourceError:
    with pytest.raises(SourceError) as info:
        load(spec, base)
    assert info.value.field == "path"
    return info.value


def _occupancy() -> np.ndarray:
    occ = np.zeros((4, 3, 2), dtype=np.uint8)
    occ[0, 0, 0] = 1
    occ[3, 2, 1] = 7
    occ[1, :, :] = 1
    return occ


def test_npy_is_one_part_named_voxels(tmp_path):
    np.save(tmp_path / "grid.npy", _occupancy())
    result = load(_spec("grid.npy", voxel_size_m=0.25), tmp_path)
    assert result.part_names == ("voxels",)
    assert result.part.dtype == np.int16 and result.part.shape == (4, 3, 2)
    assert np.array_equal(result.part != EMPTY, _occupancy() != 0)
    assert set(np.unique(result.part)) == {EMPTY, 0}
    assert result.voxel_size_m == 0.25
    assert result.style is None and result.style_names == ()
    assert result.input_files == [(tmp_path / "grid.npy").resolve()]


def test_npz_with_parts_and_styles(tmp_path):
    occ = _occupancy().astype(bool)
    part = np.full(occ.shape, 99)  # values in empty voxels are ignored
    part[occ] = 0
    part[3, 2, 1] = 1
    style = np.where(occ, 2, -5)
    np.savez(tmp_path / "g.npz", occupancy=occ, part=part, part_names=np.array(["body", "roof"]),
             style=style, style_names=np.array(["brick", "wood", "stone"]))
    result = load(_spec("g.npz"), tmp_path)
    assert result.part_names == ("body", "roof")
    assert result.part[3, 2, 1] == 1 and result.part[0, 0, 0] == 0 and result.part[2, 0, 0] == EMPTY
    assert result.style_names == ("brick", "wood", "stone")
    assert np.array_equal(result.style, np.where(occ, 2, EMPTY))
    assert result.warnings == []


def test_npz_default_names_and_unknown_keys(tmp_path):
    occ = _occupancy()
    np.savez(tmp_path / "g.npz", occupancy=occ, part=(occ != 0) * 2, style=np.zeros(occ.shape, int), notes=np.zeros(1))
    result = load(_spec("g.npz"), tmp_path)
    assert result.part_names == ("part_0", "part_1", "part_2")
    assert result.style_names == ("style_0",)
    assert result.warnings == ["ignored arrays in g.npz: notes (known: occupancy, part, part_names, style, style_names)"]


def test_npz_part_names_are_sanitised(tmp_path):
    occ = _occupancy()
    np.savez(tmp_path / "g.npz", occupancy=occ, part=np.zeros(occ.shape, int), part_names=np.array(["left arm", "left?arm"]))
    assert load(_spec("g.npz"), tmp_path).part_names == ("left_arm", "left_arm_2")


def test_up_axis_z_puts_input_z_up(tmp_path):
    occ = np.zeros((2, 3, 5), dtype=bool)
    occ[:, :, 4] = True  # the top layer in a Z-up file
    np.save(tmp_path / "z.npy", occ)
    part = load(_spec("z.npy", up_axis="z"), tmp_path).part
    assert part.shape == (2, 5, 3)
    assert (part[:, 4, :] == 0).all() and (part[:, :4, :] == EMPTY).all()


@pytest.mark.parametrize("up", list(UpAxis))
def test_grid_rotation_agrees_with_the_frames_rotation(up):
    rng = np.random.default_rng(3)
    shape = (3, 4, 5)
    grid = rng.integers(-1, 3, size=shape).astype(np.int16)
    rotated = rotate_grid(grid, up)
    # Where sources.frames sends each input voxel centre, relative to the rotated box's min corner.
    index = np.argwhere(np.ones(shape, bool))
    corners = np.array([[x, y, z] for x in (0, shape[0]) for y in (0, shape[1]) for z in (0, shape[2])], float)
    low = transform_points(corners, up, 1.0).min(axis=0)
    target = np.floor(transform_points(index + 0.5, up, 1.0) - low).astype(int)
    assert rotated.shape == tuple(int(n) for n in np.ptp(transform_points(corners, up, 1.0), axis=0))
    assert np.array_equal(rotated[tuple(target.T)], grid[tuple(index.T)])


# --------------------------------------------------------------------------- errors


def test_missing_file(tmp_path):
    err = _error(_spec("missing.npy"), tmp_path)
    assert str((tmp_path / "missing.npy").resolve()) in err.message


def test_wrong_extension(tmp_path):
    (tmp_path / "grid.vox").write_bytes(b"VOX ")
    err = _error(_spec("grid.vox"), tmp_path)
    assert "'.vox'" in err.message and ".npy" in err.hint and ".npz" in err.hint


@pytest.mark.parametrize("name", ["junk.npy", "junk.npz"])
def test_not_a_numpy_file(tmp_path, name):
    (tmp_path / name).write_bytes(b"definitely not numpy")
    assert _error(_spec(name), tmp_path).message == "cannot read voxels: not a NumPy .npy/.npz file"


def test_empty_file(tmp_path):
    (tmp_path / "e.npy").write_bytes(b"")
    assert _error(_spec("e.npy"), tmp_path).message == "cannot read voxels: the file is empty"


def test_truncated_npz(tmp_path):
    np.savez(tmp_path / "g.npz", occupancy=np.ones((4, 4, 4)))
    data = (tmp_path / "g.npz").read_bytes()
    (tmp_path / "g.npz").write_bytes(data[: len(data) // 2])
    assert _error(_spec("g.npz"), tmp_path).message.startswith("cannot read voxels:")


def test_pickled_objects_are_not_loaded(tmp_path):
    np.save(tmp_path / "o.npy", np.array([{"a": 1}, None], dtype=object), allow_pickle=True)
    assert "Python objects" in _error(_spec("o.npy"), tmp_path).message


def test_wrong_ndim(tmp_path):
    np.save(tmp_path / "flat.npy", np.ones((4, 4)))
    err = _error(_spec("flat.npy"), tmp_path)
    assert err.message == "the array must be 3-D (x, y, z), got 2-D with shape (4, 4)"


def test_non_numeric_occupancy(tmp_path):
    np.save(tmp_path / "s.npy", np.full((2, 2, 2), "x"))
    assert "numbers or booleans" in _error(_spec("s.npy"), tmp_path).message


def test_missing_occupancy_key(tmp_path):
    np.savez(tmp_path / "g.npz", occ=np.ones((2, 2, 2)), part=np.zeros((2, 2, 2), int))
    err = _error(_spec("g.npz"), tmp_path)
    assert err.message == "the .npz has no 'occupancy' array (found: occ, part)"


def test_part_shape_mismatch(tmp_path):
    np.savez(tmp_path / "g.npz", occupancy=np.ones((2, 2, 2)), part=np.zeros((2, 2, 3), int))
    err = _error(_spec("g.npz"), tmp_path)
    assert err.message == "'part' has shape (2, 2, 3) but 'occupancy' has (2, 2, 2)"


def test_part_must_be_integers(tmp_path):
    np.savez(tmp_path / "g.npz", occupancy=np.ones((2, 2, 2)), part=np.zeros((2, 2, 2)))
    assert "'part' must be an integer array" in _error(_spec("g.npz"), tmp_path).message


def test_part_index_out_of_range(tmp_path):
    part = np.zeros((2, 2, 2), int)
    part[1, 1, 1] = 2
    np.savez(tmp_path / "g.npz", occupancy=np.ones((2, 2, 2)), part=part, part_names=np.array(["a", "b"]))
    err = _error(_spec("g.npz"), tmp_path)
    assert err.message == "'part' index 2 is out of range for 2 part name(s) (occupied voxels need 0..1)"


def test_negative_style_in_an_occupied_voxel(tmp_path):
    style = np.zeros((2, 2, 2), int)
    style[0, 0, 0] = -1
    np.savez(tmp_path / "g.npz", occupancy=np.ones((2, 2, 2)), style=style)
    assert "'style' index -1 is out of range" in _error(_spec("g.npz"), tmp_path).message


def test_names_without_indices(tmp_path):
    np.savez(tmp_path / "g.npz", occupancy=np.ones((2, 2, 2)), part_names=np.array(["a"]))
    assert _error(_spec("g.npz"), tmp_path).message == "'part_names' is given but 'part' is not"


def test_bad_names_array(tmp_path):
    np.savez(tmp_path / "g.npz", occupancy=np.ones((2, 2, 2)), part=np.zeros((2, 2, 2), int),
             part_names=np.array([1, 2]))
    assert "'part_names' must be a non-empty 1-D array of strings" in _error(_spec("g.npz"), tmp_path).message


def test_all_empty_grid(tmp_path):
    np.save(tmp_path / "empty.npy", np.zeros((3, 3, 3)))
    assert "empty" in _error(_spec("empty.npy"), tmp_path).message


def _npz_with(path: Path, members: dict[str, bytes]) -> None:
    import zipfile

    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)


def _npy(array: np.ndarray) -> bytes:
    import io

    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=True)
    return buffer.getvalue()


def test_headers_are_checked_before_any_array_is_loaded(tmp_path, monkeypatch):
    from sources.voxels import inspect_arrays

    _npz_with(tmp_path / "bomb.npz", {"occupancy.npy": _npy(np.zeros((64, 128, 128), np.uint8))})
    assert inspect_arrays(tmp_path / "bomb.npz") == {"occupancy": ((64, 128, 128), np.dtype(np.uint8))}
    monkeypatch.setenv("DECOLLAGE_MAX_VOXELS_MB", "0.5")
    assert "unpacks to 1.0 MB, more than the 0.5 MB limit" in _error(_spec("bomb.npz"), tmp_path).message
    monkeypatch.delenv("DECOLLAGE_MAX_VOXELS_MB")
    header = _npy(np.zeros((2, 2, 2), np.uint8))
    lying = header.replace(b"(2, 2, 2), }", b"(4096, 4096, 4096)}")  # same length: only the claim changes
    (tmp_path / "lie.npy").write_bytes(lying)
    assert "MB limit for voxels files" in _error(_spec("lie.npy"), tmp_path).message
    _npz_with(tmp_path / "obj.npz", {"occupancy.npy": _npy(np.array([None, 1], dtype=object))})
    assert "Python objects" in _error(_spec("obj.npz"), tmp_path).message
    _npz_with(tmp_path / "many.npz", {f"a{i}.npy": _npy(np.zeros(1)) for i in range(20)})
    assert "more than 16" in _error(_spec("many.npz"), tmp_path).message


def test_preflight_checks_rank_and_presence_without_loading(tmp_path):
    from sources.voxels import preflight

    np.save(tmp_path / "flat.npy", np.ones((3, 3), np.uint8))
    with pytest.raises(SourceError, match="must be 3-D"):
        preflight(_spec("flat.npy"), tmp_path)
    np.savez(tmp_path / "nothing.npz", part=np.ones((2, 2, 2), np.int16))
    with pytest.raises(SourceError, match="no 'occupancy'"):
        preflight(_spec("nothing.npz"), tmp_path)

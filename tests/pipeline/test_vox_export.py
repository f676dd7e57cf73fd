""".vox export: the coarse grid comes back identical through the vox source, the fine grid fits 256 per side."""

from __future__ import annotations

import numpy as np
import pytest

from core.grid import EMPTY, FineGrid, LabeledGrid
from core.recipe import FitMode, GridSettings, RegionRule, UpAxis, VoxSource
from geometry.voxelize import voxelize
from pipeline.regions import apply_regions
from pipeline.vox_export import coarse_vox, fine_vox, to_file_frame
from sources import load_source
from sources.vox_file import MAX_SIDE, model_grid, read_vox
from sources.voxels import rotate_grid


@pytest.mark.parametrize("up", list(UpAxis))
def test_file_frame_inverts_the_source_rotation(up):
    grid = np.arange(2 * 3 * 5).reshape(2, 3, 5)
    assert np.array_equal(rotate_grid(to_file_frame(grid, up), up), grid)


def _labelled(shape=(6, 5, 4), seed=0) -> LabeledGrid:
    """A grid touching every side (the vox source crops to the occupied box), 2 parts × 3 styles."""
    rng = np.random.default_rng(seed)
    occ = rng.random(shape) < 0.6
    occ[0, 0, 0] = occ[-1, -1, -1] = True
    part = np.where(occ, rng.integers(0, 2, shape), EMPTY).astype(np.int16)
    style = np.where(occ, rng.integers(0, 3, shape), EMPTY).astype(np.int16)
    return LabeledGrid(occ, part, style, ("body", "roof"), ("cottage", "tower", "moss"), 0.1)


def _read_back(tmp_path, data: bytes, record: dict, voxel_size_m: float) -> LabeledGrid:
    """The exported file through the vox source, the voxelizer and '@source' regions, as a recipe would."""
    (tmp_path / "a.vox").write_bytes(data)
    mapping = {k: v for k, v in record["source"].items() if k != "kind"}
    source = load_source(VoxSource(kind="vox", path="a.vox", voxel_size_m=voxel_size_m, **mapping), tmp_path)
    settings = GridSettings(fit=FitMode.VOXEL_SIZE, voxel_size_m=voxel_size_m, max_cells=1024)
    grid, _ = apply_regions(voxelize(source, settings, FitMode.VOXEL_SIZE),
                            [RegionRule(part="@source", style="@source")])
    return grid


def _same_labels(a: LabeledGrid, b: LabeledGrid) -> bool:
    names = lambda g, arr, vocab: np.where(g.occupancy, np.asarray(vocab, dtype=object)[arr.clip(0)], None)  # noqa: E731
    return (a.shape == b.shape and np.array_equal(a.occupancy, b.occupancy)
            and np.array_equal(names(a, a.part, a.part_names), names(b, b.part, b.part_names))
            and np.array_equal(names(a, a.style, a.style_names), names(b, b.style, b.style_names)))


def test_coarse_grid_round_trips_through_the_vox_source(tmp_path):
    grid = _labelled()
    data, record = coarse_vox(grid)
    assert record["models"] == 1 and record["source"]["kind"] == "vox"
    assert sorted(record["source"]["parts"]) == ["body", "roof"]
    back = _read_back(tmp_path, data, record, grid.voxel_size_m)
    assert _same_labels(grid, back)


def test_coarse_grid_longer_than_the_format_limit_is_tiled(tmp_path):
    grid = _labelled(shape=(MAX_SIDE + 40, 3, 2), seed=1)
    data, record = coarse_vox(grid)
    scene = read_vox(data)
    assert record["models"] == 2 and record["source"]["model"] == "@all"
    assert all(max(m.size) <= MAX_SIDE for m in scene.models)
    assert _same_labels(grid, _read_back(tmp_path, data, record, grid.voxel_size_m))


def _fine(shape, styles=("cottage", "tower")) -> FineGrid:
    occ = np.zeros(shape, dtype=np.float32)
    occ[: shape[0] // 2] = 1.0
    style = np.zeros(shape, dtype=np.int16)
    style[:, shape[1] // 2:] = 1
    return FineGrid(occ, style, styles, 0.01)


def test_fine_grid_at_256_is_written_voxel_for_voxel():
    fine = _fine((256, 64, 32))
    data, record = fine_vox(fine)
    assert record["downsample"] == 1 and record["palette"] == {"1": "cottage", "2": "tower"}
    labels = model_grid(read_vox(data).models[0])
    expected = np.where(fine.occupancy >= 0.4, fine.style + 1, 0).astype(np.uint8)
    assert np.array_equal(labels, to_file_frame(expected))


def test_fine_grid_above_256_is_downsampled_to_fit():
    fine = _fine((16 * 20, 32, 48))  # a 20-cell-long coarse grid: 320 fine voxels
    data, record = fine_vox(fine)
    model = read_vox(data).models[0]
    assert record["downsample"] == 2 and max(model.size) <= MAX_SIDE
    labels = rotate_grid(model_grid(model), "z")
    assert labels.shape == (160, 16, 24)
    assert (labels[:80] > 0).all() and (labels[80:] == 0).all()
    assert set(np.unique(labels[:80, :8])) == {1} and set(np.unique(labels[:80, 8:])) == {2}


def test_a_fine_vox_built_block_by_block_is_the_whole_grids():
    from pipeline.vox_export import FineVox

    rng = np.random.default_rng(2)
    fine = FineGrid((rng.random((16 * 40, 48, 32)) < 0.55).astype(np.float32),
                    rng.integers(0, 3, (16 * 40, 48, 32)).astype(np.int16), ("cottage", "tower", "druse"), 0.01)
    whole, record = fine_vox(fine)
    assert record["downsample"] == 3  # 640 fine columns: blocks of 32 cells do not fall on its boundaries
    writer = FineVox(fine.shape, fine.style_names)
    for x0 in range(0, fine.shape[0], 16 * 12):
        writer.add(x0, fine.occupancy[x0:x0 + 16 * 12], fine.style[x0:x0 + 16 * 12])
    assert writer.encode() == (whole, record)

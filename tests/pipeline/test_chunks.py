"""Block-by-block detailizing and meshing of long grids (pipeline/chunks.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from scipy.spatial import cKDTree

import pipeline.chunks as chunks
from core.grid import UPSAMPLE_FACTOR, FineGrid, LabeledGrid
from core.structure import strict_loose_iou
from pipeline.chunks import Chunk, budget_shares, detailize_and_mesh, merge_extras, plan_chunks
from pipeline.mesh import MeshSettings

F = UPSAMPLE_FACTOR


def bar_grid(length: int = 40) -> LabeledGrid:
    """A bar along x with a bump every 7 cells and two styles in bands of 10 cells: surface crosses every seam."""
    occ = np.zeros((length, 4, 3), bool)
    occ[:, 1:3, 1:2] = True
    occ[::7, 3, 1] = True
    style = np.where(occ, np.arange(length)[:, None, None] // 10 % 2, -1).astype(np.int16)
    return LabeledGrid(occ, np.where(occ, 0, -1).astype(np.int16), style, ("body",), ("brick", "slate"), 0.1,
                       (0.5, -0.2, 0.0))


def local_detailizer(grid: LabeledGrid) -> FineGrid:
    """A detailizer whose output at a voxel depends only on cells within 1 coarse cell (the halo is 2)."""
    fine = grid.occupancy.repeat(F, 0).repeat(F, 1).repeat(F, 2).astype(np.float32)
    fine = ndimage.gaussian_filter(fine, 1.5, truncate=4.0)  # radius 6 fine voxels
    x = np.arange(fine.shape[0])[:, None, None] + grid.origin_m[0] / grid.voxel_size_m * F
    fine *= (0.9 + 0.1 * np.sin(x * 0.37)).astype(np.float32)  # vertices off round positions, same in every block
    style = np.maximum(grid.style, 0).repeat(F, 0).repeat(F, 1).repeat(F, 2)
    return FineGrid(fine, style, grid.style_names, grid.voxel_size_m / F, grid.origin_m,
                    extras={"exemplars": [f"ex{int(grid.origin_m[0] * 10)}"], "seed": 0})


@pytest.fixture
def small_blocks(monkeypatch):
    monkeypatch.setattr(chunks, "WHOLE_MAX_CELLS", 16)
    monkeypatch.setattr(chunks, "CHUNK_CELLS", 1)
    monkeypatch.setattr(chunks, "CHUNK_MAX_CELLS", 12 * 4 * 3)  # 12 columns of bar_grid's 4 × 3


def _rod(length: int) -> np.ndarray:
    occ = np.zeros((length, 4, 3), bool)
    occ[:, 1, 1] = True
    return occ


def test_plan_covers_the_columns_once_with_a_halo(small_blocks):
    assert plan_chunks(_rod(16)) == [Chunk(0, 16, 0, 16)]
    plan = plan_chunks(_rod(40))
    # ⌈40 / 12⌉ = 4 blocks (an even count) of equal occupied cells
    assert [(c.start, c.stop) for c in plan] == [(0, 10), (10, 20), (20, 30), (30, 40)]
    assert [(c.lo, c.hi) for c in plan] == [(0, 12), (8, 22), (18, 32), (28, 40)]
    assert chunks.detail_shape((40, 4, 3)) == (16, 4, 3)  # the widest block the plan may cut (12) + context
    assert chunks.detail_shape((16, 4, 3)) == (16, 4, 3)
    # ⌈25 / 12⌉ = 3 blocks, made 4 so that two processes get halves of the same work; 25 = 7 + 6 + 6 + 6
    assert [(c.start, c.stop) for c in plan_chunks(_rod(25))] == [(0, 7), (7, 13), (13, 19), (19, 25)]


def test_plan_cuts_blocks_of_equal_occupied_cells_within_the_width(small_blocks, monkeypatch):
    occ = _rod(40)
    occ[:10, 1, :] = True  # the first quarter holds 30 of the 60 occupied cells
    monkeypatch.setattr(chunks, "CHUNK_MAX_CELLS", 30 * 4 * 3)  # blocks up to 30 columns: two blocks
    assert [(c.start, c.stop) for c in plan_chunks(occ)] == [(0, 10), (10, 40)]
    monkeypatch.setattr(chunks, "CHUNK_MAX_CELLS", 24 * 4 * 3)  # equal shares would make one 30 wide
    assert [(c.start, c.stop) for c in plan_chunks(occ)] == [(0, 20), (20, 40)]
    assert plan_chunks(np.zeros((40, 4, 3), bool))[0] == Chunk(0, 20, 0, 22)  # nothing to share
    monkeypatch.setattr(chunks, "CHUNK_MAX_CELLS", 12)  # a fat cross-section keeps CHUNK_CELLS columns a block
    monkeypatch.setattr(chunks, "CHUNK_CELLS", 15)
    assert [(c.start, c.stop) for c in plan_chunks(occ)] == [(0, 5), (5, 10), (10, 25), (25, 40)]
    assert chunks.detail_shape((40, 4, 3)) == (19, 4, 3)
    # a grid just over the whole-block length still goes to two processes
    assert [(c.start, c.stop) for c in plan_chunks(_rod(17))] == [(0, 9), (9, 17)]


@pytest.mark.parametrize("step", [1, 2])
def test_blocks_join_into_the_same_closed_mesh_as_the_whole_grid(small_blocks, monkeypatch, step):
    grid = bar_grid()
    settings = MeshSettings(max_triangles=None, sample_step=step)
    parts = detailize_and_mesh(grid, local_detailizer, settings)
    monkeypatch.setattr(chunks, "WHOLE_MAX_CELLS", 1000)
    halves = detailize_and_mesh(grid, local_detailizer, settings)  # detailized whole, meshed as two pieces
    monkeypatch.setattr(chunks, "MESH_SPLIT_MIN_CELLS", 1000)
    whole = detailize_and_mesh(grid, local_detailizer, settings)
    assert parts.chunks == 4 and whole.chunks == 1 and halves.chunks == 1
    assert halves.mesh.is_watertight and len(halves.mesh.faces) == len(whole.mesh.faces)
    assert cKDTree(whole.mesh.vertices).query(halves.mesh.vertices)[0].max() < 1e-6
    assert parts.mesh.is_watertight and whole.mesh.is_watertight
    # the same surface: the same vertices (welded on the seams; float32 rounding apart) and as many faces
    assert len(parts.mesh.vertices) == len(whole.mesh.vertices) and len(parts.mesh.faces) == len(whole.mesh.faces)
    gap, _ = cKDTree(whole.mesh.vertices).query(parts.mesh.vertices)
    assert gap.max() < 1e-6
    assert parts.mesh.volume == pytest.approx(whole.mesh.volume, rel=1e-6)
    strict, loose = strict_loose_iou(local_detailizer(grid).occupancy, grid.occupancy)
    assert parts.structure == {"strict_iou": round(strict, 4), "loose_iou": round(loose, 4)}
    assert parts.fine_shape == tuple(n * F for n in grid.shape)
    # colours follow the style bands across seams
    colours = {tuple(c) for c in np.asarray(parts.mesh.visual.vertex_colors)}
    assert len(colours) == 2


@pytest.mark.parametrize("taubin,step", [(0, 1), (3, 1), (3, 2)])
def test_decimated_and_smoothed_blocks_stay_closed_within_the_budget(small_blocks, taubin, step):
    grid = bar_grid()
    result = detailize_and_mesh(grid, local_detailizer, MeshSettings(max_triangles=6000, taubin_iterations=taubin,
                                                                     sample_step=step))
    assert result.mesh.is_watertight and result.mesh.volume > 0
    assert 0.8 * 6000 <= len(result.mesh.faces) <= 6000


def test_budget_follows_the_coarse_surface(small_blocks):
    grid = bar_grid()
    plan = plan_chunks(grid.occupancy)
    shares = budget_shares(grid.occupancy, plan, 10_000)
    assert sum(shares) <= 10_000
    surface = [chunks.coarse_surface_faces(grid.occupancy[c.start:c.stop]).sum() for c in plan]
    assert np.argmax(shares) == np.argmax(surface) and np.argmin(shares) == np.argmin(surface)
    assert budget_shares(grid.occupancy, plan, None) == [None] * 4


def test_two_processes_give_the_same_mesh_bit_for_bit(small_blocks):
    grid = bar_grid(45)
    settings = MeshSettings(max_triangles=5000, taubin_iterations=3)
    one_t: dict[str, float] = {}
    two_t: dict[str, float] = {}
    one = detailize_and_mesh(grid, local_detailizer, settings, one_t, processes=1)
    two = detailize_and_mesh(grid, local_detailizer, settings, two_t, processes=2)
    assert one.chunks == two.chunks == 4
    assert np.array_equal(one.mesh.vertices, two.mesh.vertices) and np.array_equal(one.mesh.faces, two.mesh.faces)
    assert np.array_equal(one.mesh.visual.vertex_colors, two.mesh.visual.vertex_colors)
    assert one.structure == two.structure and one.extras == two.extras
    assert set(two_t) == {"detailize", "mesh"} and all(t > 0 for t in two_t.values())


def test_one_block_meshed_in_two_processes_equals_one_process_bit_for_bit(small_blocks, monkeypatch):
    monkeypatch.setattr(chunks, "WHOLE_MAX_CELLS", 1000)  # one block, detailized whole, meshed as two pieces
    calls = []

    def counted(grid: LabeledGrid) -> FineGrid:
        calls.append(grid.shape)
        return local_detailizer(grid)

    grid = bar_grid(45)
    settings = MeshSettings(max_triangles=5000, taubin_iterations=3)
    one = detailize_and_mesh(grid, counted, settings, processes=1)
    two = detailize_and_mesh(grid, counted, settings, processes=2)
    assert calls == [grid.shape, grid.shape]  # once per build: the pieces are columns of the one field
    assert one.chunks == two.chunks == 1 and one.mesh.is_watertight and len(one.mesh.faces) <= 5000
    assert np.array_equal(one.mesh.vertices, two.mesh.vertices) and np.array_equal(one.mesh.faces, two.mesh.faces)
    assert one.structure == two.structure


def test_a_column_detailizer_gives_each_piece_its_own_columns_bit_for_bit_in_two_processes(monkeypatch):
    """With ``columns`` (the learned model's ``column_detailizer``) the two pieces of one block are detailized
    apart after one shared step; one or two processes give the same bytes, and the whole field is never made."""
    shared, parts = [], []

    def columns(grid: LabeledGrid):
        shared.append(grid.shape)
        whole = local_detailizer(grid)  # the shared work: each part below is cut from it, as a real model's is

        def part(start: int, stop: int) -> FineGrid:
            parts.append((start, stop))
            origin = (grid.origin_m[0] + start * grid.voxel_size_m, *grid.origin_m[1:])
            return FineGrid(whole.occupancy[start * F:stop * F].copy(), whole.style[start * F:stop * F].copy(),
                            grid.style_names, whole.voxel_size_m, origin, extras=whole.extras)
        return part

    def never(grid: LabeledGrid) -> FineGrid:
        raise AssertionError("the whole grid was detailized")

    grid = bar_grid(30)
    settings = MeshSettings(max_triangles=5000, taubin_iterations=3)
    one = detailize_and_mesh(grid, never, settings, processes=1, columns=columns)
    two = detailize_and_mesh(grid, never, settings, processes=2, columns=columns)
    split = chunks.mesh_halves(grid.occupancy)[1].start
    # one process: both parts; two: this one's (the child's part is computed in the child, unseen here)
    assert shared == [grid.shape] * 2 and parts == [(0, split), (split, 30), (0, split)]
    assert one.chunks == two.chunks == 2 and one.mesh.is_watertight
    assert np.array_equal(one.mesh.vertices, two.mesh.vertices) and np.array_equal(one.mesh.faces, two.mesh.faces)
    assert one.structure == two.structure
    reference = detailize_and_mesh(grid, local_detailizer, settings)  # the same field, detailized whole
    assert len(reference.mesh.faces) == len(one.mesh.faces) and one.structure == reference.structure


def test_a_thin_feature_on_a_seam_welds_at_half_resolution(small_blocks):
    """A cell whose material is thinner than a sample is raised to keep it (``keep_thin_cells``); when that cell
    starts a block, the plane it shares with the previous block must stay as that block meshes it."""
    grid = bar_grid(40)
    occ = grid.occupancy.copy()
    occ[10, 3, 1] = True  # a cell above the bar, right after the seam at column 10 (plan: 0-10, 10-20, ...)
    grid = LabeledGrid(occ, np.where(occ, 0, -1).astype(np.int16), np.where(occ, 0, -1).astype(np.int16),
                       grid.part_names, grid.style_names, grid.voxel_size_m, grid.origin_m)

    def sheet(columns: LabeledGrid) -> FineGrid:
        fine = local_detailizer(columns)
        x0 = 10 * F - int(round(columns.origin_m[0] / columns.voxel_size_m - grid.origin_m[0] / grid.voxel_size_m)) * F
        if 0 <= x0 < fine.occupancy.shape[0]:
            fine.occupancy[x0:x0 + F, 3 * F:4 * F, F:2 * F] = 0.0
            fine.occupancy[x0:x0 + F, 3 * F, F + 2:2 * F - 2] = 1.0  # a sheet one voxel thick, on the bar's top
        return fine

    mesh = detailize_and_mesh(grid, sheet, MeshSettings(max_triangles=None, sample_step=2)).mesh
    assert mesh.is_watertight


def test_mesh_halves_balance_the_coarse_surface():
    occ = np.zeros((20, 4, 4), bool)
    occ[:, 1:3, 1:3] = True
    assert chunks.mesh_halves(occ) == [Chunk(0, 10, 0, 20), Chunk(10, 20, 0, 20)]
    occ[:5] = True  # a wide first quarter: more surface there
    (first, second) = chunks.mesh_halves(occ)
    assert first.stop < 10 and second.start == first.stop and second.stop == 20


def test_the_split_balances_the_blocks_work():
    occ = np.zeros((40, 4, 4), bool)
    occ[:, 1:3, 1:3] = True
    plan = [Chunk(0, 10, 0, 12), Chunk(10, 20, 8, 22), Chunk(20, 30, 18, 32), Chunk(30, 40, 28, 40)]
    assert chunks.split_blocks(occ, plan) == 2
    occ[:10] = True  # the first block holds most of the surface
    assert chunks.split_blocks(occ, plan) == 1


def test_an_error_in_the_second_process_is_raised_as_itself(small_blocks):
    from core.errors import DetailizeError

    def failing(grid: LabeledGrid) -> FineGrid:
        if grid.origin_m[0] > 2.0:  # blocks of the second half
            raise DetailizeError("no exemplar for style 'slate'", field="regions", hint="add one")
        return local_detailizer(grid)

    with pytest.raises(DetailizeError, match="no exemplar for style 'slate'") as caught:
        detailize_and_mesh(bar_grid(45), failing, MeshSettings(max_triangles=None), processes=2)
    assert caught.value.field == "regions" and caught.value.hint == "add one"


def test_extras_of_blocks_are_merged():
    merged = merge_extras([{"exemplars": ["a", "b"], "seed": 1}, {"exemplars": ["b", "c"], "seed": 2}])
    assert merged == {"exemplars": ["a", "b", "c"], "seed": 1}


def test_timings_are_added_per_stage(small_blocks):
    timings: dict[str, float] = {}
    detailize_and_mesh(bar_grid(), local_detailizer, MeshSettings(max_triangles=4000), timings)
    assert set(timings) == {"detailize", "mesh"} and all(t > 0 for t in timings.values())


_PEAK_RSS = """
import json, sys
sys.argv = ["decollage", *sys.argv[1:]]
from cli.app import main
from core.processes import children_peak_rss_mb, own_peak_rss_mb
try:
    main()
finally:
    print(json.dumps({"peak_mb": own_peak_rss_mb() + children_peak_rss_mb()}), file=sys.stderr)
"""


@pytest.mark.e2e  # a whole 20-letter build with the shipped model (about a minute on 2 cores)
def test_a_20_letter_word_builds_with_default_settings_within_2_gb(tmp_path):
    import json
    import subprocess
    import sys
    from pathlib import Path

    recipe = tmp_path / "long.yaml"
    recipe.write_text("""version: 1
assets:
  - name: long
    source: {kind: text, text: ABCDEFGHIJKLMNOPQRST, size_m: 0.5, depth_m: 0.12}
    regions:
      - {parts: ["*"], part: bottom, style: tower}
      - {band: {from: 0.65}, part: top, style: druse}
""")
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-c", _PEAK_RSS, "build", str(recipe), "-o", str(out), "--quiet"],
                          cwd=Path(__file__).resolve().parents[2], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    peak_mb = json.loads(proc.stderr.strip().splitlines()[-1])["peak_mb"]
    entry = json.loads((out / "manifest.json").read_text())["assets"][0]
    # 364 columns of 21 × 6 cells: blocks of at most CHUNK_MAX_CELLS // 126 = 65 columns, an even count
    assert entry["status"] == "built" and entry["chunks"] == 6
    assert entry["coarse_grid"]["shape"][0] > 256  # longer than the old grid.max_cells
    assert entry["mesh"]["triangles"] <= 60_000 and entry["structure"]["strict_iou"] > 0.9
    print(f"peak RSS {peak_mb:.0f} MB")
    assert peak_mb < 2000, f"peak RSS {peak_mb:.0f} MB"

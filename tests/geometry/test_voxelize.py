"""Voxelizer: grid sizing, solid fill, labels, keep_thin, errors, voxels resampling (known answers)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from core.errors import VoxelizeError
from core.grid import EMPTY
from core.recipe import FitMode, GridSettings
from geometry.voxelize import PartGrid, solid_occupancy, voxelize
from sources.base import PartMeshes, PartVoxels


def _box(size, at=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    mesh = trimesh.creation.box(extents=size)
    mesh.apply_translation(at)
    return mesh


def _grid(parts: dict, mode: FitMode = FitMode.LONGEST, **settings) -> PartGrid:
    return voxelize(PartMeshes(parts=parts), GridSettings(**settings), mode)


def _count(grid: PartGrid) -> int:
    return int((grid.part != EMPTY).sum())


# --------------------------------------------------------------------------- sizing and simple solids


def test_box_fills_exactly_its_voxels_and_sits_at_the_origin():
    grid = _grid({"box": _box((4.0, 2.0, 1.0), at=(10.0, 1.0, -3.0))})
    assert grid.shape == (16, 8, 4)
    assert grid.voxel_size_m == pytest.approx(0.25)
    assert grid.origin_m == pytest.approx((8.0, 0.0, -3.5))
    assert _count(grid) == 16 * 8 * 4
    assert grid.part.dtype == np.int16 and grid.part_names == ("box",)
    assert grid.warnings == ()


def test_box_is_centred_when_its_extent_is_not_a_whole_number_of_voxels():
    # 4 × 1.1 × 1: voxel 0.25 → Y needs ceil(4.4) = 5 voxels; the box is centred in them,
    # so the two end layers are 0.7 covered: 3 of 4 sample rows (coverage 0.75).
    box = {"box": _box((4.0, 1.1, 1.0))}
    grid = _grid(box)
    assert grid.shape == (16, 5, 4)
    assert grid.origin_m[1] == pytest.approx(-0.625)
    assert (grid.part == 0).all()
    strict = _grid(box, min_coverage=0.8)
    assert (strict.part[:, [0, 4], :] == EMPTY).all()
    assert (strict.part[:, 1:4, :] == 0).all()


def test_sphere_voxel_count_matches_its_volume():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    grid = _grid({"ball": sphere})
    assert grid.shape == (16, 16, 16)
    expected = 4.0 / 3.0 * math.pi * 8.0 ** 3  # radius 8 voxels
    assert _count(grid) == pytest.approx(expected, rel=0.03)
    # Symmetric under mirroring every axis.
    occ = grid.part != EMPTY
    assert np.array_equal(occ, occ[::-1, ::-1, ::-1])


def test_fit_height_grows_x_for_a_wide_shape():
    grid = _grid({"wide": _box((4.0, 1.0, 1.0))}, FitMode.HEIGHT)
    assert grid.shape == (64, 16, 16)
    assert grid.voxel_size_m == pytest.approx(1.0 / 16)
    assert _count(grid) == 64 * 16 * 16


def test_fit_voxel_size_uses_the_given_size():
    grid = _grid({"box": _box((1.0, 0.5, 0.25))}, FitMode.VOXEL_SIZE, fit=FitMode.VOXEL_SIZE, voxel_size_m=0.125)
    assert grid.shape == (8, 4, 2)
    assert _count(grid) == 64


def test_too_many_cells_is_refused_with_the_dims():
    with pytest.raises(VoxelizeError) as info:
        _grid({"wide": _box((80.0, 1.0, 1.0))}, FitMode.HEIGHT)
    err = info.value
    assert err.field == "grid"
    assert "1280×16×16" in err.message and "max_cells = 1024" in err.message
    assert err.hint.startswith("lower grid.resolution or raise grid.max_cells")


# --------------------------------------------------------------------------- parts, overlaps, open and hollow meshes


def test_two_boxes_side_by_side_get_their_own_labels():
    grid = _grid({"left": _box((2.0, 1.0, 1.0), at=(-1.0, 0, 0)), "right": _box((2.0, 1.0, 1.0), at=(1.0, 0, 0))})
    assert grid.shape == (16, 4, 4)
    assert (grid.part[:8] == 0).all()
    assert (grid.part[8:] == 1).all()


def test_overlap_between_parts_goes_to_the_earlier_part_on_ties():
    grid = _grid({"a": _box((2.0, 2.0, 2.0)), "b": _box((2.0, 2.0, 2.0), at=(1.0, 0, 0))})
    # x extent 3 → voxel 3/16; a covers x < 2 m from the left = 10.67 voxels.
    row = grid.part[:, 5, 5]
    assert (row[:10] == 0).all() and (row[11:] == 1).all()
    # Voxel 10 is 2/3 inside 'a' and fully inside 'b': the larger coverage wins.
    assert row[10] == 1


def test_overlapping_bodies_in_one_part_do_not_cancel():
    both = trimesh.util.concatenate([_box((2.0, 2.0, 2.0)), _box((2.0, 2.0, 2.0), at=(1.0, 0, 0))])
    assert both.is_watertight
    single = _grid({"both": both})
    separate = _grid({"a": _box((2.0, 2.0, 2.0)), "b": _box((2.0, 2.0, 2.0), at=(1.0, 0, 0))})
    assert np.array_equal(single.part != EMPTY, separate.part != EMPTY)
    assert (single.part[:, 5, 5] == 0).all()  # the overlap is solid


def test_open_box_still_fills_with_a_warning():
    box = _box((4.0, 2.0, 1.0))
    keep = np.flatnonzero(box.face_normals[:, 1] < 0.9)  # drop the two top triangles
    open_box = trimesh.Trimesh(box.vertices, box.faces[keep], process=False)
    assert not open_box.is_watertight
    grid = _grid({"tray": open_box})
    assert _count(grid) == 16 * 8 * 4
    assert grid.warnings == ("part 'tray' is not watertight; filled by 3-axis ray-parity vote "
                             "(gaps narrower than a voxel are bridged)",)


def test_hollow_shell_keeps_its_void():
    outer = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    inner = trimesh.creation.icosphere(subdivisions=4, radius=0.5)
    inner.invert()
    shell = trimesh.util.concatenate([outer, inner])
    assert shell.is_watertight
    grid = _grid({"shell": shell}, resolution=64)
    assert grid.shape == (64, 64, 64)
    occ = grid.part != EMPTY
    assert not occ[24:40, 24:40, 24:40].any()  # well inside the 16-voxel inner radius
    assert occ[32, 32, 4] and occ[32, 32, 59]
    expected = 4.0 / 3.0 * math.pi * (32.0 ** 3 - 16.0 ** 3)
    assert occ.sum() == pytest.approx(expected, rel=0.03)


def test_inside_out_mesh_is_still_solid():
    box = _box((4.0, 2.0, 1.0))
    box.invert()
    assert _count(_grid({"box": box})) == 16 * 8 * 4


def test_ball_inside_a_cavity_stays_solid():
    outer = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    cavity = trimesh.creation.icosphere(subdivisions=3, radius=0.7)
    cavity.invert()
    core = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    grid = _grid({"rattle": trimesh.util.concatenate([outer, cavity, core])}, resolution=32)
    occ = grid.part != EMPTY
    assert occ[16, 16, 16]  # the core
    assert not occ[16, 16, 16 + 8]  # the gap between core and shell (radius 0.5 = 8 voxels)
    assert occ[16, 16, 16 + 14]  # the shell (radius 0.875)


# --------------------------------------------------------------------------- coverage, thin parts


def test_solid_occupancy_gives_fractional_coverage():
    # A slab covering 1.5 voxels along x in a 2×1×1 grid of 1 m voxels.
    slab = _box((1.5, 1.0, 1.0), at=(0.75, 0.5, 0.5))
    coverage = solid_occupancy(slab, (2, 1, 1), (0.0, 0.0, 0.0), 1.0, supersample=4)
    assert coverage.dtype == np.float32
    assert coverage[:, 0, 0] == pytest.approx([1.0, 0.5])
    centre_only = solid_occupancy(slab, (2, 1, 1), (0.0, 0.0, 0.0), 1.0, supersample=1)
    assert centre_only[:, 0, 0] == pytest.approx([1.0, 1.0])


def test_rays_through_projected_edges_and_vertices_count_once():
    # Octahedron |x|+|y|+|z-0.25| <= 3 with vertices and edges over sample columns;
    # no sample lies on its surface, so the exact answer is known.
    vertices = np.array([[3, 0, 0], [-3, 0, 0], [0, 3, 0], [0, -3, 0], [0, 0, 3], [0, 0, -3]], float)
    vertices[:, 2] += 0.25
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    octa = trimesh.Trimesh(vertices, faces, process=False)
    assert octa.is_watertight and octa.volume > 0
    coverage = solid_occupancy(octa, (8, 8, 8), (-4.5, -4.5, -4.5), 1.0)  # voxel centres on integers -4..3
    centres = np.stack(np.meshgrid(*[np.arange(-4, 4)] * 3, indexing="ij"), axis=-1)
    expected = np.abs(centres[..., 0]) + np.abs(centres[..., 1]) + np.abs(centres[..., 2] - 0.25) < 3
    assert np.array_equal(coverage > 0, expected)


def test_thin_plate_voxelizes_to_nothing_then_keep_thin_rescues_it():
    plate = {"plate": _box((1.0, 0.3 / 16, 1.0))}  # 0.3 voxel thick → 50 % coverage
    with pytest.raises(VoxelizeError) as info:
        _grid(plate, min_coverage=0.9)
    assert info.value.message == "the source voxelizes to nothing at this resolution"
    assert "keep_thin" in info.value.hint
    grid = _grid(plate, min_coverage=0.9, keep_thin=True)
    assert grid.shape == (16, 1, 16)
    assert _count(grid) == 256


def test_keep_thin_keeps_a_thin_part_next_to_a_thick_one():
    # The fin is 0.32 voxel thick and straddles a voxel boundary: 25 % coverage in two layers.
    parts = {"body": _box((1.0, 1.0, 1.0)), "fin": _box((0.5, 0.06, 0.5), at=(0.75, 0.0, 0.0))}
    plain = _grid(parts, resolution=8)
    assert plain.shape == (8, 6, 6)
    assert not (plain.part == 1).any()
    assert any("'fin' occupies no voxel" in w for w in plain.warnings)
    kept = _grid(parts, resolution=8, keep_thin=True)
    fin = kept.part == 1
    assert fin.any()
    assert set(np.flatnonzero(fin.any(axis=(0, 2)))) == {2, 3}  # the two layers it straddles
    # The body keeps its cells; where the fin's rule adds a cell the body covers more, the body labels it.
    assert (kept.part[plain.part == 0] == 0).all()


def test_voxelize_is_deterministic():
    torus = trimesh.creation.torus(1.0, 0.3, major_sections=48, minor_sections=24)
    first = _grid({"ring": torus, "peg": _box((0.3, 1.0, 0.3))}, resolution=24)
    second = _grid({"ring": torus, "peg": _box((0.3, 1.0, 0.3))}, resolution=24)
    assert np.array_equal(first.part, second.part)
    assert first.origin_m == second.origin_m


# --------------------------------------------------------------------------- voxels sources


def _voxels(part: np.ndarray, names=("a",), style=None, style_names=(), voxel=0.1) -> PartVoxels:
    return PartVoxels(part=part.astype(np.int16), part_names=tuple(names), voxel_size_m=voxel,
                      style=None if style is None else style.astype(np.int16), style_names=tuple(style_names))


def test_voxels_pass_through_cropped_when_they_already_fit():
    part = np.full((20, 20, 20), EMPTY, np.int16)
    part[2:18, 4:12, 5:9] = 0
    part[2:18, 10:12, 5:9] = 1
    grid = voxelize(_voxels(part, names=("a", "b")), GridSettings(), FitMode.LONGEST)
    assert grid.shape == (16, 8, 4)
    assert np.array_equal(grid.part, part[2:18, 4:12, 5:9])
    assert grid.voxel_size_m == pytest.approx(0.1)
    assert grid.origin_m == pytest.approx((0.2, 0.4, 0.5))


def test_voxels_resample_by_two_with_majority_labels_and_styles():
    part = np.zeros((32, 16, 8), np.int16)
    part[:, 12:] = 1  # top quarter is part 1
    style = np.zeros_like(part)
    style[16:] = 1
    grid = voxelize(_voxels(part, names=("body", "roof"), style=style, style_names=("s0", "s1")),
                    GridSettings(), FitMode.LONGEST)
    assert grid.shape == (16, 8, 4)
    assert grid.voxel_size_m == pytest.approx(0.2)
    assert (grid.part[:, :6] == 0).all() and (grid.part[:, 6:] == 1).all()
    assert (grid.style[:8] == 0).all() and (grid.style[8:] == 1).all()
    assert grid.style_names == ("s0", "s1")


def test_voxels_resample_by_a_non_integer_factor():
    part = np.zeros((24, 24, 24), np.int16)  # a full cube, 24 → 16 voxels (factor 1.5)
    grid = voxelize(_voxels(part), GridSettings(), FitMode.LONGEST)
    assert grid.shape == (16, 16, 16)
    assert (grid.part == 0).all()
    assert grid.voxel_size_m == pytest.approx(0.15)


def test_voxels_upsample_keeps_the_shape():
    part = np.full((8, 8, 8), EMPTY, np.int16)
    part[:, :4] = 0
    grid = voxelize(_voxels(part), GridSettings(), FitMode.LONGEST)
    assert grid.shape == (16, 8, 16)  # cropped to 8×4×8 input voxels, then doubled
    assert (grid.part == 0).all()


def test_voxels_fit_voxel_size_equal_to_the_input_passes_through():
    part = np.zeros((40, 3, 5), np.int16)
    grid = voxelize(_voxels(part, voxel=0.05), GridSettings(fit=FitMode.VOXEL_SIZE, voxel_size_m=0.05),
                    FitMode.VOXEL_SIZE)
    assert grid.shape == (40, 3, 5)


def test_empty_voxels_are_refused():
    with pytest.raises(VoxelizeError, match="voxelizes to nothing"):
        voxelize(_voxels(np.full((4, 4, 4), EMPTY, np.int16)), GridSettings(), FitMode.LONGEST)

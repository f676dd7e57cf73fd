"""Meshing (pipeline/mesh.py), palette and export (pipeline/export.py).

Fixtures are small voxel fields made in code; known answers come from the
analytic sphere / box they were made from.
"""

from __future__ import annotations

import errno
import json
import os
import struct

import numpy as np
import pytest
import trimesh
from PIL import Image
from scipy import ndimage

from core import files as files_mod
from pipeline import export as export_mod
from core.errors import ExportError, MeshingError
from pipeline.export import apply_pivot, export_asset, export_mesh, mesh_stats, pivot_translation
from core.files import ensure_writable_dir, write_bytes_atomic
from core.grid import FineGrid
from pipeline.mesh import (
    FULL_RES_FACES_PER_COARSE_FACE,
    HALF_RES_FACE_RATIO,
    HALF_RES_LEVEL,
    MeshSettings,
    box_average,
    mesh_fine_grid,
    mesh_sample_step,
    signed_volume,
)
from pipeline.simplify import drop_coincident_faces, edge_groups, split_pinches
from pipeline.palette import NEUTRAL_RGBA, PALETTE, palette_rgba, style_color
from core.recipe import ExportFormat, ExportSettings, MeshResolution, Pivot

VOXEL = 0.01
ORIGIN = (-0.3, 0.1, 0.2)
N = 48
RADIUS = 0.16
# On a voxel centre (x), a voxel corner (z) and a voxel centre (y): the voxelized
# sphere is then mirror-symmetric about this point, so its mesh's bbox centre must
# land on it exactly, and a half-voxel offset bug would show as 0.5 voxel.
CENTRE = np.array(ORIGIN) + np.array([24.5, 23.5, 24.0]) * VOXEL


def voxel_centres(shape: tuple[int, int, int], origin=ORIGIN, voxel=VOXEL) -> np.ndarray:
    """(X, Y, Z, 3) world position of every voxel centre."""
    idx = np.indices(shape, dtype=np.float64).transpose(1, 2, 3, 0)
    return np.asarray(origin) + (idx + 0.5) * voxel


def smoothed(binary: np.ndarray, sigma: float = 1.0) -> np.ndarray:
    return ndimage.gaussian_filter(binary.astype(np.float32), sigma).astype(np.float32)


def fine_grid(occupancy: np.ndarray, style: np.ndarray | None = None, names=("stone",), origin=ORIGIN) -> FineGrid:
    if style is None:
        style = np.zeros(occupancy.shape, np.int16)
    return FineGrid(occupancy, style.astype(np.int16), tuple(names), VOXEL, origin)


@pytest.fixture(scope="module")
def sphere_grid() -> FineGrid:
    inside = np.linalg.norm(voxel_centres((N, N, N)) - CENTRE, axis=-1) <= RADIUS
    return fine_grid(smoothed(inside))


@pytest.fixture(scope="module")
def sphere_mesh(sphere_grid) -> trimesh.Trimesh:
    return mesh_fine_grid(sphere_grid, MeshSettings(max_triangles=None))


# --------------------------------------------------------------------------- palette


def test_palette_follows_names_and_keeps_an_assets_styles_apart():
    assert style_color("brick", 0) == (*PALETTE[0][1], 255)
    # the same name has the same colour in every asset, whatever its position
    moss_first = palette_rgba(("moss", "stone"))[0]
    moss_second = palette_rgba(("stone", "moss"))[1]
    assert tuple(moss_first) == tuple(moss_second)
    # up to twelve styles in one asset never share a colour
    names = [f"style{i}" for i in range(len(PALETTE))]
    assert len({tuple(c) for c in palette_rgba(names)[:-1]}) == len(PALETTE)
    colours = {style_color("s", i) for i in range(len(PALETTE))}
    assert len(colours) == len(PALETTE) >= 12
    rgb = np.array([c[:3] for c in colours], dtype=float)
    gaps = np.linalg.norm(rgb[:, None] - rgb[None], axis=-1) + np.eye(len(rgb)) * 1e9
    assert gaps.min() > 40  # clearly distinguishable
    assert style_color("s", len(PALETTE)) == style_color("s", 0)  # wraps around
    assert style_color("s", -1) == NEUTRAL_RGBA
    lut = palette_rgba(("a", "b"))
    assert lut.shape == (3, 4) and lut.dtype == np.uint8 and tuple(lut[2]) == NEUTRAL_RGBA


# --------------------------------------------------------------------------- meshing


def test_sphere_is_closed_outward_and_in_the_right_place(sphere_mesh):
    mesh = sphere_mesh
    assert mesh.is_watertight and mesh.is_winding_consistent
    analytic = 4.0 / 3.0 * np.pi * RADIUS**3
    assert mesh.volume > 0
    assert mesh.volume == pytest.approx(analytic, rel=0.05)
    expected = np.stack([CENTRE - RADIUS, CENTRE + RADIUS])
    assert np.abs(mesh.bounds - expected).max() < VOXEL
    # The no-half-voxel-offset rule, precisely.
    assert np.abs(mesh.bounds.mean(axis=0) - CENTRE).max() < 0.1 * VOXEL
    assert signed_volume(mesh.vertices, mesh.faces) == pytest.approx(mesh.volume)


def test_crop_offset_matches_meshing_the_whole_grid(sphere_grid, sphere_mesh):
    # The same field inside a larger grid, shifted by (10, 5, 20) voxels with the
    # origin moved back by as much: the surface must be the same in metres.
    shift = np.array([10, 5, 20])
    big = np.zeros(tuple(np.array(sphere_grid.shape) + shift + 7), np.float32)
    big[shift[0]:shift[0] + N, shift[1]:shift[1] + N, shift[2]:shift[2] + N] = sphere_grid.occupancy
    origin = tuple(np.asarray(ORIGIN) - shift * VOXEL)
    mesh = mesh_fine_grid(fine_grid(big, origin=origin), MeshSettings(max_triangles=None))
    assert len(mesh.faces) == len(sphere_mesh.faces)
    np.testing.assert_allclose(mesh.bounds, sphere_mesh.bounds, atol=1e-9)


def test_shape_touching_the_grid_border_is_closed():
    occ = np.zeros((20, 16, 12), np.float32)
    occ[:8, :6, :] = 1.0  # touches x = 0, y = 0 and both z faces
    mesh = mesh_fine_grid(fine_grid(occ), MeshSettings(max_triangles=None))
    assert mesh.is_watertight and mesh.volume > 0
    # Binary field, iso 0.4: the surface lies 0.1 voxel beyond the outer voxel
    # boundary (interpolating 1 → 0 between voxel centres).
    np.testing.assert_allclose(mesh.bounds[0], np.asarray(ORIGIN) - 0.1 * VOXEL, atol=1e-9)
    np.testing.assert_allclose(mesh.bounds[1], np.asarray(ORIGIN) + (np.array([8, 6, 12]) + 0.1) * VOXEL, atol=1e-9)


def test_decimation_honours_max_triangles_and_stays_closed(sphere_grid, sphere_mesh):
    assert len(sphere_mesh.faces) > 5000
    for target in (3000, 800):
        mesh = mesh_fine_grid(sphere_grid, MeshSettings(max_triangles=target))
        assert 0.9 * target <= len(mesh.faces) <= target
        assert mesh.is_watertight and mesh.volume > 0
        assert mesh.volume == pytest.approx(sphere_mesh.volume, rel=0.03)
    # Small / thin fields under strong decimation are where fins appear (see
    # drop_coincident_faces): sweep a range of targets on a less smooth sphere.
    inside = np.linalg.norm(voxel_centres((N, N, N)) - CENTRE, axis=-1) <= RADIUS
    rough = fine_grid(smoothed(inside, 0.7))
    for target in range(700, 1400, 97):
        assert mesh_fine_grid(rough, MeshSettings(max_triangles=target, vertex_colors=False)).is_watertight


def test_drop_coincident_faces_removes_fins_and_degenerates():
    faces = np.array([[0, 1, 2], [2, 1, 3], [1, 2, 3], [4, 4, 5], [5, 6, 7]])
    np.testing.assert_array_equal(drop_coincident_faces(faces), [[0, 1, 2], [5, 6, 7]])


def test_a_triangle_twice_with_one_winding_keeps_one_copy():
    """Removing both copies would open a hole; of three copies (two one way, one the other) one stays, as two."""
    faces = np.array([[0, 1, 2], [1, 2, 0], [3, 4, 5], [5, 3, 4], [4, 3, 5], [6, 7, 8]])
    np.testing.assert_array_equal(drop_coincident_faces(faces), [[0, 1, 2], [3, 4, 5], [6, 7, 8]])
    closed = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]])  # a tetrahedron
    doubled = np.concatenate([closed, closed[2:3]])  # one face twice: edges in three faces
    assert trimesh.Trimesh(np.eye(4)[:, :3] + 0.1, drop_coincident_faces(doubled), process=False).is_watertight


def test_bounded_smoothing_moves_no_vertex_farther_than_the_bound_and_keeps_block_borders():
    rng = np.random.default_rng(0)
    occ = np.zeros((30, 30, 30), np.float32)
    occ[5:25, 5:25, 5:25] = 1.0
    occ[5:25, 24, 5:25] = rng.random((20, 20)) > 0.5  # a rough face: terraces and spikes
    from pipeline.mesh import crop_padded, marching_cubes, taubin_smooth

    volume, start = crop_padded(occ, 0.4)
    verts, faces = marching_cubes(volume, 0.4)
    fixed = verts[:, 0] < 8
    out = taubin_smooth(verts, faces, 20, fixed, max_shift=0.5)
    assert np.abs(out - verts).max() <= 0.5 + 1e-6
    np.testing.assert_array_equal(out[fixed], verts[fixed])
    free = taubin_smooth(verts, faces, 20)
    assert np.abs(free - verts).max() > 0.5  # the bound is what held them


def test_taubin_smoothing_keeps_shape(sphere_grid, sphere_mesh):
    mesh = mesh_fine_grid(sphere_grid, MeshSettings(max_triangles=None, taubin_iterations=5))
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(sphere_mesh.volume, rel=0.02)
    assert not np.allclose(mesh.vertices, sphere_mesh.vertices)


def test_half_resolution_meshes_the_same_sphere_with_a_quarter_of_the_triangles():
    # a binary field, as the copying detailizer makes: the half-resolution level is set for those
    inside = np.linalg.norm(voxel_centres((N, N, N)) - CENTRE, axis=-1) <= RADIUS
    sphere_grid = fine_grid(inside.astype(np.float32))
    sphere_mesh = mesh_fine_grid(sphere_grid, MeshSettings(max_triangles=None))
    half = mesh_fine_grid(sphere_grid, MeshSettings(max_triangles=None, sample_step=2))
    assert half.is_watertight
    assert 0.15 < len(half.faces) / len(sphere_mesh.faces) < 0.35
    # the same place: radius and centre within a fraction of a fine voxel (a half-sample offset bug is 0.5 voxel)
    radius = np.linalg.norm(half.vertices - CENTRE, axis=1)
    full_radius = np.linalg.norm(sphere_mesh.vertices - CENTRE, axis=1)
    assert abs(radius.mean() - full_radius.mean()) < 0.25 * VOXEL
    assert np.abs(half.bounds.mean(axis=0) - CENTRE).max() < 0.1 * VOXEL
    # HALF_RES_LEVEL 0.55 puts the surface ~0.1 voxel inside the voxel boundary, the full-resolution ISO_LEVEL
    # 0.4 ~0.1 voxel outside it: on this 16-voxel sphere the volumes differ by 3 × 0.2 / 16 ≈ 4 %
    assert 0.93 < half.volume / sphere_mesh.volume < 0.99


def test_a_shape_thinner_than_a_half_resolution_sample_is_meshed_at_full_resolution():
    occ = np.zeros((12, 12, 12), np.float32)
    occ[2:10, 5, 5] = 1.0  # a one-voxel rod: its 2×2×2 averages never reach half
    mesh = mesh_fine_grid(fine_grid(occ), MeshSettings(max_triangles=None, sample_step=2))
    full = mesh_fine_grid(fine_grid(occ), MeshSettings(max_triangles=None))
    assert mesh.is_watertight and mesh.volume == pytest.approx(full.volume) and mesh.volume > 4 * VOXEL**3


def test_box_average_is_the_mean_of_each_box_and_pads_with_zeros():
    rng = np.random.default_rng(0)
    field = rng.random((6, 5, 4), dtype=np.float32)
    out = box_average(field, 2)
    assert out.shape == (3, 3, 2) and out.dtype == np.float32
    assert out[1, 1, 1] == pytest.approx(field[2:4, 2:4, 2:4].mean(), abs=1e-6)
    assert out[2, 2, 0] == pytest.approx(field[4:6, 4:5, 0:2].sum() / 8, abs=1e-6)  # the missing row counts 0
    assert box_average(field, 1) is field
    # a box's value does not depend on the array it was cut from (blocks that share a plane weld)
    np.testing.assert_array_equal(box_average(field[2:], 2), out[1:])


def test_smoothed_vertices_stay_in_the_coarse_cells_and_inner_creases_stay_sharp():
    from pipeline.mesh import keep_in_cells, near_inner_creases

    # an L of three cells (0,0,0), (1,0,0), (0,1,0): cell (1,1,0) is the empty inner corner
    coarse = np.zeros((2, 2, 1), bool)
    coarse[0, 0, 0] = coarse[1, 0, 0] = coarse[0, 1, 0] = True
    verts = np.array([[21.0, 20.0, 5.0],   # inside the empty corner cell, nearer the face y = 15.5
                      [5.0, 5.0, 5.0],     # inside an occupied cell
                      [40.0, 5.0, 5.0],    # beyond the grid next to cell (1, 0, 0)
                      [18.0, 18.0, 5.0]])  # in the empty cell, locked
    fixed = np.array([False, False, False, True])
    moved = keep_in_cells(verts, coarse, fixed)
    assert moved == 2
    np.testing.assert_allclose(verts[0], [21.0, 15.5, 5.0])  # onto the nearest occupied cell's face
    np.testing.assert_allclose(verts[1], [5.0, 5.0, 5.0])
    np.testing.assert_allclose(verts[2], [31.5, 5.0, 5.0])
    np.testing.assert_allclose(verts[3], [18.0, 18.0, 5.0])
    crease = near_inner_creases(np.array([[16.0, 14.8, 5.0], [16.0, 10.0, 5.0], [5.0, 5.0, 5.0]]), coarse)
    assert crease.tolist() == [True, False, False]  # within 1.5 voxels of the corner cell only


def test_half_resolution_keeps_material_thinner_than_a_sample():
    from pipeline.mesh import keep_thin_cells

    field = np.zeros((32, 16, 16), np.float32)
    field[3:13, 7, 7] = 1.0  # a one-voxel stroke in cell (0, 0, 0): its 2³ box averages are 0.25
    field[16:32, :, :] = 1.0  # cell (1, 0, 0) is solid
    samples = box_average(field, 2)
    assert samples[:8].max() < HALF_RES_LEVEL
    assert keep_thin_cells(samples, field, 2, HALF_RES_LEVEL, 0.4) == 1  # only the thin cell
    kept = samples[:8] >= HALF_RES_LEVEL
    assert kept.sum() == 6 and kept[1:7, 3, 3].all()  # voxels 3..12 lie in boxes 1..6
    assert (samples[8:] == 1.0).all()  # the solid cell is as it was


def test_auto_mesh_resolution_follows_the_budget():
    bar = np.zeros((80, 3, 3), bool)
    bar[:, 1, 1] = True  # 4 · 80 + 2 = 322 exposed coarse faces: about 165 000 full-resolution triangles
    faces = FULL_RES_FACES_PER_COARSE_FACE * 322
    assert mesh_sample_step(MeshResolution.AUTO, faces // HALF_RES_FACE_RATIO, bar) == 2

    assert mesh_sample_step(MeshResolution.AUTO, faces // HALF_RES_FACE_RATIO + 1, bar) == 1
    assert mesh_sample_step(MeshResolution.AUTO, None, bar) == 1  # no budget: nothing to lose
    assert mesh_sample_step(MeshResolution.FULL, 10, bar) == 1
    assert mesh_sample_step(MeshResolution.HALF, None, bar) == 2
    assert MeshSettings.from_export(ExportSettings(max_triangles=100, mesh_resolution="auto"), bar).sample_step == 2
    with pytest.raises(ValueError):
        MeshSettings(sample_step=3)


def _tetra(apex_y: float, offset: int) -> np.ndarray:
    """Faces of an outward tetrahedron on the edge (0, 1) with its other corners at offset, offset + 1."""
    faces = np.array([[0, 1, offset], [0, offset + 1, 1], [1, offset + 1, offset], [0, offset, offset + 1]])
    return faces if apex_y > 0 else faces[:, ::-1]


def test_a_pinch_along_an_edge_is_split_into_two_closed_sheets():
    verts = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0.2], [0.5, 0.3, 1], [0.5, -1, 0.2], [0.5, -0.3, -1]], float)
    upper, lower = _tetra(1, 2), _tetra(-1, 4)
    for tet in (upper, lower):  # wind both outward
        if signed_volume(verts, tet) < 0:
            tet[:] = tet[:, ::-1]
    faces = np.concatenate([upper, lower])
    assert not trimesh.Trimesh(verts, faces, process=False).is_watertight  # edge (0, 1) is in four faces
    source, split = split_pinches(faces, len(verts))
    mesh = trimesh.Trimesh(verts[source], split, process=False)
    assert mesh.is_watertight and len(source) == 8 and (source[:6] == np.arange(6)).all()
    assert mesh.volume == pytest.approx(signed_volume(verts, faces))
    # a closed 2-manifold is returned as it was
    same_source, same = split_pinches(upper, 6)
    assert (same == upper).all() and (same_source == np.arange(6)).all()
    # beside an open border (a block's side): the border's edges stay open and the pinch is still split
    sheet = np.array([[6, 7, 8]])
    open_verts = np.concatenate([verts, [[3, 0, 0], [4, 0, 0], [3, 1, 0]]])
    source, split = split_pinches(np.concatenate([faces, sheet]), len(open_verts))
    counts = np.bincount(edge_groups(split, len(source))[2], minlength=5)
    assert len(source) == 11 and counts[1] == 3 and counts[2] == 12 and counts[3:].sum() == 0


def test_splitting_pinches_of_decimated_meshes_never_opens_holes(sphere_grid, monkeypatch):
    from pipeline import mesh as mesh_mod
    from pipeline import simplify

    rng = np.random.default_rng(5)
    occupancy = np.asarray(sphere_grid.occupancy)
    fixed = left = closed_left = 0
    for noise, target in ((0.2, 3000), (0.35, 3000), (0.35, 800)):
        rough = (occupancy + rng.normal(0, noise, occupancy.shape) > 0.5).astype(np.float32)
        volume, _ = mesh_mod.crop_padded(rough, 0.4)
        verts, faces = mesh_mod.marching_cubes(volume, 0.4)
        with monkeypatch.context() as patch:  # the simplifier's own output, pinches and all
            patch.setattr(simplify, "close_pinches", lambda f, v: (np.arange(len(v)), f))
            kept, raw = simplify.decimate_kept(verts, faces, target)
        source, split = split_pinches(raw, len(kept))
        before = np.bincount(simplify.edge_groups(raw, len(kept))[2], minlength=8)
        after = np.bincount(simplify.edge_groups(split, len(source))[2], minlength=8)
        assert after[1] <= before[1] and after[3:].sum() <= before[3:].sum()  # no new holes, no new pinches
        assert len(split) == len(raw) and (kept[source][:len(kept)] == kept).all()
        fixed += before[3:].sum() - after[3:].sum()
        # what the split leaves, collapses and flips close (the noisiest meshes are open at the crop already)
        closed_source, closed = simplify.close_pinches(raw, np.asarray(verts, dtype=np.float64)[kept])
        counts = np.bincount(simplify.edge_groups(closed, len(closed_source))[2], minlength=8)
        assert counts[1] <= before[1] and counts[3:].sum() <= after[3:].sum()  # no new holes, never worse
        assert len(raw) - len(closed) <= 4 * before[3:].sum()  # a few faces per collapsed edge
        assert closed_source.max() < len(kept) and len(np.unique(closed)) == len(closed_source)
        order, starts, counts_raw = simplify.edge_groups(raw, len(kept))
        border = order[starts[counts_raw == 1]]  # vertices on an open boundary never move (blocks are welded)
        assert set(raw.reshape(-1)[border].tolist()) <= set(closed_source.tolist())
        left += after[3:].sum()
        closed_left += counts[3:].sum()
    # the split alone leaves some (47 here); collapses and flips close at least nine in ten of them (all but 1)
    assert fixed > 0 and left > 0 and closed_left * 10 <= left


def test_meshing_is_deterministic(sphere_grid):
    a = mesh_fine_grid(sphere_grid, MeshSettings(max_triangles=2000))
    b = mesh_fine_grid(sphere_grid, MeshSettings(max_triangles=2000))
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.faces, b.faces)


def test_vertex_colours_follow_style_regions():
    occ = np.zeros((24, 12, 12), np.float32)
    occ[2:22, 2:10, 2:10] = 1.0
    style = np.where(np.arange(24)[:, None, None] < 12, 0, 1) * np.ones((1, 12, 12))
    mesh = mesh_fine_grid(fine_grid(smoothed(occ, 0.8), style, names=("brick", "slate")))
    colours = np.asarray(mesh.visual.vertex_colors)
    assert colours.shape == (len(mesh.vertices), 4) and colours.dtype == np.uint8
    split_x = ORIGIN[0] + 12 * VOXEL
    x = mesh.vertices[:, 0]
    left, right = colours[x < split_x - VOXEL], colours[x > split_x + VOXEL]
    assert len(left) > 50 and len(right) > 50
    brick, slate = (tuple(c) for c in palette_rgba(("brick", "slate"))[:2])
    assert brick != slate
    assert (left == brick).all()
    assert (right == slate).all()
    assert {tuple(c) for c in colours} == {brick, slate}


def test_invalid_style_gets_neutral_colour_and_colours_can_be_off():
    occ = np.zeros((10, 10, 10), np.float32)
    occ[3:7, 3:7, 3:7] = 1.0
    grid = fine_grid(occ, np.full(occ.shape, -1, np.int16))
    mesh = mesh_fine_grid(grid)
    assert {tuple(c) for c in np.asarray(mesh.visual.vertex_colors)} == {NEUTRAL_RGBA}
    plain = mesh_fine_grid(grid, MeshSettings(vertex_colors=False))
    assert plain.visual.kind is None


def test_empty_or_invalid_field_raises_meshing_error():
    empty = fine_grid(np.full((8, 8, 8), 0.39, np.float32))
    with pytest.raises(MeshingError, match="empty; nothing to mesh") as info:
        mesh_fine_grid(empty)
    assert info.value.hint
    bad = np.ones((8, 8, 8), np.float32)
    bad[1, 2, 3] = np.nan
    with pytest.raises(MeshingError, match="NaN"):
        mesh_fine_grid(fine_grid(bad))


def test_mesh_settings_from_recipe_export_settings():
    settings = MeshSettings.from_export(ExportSettings(taubin_iterations=3, max_triangles=None, vertex_colors=False,
                                                       taubin_max_shift_voxels=None))
    assert settings == MeshSettings(taubin_iterations=3, max_triangles=None, vertex_colors=False)
    defaults = MeshSettings.from_export(ExportSettings(), np.ones((4, 4, 4), bool))
    # the defaults: bounded smoothing, and the 'auto' budget of a prop (32 per exposed coarse face, at least 2000)
    assert defaults == MeshSettings(taubin_iterations=8, taubin_max_shift=0.5, max_triangles=max(32 * 96, 2000))
    with pytest.raises(ValueError):
        MeshSettings(max_triangles=2)


# --------------------------------------------------------------------------- export


def glb_json(data: bytes) -> dict:
    magic, version, length = struct.unpack("<4sII", data[:12])
    assert (magic, version, length) == (b"glTF", 2, len(data))
    chunk_length, chunk_type = struct.unpack("<I4s", data[12:20])
    assert chunk_type == b"JSON"
    return json.loads(data[20:20 + chunk_length])


@pytest.fixture(scope="module")
def coloured_mesh() -> trimesh.Trimesh:
    occ = np.zeros((20, 14, 12), np.float32)
    occ[3:17, 2:12, 3:9] = 1.0
    style = np.where(np.arange(14)[None, :, None] < 7, 0, 1) * np.ones((20, 1, 12))
    return mesh_fine_grid(fine_grid(smoothed(occ, 0.8), style, names=("brick", "slate")),
                          MeshSettings(max_triangles=1500))


@pytest.mark.parametrize("fmt", list(ExportFormat))
def test_export_round_trip(tmp_path, coloured_mesh, fmt):
    paths = export_mesh(coloured_mesh, tmp_path, "crate", [fmt], Pivot.SOURCE)
    assert paths == {fmt.value: tmp_path / f"crate.{fmt.value}"}
    assert sorted(os.listdir(tmp_path)) == [f"crate.{fmt.value}"]  # no temporaries, no .mtl
    if fmt == ExportFormat.GLB:
        scene = trimesh.load(paths["glb"], process=False)
        assert list(scene.geometry) == ["crate"]
        loaded = scene.geometry["crate"]
    else:
        # STL is a triangle soup: let trimesh merge its vertices.
        loaded = trimesh.load(paths[fmt.value], process=fmt == ExportFormat.STL)
    assert len(loaded.faces) == len(coloured_mesh.faces)
    np.testing.assert_allclose(loaded.bounds, coloured_mesh.bounds, atol=1e-6)
    expected_colours = {tuple(c) for c in np.asarray(coloured_mesh.visual.vertex_colors)}
    assert len(expected_colours) == 2
    if fmt == ExportFormat.GLB:
        # No material by default: trimesh reads COLOR_0 back as plain vertex colours.
        assert loaded.visual.kind == "vertex"
        np.testing.assert_array_equal(loaded.visual.vertex_colors, coloured_mesh.visual.vertex_colors)
        flat = trimesh.load(paths["glb"], force="mesh")
        assert flat.visual.kind == "vertex" and len(flat.faces) == len(coloured_mesh.faces)
        assert "vertex_normals" in loaded._cache.cache  # read from the file, not recomputed
        np.testing.assert_allclose(loaded.vertex_normals, coloured_mesh.vertex_normals, atol=1e-5)
        np.testing.assert_array_equal(loaded.faces, coloured_mesh.faces)
    elif fmt in (ExportFormat.PLY, ExportFormat.OBJ):
        assert loaded.visual.kind == "vertex"
        assert {tuple(c) for c in np.asarray(loaded.visual.vertex_colors)} == expected_colours
    else:
        assert loaded.is_watertight  # STL has no colours; geometry must survive the vertex soup


def test_glb_is_named_lit_deterministic(tmp_path, coloured_mesh):
    first = export_mesh(coloured_mesh, tmp_path / "a", "crate", [ExportFormat.GLB], Pivot.BOTTOM_CENTER)["glb"]
    second = export_mesh(coloured_mesh, tmp_path / "b", "crate", [ExportFormat.GLB], Pivot.BOTTOM_CENTER)["glb"]
    assert first.read_bytes() == second.read_bytes()
    tree = glb_json(first.read_bytes())
    assert tree["meshes"][0]["name"] == "crate" and tree["nodes"][0]["name"] == "crate"
    primitive = tree["meshes"][0]["primitives"][0]
    assert {"POSITION", "NORMAL", "COLOR_0"} <= set(primitive["attributes"])
    assert "material" not in primitive and "materials" not in tree
    assert "extras" not in tree["meshes"][0]
    scene = trimesh.load(first)
    assert list(scene.geometry) == ["crate"]


def test_glb_matte_material_option(tmp_path, coloured_mesh):
    written, _ = export_asset(coloured_mesh, tmp_path, "crate", [ExportFormat.GLB], Pivot.SOURCE, glb_material=True)
    tree = glb_json(written["glb"].read_bytes())
    primitive = tree["meshes"][0]["primitives"][0]
    assert tree["materials"][primitive["material"]]["pbrMetallicRoughness"]["metallicFactor"] == 0.0
    # trimesh then keeps COLOR_0 as a vertex attribute of the textured visual
    loaded = trimesh.load(written["glb"]).geometry["crate"]
    np.testing.assert_array_equal(loaded.visual.vertex_attributes["color"], coloured_mesh.visual.vertex_colors)


def test_pivots(tmp_path, coloured_mesh):
    lo, hi = coloured_mesh.bounds
    bottom = export_mesh(coloured_mesh, tmp_path, "b", [ExportFormat.PLY], Pivot.BOTTOM_CENTER)["ply"]
    b_lo, b_hi = trimesh.load(bottom, process=False).bounds
    assert b_lo[1] == pytest.approx(0.0, abs=1e-6)
    assert (b_lo[0] + b_hi[0]) / 2 == pytest.approx(0.0, abs=1e-6)
    assert (b_lo[2] + b_hi[2]) / 2 == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_allclose(b_hi - b_lo, hi - lo, atol=1e-6)
    centred = export_mesh(coloured_mesh, tmp_path, "c", [ExportFormat.PLY], Pivot.CENTER)["ply"]
    np.testing.assert_allclose(trimesh.load(centred, process=False).bounds.mean(axis=0), 0.0, atol=1e-6)
    np.testing.assert_allclose(pivot_translation(np.array([[1.0, 2.0, 3.0], [3.0, 5.0, 7.0]]), Pivot.BOTTOM_CENTER),
                               [-2.0, -2.0, -5.0])
    np.testing.assert_allclose(pivot_translation(np.array([[1.0, 2.0, 3.0], [3.0, 5.0, 7.0]]), Pivot.SOURCE), 0.0)
    moved, shift = apply_pivot(coloured_mesh, Pivot.CENTER)
    np.testing.assert_allclose(moved.vertices, coloured_mesh.vertices + shift)
    np.testing.assert_allclose(coloured_mesh.bounds, [lo, hi])  # the input is not modified


def _boom(mesh, stem):
    raise RuntimeError("encoder exploded")


def test_failure_in_second_format_leaves_no_files(tmp_path, coloured_mesh, monkeypatch):
    monkeypatch.setitem(export_mod.ENCODERS, ExportFormat.STL, _boom)
    with pytest.raises(ExportError, match="could not encode STL") as info:
        export_mesh(coloured_mesh, tmp_path, "crate", [ExportFormat.GLB, ExportFormat.STL, ExportFormat.PLY],
                    Pivot.SOURCE)
    assert info.value.file == str(tmp_path / "crate.stl")
    assert os.listdir(tmp_path) == []  # not even the GLB, nor a temporary


def test_write_failure_and_commit_failure_leave_no_files(tmp_path, coloured_mesh, monkeypatch):
    old = tmp_path / "crate.glb"
    old.write_bytes(b"previous export")
    calls = {"fsync": 0, "replace": 0}
    real_fsync, real_replace = os.fsync, os.replace

    def fsync_fails_second(fd):
        calls["fsync"] += 1
        if calls["fsync"] == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        real_fsync(fd)

    monkeypatch.setattr(files_mod.os, "fsync", fsync_fails_second)
    with pytest.raises(ExportError, match="No space left"):
        export_mesh(coloured_mesh, tmp_path, "crate", [ExportFormat.GLB, ExportFormat.PLY], Pivot.SOURCE)
    assert os.listdir(tmp_path) == ["crate.glb"] and old.read_bytes() == b"previous export"
    monkeypatch.setattr(files_mod.os, "fsync", real_fsync)

    def replace_fails_second(src, dst):
        calls["replace"] += 1
        if calls["replace"] == 2:
            raise OSError(errno.EIO, "Input/output error")
        real_replace(src, dst)

    monkeypatch.setattr(files_mod.os, "replace", replace_fails_second)
    with pytest.raises(ExportError, match="Input/output error") as info:
        export_mesh(coloured_mesh, tmp_path, "crate", [ExportFormat.STL, ExportFormat.PLY], Pivot.SOURCE)
    assert info.value.file == str(tmp_path / "crate.ply")
    assert os.listdir(tmp_path) == ["crate.glb"]  # the STL that was already moved is taken back


def test_export_asset_writes_meshes_and_preview_together(tmp_path, coloured_mesh, monkeypatch):
    written, shift = export_asset(coloured_mesh, tmp_path, "crate", [ExportFormat.GLB, ExportFormat.STL],
                                  Pivot.BOTTOM_CENTER, preview_size_px=64)
    assert list(written) == ["glb", "stl", "preview"]
    assert sorted(os.listdir(tmp_path)) == ["crate.glb", "crate.png", "crate.stl"]
    np.testing.assert_allclose(shift, pivot_translation(coloured_mesh.bounds, Pivot.BOTTOM_CENTER))
    with Image.open(written["preview"]) as image:
        assert image.size == (64, 64)

    def broken_preview(mesh, size_px):
        raise MemoryError("out of memory while rendering")

    monkeypatch.setattr(export_mod, "preview_png", broken_preview)
    with pytest.raises(ExportError, match="could not encode PNG"):
        export_asset(coloured_mesh, tmp_path / "again", "crate", [ExportFormat.GLB], Pivot.SOURCE, preview_size_px=64)
    assert os.listdir(tmp_path / "again") == []


def test_unwritable_output_dir(tmp_path, coloured_mesh):
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a folder")
    with pytest.raises(ExportError, match="not writable") as info:
        export_mesh(coloured_mesh, blocker / "out", "crate", [ExportFormat.GLB], Pivot.SOURCE)
    assert info.value.file == str(blocker / "out") and info.value.hint
    with pytest.raises(ExportError, match="not writable"):
        ensure_writable_dir(blocker)
    nested = tmp_path / "new" / "deeper"
    ensure_writable_dir(nested)
    assert nested.is_dir() and os.listdir(nested) == []  # the probe file is gone


def test_write_bytes_atomic_replaces_whole_file(tmp_path):
    target = tmp_path / "preview.png"
    target.write_bytes(b"old content that is longer")
    write_bytes_atomic(target, b"new")
    assert target.read_bytes() == b"new"
    assert os.listdir(tmp_path) == ["preview.png"]


def test_mesh_stats(sphere_mesh):
    stats = mesh_stats(sphere_mesh)
    assert stats["triangles"] == len(sphere_mesh.faces) and stats["vertices"] == len(sphere_mesh.vertices)
    assert stats["watertight"] is True
    np.testing.assert_allclose(stats["bbox_min_m"], CENTRE - RADIUS, atol=VOXEL)
    np.testing.assert_allclose(stats["bbox_max_m"], CENTRE + RADIUS, atol=VOXEL)
    json.dumps(stats)  # plain JSON types only


def test_a_field_that_spills_over_the_coarse_cells_keeps_its_shape():
    from pipeline.mesh import mesh_piece

    # a slab filling cell 0 and reaching 4 voxels into cell 1, which the coarse grid leaves empty (as a learned
    # model's output may): its vertices are the detailizer's output and are not pushed back onto the cell face
    field = np.zeros((32, 16, 16), np.float32)
    field[2:20, 2:14, 2:14] = 1.0
    coarse = np.array([True, False])[:, None, None]
    settings = MeshSettings(max_triangles=None, taubin_iterations=8)
    spilled = mesh_piece(field, None, ("a",), settings, None, coarse=coarse, confined=False)
    assert spilled.vertices[:, 0].max() > 19.0
    confined = mesh_piece(field, None, ("a",), settings, None, coarse=coarse, confined=True)
    assert confined.vertices[:, 0].max() <= 15.5 + 1e-9  # the same call told the field is confined clamps it

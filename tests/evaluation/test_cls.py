"""Tests of the Cls-score: the fast depth-shaded renderer (evaluation/render_eval.py) and the classifier (evaluation/cls_score.py)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from evaluation import render_eval as R
from evaluation.cls_score import ClsConfig, ViewBank, cls_score, render_bank, split_views


@pytest.fixture(autouse=True)
def _one_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _cube64() -> np.ndarray:
    x = np.zeros((64, 64, 64), bool)
    x[16:48, 16:48, 16:48] = True
    return x


def _sphere(r: float, n: int = 64) -> np.ndarray:
    c = np.arange(n) - (n - 1) / 2
    x, y, z = np.meshgrid(c, c, c, indexing="ij", sparse=True)
    return x**2 + y**2 + z**2 < r * r


def _cube(half: int, n: int = 64) -> np.ndarray:
    x = np.zeros((n, n, n), bool)
    a = n // 2 - half
    x[a : n - a, a : n - a, a : n - a] = True
    return x


def _ragged() -> np.ndarray:
    rng = np.random.default_rng(4)
    x = np.zeros((40, 36, 44), bool)
    x[8:30, 6:28, 10:36] = rng.random((22, 22, 26)) > 0.35  # ragged, with holes and grazing rays
    x[20:24, 30:34, 2:6] = True  # a separate small block
    return x


# --------------------------------------------------------------------------- renderer


def test_surface_voxels_exposed_faces():
    one = np.zeros((5, 5, 5), bool)
    one[2, 2, 2] = True
    sv = R.surface_voxels(one)
    assert len(sv) == 1 and sv.faces[0] == 0b111111
    np.testing.assert_array_equal(sv.points[0], [0.0, 0.0, 0.0])  # the grid centre
    block = np.zeros((6, 6, 6), bool)
    block[1:5, 1:5, 1:5] = True
    sv = R.surface_voxels(block)
    assert len(sv) == 64 - 8  # the 2³ core has no exposed face
    corner = np.nonzero((sv.points == -1.5).all(axis=1))[0]
    assert sv.faces[corner[0]] == 0b010101  # -x, -y, -z exposed
    full = np.ones((3, 3, 3), bool)  # outside the grid counts as empty
    assert len(R.surface_voxels(full)) == 26
    assert len(R.surface_voxels(np.zeros((4, 4, 4), bool))) == 0


def test_render_front_view_of_a_cube():
    im = R.render_depth_shaded(_cube64(), [0.0], [0.0])[0]
    assert im.shape == (256, 256) and im.dtype == np.uint8
    # the 32-voxel face faces the camera: flat, n_z = 1 → 220; one voxel per pixel, columns/rows 112..143
    assert (im[112:144, 112:144] == 220).all()
    assert (im[111, :] == 255).all() and (im[144, :] == 255).all() and (im[:, 111] == 255).all()
    assert set(np.unique(im)) == {220, 255}


def test_render_oblique_view_shades_by_normal():
    im = R.render_depth_shaded(_cube64(), [np.pi / 4], [0.0])[0]
    # two faces at 45°: n_z = cos 45° → round(220 · 0.7071) = 156
    values, counts = np.unique(im, return_counts=True)
    assert values[np.argmax(np.where(values < 255, counts, 0))] == 156
    # silhouette width = the cube's diagonal, 32·√2 ≈ 45 px
    row = im[128] < 255
    assert 44 <= row.sum() <= 47


def test_render_views_seeded_and_empty():
    a = R.render_views(_cube64(), n_views=3, seed=7)
    assert a.shape == (3, 256, 256)
    np.testing.assert_array_equal(a, R.render_views(_cube64(), n_views=3, seed=7))
    assert not np.array_equal(a, R.render_views(_cube64(), n_views=3, seed=8))
    az, el = R.view_angles(1000, seed=1)
    assert az.min() >= 0 and az.max() < 2 * np.pi and np.abs(el).max() <= np.pi / 4
    assert (R.render_views(np.zeros((20, 20, 20), bool), n_views=2) == 255).all()


def test_fast_renderer_matches_the_reference_ray_march():
    """Splatting exposed voxels gives the ray march's silhouette and (nearly) its shading."""
    x = _ragged()
    az, el = [0.3, 2.0, 4.4], [0.5, -0.7, 0.1]
    fast = R.render_depth_shaded(x, az, el)
    ref = R.render_depth_shaded_raymarch(x, az, el)
    for f, r in zip(fast, ref):
        fs, rs = f < 255, r < 255
        assert (fs & rs).sum() / (fs | rs).sum() > 0.9  # a ragged 40³ shape: the edge pixels are a large share
        assert abs(float(f[fs].mean()) - float(r[rs].mean())) < 12


def test_render_empty_space_skipping_is_exact():
    """The reference ray march's accelerated first hits equal the plain march's."""
    x = _ragged()
    vol = torch.nn.functional.pad(torch.from_numpy(x).float(), (R.RENDER_PAD,) * 6)[None, None]
    coarse = R._coarse_map(vol)
    centre = (torch.tensor(vol.shape[2:], dtype=torch.float32) - 1) / 2
    g = torch.arange(-40, 40, dtype=torch.float32)
    col, row = torch.meshgrid(g, g, indexing="xy")
    for a, e in [(0.3, 0.5), (2.0, -0.7), (4.4, 0.1)]:
        w = torch.tensor([np.cos(e) * np.sin(a), np.sin(e), np.cos(e) * np.cos(a)], dtype=torch.float32)
        r = torch.tensor([np.cos(a), 0.0, -np.sin(a)], dtype=torch.float32)
        plane = (centre + col[..., None] * r + row[..., None] * torch.linalg.cross(w, r)).reshape(-1, 3)
        full = R._first_hit_full(vol, plane, w, 60.0, 121)
        fast = R._first_hit_fast(vol, coarse, plane, w, 60.0, 121)
        assert 300 < int(torch.isfinite(full).sum()) < len(full)
        torch.testing.assert_close(fast, full, rtol=0, atol=0)


# --------------------------------------------------------------------------- classifier

_TINY = ClsConfig("test", n_views=8, test_views=4, steps=80, batch=32, width=4, crop=32, test_crops=8)


def test_split_views_is_disjoint_and_complete():
    train, test = split_views(24, 8)
    assert len(train) == 16 and len(test) == 8
    assert not set(train) & set(test) and set(train) | set(test) == set(range(24))
    with pytest.raises(ValueError):
        split_views(4, 4)
    bank = ViewBank(4, 1)
    for s in range(3):
        bank.add(np.full((4, 8, 8), s, np.uint8) + np.arange(4, dtype=np.uint8)[:, None, None] * 10)
    # per shape: views 0-2 train, view 3 test; no image is on both sides
    assert bank.train_shape == [0, 0, 0, 1, 1, 1, 2, 2, 2] and bank.test_shape == [0, 1, 2]
    assert [int(im[0, 0]) for im in bank.test] == [30, 31, 32]
    assert {int(im[0, 0]) for im in bank.train}.isdisjoint({int(im[0, 0]) for im in bank.test})
    with pytest.raises(ValueError, match="renders of one shape"):
        bank.add(np.zeros((3, 8, 8), np.uint8))


def test_cls_config_is_validated():
    with pytest.raises(ValueError, match="test_views"):
        ClsConfig(n_views=8, test_views=8)
    with pytest.raises(ValueError, match="batch"):
        ClsConfig(batch=3)
    with pytest.raises(ValueError, match="multiple of 16"):
        ClsConfig(crop=40)


def test_cls_identical_and_same_shapes_are_chance():
    cubes = render_bank([_cube(h) for h in (18, 20, 22, 24)], _TINY)
    same = cls_score(cubes, cubes, _TINY)
    assert same.cls == 0.5  # identical images, identical crops: whatever the classifier says, it is a coin
    other_views = render_bank([_cube(h) for h in (18, 20, 22, 24)], _TINY, seeds=range(50, 54))
    r = cls_score(cubes, other_views, _TINY)
    assert abs(r.cls - 0.5) < 0.12
    assert r.variant == "test" and r.split == "views" and r.test_images == (16, 16) and r.train_images == (16, 16)


def test_cls_cubes_vs_spheres_is_high():
    cubes = render_bank([_cube(h) for h in (18, 20, 22, 24)], _TINY)
    spheres = render_bank([_sphere(r) for r in (20, 23, 26, 29)], _TINY, seeds=range(100, 104))
    r = cls_score(cubes, spheres, _TINY)
    assert r.cls > 0.75 and r.real_acc > 0.6 and r.fake_acc > 0.6
    assert r.to_json()["config"]["steps"] == 80
    assert len(r.fake_acc_per_shape) == 4 and np.mean(r.fake_acc_per_shape) == pytest.approx(r.fake_acc)

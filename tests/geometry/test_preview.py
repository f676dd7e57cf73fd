"""Preview renderer (geometry/preview.py): size, content, determinism, orientation."""

from __future__ import annotations

import os

import numpy as np
import pytest
import trimesh
from PIL import Image

from geometry import preview
from geometry.preview import render_preview, save_preview

RED = (220, 30, 30, 255)
BLUE = (30, 60, 220, 255)


def coloured_box(centre: tuple[float, float, float], rgba: tuple[int, int, int, int]) -> trimesh.Trimesh:
    box = trimesh.creation.box(extents=(0.4, 0.5, 0.4))
    box.apply_translation(centre)
    box.visual.vertex_colors = np.tile(np.asarray(rgba, np.uint8), (len(box.vertices), 1))
    return box


@pytest.fixture(scope="module")
def red_left_blue_right() -> trimesh.Trimesh:
    """Two touching boxes: red at x < 0, blue at x > 0 (+Y up, front +Z)."""
    return trimesh.util.concatenate([coloured_box((-0.2, 0.25, 0.0), RED), coloured_box((0.2, 0.25, 0.0), BLUE)])


@pytest.fixture(scope="module")
def sphere() -> trimesh.Trimesh:
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=0.3)
    colours = np.where(mesh.vertices[:, 1:2] > 0, np.array([[200, 160, 60, 255]]), np.array([[80, 120, 170, 255]]))
    mesh.visual.vertex_colors = colours.astype(np.uint8)
    return mesh


def coverage(image: Image.Image) -> float:
    """Fraction of pixels that differ from the background gradient."""
    pixels = np.asarray(image, dtype=np.int16)
    background = preview._background(image.size[0]).astype(np.int16)
    return float((np.abs(pixels - background).max(axis=2) > 6).mean())


def test_size_mode_and_content(sphere):
    image = render_preview(sphere, 128)
    assert image.size == (128, 128) and image.mode == "RGB"
    assert len(np.unique(np.asarray(image).reshape(-1, 3), axis=0)) > 30  # shaded, not flat
    # A sphere seen orthographically fills π/4 of the 85 % square it is fit into.
    assert coverage(image) == pytest.approx(np.pi / 4 * 0.85**2, abs=0.03)
    assert 0.2 < coverage(render_preview(sphere, 64, supersample=1)) < 0.9


def test_render_is_deterministic(sphere, tmp_path):
    assert np.array_equal(np.asarray(render_preview(sphere, 96)), np.asarray(render_preview(sphere, 96)))
    save_preview(sphere, tmp_path / "a.png", 96)
    save_preview(sphere, tmp_path / "b.png", 96)
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()
    with Image.open(tmp_path / "a.png") as loaded:
        assert loaded.format == "PNG" and loaded.size == (96, 96)
        assert np.array_equal(np.asarray(loaded.convert("RGB")), np.asarray(render_preview(sphere, 96)))
    assert sorted(os.listdir(tmp_path)) == ["a.png", "b.png"]  # written atomically, no temporaries


def test_left_is_left(red_left_blue_right):
    pixels = np.asarray(render_preview(red_left_blue_right, 128), dtype=np.int32)
    r, b = pixels[..., 0], pixels[..., 2]
    red = (r > 60) & (r > 2 * b)
    blue = (b > 60) & (b > 2 * r)
    assert red.sum() > 500 and blue.sum() > 500
    red_cols, blue_cols = np.nonzero(red)[1], np.nonzero(blue)[1]
    assert red_cols.mean() + 20 < blue_cols.mean()
    assert np.median(red_cols) < np.median(blue_cols)


def test_up_is_up_and_lit_from_above(sphere):
    pixels = np.asarray(render_preview(sphere, 128), dtype=np.int32)
    # The +Y half is ochre (red > blue), the -Y half slate (blue > red).
    ochre = pixels[..., 0] > pixels[..., 2] + 40
    slate = pixels[..., 2] > pixels[..., 0] + 40
    assert np.nonzero(ochre)[0].mean() < np.nonzero(slate)[0].mean()  # image rows grow downwards


def test_meshes_without_colours_and_empty_meshes():
    grey = render_preview(trimesh.creation.icosphere(subdivisions=2), 64)
    pixels = np.asarray(grey, dtype=np.int32)
    on_object = np.abs(pixels - preview._background(64)).max(axis=2) > 6
    assert on_object.any()
    spread = pixels[on_object].max(axis=1) - pixels[on_object].min(axis=1)
    assert spread.max() <= 12  # grey shading (anti-aliased edges blend with the bluish background)
    empty = render_preview(trimesh.Trimesh(), 32)
    assert coverage(empty) == 0.0


def test_face_colours_and_loaded_glb_colours(red_left_blue_right):
    by_face = red_left_blue_right.copy()
    by_face.visual.face_colors = np.tile(np.asarray(RED, np.uint8), (len(by_face.faces), 1))
    pixels = np.asarray(render_preview(by_face, 64, supersample=1), dtype=np.int32)
    assert ((pixels[..., 0] > 60) & (pixels[..., 0] > 2 * pixels[..., 2])).sum() > 300
    # A GLB written with a material loads with COLOR_0 as a vertex attribute.
    textured = trimesh.Trimesh(red_left_blue_right.vertices, red_left_blue_right.faces,
                               visual=trimesh.visual.TextureVisuals(), process=False)
    textured.visual.vertex_attributes["color"] = np.asarray(red_left_blue_right.visual.vertex_colors)
    assert np.array_equal(np.asarray(render_preview(textured, 64)), np.asarray(render_preview(red_left_blue_right, 64)))


def test_pyvista_renderer_same_view_or_falls_back(red_left_blue_right):
    pytest.importorskip("pyvista")
    image = render_preview(red_left_blue_right, 96, renderer=preview.Renderer.PYVISTA)
    assert image.size == (96, 96) and image.mode == "RGB"
    assert image.info["renderer"] in ("pyvista", "numpy")  # numpy where the machine has no GL
    pixels = np.asarray(image, dtype=np.int32)
    red = (pixels[..., 0] > 60) & (pixels[..., 0] > 2 * pixels[..., 2])
    blue = (pixels[..., 2] > 60) & (pixels[..., 2] > 2 * pixels[..., 0])
    assert red.sum() > 200 and blue.sum() > 200
    assert np.nonzero(red)[1].mean() + 10 < np.nonzero(blue)[1].mean()


def test_pyvista_failure_falls_back_to_numpy(red_left_blue_right, monkeypatch, tmp_path):
    monkeypatch.setattr(preview, "_VTK_TIMEOUT_S", 0.001)  # the child cannot finish in time
    image = render_preview(red_left_blue_right, 64, renderer=preview.Renderer.PYVISTA)
    assert image.info["renderer"] == "numpy"
    assert np.array_equal(np.asarray(image), np.asarray(render_preview(red_left_blue_right, 64)))
    assert save_preview(red_left_blue_right, tmp_path / "p.png", 64, renderer=preview.Renderer.PYVISTA) == "numpy"

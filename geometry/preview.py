"""Preview images: a small, deterministic software renderer (numpy + Pillow, no GL).

An orthographic z-buffer rasterizer: the camera looks at the mesh from the
front (+Z) turned ``azimuth_deg`` toward +X and raised ``elevation_deg``; the
shape is scaled to fill about 85 % of the image. Each triangle has one colour
(the mean of its vertex colours, or a neutral grey); lighting is Lambert with a
key light from the upper left, a weak fill light from the right and ambient,
using normals interpolated from the vertex normals so that dense marching-cubes
meshes look smooth (but flat across creases sharper than ~37°, so that boxes
stay boxes). The image is rendered at ``supersample``× and reduced with a
Lanczos filter for antialiased edges. Back faces are culled: meshes from
``mesh.py`` are closed.

Everything is vectorised: every triangle's pixel-bounding-box candidates are
generated with ``np.repeat``, tested with precomputed per-triangle edge
functions, and the nearest triangle per pixel wins through ``np.maximum.at``.
Same mesh and size → same pixels.

Optionally (``renderer=Renderer.PYVISTA``) the same view is drawn by VTK
off-screen (EGL) in a child process — a missing GL stack makes VTK crash the
process rather than raise — and any failure falls back to the numpy renderer.
``image.info["renderer"]`` says which one drew the picture. VTK output depends
on the GL driver, so only the numpy renderer is meant for golden images.
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
import tempfile
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from core.files import write_bytes_atomic

if TYPE_CHECKING:
    import trimesh
    from PIL import Image

#: Fraction of the image the larger projected extent fills.
FILL_FRACTION = 0.85
#: Background gradient, top and bottom rows (RGB).
BACKGROUND_TOP = (240, 241, 244)
BACKGROUND_BOTTOM = (196, 200, 207)
#: Colour of triangles without vertex/face colours.
DEFAULT_RGB = (180, 180, 180)
#: Lighting: ambient + key·max(0, n·key) + fill·max(0, n·fill), in camera space.
AMBIENT, KEY, FILL = 0.32, 0.68, 0.18
_KEY_DIR_CAM = (-0.45, 0.65, 0.62)  # (right, up, toward the viewer)
_FILL_DIR_CAM = (0.8, -0.1, 0.6)
# Corners whose vertex normal deviates more than ~37° from the face normal are shaded flat.
_CREASE_COS = 0.8
# Candidates (pixel × triangle pairs) handled per chunk: bounds the memory to ~100 MB.
_CHUNK_CANDIDATES = 2_000_000
# The VTK child process: importing pyvista and the first EGL frame take ~2-4 s.
_VTK_TIMEOUT_S = 60.0


class Renderer(str, Enum):
    """Which renderer draws previews."""

    NUMPY = "numpy"  # built-in software rasterizer: deterministic, no GL (default)
    PYVISTA = "pyvista"  # VTK off-screen in a child process; falls back to numpy


def render_preview(
    mesh: "trimesh.Trimesh",
    size_px: int = 512,
    azimuth_deg: float = 30.0,
    elevation_deg: float = 20.0,
    supersample: int = 2,
    renderer: Renderer = Renderer.NUMPY,
) -> "Image.Image":
    """Render ``mesh`` to a ``size_px`` × ``size_px`` RGB image (see module docstring)."""
    from PIL import Image

    if size_px < 1 or supersample < 1:
        raise ValueError("size_px and supersample must be >= 1")
    if Renderer(renderer) == Renderer.PYVISTA and len(mesh.faces):
        drawn = _render_vtk(mesh, size_px, azimuth_deg, elevation_deg)
        if drawn is not None:
            drawn.info["renderer"] = Renderer.PYVISTA.value
            return drawn
    side = size_px * supersample
    image = _background(side)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if len(faces):
        right, up, back = _camera_basis(azimuth_deg, elevation_deg)
        screen, depth = _project(vertices, right, up, back, side)
        face_ids, pixels = _rasterize(screen, depth, faces, side)
        if len(pixels):
            rgb = _shade(mesh, faces, face_ids, pixels, screen, side, (right, up, back))
            image.reshape(-1, 3)[pixels] = rgb
    result = Image.fromarray(image, mode="RGB")
    if supersample > 1:
        result = result.resize((size_px, size_px), Image.Resampling.LANCZOS)
    result.info["renderer"] = Renderer.NUMPY.value
    return result


def preview_png(mesh: "trimesh.Trimesh", size_px: int = 512, renderer: Renderer = Renderer.NUMPY) -> bytes:
    """The preview as PNG file bytes (no metadata chunks, so no timestamps)."""
    buffer = io.BytesIO()
    render_preview(mesh, size_px, renderer=renderer).save(buffer, format="PNG", optimize=False)
    return buffer.getvalue()


def save_preview(mesh: "trimesh.Trimesh", path: Path, size_px: int = 512,
                 renderer: Renderer = Renderer.NUMPY) -> str:
    """Render and write a PNG atomically; returns the renderer that drew it.

    Raises ExportError if the file cannot be written.
    """

    image = render_preview(mesh, size_px, renderer=renderer)
    buffer = io.BytesIO()
    image.save(buffer, format="PNG", optimize=False)
    write_bytes_atomic(Path(path), buffer.getvalue())
    return image.info["renderer"]


# --------------------------------------------------------------------------- camera


def _camera_basis(azimuth_deg: float, elevation_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors right, up, back (toward the viewer) in world coordinates."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    back = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    right = np.cross([0.0, 1.0, 0.0], back)
    right /= np.linalg.norm(right)  # elevation is never ±90° in practice
    up = np.cross(back, right)
    return right, up, back


def _project(vertices: np.ndarray, right: np.ndarray, up: np.ndarray, back: np.ndarray,
             side: int) -> tuple[np.ndarray, np.ndarray]:
    """(V, 2) pixel coordinates (x right, y down; pixel centres at +0.5) and (V,) depth (larger = nearer)."""
    sx, sy, depth = vertices @ right, vertices @ up, vertices @ back
    lo = np.array([sx.min(), sy.min()])
    hi = np.array([sx.max(), sy.max()])
    extent = max(float((hi - lo).max()), 1e-12)
    scale = FILL_FRACTION * side / extent
    centre = (lo + hi) / 2.0
    screen = np.empty((len(vertices), 2))
    screen[:, 0] = side / 2.0 + (sx - centre[0]) * scale
    screen[:, 1] = side / 2.0 - (sy - centre[1]) * scale
    return screen, depth


# --------------------------------------------------------------------------- rasterizer


def _edge_coefficients(screen: np.ndarray, depth: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per front-facing triangle: linear functions of the pixel centre (x, y).

    Returns (kept face indices (F',), (F', 9) float64 [A0 B0 C0 A1 B1 C1 Az Bz Cz])
    where w0 = A0·x + B0·y + C0 and w1 likewise are the barycentric weights of
    the first two corners, and z the interpolated depth.
    """
    a, b, c = screen[faces[:, 0]], screen[faces[:, 1]], screen[faces[:, 2]]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    # With y pointing down, an outward (counter-clockwise) face seen from the
    # front has negative signed area; the rest are back faces or edge-on.
    keep = np.flatnonzero(area2 < -1e-12)
    a, b, c, area2 = a[keep], b[keep], c[keep], area2[keep]
    za, zb, zc = (depth[faces[keep, i]] for i in range(3))
    inv = 1.0 / area2
    coef = np.empty((len(keep), 9))
    coef[:, 0] = (b[:, 1] - c[:, 1]) * inv
    coef[:, 1] = (c[:, 0] - b[:, 0]) * inv
    coef[:, 2] = (b[:, 0] * c[:, 1] - c[:, 0] * b[:, 1]) * inv
    coef[:, 3] = (c[:, 1] - a[:, 1]) * inv
    coef[:, 4] = (a[:, 0] - c[:, 0]) * inv
    coef[:, 5] = (c[:, 0] * a[:, 1] - a[:, 0] * c[:, 1]) * inv
    dza, dzb = za - zc, zb - zc
    coef[:, 6] = coef[:, 0] * dza + coef[:, 3] * dzb
    coef[:, 7] = coef[:, 1] * dza + coef[:, 4] * dzb
    coef[:, 8] = zc + coef[:, 2] * dza + coef[:, 5] * dzb
    return keep, coef


def _rasterize(screen: np.ndarray, depth: np.ndarray, faces: np.ndarray, side: int) -> tuple[np.ndarray, np.ndarray]:
    """Visible triangle per covered pixel: (N,) face indices and (N,) flat pixel indices (ascending)."""
    keep, coef = _edge_coefficients(screen, depth, faces)
    corners = screen[faces[keep]]  # (F', 3, 2)
    # Pixel (col, row) is covered when its centre (col + 0.5, row + 0.5) is inside.
    lo = np.clip(np.ceil(corners.min(axis=1) - 0.5), 0, side).astype(np.int64)
    hi = np.clip(np.floor(corners.max(axis=1) - 0.5), -1, side - 1).astype(np.int64)
    width = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0)
    counts = width * np.maximum(hi[:, 1] - lo[:, 1] + 1, 0)
    has = np.flatnonzero(counts)
    keep, coef, lo, width, counts = keep[has], coef[has], lo[has], width[has], counts[has]
    inv_width = 1.0 / np.maximum(width, 1)
    columns = [np.ascontiguousarray(coef[:, i]) for i in range(9)]  # gathers of 1-D arrays are cheap

    zbuf = np.full(side * side, -np.inf)
    hits_pix, hits_z, hits_face = [], [], []
    ends = np.cumsum(counts)
    start = 0
    while start < len(counts):
        # Faces [start, stop) hold at most _CHUNK_CANDIDATES candidates (at least one face).
        base = ends[start - 1] if start else 0
        stop = max(int(np.searchsorted(ends, base + _CHUNK_CANDIDATES, side="right")), start + 1)
        n = counts[start:stop]
        face = np.repeat(np.arange(start, stop), n)  # index into the kept arrays
        offset = np.arange(int(n.sum()), dtype=np.float64) - np.repeat(np.cumsum(n) - n, n)
        # row/col within the face's bbox without integer division: offset is an
        # integer, so (offset + 0.5) / width is never within rounding of an integer.
        row_in = np.floor((offset + 0.5) * inv_width[face])
        px = lo[face, 0] + (offset - row_in * width[face]) + 0.5
        py = lo[face, 1] + row_in + 0.5
        w0 = columns[0][face] * px + columns[1][face] * py + columns[2][face]
        w1 = columns[3][face] * px + columns[4][face] * py + columns[5][face]
        # Inclusive edges (tiny tolerance) so that shared edges leave no cracks.
        inside = np.flatnonzero((w0 >= -1e-9) & (w1 >= -1e-9) & (w0 + w1 <= 1.0 + 1e-9))
        face, px, py = face[inside], px[inside], py[inside]
        z = columns[6][face] * px + columns[7][face] * py + columns[8][face]
        pix = py.astype(np.int64) * side + px.astype(np.int64)  # truncation drops the +0.5
        np.maximum.at(zbuf, pix, z)
        hits_pix.append(pix)
        hits_z.append(z)
        hits_face.append(keep[face])
        start = stop
    if not hits_pix:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    pix = np.concatenate(hits_pix)
    front = np.concatenate(hits_z) == zbuf[pix]
    # Ties at equal depth (a pixel exactly on a shared edge): the larger face
    # index wins, so the result never depends on candidate order.
    fbuf = np.full(side * side, -1, dtype=np.int64)
    np.maximum.at(fbuf, pix[front], np.concatenate(hits_face)[front])
    covered = np.flatnonzero(fbuf >= 0)
    return fbuf[covered], covered


# --------------------------------------------------------------------------- shading


def _shade(mesh: "trimesh.Trimesh", faces: np.ndarray, face_ids: np.ndarray, pixels: np.ndarray,
           screen: np.ndarray, side: int, basis: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """(N, 3) uint8 colour of each covered pixel; ``basis`` = camera (right, up, back)."""
    tri = faces[face_ids]
    # Barycentric weights at the pixel centres, for interpolated normals.
    a, b, c = screen[tri[:, 0]], screen[tri[:, 1]], screen[tri[:, 2]]
    px = (pixels % side) + 0.5
    py = (pixels // side) + 0.5
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    w0 = ((b[:, 0] - px) * (c[:, 1] - py) - (c[:, 0] - px) * (b[:, 1] - py)) / area2
    w1 = ((c[:, 0] - px) * (a[:, 1] - py) - (a[:, 0] - px) * (c[:, 1] - py)) / area2
    w2 = 1.0 - w0 - w1
    vn = np.asarray(mesh.vertex_normals, dtype=np.float64)
    fn = np.asarray(mesh.face_normals, dtype=np.float64)[face_ids]
    normal = np.zeros_like(fn)
    for corner, weight in enumerate((w0, w1, w2)):
        n = vn[tri[:, corner]]
        # Across a crease (e.g. a box edge) the averaged vertex normal is wrong
        # for both sides; use the face's own normal there.
        crease = np.einsum("ij,ij->i", n, fn) < _CREASE_COS
        n[crease] = fn[crease]
        normal += n * weight[:, None]
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)

    to_world = np.stack(basis)  # rows: camera axes in world coordinates
    key = _unit(np.asarray(_KEY_DIR_CAM) @ to_world)
    fill = _unit(np.asarray(_FILL_DIR_CAM) @ to_world)
    light = AMBIENT + KEY * np.maximum(normal @ key, 0.0) + FILL * np.maximum(normal @ fill, 0.0)

    base = _face_rgb(mesh, faces)[face_ids]
    return np.clip(base * np.minimum(light, 1.15)[:, None], 0, 255).astype(np.uint8)


def _face_rgb(mesh: "trimesh.Trimesh", faces: np.ndarray) -> np.ndarray:
    """(F, 3) float RGB per face: mean of its vertex colours, face colours, or the default grey."""
    visual = getattr(mesh, "visual", None)
    kind = getattr(visual, "kind", None)
    if kind == "vertex":
        colors = np.asarray(visual.vertex_colors, dtype=np.float64)[:, :3]
        return colors[faces].mean(axis=1)
    if kind == "face":
        return np.asarray(visual.face_colors, dtype=np.float64)[:, :3]
    attributes = getattr(visual, "vertex_attributes", {})
    if "color" in attributes and len(attributes["color"]) == len(mesh.vertices):
        # A GLB with a material loads this way (COLOR_0 as a vertex attribute).
        return np.asarray(attributes["color"], dtype=np.float64)[:, :3][faces].mean(axis=1)
    return np.tile(np.asarray(DEFAULT_RGB, dtype=np.float64), (len(faces), 1))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _background(side: int) -> np.ndarray:
    """(side, side, 3) uint8 vertical gradient, light at the top."""
    t = np.linspace(0.0, 1.0, side)[:, None]
    rows = (1 - t) * np.asarray(BACKGROUND_TOP, float) + t * np.asarray(BACKGROUND_BOTTOM, float)
    return np.ascontiguousarray(np.broadcast_to(rows.round().astype(np.uint8)[:, None, :], (side, side, 3)))


# --------------------------------------------------------------------------- optional VTK renderer


def _render_vtk(mesh: "trimesh.Trimesh", size_px: int, azimuth_deg: float, elevation_deg: float) -> "Image.Image | None":
    """The same view drawn by pyvista in a child process; None if that fails for any reason."""
    from PIL import Image

    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    right, up, back = _camera_basis(azimuth_deg, elevation_deg)
    projected = np.stack([vertices @ right, vertices @ up])
    extent = max(float((projected.max(axis=1) - projected.min(axis=1)).max()), 1e-12)
    mid_screen = (projected.max(axis=1) + projected.min(axis=1)) / 2.0
    mid_depth = float((vertices @ back).max() + (vertices @ back).min()) / 2.0
    focus = mid_screen[0] * right + mid_screen[1] * up + mid_depth * back
    face_rgb = np.clip(_face_rgb(mesh, np.asarray(mesh.faces)), 0, 255).astype(np.uint8)
    with tempfile.TemporaryDirectory(prefix="decollage-vtk-") as tmp:
        scene, png = Path(tmp) / "scene.npz", Path(tmp) / "preview.png"
        np.savez(scene, vertices=vertices, faces=np.asarray(mesh.faces, dtype=np.int64), face_rgb=face_rgb,
                 focus=focus, back=back, up=up, half_height=extent / FILL_FRACTION / 2.0,
                 size_px=size_px, top=BACKGROUND_TOP, bottom=BACKGROUND_BOTTOM)
        env = dict(os.environ, VTK_DEFAULT_OPENGL_WINDOW="vtkEGLRenderWindow")
        try:
            done = subprocess.run([sys.executable, __file__, str(scene), str(png)], env=env,
                                  capture_output=True, timeout=_VTK_TIMEOUT_S, check=False)
        except (OSError, subprocess.SubprocessError):
            return None
        if done.returncode != 0 or not png.is_file():
            return None
        try:
            with Image.open(png) as image:
                return image.convert("RGB")
        except OSError:
            return None


def _vtk_child(scene_path: str, png_path: str) -> None:
    """Child-process side of ``_render_vtk``: draw the saved scene and write a PNG."""
    import pyvista as pv

    scene = np.load(scene_path)
    faces = scene["faces"]
    cells = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()
    poly = pv.PolyData(scene["vertices"], cells)
    poly.cell_data["rgb"] = scene["face_rgb"]
    size = int(scene["size_px"])
    plotter = pv.Plotter(off_screen=True, window_size=(size, size))
    plotter.add_mesh(poly, scalars="rgb", rgb=True, smooth_shading=False, show_scalar_bar=False)
    plotter.set_background(tuple(scene["bottom"] / 255.0), top=tuple(scene["top"] / 255.0))
    focus = scene["focus"]
    distance = 10.0 * float(scene["half_height"]) + 1.0
    plotter.camera.position = tuple(focus + distance * scene["back"])
    plotter.camera.focal_point = tuple(focus)
    plotter.camera.up = tuple(scene["up"])
    plotter.camera.parallel_projection = True
    plotter.camera.parallel_scale = float(scene["half_height"])
    plotter.reset_camera_clipping_range()
    plotter.screenshot(png_path)
    plotter.close()


if __name__ == "__main__":  # run by _render_vtk as a child process
    _vtk_child(sys.argv[1], sys.argv[2])

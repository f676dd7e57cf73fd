"""Contact sheets of style sets: every exemplar rendered, coloured by part, tiled into one PNG.

Role: turns a ``StyleSet`` into a picture a person can judge the detail on.
Each exemplar's cropped labels are meshed by marching cubes at full
resolution (one voxel = one marching-cubes cell, so slats and spindles stay
visible), vertices take the colour of the part of the voxel just inside the
surface, and ``geometry.preview.render_preview`` draws it (numpy renderer,
deterministic, headless). Tiles carry the exemplar's name and category.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from core.files import code_digest, ensure_writable_dir, write_bytes_atomic
from geometry.preview import render_preview
from stylesets.format import Exemplar, StyleSet

if TYPE_CHECKING:
    import trimesh
    from PIL import Image

#: Part colours by label (1-based; index 0 unused): distinct, readable on the grey background.
PART_RGB = np.array([(128, 128, 128), (214, 96, 77), (67, 147, 195), (120, 170, 60), (240, 180, 50),
                     (150, 100, 190), (90, 200, 190), (230, 120, 180), (160, 120, 80)], dtype=np.uint8)
#: Triangles per tile mesh above which it is decimated (renders stay within seconds).
MAX_TILE_TRIANGLES = 250_000


def part_rgb(label: int) -> tuple[int, int, int]:
    """Colour of part label ``label`` (1-based)."""
    return tuple(int(c) for c in PART_RGB[1 + (label - 1) % (len(PART_RGB) - 1)])


def exemplar_mesh(exemplar: Exemplar) -> "trimesh.Trimesh":
    """Marching-cubes mesh of the exemplar (voxel units), vertex-coloured by part."""
    import trimesh
    from skimage.measure import marching_cubes

    labels = exemplar.labels
    padded = np.pad(labels, 1)
    verts, faces, _, _ = marching_cubes((padded > 0).astype(np.float32), level=0.5, method="lewiner")
    faces = faces[:, ::-1]  # outward normals for skimage's winding on a "solid = 1" field
    if len(faces) > MAX_TILE_TRIANGLES:
        import fast_simplification

        verts, faces = fast_simplification.simplify(verts.astype(np.float32), faces.astype(np.int64),
                                                    target_reduction=1 - MAX_TILE_TRIANGLES / len(faces))
    mesh = trimesh.Trimesh(vertices=verts, faces=faces, process=False)
    # Part at each vertex: the occupied voxel nearest to it among its 8 cell corners.
    idx = np.clip(np.round(verts).astype(np.int64), 0, np.array(padded.shape) - 1)
    lab = padded[idx[:, 0], idx[:, 1], idx[:, 2]]
    missing = lab == 0
    if missing.any():
        # Vertices rounding onto an empty voxel look one step along the inward normal instead.
        normals = mesh.vertex_normals[missing]
        probe = np.clip(np.round(verts[missing] - normals).astype(np.int64), 0, np.array(padded.shape) - 1)
        lab[missing] = padded[probe[:, 0], probe[:, 1], probe[:, 2]]
    rgb = PART_RGB[np.where(lab > 0, 1 + (lab.astype(np.int64) - 1) % (len(PART_RGB) - 1), 0)]
    mesh.visual.vertex_colors = np.c_[rgb, np.full(len(rgb), 255, np.uint8)]
    return mesh


def render_exemplar(exemplar: Exemplar, size_px: int = 320) -> "Image.Image":
    """One exemplar's tile image (no caption)."""

    return render_preview(exemplar_mesh(exemplar), size_px=size_px, azimuth_deg=35.0, elevation_deg=22.0,
                          supersample=2)


def contact_sheet(style_set: StyleSet, tile_px: int = 320, columns: int = 8) -> "Image.Image":
    """Every exemplar of ``style_set`` in a grid, captioned with name and category, plus a part legend."""
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.load_default()
    caption_px = 34
    n = len(style_set.exemplars)
    columns = max(1, min(columns, n))
    rows = -(-n // columns)
    legend_px = 30
    title = f"set '{style_set.name}': {n} exemplars at {style_set.resolution}^3"
    # The legend is one line; a sheet of few tiles is widened to hold it.
    legend_w = 8 + sum(30 + 8 * len(p) for p in style_set.vocabulary.parts) + 20 + 7 * len(title)
    width = max(columns * tile_px, legend_w)
    sheet = Image.new("RGB", (width, rows * (tile_px + caption_px) + legend_px), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    x = 8
    for i, part in enumerate(style_set.vocabulary.parts):
        draw.rectangle([x, 8, x + 14, 22], fill=part_rgb(i + 1))
        draw.text((x + 18, 9), part, fill=(0, 0, 0), font=font)
        x += 30 + 8 * len(part)
    draw.text((x + 20, 9), title, fill=(0, 0, 0), font=font)
    for i, ex in enumerate(style_set.exemplars):
        r, c = divmod(i, columns)
        left, top = c * tile_px, legend_px + r * (tile_px + caption_px)
        sheet.paste(render_exemplar(ex, tile_px), (left, top))
        ratio = ex.meta.get("detail", {}).get("ratio", 0)
        draw.text((left + 6, top + tile_px + 3), ex.name, fill=(0, 0, 0), font=font)
        draw.text((left + 6, top + tile_px + 17), f"{ex.category}  detail x{ratio:.2f}", fill=(90, 90, 90),
                  font=font)
    return sheet


#: PNG text chunk holding the inputs hash of the set a sheet was drawn from (so an up-to-date sheet is kept).
SHEET_HASH_KEY = "decollage-style-set"


def _code_hash() -> str:
    """sha256 (16 hex digits) of the code that draws sheets: a new renderer redraws old sheets."""

    return code_digest("stylesets/contact_sheet.py", "geometry/preview.py")[:16]


def sheet_path(style_set: StyleSet) -> "Path":
    """Default sheet file: ``<name>.png`` next to the set file."""
    from pathlib import Path

    if style_set.path is None:
        raise ValueError("the style set was not loaded from a file")
    return Path(style_set.path).with_name(f"{style_set.name}.png")


def write_contact_sheet(style_set: StyleSet, path: "Path | None" = None, force: bool = False) -> tuple["Path", bool]:
    """Write the set's contact sheet PNG (default ``sheet_path``); returns (path, written).

    The PNG records the set's inputs hash (and this renderer's code hash); an
    existing sheet with the same record is kept (written False) unless ``force``. Written atomically (ExportError).
    """
    import io
    from pathlib import Path

    from PIL import Image, PngImagePlugin


    path = Path(path) if path is not None else sheet_path(style_set)
    stamp = f"{style_set.name}:{style_set.inputs_hash}:{_code_hash()}"
    if not force and path.is_file():
        try:
            with Image.open(path) as old:
                if getattr(old, "text", {}).get(SHEET_HASH_KEY) == stamp:
                    return path, False
        except (OSError, ValueError):
            pass  # unreadable: redraw
    info = PngImagePlugin.PngInfo()
    info.add_text(SHEET_HASH_KEY, stamp)
    buffer = io.BytesIO()
    contact_sheet(style_set).save(buffer, format="PNG", pnginfo=info)
    if str(path.parent):
        ensure_writable_dir(path.parent)
    write_bytes_atomic(path, buffer.getvalue())
    return path, True

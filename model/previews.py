"""Sample previews during training: a picture of what the generator makes of fixed inputs.

Role: ``write_preview`` renders, for up to ``n`` styles, the style exemplar as the
reconstruction step sees it (top row: its smoothed 256³ target) next to what the
generator makes of that exemplar's coarse grid (bottom row), plus one held-out
augmented, style-mixed content (last column, generated only). The inputs are drawn
from a fixed seed, so previews of successive steps are comparable. The output is a
PNG of ``n + 1`` columns × 2 rows of ``tile_px`` tiles, grey meshes at the iso level
0.4, headless (``geometry.preview``'s numpy renderer).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from geometry.preview import render_preview
from model.config import ModelConfig
from model.data import AugmentConfig, Exemplar, Sample, augmented_sample, style_sample
from core.grid import ISO_LEVEL

if TYPE_CHECKING:
    from PIL import Image

#: Seed of the preview inputs (distinct from any training seed's draws: its own stream of steps).
PREVIEW_SEED = 90_210


def _tile(volume: np.ndarray, tile_px: int) -> "Image.Image":
    """(X, Y, Z) occupancy in [0, 1] → a rendered tile (a blank one where nothing crosses the iso level)."""
    import trimesh
    from PIL import Image

    if volume.max(initial=0.0) <= ISO_LEVEL:  # nothing to mesh (the padding below is always empty)
        return Image.new("RGB", (tile_px, tile_px), (235, 235, 235))
    from skimage.measure import marching_cubes

    verts, faces, _, _ = marching_cubes(np.pad(volume, 1).astype(np.float32), level=ISO_LEVEL)
    mesh = trimesh.Trimesh(verts, faces[:, ::-1], process=False)
    return render_preview(mesh, size_px=tile_px, azimuth_deg=35.0, elevation_deg=22.0, supersample=1)


def preview_samples(exemplars: Sequence[Exemplar], cfg: ModelConfig, aug: AugmentConfig, n: int) -> list[Sample]:
    """The fixed preview inputs: ``min(n, N)`` style samples, then one augmented mixed content."""
    styles = np.linspace(0, len(exemplars) - 1, num=min(n, len(exemplars))).round().astype(int)
    samples = [style_sample(exemplars, int(s), cfg, aug, PREVIEW_SEED, k) for k, s in enumerate(styles)]
    samples.append(augmented_sample(exemplars, cfg, aug, PREVIEW_SEED, 0))
    return samples


def write_preview(generator, samples: Sequence[Sample], path: Path, tile_px: int = 192) -> Path:
    """Render targets (top) and generated outputs (bottom) of ``samples`` into the PNG ``path``."""
    import torch
    from PIL import Image, ImageDraw

    cols = len(samples)
    sheet = Image.new("RGB", (cols * tile_px, 2 * tile_px + 16), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    was_training = generator.training
    generator.eval()
    try:
        for c, s in enumerate(samples):
            with torch.inference_mode():
                inputs = generator.make_inputs(torch.from_numpy(s.coarse_occupancy)[None],
                                               torch.from_numpy(s.coarse_labels.astype(np.int64))[None],
                                               torch.from_numpy(s.style_index())[None])
                out = generator(*inputs, final_only=True)[-1][0, 0].float().cpu().numpy()
            is_style = c < cols - 1
            if is_style:
                sheet.paste(_tile(s.targets[-1], tile_px), (c * tile_px, 0))
            sheet.paste(_tile(out, tile_px), (c * tile_px, tile_px))
            label = s.sources[0] if is_style else "mix: " + "+".join(s.sources)
            draw.text((c * tile_px + 4, 2 * tile_px + 2), label[:30], fill=(0, 0, 0))
    finally:
        generator.train(was_training)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path)
    return path

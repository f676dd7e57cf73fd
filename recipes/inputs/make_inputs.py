"""Regenerate the small example inputs in this folder (they are committed; run only to change them).

    .venv/bin/python recipes/inputs/make_inputs.py

- ``cottage.glb``: a low-poly cottage made here, three named nodes (walls, roof,
  chimney), +Y up, metres: what a user would export from a DCC tool.
- ``mushroom.npz``: a 16³ voxel grid with ``occupancy``, ``part`` and
  ``part_names`` (stem, cap), [x, y, z] indexed, +Y up: what another generator
  would hand over.
- ``tower.vox``: a 12 × 12 × 16 MagicaVoxel model (z up) painted with palette
  index 1 (walls), 2 (roof) and 3 (door): what a voxel artist would save.
"""

from pathlib import Path

import numpy as np
import trimesh

from sources.vox_file import write_vox

HERE = Path(__file__).parent


def cottage() -> trimesh.Scene:
    walls = trimesh.creation.box(extents=(1.2, 0.7, 0.8))
    walls.apply_translation((0, 0.35, 0))
    # Gable roof: a triangular prism along X, overhanging the walls.
    profile = trimesh.path.polygons.Polygon([(-0.5, 0.0), (0.5, 0.0), (0.0, 0.45)])
    roof = trimesh.creation.extrude_polygon(profile, 1.4)  # along +Z
    roof.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
    roof.apply_translation((-0.7, 0.7, 0))
    chimney = trimesh.creation.box(extents=(0.16, 0.4, 0.16))
    chimney.apply_translation((0.3, 1.0, -0.12))
    scene = trimesh.Scene()
    for name, mesh in (("walls", walls), ("roof", roof), ("chimney", chimney)):
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    return scene


def mushroom(n: int = 16) -> dict[str, np.ndarray]:
    x, y, z = np.meshgrid(*(np.arange(n) + 0.5,) * 3, indexing="ij")
    c = n / 2
    r_xz = np.hypot(x - c, z - c)
    stem = (r_xz <= 2.6) & (y < 8.5)
    cap = ((r_xz / 7.5) ** 2 + ((y - 8) / 6.0) ** 2 <= 1.0) & (y >= 8)
    occupancy = stem | cap
    part = np.where(cap, 1, 0).astype(np.int16)
    part[~occupancy] = 0
    return {"occupancy": occupancy, "part": part, "part_names": np.array(["stem", "cap"])}


def tower() -> bytes:
    grid = np.zeros((12, 12, 16), dtype=np.uint8)
    x, y = np.meshgrid(np.arange(12) + 0.5, np.arange(12) + 0.5, indexing="ij")
    r = np.hypot(x - 6, y - 6)
    grid[r <= 4.5, :10] = 1  # round walls
    for z in range(10, 16):  # a cone roof
        grid[r <= 5.5 * (16 - z) / 6, z] = 2
    grid[5:7, 1:3, 0:3] = 3  # a door on the front (-y)
    palette = np.zeros((256, 4), dtype=np.uint8)
    palette[1:4] = [(168, 160, 150, 255), (193, 80, 62, 255), (139, 100, 72, 255)]
    return write_vox([grid], palette)


if __name__ == "__main__":
    cottage().export(HERE / "cottage.glb")
    np.savez_compressed(HERE / "mushroom.npz", **mushroom())
    (HERE / "tower.vox").write_bytes(tower())
    print("wrote", HERE / "cottage.glb", HERE / "mushroom.npz", HERE / "tower.vox")

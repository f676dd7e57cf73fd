"""Compressed GLBs (pipeline/glb_meshopt.py): what comes back, the validator, the size goal, determinism."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy import ndimage
from scipy.spatial import cKDTree

from core.grid import FineGrid
from core.recipe import EngineProfile, ExportFormat, GlbCompression
from pipeline.export import _encode_glb_nodes, export_asset
from pipeline.glb_meshopt import POSITION_STEPS, encode_glb_meshopt
from pipeline.mesh import MeshSettings, mesh_fine_grid
from tests.glb_reader import chunks, decompress, read_glb
from tests.gltf_validator import validate_glbs

VOXEL = 0.004


def coloured_mesh(max_triangles: int, n: int = 96) -> trimesh.Trimesh:
    """A bumpy two-style sphere, decimated to ``max_triangles``, in metres."""
    idx = np.indices((n, n, n)).transpose(1, 2, 3, 0) - (n - 1) / 2
    r = np.linalg.norm(idx, axis=-1)
    bumps = 2.0 * np.sin(idx[..., 0] * 0.5) * np.sin(idx[..., 1] * 0.4)
    occ = ndimage.gaussian_filter((r < n * 0.4 + bumps).astype(np.float32), 0.8)
    style = (idx[..., 1] > 0).astype(np.int16)
    fine = FineGrid(occ, style, ("brick", "slate"), VOXEL, (1.0, 0.0, -0.5))
    return mesh_fine_grid(fine, MeshSettings(max_triangles=max_triangles))


@pytest.fixture(scope="module")
def mesh() -> trimesh.Trimesh:
    return coloured_mesh(20_000)


def test_geometry_colours_and_normals_come_back(mesh):
    tree, meshes = read_glb(encode_glb_meshopt([("thing", mesh)], asset_extras={"provenance": {"a": 1}}))
    assert tree["extensionsRequired"] == ["EXT_meshopt_compression", "KHR_mesh_quantization"]
    assert tree["asset"]["extras"] == {"provenance": {"a": 1}}
    verts, faces, normals, colours = meshes["thing"]
    assert len(verts) == len(mesh.vertices) and len(faces) == len(mesh.faces)
    step = (mesh.bounds[1] - mesh.bounds[0]) / POSITION_STEPS
    gap, nearest = cKDTree(mesh.vertices).query(verts)
    assert gap.max() <= np.linalg.norm(step) / 2 + 1e-12  # within half a quantization step
    assert len(np.unique(nearest)) == len(verts)  # one to one
    np.testing.assert_array_equal(colours, np.asarray(mesh.visual.vertex_colors)[nearest])
    assert np.einsum("ij,ij->i", normals, np.asarray(mesh.vertex_normals)[nearest]).min() > 0.99
    # the same triangles, reordered for the vertex cache
    back = {tuple(sorted(t)) for t in nearest[faces]}
    assert back == {tuple(sorted(t)) for t in np.asarray(mesh.faces)}
    assert trimesh.Trimesh(verts, faces).volume == pytest.approx(mesh.volume, rel=1e-3)


def test_a_50k_triangle_asset_is_under_1_mb_and_several_times_smaller_than_plain():
    big = coloured_mesh(50_000, n=160)
    assert len(big.faces) > 45_000
    packed = encode_glb_meshopt([("big", big)])
    plain = _encode_glb_nodes([("big", big)])
    assert len(packed) < 1_000_000 and len(plain) > 5 * len(packed)


def test_the_bytes_do_not_change_between_runs(mesh):
    assert encode_glb_meshopt([("thing", mesh)]) == encode_glb_meshopt([("thing", mesh)])


@pytest.mark.e2e  # the Khronos validator (node)
@pytest.mark.parametrize("profile", [EngineProfile.GENERIC, EngineProfile.UNITY])
def test_compressed_files_and_their_decoded_data_pass_the_validator(tmp_path, mesh, profile):
    lods = [coloured_mesh(5_000)]
    written, _ = export_asset(mesh, tmp_path, "thing", [ExportFormat.GLB], profile=profile, lods=lods,
                              glb_material=True, compression=GlbCompression.MESHOPT,
                              asset_extras={"provenance": {}})
    glbs = [p for k, p in written.items() if k.startswith("glb")]
    decoded = []
    for path in glbs:
        tree, _ = chunks(path.read_bytes())
        assert "EXT_meshopt_compression" in tree["extensionsRequired"]
        plain = tmp_path / f"{path.stem}.decoded.glb"
        plain.write_bytes(decompress(path.read_bytes()))
        decoded.append(plain)
    for report in validate_glbs(glbs + decoded):
        assert report["errors"] == 0 and report["warnings"] == 0, report

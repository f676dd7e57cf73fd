"""Meshing: the detailizer's fine occupancy field → one closed, coloured triangle mesh.

Steps (all deterministic):

1. crop the field to the bounding box of voxels ≥ iso plus a one-voxel margin;
2. pad the crop with one voxel of zeros, so that shapes touching the grid
   border still give a closed surface (marching cubes leaves it open otherwise);
3. marching cubes (scikit-image, Lewiner) at the iso level; faces are flipped so
   that normals point outward (positive volume);
4. optional Taubin smoothing, then quadric decimation (fast-simplification) down
   to ``max_triangles``, both in voxel units so that they do not depend on scale;
5. map to metres: a sample index ``idx`` of the padded crop is the centre of grid
   voxel ``idx - 1 + crop_start``, i.e. ``origin + (idx - 1 + crop_start + 0.5) * voxel``;
6. vertex colours: the palette colour of the style of the voxel just inside the
   surface at each vertex.

The result is a ``trimesh.Trimesh`` in metres, canonical frame (+Y up, front +Z).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core.errors import MeshingError
from core.grid import ISO_LEVEL, FineGrid
from core.recipe import ExportSettings
from pipeline.palette import palette_rgba

if TYPE_CHECKING:
    import trimesh


# Taubin's classic pass-band choice: λ = 0.5, μ = -0.53 (k_PB ≈ 0.1) removes the
# marching-cubes staircase with almost no shrinkage.
_TAUBIN_LAMBDA = 0.5
_TAUBIN_MU = 0.53

# How far inside the surface (in voxels) a vertex looks up its style: half a
# voxel lands in the occupied voxel next to the surface, whose style is the
# detailizer's own choice rather than the fill of an empty neighbour.
_STYLE_PROBE_VOXELS = 0.5


@dataclass(frozen=True)
class MeshSettings:
    """How a fine grid becomes a mesh.

    Attributes:
        taubin_iterations: Taubin smoothing passes (each = one shrink + one
            inflate step); 0 = off.
        max_triangles: decimate to at most this many triangles; None = never.
        vertex_colors: colour vertices by style (palette.py); off = no colours.
    """

    taubin_iterations: int = 0
    max_triangles: int | None = 150_000
    vertex_colors: bool = True

    def __post_init__(self) -> None:
        if self.taubin_iterations < 0:
            raise ValueError("taubin_iterations must be >= 0")
        if self.max_triangles is not None and self.max_triangles < 4:
            raise ValueError("max_triangles must be >= 4 (a tetrahedron) or None")

    @classmethod
    def from_export(cls, export: "ExportSettings") -> "MeshSettings":
        """The meshing part of a recipe's ``export`` settings."""
        return cls(
            taubin_iterations=export.taubin_iterations,
            max_triangles=export.max_triangles,
            vertex_colors=export.vertex_colors,
        )


def mesh_fine_grid(fine: FineGrid, settings: MeshSettings | None = None, iso: float = ISO_LEVEL) -> "trimesh.Trimesh":
    """Turn a fine occupancy field into a closed triangle mesh in metres.

    Args:
        fine: the detailizer's output; ``occupancy`` (X, Y, Z) float32 in [0, 1].
        settings: smoothing / decimation / colour options (default ``MeshSettings()``).
        iso: surface level; voxels with occupancy ≥ iso are inside.

    Returns:
        ``trimesh.Trimesh`` with outward normals, vertices in metres; with
        ``settings.vertex_colors`` its ``visual.vertex_colors`` are (V, 4) uint8 RGBA.

    Raises:
        MeshingError: the field is empty, not finite, or a meshing step failed.
    """
    import trimesh

    settings = settings or MeshSettings()
    crop, start = crop_padded(fine.occupancy, iso)
    verts, faces = marching_cubes(crop, iso)
    # Back to grid-voxel units (still unscaled): undo the pad, add the crop start.
    verts += start - 1

    if settings.taubin_iterations > 0:
        smooth = trimesh.Trimesh(verts, faces, process=True)
        trimesh.smoothing.filter_taubin(
            smooth, lamb=_TAUBIN_LAMBDA, nu=_TAUBIN_MU, iterations=2 * settings.taubin_iterations
        )
        verts, faces = np.asarray(smooth.vertices), np.asarray(smooth.faces)

    if settings.max_triangles is not None and len(faces) > settings.max_triangles:
        verts, faces = decimate(verts, faces, settings.max_triangles)

    origin = np.asarray(fine.origin_m, dtype=np.float64)
    verts_m = origin + (verts + 0.5) * float(fine.voxel_size_m)
    mesh = trimesh.Trimesh(verts_m, faces, process=True)
    if len(mesh.faces) == 0:
        raise MeshingError("meshing produced no triangles", hint="the detailed shape is too small or too thin")
    # Guard against a change of scikit-image's winding convention: the volume of
    # a closed, outward-facing mesh is positive.
    if signed_volume(mesh.vertices, mesh.faces) < 0:
        mesh.invert()

    if settings.vertex_colors:
        mesh.visual.vertex_colors = vertex_style_colors(fine, mesh)
    return mesh


def crop_padded(occupancy: np.ndarray, iso: float) -> tuple[np.ndarray, np.ndarray]:
    """Crop to the inside voxels' bbox (+1 margin) and pad with one voxel of zeros.

    Returns the padded float32 crop and the (3,) grid index of the crop's first
    voxel (float64 holding whole numbers, ready to add to vertex indices).
    """
    # Max-projections are one cheap pass each and, unlike a comparison, carry a
    # NaN/inf anywhere in the field through to the check below.
    projections = [occupancy.max(axis=axes) for axes in ((1, 2), (0, 2), (0, 1))]
    if not all(np.isfinite(p).all() for p in projections):
        raise MeshingError(
            "the detailed grid contains NaN or infinite values",
            hint="the detailizer produced invalid output; check its checkpoint and input",
        )
    lo, hi = [], []
    for proj in projections:
        inside = np.flatnonzero(proj >= iso)
        if inside.size == 0:
            raise MeshingError(
                "the detailed grid is empty; nothing to mesh",
                hint="no voxel reaches the iso level; check the source shape, the grid fit, and the detailizer",
            )
        lo.append(max(int(inside[0]) - 1, 0))
        hi.append(min(int(inside[-1]) + 2, proj.shape[0]))
    crop = occupancy[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    return np.pad(crop, 1, mode="constant", constant_values=0.0), np.asarray(lo, dtype=np.float64)


def marching_cubes(volume: np.ndarray, iso: float) -> tuple[np.ndarray, np.ndarray]:
    """(V, 3) float64 sample-index vertices and (F, 3) int64 outward-wound faces."""
    from skimage import measure

    try:
        verts, faces, _normals, _values = measure.marching_cubes(
            volume, level=iso, method="lewiner", allow_degenerate=False
        )
    except (ValueError, RuntimeError) as exc:
        raise MeshingError(f"marching cubes failed: {exc}", hint="check the detailed grid's values") from None
    # scikit-image winds faces so that normals point down the gradient, i.e.
    # into a field that is high inside; reversing each face turns them outward.
    return verts.astype(np.float64), np.ascontiguousarray(faces[:, ::-1], dtype=np.int64)


def decimate(verts: np.ndarray, faces: np.ndarray, target: int) -> tuple[np.ndarray, np.ndarray]:
    """Quadric decimation to at most ``target`` faces (voxel units in, voxel units out)."""
    import fast_simplification

    try:
        out_v, out_f = fast_simplification.simplify(verts, faces.astype(np.int32), target_count=target)
        if len(out_f) > target:
            # The simplifier stops early when no collapse stays under its error
            # bound; one more round from the smaller mesh nearly always finishes.
            out_v, out_f = fast_simplification.simplify(out_v, out_f.astype(np.int32), target_count=target)
    except (ValueError, RuntimeError) as exc:
        raise MeshingError(f"decimation failed: {exc}", field="export.max_triangles",
                           hint="set export.max_triangles: null to skip it") from None
    out_f = drop_coincident_faces(np.asarray(out_f, dtype=np.int64))
    if len(out_f) > target:
        raise MeshingError(
            f"could not decimate below {len(out_f)} triangles (max_triangles is {target})",
            field="export.max_triangles", hint="raise export.max_triangles or set it to null",
        )
    if len(out_f) == 0:
        raise MeshingError(f"decimation to {target} triangles left nothing", field="export.max_triangles",
                           hint="raise export.max_triangles")
    return np.asarray(out_v, dtype=np.float64), out_f


def drop_coincident_faces(faces: np.ndarray) -> np.ndarray:
    """(F', 3) faces without degenerate faces and without faces that share all three vertices.

    Strong decimation occasionally folds a thin spot into two back-to-back
    triangles on the same three vertices (a zero-volume fin); their edges are
    then used four times and the mesh is no longer watertight. Removing every
    copy of such a triangle restores a closed 2-manifold.
    """
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    if len(faces) == 0:
        return faces
    key = np.sort(faces, axis=1)
    if int(key[:, 2].max()) < (1 << 21):
        # One int64 per triangle: a 1-D unique is several times faster than axis=0.
        key = (key[:, 0] << 42) | (key[:, 1] << 21) | key[:, 2]
        _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    else:
        _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inverse.ravel()] == 1]


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume (units³) of a closed triangle mesh; positive when faces wind outward.

    Sum of the signed tetrahedra (origin, a, b, c); much cheaper than trimesh's
    full mass properties, which compute inertia as well.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)


def vertex_style_colors(fine: FineGrid, mesh: "trimesh.Trimesh") -> np.ndarray:
    """(V, 4) uint8 RGBA: palette colour of the style just inside the surface at each vertex.

    Each vertex looks half a voxel inward along its normal and takes the style of
    the voxel there (indices clamped to the grid); invalid styles get the neutral grey.
    """
    voxel = float(fine.voxel_size_m)
    probe = np.asarray(mesh.vertices) - _STYLE_PROBE_VOXELS * voxel * np.asarray(mesh.vertex_normals)
    idx = np.floor((probe - np.asarray(fine.origin_m, dtype=np.float64)) / voxel).astype(np.int64)
    np.clip(idx, 0, np.asarray(fine.shape) - 1, out=idx)
    styles = fine.style[idx[:, 0], idx[:, 1], idx[:, 2]].astype(np.int64)
    lut = palette_rgba(fine.style_names)
    neutral = len(fine.style_names)
    valid = (styles >= 0) & (styles < neutral)
    return lut[np.where(valid, styles, neutral)]


def mesh_stats(mesh: "trimesh.Trimesh") -> dict:
    """Plain-JSON facts about a mesh for the manifest (lengths in metres).

    Pass the mesh as exported (pivot applied) so that the box matches the files.
    """
    lo, hi = np.asarray(mesh.bounds, dtype=np.float64)
    return {
        "triangles": int(len(mesh.faces)),
        "vertices": int(len(mesh.vertices)),
        "bbox_min_m": [float(v) for v in lo],
        "bbox_max_m": [float(v) for v in hi],
        "watertight": bool(mesh.is_watertight),
    }

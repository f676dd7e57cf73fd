"""Export: a finished mesh → GLB / OBJ / STL / PLY files, written all-or-nothing.

Every asset's files are first written to hidden temporary files in the output
folder (same filesystem), and moved onto their final names with ``os.replace``
only once every one of them was written. A failure at any point removes the
temporaries and raises ``ExportError``: nothing half-written ever appears
under a final name.

The mesh is already in the canonical frame (+Y up, front +Z, metres, as glTF
wants), so no rotation happens here; only the pivot moves it. Encoders are
deterministic: the same mesh gives byte-identical files (no timestamps, no
random names inside the files).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from core.errors import DecollageError, ExportError
from core.files import AtomicWriter, ensure_writable_dir
from core.recipe import EngineProfile, ExportFormat, GlbCompression, Pivot
from geometry.preview import preview_png
from pipeline.engines import layout, other_format_transform
from pipeline.glb_meshopt import encode_glb_meshopt
from pipeline.mesh import mesh_stats  # noqa: F401 - part of this module's API (manifest facts)

if TYPE_CHECKING:
    import trimesh

#: Written into the GLB ``asset.generator`` field and the OBJ/PLY header comment.
GENERATOR = "decollage"

# GLB material: glTF's default material (used when a primitive has none) is
# fully metallic, which renders vertex colours nearly black in most engines
# and viewers; a rough dielectric white shows COLOR_0 as intended.
_GLB_MATERIAL = {
    "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9},
}

_GL_ARRAY_BUFFER, _GL_ELEMENT_ARRAY_BUFFER = 34962, 34963

# --------------------------------------------------------------------------- pivot


def pivot_translation(bounds_m: np.ndarray, pivot: Pivot) -> np.ndarray:
    """(3,) translation in metres that puts a mesh with ``bounds_m`` (2, 3) at ``pivot``.

    bottom_center: footprint centre (x, z) at 0 and lowest point at y = 0.
    center: bounding-box centre at 0.  source: no translation.
    """
    lo, hi = np.asarray(bounds_m, dtype=np.float64)
    centre = (lo + hi) / 2.0
    pivot = Pivot(pivot)
    if pivot == Pivot.BOTTOM_CENTER:
        return -np.array([centre[0], lo[1], centre[2]])
    if pivot == Pivot.CENTER:
        return -centre
    return np.zeros(3)


def apply_pivot(mesh: "trimesh.Trimesh", pivot: Pivot) -> tuple["trimesh.Trimesh", np.ndarray]:
    """A translated copy of ``mesh`` and the (3,) translation in metres that was applied."""
    shift = pivot_translation(mesh.bounds, pivot)
    return transformed(mesh, shift), shift


def transformed(mesh: "trimesh.Trimesh", shift: np.ndarray, linear: np.ndarray | None = None) -> "trimesh.Trimesh":
    """A copy of ``mesh`` translated by ``shift`` (3,), then mapped by ``linear`` (3, 3; det > 0) if given.

    The copy shares faces, carries the vertex normals and the vertex or face
    colours; it has no metadata, so nothing from the caller leaks into the
    files. Built from arrays because ``Trimesh.copy`` deep-copies and re-hashes
    everything (~10× slower here).
    """
    import trimesh

    vertices = np.asarray(mesh.vertices, dtype=np.float64) + shift
    normals = np.asarray(mesh.vertex_normals)
    if linear is not None:
        vertices = vertices @ linear.T
        normals = normals @ linear.T
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    kind = getattr(mesh.visual, "kind", None)
    return trimesh.Trimesh(
        vertices=vertices,
        faces=np.asarray(mesh.faces),
        vertex_normals=normals,
        vertex_colors=np.asarray(mesh.visual.vertex_colors) if kind == "vertex" else None,
        face_colors=np.asarray(mesh.visual.face_colors) if kind == "face" else None,
        process=False,
        validate=False,
    )


# --------------------------------------------------------------------------- encoders


def _encode_glb(mesh: "trimesh.Trimesh", stem: str, matte_material: bool = False) -> bytes:
    """One mesh as a GLB node named ``stem`` (see ``_encode_glb_nodes``)."""
    return _encode_glb_nodes([(stem, mesh)], matte_material)


def _encode_glb_nodes(nodes: list[tuple[str, "trimesh.Trimesh"]], matte_material: bool = False,
                      asset_extras: dict | None = None, compression: GlbCompression = GlbCompression.NONE) -> bytes:
    """GLB with one named node (and mesh) per entry, normals and COLOR_0 where coloured.

    ``matte_material`` adds a white non-metallic material. ``asset_extras`` (plain JSON)
    becomes the glTF ``asset.extras`` (the asset's provenance, ``pipeline/provenance.py``).
    ``compression`` meshopt writes quantized, compressed geometry (``pipeline/glb_meshopt.py``).

    Without a material, glTF's default one is fully metallic, which some
    renderers (three.js, for one) show almost black; with one, trimesh reads the
    colours back as a vertex attribute of a textured visual instead of as plain
    vertex colours. So the material is a choice (``export.glb_material``).
    """
    import trimesh

    if GlbCompression(compression) == GlbCompression.MESHOPT:
        return encode_glb_meshopt(nodes, _GLB_MATERIAL if matte_material else None, asset_extras, GENERATOR)
    scene = trimesh.Scene()
    for name, mesh in nodes:
        scene.add_geometry(mesh, geom_name=name, node_name=name)

    def finish_tree(tree: dict) -> None:
        tree["asset"]["generator"] = GENERATOR
        if asset_extras:
            tree["asset"]["extras"] = asset_extras
        if matte_material:
            tree["materials"] = [{"name": nodes[0][0], **_GLB_MATERIAL}]
        for gltf_mesh in tree.get("meshes", []):
            gltf_mesh.pop("extras", None)  # trimesh copies mesh.metadata here; keep files clean
            for primitive in gltf_mesh["primitives"]:
                if matte_material:
                    primitive["material"] = 0
                # Buffer-view targets let loaders upload straight to the GPU
                # (the Khronos validator hints at them otherwise).
                accessors, views = tree["accessors"], tree["bufferViews"]
                for accessor in primitive["attributes"].values():
                    views[accessors[accessor]["bufferView"]]["target"] = _GL_ARRAY_BUFFER
                views[accessors[primitive["indices"]]["bufferView"]]["target"] = _GL_ELEMENT_ARRAY_BUFFER

    return trimesh.exchange.gltf.export_glb(scene, include_normals=True, tree_postprocessor=finish_tree)


def _encode_obj(mesh: "trimesh.Trimesh", stem: str) -> bytes:
    import trimesh

    # Colours use the common "v x y z r g b" extension; no texture, so no .mtl file.
    text = trimesh.exchange.obj.export_obj(
        mesh, include_normals=True, include_color=True, include_texture=False,
        header=f"{GENERATOR}: {stem}, metres, +Y up",
    )
    return text.encode("utf-8")


def _encode_stl(mesh: "trimesh.Trimesh", stem: str) -> bytes:
    import trimesh

    return trimesh.exchange.stl.export_stl(mesh)


def _encode_ply(mesh: "trimesh.Trimesh", stem: str) -> bytes:
    import trimesh

    return trimesh.exchange.ply.export_ply(mesh, encoding="binary", vertex_normal=True)


#: One encoder per format: (mesh, stem) → file bytes.
ENCODERS: dict[ExportFormat, Callable[["trimesh.Trimesh", str], bytes]] = {
    ExportFormat.GLB: _encode_glb,
    ExportFormat.OBJ: _encode_obj,
    ExportFormat.STL: _encode_stl,
    ExportFormat.PLY: _encode_ply,
}


def export_asset(
    mesh: "trimesh.Trimesh",
    out_dir: Path,
    stem: str,
    formats: list[ExportFormat],
    pivot: Pivot = Pivot.BOTTOM_CENTER,
    preview_size_px: int | None = None,
    glb_material: bool = False,
    profile: EngineProfile = EngineProfile.GENERIC,
    lods: Sequence["trimesh.Trimesh"] = (),
    collision: Sequence["trimesh.Trimesh"] = (),
    asset_extras: dict | None = None,
    extra_files: Sequence[tuple[str, str, Callable[[], bytes]]] = (),
    compression: GlbCompression = GlbCompression.NONE,
) -> tuple[dict[str, Path], np.ndarray]:
    """Write all files of one asset, all or nothing: ``<stem>.<format>``, ``<stem>.png`` and engine extras.

    Args:
        mesh: the asset (LOD0) in the canonical frame, metres (see mesh.py).
        out_dir: created if missing.
        stem: file name without extension, also the GLB node/mesh name.
        formats: mesh formats to write, in order.
        pivot: where the exported origin sits (computed on ``mesh``, applied to every mesh).
        preview_size_px: also write a preview PNG of this size (preview.py); None = no preview.
        glb_material: give the GLB a white matte material (see ``_encode_glb_nodes``).
        profile: engine naming/layout/axes (pipeline/engines.py); LOD and collision
            meshes go into the GLB outputs only; OBJ/STL/PLY hold LOD0.
        lods: LOD1..n meshes (same frame as ``mesh``).
        collision: collision pieces (same frame as ``mesh``).
        asset_extras: JSON written into every GLB's ``asset.extras`` (provenance and licences).
        compression: how GLB files store geometry (``GlbCompression``; OBJ/STL/PLY are never compressed).
        extra_files: more files of the asset, ``(kind, file name, () → bytes)``, written
            with the others, all or nothing (the ``.vox`` exports, ``pipeline/vox_export.py``).

    Returns:
        (kind → final path, with kinds ``"glb"``, ``"obj"``, ``"stl"``, ``"ply"``,
        ``"preview"`` and ``"glb_LOD1"``-style kinds for extra GLB files; the (3,)
        pivot translation in metres that was applied, for the manifest).

    Raises:
        ExportError: the folder is not writable, or encoding/writing any file failed;
            in that case none of this call's files exist.
    """

    if not stem or Path(stem).name != stem or stem.startswith("."):
        raise ValueError(f"stem must be a plain, visible file name, got {stem!r}")
    out_dir = Path(out_dir)
    ensure_writable_dir(out_dir)
    moved, shift = apply_pivot(mesh, pivot)
    plan = layout(profile, stem, moved, [transformed(m, shift) for m in lods],
                  [transformed(m, shift) for m in collision])
    linear = other_format_transform(profile)
    other = transformed(moved, np.zeros(3), linear) if linear is not None else moved

    jobs: list[tuple[str, str, Callable[[], bytes]]] = []
    for fmt in (ExportFormat(f) for f in formats):
        if fmt == ExportFormat.GLB:
            jobs.append(("glb", f"{stem}.glb",
                         lambda nodes=plan.main_nodes: _encode_glb_nodes(nodes, glb_material, asset_extras,
                                                                         compression)))
            for file_stem, nodes in plan.extra_files:
                jobs.append((f"glb{file_stem[len(stem):]}", f"{file_stem}.glb",
                             lambda nodes=nodes: _encode_glb_nodes(nodes, glb_material, asset_extras, compression)))
        else:
            jobs.append((fmt.value, f"{stem}.{fmt.value}", lambda fmt=fmt: ENCODERS[fmt](other, stem)))
    if preview_size_px is not None:

        jobs.append(("preview", f"{stem}.png", lambda: preview_png(moved, preview_size_px)))
    jobs.extend(extra_files)
    written: dict[str, Path] = {}
    with AtomicWriter(out_dir) as writer:
        for kind, filename, encode in jobs:
            path = out_dir / filename
            try:
                data = encode()
            except DecollageError:
                raise
            except Exception as exc:  # a library failure while encoding: report it as ours
                raise ExportError(f"could not encode {path.suffix[1:].upper()}: {exc}", file=path,
                                  hint="this is likely a bug; please report it with the recipe") from exc
            writer.add(path, data)
            written[kind] = path
    return written, shift


def export_mesh(
    mesh: "trimesh.Trimesh",
    out_dir: Path,
    stem: str,
    formats: list[ExportFormat],
    pivot: Pivot = Pivot.BOTTOM_CENTER,
) -> dict[str, Path]:
    """Mesh files only (no preview): ``export_asset`` without the translation.

    Returns format value (e.g. ``"glb"``) → final path. The translation applied is
    ``pivot_translation(mesh.bounds, pivot)``.
    """
    written, _shift = export_asset(mesh, out_dir, stem, formats, pivot)
    return written

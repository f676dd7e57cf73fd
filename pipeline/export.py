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

import itertools
import os
import threading
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Callable

import numpy as np

from pipeline.errors import DecollageError, ExportError
from pipeline.recipe import ExportFormat, Pivot

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

_WRITABLE_HINT = "choose another output folder (--out) or fix its permissions"

# Unique temporary names within this process; pid separates processes.
_temp_counter = itertools.count()
_temp_lock = threading.Lock()


# --------------------------------------------------------------------------- atomic writing


class AtomicWriter:
    """Write several files so that either all of them appear, or none.

    Usage::

        with AtomicWriter(out_dir) as writer:
            writer.add(out_dir / "a.glb", glb_bytes)   # written to a temp file now
            writer.add(out_dir / "a.stl", stl_bytes)
        # leaving the block without an exception moves all of them into place;
        # an exception removes the temporaries and propagates
        # (an OSError is turned into ExportError).

    Files must live in ``out_dir`` so that ``os.replace`` is an atomic rename.
    """

    def __init__(self, out_dir: Path) -> None:
        self.out_dir = Path(out_dir)
        self._pending: list[tuple[Path, Path]] = []  # (temporary, final)

    def add(self, path: Path, data: bytes) -> None:
        """Write ``data`` to a temporary file that ``commit`` will move onto ``path``."""
        path = Path(path)
        if path.parent.resolve() != self.out_dir.resolve():
            raise ValueError(f"{path} is not directly inside {self.out_dir}")
        if any(final == path for _, final in self._pending):
            raise ValueError(f"{path} was added twice")
        with _temp_lock:
            serial = next(_temp_counter)
        temp = path.with_name(f".{path.name}.{os.getpid()}.{serial}.tmp")
        try:
            # O_EXCL: never write through someone else's file; 0o666 lets the
            # umask decide the final permissions, as for any normal file.
            fd = os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except OSError as exc:
            raise _os_error(exc, path) from None
        self._pending.append((temp, path))
        try:
            with os.fdopen(fd, "wb") as handle:
                handle.write(data)
                handle.flush()
                # Make the content durable before the rename can be.
                os.fsync(handle.fileno())
        except OSError as exc:
            raise _os_error(exc, path) from None

    def commit(self) -> list[Path]:
        """Move every temporary onto its final name; returns the final paths.

        Should a rename fail half-way (it practically cannot within one
        folder), the files already moved are removed too, so the asset is left
        with none of its new files rather than a mixture.
        """
        placed: list[Path] = []
        try:
            for temp, final in self._pending:
                os.replace(temp, final)
                placed.append(final)
        except OSError as exc:
            for final in placed:
                _remove_quietly(final)
            self.discard()
            raise _os_error(exc, final) from None
        done = [final for _, final in self._pending]
        self._pending = []
        return done

    def discard(self) -> None:
        """Remove all temporaries that were not moved into place."""
        for temp, _ in self._pending:
            _remove_quietly(temp)
        self._pending = []

    def __enter__(self) -> "AtomicWriter":
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()


def write_bytes_atomic(path: Path, data: bytes) -> None:
    """Write one file atomically (temporary file + rename). Raises ExportError."""
    path = Path(path)
    with AtomicWriter(path.parent) as writer:
        writer.add(path, data)


def ensure_writable_dir(path: Path) -> None:
    """Create ``path`` (and parents) if missing and check that files can be written in it.

    The check writes and deletes a real probe file, which also catches
    read-only mounts and ACLs that permission bits do not show.

    Raises:
        ExportError: the folder cannot be created or written.
    """
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise ExportError("output directory is not writable: a file with this name exists",
                          file=path, hint=_WRITABLE_HINT) from None
    except OSError as exc:
        raise ExportError(f"output directory is not writable: {exc.strerror or exc}",
                          file=path, hint=_WRITABLE_HINT) from None
    probe = path / f".decollage-probe.{os.getpid()}.{threading.get_ident()}"
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        try:
            os.write(fd, b"probe")
        finally:
            os.close(fd)
    except OSError as exc:
        raise ExportError(f"output directory is not writable: {exc.strerror or exc}",
                          file=path, hint=_WRITABLE_HINT) from None
    finally:
        _remove_quietly(probe)


def _os_error(exc: OSError, path: Path) -> ExportError:
    return ExportError(f"could not write: {exc.strerror or exc}", file=path,
                       hint="check free disk space and the folder's permissions")


def _remove_quietly(path: Path) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass
    except OSError:
        pass  # best effort: the caller is already reporting the real failure


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
    moved = mesh.copy()
    if np.any(shift != 0.0):
        moved.apply_translation(shift)
    return moved, shift


# --------------------------------------------------------------------------- encoders


def _encode_glb(mesh: "trimesh.Trimesh", stem: str) -> bytes:
    import trimesh

    named = mesh.copy()
    named.metadata = {}  # trimesh would copy metadata into the file as "extras"
    scene = trimesh.Scene()
    scene.add_geometry(named, geom_name=stem, node_name=stem)

    def finish_tree(tree: dict) -> None:
        tree["asset"]["generator"] = GENERATOR
        tree["materials"] = [{"name": stem, **_GLB_MATERIAL}]
        for gltf_mesh in tree.get("meshes", []):
            if not gltf_mesh.get("extras"):
                gltf_mesh.pop("extras", None)
            for primitive in gltf_mesh["primitives"]:
                primitive["material"] = 0

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


def export_mesh(
    mesh: "trimesh.Trimesh",
    out_dir: Path,
    stem: str,
    formats: list[ExportFormat],
    pivot: Pivot = Pivot.BOTTOM_CENTER,
) -> dict[str, Path]:
    """Write ``<out_dir>/<stem>.<format>`` for every format, all or nothing.

    Args:
        mesh: the asset in the canonical frame, metres (see mesh.py).
        out_dir: created if missing.
        stem: file name without extension, also the GLB node/mesh name.
        formats: formats to write, in order.
        pivot: where the exported origin sits; the translation applied is
            ``pivot_translation(mesh.bounds, pivot)`` (record it in the manifest).

    Returns:
        format value (e.g. ``"glb"``) → final path, in the order of ``formats``.

    Raises:
        ExportError: the folder is not writable, or encoding/writing any file failed;
            in that case none of this call's files exist.
    """
    if not stem or Path(stem).name != stem or stem.startswith("."):
        raise ValueError(f"stem must be a plain, visible file name, got {stem!r}")
    out_dir = Path(out_dir)
    ensure_writable_dir(out_dir)
    moved, _shift = apply_pivot(mesh, pivot)
    written: dict[str, Path] = {}
    with AtomicWriter(out_dir) as writer:
        for fmt in (ExportFormat(f) for f in formats):
            path = out_dir / f"{stem}.{fmt.value}"
            try:
                data = ENCODERS[fmt](moved, stem)
            except DecollageError:
                raise
            except Exception as exc:  # a library failure while encoding: report it as ours
                raise ExportError(f"could not encode {fmt.value.upper()}: {exc}", file=path,
                                  hint="this is likely a bug; please report it with the recipe") from exc
            writer.add(path, data)
            written[fmt.value] = path
    return written


def mesh_stats(mesh: "trimesh.Trimesh") -> dict:
    """Plain-JSON facts about a mesh for the manifest (lengths in metres)."""
    lo, hi = np.asarray(mesh.bounds, dtype=np.float64)
    return {
        "triangles": int(len(mesh.faces)),
        "vertices": int(len(mesh.vertices)),
        "bbox_min_m": [float(v) for v in lo],
        "bbox_max_m": [float(v) for v in hi],
        "watertight": bool(mesh.is_watertight),
    }

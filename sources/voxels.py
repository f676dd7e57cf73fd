"""The ``voxels`` source: a ready-made grid (.npy / .npz) → ``PartVoxels``, +Y up.

File layout (arrays indexed ``[x, y, z]`` in the file's own frame, whose up
axis is ``spec.up_axis``; one voxel is ``spec.voxel_size_m`` metres):

- ``.npy``: one 3-D array; nonzero = occupied. One part named ``voxels``.
- ``.npz``: ``occupancy`` (required, 3-D, nonzero = occupied); optional
  ``part`` (integer, same shape: 0-based part index of each occupied voxel)
  with optional ``part_names`` (1-D strings; default ``part_0``, ``part_1``...);
  optional ``style`` (integer, same shape) with optional ``style_names``
  (default ``style_0``...). Values in empty voxels are ignored. Other keys are
  ignored with a warning.

The grid is turned into the canonical frame by axis permutations and flips
derived from ``sources.frames.up_axis_rotation``, so a voxel lands exactly
where the same rotation takes its centre (input voxel (0, 0, 0)'s min corner
is the origin before rotation; the rotated grid starts at index 0 again).
Files are read with ``allow_pickle=False``, and only after their headers were
checked (``inspect_arrays``): the file must be a regular file within the voxels
size limit (``core/files.py``, ``InputKind.VOXELS``), and the arrays it holds,
once decompressed, at most that limit together (a small ``.npz`` cannot
unpack into gigabytes) in at most ``MAX_ARRAYS`` arrays. Every problem is a
``SourceError`` with ``field="path"``.
"""

from __future__ import annotations

import math
import zipfile
from pathlib import Path
from typing import BinaryIO

import numpy as np

from core.errors import SourceError
from core.files import InputKind, input_file, input_limit_bytes
from core.grid import EMPTY
from core.recipe import UpAxis, VoxelsSource
from sources.base import PartVoxels
from sources.frames import up_axis_rotation
from sources.mesh import sanitize_name, unique_name

#: File extensions this source reads.
SUPPORTED_FORMATS: tuple[str, ...] = ("npy", "npz")
_NPZ_KEYS = ("occupancy", "part", "part_names", "style", "style_names")
_MAX_LABELS = int(np.iinfo(np.int16).max)
#: Most arrays an .npz may hold.
MAX_ARRAYS: int = 16


def preflight(spec: VoxelsSource, base_dir: Path) -> None:
    """Checks before building: a regular file within the size limit whose array headers are sound (nothing loaded)."""
    headers = inspect_arrays(_resolve(spec.path, base_dir))
    if "occupancy" not in headers:
        raise SourceError(f"the .npz has no 'occupancy' array (found: {', '.join(sorted(headers)) or 'none'})",
                          field="path", hint="save the 3-D occupancy under the key 'occupancy'")
    shape = headers["occupancy"][0]
    if len(shape) != 3:
        raise SourceError(f"the occupancy must be 3-D (x, y, z), got {len(shape)}-D with shape {shape}",
                          field="path", hint="save a 3-D array indexed [x, y, z]")


def load(spec: VoxelsSource, base_dir: Path) -> PartVoxels:
    """Read ``spec.path`` (relative to ``base_dir``) into a ``PartVoxels`` in the canonical frame."""
    path = _resolve(spec.path, base_dir)
    warnings: list[str] = []
    arrays = _read(path)
    occupancy = _occupancy(arrays["occupancy"], "'occupancy'" if len(arrays) > 1 or path.suffix.lower() == ".npz"
                           else "the array")
    part, part_names = _labels(arrays, "part", occupancy, default_name="voxels" if "part" not in arrays else None)
    style = style_names = None
    if "style" in arrays or "style_names" in arrays:
        style, style_names = _labels(arrays, "style", occupancy, default_name=None)
    extra = sorted(set(arrays) - set(_NPZ_KEYS))
    if extra:
        warnings.append(f"ignored arrays in {path.name}: {', '.join(extra)} (known: {', '.join(_NPZ_KEYS)})")
    if not occupancy.any():
        raise SourceError("the voxel grid is empty (no nonzero voxel)", field="path",
                          hint="occupied voxels must be nonzero")
    return PartVoxels(
        part=rotate_grid(part, spec.up_axis),
        part_names=part_names,
        voxel_size_m=float(spec.voxel_size_m),
        style=None if style is None else rotate_grid(style, spec.up_axis),
        style_names=style_names or (),
        warnings=warnings,
        input_files=[path],
    )


def rotate_grid(grid: np.ndarray, up: UpAxis | str) -> np.ndarray:
    """(X, Y, Z) grid in the input frame → the same voxels in the canonical frame (+Y up).

    Uses the rotation of ``sources.frames.up_axis_rotation``: output axis ``a``
    is input axis ``b`` where ``R[a, b] = ±1``, reversed where it is -1.
    """
    rotation = up_axis_rotation(up)
    source_axis = [int(np.argmax(np.abs(row))) for row in rotation]
    out = np.transpose(grid, source_axis)
    flips = tuple(a for a in range(3) if rotation[a, source_axis[a]] < 0)
    if flips:
        out = np.flip(out, axis=flips)
    return np.ascontiguousarray(out)


# --------------------------------------------------------------------------- reading


def _resolve(relative: str, base_dir: Path) -> Path:
    path = input_file(relative, base_dir, field="path", noun="file", hint="name a .npy or .npz file",
                      kind=InputKind.VOXELS)
    if path.suffix.lower().lstrip(".") not in SUPPORTED_FORMATS:
        raise SourceError(f"unsupported voxel format {path.suffix or '(no extension)'!r}", field="path",
                          hint="supported: .npy (one occupancy array) or .npz (occupancy, part, style...)")
    return path


def inspect_arrays(path: Path) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """Name → (shape, dtype) of every array in the file, from the headers only; refuses what ``_read`` must not load.

    Refused: not an .npy/.npz file, an array of Python objects, more than ``MAX_ARRAYS``
    arrays, or arrays whose data together exceed the voxels size limit once decompressed.
    """
    is_npz = path.suffix.lower() == ".npz"
    limit = input_limit_bytes(InputKind.VOXELS)
    try:
        with open(path, "rb") as handle:
            magic = handle.read(6)
            handle.seek(0)
            # np.load would take anything else for a pickle and blame pickling; name the real problem.
            if magic == b"\x93NUMPY":
                headers = {"occupancy": _npy_header(handle, path, is_npz)}
            elif magic.startswith((b"PK\x03\x04", b"PK\x05\x06")):
                headers = _npz_headers(handle, path, limit)
            else:
                raise SourceError("cannot read voxels: " + ("the file is empty" if not magic else
                                  "not a NumPy .npy/.npz file"), field="path", hint=_format_hint(is_npz))
    except OSError as exc:
        raise SourceError(f"cannot read voxels: {exc.strerror or exc}", field="path") from None
    total = sum(math.prod(shape) * dtype.itemsize for shape, dtype in headers.values())
    if total > limit:
        raise SourceError(f"the arrays hold {total / (1 << 20):,.1f} MB once decompressed, more than the "
                          f"{limit / (1 << 20):.4g} MB limit for voxels files", field="path",
                          hint=f"use a smaller grid, or raise the limit with {InputKind.VOXELS.env_var}=<MB>")
    return headers


def _npy_header(handle: BinaryIO, path: Path, is_npz: bool) -> tuple[tuple[int, ...], np.dtype]:
    try:
        version = np.lib.format.read_magic(handle)
        reader = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = reader(handle)
    except (ValueError, EOFError, OSError, SyntaxError, TypeError) as exc:
        raise SourceError(f"cannot read voxels: a broken array header ({str(exc).splitlines()[0][:120]})",
                          field="path", hint=_format_hint(is_npz)) from None
    if dtype.hasobject:
        raise SourceError("cannot read voxels: it holds Python objects, which are not loaded for safety",
                          field="path", hint=_format_hint(is_npz))
    return tuple(int(n) for n in shape), dtype


def _npz_headers(handle: BinaryIO, path: Path, limit: int) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    try:
        with zipfile.ZipFile(handle) as archive:
            members = [info for info in archive.infolist() if not info.is_dir()]
            if len(members) > MAX_ARRAYS:
                raise SourceError(f"the .npz holds {len(members)} files, more than {MAX_ARRAYS}", field="path",
                                  hint="save only occupancy, part, part_names, style and style_names")
            unpacked = sum(info.file_size for info in members)
            if unpacked > limit:
                raise SourceError(f"the .npz unpacks to {unpacked / (1 << 20):,.1f} MB, more than the "
                                  f"{limit / (1 << 20):.4g} MB limit for voxels files", field="path",
                                  hint=f"use a smaller grid, or raise the limit with {InputKind.VOXELS.env_var}=<MB>")
            headers = {}
            for info in members:
                with archive.open(info) as member:
                    headers[info.filename.removesuffix(".npy")] = _npy_header(member, path, True)
            return headers
    except (zipfile.BadZipFile, EOFError, RuntimeError, NotImplementedError) as exc:
        raise SourceError(f"cannot read voxels: {type(exc).__name__}: {str(exc)[:160]}", field="path",
                          hint=_format_hint(True)) from None


def _read(path: Path) -> dict[str, np.ndarray]:
    """The file's arrays by name (an .npy becomes ``{"occupancy": array}``), after ``inspect_arrays``."""
    is_npz = path.suffix.lower() == ".npz"
    inspect_arrays(path)
    try:
        # np.load goes by the file's magic bytes, not its extension.
        loaded = np.load(path, allow_pickle=False)
        if isinstance(loaded, np.lib.npyio.NpzFile):
            with loaded:
                arrays = {key: loaded[key] for key in loaded.files}
            if "occupancy" not in arrays:
                raise SourceError(
                    f"the .npz has no 'occupancy' array (found: {', '.join(sorted(arrays)) or 'none'})",
                    field="path", hint="save the 3-D occupancy under the key 'occupancy'")
        elif isinstance(loaded, np.ndarray):
            arrays = {"occupancy": loaded}
        else:  # pragma: no cover - np.load returns one of the two
            raise SourceError("cannot read voxels: unknown content", field="path", hint=_format_hint(is_npz))
    except ValueError as exc:
        reason = ("it holds Python objects, which are not loaded for safety" if "allow_pickle" in str(exc)
                  else str(exc).splitlines()[0][:160])
        raise SourceError(f"cannot read voxels: {reason}", field="path",
                          hint=_format_hint(is_npz)) from None
    except (OSError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise SourceError(f"cannot read voxels: {type(exc).__name__}: {str(exc)[:160]}", field="path",
                          hint=_format_hint(is_npz)) from None
    return arrays


def _format_hint(is_npz: bool) -> str:
    return ("write it with numpy.savez(path, occupancy=..., part=..., part_names=...)" if is_npz
            else "write it with numpy.save(path, occupancy_array)")


def _occupancy(array: np.ndarray, what: str) -> np.ndarray:
    """(X, Y, Z) bool from a numeric/bool 3-D array."""
    if array.ndim != 3:
        raise SourceError(f"{what} must be 3-D (x, y, z), got {array.ndim}-D with shape {array.shape}",
                          field="path", hint="save a 3-D array indexed [x, y, z]")
    if not (np.issubdtype(array.dtype, np.number) or array.dtype == np.bool_):
        raise SourceError(f"{what} must be numbers or booleans, got dtype {array.dtype}", field="path",
                          hint="nonzero marks an occupied voxel")
    occupied = array != 0
    if np.issubdtype(array.dtype, np.floating):
        occupied &= ~np.isnan(array)
    return occupied


def _labels(arrays: dict, key: str, occupancy: np.ndarray,
            default_name: str | None) -> tuple[np.ndarray, tuple[str, ...]]:
    """(X, Y, Z) int16 label per voxel (-1 empty) and the names behind it, for ``part`` or ``style``."""
    names_key = f"{key}_names"
    if key not in arrays:
        if names_key in arrays:
            raise SourceError(f"'{names_key}' is given but '{key}' is not", field="path",
                              hint=f"add the '{key}' index array or drop '{names_key}'")
        # Only parts have a default (everything is one part).
        return np.where(occupancy, np.int16(0), np.int16(EMPTY)).astype(np.int16), (default_name or key,)
    labels = arrays[key]
    if labels.shape != occupancy.shape:
        raise SourceError(f"'{key}' has shape {labels.shape} but 'occupancy' has {occupancy.shape}",
                          field="path", hint=f"'{key}' must have the same shape as 'occupancy'")
    if not np.issubdtype(labels.dtype, np.integer):
        raise SourceError(f"'{key}' must be an integer array, got dtype {labels.dtype}", field="path",
                          hint=f"store 0-based {key} indices")
    used = labels[occupancy]
    names = _names(arrays, names_key, key, int(used.max()) + 1 if used.size else 1)
    if used.size and (used.min() < 0 or used.max() >= len(names)):
        bad = used[(used < 0) | (used >= len(names))][0]
        raise SourceError(f"'{key}' index {int(bad)} is out of range for {len(names)} {key} name(s) "
                          f"(occupied voxels need 0..{len(names) - 1})", field="path",
                          hint=f"fix the '{key}' array or list more '{names_key}'")
    out = np.full(occupancy.shape, EMPTY, dtype=np.int16)
    out[occupancy] = used.astype(np.int16)
    return out, names


def _names(arrays: dict, names_key: str, key: str, count: int) -> tuple[str, ...]:
    if names_key not in arrays:
        if count > _MAX_LABELS:
            raise SourceError(f"'{key}' uses more than {_MAX_LABELS} indices", field="path",
                              hint=f"use fewer {key}s")
        return tuple(f"{key}_{i}" for i in range(count))
    raw = arrays[names_key]
    if raw.ndim != 1 or raw.dtype.kind not in ("U", "S") or raw.size == 0:
        raise SourceError(f"'{names_key}' must be a non-empty 1-D array of strings, got {raw.dtype} {raw.shape}",
                          field="path", hint=f"e.g. numpy.array(['body', 'roof']) for '{names_key}'")
    if raw.size > _MAX_LABELS:
        raise SourceError(f"'{names_key}' lists more than {_MAX_LABELS} names", field="path")
    names: list[str] = []
    for value in raw.tolist():
        text = value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)
        names.append(unique_name(sanitize_name(text), names))
    return tuple(names)

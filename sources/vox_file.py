"""The MagicaVoxel ``.vox`` file format: read a scene, place its model instances, write models.

Role: the chunk codec only (no recipe, no part names). The ``vox`` source
(``sources/vox.py``) reads with it; the ``.vox`` export (``pipeline/vox_export.py``)
writes with it.

The format (ephtracy's published ``MagicaVoxel-file-format-vox.txt`` and its
scene-graph extension), little-endian throughout::

    "VOX " int32 version (150, or 200 from MagicaVoxel 0.99.7 on)
    chunk := id[4] int32 content_bytes int32 children_bytes content children
    MAIN { [PACK] (SIZE XYZI)* [RGBA] nTRN/nGRP/nSHP/LAYR/MATL/rOBJ/rCAM/NOTE/IMAP... }
    SIZE: int32 x, y, z (1..256 each; z is up)
    XYZI: int32 n, then n × (x, y, z, palette index) uint8; index 0 is never a voxel
    RGBA: 256 × (r, g, b, a); entry i is the colour of palette index i + 1
    nTRN: int32 node, DICT attrs (_name, _hidden), int32 child, int32 -1, int32 layer,
          int32 frames, frames × DICT (_r packed rotation, _t "x y z" translation)
    nGRP: int32 node, DICT, int32 n, n × int32 child
    nSHP: int32 node, DICT, int32 n, n × (int32 model, DICT)
    LAYR: int32 layer, DICT (_name, _hidden), int32 -1
    DICT := int32 n, n × (STRING key, STRING value); STRING := int32 bytes, bytes

Placement of a model instance (as MagicaVoxel and opengametools' ``ogt_vox``
do it): the transforms on the path from the root compose to ``(R, t)`` and
voxel ``v`` of a model of size ``s`` lands at ``floor(R · (v + ½ − ⌊s/2⌋)) + t``;
the rotation turns the model about its centre, rounded down to a voxel corner.

Every problem with the bytes raises ``SourceError`` (``field="path"``): chunk
sizes are checked against the file, sizes and coordinates against the format's
limits, and the scene graph against cycles and dangling ids.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

from core.errors import SourceError

#: The format's limit on a model's side (SIZE), in voxels.
MAX_SIDE = 256
#: Versions this reader knows (150: the classic format; 200: with the scene graph, MagicaVoxel 0.99.7+).
KNOWN_VERSIONS = (150, 200)
#: Version this writer writes.
WRITE_VERSION = 200
#: Largest merged scene, in voxel cells (a 1024 × 1024 × 256 box), so a stray translation cannot exhaust memory.
MAX_SCENE_CELLS = 1 << 28
#: Largest number of model instances, and of voxels placed in all (a scene graph sharing nodes can multiply them).
MAX_INSTANCES = 4096
MAX_PLACED_VOXELS = 1 << 25
_MAX_DEPTH = 64
_HINT = "save the file again from MagicaVoxel or Goxel (File > Export > .vox)"


def _bad(message: str, hint: str = _HINT) -> SourceError:
    return SourceError(f"not a readable .vox file: {message}", field="path", hint=hint)


@dataclass(frozen=True)
class VoxModel:
    """One model: ``size`` (3,) voxels and ``voxels`` (N, 4) uint8 rows (x, y, z, palette index 1..255)."""

    size: tuple[int, int, int]
    voxels: np.ndarray


@dataclass(frozen=True)
class VoxInstance:
    """One placement of a model in the scene.

    ``rotation``: (3, 3) int signed permutation; ``translation``: (3,) int voxels; both composed
    from the root. ``name``: the nearest ``_name`` on its path ("" if none).
    """

    model: int
    name: str
    rotation: np.ndarray
    translation: np.ndarray
    hidden: bool = False


@dataclass(frozen=True)
class VoxScene:
    """A read file. ``palette``: (256, 4) uint8 RGBA, row i = palette index i (row 0 unused), or None
    when the file has no RGBA chunk (editors then show their default palette).
    ``placed``: False when the file has no scene graph (each model then stands alone at the origin).
    ``notes``: what the reader skipped or simplified, for the manifest's warnings."""

    version: int
    models: tuple[VoxModel, ...]
    instances: tuple[VoxInstance, ...]
    palette: np.ndarray | None
    placed: bool
    notes: tuple[str, ...] = field(default=())


# --------------------------------------------------------------------------- reading


class _Reader:
    """Bounds-checked little-endian reads inside ``data[start:end]``."""

    def __init__(self, data: bytes, start: int, end: int, what: str) -> None:
        self.data, self.pos, self.end, self.what = data, start, end, what

    def take(self, n: int) -> bytes:
        if n < 0 or self.pos + n > self.end:
            raise _bad(f"{self.what} chunk is truncated")
        out = self.data[self.pos:self.pos + n]
        self.pos += n
        return out

    def int32(self) -> int:
        return struct.unpack("<i", self.take(4))[0]

    def string(self) -> str:
        return self.take(self.int32()).decode("utf-8", "replace")

    def dict(self) -> dict[str, str]:
        count = self.int32()
        if count < 0 or count * 8 > self.end - self.pos:
            raise _bad(f"{self.what} chunk has a bad dictionary size {count}")
        return {self.string(): self.string() for _ in range(count)}


def _chunks(data: bytes, start: int, end: int):
    """Yield (id, content_start, content_end) of the chunks laid one after the other in [start, end)."""
    pos = start
    while pos < end:
        if pos + 12 > end:
            raise _bad("a chunk header is truncated")
        cid, content, children = struct.unpack_from("<4sii", data, pos)
        if content < 0 or children < 0 or pos + 12 + content + children > end:
            raise _bad(f"chunk {cid!r} claims more bytes than the file has")
        yield cid, pos + 12, pos + 12 + content
        pos += 12 + content + children


def read_vox(data: bytes) -> VoxScene:
    """Parse a whole ``.vox`` file's bytes (see the module docstring). Raises SourceError."""
    if len(data) < 8 or data[:4] != b"VOX ":
        raise _bad("it does not start with 'VOX '" if data else "the file is empty")
    version = struct.unpack_from("<i", data, 4)[0]
    if version not in KNOWN_VERSIONS:
        raise _bad(f"unknown format version {version} (known: {', '.join(map(str, KNOWN_VERSIONS))})")
    if len(data) < 20 or data[8:12] != b"MAIN":
        raise _bad("no MAIN chunk")
    content, children = struct.unpack_from("<ii", data, 12)
    content_end = 20 + content
    children_end = content_end + children
    if content < 0 or children < 0 or children_end > len(data):
        raise _bad("the MAIN chunk claims more bytes than the file has")
    sizes: list[tuple[int, int, int]] = []
    models: list[VoxModel] = []
    palette = None
    nodes: dict[int, tuple] = {}
    layers_hidden: set[int] = set()
    notes: list[str] = []
    for cid, lo, hi in _chunks(data, content_end, children_end):
        r = _Reader(data, lo, hi, cid.decode("latin-1"))
        if cid == b"SIZE":
            size = (r.int32(), r.int32(), r.int32())
            if not all(1 <= n <= MAX_SIDE for n in size):
                raise _bad(f"model size {size} is outside 1..{MAX_SIDE} per axis")
            sizes.append(size)
        elif cid == b"XYZI":
            models.append(_read_xyzi(r, sizes, len(models), notes))
        elif cid == b"RGBA":
            rgba = np.frombuffer(r.take(1024), dtype=np.uint8).reshape(256, 4)
            palette = np.zeros((256, 4), dtype=np.uint8)
            palette[1:] = rgba[:255]
        elif cid in (b"nTRN", b"nGRP", b"nSHP"):
            node = r.int32()
            if node in nodes:
                raise _bad(f"scene node {node} is defined twice")
            nodes[node] = _read_node(cid, r, notes)
        elif cid == b"LAYR":
            layer, attrs = r.int32(), r.dict()
            if attrs.get("_hidden") == "1":
                layers_hidden.add(layer)
        # PACK, MATL, MATT, rOBJ, rCAM, NOTE, IMAP and newer chunks carry nothing this reader needs.
    if len(sizes) != len(models):
        raise _bad(f"{len(sizes)} SIZE chunks but {len(models)} XYZI chunks")
    if not models:
        raise _bad("the file has no model")
    if nodes:
        instances = _walk(nodes, models, layers_hidden)
    else:
        instances = [VoxInstance(i, "", np.eye(3, dtype=np.int64), np.zeros(3, np.int64)) for i in range(len(models))]
    return VoxScene(version, tuple(models), tuple(instances), palette, bool(nodes), tuple(dict.fromkeys(notes)))


def _read_xyzi(r: _Reader, sizes: list, index: int, notes: list[str]) -> VoxModel:
    if len(sizes) != index + 1:
        raise _bad(f"model {index}'s XYZI chunk is not preceded by its SIZE chunk")
    count = r.int32()
    if count < 0 or count * 4 > r.end - r.pos:
        raise _bad(f"model {index} claims {count} voxels, more than its chunk holds")
    voxels = np.frombuffer(r.take(4 * count), dtype=np.uint8).reshape(count, 4)
    size = sizes[index]
    outside = np.any(voxels[:, :3] >= np.asarray(size), axis=1)
    if outside.any():
        x, y, z, _ = voxels[outside][0]
        raise _bad(f"model {index} has a voxel at ({x}, {y}, {z}) outside its size {size}")
    if np.any(voxels[:, 3] == 0):
        notes.append(f"model {index}: {int((voxels[:, 3] == 0).sum())} voxels with palette index 0 (empty) ignored")
        voxels = voxels[voxels[:, 3] != 0]
    return VoxModel(size, np.ascontiguousarray(voxels))


def _read_node(cid: bytes, r: _Reader, notes: list[str]) -> tuple:
    """("T", attrs, child, layer, rotation, translation) | ("G", attrs, children) | ("S", attrs, model)."""
    attrs = r.dict()
    if cid == b"nTRN":
        child, _reserved, layer, frames = r.int32(), r.int32(), r.int32(), r.int32()
        if frames < 1:
            raise _bad("a transform node has no frame")
        frame = r.dict()
        if frames > 1:
            notes.append("animated transforms: only the first keyframe is read")
        return ("T", attrs, child, layer, _rotation(frame.get("_r")), _translation(frame.get("_t")))
    if cid == b"nGRP":
        count = r.int32()
        if count < 0 or count * 4 > r.end - r.pos:
            raise _bad(f"a group node claims {count} children")
        return ("G", attrs, [r.int32() for _ in range(count)])
    count = r.int32()
    if count < 1:
        raise _bad("a shape node has no model")
    model = r.int32()
    r.dict()
    if count > 1:
        notes.append("animated shapes: only the first keyframe's model is read")
    return ("S", attrs, model)


def _rotation(text: str | None) -> np.ndarray:
    """Packed ``_r`` byte → (3, 3) int: bits 0-1 / 2-3 the column of row 0 / row 1's entry, bits 4-6 the signs."""
    if text is None:
        return np.eye(3, dtype=np.int64)
    try:
        bits = int(text)
    except ValueError:
        raise _bad(f"rotation {text!r} is not a number") from None
    col0, col1 = bits & 3, (bits >> 2) & 3
    if col0 > 2 or col1 > 2 or col0 == col1 or not 0 <= bits < 128:
        raise _bad(f"rotation {bits} is not a valid packed rotation")
    cols = (col0, col1, 3 - col0 - col1)
    out = np.zeros((3, 3), dtype=np.int64)
    for row, col in enumerate(cols):
        out[row, col] = -1 if bits >> (4 + row) & 1 else 1
    return out


def _translation(text: str | None) -> np.ndarray:
    if text is None:
        return np.zeros(3, dtype=np.int64)
    parts = text.split()
    try:
        values = [int(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or any(abs(v) > 1 << 20 for v in values):
        raise _bad(f"translation {text!r} is not three integers")
    return np.asarray(values, dtype=np.int64)


def _walk(nodes: dict[int, tuple], models: list[VoxModel], layers_hidden: set[int]) -> list[VoxInstance]:
    """Instances in scene order, with transforms composed from the root (node 0)."""
    if 0 not in nodes or nodes[0][0] != "T":
        raise _bad("the scene graph has no root transform (node 0)")
    out: list[VoxInstance] = []
    visits = [0]

    def visit(node_id: int, rot: np.ndarray, trans: np.ndarray, name: str, hidden: bool, path: tuple) -> None:
        if node_id in path or len(path) > _MAX_DEPTH:
            raise _bad("the scene graph has a cycle or is too deep")
        visits[0] += 1
        if visits[0] > 16 * MAX_INSTANCES or len(out) > MAX_INSTANCES:
            raise _bad(f"the scene graph places more than {MAX_INSTANCES} models")
        if node_id not in nodes:
            raise _bad(f"the scene graph names node {node_id}, which the file does not define")
        node = nodes[node_id]
        path = (*path, node_id)
        if node[0] == "T":
            _, attrs, child, layer, r, t = node
            visit(child, rot @ r, rot @ t + trans, attrs.get("_name") or name,
                  hidden or attrs.get("_hidden") == "1" or layer in layers_hidden, path)
        elif node[0] == "G":
            for child in node[2]:
                visit(child, rot, trans, name, hidden, path)
        else:
            if not 0 <= node[2] < len(models):
                raise _bad(f"a shape node names model {node[2]}, but the file has {len(models)}")
            out.append(VoxInstance(node[2], name, rot, trans, hidden))

    visit(0, np.eye(3, dtype=np.int64), np.zeros(3, dtype=np.int64), "", False, ())
    return out


def model_grid(model: VoxModel) -> np.ndarray:
    """(X, Y, Z) uint8 palette indices of a model in its own frame and size (0 = empty), unplaced."""
    grid = np.zeros(model.size, dtype=np.uint8)
    grid[model.voxels[:, 0], model.voxels[:, 1], model.voxels[:, 2]] = model.voxels[:, 3]
    return grid


def place(model: VoxModel, instance: VoxInstance) -> np.ndarray:
    """(N, 4) int64 rows (x, y, z, palette index): the model's voxels where the instance puts them in the scene."""
    half = np.asarray(model.size, dtype=np.int64) // 2
    out = np.empty((len(model.voxels), 4), dtype=np.int64)
    for row in range(3):  # R is a signed permutation: one column per row (a matmul is far slower on ints)
        col = int(np.flatnonzero(instance.rotation[row])[0])
        doubled = 2 * (model.voxels[:, col].astype(np.int64) - half[col]) + 1  # 2 · (v + ½ − ⌊s/2⌋), odd
        out[:, row] = (int(instance.rotation[row, col]) * doubled + 2 * int(instance.translation[row]) - 1) // 2
    out[:, 3] = model.voxels[:, 3]
    return out


def dense(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4) placed rows → ((X, Y, Z) uint8 palette indices over their bounding box, (3,) min corner).

    Where rows overlap, the later one wins (MagicaVoxel draws later instances on top).
    """
    lo = rows[:, :3].min(axis=0)
    shape = rows[:, :3].max(axis=0) - lo + 1
    if int(np.prod(shape)) > MAX_SCENE_CELLS:
        raise SourceError(f"the placed models span {tuple(int(n) for n in shape)} voxels, too large to read",
                          field="model", hint="pick one model with model: <index or name>")
    grid = np.zeros(tuple(int(n) for n in shape), dtype=np.uint8)
    idx = rows[:, :3] - lo
    grid[idx[:, 0], idx[:, 1], idx[:, 2]] = rows[:, 3].astype(np.uint8)
    return grid, lo


# --------------------------------------------------------------------------- writing


def _chunk(cid: bytes, content: bytes, children: bytes = b"") -> bytes:
    return struct.pack("<4sii", cid, len(content), len(children)) + content + children


def _string(text: str) -> bytes:
    raw = text.encode("utf-8")
    return struct.pack("<i", len(raw)) + raw


def _dict(items: dict[str, str]) -> bytes:
    return struct.pack("<i", len(items)) + b"".join(_string(k) + _string(v) for k, v in items.items())


def pack_rotation(rotation: np.ndarray) -> int:
    """(3, 3) signed permutation → the packed ``_r`` byte (inverse of the reader's decoding)."""
    cols = [int(np.flatnonzero(row)[0]) for row in np.asarray(rotation)]
    signs = [int(np.asarray(rotation)[i, c] < 0) for i, c in enumerate(cols)]
    return cols[0] | cols[1] << 2 | signs[0] << 4 | signs[1] << 5 | signs[2] << 6


def write_vox(models: list[np.ndarray], palette: np.ndarray | None = None,
              positions: list[tuple[int, int, int]] | None = None, names: list[str] | None = None,
              rotations: list[np.ndarray] | None = None) -> bytes:
    """A ``.vox`` file (version 200) holding ``models``, each placed once in a flat scene.

    Args:
        models: (X, Y, Z) uint8 palette indices, 0 = empty, each side 1..256, z up.
        palette: (256, 4) uint8 RGBA, row i = palette index i (row 0 is not written); None: no RGBA chunk.
        positions: per model, the scene position of its voxel (0, 0, 0) when not rotated (default: origin).
        names: per model, the instance name (``_name``) shown in the editor's outliner.
        rotations: per model, a (3, 3) signed permutation applied about the model's centre (default: none).
    """
    body = b""
    for grid in models:
        if grid.ndim != 3 or grid.dtype != np.uint8 or not all(1 <= n <= MAX_SIDE for n in grid.shape):
            raise ValueError(f"a model must be a 3-D uint8 grid of 1..{MAX_SIDE} per side, got {grid.dtype} {grid.shape}")
        filled = grid > 0
        rows = np.empty((int(filled.sum()), 4), dtype=np.uint8)
        for axis, coords in enumerate(np.nonzero(filled)):
            rows[:, axis] = coords
        rows[:, 3] = grid[filled]
        body += _chunk(b"SIZE", struct.pack("<iii", *grid.shape))
        body += _chunk(b"XYZI", struct.pack("<i", len(rows)) + rows.tobytes())
    n = len(models)
    children = [2 + 2 * i for i in range(n)]
    body += _chunk(b"nTRN", struct.pack("<i", 0) + _dict({}) + struct.pack("<iiii", 1, -1, -1, 1) + _dict({}))
    body += _chunk(b"nGRP", struct.pack("<i", 1) + _dict({}) + struct.pack("<i", n)
                   + b"".join(struct.pack("<i", c) for c in children))
    for i, grid in enumerate(models):
        half = np.asarray(grid.shape) // 2
        frame = {"_t": " ".join(str(int(v)) for v in np.asarray((positions or [(0, 0, 0)] * n)[i]) + half)}
        if rotations is not None:
            frame = {"_r": str(pack_rotation(rotations[i])), **frame}
        attrs = {"_name": names[i]} if names and names[i] else {}
        body += _chunk(b"nTRN", struct.pack("<i", children[i]) + _dict(attrs)
                       + struct.pack("<iiii", children[i] + 1, -1, 0, 1) + _dict(frame))
        body += _chunk(b"nSHP", struct.pack("<i", children[i] + 1) + _dict({}) + struct.pack("<ii", 1, i) + _dict({}))
    body += _chunk(b"LAYR", struct.pack("<i", 0) + _dict({}) + struct.pack("<i", -1))
    if palette is not None:
        rgba = np.zeros((256, 4), dtype=np.uint8)
        rgba[:255] = np.asarray(palette, dtype=np.uint8)[1:256]
        body += _chunk(b"RGBA", rgba.tobytes())
    return b"VOX " + struct.pack("<i", WRITE_VERSION) + _chunk(b"MAIN", b"", body)

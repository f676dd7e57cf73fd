"""Read the project's GLBs back in tests, plain or meshopt-compressed (pipeline/glb_meshopt.py).

``read_glb(data)`` → (glTF JSON, {node name: (vertices (V, 3) metres float64, faces (F, 3), normals (V, 3),
colours (V, 4) uint8 or None)}). Node transforms (translation, scale: the dequantization) are applied.
"""

from __future__ import annotations

import json
import struct

import numpy as np

_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}


def chunks(data: bytes) -> tuple[dict, bytes]:
    magic, version, length = struct.unpack("<4sII", data[:12])
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_len, json_type = struct.unpack("<I4s", data[12:20])
    assert json_type == b"JSON"
    tree = json.loads(data[20:20 + json_len])
    rest = data[20 + json_len:]
    binary = b""
    if rest:
        bin_len, bin_type = struct.unpack("<I4s", rest[:8])
        assert bin_type == b"BIN\0"
        binary = rest[8:8 + bin_len]
    return tree, binary


def _view_bytes(tree: dict, binary: bytes, index: int) -> tuple[bytes, int | None]:
    """(uncompressed bytes of a buffer view, its byte stride)."""
    import meshoptimizer

    view = tree["bufferViews"][index]
    ext = view.get("extensions", {}).get("EXT_meshopt_compression")
    if ext is None:
        start = view.get("byteOffset", 0)
        return binary[start:start + view["byteLength"]], view.get("byteStride")
    assert ext["buffer"] == 0
    packed = binary[ext.get("byteOffset", 0):ext.get("byteOffset", 0) + ext["byteLength"]]
    count, stride = ext["count"], ext["byteStride"]
    if ext["mode"] == "ATTRIBUTES":
        out = meshoptimizer.decode_vertex_buffer(count, stride, packed)
    else:
        assert ext["mode"] == "TRIANGLES"
        out = meshoptimizer.decode_index_buffer(count, stride, packed)
    return np.asarray(out).tobytes(), stride


def _accessor(tree: dict, binary: bytes, index: int) -> np.ndarray:
    acc = tree["accessors"][index]
    raw, stride = _view_bytes(tree, binary, acc["bufferView"])
    dtype = np.dtype(_DTYPES[acc["componentType"]])
    width = _WIDTH[acc["type"]]
    item = dtype.itemsize * width
    stride = stride or item
    start = acc.get("byteOffset", 0)
    rows = np.frombuffer(raw, dtype=np.uint8)[start:start + stride * acc["count"]]
    rows = rows[: stride * acc["count"]].reshape(acc["count"], stride)[:, :item].copy()
    values = rows.view(dtype).reshape(acc["count"], width)
    if acc.get("normalized"):
        info = np.iinfo(dtype)
        values = np.maximum(values / info.max, -1.0)
    return values


def read_glb(data: bytes) -> tuple[dict, dict]:
    tree, binary = chunks(data)
    meshes = {}
    for node in tree["nodes"]:
        if "mesh" not in node:
            continue
        primitive = tree["meshes"][node["mesh"]]["primitives"][0]
        attrs = primitive["attributes"]
        verts = _accessor(tree, binary, attrs["POSITION"]).astype(np.float64)
        verts = verts * np.asarray(node.get("scale", [1, 1, 1])) + np.asarray(node.get("translation", [0, 0, 0]))
        faces = _accessor(tree, binary, primitive["indices"]).reshape(-1, 3).astype(np.int64)
        normals = _accessor(tree, binary, attrs["NORMAL"]).astype(np.float64)
        colours = None
        if "COLOR_0" in attrs:
            acc = tree["accessors"][attrs["COLOR_0"]]
            raw = _accessor(tree, binary, attrs["COLOR_0"])
            colours = np.rint(raw * 255).astype(np.uint8) if acc.get("normalized") else raw.astype(np.uint8)
        meshes[node["name"]] = (verts, faces, normals, colours)
    return tree, meshes


def decompress(data: bytes) -> bytes:
    """The same GLB with every meshopt-compressed buffer view decoded into a plain binary chunk.

    The Khronos validator checks the structure of EXT_meshopt_compression files but cannot decode them;
    validating this copy checks the decoded data too (index ranges, accessor bounds, normal lengths).
    """
    from pipeline.glb_meshopt import glb_container

    tree, binary = chunks(data)
    out = bytearray()
    for index, view in enumerate(tree["bufferViews"]):
        raw, stride = _view_bytes(tree, binary, index)
        view.pop("extensions", None)
        view.update({"buffer": 0, "byteOffset": len(out), "byteLength": len(raw)})
        out += raw + b"\0" * (-len(raw) % 4)
    tree["buffers"] = [{"byteLength": len(out)}]
    for key in ("extensionsUsed", "extensionsRequired"):
        tree[key] = [e for e in tree[key] if e != "EXT_meshopt_compression"]
    return glb_container(tree, bytes(out))

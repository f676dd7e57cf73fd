"""The hostile-input catalogue: odd and broken inputs of every kind give a clear exit 1 or 2, never more.

Every case is made here, in code, in its own folder (tiny files; "2 GB" files
are sparse), and run as the real CLI by ``tests/hostile_harness.py``: one
process imports the CLI once and forks a child per case under an address-space
limit, so the whole catalogue costs about one CLI start-up plus its cases.
Each case asserts:

- the exit code (2: nothing built; 1: the asset failed, the build went on;
  0 for the few controls that must keep working);
- one line naming the file and the field (or option, or YAML line), with the
  limit or the problem (``words``); no traceback, no "internal error";
- no partial files: a refused build leaves the output folder as it was (or
  absent), a failed asset leaves only the build-level files (``manifest.json``,
  ``NOTICE.txt``, ``build.json``, and the emptied lock in ``.decollage``);
- bounded time and memory: under the case's ``max_s`` (20 s; scripts, which
  start a CAD engine, 60-90 s) and ``MAX_RSS_MB`` (1 GB) peak RSS.

The cases listed in the issue this catalogue answers are marked ``# issue``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

pytestmark = pytest.mark.e2e

HARNESS = Path(__file__).with_name("hostile_harness.py")
MAX_RSS_MB = 1024.0
#: What a build whose assets all failed leaves: the build-level files only, and the output folder's
#: lock (pipeline/lock.py: left empty once the build is over).
BUILD_LEVEL_FILES = [".decollage/build.lock", "NOTICE.txt", "build.json", "manifest.json"]

TEXT = "{kind: text, text: A}"


def recipe(source: str = TEXT, *, asset: str = "", det: str = "upsample", style: str = "brick",
           top: str = "", name: str = "a") -> str:
    """A one-asset recipe; ``asset`` adds lines (4-space indented) to the asset, ``top`` to the top level."""
    return (f"version: 1\n{top}assets:\n  - name: {name}\n    source: {source}\n"
            f"    regions: [{{part: body, style: {style}}}]\n    detailize: {{detailizer: {det}}}\n{asset}")


def write(folder: Path, name: str, content: str | bytes) -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def sparse(folder: Path, name: str, size: int) -> Path:
    path = folder / name
    with open(path, "wb") as handle:
        handle.truncate(size)
    return path


def obj(vertices: list[tuple[float, float, float]], faces: list[tuple[int, int, int]]) -> str:
    return "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices) + "".join(
        f"f {a} {b} {c}\n" for a, b, c in faces)


def cube_obj(size: float = 1.0) -> str:
    s = size
    v = [(x * s, y * s, z * s) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    f = [(1, 3, 4), (1, 4, 2), (5, 6, 8), (5, 8, 7), (1, 2, 6), (1, 6, 5), (3, 7, 8), (3, 8, 4),
         (1, 5, 7), (1, 7, 3), (2, 4, 8), (2, 8, 6)]
    return obj(v, f)


def sphere_obj() -> str:
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    return obj([tuple(map(float, p)) for p in mesh.vertices], [tuple(int(i) + 1 for i in f) for f in mesh.faces])


def mesh_recipe(folder: Path, content: str, *, name: str = "m.obj", source_extra: str = "", asset: str = "") -> list:
    write(folder, name, content)
    write(folder, "r.yaml", recipe(f"{{kind: mesh, path: {name}{source_extra}}}", asset=asset))
    return ["build", "r.yaml", "-o", "out"]


def npy_header_only(shape: tuple[int, ...], descr: str = "|u1") -> bytes:
    """An .npy header that claims ``shape`` followed by 8 bytes of data (a file that lies about its size)."""
    import io

    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": descr, "fortran_order": False, "shape": shape})
    return buffer.getvalue() + bytes(8)


def npy_bytes(array: np.ndarray) -> bytes:
    import io

    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=True)
    return buffer.getvalue()


@dataclass
class Case:
    id: str
    make: Callable[[Path], list[str]]  # writes the case's files into its folder; returns the CLI arguments
    code: int
    field: str | None = None  # what the message must name: a field path, an option, or "line N"
    file: str | None = "r.yaml"  # the file the message must name (None: none, e.g. a CLI option)
    words: str = ""  # a phrase the message must contain (the limit, or the problem)
    env: dict = dataclass_field(default_factory=dict)
    max_s: float = 20.0  # the case must end within this (the harness stops it 15 s later)
    needs_root: bool = False


def _build(name: str = "r.yaml") -> list[str]:
    return ["build", name, "-o", "out"]


def _recipe_case(text: str) -> Callable[[Path], list[str]]:
    def make(folder: Path) -> list[str]:
        write(folder, "r.yaml", text)
        return _build()
    return make


def _deep(kind: str, depth: int) -> str:
    if kind == "list":
        return "version: 1\nassets: " + "[" * depth + "]" * depth + "\n"
    return "version: 1\nextra: " + "{a: " * depth + "1" + "}" * depth + "\n"


def _alias_bomb() -> str:
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    lines += [f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 10)]
    return "\n".join(lines) + "\n" + recipe()


def _variants(count_a: int, count_b: int, assets: int = 1) -> str:
    a = "[" + ",".join(f"w{i}" for i in range(count_a)) + "]"
    b = "[" + ",".join(str(i) for i in range(count_b)) + "]"
    body = "".join(f"  - name: v{k}\n    variants: {{word: {a}, seed: {b}}}\n"
                   f"    source: {{kind: text, text: '${{word}}'}}\n    regions: [{{part: body, style: brick}}]\n"
                   f"    detailize: {{detailizer: upsample, seed: '${{seed}}'}}\n" for k in range(assets))
    return "version: 1\nassets:\n" + body


def _cad_tree(depth: int) -> str:
    node = "{shape: box, size: [1, 1, 1]}"
    for _ in range(depth - 1):
        node = "{shape: union, children: [" + node + "]}"
    node = node.replace("{shape: ", "{name: tower, shape: ", 1)
    return recipe(f"{{kind: cad, parts: [{node}]}}")


def _many_shapes(count: int) -> str:
    children = ", ".join(f"{{shape: box, size: [1, 1, 1], at: [{i}, 0, 0]}}" for i in range(count))
    return recipe(f"{{kind: cad, parts: [{{name: row, shape: union, children: [{children}]}}]}}")


def _script(body: str, extra: str = "") -> Callable[[Path], list[str]]:
    def make(folder: Path) -> list[str]:
        write(folder, "tower.py", "import os, sys\n\n\ndef build():\n" +
              "".join(f"    {line}\n" for line in body.splitlines()))
        write(folder, "r.yaml", recipe(f"{{kind: cad, script: tower.py{extra}}}"))
        return _build()
    return make


def _script_batch(folder: Path) -> list[str]:
    """One recipe, one asset per way a script can fail without raising: each fails alone, the build says 1."""
    write(folder, "s.py", "\n".join([
        "import ctypes, os, sys",
        "from build123d import Box",
        "def ok(): return Box(1, 1, 1)",
        "def exits(): os._exit(0)",
        "def quits(): sys.exit(0)",
        "def loops():",
        "    while True: pass",
        "def eats():",
        "    keep = []",
        "    while True: keep.append(bytearray(32 << 20))",
        "def crashes(): ctypes.string_at(0)",
    ]) + "\n")
    assets = "".join(
        f"  - name: {fn}\n    source: {{kind: cad, script: s.py, script_function: {fn}, script_timeout_s: 3, "
        f"script_memory_mb: 256}}\n    regions: [{{part: body, style: brick}}]\n"
        f"    detailize: {{detailizer: upsample}}\n"
        for fn in ("exits", "quits", "loops", "eats", "crashes"))
    write(folder, "r.yaml", "version: 1\nassets:\n" + assets)
    return _build()


def _import_sparse_mesh(folder: Path) -> list[str]:
    (folder / "in").mkdir()
    sparse(folder / "in", "chair.stl", 2 << 30)
    return ["styles", "import", "in", "--name", "x", "--vocab", "things", "--out", "sets", "--no-sheet", "-q"]


def _link(folder: Path, name: str, target: str) -> Path:
    path = folder / name
    path.symlink_to(target)
    return path


def _fifo(folder: Path, name: str) -> Path:
    path = folder / name
    os.mkfifo(path)
    return path


def _voxels_case(make_file: Callable[[Path], None], extra: str = "") -> Callable[[Path], list[str]]:
    def make(folder: Path) -> list[str]:
        make_file(folder)
        write(folder, "r.yaml", recipe(f"{{kind: voxels, path: g.npz{extra}}}"))
        return _build()
    return make


def _npz(members: dict[str, bytes]) -> Callable[[Path], None]:
    def make(folder: Path) -> None:
        with zipfile.ZipFile(folder / "g.npz", "w", zipfile.ZIP_DEFLATED) as archive:
            for name, data in members.items():
                archive.writestr(name, data)
    return make


def _good_voxels(folder: Path) -> None:
    grid = np.zeros((6, 6, 6), dtype=np.uint8)
    grid[1:5, 0:5, 1:5] = 1
    np.savez(folder / "g.npz", occupancy=grid)


def _checkpoint_case(make_file: Callable[[Path], str]) -> Callable[[Path], list[str]]:
    def make(folder: Path) -> list[str]:
        name = make_file(folder)
        write(folder, "r.yaml", recipe(det=f"decollage, checkpoint: {name}", style="tower"))
        return _build()
    return make


def _style_set_case(make_file: Callable[[Path], str]) -> Callable[[Path], list[str]]:
    def make(folder: Path) -> list[str]:
        return ["styles", "show", make_file(folder), "--no-sheet"]
    return make


def _output_case(prepare: Callable[[Path], None]) -> Callable[[Path], list[str]]:
    def make(folder: Path) -> list[str]:
        _good_voxels(folder)
        write(folder, "r.yaml", recipe("{kind: voxels, path: g.npz}"))
        prepare(folder)
        return _build()
    return make


def _read_only_cache(folder: Path) -> None:
    cache = folder / "out" / ".decollage"
    cache.mkdir(parents=True)
    subprocess.run(["mount", "--bind", str(cache), str(cache)], check=True, capture_output=True)
    subprocess.run(["mount", "-o", "remount,ro,bind", str(cache)], check=True, capture_output=True)


def _validate_never_runs(folder: Path) -> list[str]:
    write(folder, "tower.py", "open(__file__ + '.ran', 'w').write('ran')\ndef build():\n    raise SystemExit\n")
    write(folder, "r.yaml", recipe("{kind: cad, script: tower.py}"))
    return ["validate", "r.yaml"]


def _list_never_runs(folder: Path) -> list[str]:
    _validate_never_runs(folder)
    return ["build", "r.yaml", "--list"]


CASES: list[Case] = [
    # ------------------------------------------------------------------ the recipe file
    Case("recipe_dev_zero", lambda d: ["build", "/dev/zero", "-o", "out"], 2, None, "/dev/zero",  # issue
         "character device"),
    Case("recipe_is_folder", lambda d: (d / "r.yaml").mkdir() or _build(), 2, None, "r.yaml", "folder"),
    Case("recipe_missing", lambda d: _build("nope.yaml"), 2, None, "nope.yaml", "not found"),
    Case("recipe_fifo", lambda d: _fifo(d, "r.yaml") and _build(), 2, None, "r.yaml", "named pipe"),
    Case("recipe_sparse_2gb", lambda d: sparse(d, "r.yaml", 2 << 30) and _build(), 2, None, "r.yaml",  # issue
         "1 MB limit"),
    Case("recipe_over_limit", lambda d: write(d, "r.yaml", recipe() + "#" * (1 << 20)) and _build(), 2, None,
         "r.yaml", "DECOLLAGE_MAX_RECIPE_MB"),
    Case("recipe_binary", lambda d: write(d, "r.yaml", bytes(range(256)) * 4) and _build(), 2, None, "r.yaml",
         "UTF-8"),
    Case("yaml_alias_bomb", _recipe_case(_alias_bomb()), 2, "line", "r.yaml", "250,000 values"),  # issue
    Case("yaml_recursive_alias", _recipe_case("a: &x [1, *x]\n" + recipe()), 2, "line 1", "r.yaml", "recursive"),
    Case("yaml_deep_lists", _recipe_case(_deep("list", 3000)), 2, "line 2", "r.yaml", "100 levels"),  # issue
    Case("yaml_deep_maps", _recipe_case(_deep("map", 3000)), 2, "line 2", "r.yaml", "100 levels"),  # issue
    Case("yaml_duplicate_key", _recipe_case(recipe().replace("version: 1\n", "version: 1\nversion: 1\n")), 2,
         "line 2", "r.yaml", "duplicate key"),
    Case("yaml_list_as_key", _recipe_case("{[1, 2]: 3}\n"), 2, "line 1", "r.yaml", "mapping key"),
    Case("yaml_python_tag", _recipe_case("version: !!python/object/apply:os.system ['echo hi']\n"), 2, "line 1",
         "r.yaml", "not valid YAML"),
    Case("yaml_two_documents", _recipe_case(recipe() + "---\n" + recipe()), 2, "line", "r.yaml",
         "but found another document"),
    Case("yaml_date_is_a_string", lambda d: write(d, "r.yaml", recipe("{kind: text, text: 2024-01-01}")) and
         ["validate", "r.yaml"], 0, None, None),
    Case("yaml12_exponent_number", lambda d: mesh_recipe(d, cube_obj(), source_extra=", scale: 1e-3") and  # issue
         ["validate", "r.yaml"], 0, None, None),
    Case("yaml12_no_is_a_string", lambda d: write(d, "r.yaml", recipe("{kind: text, text: NO}")) and
         ["validate", "r.yaml"], 0, None, None),
    Case("variants_500k", _recipe_case(_variants(100, 100, assets=50)), 2, "assets", "r.yaml",  # issue
         "500,000 assets"),
    Case("variants_one_asset_20k", _recipe_case(_variants(200, 100)), 2, "assets", "r.yaml", "--max-assets"),
    Case("variants_max_assets_flag", lambda d: write(d, "r.yaml", _variants(10, 3)) and
         ["validate", "r.yaml", "--max-assets", "20"], 2, "assets", "r.yaml", "cap of 20"),
    Case("variants_list_is_fast", lambda d: write(d, "r.yaml", _variants(50, 30)) and
         ["build", "r.yaml", "--list"], 0, None, None),
    Case("variants_unknown_key",
         _recipe_case(recipe("{kind: text, text: '${nope}'}", asset="    variants: {w: [a]}\n")), 2,
         "assets[0].source.text", "r.yaml", "not a variant key"),
    Case("cad_tree_40_deep", _recipe_case(_cad_tree(40)), 2, "assets[0].source", "r.yaml", "32 levels"),
    Case("cad_tree_450_deep", _recipe_case(_cad_tree(450)), 2, "line 4", "r.yaml", "100 levels"),  # issue
    Case("cad_1001_shapes", _recipe_case(_many_shapes(1001)), 2, "assets[0].source", "r.yaml", "1000"),
    Case("seed_2_64", _recipe_case(recipe(det="upsample, seed: 18446744073709551616")), 2,  # issue
         "assets[0].detailize.seed", "r.yaml", "4294967295"),
    Case("seed_negative", _recipe_case(recipe(det="upsample, seed: -1")), 2, "assets[0].detailize.seed"),
    Case("size_m_1e12", _recipe_case(recipe("{kind: text, text: A, size_m: 1e12}")), 2,  # issue
         "assets[0].source.size_m", "r.yaml", "1000"),
    Case("size_m_nan", _recipe_case(recipe("{kind: text, text: A, size_m: .nan}")), 2, "assets[0].source.size_m",
         "r.yaml", "finite"),
    Case("scale_inf", lambda d: mesh_recipe(d, cube_obj(), source_extra=", scale: .inf"), 2,  # issue
         "assets[0].source.scale", "r.yaml", "finite"),
    Case("scale_1e30", lambda d: mesh_recipe(d, cube_obj(), source_extra=", scale: 1.0e+30"), 2,  # issue
         "assets[0].source.scale", "r.yaml", "1000000"),
    Case("scale_1e-30", lambda d: mesh_recipe(d, cube_obj(), source_extra=", scale: 1.0e-30"), 2,  # issue
         "assets[0].source.scale", "r.yaml", "0.000001"),
    Case("rotate_1e9", _recipe_case(recipe("{kind: cad, parts: [{name: b, shape: box, size: [1, 1, 1], "
                                           "rotate_deg: [1e9, 0, 0]}]}")), 2, "assets[0].source.parts[0].rotate_deg"),
    Case("at_1e300", _recipe_case(recipe("{kind: cad, parts: [{name: b, shape: box, size: [1, 1, 1], "
                                         "at: [1e300, 0, 0]}]}")), 2, "assets[0].source.parts[0].at"),
    Case("huge_integer", _recipe_case(recipe(asset="    grid: {resolution: " + "9" * 400 + "}\n")), 2,
         "assets[0].grid.resolution"),
    Case("text_too_long", _recipe_case(recipe("{kind: text, text: '" + "A" * 3000 + "'}")), 2,
         "assets[0].source.text", "r.yaml", "2000"),
    Case("profile_too_long", _recipe_case(recipe("{kind: cad, parts: [{name: p, shape: extrude, height: 1, profile: ["
                                                 + ", ".join(f"[{i}, {i % 7}]" for i in range(10_001)) + "]}]}")),
         2, "assets[0].source.parts[0].profile"),
    # ------------------------------------------------------------------ fonts
    Case("font_missing", _recipe_case(recipe("{kind: text, text: A, font: nope.ttf}")), 2,
         "assets[0].source.font", "r.yaml", "not found"),
    Case("font_dev_zero", lambda d: _link(d, "z.ttf", "/dev/zero") and _recipe_case(
        recipe("{kind: text, text: A, font: z.ttf}"))(d), 2, "assets[0].source.font", "r.yaml", "character device"),
    Case("font_folder", lambda d: (d / "f.ttf").mkdir() or _recipe_case(
        recipe("{kind: text, text: A, font: f.ttf}"))(d), 2, "assets[0].source.font", "r.yaml", "not a font"),
    Case("font_garbage", lambda d: write(d, "f.ttf", os.urandom(3000)) and _recipe_case(
        recipe("{kind: text, text: A, font: f.ttf}"))(d), 2, "assets[0].source.font", "r.yaml", "not a readable"),
    Case("font_sparse_200mb", lambda d: sparse(d, "f.ttf", 200 << 20) and _recipe_case(
        recipe("{kind: text, text: A, font: f.ttf}"))(d), 2, "assets[0].source.font", "r.yaml", "128 MB limit"),
    Case("font_lacks_glyphs", lambda d: write(d, "r.yaml", recipe("{kind: text, text: '漢字'}")) and  # issue
         ["validate", "r.yaml"], 2, "assets[0].source.text", "r.yaml", "no glyph"),
    Case("text_mixed_directions", lambda d: write(d, "r.yaml", recipe("{kind: text, text: 'abc سلام'}")) and
         ["validate", "r.yaml"], 2, "assets[0].source.text", "r.yaml", "right-to-left"),
    # ------------------------------------------------------------------ meshes
    Case("mesh_dev_zero", lambda d: write(d, "r.yaml", recipe("{kind: mesh, path: /dev/zero}")) and _build(), 2,
         "assets[0].source.path", "r.yaml", "character device"),
    Case("mesh_sparse_2gb", lambda d: sparse(d, "m.stl", 2 << 30) and write(  # issue
        d, "r.yaml", recipe("{kind: mesh, path: m.stl}")) and _build(), 2, "assets[0].source.path", "r.yaml",
        "DECOLLAGE_MAX_MESH_MB"),
    Case("mesh_fifo", lambda d: _fifo(d, "m.obj") and write(d, "r.yaml", recipe("{kind: mesh, path: m.obj}"))
         and _build(), 2, "assets[0].source.path", "r.yaml", "named pipe"),
    Case("mesh_unknown_format", lambda d: mesh_recipe(d, cube_obj(), name="m.fbx"), 2, "assets[0].source.path",
         "r.yaml", "unsupported mesh format"),
    Case("mesh_over_limit_env", lambda d: mesh_recipe(d, cube_obj() + "#" * 200_000), 2, "assets[0].source.path",
         "r.yaml", "0.1 MB limit", env={"DECOLLAGE_MAX_MESH_MB": "0.1"}),
    Case("mesh_limit_env_unusable", lambda d: mesh_recipe(d, cube_obj()), 2, "DECOLLAGE_MAX_MESH_MB", None,
         "not a size", env={"DECOLLAGE_MAX_MESH_MB": "lots"}),
    Case("mesh_huge_coordinates", lambda d: mesh_recipe(d, cube_obj(1e30)), 1, "assets[0].source.path", "r.yaml",
         "too large"),
    Case("mesh_tiny_coordinates", lambda d: mesh_recipe(d, cube_obj(1e-7)), 1, "assets[0].source.path", "r.yaml",
         "collapses to a point"),
    Case("mesh_all_faces_collapsed", lambda d: mesh_recipe(
        d, obj([(0, 0, 0), (1, 1, 1), (2, 2, 2), (3, 3, 3)], [(1, 2, 3), (2, 3, 4), (1, 2, 4)])), 1,
        "assets[0].source.path", "r.yaml", "no faces"),
    Case("mesh_nan_vertex", lambda d: mesh_recipe(d, cube_obj().replace("v 0.0 0.0 0.0", "v nan 0 0")), 1,
         "assets[0].source.path", "r.yaml", "NaN"),
    Case("mesh_resolution_64", lambda d: mesh_recipe(d, sphere_obj(), asset="    grid: {resolution: 64}\n"), 1,  # issue
         "assets[0].grid", "r.yaml", "memory budget"),
    Case("mesh_budget_env_unusable", lambda d: mesh_recipe(d, cube_obj()), 2, "DECOLLAGE_MEMORY_BUDGET_GB", None,
         "not a size", env={"DECOLLAGE_MEMORY_BUDGET_GB": "-1"}),
    Case("mesh_gltf_not_json", lambda d: mesh_recipe(d, "not json {", name="m.gltf"), 1, "assets[0].source.path",
         "r.yaml", "glTF"),
    # ------------------------------------------------------------------ voxel grids
    Case("voxels_dev_zero", lambda d: _link(d, "g.npz", "/dev/zero") and write(
        d, "r.yaml", recipe("{kind: voxels, path: g.npz}")) and _build(), 2, "assets[0].source.path", "r.yaml",
        "character device"),
    Case("voxels_zip_bomb", _voxels_case(_npz({"occupancy.npy": npy_bytes(np.zeros((128, 128, 256), np.uint8))})),
         2, "assets[0].source.path", "r.yaml", "unpacks to 4.0 MB", env={"DECOLLAGE_MAX_VOXELS_MB": "1"}),
    Case("voxels_header_lies", _voxels_case(_npz({"occupancy.npy": npy_header_only((9999, 9999, 9999))})), 2,
         "assets[0].source.path", "r.yaml", "MB limit"),
    Case("voxels_pickled_objects", _voxels_case(_npz({"occupancy.npy": npy_bytes(np.array([{"a": 1}], object))})),
         2, "assets[0].source.path", "r.yaml", "Python objects"),
    Case("voxels_not_numpy", _voxels_case(lambda d: write(d, "g.npz", b"PK\x03\x04" + os.urandom(500)) and None), 2,
         "assets[0].source.path", "r.yaml", "cannot read voxels"),
    Case("voxels_too_many_arrays", _voxels_case(_npz({f"a{i}.npy": npy_bytes(np.zeros(1)) for i in range(40)})), 2,
         "assets[0].source.path", "r.yaml", "more than 16"),
    Case("voxels_not_3d", _voxels_case(_npz({"occupancy.npy": npy_bytes(np.ones((4, 4), np.uint8))})), 2,
         "assets[0].source.path", "r.yaml", "3-D"),
    Case("voxels_no_occupancy", _voxels_case(_npz({"part.npy": npy_bytes(np.ones((4, 4, 4), np.int16))})), 2,
         "assets[0].source.path", "r.yaml", "'occupancy'"),
    Case("vox_dev_zero", lambda d: _link(d, "m.vox", "/dev/zero") and write(
        d, "r.yaml", recipe("{kind: vox, path: m.vox}")) and _build(), 2, "assets[0].source.path", "r.yaml",
        "character device"),
    Case("vox_sparse_1gb", lambda d: sparse(d, "m.vox", 1 << 30) and write(
        d, "r.yaml", recipe("{kind: vox, path: m.vox}")) and _build(), 2, "assets[0].source.path", "r.yaml",
        "DECOLLAGE_MAX_VOX_MB"),
    Case("vox_garbage", lambda d: write(d, "m.vox", b"VOX " + os.urandom(300)) and write(
        d, "r.yaml", recipe("{kind: vox, path: m.vox}")) and _build(), 1, "assets[0].source.path", "r.yaml",
        "not a readable .vox file"),
    # ------------------------------------------------------------------ checkpoints
    Case("checkpoint_random_bytes", _checkpoint_case(lambda d: write(d, "c.pt", os.urandom(4096)) and "c.pt"),  # issue
         2, "assets[0].detailize.checkpoint", "r.yaml", "not a torch file"),
    Case("checkpoint_dev_zero", _checkpoint_case(lambda d: _link(d, "c.pt", "/dev/zero") and "c.pt"), 2,
         "assets[0].detailize.checkpoint", "r.yaml", "character device"),
    Case("checkpoint_sparse_1gb", _checkpoint_case(lambda d: sparse(d, "c.pt", 1 << 30) and "c.pt"), 2,
         "assets[0].detailize.checkpoint", "r.yaml", "DECOLLAGE_MAX_CHECKPOINT_MB"),
    Case("checkpoint_missing", _checkpoint_case(lambda d: "c.pt"), 2, "assets[0].detailize.checkpoint", "r.yaml",
         "not found"),
    # ------------------------------------------------------------------ style sets
    Case("style_set_dev_zero", _style_set_case(lambda d: _link(d, "s.npz", "/dev/zero").name), 2, None, "s.npz",
         "character device"),
    Case("style_set_garbage", _style_set_case(lambda d: write(d, "s.npz", os.urandom(2000)).name), 2, None, "s.npz",
         "truncated or corrupt"),
    Case("style_set_zip_bomb", _style_set_case(lambda d: _npz({"meta.npy": npy_bytes(np.zeros(3 << 20, np.uint8))})(d)
                                               or (d / "g.npz").rename(d / "s.npz").name), 2, None, "s.npz",
         "unpacks to", env={"DECOLLAGE_MAX_STYLE_SET_MB": "1"}),
    Case("style_set_sparse_2gb", _style_set_case(lambda d: sparse(d, "s.npz", 2 << 30).name), 2, None, "s.npz",
         "1024 MB limit"),
    Case("styles_import_sparse_mesh", _import_sparse_mesh, 2, None, "chair.stl", "256 MB limit"),
    # ------------------------------------------------------------------ output folders
    Case("out_is_a_file", _output_case(lambda d: write(d, "out", "x") and None), 2, None, "out", "is a file"),
    Case("out_under_a_file", lambda d: _output_case(lambda d: write(d, "blocker", "x") and None)(d)[:-1] +
         ["blocker/out"], 2, None, "blocker", "is a file"),
    Case("out_cache_is_a_file", _output_case(lambda d: write(d, "out/.decollage", "x") and None), 2, None,  # issue
         ".decollage", "must be a folder"),
    Case("out_manifest_is_a_folder", _output_case(lambda d: (d / "out" / "manifest.json").mkdir(parents=True)),  # issue
         2, None, "manifest.json", "must be a file"),
    Case("out_notice_is_a_folder", _output_case(lambda d: (d / "out" / "NOTICE.txt").mkdir(parents=True)), 2, None,
         "NOTICE.txt", "must be a file"),
    Case("out_cache_read_only", _output_case(_read_only_cache), 2, None, ".decollage", "not writable",  # issue
         needs_root=True),
    # ------------------------------------------------------------------ scripts
    Case("script_os_exit", _script("os._exit(0)"), 1, "assets[0].source.script", "r.yaml",  # issue
         "ended its own process", max_s=60),
    Case("script_failure_modes", _script_batch, 1, "assets[0].source.script", "r.yaml", "ended its own process",
         max_s=90),
    Case("script_not_python", lambda d: write(d, "t.txt", "x") and _recipe_case(
        recipe("{kind: cad, script: t.txt}"))(d), 2, "assets[0].source.script", "r.yaml", ".py"),
    Case("script_dev_zero", lambda d: _link(d, "t.py", "/dev/zero") and _recipe_case(
        recipe("{kind: cad, script: t.py}"))(d), 2, "assets[0].source.script", "r.yaml", "character device"),
    Case("validate_never_runs_scripts", _validate_never_runs, 0, None, None),
    Case("list_never_runs_scripts", _list_never_runs, 0, None, None),
    # ------------------------------------------------------------------ command-line flags
    Case("flag_jobs_zero", lambda d: _build() + ["--jobs", "0"] if write(d, "r.yaml", recipe()) else [], 2, "--jobs",
         None, "greater than or equal to 1"),
    Case("flag_unknown", lambda d: _build() + ["--frobnicate"] if write(d, "r.yaml", recipe()) else [], 2, None,
         None, "No such option"),
    Case("flag_max_assets_zero", lambda d: ["validate", "r.yaml", "--max-assets", "0"] if write(
        d, "r.yaml", recipe()) else [], 2, "--max-assets", None, "greater than or equal to 1"),
    Case("flag_gpus_without_cluster", lambda d: _build() + ["--gpus-per-task", "1"] if write(
        d, "r.yaml", recipe()) else [], 2, "--gpus-per-task", None, "--executor dask"),
    Case("flag_dask_without_address", lambda d: _build() + ["--executor", "dask"] if write(
        d, "r.yaml", recipe()) else [], 2, None, None, "--address"),
    Case("flag_only_unknown", lambda d: _build() + ["--only", "zz"] if write(d, "r.yaml", recipe()) else [], 2,
         None, None, "'zz'"),
    Case("flag_missing_recipe_argument", lambda d: ["build"], 2, "recipe", None, "Missing argument"),
]

CASE_IDS = [case.id for case in CASES]
_BY_ID = {case.id: case for case in CASES}


def _can_mount_read_only(folder: Path) -> bool:
    probe = folder / "mount-probe"
    probe.mkdir()
    try:
        if os.geteuid() != 0:
            return False
        ok = subprocess.run(["mount", "--bind", str(probe), str(probe)], capture_output=True).returncode == 0
        if ok:
            subprocess.run(["umount", str(probe)], capture_output=True)
        return ok
    except OSError:
        return False


def _snapshot(out: Path) -> dict[str, bytes] | None:
    if not out.exists() or not out.is_dir():
        return None if not out.exists() else {"": b"(a file)"}
    return {str(p.relative_to(out)): (p.read_bytes() if p.is_file() else b"(folder)")
            for p in sorted(out.rglob("*"))}


@pytest.fixture(scope="module")
def catalogue(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("hostile")
    can_mount = _can_mount_read_only(root)
    cases, before, mounts = [], {}, []
    for case in CASES:
        if case.needs_root and not can_mount:
            continue
        folder = root / case.id
        folder.mkdir()
        args = case.make(folder)
        if case.id == "out_cache_read_only":
            mounts.append(folder / "out" / ".decollage")
        before[case.id] = _snapshot(folder / "out")
        cases.append({"id": case.id, "args": [str(a) for a in args], "cwd": str(folder), "env": case.env,
                      "timeout_s": case.max_s + 15})
    (root / "cases.json").write_text(json.dumps(cases), encoding="utf-8")
    try:
        proc = subprocess.run([sys.executable, str(HARNESS), str(root / "cases.json"), str(root / "results.json")],
                              capture_output=True, text=True, timeout=900)
        assert proc.returncode == 0, proc.stderr[-3000:]
        results = json.loads((root / "results.json").read_text(encoding="utf-8"))
    finally:
        for mount in mounts:
            subprocess.run(["umount", str(mount)], capture_output=True)
    return {"root": root, "results": results, "before": before}


def _message_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith(("error:", "failed "))]


@pytest.mark.parametrize("case_id", CASE_IDS)
def test_hostile_case(catalogue, case_id):
    case = _BY_ID[case_id]
    if case_id not in catalogue["results"]:
        pytest.skip("needs root and a bind mount for a read-only folder")
    result = catalogue["results"][case_id]
    folder = catalogue["root"] / case_id
    stderr, stdout = result["stderr"], result["stdout"]
    shown = f"exit {result['exit']} signal {result['signal']} timed out {result['timed_out']}\n{stderr[-2000:]}"
    assert not result["timed_out"] and result["signal"] is None, shown
    assert result["exit"] == case.code, shown
    assert "Traceback" not in stderr + stdout and "internal error" not in stderr, shown
    assert result["wall_s"] < case.max_s, shown
    assert result["peak_rss_mb"] < MAX_RSS_MB, shown
    lines = _message_lines(stderr)
    if case.code == 0:
        assert lines == [], shown
        assert not any(folder.glob("*.ran")), "a script ran during validate or --list"
        return
    assert lines, shown
    message = lines[0]
    if case.code == 2:
        assert len([ln for ln in stderr.splitlines() if ln.strip()]) == 1, shown  # one line, nothing else
        assert _snapshot(folder / "out") == catalogue["before"][case_id], "the refused build wrote files"
    else:
        assert message.startswith("failed "), shown
        manifest = json.loads((folder / "out" / "manifest.json").read_text())
        assert manifest["summary"]["built"] == 0, manifest["summary"]
        assert all(a["status"] == "failed" and a["outputs"] == {} for a in manifest["assets"])
        files = sorted(str(p.relative_to(folder / "out")) for p in (folder / "out").rglob("*") if p.is_file())
        assert files == BUILD_LEVEL_FILES, files  # no asset file, no record of a failed asset
    if case.file:
        assert case.file in message, shown
    if case.field:
        assert case.field in message, shown
    assert case.words in message, shown


def test_script_failure_modes_each_say_what_happened(catalogue):
    """os._exit, sys.exit, an endless loop, a memory blow-up and a crash fail their own asset, each with its reason."""
    if "script_failure_modes" not in catalogue["results"]:
        pytest.skip("not run")
    manifest = json.loads((catalogue["root"] / "script_failure_modes" / "out" / "manifest.json").read_text())
    errors = {a["name"]: a["error"] for a in manifest["assets"]}
    expected = {"exits": "ended its own process", "quits": "script raised SystemExit",
                "loops": "did not finish within 3 s", "eats": "ran out of memory", "crashes": "SIGSEGV"}
    for name, words in expected.items():
        assert words in errors[name] and "r.yaml: assets[" in errors[name] and ".source.script" in errors[name], \
            errors[name]


def test_catalogue_is_large_enough():
    assert len(CASES) + 4 >= 60  # + the four extra failure modes of script_failure_modes
    assert len(set(CASE_IDS)) == len(CASE_IDS)

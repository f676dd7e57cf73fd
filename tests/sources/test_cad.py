"""The cad source: primitives, placement, booleans, frames, and users' scripts (build123d and cadquery)."""

from __future__ import annotations

import math
import os
import sys
import textwrap
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from core.errors import SourceError
from core.recipe import CadSource
from sources import cad, cad_script
from sources.frames import transform_points, up_axis_rotation


def spec(**fields) -> CadSource:
    return CadSource.model_validate({"kind": "cad", **fields})


def build(*parts: dict, **fields):
    return cad.load(spec(parts=list(parts), **fields), Path("."))


def script_file(folder: Path, text: str, name: str = "tower.py") -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return path


# --------------------------------------------------------------------------- frames


@pytest.mark.parametrize("up", ["x", "y", "z", "-x", "-y", "-z"])
def test_up_axis_rotation_is_proper_and_maps_up_to_plus_y(up):
    rot = up_axis_rotation(up)
    axis = np.zeros(3)
    axis["xyz".index(up[-1])] = -1.0 if up.startswith("-") else 1.0
    assert np.linalg.det(rot) == pytest.approx(1.0)
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(rot @ axis, [0, 1, 0], atol=1e-12)


def test_z_up_maps_cad_front_to_plus_z():
    # CAD: up +Z, front faces -Y.  Canonical: up +Y, front +Z.
    np.testing.assert_allclose(transform_points([[1, 2, 3]], "z", 1.0), [[1, 3, -2]])
    np.testing.assert_allclose(up_axis_rotation("z") @ [0, -1, 0], [0, 0, 1])


# --------------------------------------------------------------------------- primitives


def test_box_in_millimetres_becomes_metres_and_centred():
    pm = build({"name": "b", "shape": "box", "size": [100, 200, 300]}, units="mm")
    mesh = pm.parts["b"]
    # CAD (x, y, z) extents (0.1, 0.2, 0.3) m → canonical (x, z, -y): (0.1, 0.3, 0.2).
    np.testing.assert_allclose(mesh.bounds, [[-0.05, -0.15, -0.1], [0.05, 0.15, 0.1]], atol=1e-9)
    assert mesh.volume == pytest.approx(0.006, rel=1e-9)
    assert mesh.is_watertight and pm.warnings == [] and pm.input_files == []


def test_up_axis_z_makes_a_cad_tall_box_tall_along_y_and_y_up_keeps_it():
    tall = {"name": "t", "shape": "box", "size": [1, 1, 5], "at": [0, -3, 0]}
    z_up = build(tall).parts["t"]
    assert z_up.extents[1] == pytest.approx(5) and z_up.extents[0] == pytest.approx(1)
    assert z_up.centroid[2] == pytest.approx(3)  # placed toward CAD's front (-Y) → canonical front (+Z)
    y_up = build(tall, up_axis="y").parts["t"]
    np.testing.assert_allclose(y_up.extents, [1, 1, 5])
    np.testing.assert_allclose(y_up.centroid, [0, -3, 0], atol=1e-9)


def test_sphere_and_cone_are_watertight_and_close_to_analytic():
    pm = build(
        {"name": "ball", "shape": "sphere", "radius": 2},
        {"name": "spike", "shape": "cone", "radius_bottom": 1.5, "height": 3},
        {"name": "frustum", "shape": "cone", "radius_bottom": 0, "radius_top": 1, "height": 2},
        {"name": "ring", "shape": "torus", "major_radius": 3, "minor_radius": 0.5},
    )
    assert pm.warnings == []
    expected = {
        "ball": 4 / 3 * math.pi * 8,
        "spike": math.pi * 1.5**2 * 3 / 3,
        "frustum": math.pi * 1 * 2 / 3,
        "ring": 2 * math.pi**2 * 3 * 0.25,
    }
    for name, volume in expected.items():
        assert pm.parts[name].is_watertight, name
        assert pm.parts[name].volume == pytest.approx(volume, rel=0.02), name
    # The cone stands on CAD z = 0, which is canonical y = 0, and rises to its height.
    np.testing.assert_allclose(pm.parts["spike"].bounds[:, 1], [0, 3], atol=1e-9)
    np.testing.assert_allclose(pm.parts["ball"].bounds, [[-2, -2, -2], [2, 2, 2]], atol=0.01)


def test_cylinder_stands_on_z0_and_keeps_its_volume():
    mesh = build({"name": "c", "shape": "cylinder", "radius": 1, "height": 4}).parts["c"]
    np.testing.assert_allclose(mesh.bounds[:, 1], [0, 4], atol=1e-9)
    assert mesh.volume == pytest.approx(math.pi * 4, rel=0.02)


def test_extrude_l_profile_has_area_times_height_for_either_winding():
    ccw = [[0, 0], [2, 0], [2, 1], [1, 1], [1, 3], [0, 3]]
    pm = build({"name": "ccw", "shape": "extrude", "profile": ccw, "height": 2},
               {"name": "cw", "shape": "extrude", "profile": ccw[::-1], "height": 2})
    for name in ("ccw", "cw"):
        mesh = pm.parts[name]
        assert mesh.volume == pytest.approx(4 * 2, rel=1e-6)
        np.testing.assert_allclose(mesh.bounds[:, 1], [0, 2], atol=1e-9)  # z ∈ [0, height] → y


def test_self_crossing_profile_is_refused():
    with pytest.raises(SourceError) as info:
        build({"name": "x", "shape": "extrude", "profile": [[0, 0], [1, 1], [1, 0], [0, 1]], "height": 1})
    assert info.value.field == "parts[0].profile"


# --------------------------------------------------------------------------- placement and booleans


def test_rotation_order_is_x_then_y_then_z_before_translation():
    rod = {"shape": "cylinder", "radius": 0.1, "height": 2}
    pm = build(
        {"name": "along_x", **rod, "rotate_deg": [0, 90, 0]},             # +Z axis → +X
        {"name": "along_y", **rod, "rotate_deg": [0, 90, 90]},            # then 90° about Z: +X → +Y
        {"name": "moved", **rod, "rotate_deg": [0, 90, 0], "at": [0, 0, 5]},
    )
    along_x, along_y, moved = (pm.parts[n].bounds for n in ("along_x", "along_y", "moved"))
    np.testing.assert_allclose(along_x[:, 0], [0, 2], atol=1e-6)
    # CAD +Y is canonical -Z. (Z-then-Y order would have given +X again.)
    np.testing.assert_allclose(along_y[:, 2], [-2, 0], atol=1e-6)
    assert along_y[1, 0] == pytest.approx(0.1, abs=1e-3)
    # The translation is not rotated: CAD z = 5 is canonical y = 5.
    assert moved.mean(axis=0)[1] == pytest.approx(5, abs=1e-3)  # ±radius, up to chord error
    np.testing.assert_allclose(moved[:, 0], [0, 2], atol=1e-6)


def test_difference_box_minus_cylinder_matches_analytic_volume():
    pm = build({
        "name": "plate", "shape": "difference", "children": [
            {"shape": "box", "size": [40, 40, 20]},
            {"shape": "cylinder", "radius": 8, "height": 30, "at": [0, 0, -15]},
        ]}, units="mm")
    expected_m3 = (40 * 40 * 20 - math.pi * 8**2 * 20) * 1e-9
    assert pm.parts["plate"].volume == pytest.approx(expected_m3, rel=0.02)
    assert pm.parts["plate"].is_watertight and pm.warnings == []


def test_boolean_placement_moves_the_combined_result():
    pm = build({
        "name": "pair", "shape": "union", "at": [10, 0, 0], "rotate_deg": [0, 0, 90], "children": [
            {"shape": "box", "size": [2, 2, 2]},
            {"shape": "box", "size": [2, 2, 2], "at": [4, 0, 0]},
        ]})
    # Union spans CAD x ∈ [-1, 5]; rotated 90° about Z it spans y ∈ [-1, 5]; then x += 10.
    # Canonical (x, z, -y): x ∈ [9, 11], z ∈ [-5, 1].
    np.testing.assert_allclose(pm.parts["pair"].bounds[:, [0, 2]], [[9, -5], [11, 1]], atol=1e-6)
    assert pm.parts["pair"].volume == pytest.approx(16, rel=1e-6)


def test_disjoint_intersection_is_an_error_at_its_node():
    far = {"shape": "box", "size": [1, 1, 1], "at": [5, 0, 0]}
    with pytest.raises(SourceError) as info:
        build({"name": "gone", "shape": "intersection", "children": [{"shape": "sphere", "radius": 1}, far]})
    assert info.value.field == "parts[0]"
    assert "empty" in info.value.message
    nested = {"name": "n", "shape": "union", "children": [
        {"shape": "box", "size": [1, 1, 1]},
        {"shape": "intersection", "children": [{"shape": "sphere", "radius": 1}, far]},
    ]}
    with pytest.raises(SourceError) as info:
        build({"name": "ok", "shape": "box", "size": [1, 1, 1]}, nested)
    assert info.value.field == "parts[1].children[1]"


def test_parts_keep_their_names_and_recipe_order():
    pm = build({"name": "zeta", "shape": "box", "size": [1, 1, 1]},
               {"name": "alpha", "shape": "sphere", "radius": 1, "at": [0, 0, 3]})
    assert list(pm.parts) == ["zeta", "alpha"]
    assert pm.parts["alpha"].centroid[1] == pytest.approx(3, abs=1e-3)


def test_explicit_tolerance_changes_the_tessellation():
    ball = {"name": "s", "shape": "sphere", "radius": 1}
    coarse = build(ball, tolerance=0.05).parts["s"]
    fine = build(ball).parts["s"]
    assert len(coarse.faces) < len(fine.faces)


# --------------------------------------------------------------------------- build123d scripts


def load_script(path: Path, **fields):
    return cad.load(spec(script=path.name, **fields), path.parent)


def test_script_returning_a_shape_is_one_part_named_after_the_file(tmp_path):
    path = script_file(tmp_path, """
        from build123d import Box
        def build():
            return Box(10, 20, 30)
        if __name__ == "__main__":
            raise SystemExit("must not run as __main__")
        """)
    pm = load_script(path, units="mm")
    assert list(pm.parts) == ["tower"]
    np.testing.assert_allclose(pm.parts["tower"].extents, [0.01, 0.03, 0.02])
    assert pm.input_files == [path.resolve()]
    assert str(tmp_path) not in sys.path


def test_script_returning_a_dict_or_pairs_keeps_names_and_order(tmp_path):
    path = script_file(tmp_path, """
        from build123d import Box, Sphere, Pos, BuildPart
        def build():
            return {"top": Pos(0, 0, 5) * Sphere(1), "base": Box(2, 2, 2)}
        def pairs():
            with BuildPart() as handle:
                Box(1, 1, 1)
            return [("b-1", Box(1, 1, 1)), ("a.2", handle)]
        """)
    pm = load_script(path)
    assert list(pm.parts) == ["top", "base"]
    assert pm.parts["top"].centroid[1] == pytest.approx(5, abs=1e-3)
    assert pm.warnings == []
    assert list(load_script(path, script_function="pairs").parts) == ["b-1", "a.2"]


def test_script_exception_is_a_one_line_source_error(tmp_path):
    path = script_file(tmp_path, """
        from build123d import Box

        def build():
            size = 3
            raise ValueError(f"bad size {size}")
        """)
    with pytest.raises(SourceError) as info:
        load_script(path)
    err = info.value
    assert err.field == "script"
    assert err.message == "script raised ValueError: bad size 3 (line 6 of tower.py)"
    assert "Traceback" not in err.one_line() and err.__cause__ is None


def test_script_errors_while_loading_are_reported_with_their_line(tmp_path):
    broken = script_file(tmp_path, "x = 1\ndef build(:\n    pass\n", name="broken.py")
    with pytest.raises(SourceError, match=r"script raised SyntaxError: .* \(line 2 of broken.py\)"):
        load_script(broken)
    dividing = script_file(tmp_path, "a = 1\nb = a / 0\n", name="dividing.py")
    with pytest.raises(SourceError, match=r"ZeroDivisionError: division by zero \(line 2 of dividing.py\)"):
        load_script(dividing)


def test_missing_function_lists_the_functions_found(tmp_path):
    path = script_file(tmp_path, """
        from build123d import *
        def make():
            return Box(1, 1, 1)
        def helper():
            pass
        """)
    with pytest.raises(SourceError) as info:
        load_script(path)
    assert info.value.field == "script_function"
    assert "'build'" in info.value.message and "helper, make" in info.value.message
    assert "Box" not in info.value.message  # imported names are not the script's functions


def test_missing_script_file(tmp_path):
    with pytest.raises(SourceError) as info:
        cad.load(spec(script="nowhere.py"), tmp_path)
    assert info.value.field == "script" and "not found" in info.value.message


@pytest.mark.parametrize("returned, expected", [
    ("42", "returned a int"),
    ("{'bad name': Box(1, 1, 1)}", "invalid part name 'bad name'"),
    ("{'a': 'text'}", "part 'a' that is a str"),
    ("{}", "returned no parts"),
    ("[('a', Box(1, 1, 1)), ('a', Box(1, 1, 1))]", "duplicate part names"),
    ("Box(1, 1, 1).faces()[0]", "has no solid"),
])
def test_wrong_return_values_are_explained(tmp_path, returned, expected):
    path = script_file(tmp_path, f"from build123d import Box\ndef build():\n    return {returned}\n")
    with pytest.raises(SourceError, match=expected) as info:
        load_script(path)
    assert info.value.field == "script"


# --------------------------------------------------------------------------- cadquery scripts


def test_missing_cadquery_runtime_says_how_to_install(tmp_path, monkeypatch):
    path = script_file(tmp_path, "def build():\n    pass\n")
    monkeypatch.setenv(cad_script.CADQUERY_PYTHON_ENV, str(tmp_path / "no-python"))
    with pytest.raises(SourceError) as info:
        load_script(path, script_engine="cadquery")
    assert info.value.field == "script_engine"
    assert "bash scripts/install.sh cadquery" in info.value.hint


def _cadquery_runtime() -> Path:
    try:
        return cad_script.find_cadquery_python()
    except SourceError:
        pytest.skip("the optional cadquery runtime is not installed (bash scripts/install.sh cadquery)")


@pytest.mark.cadquery
def test_cadquery_script_with_two_named_parts(tmp_path):
    _cadquery_runtime()
    path = script_file(tmp_path, """
        import cadquery as cq
        def build():
            base = cq.Workplane("XY").box(40, 40, 10).faces(">Z").workplane().hole(10)
            top = cq.Workplane("XY").sphere(5).translate((0, 0, 20))
            return {"base": base, "top": top}
        """)
    pm = load_script(path, units="mm", script_engine="cadquery")
    assert list(pm.parts) == ["base", "top"] and pm.warnings == []
    assert pm.parts["base"].volume == pytest.approx((40 * 40 * 10 - math.pi * 25 * 10) * 1e-9, rel=0.02)
    assert pm.parts["top"].volume == pytest.approx(4 / 3 * math.pi * 125e-9, rel=0.02)
    assert pm.parts["top"].centroid[1] == pytest.approx(0.02, abs=1e-4)  # CAD z = 20 mm → +Y
    assert pm.input_files == [path.resolve()]


@pytest.mark.cadquery
def test_cadquery_script_error_has_the_same_wording(tmp_path):
    _cadquery_runtime()
    path = script_file(tmp_path, "import cadquery as cq\n\ndef build():\n    raise RuntimeError('no lid')\n")
    with pytest.raises(SourceError) as info:
        load_script(path, script_engine="cadquery")
    assert info.value.field == "script"
    assert info.value.message == "script raised RuntimeError: no lid (line 4 of tower.py)"


# --------------------------------------------------------------------------- isolation of scripts


def test_scripts_never_run_in_the_build_process(tmp_path):
    path = script_file(tmp_path, """
        import os, pathlib
        from build123d import Box
        def build():
            pathlib.Path(__file__).with_name("pid.txt").write_text(str(os.getpid()))
            return Box(1, 1, 1)
        """)
    load_script(path)
    assert int((tmp_path / "pid.txt").read_text()) != os.getpid()  # another process ran it
    assert "decollage_script" not in sys.modules


@pytest.mark.parametrize("body, fields, words", [
    ("os._exit(0)", {}, "ended its own process (os._exit(0) or similar) before build() returned"),
    ("os._exit(3)", {}, "exited with status 3 before build() returned"),
    ("sys.exit(0)", {}, "script raised SystemExit: 0 (line 6 of tower.py)"),
    ("while True:\n        pass", {"script_timeout_s": 1}, "did not finish within 1 s (script_timeout_s)"),
    ("keep = [bytearray(32 << 20) for _ in range(100)]", {"script_memory_mb": 64},
     "ran out of memory (script_memory_mb = 64 MiB"),
    ("import ctypes; ctypes.string_at(0)", {}, "crashed before build() returned (SIGSEGV"),
])
def test_a_script_that_ends_crashes_loops_or_eats_memory_fails_its_asset(tmp_path, body, fields, words):
    path = script_file(tmp_path, "import os, sys\nfrom build123d import Box\n\n\ndef build():\n    " + body + "\n")
    with pytest.raises(SourceError) as info:
        load_script(path, **fields)
    assert info.value.field == "script" and words in info.value.message, info.value.message
    # the warm runner survives any of these: the next script runs as usual
    ok = script_file(tmp_path, "from build123d import Box\ndef build():\n    return Box(1, 2, 3)\n", name="ok.py")
    assert list(load_script(ok).parts) == ["ok"]


def test_local_modules_and_data_files_a_script_reads_join_its_input_files(tmp_path):
    """Recorded in the runner's child (sources/script_reads.py): modules in import order, then data files
    (one of them absent)."""
    (tmp_path / "helpers").mkdir()
    (tmp_path / "helpers" / "__init__.py").write_text("")
    (tmp_path / "helpers" / "sizes.py").write_text("WIDTH = 3\n")
    (tmp_path / "shapes.py").write_text("from build123d import Box\ndef box(w, d):\n    return Box(w, d, 1)\n")
    (tmp_path / "depth.txt").write_text("2")
    path = script_file(tmp_path, """
        import json  # the standard library is not a local module
        import pathlib
        import shapes
        from helpers.sizes import WIDTH
        def build():
            depth = float(pathlib.Path(__file__).with_name("depth.txt").read_text())
            pathlib.Path(__file__).with_name("scratch.txt").write_text("written by the script: not an input")
            try:
                depth += float(pathlib.Path(__file__).with_name("extra.txt").read_text())
            except FileNotFoundError:
                pass
            return shapes.box(WIDTH, depth)
        """)
    pm = load_script(path)
    assert pm.input_files == [path.resolve(), *(p.resolve() for p in (
        tmp_path / "shapes.py", tmp_path / "helpers" / "__init__.py", tmp_path / "helpers" / "sizes.py",
        tmp_path / "depth.txt", tmp_path / "extra.txt"))]  # extra.txt: looked for in vain, recorded as absent
    np.testing.assert_allclose(pm.parts["tower"].extents, [3, 1, 2])


@pytest.mark.cadquery
def test_a_cadquery_scripts_local_modules_and_data_files_join_its_input_files(tmp_path):
    _cadquery_runtime()
    (tmp_path / "sizes.py").write_text("WIDTH = 30\n")
    (tmp_path / "height.txt").write_text("20")
    path = script_file(tmp_path, """
        import pathlib
        import cadquery as cq
        import sizes
        def build():
            height = float(pathlib.Path(__file__).with_name("height.txt").read_text())
            return cq.Workplane("XY").box(sizes.WIDTH, 10, height)
        """)
    pm = load_script(path, units="mm", script_engine="cadquery")
    assert pm.input_files == [path.resolve(), (tmp_path / "sizes.py").resolve(), (tmp_path / "height.txt").resolve()]
    np.testing.assert_allclose(sorted(pm.parts["tower"].extents), [0.01, 0.02, 0.03], atol=1e-6)


def test_threads_sharing_the_warm_runner_take_turns(tmp_path):
    """One answer line per request line: two threads of one process must not read each other's answers."""
    paths = [script_file(tmp_path, f"from build123d import Box\ndef build():\n    return Box({i + 1}, 1, 1)\n",
                         name=f"s{i}.py") for i in range(4)]
    with ThreadPoolExecutor(max_workers=4) as pool:
        results = list(pool.map(load_script, paths))
    for i, (path, pm) in enumerate(zip(paths, results)):
        assert list(pm.parts) == [f"s{i}"] and pm.input_files == [path.resolve()]
        assert max(pm.parts[f"s{i}"].extents) == pytest.approx(i + 1)


def test_what_a_script_starts_is_stopped_and_what_it_prints_stays_out(tmp_path, capfd):
    marker = tmp_path / "alive"
    path = script_file(tmp_path, f"""
        import subprocess, sys
        from build123d import Box
        def build():
            print("noise from the script")
            subprocess.Popen([sys.executable, "-c", "import time, pathlib; time.sleep(2); "
                              "pathlib.Path({str(marker)!r}).write_text('x')"])
            return Box(1, 1, 1)
        """)
    load_script(path)
    import time

    time.sleep(3)
    assert not marker.exists()  # the script's child was killed with its process group
    assert "noise from the script" not in capfd.readouterr().out


def test_validate_and_list_never_run_a_script(tmp_path):
    path = script_file(tmp_path, "open(__file__ + '.ran', 'w').close()\ndef build():\n    pass\n")
    cad.preflight(spec(script=path.name), tmp_path)
    assert not (tmp_path / "tower.py.ran").exists()
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(SourceError, match=".py file"):
        cad.preflight(spec(script="notes.txt"), tmp_path)


def test_a_deep_boolean_tree_is_built_without_recursion():
    from core.recipe import BooleanShape, BoxShape

    node = BoxShape(shape="box", size=(1, 2, 3))
    for _ in range(3000):  # far deeper than the schema allows (MAX_CAD_DEPTH), to prove the walk is iterative
        node = BooleanShape.model_construct(shape="union", children=[node], name=None, at=(0, 0, 0),
                                            rotate_deg=(0, 0, 0))
    shape = cad.build_node(node, "parts[0]")
    assert shape.bounding_box().size.Z == pytest.approx(3)


@pytest.mark.parametrize("python, words", [
    (sys.executable, "cannot import cadquery"),  # a Python without cadquery: the runner says so and stops
    ("/bin/false", "failed: no output"),  # not a Python at all: it ends at once
])
def test_a_runtime_that_cannot_run_scripts_is_a_clear_error(tmp_path, monkeypatch, python, words):
    path = script_file(tmp_path, "def build():\n    pass\n")
    monkeypatch.setenv(cad_script.CADQUERY_PYTHON_ENV, python)
    with pytest.raises(SourceError) as info:
        load_script(path, script_engine="cadquery")
    assert info.value.field == "script_engine" and words in info.value.message, info.value.message

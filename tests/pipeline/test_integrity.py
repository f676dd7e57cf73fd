"""Build integrity: the cache sees every input file, outputs do not depend on --jobs, and a stopped build
leaves a folder its manifest describes (pipeline/cache.py, batch.py, executors.py, workers.py, lock.py)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

from cli.app import app
from core.processes import process_alive
from pipeline.lock import BuildLock, lock_path

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.e2e  # whole builds, subprocess CLI runs

SCRIPT = """
import build123d as bd
import helper

def build():
    return {"block": bd.Box(helper.SIZE, 1.0, 1.0)}
"""

OBJ = """mtllib crate.mtl
o crate
usemtl wood
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
"""

#: Every source kind: text (the bundled font), cad primitives, a build123d script with a helper module,
#: a GLB, a glTF with external buffers, an OBJ with a material library, a voxel grid.
BATCH = """
version: 1
defaults:
  grid: {{resolution: 8}}
  detailize: {{detailizer: {detailizer}}}
  export: {{max_triangles: 3000, preview_size_px: 64}}
assets:
  - name: word
    source: {{kind: text, text: Ab, size_m: 0.3}}
    regions: [{{parts: ["*"], part: bottom, style: tower}}, {{band: {{from: 0.6}}, part: top, style: druse}}]
  - name: tower
    source:
      kind: cad
      parts:
        - {{name: shaft, shape: cylinder, radius: 0.5, height: 1.6, at: [0, 0, 0]}}
        - {{name: roof, shape: cone, radius_bottom: 0.75, height: 0.9, at: [0, 0, 1.6]}}
    regions: [{{parts: [shaft], part: body, style: temple}}, {{parts: [roof], part: roof, style: pagoda}}]
  - name: scripted
    source: {{kind: cad, script: block.py}}
    regions: [{{part: bottom, style: townhouse}}]
  - name: cottage
    source: {{kind: mesh, path: cottage.glb}}
    regions: [{{parts: [walls, chimney], part: body, style: barn}}, {{parts: [roof], part: roof, style: cottage}}]
  - name: box
    source: {{kind: mesh, path: box.gltf}}
    regions: [{{part: bottom, style: tower}}]
  - name: crate
    source: {{kind: mesh, path: crate.obj}}
    regions: [{{part: bottom, style: barn}}]
  - name: mushroom
    source: {{kind: voxels, path: mushroom.npz, voxel_size_m: 0.05}}
    regions: [{{parts: [stem], part: bottom, style: cactus}}, {{parts: [cap], part: top, style: bush}}]
"""


def _write_gltf_box(folder: Path, size_m: float, json_too: bool = True) -> None:
    """``box.gltf`` whose geometry lives in external ``.bin`` buffers (only the buffers when ``json_too`` is False)."""
    files = trimesh.creation.box(extents=(size_m, size_m, size_m)).export(file_type="gltf")
    for name, data in files.items():
        if name.endswith(".bin") or json_too:
            (folder / ("box.gltf" if name == "model.gltf" else name)).write_bytes(data)


@pytest.fixture
def recipe_dir(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    shutil.copy(REPO / "recipes" / "inputs" / "cottage.glb", folder)
    shutil.copy(REPO / "recipes" / "inputs" / "mushroom.npz", folder)
    (folder / "block.py").write_text(SCRIPT)
    (folder / "helper.py").write_text("SIZE = 1.0\n")
    (folder / "crate.obj").write_text(OBJ)
    (folder / "crate.mtl").write_text("newmtl wood\nKd 0.6 0.4 0.2\n")
    _write_gltf_box(folder, 1.0)
    return folder


def _recipe(folder: Path, detailizer: str = "upsample") -> Path:
    path = folder / "batch.yaml"
    path.write_text(BATCH.format(detailizer=detailizer))
    return path


def _cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def _build(*args) -> dict:
    result = _cli("build", *args, "--json", "--quiet")
    assert result.exit_code == 0, result.stderr
    return json.loads(result.stdout)


def _check(recipe: Path, out: Path) -> dict:
    result = _cli("build", recipe, "-o", out, "--check", "--json")
    assert result.exit_code in (0, 1), result.stderr
    return json.loads(result.stdout)


def _manifest_entry(out: Path, name: str) -> dict:
    return next(a for a in json.loads((out / "manifest.json").read_text())["assets"] if a["name"] == name)


def _size_m(out: Path, name: str) -> list[float]:
    mesh = _manifest_entry(out, name)["mesh"]
    return [round(b - a, 2) for a, b in zip(mesh["bbox_min_m"], mesh["bbox_max_m"])]


# --------------------------------------------------------------------------- the input closure


def test_manifest_lists_every_file_each_source_read(recipe_dir, tmp_path):
    out = tmp_path / "out"
    _build(_recipe(recipe_dir), "-o", out)
    files = {a["name"]: [f["path"] for f in a["inputs"]["files"]]
             for a in json.loads((out / "manifest.json").read_text())["assets"]}
    buffers = sorted(p.name for p in recipe_dir.glob("*.bin"))
    assert files["box"][0] == "box.gltf" and sorted(files["box"][1:]) == buffers and buffers
    assert files["crate"] == ["crate.obj", "crate.mtl"]
    assert files["scripted"] == ["block.py", "helper.py"]
    assert files["word"] == ["<decollage>/sources/fonts/DejaVuSans-Bold.ttf"]
    assert files["cottage"] == ["cottage.glb"] and files["mushroom"] == ["mushroom.npz"]
    assert files["tower"] == []  # primitives read nothing; the upsample baseline loads no weights
    entry = _manifest_entry(out, "box")["inputs"]["files"][1]
    assert entry["read_by"] == "source" and len(entry["sha256"]) == 64


def test_editing_a_gltf_buffer_makes_the_asset_stale_and_rebuilds_it(recipe_dir, tmp_path):
    """The reproducer: only the .bin changes (a 1 m box becomes 3 m); the .gltf JSON stays as it was."""
    recipe, out = _recipe(recipe_dir), tmp_path / "out"
    _build(recipe, "-o", out, "--only", "box")
    assert _size_m(out, "box") == pytest.approx([1.0, 1.0, 1.0], abs=0.05)
    gltf = (recipe_dir / "box.gltf").read_bytes()
    _write_gltf_box(recipe_dir, 3.0, json_too=False)
    assert (recipe_dir / "box.gltf").read_bytes() == gltf
    check = _check(recipe, out)
    assert "box" in check["stale"] and check["reasons"]["box"].startswith("input changed: gltf_buffer_")
    assert "cottage" in check["stale"]  # never built here; the point is "box" above
    summary = _build(recipe, "-o", out, "--only", "box")
    assert summary["summary"]["built"] == 1 and _size_m(out, "box") == pytest.approx([3.0, 3.0, 3.0], abs=0.05)
    clean = tmp_path / "clean"
    _build(recipe, "-o", clean, "--only", "box")
    assert (out / "box.glb").read_bytes() == (clean / "box.glb").read_bytes()


def test_editing_a_script_helper_makes_the_asset_stale_and_rebuilds_it(recipe_dir, tmp_path):
    recipe, out = _recipe(recipe_dir), tmp_path / "out"
    _build(recipe, "-o", out, "--only", "scripted")
    assert _size_m(out, "scripted")[0] == pytest.approx(1.0, abs=0.05)
    assert _check(recipe, out)["reasons"].get("scripted") is None  # up to date
    (recipe_dir / "helper.py").write_text("SIZE = 3.0\n")
    check = _check(recipe, out)
    assert check["reasons"]["scripted"] == "input changed: helper.py"
    _build(recipe, "-o", out, "--only", "scripted")
    assert _size_m(out, "scripted")[0] == pytest.approx(3.0, abs=0.05)
    assert _check(recipe, out)["reasons"].get("scripted") is None


OPTIONAL_SCRIPT = """
import pathlib
import build123d as bd
import helper

def build():
    try:
        depth = float(pathlib.Path(__file__).with_name("extra.txt").read_text())
    except FileNotFoundError:
        depth = 1.0
    return {"block": bd.Box(helper.SIZE, 1.0, depth)}
"""


def test_a_file_a_script_looked_for_in_vain_is_recorded_absent_and_creating_it_makes_the_asset_stale(
        recipe_dir, tmp_path):
    """The script runs in the runner's forked child; what it read (and missed) comes back into the closure."""
    (recipe_dir / "optional.py").write_text(OPTIONAL_SCRIPT)
    recipe = recipe_dir / "optional.yaml"
    recipe.write_text("""
version: 1
assets:
  - name: optional
    source: {kind: cad, script: optional.py}
    grid: {resolution: 8}
    regions: [{part: bottom, style: townhouse}]
    detailize: {detailizer: upsample}
    export: {max_triangles: 2000, preview: false}
""")
    out = tmp_path / "out"
    _build(recipe, "-o", out)
    files = _manifest_entry(out, "optional")["inputs"]["files"]
    assert [f["path"] for f in files] == ["optional.py", "helper.py", "extra.txt"]
    assert files[2] == {"path": "extra.txt", "sha256": None, "read_by": "source"}
    assert _check(recipe, out)["reasons"].get("optional") is None
    (recipe_dir / "extra.txt").write_text("2.5")
    assert _check(recipe, out)["reasons"]["optional"] == "input changed: extra.txt"
    _build(recipe, "-o", out)
    assert max(_size_m(out, "optional")) == pytest.approx(2.5, abs=0.05)  # the block is 2.5 m deep now


def test_editing_a_material_library_or_adding_a_missing_one_makes_the_asset_stale(recipe_dir, tmp_path):
    recipe, out = _recipe(recipe_dir), tmp_path / "out"
    _build(recipe, "-o", out, "--only", "crate")
    (recipe_dir / "crate.mtl").write_text("newmtl wood\nKd 0.1 0.1 0.1\n")
    assert _check(recipe, out)["reasons"]["crate"] == "input changed: crate.mtl"
    # a material library the OBJ names but that is missing is recorded as absent; creating it is a change
    (recipe_dir / "crate.obj").write_text(OBJ.replace("crate.mtl", "other.mtl"))
    _build(recipe, "-o", out, "--only", "crate")
    assert _manifest_entry(out, "crate")["inputs"]["files"][1] == {"path": "other.mtl", "sha256": None,
                                                                     "read_by": "source"}
    assert _check(recipe, out)["reasons"].get("crate") is None
    (recipe_dir / "other.mtl").write_text("newmtl wood\n")
    assert _check(recipe, out)["reasons"]["crate"] == "input changed: other.mtl"


def test_the_checkpoint_a_detailizer_loads_is_in_the_closure(recipe_dir, tmp_path):
    checkpoint = tmp_path / "mine.pt"
    shutil.copy(REPO / "model" / "weights" / "things.pt", checkpoint)
    recipe = recipe_dir / "one.yaml"
    recipe.write_text(f"""
version: 1
assets:
  - name: tower
    source: {{kind: cad, parts: [{{name: a, shape: box, size: [1, 1, 1]}}]}}
    grid: {{resolution: 8}}
    regions: [{{part: bottom, style: tower}}]
    detailize: {{detailizer: decollage, checkpoint: {checkpoint}}}
    export: {{max_triangles: 2000, preview: false}}
""")
    out = tmp_path / "out"
    _build(recipe, "-o", out)
    entry = _manifest_entry(out, "tower")
    files = entry["inputs"]["files"]
    assert files == [{"path": "../mine.pt", "sha256": files[0]["sha256"], "read_by": "detailizer"}]
    assert entry["detailizer"]["checkpoint"] == "../mine.pt"


def _absolute_strings(value, roots: tuple[str, ...]) -> list[str]:
    """Every string inside a JSON value that names a place under one of ``roots``."""
    if isinstance(value, dict):
        return [s for v in value.values() for s in _absolute_strings(v, roots)]
    if isinstance(value, list):
        return [s for v in value for s in _absolute_strings(v, roots)]
    return [value] if isinstance(value, str) and any(r in value for r in roots) else []


def test_the_manifest_names_no_path_of_this_machine(recipe_dir, tmp_path):
    """The shipped weights, the quilt's style set file and the recipe are written portably (issue 16)."""
    recipe = recipe_dir / "portable.yaml"
    recipe.write_text("""
version: 1
assets:
  - name: learned
    source: {kind: cad, parts: [{name: a, shape: box, size: [1, 1, 1]}]}
    grid: {resolution: 6}
    regions: [{part: bottom, style: tower}]
    detailize: {detailizer: decollage}
    export: {max_triangles: 2000, preview: false}
  - name: copied
    source: {kind: cad, parts: [{name: a, shape: box, size: [1, 1, 1]}]}
    grid: {resolution: 6}
    regions: [{part: body, style: cottage}]
    detailize: {detailizer: quilt}
    export: {max_triangles: 2000, preview: false}
""")
    out = tmp_path / "out"
    manifest = _build(str(recipe.resolve()), "-o", out)  # an absolute recipe path on the command line
    assert manifest["summary"]["built"] == 2
    learned = _manifest_entry(out, "learned")
    assert learned["detailizer"]["checkpoint"] == "<decollage>/model/weights/things.pt"
    assert _manifest_entry(out, "copied")["detailizer"]["style_set_path"] == "<styles>/things.npz"
    text = (out / "manifest.json").read_text()
    assert json.loads(text)["recipe"]["path"] == "../in/portable.yaml"
    roots = (str(REPO), str(tmp_path), str(Path.home()))
    assert _absolute_strings(json.loads(text), roots) == []


# --------------------------------------------------------------------------- --jobs gives the same bytes


def _all_bytes(out: Path) -> dict[str, bytes]:
    """Every output file's bytes; the manifest without its timings (the only values allowed to differ).

    ``build.json`` is left out: it is the rebuild signal, a counter and a time by design.
    """
    files = {p.name: p.read_bytes() for p in sorted(out.iterdir())
             if p.is_file() and p.name not in ("manifest.json", "build.json")}
    manifest = json.loads((out / "manifest.json").read_text())
    for entry in manifest["assets"]:
        entry.pop("timings_s")
    files["manifest.json"] = json.dumps(manifest, sort_keys=True).encode()
    return files


def test_jobs_1_and_2_and_a_cluster_give_byte_identical_outputs_with_the_learned_model(recipe_dir, tmp_path):
    """Every source kind through the shipped model (its convolutions round by thread count: ASSET_THREADS)."""
    distributed = pytest.importorskip("distributed")
    recipe = _recipe(recipe_dir, "decollage")
    one, two, dask = tmp_path / "j1", tmp_path / "j2", tmp_path / "dask"
    assert _build(recipe, "-o", one, "--jobs", "1")["summary"]["built"] == 7
    assert _build(recipe, "-o", two, "--jobs", "2")["summary"]["built"] == 7
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:  # workers with torch's default threads
        assert _build(recipe, "-o", dask, "--executor", "dask", "--address",
                      cluster.scheduler_address)["summary"]["built"] == 7
    a = _all_bytes(one)
    assert len(a) == 16  # 7 GLBs, 7 PNGs, NOTICE.txt, the manifest
    for other in (two, dask):
        b = _all_bytes(other)
        assert sorted(b) == sorted(a) and [name for name in a if a[name] != b[name]] == [], other.name
    print(f"\ncompared {len(a)} files ({sum(map(len, a.values()))} bytes) of -j 1 with -j 2 and a cluster: identical")


# --------------------------------------------------------------------------- stopping


def _start(recipe: Path, out: Path, *args: str) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "cli.app", "build", str(recipe), "-o", str(out), *args]
    return subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _workers(pid: int) -> list[int]:
    """The worker processes of build ``pid`` (its spawned children, not multiprocessing's resource tracker)."""
    found = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        for child in (task / "children").read_text().split():
            cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
            if b"spawn_main" in cmdline and b"resource_tracker" not in cmdline:
                found.append(int(child))
    return found


def _wait_for_first_record(proc: subprocess.Popen, out: Path, timeout_s: float = 180) -> None:
    records = out / ".decollage"
    deadline = time.time() + timeout_s
    while time.time() < deadline and not any(p.suffix == ".json" for p in records.glob("*")):
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    assert any(records.glob("*.json")), "no asset was built in time"


def _slow_batch(recipe_dir: Path) -> Path:
    """Twelve learned-model assets: enough work that a stop always lands mid-build."""
    recipe = recipe_dir / "slow.yaml"
    recipe.write_text("""
version: 1
defaults:
  grid: {resolution: 8}
  export: {max_triangles: 3000, preview_size_px: 64}
assets:
  - name: t
    variants: {h: [1.0, 1.2, 1.4, 1.6, 1.8, 2.0], roof: [pagoda, cottage]}
    source:
      kind: cad
      parts:
        - {name: shaft, shape: cylinder, radius: 0.5, height: "${h}", at: [0, 0, 0]}
        - {name: roof, shape: cone, radius_bottom: 0.75, height: 0.9, at: [0, 0, "${h}"]}
    regions: [{parts: [shaft], part: body, style: temple}, {parts: [roof], part: roof, style: "${roof}"}]
""")
    return recipe


def _assert_manifest_matches_folder(out: Path) -> set[str]:
    listed = {a["name"] for a in json.loads((out / "manifest.json").read_text())["assets"]}
    on_disk = {p.stem for p in out.glob("*.glb")}
    recorded = {p.stem for p in (out / ".decollage").glob("*.json")}
    assert listed == on_disk == recorded, (listed, on_disk, recorded)
    assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")]
    return listed


@pytest.mark.parametrize("jobs", [1, 2])
def test_ctrl_c_stops_within_2_s_and_the_manifest_lists_exactly_the_assets_on_disk(recipe_dir, tmp_path, jobs):
    recipe, out = _slow_batch(recipe_dir), tmp_path / "out"
    proc = _start(recipe, out, "--jobs", str(jobs))
    _wait_for_first_record(proc, out)
    workers = _workers(proc.pid)
    assert len(workers) == (2 if jobs == 2 else 0)
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole foreground group
    sent = time.perf_counter()
    _, stderr = proc.communicate(timeout=30)
    stopped_s = time.perf_counter() - sent
    assert not [w for w in workers if process_alive(w)]
    print(f"\n-j {jobs}: exit {proc.returncode} {stopped_s:.2f} s after SIGINT")
    assert proc.returncode == 130 and stopped_s < 2.0, stderr
    assert "interrupted by Ctrl-C" in stderr and "assets in progress" in stderr
    time.sleep(1.0)  # nothing lands later
    listed = _assert_manifest_matches_folder(out)
    assert 1 <= len(listed) < 12
    check = _check(recipe, out)  # the next build rebuilds exactly the others
    assert set(check["up_to_date"]) == listed and len(check["stale"]) == 12 - len(listed)


def test_kill_9_of_the_parent_leaves_no_worker_alive(recipe_dir, tmp_path):
    recipe, out = _slow_batch(recipe_dir), tmp_path / "out"
    proc = _start(recipe, out, "--jobs", "2")
    _wait_for_first_record(proc, out)
    workers = _workers(proc.pid)
    assert len(workers) == 2
    os.kill(proc.pid, signal.SIGKILL)  # the parent only: its workers are re-parented
    killed = time.perf_counter()
    proc.wait(timeout=10)
    while [w for w in workers if process_alive(w)] and time.perf_counter() - killed < 5.0:
        time.sleep(0.02)
    gone_s = time.perf_counter() - killed
    print(f"\nworkers gone {gone_s:.2f} s after kill -9 of the parent")
    assert not [w for w in workers if process_alive(w)]
    records = {p.name for p in (out / ".decollage").glob("*.json")}
    time.sleep(2.0)
    assert {p.name for p in (out / ".decollage").glob("*.json")} == records  # nothing written afterwards
    check = _check(recipe, out)
    assert {f"{n}.json" for n in check["up_to_date"]} == records


def test_a_cluster_stops_the_tasks_of_a_killed_build(recipe_dir, tmp_path):
    """The cluster's workers are not the build's to kill: its queued tasks are dropped and its running
    ones stop at their next stage, since their build no longer holds the folder (pipeline/lock.py)."""
    distributed = pytest.importorskip("distributed")
    recipe, out = _slow_batch(recipe_dir), tmp_path / "out"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        proc = _start(recipe, out, "--executor", "dask", "--address", cluster.scheduler_address)
        _wait_for_first_record(proc, out)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        records = {p.name for p in (out / ".decollage").glob("*.json")}
        time.sleep(5.0)
        files = sorted(p.name for p in out.iterdir())
        time.sleep(3.0)
        assert sorted(p.name for p in out.iterdir()) == files  # nothing runs any more after 5 s
        assert {p.name for p in (out / ".decollage").glob("*.json")} == records  # nor recorded after the kill
    assert len(records) < 12


def test_sigterm_stops_the_build_like_ctrl_c(recipe_dir, tmp_path):
    recipe, out = _slow_batch(recipe_dir), tmp_path / "out"
    proc = _start(recipe, out, "--jobs", "2")
    _wait_for_first_record(proc, out)
    proc.terminate()  # the parent only, as `kill` or a CI timeout does
    _, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 143 and "interrupted by SIGTERM" in stderr, stderr
    _assert_manifest_matches_folder(out)


# --------------------------------------------------------------------------- the output folder's lock


def test_a_build_waits_for_the_lock_or_stops_with_a_clear_message(recipe_dir, tmp_path):
    recipe, out = _recipe(recipe_dir), tmp_path / "out"
    other = BuildLock(out)  # another build holds the folder
    other.acquire()
    try:
        result = _cli("build", recipe, "-o", out, "--only", "crate", "--no-wait")
        assert result.exit_code == 2 and "another build is writing into this folder (pid" in result.stderr
        assert not (out / "manifest.json").exists()
        waiting = _start(recipe, out, "--only", "crate")
        line = waiting.stderr.readline()
        assert line.startswith("waiting:") and "is being written by another build (pid" in line, line
        assert waiting.poll() is None
    finally:
        other.release()
    _, stderr = waiting.communicate(timeout=120)
    assert waiting.returncode == 0, stderr
    assert _assert_manifest_matches_folder(out) == {"crate"}


def test_a_lock_left_by_a_killed_build_is_taken_over(recipe_dir, tmp_path):
    recipe, out = _recipe(recipe_dir), tmp_path / "out"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    lock_path(out).parent.mkdir(parents=True)
    lock_path(out).write_text(json.dumps({"build": "0" * 16, "pid": int(dead.stdout), "ticks": None,
                                          "host": socket.gethostname(), "started_at": "2026-01-01T00:00:00Z"}))
    result = _cli("build", recipe, "-o", out, "--only", "crate")
    assert result.exit_code == 0, result.stderr
    assert f"did not finish (pid {int(dead.stdout)} on" in result.stderr
    assert lock_path(out).read_text() == ""  # released: a finished build leaves the lock empty


def test_two_builds_at_once_leave_a_consistent_folder(recipe_dir, tmp_path):
    recipe, out = _recipe(recipe_dir), tmp_path / "out"
    first, second = _start(recipe, out, "--json"), _start(recipe, out, "--json")
    outputs = [json.loads(p.communicate(timeout=600)[0])["summary"] for p in (first, second)]
    assert first.returncode == second.returncode == 0
    assert sorted((s["built"], s["cached"]) for s in outputs) == [(0, 7), (7, 0)]  # one built, the other waited
    assert len(_assert_manifest_matches_folder(out)) == 7

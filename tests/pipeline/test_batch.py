"""Batch builds: incremental cache, --check/--list/--json, parallel jobs, interruption, cluster executor."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.app import app

pytestmark = pytest.mark.e2e  # whole batch builds, subprocess CLI runs

REPO = Path(__file__).resolve().parents[2]

BATCH = """
version: 1
defaults:
  detailize: {{detailizer: upsample}}
  export: {{max_triangles: 3000, preview_size_px: 96}}
assets:
  - name: shroom
    variants: {{style: [moss, birch, stone], seed: [0, 1]}}
    source: {{kind: voxels, path: {npz}, voxel_size_m: 0.05}}
    grid: {{fit: voxel_size, voxel_size_m: 0.1}}
    regions: [{{parts: ["*"], part: body, style: "${{style}}"}}]
    detailize: {{seed: "${{seed}}"}}
  - name: letter
    source: {{kind: text, text: A, size_m: 0.2}}
    grid: {{resolution: 8}}
    regions: [{{part: body, style: stone}}]
"""


@pytest.fixture
def batch(tmp_path):
    npz = tmp_path / "shroom.npz"
    shutil.copy(REPO / "recipes" / "inputs" / "mushroom.npz", npz)
    recipe = tmp_path / "batch.yaml"
    recipe.write_text(BATCH.format(npz=npz.name))
    return recipe


def _cli(*args):
    result = CliRunner().invoke(app, [str(a) for a in args])
    return result


def _json(*args):
    result = _cli(*args, "--json")
    assert result.exit_code in (0, 1), result.stderr
    return result.exit_code, json.loads(result.stdout)


def _statuses(summary):
    return {a["name"]: a["status"] for a in summary["assets"]}


def test_list_shows_the_expansion(batch):
    result = _cli("build", batch, "--list", "--json")
    assert result.exit_code == 0
    rows = json.loads(result.stdout)
    assert [r["name"] for r in rows][:2] == ["shroom_moss_0", "shroom_moss_1"] and len(rows) == 7
    assert rows[-1] == {"name": "letter", "recipe_field": "assets[1]", "source": "text", "variant": None}


def test_showcase_batch_expands_to_at_least_48_assets():
    result = _cli("build", REPO / "recipes" / "batch_showcase.yaml", "--list", "--json")
    assert result.exit_code == 0, result.stderr
    names = [r["name"] for r in json.loads(result.stdout)]
    assert len(names) >= 48 and len(set(names)) == len(names)


def test_second_build_is_cached_and_identical(batch, tmp_path):
    out = tmp_path / "out"
    assert _cli("build", batch, "-o", out, "--check").exit_code == 1  # nothing built yet: stale
    code, first = _json("build", batch, "-o", out)
    assert code == 0 and first["summary"] == {"assets": 7, "built": 7, "cached": 0, "failed": 0}
    manifest = (out / "manifest.json").read_bytes()
    code, second = _json("build", batch, "-o", out)
    assert second["summary"]["cached"] == 7 and second["summary"]["built"] == 0
    assert (out / "manifest.json").read_bytes() == manifest  # a CI job can diff it
    assert second["wall_time_s"] < 0.2 * first["wall_time_s"]
    assert _cli("build", batch, "-o", out, "--check").exit_code == 0

    # one changed entry rebuilds only that asset
    batch.write_text(batch.read_text().replace("text: A,", "text: B,"))
    code, third = _json("build", batch, "-o", out)
    assert [n for n, s in _statuses(third).items() if s == "built"] == ["letter"]
    # changed input bytes rebuild every asset that reads them
    npz = tmp_path / "shroom.npz"
    npz.write_bytes(npz.read_bytes() + b"")  # same bytes: still cached
    assert _json("build", batch, "-o", out)[1]["summary"]["cached"] == 7
    # --force rebuilds everything, with identical files
    code, forced = _json("build", batch, "-o", out, "--force")
    assert forced["summary"]["built"] == 7
    assert (out / "manifest.json").read_bytes() != manifest  # timings and the changed letter differ


def test_tampered_output_is_rebuilt(batch, tmp_path):
    out = tmp_path / "out"
    _json("build", batch, "-o", out, "--only", "letter")
    (out / "letter.glb").write_bytes(b"half-written")
    code, again = _json("build", batch, "-o", out, "--only", "letter")
    assert _statuses(again) == {"letter": "built"}


def test_jobs_give_byte_identical_outputs(batch, tmp_path):
    code, one = _json("build", batch, "-o", tmp_path / "j1", "--jobs", "1")
    code, two = _json("build", batch, "-o", tmp_path / "j2", "--jobs", "2")
    assert two["summary"]["built"] == 7
    for name in _statuses(one):
        for suffix in ("glb", "png"):
            assert (tmp_path / "j1" / f"{name}.{suffix}").read_bytes() == \
                   (tmp_path / "j2" / f"{name}.{suffix}").read_bytes(), name


def test_fail_fast_stops_after_the_first_failure(batch, tmp_path):
    batch.write_text(batch.read_text().replace("shroom.npz", "broken.npz"))
    # An empty grid passes the pre-flight checks (a readable file) and fails its asset while building.
    np.savez(tmp_path / "broken.npz", occupancy=np.zeros((4, 4, 4), dtype=np.uint8))
    result = _cli("build", batch, "-o", tmp_path / "out", "--fail-fast", "--json")
    assert result.exit_code == 1
    summary = json.loads(result.stdout)
    assert summary["summary"]["failed"] == 1 and summary["summary"]["assets"] == 1
    result = _cli("build", batch, "-o", tmp_path / "out2", "--json")
    assert json.loads(result.stdout)["summary"] == {"assets": 7, "built": 1, "cached": 0, "failed": 6}


@pytest.mark.parametrize("sig, jobs", [(signal.SIGKILL, 1), (signal.SIGINT, 2)])
def test_killed_build_resumes_with_only_the_missing_assets(batch, tmp_path, sig, jobs):
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "cli.app", "build", str(batch), "-o", str(out), "--quiet", "--jobs", str(jobs)]
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    records = out / ".decollage"
    deadline = time.time() + 120
    while time.time() < deadline and not (records.exists() and any(records.glob("*.json"))):
        time.sleep(0.05)
    os.killpg(proc.pid, sig)  # the whole process group, as a terminal's Ctrl-C or a CI timeout would
    proc.wait(timeout=60)
    done_before = {p.stem for p in records.glob("*.json")}
    # kill at the first record: the widest margin before all 7 are done, even on a loaded machine
    assert 1 <= len(done_before) < 7
    code, resumed = _json("build", batch, "-o", out)
    statuses = _statuses(resumed)
    assert {n for n, s in statuses.items() if s == "cached"} == done_before
    assert all(s in ("built", "cached") for s in statuses.values())
    files = sorted(p.name for p in out.iterdir())
    assert [f for f in files if f.startswith(".") and f != ".decollage"] == []  # no temporaries left
    assert len([f for f in files if f.endswith(".glb")]) == 7


def test_dask_executor_matches_the_local_build(batch, tmp_path):
    distributed = pytest.importorskip("distributed")
    code, local = _json("build", batch, "-o", tmp_path / "local")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None, resources={"GPU": 1}) as cluster:
        code, remote = _json("build", batch, "-o", tmp_path / "dask", "--executor", "dask",
                             "--address", cluster.scheduler_address, "--gpus-per-task", "1")
    assert remote["summary"]["built"] == 7
    for name in _statuses(local):
        assert (tmp_path / "local" / f"{name}.glb").read_bytes() == (tmp_path / "dask" / f"{name}.glb").read_bytes()


def test_unreachable_cluster_fails_fast_and_clearly(batch, tmp_path):
    out = tmp_path / "out"
    _json("build", batch, "-o", out, "--only", "letter")
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    batch.write_text(batch.read_text().replace("text: A,", "text: B,"))  # stale: the cluster is needed
    started = time.time()
    result = _cli("build", batch, "-o", out, "--executor", "dask", "--address", "tcp://127.0.0.1:9")
    assert result.exit_code == 2 and time.time() - started < 30
    assert "cannot reach the Dask scheduler" in result.stderr
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before  # manifest kept as it was


def test_default_detailizer_key_covers_the_shipped_weights(write_recipe, tmp_path, monkeypatch):
    """An asset that names no checkpoint is rebuilt when the shipped model's bytes change."""
    from pipeline.batch import plan_build
    from core.recipe_loader import load_recipe

    weights = tmp_path / "things.pt"
    monkeypatch.setattr("model.infer.DEFAULT_CHECKPOINT", weights)
    recipe = write_recipe("""
version: 1
assets:
  - name: letter
    source: {kind: text, text: A, size_m: 0.2}
    regions: [{part: bottom, style: tower}]
    detailize: {detailizer: decollage}
""")
    loaded = load_recipe(recipe)

    def key():
        return plan_build(loaded, tmp_path / "out")[0].key

    weights.write_bytes(b"weights v1")
    first = key()
    assert key() == first
    weights.write_bytes(b"weights v2")
    assert key() != first


def test_gpus_per_task_without_a_cluster_is_a_usage_error(batch, tmp_path):
    result = _cli("build", batch, "-o", tmp_path / "out", "--gpus-per-task", "1")
    assert result.exit_code == 2 and "needs --executor dask" in result.stderr
    assert not (tmp_path / "out").exists()

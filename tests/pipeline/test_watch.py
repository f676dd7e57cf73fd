"""Watch mode: after a save, exactly the assets whose inputs changed are rebuilt, from a cached batch, promptly."""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.app import app
from core.recipe_loader import load_recipe
from pipeline.batch import build_recipe
from pipeline.manifest import BUILD_SIGNAL
from pipeline.watch import Rebuild, watch_build, watched_files
from sources.vox_file import write_vox

N_ASSETS = 8
#: The acceptance bound: an edit is rebuilt within this long of the save (2 cores, cached batch), on the
#: machine kind it was set for.
LATENCY_S = 2.0
#: The reference workload's median (``evaluation.benchmarking.reference_workload_seconds``) on that machine
#: (2-core AMD EPYC, quiet): a machine that runs it slower — or the same VM in a slow phase, which swings 2×
#: within minutes — gets a bound as much longer (never shorter): speed compares across machines as a ratio.
REFERENCE_NOMINAL_S = 0.22
#: From the save to the start of the rebuild (event delivery and the debounce's quiet period).
DETECT_S = 1.0


def _check_latency(round_: Rebuild, what: str) -> None:
    """The 2 s bound (scaled by the reference workload timed now) on a machine that is not oversubscribed;
    under contention (other builds running on the same cores) only the detection delay is held to its bound.
    The figures are printed (pytest -s)."""
    from evaluation.benchmarking import reference_workload_seconds

    asset = next(r for r in round_.reports if not r.cached)
    load = os.getloadavg()[0]
    reference = reference_workload_seconds(repeats=3)["median_s"]
    bound = LATENCY_S * max(1.0, reference / REFERENCE_NOMINAL_S)
    print(f"\nwatch latency ({what}): {round_.since_save_s:.2f} s from the save to the manifest: detected after "
          f"{round_.detected_s:.2f} s, round {round_.build_s:.2f} s (the asset's stages "
          f"{sum(asset.timings_s.values()):.2f} s), CPU {round_.cpu_s:.2f} s; load average {load:.1f} on "
          f"{os.cpu_count()} cores; reference workload {reference:.3f} s, bound {bound:.2f} s")
    assert round_.detected_s < DETECT_S
    if load <= (os.cpu_count() or 1):
        assert round_.since_save_s < bound


def _model(height: int) -> np.ndarray:
    grid = np.zeros((5, 4, 8), dtype=np.uint8)
    grid[:, :, :height] = 1
    grid[1:4, 1:3, height:] = 2
    return grid


def _recipe(styles: list[str], detailizer: str = "upsample") -> str:
    assets = "".join(f"""
  - name: hut{i}
    source: {{kind: vox, path: hut{i}.vox, parts: {{body: [1], roof: [2]}}}}
    regions: [{{part: body, style: {style}}}, {{parts: [roof], part: roof, style: tower}}]
""" for i, style in enumerate(styles))
    return f"""version: 1
defaults:
  detailize: {{detailizer: {detailizer}}}
  grid: {{resolution: 16}}
  export: {{preview_size_px: 256}}
assets:{assets}"""


def _batch(folder: Path, detailizer: str = "upsample") -> Path:
    for i in range(N_ASSETS):
        (folder / f"hut{i}.vox").write_bytes(write_vox([_model(3 + i % 4)]))
    recipe = folder / "batch.yaml"
    recipe.write_text(_recipe(["cottage"] * N_ASSETS, detailizer))
    return recipe


class _Watcher:
    """watch_build in a thread; rounds arrive on a queue-like list."""

    def __init__(self, recipe: Path, out: Path) -> None:
        self.rounds: list[Rebuild] = []
        self.arrived = threading.Condition()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=watch_build, args=(recipe, lambda loaded: build_recipe(loaded, out),
                                                                  self._add), kwargs={"stop": self.stop})

    def _add(self, round_: Rebuild) -> None:
        with self.arrived:
            self.rounds.append(round_)
            self.arrived.notify_all()

    def next_round(self, count: int, timeout: float = 60.0) -> Rebuild:
        with self.arrived:
            assert self.arrived.wait_for(lambda: len(self.rounds) >= count, timeout), "no rebuild came"
            return self.rounds[count - 1]

    def __enter__(self) -> "_Watcher":
        self.thread.start()
        self.next_round(1)
        time.sleep(0.5)  # the first build is reported before the file watch is armed
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        self.thread.join(timeout=10)
        assert not self.thread.is_alive()


def _watch_and_edit(tmp_path, detailizer: str = "upsample") -> list[Rebuild]:
    recipe, out = _batch(tmp_path, detailizer), tmp_path / "out"
    build_recipe(load_recipe(recipe), out)  # the cached batch
    with _Watcher(recipe, out) as watcher:
        assert watcher.rounds[0].rebuilt == [] and watcher.rounds[0].error is None
        (tmp_path / "hut3.vox").write_bytes(write_vox([_model(2)]))  # a new shape for one asset
        first = watcher.next_round(2)
        styles = ["cottage"] * N_ASSETS
        styles[5] = "pagoda"
        recipe.write_text(_recipe(styles, detailizer))  # one recipe entry changes
        second = watcher.next_round(3)
        (tmp_path / "hut1.vox").write_bytes((tmp_path / "hut1.vox").read_bytes())  # saved, same bytes
        third = watcher.next_round(4)
    return [first, second, third]


def test_watch_rebuilds_exactly_the_changed_asset(tmp_path):
    edit, entry, same = _watch_and_edit(tmp_path)
    assert edit.changed == [(tmp_path / "hut3.vox").resolve()] and edit.rebuilt == ["hut3"]
    assert entry.changed == [(tmp_path / "batch.yaml").resolve()] and entry.rebuilt == ["hut5"]
    assert same.rebuilt == []  # the bytes did not change: nothing to rebuild
    assert all(r.error is None and len(r.reports) == N_ASSETS for r in (edit, entry, same))
    signal = json.loads((tmp_path / "out" / BUILD_SIGNAL).read_text())
    assert signal["counter"] == 5 and signal["rebuilt"] == []  # 1 batch build + 4 watch rounds
    _check_latency(edit, f"upsample batch of {N_ASSETS}, an input file saved")
    _check_latency(entry, f"upsample batch of {N_ASSETS}, a recipe entry saved")


@pytest.mark.e2e
@pytest.mark.parametrize("detailizer", ["quilt", "decollage"])  # the default, and the shipped model
def test_watch_latency_with_the_real_detailizers(tmp_path, detailizer):
    edit, entry, _ = _watch_and_edit(tmp_path, detailizer)
    assert edit.rebuilt == ["hut3"] and entry.rebuilt == ["hut5"]
    _check_latency(edit, f"{detailizer} batch of {N_ASSETS}, an input file saved")
    _check_latency(entry, f"{detailizer} batch of {N_ASSETS}, a recipe entry saved")


def test_watched_files_are_the_recipe_its_inputs_and_the_weights(tmp_path):
    recipe = _batch(tmp_path, "decollage")
    files = watched_files(load_recipe(recipe), None)
    assert recipe.resolve() in files and (tmp_path / "hut0.vox").resolve() in files
    assert any(p.name == "things.pt" for p in files)


def test_a_broken_recipe_is_reported_and_watching_goes_on(tmp_path):
    recipe, out = _batch(tmp_path), tmp_path / "out"
    with _Watcher(recipe, out) as watcher:
        assert sorted(watcher.rounds[0].rebuilt) == sorted(f"hut{i}" for i in range(N_ASSETS))
        recipe.write_text("version: 1\nassets: [")
        broken = watcher.next_round(2)
        assert broken.reports is None and "not valid YAML" in broken.error.message
        recipe.write_text(_recipe(["cottage"] * N_ASSETS))
        assert watcher.next_round(3).rebuilt == []  # the same recipe again: all cached


def test_watch_refuses_list_check_and_json(tmp_path):
    recipe = _batch(tmp_path)
    result = CliRunner().invoke(app, ["build", str(recipe), "-o", str(tmp_path / "o"), "--watch", "--check"])
    assert result.exit_code == 2 and "--watch" in result.stderr

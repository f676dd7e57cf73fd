"""``decollage view`` and ``decollage paint`` as a user runs them: the URL on stdout, Ctrl-C stops cleanly."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from tests.conftest import REPO

pytestmark = pytest.mark.e2e


def _start(*args: str) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen([sys.executable, "-m", "cli.app", *args], cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    url = proc.stdout.readline().strip()
    if not url.startswith("http://127.0.0.1:"):
        proc.kill()
        raise AssertionError(f"no URL on stdout: {url!r} {proc.stderr.read()}")
    return proc, url


def _stop(proc: subprocess.Popen) -> tuple[int, str, float]:
    started = time.monotonic()
    proc.send_signal(signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise
    return proc.returncode, err, time.monotonic() - started


def test_view_serves_the_build_and_stops_on_ctrl_c(small_build):
    proc, url = _start("view", str(small_build), "--port", "0")
    try:
        manifest = json.loads(urllib.request.urlopen(url + "api/manifest", timeout=30).read())
        assert len(manifest["assets"]) == 3
        assert urllib.request.urlopen(url, timeout=30).read().startswith(b"<!doctype html>")
        with urllib.request.urlopen(url + "vendor/three/build/three.module.js", timeout=30) as response:
            assert response.headers["Content-Type"].startswith("text/javascript")
    finally:
        code, err, took = _stop(proc)
    assert code == 0 and "stopped" in err and took < 10, (code, err)
    assert "Traceback" not in err


def test_paint_stops_on_ctrl_c_and_refuses_a_missing_asset(small_recipe):
    proc, url = _start("paint", str(small_recipe), "--asset", "word", "--port", "0")
    try:
        session = json.loads(urllib.request.urlopen(url + "api/session", timeout=30).read())
        assert session["initial"] == "word" and "upsample" in session["detailizers"]
    finally:
        code, err, took = _stop(proc)
    assert code == 0 and "stopped" in err and took < 10, (code, err)
    done = subprocess.run([sys.executable, "-m", "cli.app", "paint", str(small_recipe), "--asset", "nope"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "'nope' is not in the recipe" in done.stderr and "Traceback" not in done.stderr


def test_view_of_a_folder_without_manifest_is_a_clear_error(tmp_path: Path):
    done = subprocess.run([sys.executable, "-m", "cli.app", "view", str(tmp_path), "--port", "0"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "no manifest.json" in done.stderr

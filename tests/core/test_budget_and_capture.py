"""The pre-flight memory estimate (core/budget.py) and the capture of library warnings (core/capture.py)."""

from __future__ import annotations

import logging
import warnings

import numpy as np
import pytest

from core.budget import (
    BASE_BYTES,
    DEFAULT_MEMORY_BUDGET_GB,
    check_asset_memory,
    estimate_asset_bytes,
    memory_budget_bytes,
)
from core.capture import MAX_NOTES, captured_warnings
from core.errors import UsageError, VoxelizeError


def test_the_estimate_grows_with_the_fine_grid_and_the_voxelizer_samples():
    assert estimate_asset_bytes((16, 16, 16)) == BASE_BYTES + 16**3 * 16**3 * 32
    assert estimate_asset_bytes((256, 1, 1), supersample=1) == BASE_BYTES + 256 * 4096 * 32
    assert estimate_asset_bytes((64, 64, 64), supersample=4) > estimate_asset_bytes((64, 64, 64)) / 2


def test_a_grid_past_the_budget_is_refused_with_what_to_lower(monkeypatch):
    monkeypatch.delenv("DECOLLAGE_MEMORY_BUDGET_GB", raising=False)
    assert memory_budget_bytes() == int(DEFAULT_MEMORY_BUDGET_GB * 1e9)
    assert check_asset_memory((40, 40, 40), resolution=40, fit="longest") < memory_budget_bytes()
    with pytest.raises(VoxelizeError) as info:
        check_asset_memory((64, 64, 64), resolution=64, fit="longest")
    err = info.value
    assert err.field == "grid" and "1024×1024×1024 fine grid" in err.message and "10 GB memory budget" in err.message
    assert "lower grid.resolution to 4" in err.hint and "DECOLLAGE_MEMORY_BUDGET_GB" in err.hint
    with pytest.raises(VoxelizeError, match="memory budget") as info:
        check_asset_memory((200, 200, 200), resolution=16, fit="voxel_size")
    assert "raise grid.voxel_size_m" in info.value.hint
    monkeypatch.setenv("DECOLLAGE_MEMORY_BUDGET_GB", "100")
    check_asset_memory((64, 64, 64), resolution=64, fit="longest")
    monkeypatch.setenv("DECOLLAGE_MEMORY_BUDGET_GB", "lots")
    with pytest.raises(UsageError):
        memory_budget_bytes()


def test_library_warnings_are_counted_once_in_the_projects_words(capfd):
    notes: list[str] = ["the source's own note"]
    with captured_warnings(notes):
        for _ in range(3):  # as if numpy's own code warned
            warnings.warn_explicit("overflow encountered in multiply", RuntimeWarning,
                                   "/venv/lib/python3.11/site-packages/numpy/_core/x.py", 1)
        np.array([1e308]) * 10  # numpy warns on behalf of its caller: this file
        warnings.warn("something odd", UserWarning)
        logging.getLogger("trimesh").warning("face normals didn't match")
    assert notes[0] == "the source's own note"
    assert any(n.startswith("numpy warned 3 times: overflow encountered in multiply (RuntimeWarning)") for n in notes)
    assert "decollage (tests/core/test_budget_and_capture.py) warned: something odd (UserWarning)" in notes
    assert "trimesh warned: face normals didn't match (log)" in notes
    captured = capfd.readouterr()
    assert "overflow" not in captured.err and "normals" not in captured.err  # nothing raw is printed


def test_many_kinds_of_warnings_are_capped():
    notes: list[str] = []
    with captured_warnings(notes):
        for i in range(MAX_NOTES + 5):
            warnings.warn(f"kind {i}", UserWarning)
    assert len(notes) == MAX_NOTES + 1 and "5 more kinds" in notes[-1]

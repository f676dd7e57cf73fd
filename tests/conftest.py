"""Shared test helpers: fixtures are made in code."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent

# Tests must never use more threads than CI's 2 cores.
os.environ.setdefault("OMP_NUM_THREADS", "2")


@pytest.fixture
def write_recipe(tmp_path):
    """Write recipe text into tmp_path and return its path."""

    def _write(text: str, name: str = "recipe.yaml") -> Path:
        path = tmp_path / name
        path.write_text(text)
        return path

    return _write

"""Run the Khronos glTF validator (tools/gltf, installed by `scripts/install.sh test`) on GLB files."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

TOOL = Path(__file__).resolve().parent.parent / "tools" / "gltf"


def validate_glbs(paths: list[Path]) -> list[dict]:
    """One report per file ({file, errors, warnings, messages}); skips the test if the tool is absent."""
    node = shutil.which("node")
    if node is None or not (TOOL / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("gltf-validator not installed (bash scripts/install.sh test installs it)")
    proc = subprocess.run([node, str(TOOL / "validate.mjs"), *map(str, paths)], capture_output=True,
                          text=True, timeout=300)
    reports = [json.loads(line) for line in proc.stdout.splitlines() if line.strip()]
    assert len(reports) == len(paths), proc.stderr
    return reports

"""The Khronos glTF validator (npm `gltf-validator`, which `scripts/setup.sh --test` installs
into .tools/) on an exported file: every glTF the tests write must pass it, not only load back."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
VALIDATOR = ROOT / ".tools" / "node_modules" / "gltf-validator"
SCRIPT = Path(__file__).with_name("khronos_gltf.js")


def gltf_issues(path: Path) -> dict:
    """The validator's issues for `path`: numErrors, numWarnings, messages (code, pointer, …)."""
    node = shutil.which("node")
    if node is None:
        pytest.skip("Node.js is not installed, so the Khronos glTF validator cannot run (scripts/setup.sh --test installs both)")
    assert VALIDATOR.is_dir(), "the Khronos glTF validator is missing: run bash scripts/setup.sh --test"
    r = subprocess.run([node, str(SCRIPT), str(VALIDATOR), str(path)], capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def assert_valid_gltf(path: Path) -> None:
    """No error and no warning from the Khronos validator."""
    issues = gltf_issues(path)
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"]

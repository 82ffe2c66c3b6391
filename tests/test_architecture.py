"""The import-linter contracts in pyproject.toml: the core imports neither Qt nor OpenGL; the
studies measure the render layer but never import the GUI."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_core_imports_neither_qt_nor_opengl():
    beside = Path(sys.executable).parent / "lint-imports"  # the venv's, when the suite runs from it
    exe = str(beside) if beside.exists() else shutil.which("lint-imports")
    if exe is None:
        pytest.fail("import-linter is not installed (scripts/setup.sh --test installs it)")
    proc = subprocess.run([exe, "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert "2 kept, 0 broken" in proc.stdout
    assert "The core imports neither Qt nor OpenGL KEPT" in proc.stdout
    assert "Studies measure the render layer but never the GUI KEPT" in proc.stdout

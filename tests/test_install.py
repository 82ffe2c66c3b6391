"""A non-editable install finds shaders/, materials/ and resources/ without the checkout."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow
def test_installed_package_finds_its_data(tmp_path):
    src = tmp_path / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".git", "build", "*.egg-info", "__pycache__", ".pytest_cache", ".hypothesis"))
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation", "--target", str(target), str(src)],
        check=True,
    )
    shutil.rmtree(src)  # nothing may point back into a checkout
    code = (
        "import json, brdflab, brdflab.io.resources as r;"
        "print(json.dumps({'pkg': brdflab.__file__, 'shaders': str(r.data_dir('shaders')),"
        " 'materials': [p.name for p in r.example_materials()],"
        " 'resources': str(r.data_dir('resources'))}))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env={"PYTHONPATH": str(target), "PATH": ""},
                         capture_output=True, text=True, check=True)
    info = json.loads(out.stdout)
    assert info["pkg"].startswith(str(target))
    for key in ("shaders", "resources"):
        assert Path(info[key]).is_dir() and Path(info[key]).is_relative_to(target)
    assert "fig2_lambertian_lafortune.xml" in info["materials"]

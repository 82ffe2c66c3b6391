"""Export: a material or stored fit written as a MERL table reads back as the same BRDF."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdflab.geometry.halfdiff import from_half_diff
from brdflab.io.xmlio import load
from brdflab.sources.measured import read_merl_binary

ROOT = Path(__file__).resolve().parents[1]
MATERIAL = ROOT / "materials" / "fig2_lambertian_lafortune.xml"


def _cli(*args, cwd):
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}
    return subprocess.run([sys.executable, "-m", "brdflab", *args], cwd=cwd, env=env, capture_output=True, text=True)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("export")
    result = _cli("export", str(MATERIAL), "--format", "merl", "--out", "out.binary", cwd=folder)
    assert result.returncode == 0, result.stderr
    return folder / "out.binary"


def test_merl_export_reads_back_as_the_source(exported):
    source = load(MATERIAL).material
    table = read_merl_binary(exported)
    rng = np.random.default_rng(3)
    n = 4000
    # random (θh, θd, φd) away from grazing, where MERL's grid is coarse and the lobe steep
    th = rng.uniform(0.05, 0.6, n)
    td = rng.uniform(0.05, 0.9, n)
    pd = rng.uniform(0.1, np.pi - 0.1, n)
    wi, wo = from_half_diff(th, 0.0, td, pd)
    ok = (wi[:, 2] > 0.2) & (wo[:, 2] > 0.2)
    want = source.evaluate(wi[ok], wo[ok])
    got = table.evaluate(wi[ok], wo[ok])
    rel = np.abs(got - want) / np.maximum(want, 1e-3)
    # trilinear interpolation on MERL's grid: a few per cent at most for this smooth lobe
    assert np.median(rel) < 0.01 and np.percentile(rel, 99) < 0.05
    # and not trivially equal: a different material would fail
    assert not np.allclose(got, 2 * want, rtol=0.05)


def test_export_errors_are_one_line(tmp_path):
    result = _cli("export", "missing.xml", "--out", "x.binary", cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "missing.xml" in result.stderr
    result = _cli("export", str(MATERIAL), "--fitting", "5", "--out", "x.binary", cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert not (tmp_path / "x.binary").exists()

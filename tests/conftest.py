import os
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("BRDFLAB_SHARED", ROOT.parent / "shared"))
DATA = SHARED / "data"


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_upper(rng, n):
    v = unit(rng.normal(size=(n, 3)))
    v[:, 2] = np.abs(v[:, 2]) + 1e-3
    return unit(v)


@pytest.fixture(autouse=True)
def _registry_as_it_was():
    """Models read from files by one test leave the registry with it: every other test sees
    the built-ins alone (as a user's process without model folders does)."""
    from brdflab.models.registry import _MODELS

    before = dict(_MODELS)
    yield
    _MODELS.clear()
    _MODELS.update(before)


@pytest.fixture(autouse=True)
def _own_user_cache(tmp_path_factory, monkeypatch):
    """Each test starts with an empty user cache (BRDFLAB_CACHE; its subprocesses inherit it):
    a fit one test cached, or one left by an earlier run on this machine, never answers another."""
    monkeypatch.setenv("BRDFLAB_CACHE", str(tmp_path_factory.mktemp("cache")))


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def needs_shared(*parts):
    """Skip cleanly on a machine without ../shared (a user's machine)."""
    path = DATA.joinpath(*parts)
    return pytest.mark.skipif(not path.exists(), reason=f"{path} is not available")


@pytest.fixture(scope="session")
def quick_study(tmp_path_factory):
    """`brdflab study --quick` run once for the session, as CI and a user run it (a subprocess
    from another folder): (its output folder, its --json payload, study.json with its rows)."""
    import json
    import subprocess
    import sys

    from brdflab.study.framework import read_study

    work = tmp_path_factory.mktemp("quick-study")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = subprocess.run([sys.executable, "-m", "brdflab", "study", "--quick", "--out", "study", "--json"],
                         cwd=work, env=env, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-2000:]
    out = work / "study"
    return out, json.loads(run.stdout), read_study(out)

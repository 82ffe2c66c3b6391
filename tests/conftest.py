import fcntl
import os
from contextlib import contextmanager
from pathlib import Path

if os.environ.get("PYTEST_XDIST_WORKER"):
    # each of the suite's workers (pyproject's addopts) holds one core: BLAS threads beyond it only
    # contend with the other worker (set before NumPy reads them, once). llvmpipe keeps its threads:
    # one each made the suite 2 minutes slower (17:10 against 15:09; renders in subprocesses too)
    for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")

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


@pytest.fixture(autouse=True)
def _windows_gone_with_their_test(request):
    """A window closed at a GUI test's end is destroyed when Python collects it, and its GL
    widgets make their own context current to free their resources, then none: collected
    later, in another file's test, that left the file's own offscreen context not current
    ("cannot create texture"; it showed once two workers began taking files in varying
    orders). So a GUI test's windows are collected and deleted before the next test."""
    yield
    if "qtbot" in request.fixturenames:
        import gc

        from PySide6.QtCore import QCoreApplication, QEvent

        gc.collect()
        QCoreApplication.sendPostedEvents(None, QEvent.DeferredDelete)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def needs_shared(*parts):
    """Skip cleanly on a machine without ../shared (a user's machine)."""
    path = DATA.joinpath(*parts)
    return pytest.mark.skipif(not path.exists(), reason=f"{path} is not available")


@contextmanager
def _exclusive(path: Path):
    """Hold an exclusive lock on `path` (the suite's workers are separate processes)."""
    with open(path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _session_folder(tmp_path_factory) -> Path:
    """A folder of this test session that every worker sees (under pytest-xdist each worker's
    base temp is a child of the session's; alone, the base temp is the session's own)."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


@pytest.fixture(scope="session")
def quick_study(tmp_path_factory):
    """`brdflab study --quick` run once for the session, as CI and a user run it (a subprocess
    from another folder): (its output folder, its --json payload, study.json with its rows).
    The first worker that needs it runs it; the others wait for it and read the same folder
    (three test files read it: run per worker it cost a minute twice over)."""
    import json
    import subprocess
    import sys

    from brdflab.study.framework import read_study

    work = _session_folder(tmp_path_factory) / "quick-study"
    payload = work / "payload.json"
    with _exclusive(work.parent / "quick-study.lock"):
        if not payload.exists():
            work.mkdir(exist_ok=True)
            env = {**os.environ, "PYTHONPATH": str(ROOT)}
            run = subprocess.run([sys.executable, "-m", "brdflab", "study", "--quick", "--out", "study", "--json"],
                                 cwd=work, env=env, capture_output=True, text=True, timeout=900)
            assert run.returncode == 0, run.stderr[-2000:]
            payload.write_text(run.stdout)
    out = work / "study"
    return out, json.loads(payload.read_text()), read_study(out)


def shown_and_offscreen(view) -> tuple[np.ndarray, np.ndarray]:
    """What the object view has accumulated, per sample (RGB, row 0 at the top), and the
    offscreen render of the same settings in the same context."""
    view.makeCurrent()
    p = view._progressive
    shown = np.frombuffer(p.texture.read(), np.float32).reshape(p.settings.height, p.settings.width, 4)
    offscreen = view.renderer.render(p.settings)
    view.doneCurrent()
    return shown[::-1, :, :3] / p.samples, offscreen

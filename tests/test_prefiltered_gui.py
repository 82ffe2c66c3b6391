"""The prefiltered lighting mode in a real window (Xvfb in CI). A file of its own whose name
ends in _gui.py: window tests run before any headless EGL context exists (conftest.py)."""

import os

import numpy as np
import pytest


@pytest.mark.skipif(not os.environ.get("DISPLAY"), reason="needs a display (CI runs the suite under xvfb-run)")
def test_the_window_offers_the_mode_and_draws_it(qtbot, tmp_path):
    """A person picks `prefiltered` in the object view's lighting choice: the map's stack is
    built in the worker process, then the window shows what an offscreen render gives."""
    from PySide6.QtCore import QSettings

    from brdflab.gui.main_window import MainWindow

    window = MainWindow(QSettings(str(tmp_path / "settings.ini"), QSettings.IniFormat))
    window.maybe_save = lambda: True
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    view = window.object_view
    qtbot.waitUntil(lambda: view.ctx is not None, timeout=10000)
    modes = [window.object_controls.mode.itemText(i) for i in range(window.object_controls.mode.count())]
    assert "prefiltered" in modes
    window.object_controls.mode.setCurrentText("prefiltered")
    assert view.settings.mode == "prefiltered"
    qtbot.waitUntil(lambda: view.samples_done >= 1, timeout=120000)  # a worker process starts and builds
    view.makeCurrent()
    p = view._progressive
    shown = np.frombuffer(p.texture.read(), np.float32).reshape(p.settings.height, p.settings.width, 4)
    offscreen = view.renderer.render(p.settings)
    view.doneCurrent()
    np.testing.assert_allclose(shown[::-1, :, :3], offscreen, atol=1e-5)
    assert offscreen.max() > 0 and np.isfinite(offscreen).all()
    if os.environ.get("BRDFLAB_SCREENSHOT"):
        window.grab().save(os.environ["BRDFLAB_SCREENSHOT"])

"""The Simulation dock in a real window (Xvfb): progressive lobe texture, restarts, saving,
and a simulated material opened in the main window like measured data."""

import os

import pytest

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)

CHEAP = {"SCATMECH": (8, 16), "RayBounce": (6, 10)}


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("BRDFLAB_CACHE", str(tmp_path / "cache"))


@pytest.fixture
def panel(qtbot):
    from brdflab.gui.simulated import SimulatedPanel
    from brdflab.simulation.material import SimulationSpec

    p = SimulatedPanel(SimulationSpec("GaussianHeightField", {"rms_slope": 0.2}, seed=1), levels=CHEAP)
    qtbot.addWidget(p)
    p.resize(420, 640)
    p.show()
    qtbot.waitExposed(p)
    yield p
    p.shutdown()


def test_coarse_then_fine_texture_with_times_and_a_restart_on_change(panel, qtbot):
    shown = []
    panel.texture_shown.connect(lambda level, s: shown.append(level))
    qtbot.waitUntil(lambda: shown[-2:] == [0, 1], timeout=60000)
    assert "coarse 6×12" in panel.status.text() and "fine 10×20" in panel.status.text()
    if panel.view.ctx is not None:  # (a view without OpenGL still gets its textures)
        assert panel.view.viewer._layers[0].source is panel.shown
    peak_narrow = panel.shown.values.max()
    shown.clear()
    panel._editors["rms_slope"].setValue(0.6)  # as a person edits the spin box
    qtbot.waitUntil(lambda: shown[-2:] == [0, 1], timeout=60000)
    assert panel.spec.params["rms_slope"] == pytest.approx(0.6)
    assert panel.shown.values.max() < 0.8 * peak_narrow  # a rougher surface: a lower peak (0.66× in 9° texels)
    if panel.view.ctx is not None:
        assert panel.view.viewer._layers[0].source is panel.shown
        assert not panel.view.grabFramebuffer().isNull()


def test_saved_panel_material_opens_in_the_main_window(panel, qtbot, tmp_path):
    from PySide6.QtCore import QSettings

    from brdflab.gui.main_window import MainWindow
    from brdflab.simulation.material import SimulationSpec

    panel.spec = SimulationSpec("VGrooves", {"facet": "lambertian"}, seed=2, samples=2000, resolution=8)
    path = tmp_path / "grooves.xml"
    panel.save_to(path)
    w = MainWindow(QSettings(str(tmp_path / "settings.ini"), QSettings.IniFormat))
    w.maybe_save = lambda: True
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    w.open_path(path)
    qtbot.waitUntil(lambda: not w.loading, timeout=60000)
    source = w.workspace.source
    assert source is not None and source.spec.kind == "VGrooves"
    assert w.workspace.guess is not None  # the Material dock edits the next fit's guess, as for measured data
    w.show_simulation()
    dock = w._simulation_dock.widget()
    assert dock.spec.kind == "VGrooves"
    dock.spec = SimulationSpec("SpheresOnPlane", {"coverage": 0.3}, seed=3, samples=1000, resolution=8)  # as edited
    dock.use_button.click()
    qtbot.waitUntil(lambda: not w.loading and w.workspace.source.spec.kind == "SpheresOnPlane", timeout=60000)
    assert w.workspace.dirty and w.workspace.path is None
    w.workspace.save(tmp_path / "spheres.xml")
    assert 'model="SpheresOnPlane"' in (tmp_path / "spheres.xml").read_text()
    dock.shutdown()

"""Issue 30 §1: the window shows the current document, and its controls say what they do —
in a real window (Xvfb in CI), driven as a person would."""

import os

import numpy as np
import pytest
from conftest import DATA, needs_shared
from test_gui import open_and_wait, window  # noqa: F401  (the fixture)

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY") and os.environ.get("QT_QPA_PLATFORM") not in ("offscreen",),
    reason="needs a display (CI runs the suite under xvfb-run)",
)


def shot(widget, name: str) -> None:
    """Save what `widget` shows under $BRDFLAB_SHOTS (when set), to be looked at."""
    folder = os.environ.get("BRDFLAB_SHOTS")
    if folder:
        image = widget.grabFramebuffer() if hasattr(widget, "grabFramebuffer") else widget.grab()
        image.save(os.path.join(folder, f"{name}.png"))


def _measured(tmp_path, name: str, m: float):
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.sources.measured import tabulate, write_merl_binary

    truth = AnalyticMaterial(name, "Linear", 3, [Lobe.create("Lambertian", [0.05] * 3),
                                                 Lobe.create("CookTorrance", [0.5] * 3, m=m, F0=0.3)])
    path = tmp_path / f"{name}.binary"
    write_merl_binary(tabulate(truth), path)
    return path


def test_every_view_follows_a_document_opened_while_a_fit_runs(window, qtbot, tmp_path):
    first, second = _measured(tmp_path, "first", 0.2), _measured(tmp_path, "second", 0.4)
    open_and_wait(qtbot, window, window.open_path, first)
    window.object_controls.shown.setCurrentText("fitted")
    window.fitting.lobes.setCurrentText("Lambertian,CookTorrance,CookTorrance")
    window.fitting.sample_kind.setCurrentText("all")
    window.fitting.fit_button.click()
    qtbot.waitUntil(lambda: window.document.running is not None, timeout=30000)  # the fit has drawn its parameters
    old_fit = window.document.running
    open_and_wait(qtbot, window, window.open_path, second)  # discarding the first, the fit still running
    qtbot.waitUntil(lambda: window._thread is None, timeout=60000)
    qtbot.wait(600)  # the coalesced plot and object-view refreshes have run
    window.lobe_view.catch_up()  # the viewer takes new layers when its step thread lets go of the context
    ws = window.workspace
    assert ws.document.material.name == second.name and ws.document.fittings == []
    drawn = [window.object_view.renderer.source, window.object_view.compare_source,
             *(l.source for l in window.lobe_view.viewer._layers if l is not None), window.plots._last[1]]
    assert all(s is not old_fit for s in drawn)
    assert window.object_view.renderer.source is ws.original()
    assert window.lobe_view.viewer._layers[0].source is ws.original()
    assert window.lobe_view.viewer._layers[1].source is ws.guess
    assert window.plots._last[0] is ws.original() and window.plots._last[3] == []  # no old convergence points
    from PySide6.QtCore import Qt

    window.object_view.drag(30, 10, Qt.LeftButton, Qt.NoModifier)  # orbiting draws the same
    qtbot.waitUntil(lambda: window.object_view.samples_done >= 4, timeout=20000)
    assert window.object_view.renderer.source is ws.original()
    shot(window, "a_window_after_switch")


def _mouse(widget, kind, x: int, buttons) -> None:
    """A real mouse event at (x, middle) of `widget`, left button as given."""
    from PySide6.QtCore import QPointF, Qt
    from PySide6.QtGui import QMouseEvent
    from PySide6.QtWidgets import QApplication

    pos = QPointF(x, widget.height() / 2)
    event = QMouseEvent(kind, pos, widget.mapToGlobal(pos), Qt.LeftButton, buttons, Qt.NoModifier)
    QApplication.sendEvent(widget, event)


def _ward_row(window, qtbot, name: str):
    """The Material panel's row of a new Ward lobe's `name`, the lobe selected."""
    window.editor.lobe_added.emit("Ward")
    tree = window.editor.tree
    tree.setCurrentItem(tree.topLevelItem(tree.topLevelItemCount() - 1))
    row = window.editor._rows[("param", name)]
    qtbot.waitUntil(row.isVisible, timeout=5000)
    return row


def test_a_slider_dragged_to_its_end_and_its_number_agree(window, qtbot):
    from PySide6.QtCore import QEvent, Qt
    from PySide6.QtWidgets import QStyle, QStyleOptionSlider

    row = _ward_row(window, qtbot, "ax")
    slider = row.slider
    option = QStyleOptionSlider()
    slider.initStyleOption(option)
    handle = slider.style().subControlRect(QStyle.CC_Slider, option, QStyle.SC_SliderHandle, slider).center()
    _mouse(slider, QEvent.MouseButtonPress, handle.x(), Qt.LeftButton)
    for x in range(handle.x(), -20, -10):  # past the left end: the lower bound
        _mouse(slider, QEvent.MouseMove, x, Qt.LeftButton)
    assert slider.isSliderDown() and slider.value() == 0
    lobe = window.workspace.analytic.lobes[-1]
    assert lobe.params["ax"] == pytest.approx(0.001)
    assert row.spin.value() == pytest.approx(0.001)  # during the drag
    qtbot.waitUntil(lambda: "on its lower bound" in window.warnings.text(), timeout=5000)
    _mouse(slider, QEvent.MouseButtonRelease, -20, Qt.NoButton)
    qtbot.wait(100)
    assert not slider.isSliderDown() and row.spin.value() == pytest.approx(0.001)  # and after it
    shot(window.editor, "b_slider_at_bound")


def test_enter_in_a_number_box_moves_its_slider(window, qtbot):
    from PySide6.QtCore import Qt

    row = _ward_row(window, qtbot, "ax")
    before = row.slider.value()
    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow, timeout=5000)
    qtbot.mouseClick(row.spin.lineEdit(), Qt.LeftButton)  # into the box, as a person types
    qtbot.waitUntil(row.spin.hasFocus, timeout=5000)
    row.spin.lineEdit().selectAll()
    qtbot.keyClicks(row.spin.lineEdit(), "0.02")
    qtbot.keyClick(row.spin.lineEdit(), Qt.Key_Return)
    assert row.spin.hasFocus()  # Enter, not leaving the box
    assert window.workspace.analytic.lobes[-1].params["ax"] == pytest.approx(0.02)
    assert row.slider.value() == row._to_slider(0.02) != before


@needs_shared("merl_slices", "chrome-steel.slice")
def test_rings_of_measured_chrome_are_said_to_be_the_datas_bins(window, qtbot):
    open_and_wait(qtbot, window, window.open_path, DATA / "merl_slices" / "chrome-steel.slice")
    window.object_controls.mode.setCurrentText("fis")
    qtbot.waitUntil(lambda: window.object_view.samples_done >= 64, timeout=60000)
    assert "MERL's θh bins" in window.warnings.text() and window.warnings.isVisible()
    shot(window, "d_chrome_window")
    open_and_wait(qtbot, window, window.open_path, DATA / "merl_slices" / "pink-felt.slice")
    assert "θh bins" not in window.warnings.text()  # a diffuse table has no rings to explain


def test_a_narrow_lobe_is_drawn_whole_and_framed(window, qtbot):
    from brdflab.geometry.lobe_surface import lobe_radii
    from brdflab.geometry.vec import spherical_to_cartesian

    row = _ward_row(window, qtbot, "ax")
    row.slider.setValue(0)  # ax = 0.001, the models' lower bound
    viewer = window.lobe_view.viewer
    material = window.workspace.analytic
    assert material.lobes[-1].params["ax"] == pytest.approx(0.001)
    wi = spherical_to_cartesian(np.radians(30.0), 0.0)
    peak = float(lobe_radii(material, viewer.settings.shape, np.array([[-wi[0], -wi[1], wi[2]]]))[0])
    # framed by its true peak (at the mirror direction, between the hemisphere's vertices)
    qtbot.waitUntil(lambda: abs(viewer.gain() * peak - 1.0) < 1e-3, timeout=60000)
    qtbot.wait(300)
    img = window.lobe_view.grabFramebuffer()
    shot(window.lobe_view, "c_narrow_ward_lobe")
    # the spike is drawn whole: its tip, at radius 1 along the mirror direction, is on screen and lit
    w, h = window.lobe_view.pixel_size()
    mvp = viewer.view_projection(w, h)
    tip = mvp @ np.array([-wi[0] * 0.97, -wi[1] * 0.97, wi[2] * 0.97, 1.0])
    x, y = (tip[0] / tip[3] + 1) / 2 * w, (1 - tip[1] / tip[3]) / 2 * h
    assert 0 <= x < w and 0 <= y < h
    rgb = np.frombuffer(img.convertToFormat(img.Format.Format_RGB32).constBits(), np.uint8).reshape(h, w, 4)[..., :3]
    near = rgb[int(y) - 3: int(y) + 4, int(x) - 3: int(x) + 4].reshape(-1, 3).astype(int)
    assert (np.abs(near - [36, 31, 31]).max(axis=1) > 40).any()  # not the background


def test_clicking_fit_moves_no_control_and_stop_stays_under_the_mouse(window, qtbot, tmp_path):
    from PySide6.QtCore import QPoint, Qt

    open_and_wait(qtbot, window, window.open_path, _measured(tmp_path, "first", 0.2))
    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow, timeout=5000)
    f = window.fitting
    f.sample_kind.setCurrentText("all")
    stop_at = f.stop_button.mapTo(window, QPoint(0, 0))
    qtbot.mouseClick(f.fit_button, Qt.LeftButton)
    qtbot.waitUntil(lambda: f.stop_button.isEnabled(), timeout=5000)
    qtbot.wait(100)
    shot(window, "e_fitting_running")
    assert f.stop_button.mapTo(window, QPoint(0, 0)) == stop_at  # a click at its old place stops the fit
    assert not f.tolerance.hasFocus()
    qtbot.mouseClick(f.stop_button, Qt.LeftButton)
    qtbot.waitUntil(lambda: window._thread is None, timeout=60000)
    assert f.fit_button.mapTo(window, QPoint(0, 0)).y() == stop_at.y()
    f.status.setText("a status many lines long " * 40)  # a longer status moves no button either
    qtbot.wait(50)
    assert f.fit_button.mapTo(window, QPoint(0, 0)).y() == stop_at.y()


def test_lobe_buttons_stay_put_whichever_lobe_is_selected(window, qtbot):
    from PySide6.QtCore import QPoint

    window.resize(1366, 740)  # a 1366 × 768 laptop's free area
    qtbot.waitUntil(lambda: window.height() == 740, timeout=5000)
    tree = window.editor.tree
    buttons = [b for b in window.editor.findChildren(type(window.fitting.fit_button)) if b.text() in ("Add", "Up")]
    places = []
    for k in (0, 1, 0):  # the Lambertian (3 rows), LafortuneIso (6 rows), back
        tree.setCurrentItem(tree.topLevelItem(k))
        qtbot.wait(50)
        places.append([b.mapTo(window, QPoint(0, 0)) for b in buttons])
    assert places[0] == places[1] == places[2]
    shot(window, "e_laptop_material")
